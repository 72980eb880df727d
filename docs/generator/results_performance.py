"""docs/results/performance.md, from ``benchmarks/results.json`` (:func:`performance_page`).
"""
from __future__ import annotations

import sys

from .common import _cell, _gib, _order, ROOT, _stamp, _table


def _bench_value(v) -> str:
    sys.path.insert(0, str(ROOT))
    from benchmarks.common import _fmt
    return _fmt(v)


def _performance_findings(data: dict) -> str:
    """What the benchmark sections measure and what this run shows, every figure from
    ``data`` (benchmarks/results.json)."""
    sys.path.insert(0, str(ROOT))
    from benchmarks.run import SECTIONS

    summ, secs = data.get("summary", {}), data["seconds"]
    rows = {(r["section"], r["name"]): r for r in data["rows"]}

    def val(section, name):
        r = rows.get((section, name))
        return None if r is None else r["value"]
    out = ["## What the sections measure\n\n",
           "```bash\nmake bench          # full mode: python -m benchmarks.run --json "
           "benchmarks/results.json\nmake bench-quick    # CI mode:   python -m "
           "benchmarks.run --quick\n```\n\n",
           "Both print a table and can write JSON (`--json PATH`) with every row and the "
           "machine's description; `--only` picks sections (" + ", ".join(
               f"`{s}`" for s in SECTIONS) + "). This run measured "
           + ", ".join(f"`{s}` ({secs[s]:.0f} s)" for s in secs if s != "total")
           + "; the sections it lacks were not run. Every ratio is measured in the same run "
           "on the same inputs, with interleaved repeats so both sides see the same "
           "background load; on a shared machine single figures move between runs more "
           "than ratios do.\n\n"]
    syn = summ.get("synthesis", {})
    syn = _order(syn, ("centralized", "agent2", "agent1"))
    if syn:
        c = syn.get("centralized")
        csr = any("scipy CSR" in r["note"] for r in data["rows"])
        line = ("**Synthesis.** Wall time split into the model transitions f(c_m, u), the "
                "transition table T and the sweeps of Alg. 1 to convergence (best of "
                f"{data['config']['repeats']}), each problem as the package builds it")
        line += (" at the time of this run (T as a scipy CSR matrix, per the rows' notes; "
                 "the package now factors the centralized T along θ1, so `make bench` would "
                 "give other figures)" if csr else "") + ": " + ", ".join(
            f"{name} {_bench_value(p['total'])} s ({p['iterations']} sweeps)"
            for name, p in syn.items()) + "."
        ratio = val("synthesis: centralized vs decentralized", "paper / ours centralized time")
        if ratio is not None:
            line += (f" The paper's CPU time for the centralized policy is "
                     f"{ratio:,.0f}× this run's")
            cd = val("synthesis: centralized vs decentralized", "centralized / decentralized time")
            qd = val("synthesis: centralized vs decentralized",
                     "centralized / decentralized Q size")
            if cd is not None and qd is not None:
                line += (f"; the centralized policy takes {cd:.1f}× the decentralized pair's "
                         f"time for a {qd:.1f}× larger Q-table")
            line += "."
        out.append(line + "\n\n")
        peers = [p for p in ("quantecon", "mdptoolbox") if c and p in c["per_sweep"]]
        if peers:
            agree = max(v[0] for p in syn.values() for v in p["agreement"].values())
            share = min(v[1] for p in syn.values() for v in p["agreement"].values())
            out.append(
                "Peers on the identical MDP: fuzzy Q-iteration is value iteration on the MDP "
                "whose transition probabilities are the memberships (rows of T sum to one) "
                "with rewards ρ(c_m, u). QuantEcon's `DiscreteDP` (state-action-pairs form, "
                "the scipy CSR T) and pymdptoolbox's `ValueIteration` (T split into one "
                "sparse (S, S) matrix per action) get the same T and rewards and are forced "
                "to do the same number of sweeps from V₀ = 0. Their values agree with ours "
                + ("(max |ΔV| / max |V| is exactly 0 on all three problems) " if agree == 0
                   else f"(max |ΔV| / max |V| at most {_bench_value(agree)} over the three "
                   "problems) ")
                + ("and their greedy actions are greedy in our Q (QuantEcon's computed one "
                   "sweep later) " if share == 1 else
                   f"and at least {100 * share:.0f} % of their greedy actions are greedy in "
                   "our Q ")
                + f"in this run. Time per sweep (best of {data['config']['sweep_repeats']}, "
                "interleaved), ours against theirs:\n\n"
                + _table(("problem", "ours", *peers, *(f"{p} / ours" for p in peers)),
                         [(name, f"{1e3 * p['per_sweep']['ours']:.4g} ms",
                           *(f"{1e3 * p['per_sweep'][q]:.4g} ms" for q in peers),
                           *(f"{p['per_sweep'][q] / p['per_sweep']['ours']:.2f}" for q in peers))
                          for name, p in syn.items()]) + "\n\n")
            fast = next((r for (s, n), r in rows.items() if s.endswith("centralized vs "
                                                                         "decentralized")
                         and n.startswith("fastest peer")), None)
            if fast:
                out.append(f"The row \"{_cell(fast['name'])}\" is {_bench_value(fast['value'])} "
                           f"against its note's target ({_cell(fast['note'])}): "
                           + ("met" if fast["value"] >= 1 else "**missed**") + " in this run. "
                           "mdptoolbox's setup is its constructor's input check and iteration "
                           "bound, paid once per problem (the rows' *setup*).\n\n")
    sc = summ.get("scaling", [])
    if sc:
        ran = [r for r in sc if "seconds" in r]
        pred = [r for r in sc if "seconds" not in r]
        by = {(r["scheme"], r["k"]): r for r in sc}
        line = ("**Scaling (Table II, extended).** The grids refined k× per dimension (angles "
                "12 → 12k bins, speeds 7 → 6k + 1; agent 1's τ2 axis stays the three "
                "torques), each synthesised on (11) to convergence; peak memory (tracemalloc) "
                "where run, predicted elsewhere from each scheme's bytes per unit of work on "
                "its largest run. Run: " + "; ".join(
                    f"{r['scheme']} k = {r['k']} {_bench_value(r['seconds'])} s, "
                    f"{r['peak_bytes'] / 2**20:.0f} MiB" for r in ran) + ".")
        common = [k for (s, k) in by if s == "centralized" and "seconds" in by[s, k]
                  and ("decentralized", k) in by and "seconds" in by["decentralized", k]]
        if common:
            k = max(common)
            a, b = by["centralized", k], by["decentralized", k]
            line += (f" At {k}× bins the centralized policy costs "
                     f"{a['seconds'] / b['seconds']:.0f}× the decentralized pair's time and "
                     f"{a['peak_bytes'] / b['peak_bytes']:.0f}× its memory.")
        if pred:
            line += (" Predicted, not run: " + "; ".join(
                f"{r['scheme']} k = {r['k']} {_gib(r['predicted_bytes'])}" for r in pred)
                + f" (the machine has {_gib(data['machine']['ram_bytes'])}).")
        out.append(line + " The centralized cost grows with (bins per dimension)⁴ × 9 "
                   "actions, the decentralized one with agent 1's (bins)³ × 3 × 3 and its 16 "
                   "memberships per transition.\n\n")
    ro = summ.get("rollouts", {})
    thr = [t for t in ("1", "2") if t in ro]
    if thr:
        cfg = data["config"]
        out.append(
            f"**Rollouts.** Closed-loop batched rollouts of the centralized policy on MuJoCo "
            f"({cfg['batch']} initial states, one `mujoco.rollout` call per sample period for "
            "the whole batch, the policy (14) in numpy between calls) against open-loop "
            "`mujoco.rollout` of the same model doing the same steps with the same torques "
            "in one call, the physics engine's limit here: closed / open loop "
            + ", ".join(f"{ro[t]['closed_steps_per_s'] / ro[t]['open_steps_per_s']:.2f} on "
                        f"{t} thread{'s' if t != '1' else ''}" for t in thr)
            + "; the policy takes " + ", ".join(f"{100 * ro[t]['policy_share']:.1f} %"
                                                for t in thr)
            + " of the closed loop's time. With more threads the loop hands each a short "
            "job per sample period, waits for the slower one and evaluates the policy on one "
            "core between, while the open-loop call keeps every thread busy: the likely "
            "reason the ratio falls with threads."
            + (f" The numpy plants, batch {cfg['batch']}: simplified (11) "
               f"{_bench_value(ro['simplified'])} sample periods/s, full (6)–(9) "
               f"{_bench_value(ro['full'])}." if "simplified" in ro and "full" in ro else "")
            + "\n\n")
    lb = summ.get("leaderboard", {})
    if lb.get("rows"):
        t = lb["nthread"]
        out.append(
            f"**Leaderboard rows.** One leaderboard row (`{lb['controller']}` under "
            f"`{lb['level']}`: {lb['plants']} plants × {lb['states']} states × "
            f"{lb['samples']} sample periods, one `mujoco.rollout` call per sample period, "
            "the controller once per sample on the whole batch, the level's noise and "
            "delays, summed up) against raw `mujoco.rollout` of the same models, initial "
            f"states and {lb['physics_steps']:,} physics steps in one call, on the same "
            f"{t} thread{'s' if t != 1 else ''}, interleaved: "
            + ", ".join(f"{mode} {lb['rows'][mode]['seconds']:.1f} s, "
                        f"{lb['rows'][mode]['ratio']:.2f}× raw's steps/s"
                        for mode in ("plain", "compensated") if mode in lb["rows"])
            + f" (raw {lb['raw_seconds']:.1f} s; load average {lb['load_average']:.1f} "
            "when the section started). "
            + " ".join(f"`{name}` through every level and mode: {v['seconds']:.0f} s "
                       f"({len(v['rows'])} rows)." for name, v in lb.get("through", {}).items())
            + "\n\n")
    rd = summ.get("rendering", {})
    sizes = [s for s in rd if isinstance(rd[s], dict)]
    if sizes:
        over = [rd[s]["package"] / rd[s]["bare"] for s in sizes]
        gain = [rd[s]["package"] / rd[s]["plain"] for s in sizes]
        out.append(
            "**Rendering.** The package renderer against a bare `mujoco.Renderer` of the "
            f"same scene: {min(over):.2f}–{max(over):.2f}× its frame rate, so no measurable "
            "overhead; against MuJoCo's defaults on the plain MJCF (shadow map, "
            f"multisampling) it is {min(gain):.1f}–{max(gain):.1f}× faster."
            + (f" MP4 encoding runs at {rd['encode_fps']:.0f} frames/s, so rendering, not "
               "encoding, sets a video's cost." if "encode_fps" in rd
               and rd["encode_fps"] > max(rd[s]["ghost_overlay"] for s in sizes) else "")
            + "\n\n")
    if "vector_env" not in secs:
        out.append("The Gymnasium vector environment against raw `mujoco.rollout` "
                   "(`--only vector_env`) is not in this run; see "
                   "[Gymnasium](../guides/gymnasium.md).\n\n")
    return "".join(out)


