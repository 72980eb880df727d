"""docs/results/round-off.md, from ``renders/tie_sensitivity/tie_sensitivity.json``
(:func:`round_off_page`).
"""
from __future__ import annotations

from .common import (_cell, _duration, _k_n, _machine, _never, _overlap, _sci, _seconds,
                     _stamp, _table, _wilson)


def round_off_page(data: dict) -> str:
    """docs/studies/tie_sensitivity.py's runs: the greedy rule's variants and the ties."""
    src = "renders/tie_sensitivity/tie_sensitivity.json"
    runs = sorted(data["runs"], key=lambda r: (r["states"], r["seed"]))
    main = runs[0]
    tol, eps = data["tie_tolerance"], data["epsilons"]
    rows = {(r["policy"], r["variant"]): r for r in main["rows"]}
    shipped = next(v for p, v in rows if v.startswith("shipped rule (tolerance"))
    plain = "plain argmax"

    def noisy(rule, e):
        return f"{'argmax' if rule == 'argmax' else 'shipped rule'}, Q +- {e:.0e}"

    ties = {(t["policy"], t["agent"]): t for t in main["ties"]}
    policies = main["policies"]
    genuine = min(t["smallest_genuine_gap"] for t in main["ties"]
                  if t["smallest_genuine_gap"] is not None)
    text = [_stamp(src), "# Round-off and ties: how sensitive the paper's policies are\n\n"]
    text.append(
        "Policy (14) takes the greedy action of every bin, and the "
        "[conventions](../conventions.md) break ties to the first action. A plain `argmax` "
        "only does that for exact ties. `twolink.policy.fuzzy_policy.TIE_TOLERANCE` = "
        f"{_sci(tol)} counts Q-values within {_sci(tol)} of the best as tied (the first wins); the "
        "constant's docstring says why, and the policy files record it. "
        "`docs/studies/tie_sensitivity.py` rebuilds the paper's policies under other greedy "
        "rules and runs them on the simplified plant (11) from x0 and from random states at "
        "rest. *moved* counts the greedy bins that differ from the shipped rule's; *edge* "
        "counts the failures that are arms at rest within "
        f"{_sci(data['edge_slack_deg'])}° of the 5° band edge.\n\n")
    text.append("## The ties\n\nPer agent: bins whose best two Q-values are exactly equal, "
                f"closer than {_sci(data['round_off'])} (round-off of the sweeps' sums), within "
                f"the tolerance {_sci(tol)}, and the smallest gap above it.\n\n")
    text += [_table(("policy", "agent", "bins", "exactly equal", "round-off",
                     "within the tolerance", "smallest genuine gap"),
                    [(f"`{t['policy']}`", t["agent"], t["bins"], t["exact_ties"],
                      t["round_off_ties"], t["within_tolerance"],
                      "-" if t["smallest_genuine_gap"] is None
                      else _sci(t["smallest_genuine_gap"])) for t in main["ties"]]), "\n\n"]
    frozen = ties.get(("decentralized", "agent1"))
    if frozen:
        text.append(
            f"Agent 1 of `decentralized` (frozen context) has {frozen['exact_ties']} bins "
            f"whose best two Q-values are exactly equal and {frozen['round_off_ties']} more "
            f"whose best two differ by less than {_sci(data['round_off'])}: round-off, so the "
            "summation order of the sweep would pick their action. The genuine gaps between "
            f"the best two actions of any of these agents are at least {_sci(genuine)}, so the "
            f"tolerance {_sci(tol)} lies well above the round-off and well below every genuine "
            "gap.\n\n")
    text.append(f"## The greedy rule's variants\n\n{main['states']} random states at rest "
                f"(seed {main['seed']}), 5 s; x0 θ1 is where link 1 ends from x0 "
                f"({_duration(main['seconds'])} for the run).\n\n")
    body = [(f"`{r['policy']}`", _cell(r["variant"]), r["changed_bins"],
             f"{r['successes']}/{r['states']}", _wilson(r["successes"], r["states"]),
             f"{r['edge_stalls']}/{r['states'] - r['successes']}", _seconds(r["x0_settle"]),
             f"{r['x0_final_deg'][0]:+.7f}°") for r in main["rows"]]
    text += [_table(("policy", "variant", "moved", "success", "Wilson 95 %", "edge",
                     "x0 settle", "x0 θ1"), body), "\n\n## What the data shows\n\n"]
    d = "decentralized"
    if (d, shipped) in rows and (d, plain) in rows:
        a, b = rows[d, shipped], rows[d, plain]
        e0 = eps[0]
        n_a, n_s = rows[d, noisy("argmax", e0)], rows[d, noisy("shipped", e0)]
        safe = [e for e in eps if all(rows[p, noisy("shipped", e)]["changed_bins"] == 0
                                      for p in policies)]
        broken = next((e for e in eps if e not in safe), None)
        quiet = [p for p in policies
                 if p != d and rows[p, noisy("shipped", e0)]["changed_bins"] == 0]
        tied = {p: sum(t["within_tolerance"] for (q, _), t in ties.items() if q == p)
                for p in quiet}
        near = ", ".join(f"`{p}` has {tied[p]}"
                         for p in quiet)
        line = (f"- **Round-off would decide the decentralized policy.** A plain `argmax` and "
                f"the shipped rule differ in {b['changed_bins']} of its {b['bins']} bins. "
                f"±{_sci(e0)} on Q moves {n_a['changed_bins']} bins under `argmax` and "
                f"{n_s['changed_bins']} under the tolerance. From x0 that changes where link 1 "
                f"stops: {b['x0_final_deg'][0]:.2f}° (`argmax`), "
                f"{n_a['x0_final_deg'][0]:.2f}° (`argmax`, ±{_sci(e0)}) or "
                f"{a['x0_final_deg'][0]:.7f}° (the shipped rule).")
        if near:
            line += (f" Of the other policies {near} bins within the tolerance; under it, "
                     f"±{_sci(e0)} moves none of them.")
        if safe:
            line += (f" Under the tolerance, noise up to ±{_sci(max(safe))} moves no bin of "
                     "any policy")
            line += (f"; at ±{_sci(broken)} the exact ties break at random again "
                     f"({rows[d, noisy('shipped', broken)]['changed_bins']} bins of the "
                     "decentralized policy).\n" if broken else ".\n")
        else:
            line += "\n"
        text.append(line)
        cmp = []
        for run in runs:
            r = {(x["policy"], x["variant"]): x for x in run["rows"]}
            if (d, shipped) in r and (d, plain) in r:
                s_, p_ = r[d, shipped], r[d, plain]
                cmp.append((run, s_, p_, _overlap((s_["successes"], s_["states"]),
                                                  (p_["successes"], p_["states"]))))
        if cmp:
            said = "; ".join(
                f"seed {run['seed']}, {run['states']} states: {_k_n(s_['successes'], s_['states'])}"
                f" against {_k_n(p_['successes'], p_['states'])}"
                f"{'' if ov else ' (the intervals do not overlap)'}" for run, s_, p_, ov in cmp)
            verdict = ("the intervals overlap in every run, so the change is inside the "
                       "sampling noise" if all(c[3] for c in cmp) else
                       "in some runs the intervals do not overlap")
            text.append(f"- **Success from random states, shipped rule against `argmax`** "
                        f"(decentralized): {said}; {verdict}.\n")
    ctx = []
    for run in runs:
        r = {(x["policy"], x["variant"]): x for x in run["rows"]}
        if (d, shipped) in r and (d + "_propagated", shipped) in r:
            f_, p_ = r[d, shipped], r[d + "_propagated", shipped]
            ctx.append(f"seed {run['seed']}, {run['states']} states: "
                       f"{_k_n(f_['successes'], f_['states'])} against "
                       f"{_k_n(p_['successes'], p_['states'])}"
                       + ("" if _overlap((f_["successes"], f_["states"]),
                                         (p_["successes"], p_["states"]))
                          else " (the intervals do not overlap)"))
    if ctx:
        text.append("- **Agent 1's context, frozen (`decentralized`) against propagated "
                    "(`decentralized_propagated`)**, both under the shipped rule: "
                    + "; ".join(ctx) + ".\n")
    stalls = [(p, rows[p, shipped]) for p in policies if (p, shipped) in rows]
    if stalls:
        parts = ", ".join(f"{r['edge_stalls']}/{r['states'] - r['successes']} (`{p}`)"
                          for p, r in stalls)
        line = (f"- **Edge stalls.** Of the shipped rule's failures from random states, "
                f"{parts} are arms parked within {_sci(data['edge_slack_deg'])}° of the band "
                "edge.")
        x0_edge = [p for p, r in stalls if _never(r["x0_settle"])
                   and 0 < abs(r["x0_final_deg"][0]) - 5 < data["edge_slack_deg"]]
        if x0_edge:
            line += (" The x0 rollout of " + ", ".join(f"`{p}`" for p in x0_edge)
                     + " is one of them: link 1 parks at "
                     f"{rows[x0_edge[0], shipped]['x0_final_deg'][0]:.7f}°.")
        text.append(line + " The success rates of the paper's policies rest on that "
                    "knife-edge of the metric as much as on the policies.\n")
    text.append(f"\nMachine: {_machine(data['provenance'])}. Re-create the data with "
                + "; ".join(f"`python docs/studies/tie_sensitivity.py --seed {r['seed']} "
                            f"--states {r['states']} --json {src}` ({_duration(r['seconds'])})" for r in runs)
                + " (each run is merged into the file by states, seed and policies), then "
                "`python docs/generate.py`.\n")
    return "".join(text)
