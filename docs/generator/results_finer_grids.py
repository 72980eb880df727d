"""docs/results/finer-grids.md, from ``renders/grid_study/grid_study.json``
(:func:`finer_grids_page`).
"""
from __future__ import annotations

from .common import _duration, _int, _k_n, _machine, _overlap, _seconds, _stamp, _table


def _grid_rows(run: dict) -> dict:
    return {(r["kind"], r["model"], r["refine"]): r for r in run["rows"]}


def _kn(o: dict) -> tuple:
    return o["successes"], o["states"]


def _grid_claims(run: dict) -> dict:
    """The conclusions the finer-grids page draws, each evaluated on ``run``: ``{name:
    True/False}``, or nothing for a conclusion whose rows the run lacks."""
    g, out = _grid_rows(run), {}
    refines = run["options"]["refine"]
    lo, hi = min(refines), max(refines)

    def cl(kind, model, refine, plant, what):
        return g[kind, model, refine]["closed_loop"][plant][what]
    if lo != hi and all((k, "simplified", r) in g for k in ("centralized", "decentralized")
                        for r in (lo, hi)):
        out["simplified"] = all(
            cl(k, "simplified", hi, "simplified", "random")["successes"]
            < cl(k, "simplified", lo, "simplified", "random")["successes"]
            and not _overlap(_kn(cl(k, "simplified", hi, "simplified", "random")),
                             _kn(cl(k, "simplified", lo, "simplified", "random")))
            for k in ("centralized", "decentralized"))
    for k in ("centralized", "decentralized"):
        if all((k, "full", r) in g for r in (1, 2)):
            a, b = cl(k, "full", 1, "mujoco", "noisy"), cl(k, "full", 2, "mujoco", "noisy")
            out[f"noise-{k}"] = (b["successes"] > a["successes"]
                                 and not _overlap(_kn(a), _kn(b)))
    if all(("centralized", "full", r) in g for r in (2, 3)):
        out["refine-3"] = _overlap(_kn(cl("centralized", "full", 2, "mujoco", "noisy")),
                                   _kn(cl("centralized", "full", 3, "mujoco", "noisy")))
    return out


#: The conclusions of :func:`_grid_claims`, as the page words them.
GRID_CLAIMS = {
    "simplified": "the policies synthesised on (11) succeed from fewer random poses on "
                  "their own plant at the finest grid than at the coarsest, intervals apart",
    "noise-centralized": "on MuJoCo under observation noise the centralized policy on (6) "
                         "gains from refine 2, intervals apart",
    "noise-decentralized": "on MuJoCo under observation noise the decentralized agents on "
                           "(6) gain from refine 2, intervals apart",
    "refine-3": "refine 3 of the centralized policy on (6) under noise overlaps refine 2",
}


def _sweeps(row: dict) -> str:
    """A row's sweeps, agent 2's before agent 1's (JSON sorted them)."""
    order = ("centralized", "agent2", "agent1")
    return "/".join(str(row["sweeps"][k]) for k in sorted(row["sweeps"], key=order.index))


def _plants(row: dict) -> list:
    """A row's closed loops, the simplified plant before MuJoCo (JSON sorted them)."""
    return sorted(row["closed_loop"].items(), key=lambda kv: kv[0] != "simplified")