def _earlier(data: dict) -> str:
    """A sentence on the sections kept from an earlier run (``--merge``), if any."""
    e = data.get("earlier")
    if not e:
        return ""
    m = e["machine"]
    return (f"The sections {', '.join(f'`{s}`' for s in e['sections'])} come from an "
            f"earlier `{e['command']}` run ({e['mode']} mode, load average "
            f"{m['load_average'][0]:.1f} at its start).\n\n")


def performance_page(data: dict) -> str:
    sections: dict = {}
    for row in data["rows"]:
        sections.setdefault(row["section"], []).append(row)
    m = data["machine"]
    ram = m.get("ram_bytes")
    text = [_stamp("benchmarks/results.json"), "# Performance\n\n",
            f"One `{data['command']}` run ({data['mode']} mode, {data['seconds']['total']:.0f} s) "
            f"on {m.get('cpu_count')} CPUs ({m.get('cpu_model') or m.get('processor')})"
            + (f", {ram / 2**30:.1f} GiB RAM" if ram else "")
            + f", load average {m['load_average'][0]:.1f} at the start; Python {m['python']}, "
            f"numpy {m['numpy_version']}, MuJoCo {m['mujoco_version']}, twolink "
            f"{m['twolink_version']}. How the kernels came to their shape: "
            "[Performance notes](../performance.md).\n\n" + _earlier(data),
            _performance_findings(data)]
    for section, rows in sections.items():
        text += [f"## {section}\n\n",
                 _table(("quantity", "value", "unit", "note"),
                        [(_cell(r["name"]), _bench_value(r["value"]), _cell(r["unit"]),
                          _cell(r["note"])) for r in rows]), "\n\n"]
    text += ["Re-create the data with `make bench` (writes `benchmarks/results.json`), then "
             "`python docs/generate.py`.\n"]
    return "".join(text)