def finer_grids_page(data: dict) -> str:
    """docs/studies/grid_study.py's runs: synthesis and closed loop per kind, model and
    refinement."""
    from twolink.viz.formatting import format_rate

    src = "renders/grid_study/grid_study.json"
    runs = [r for r in data["runs"] if r["options"]["sweeps"] == "synchronous"]
    serial = [r for r in data["runs"] if r["options"]["sweeps"] == "serial"]
    runs.sort(key=lambda r: (-len(r["rows"]), r["options"]["seed"]))
    main = runs[0]
    o = main["options"]
    g = _grid_rows(main)

    def cl(kind, model, refine, plant, what):
        return g[kind, model, refine]["closed_loop"][plant][what]

    def rate(c):
        return f"{format_rate(c['successes'], c['states'])} e{c['edge_stalls']}"
    text = [_stamp(src), "# Finer grids\n\n",
            "`refine=K` (`twolink synthesize ... --refine K`, `synthesize(..., refine=K)`) "
            "inserts K − 1 evenly spaced centres between neighbouring centres of the paper's "
            "bins (`fuzzy.Axis.refined`: 12K angle bins, 6K + 1 speed bins; agent 1's τ2 "
            "axis stays the three torques). `docs/studies/grid_study.py` measures what "
            f"K = {', '.join(map(str, o['refine']))} buy for the centralized policy (16) and "
            "the decentralized agents (18) (frozen context), synthesised on "
            + " and on ".join({"simplified": "the simplified model (11)",
                               "full": "the full model (6)"}[m] for m in o["models"])
            + f" ({o['sweeps']} sweeps), each run on the simplified plant and on MuJoCo over "
            f"the evaluation set (65 states), over {o['states']} random poses at rest (seed "
            f"{o['seed']}), and over the same poses with {o['noise_deg']:g}° / "
            f"{main['speed_noise']:g} rad/s Gaussian observation noise "
            "(`twolink.sim.perturbations.ObservationNoise`). Success is k/n with its 95 % "
            "Wilson interval, *eN* counts edge stalls among the failures, *median* is the "
            "median settle time of the random poses that succeed, *peak* the peak of traced "
            "numpy/scipy allocations (tracemalloc) during synthesis, *RSS* the process's "
            "high-water mark so far (configurations run from small to large). The run took "
            f"{_duration(main['seconds'])} ({main['rss_max_mib'] / 1024:.1f} GiB resident at "
            f"most) on {data['provenance']['cpu_count']} CPUs; *sweeps* lists agent 2's, then "
            "agent 1's, and the first row's time includes loading the compiled kernels.\n\n",
            "## Synthesis\n\n",
            _table(("kind", "model", "refine", "Q size", "nnz(T)", "sweeps", "time",
                    "peak", "RSS"),
                   [(r["kind"], r["model"], r["refine"], _int(r["q_size"]), _int(r["nnz"]),
                     _sweeps(r),
                     f"{r['synthesis_seconds']:.2f} s", f"{r['peak_traced_mib']:.0f} MiB",
                     f"{r['rss_max_mib']:.0f} MiB") for r in main["rows"]]), "\n\n",
            "## Closed loop, 5 s\n\n",
            _table(("kind", "model", "refine", "plant", "x0 settle", "evaluation set",
                    "random poses", "with noise", "median"),
                   [(r["kind"], r["model"], r["refine"], plant, _seconds(c["x0_settle"]),
                     rate(c["evaluation"]), rate(c["random"]), rate(c["noisy"]),
                     "-" if c["random"]["median_settle"] is None
                     else f"{c['random']['median_settle']:.2f} s")
                    for r in main["rows"] for plant, c in _plants(r)]),
            "\n\n## What the data shows\n\n"]
    hi = max(o["refine"])
    c_hi = ("centralized", "full", hi)
    if c_hi in g and ("centralized", "full", 1) in g:
        r, r1 = g[c_hi], g["centralized", "full", 1]
        bins, bins1 = r["q_size"] // 9, r1["q_size"] // 9     # 3 x 3 torque pairs
        s11 = g.get(("centralized", "simplified", hi))
        nxt = main["largest_q_table"].get(str(hi + 1))
        line = (f"- **Refine {hi} of the centralized problem fits.** It has "
                f"{_int(bins)} bins ({bins / bins1:.0f}× the paper's "
                f"{_int(bins1)}), {r['q_size'] / 1e6:.1f} M Q-values and "
                f"{r['nnz'] / 1e6:.0f} M non-zeros in T, and synthesises in "
                f"{r['synthesis_seconds']:.1f} s on the full model")
        if s11:
            sw, sw11 = r["sweeps"]["centralized"], s11["sweeps"]["centralized"]
            line += (f" ({s11['synthesis_seconds']:.1f} s on (11), whose {sw11} sweeps are "
                     f"{sw11 / sw:.1f}× the full model's {sw})")
        line += f" with {r['peak_traced_mib'] / 1024:.2f} GiB of traced allocations."
        if nxt:
            mib = 8 * nxt / 2**20
            over = 8 * nxt > data["max_q_bytes"]
            line += (f" Refine {hi + 1} would hold {nxt / 1e6:.1f} M Q-values, {mib:.0f} MiB"
                     + (f", over the policy file's {data['max_q_bytes'] >> 20} MiB limit for "
                        "a Q-table." if over else "."))
        text.append(line + "\n")
    if all((k, "simplified", r) in g for k in ("centralized", "decentralized")
           for r in o["refine"]):
        parts = []
        for k in ("centralized", "decentralized"):
            ks = [cl(k, "simplified", r, "simplified", "random") for r in o["refine"]]
            parts.append(f"the {k} one from " + ", ".join(
                f"{c['successes']}/{c['states']} (refine {r})" for c, r in zip(ks, o["refine"])))
        claims = _grid_claims(main)
        line = ("- **Policies synthesised on (11) against refinement, on their own plant** "
                "(random poses): " + "; ".join(parts) + ". "
                + ("They get worse with every refinement, the finest and coarsest grids' "
                   "intervals apart." if claims.get("simplified") else
                   "The finest grid is not clearly worse than the coarsest here."))
        key = ("centralized", "simplified", 2)
        if key in g:
            t = g[key]["closed_loop"]["simplified"]["x0_tail"]
            line += (f" From x0 the refine-2 centralized one ends with link 2 between "
                     f"{t['theta2_deg'][0]:.1f}° and {t['theta2_deg'][1]:.1f}° and "
                     f"θ̇2 between {t['dtheta2'][0]:.2f} and {t['dtheta2'][1]:.2f} rad/s over "
                     f"the last {t['seconds']:g} s, under a mean |τ2| of "
                     f"{t['mean_abs_torque2']:.3f} N m: our reading is that (11) damps link 2 "
                     "weakly and the finer bins near the goal take little torque where the "
                     "paper's coarse bins, blended by (14), still pushed (one trajectory, not "
                     "a measurement over the set).")
        best = max(cl(k, "simplified", r, "mujoco", w)["successes"]
                   for k in ("centralized", "decentralized") for r in o["refine"]
                   for w in ("evaluation", "random"))
        text.append(line + f" On MuJoCo the (11) policies succeed from at most {best} states "
                    "of any set at any refinement.\n")
    if all(("centralized", "full", r) in g for r in (1, 2)):
        a, b = (g["centralized", "full", r]["closed_loop"]["mujoco"] for r in (1, 2))
        line = ("- **Policies synthesised on (6) and run on MuJoCo, refine 1 against 2.** "
                f"Centralized, noise-free random poses: {_k_n(*_kn(a['random']))} against "
                f"{_k_n(*_kn(b['random']))}"
                + (" (overlapping)" if _overlap(_kn(a["random"]), _kn(b["random"])) else "")
                + f"; under observation noise {_k_n(*_kn(a['noisy']))} against "
                f"{_k_n(*_kn(b['noisy']))}"
                + (" (overlapping)" if _overlap(_kn(a["noisy"]), _kn(b["noisy"])) else "")
                + f"; median settle over the noise-free random successes "
                f"{_seconds(a['random']['median_settle'])} → "
                f"{_seconds(b['random']['median_settle'])}.")
        if all(("decentralized", "full", r) in g for r in (1, 2)):
            da, db = (g["decentralized", "full", r]["closed_loop"]["mujoco"] for r in (1, 2))
            line += (f" Decentralized: under noise {_k_n(*_kn(da['noisy']))} against "
                     f"{_k_n(*_kn(db['noisy']))}, noise-free {da['random']['successes']}/"
                     f"{da['random']['states']} against {db['random']['successes']}/"
                     f"{db['random']['states']}"
                     + (" (overlapping)." if _overlap(_kn(da["random"]), _kn(db["random"]))
                        else "."))
        if ("centralized", "full", 3) in g:
            c3, r2 = g["centralized", "full", 3], g["centralized", "full", 2]
            n3 = c3["closed_loop"]["mujoco"]["noisy"]
            line += (f" Refine 3: the centralized policy keeps {_k_n(*_kn(n3))} under noise"
                     + (", overlapping refine 2's," if _overlap(_kn(n3), _kn(b["noisy"]))
                        else ", apart from refine 2's,")
                     + f" at {c3['synthesis_seconds'] / r2['synthesis_seconds']:.1f}× the "
                     f"time and {c3['peak_traced_mib'] / r2['peak_traced_mib']:.1f}× the "
                     "traced memory")
            if ("decentralized", "full", 3) in g:
                d3 = g["decentralized", "full", 3]["closed_loop"]["mujoco"]["random"]
                line += (f"; the decentralized agents at refine 3 succeed from "
                         f"{_k_n(*_kn(d3))} noise-free random poses")
            line += "."
        text.append(line + "\n")
        r2 = g["centralized", "full", 2]
        e2 = b["evaluation"]
        text.append(
            "\n**Which grid to pick.** To reproduce the paper, or to control the simplified "
            "plant (11), keep the paper's grid (refine 1): the bullets above show what finer "
            "grids do to the (11) policies. To control MuJoCo (the full dynamics, standing in "
            "for a real arm), synthesise on the full model and refine twice: `twolink "
            f"synthesize centralized --model full --refine 2` ({r2['synthesis_seconds']:.1f} s "
            f"here, {_int(r2['q_size'])} Q-values) succeeds from "
            f"{e2['successes']}/{e2['states']} evaluation-set states and "
            f"{b['random']['successes']}/{b['random']['states']} random poses and keeps "
            f"{b['noisy']['successes']}/{b['noisy']['states']} under observation noise, where "
            f"the paper's grid keeps {a['noisy']['successes']}/{a['noisy']['states']}; for "
            "the decentralized agents `twolink synthesize decentralized --model full "
            "--refine 2` is the same trade.\n")
    if len(runs) > 1:
        text.append("\n## Other seeds\n\nEach conclusion above, checked on every run of "
                    "the same options but the seed:\n\n")
        claims = {r["options"]["seed"]: _grid_claims(r) for r in runs}
        body = [(GRID_CLAIMS[name], *("holds" if c.get(name) else
                                      ("-" if name not in c else "**does not hold**")
                                      for c in claims.values()))
                for name in GRID_CLAIMS]
        text += [_table(("conclusion", *(f"seed {s}" for s in claims)), body), "\n"]
        for r in runs[1:]:
            text.append(f"\n### Seed {r['options']['seed']}\n\n")
            text += [_table(("kind", "model", "refine", "plant", "x0 settle",
                             "evaluation set", "random poses", "with noise"),
                            [(x["kind"], x["model"], x["refine"], plant,
                              _seconds(c["x0_settle"]), rate(c["evaluation"]),
                              rate(c["random"]), rate(c["noisy"]))
                             for x in r["rows"] for plant, c in _plants(x)]),
                     "\n"]
    for r in serial:
        ro = r["options"]
        text.append(f"\n## Serial sweeps\n\nThe same measurement with serial sweeps "
                    f"(`--sweeps serial`; the shipped policies are synchronous), refine "
                    f"{', '.join(map(str, ro['refine']))}, seed {ro['seed']}, beside the "
                    "synchronous rows above:\n\n")
        body = []
        for x in r["rows"]:
            sync = g.get((x["kind"], x["model"], x["refine"]))
            for plant, c in _plants(x):
                s_ = sync["closed_loop"][plant] if sync else None
                body.append((x["kind"], x["model"], x["refine"], plant,
                             _sweeps(x),
                             _seconds(c["x0_settle"]), rate(c["evaluation"]), rate(c["random"]),
                             "-" if s_ is None else rate(s_["evaluation"]),
                             "-" if s_ is None else rate(s_["random"])))
        text += [_table(("kind", "model", "refine", "plant", "sweeps", "x0 settle",
                         "evaluation set", "random poses", "synchronous: evaluation set",
                         "synchronous: random poses"), body), "\n"]
        pairs = [(x["closed_loop"][pl][w], g[x["kind"], x["model"], x["refine"]]
                  ["closed_loop"][pl][w])
                 for x in r["rows"] if (x["kind"], x["model"], x["refine"]) in g
                 for pl in x["closed_loop"] for w in ("evaluation", "random")]
        if pairs:
            apart = sum(not _overlap(_kn(a), _kn(b)) for a, b in pairs)
            text.append("\n" + ("The serial and synchronous intervals overlap in every "
                                 f"one of these {len(pairs)} comparisons: the closed loop "
                                 "does not tell the two sweeps apart.\n" if not apart else
                                 f"{apart} of these {len(pairs)} comparisons have intervals "
                                 "apart.\n"))
    cmds = []
    for r in runs + serial:
        ro = r["options"]
        extra = "" if ro["seed"] == 7 else f" --seed {ro['seed']}"
        if ro["refine"] != [1, 2, 3]:
            extra += " --refine " + " ".join(map(str, ro["refine"]))
        if ro["models"] != ["simplified", "full"]:
            extra += " --models " + " ".join(ro["models"])
        if ro["sweeps"] != "synchronous":
            extra += f" --sweeps {ro['sweeps']}"
        if ro["states"] != 200:
            extra += f" --states {ro['states']}"
        if ro["noise_deg"] != 1.0:
            extra += f" --noise-deg {ro['noise_deg']:g}"
        cmds.append(f"`python docs/studies/grid_study.py{extra} --json {src}` "
                    f"({_duration(r['seconds'])})")
    text.append(f"\nMachine: {_machine(data['provenance'])}. Re-create the data with "
                + "; ".join(cmds) + " (each run is merged into the file by its options), "
                "then `python docs/generate.py`.\n")
    return "".join(text)
