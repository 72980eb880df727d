"""docs/results/leaderboard.md and docs/results/fuzzy-designs.md, both from
``renders/leaderboard/leaderboard.json`` (:func:`leaderboard_page`,
:func:`fuzzy_designs_page`, the latter judged against
:data:`~generator.targets.FUZZY_TARGETS`).
"""
from __future__ import annotations

from .common import _cell, _load, SCHEMAS, _stamp, _table
from .targets import FUZZY_TARGETS


#: The near-goal gain study's data (docs/studies/near_gain.py).
NEAR_GAIN = "renders/fuzzy_design/near_gain.json"


def leaderboard_page(report: dict) -> str:
    """The full leaderboard (twolink.studies.leaderboard.report.markdown) with its figure
    after the introduction."""
    from twolink.studies.leaderboard.report import markdown

    text = markdown(report).rstrip("\n").replace("T*", "T\\*")
    intro, _, tables = text.partition("\n## ")
    figure = ("![success against settle / T\\*, a panel per level](../renders/leaderboard/"
              "leaderboard.png)\n\nEach panel: success rate against median settle / T\\* "
              "under one level; filled markers plain, hollow ones compensated; the marker is "
              "the family (circle fuzzy, square baseline, triangle learned, diamond user), "
              "the colour the controller (the catalogue's benchmark rows); grey dots are the "
              "other controllers. Each title names the best labelled controller in the plain "
              "mode under the ranking rule.\n\n")
    return "".join([_stamp("renders/leaderboard/leaderboard.json"), intro.rstrip("\n"),
                    "\n\n", figure, "## ", tables, "\n\n",
                    "How to run it and add your controller: [Leaderboard]"
                    "(../guides/leaderboard.md). Re-create the data with `make results "
                    "STEPS=\"leaderboard docs\"` (`twolink leaderboard --all` into "
                    "renders/leaderboard, then `python docs/generate.py`).\n"])


def _fuzzy() -> dict:
    """``{name: kind}`` of the two-link catalogue entries tagged ``fuzzy``: the shipped
    fuzzy policies and the handovers between two of them."""
    from twolink.control.catalogue import shipped_entries

    return {e.name: e.kind for e in shipped_entries() if "fuzzy" in e.tags and e.links == 2}


def _kinds(names) -> dict:
    """``{controller: "centralized" | "decentralized"}`` of the fuzzy and baseline ones
    among ``names``."""
    from twolink.control.baselines import BASELINES, baseline

    fuzzy, out = _fuzzy(), {}
    for n in names:
        if n in fuzzy:
            out[n] = fuzzy[n]
        elif n in BASELINES:
            out[n] = baseline(n).kind
    return out


def fuzzy_designs_page(report: dict) -> str:
    """The tuned fuzzy designs against their targets and against the best controller of
    their kind at every level, from the committed leaderboard; then the tuning table of
    docs/studies/fuzzy_design.py when its data is committed."""
    from twolink.sim.metrics import wilson_interval
    from twolink.studies.leaderboard.ranking import ranked
    from twolink.viz.formatting import format_rate

    rows = {(r["controller"], r["level"], r["mode"]): r for r in report["rows"]}
    kinds = _kinds(dict.fromkeys(r["controller"] for r in report["rows"]))
    fuzzy_kinds = _fuzzy()
    out = [_stamp("renders/leaderboard/leaderboard.json"),
           "# Fuzzy designs against the yardstick\n\n",
           "The tuned fuzzy designs (`*_tuned` and `centralized_9levels`: more torque "
           "levels, other bins, a read-out with a speed dead zone and the argmax of Q far "
           "from the goal; `*_edge`: the same designs on bins with no centre on the goal "
           "band's edge; `*_locked`: agent 2's transitions holding joint 1; `*_gain`: "
           "a read-out that lowers the torque near the goal; `centralized_handover`: "
           "`centralized_9levels` handing the settled arm to a robust design; "
           "`decentralized_handover`: `decentralized_edge_locked` handing every joint to "
           "a robust design at the same time on a clock; [Synthesis](../guides/synthesis.md)) on the committed "
           f"leaderboard: {report['states']} evaluation states, {report['plants']} plants "
           f"per perturbed level, seed {report['seed']}, on MuJoCo. Their designs were "
           "chosen on other states and seeds (the tuning table below).\n\n## Targets\n\n"]
    def verdict(r, rate, worst, ratio):
        want, got, ok = [f"≥ {100 * rate:g} %"], [format_rate(r["successes"], r["n"])], \
            r["rate"] >= rate
        if worst is not None:
            want.append(f"worst plant ≥ {worst}/65")
            got.append(f"worst plant {r['worst_plant_successes']}/65")
            ok = ok and (r["worst_plant_successes"] or 0) >= worst
        if ratio is not None:
            v = r["settle_ratio_median"]
            want.append(f"median settle / T\\* ≤ {ratio:g}")
            got.append("never" if v is None else f"settle / T\\* {v:.2f}")
            ok = ok and v is not None and v <= ratio
        return ok, ", ".join(want), ", ".join(got)

    body = []
    for kind, level, mode, rate, worst, ratio in FUZZY_TARGETS:
        cands = [r for (n, lv, m), r in rows.items() if lv == level and m == mode
                 and fuzzy_kinds.get(n) == kind]
        if not cands:
            continue
        judged = [(verdict(r, rate, worst, ratio), r) for r in cands]
        # the policy that meets it, else the one with the most successes
        (ok, want, got), r = max(judged, key=lambda j: (j[0][0], j[1]["successes"],
                                                        -(j[1]["settle_ratio_median"] or 1e9)))
        body.append((kind, level, mode, want, f"`{r['controller']}` {got}",
                     "met" if ok else "**missed**"))
    out += ["The best fuzzy policy of each kind for each target (one that meets it, if any "
            "does).\n\n",
            _table(("kind", "level", "mode", "target", "measured", ""), body), "\n\n"]
    # one design for every target of its kind: the recommended design
    one = []
    for kind in dict.fromkeys(t[0] for t in FUZZY_TARGETS):
        targets = [t for t in FUZZY_TARGETS if t[0] == kind]
        met = {}
        for name, k in fuzzy_kinds.items():
            if k != kind:
                continue
            met[name] = [t for t in targets if (name, t[1], t[2]) in rows
                         and verdict(rows[name, t[1], t[2]], *t[3:])[0]]
        if not met:
            continue
        full = sorted(n for n, m in met.items() if len(m) == len(targets))
        if full:
            one.append(f"- {kind}: {', '.join(f'`{n}`' for n in full)} meets all "
                       f"{len(targets)}.\n")
        else:
            best = max(sorted(met), key=lambda n: len(met[n]))
            missed = [f"`{t[1]}` {t[2]}" for t in targets if t not in met[best]]
            one.append(f"- {kind}: **none**; the closest, `{best}`, meets "
                       f"{len(met[best])} of {len(targets)} (misses {', '.join(missed)}).\n")
    out += ["One design that meets every target of its kind (the recommended design):\n\n",
            *one, "\n"]
    out.append("## Best of each kind\n\nPer level and mode, the controller of each kind "
               "ranked first by the [leaderboard's rule](leaderboard.md) (success, ties "
               "within overlapping 95 % intervals going to the shorter median settle / T\\*) "
               "and the best fuzzy policy of that kind by the same rule; *within* when the "
               "fuzzy policy's 95 % interval reaches the best one's rate.\n\n")
    body = []
    for level in report["levels"]:
        for mode in ("plain", "compensated"):
            for kind in ("centralized", "decentralized"):
                cands = [r for (n, lv, m), r in rows.items()
                         if lv == level and m == mode and kinds.get(n) == kind]
                if not cands:
                    continue
                best = ranked(cands)[0]
                fuzzy = [r for r in cands if r["controller"] in fuzzy_kinds]
                if not fuzzy:
                    continue
                f = ranked(fuzzy)[0]
                hi = wilson_interval(f["successes"], f["n"])[1]
                verdict = "best" if f is best else ("within" if hi >= best["rate"] - 1e-9 else
                                                    "below")
                body.append((level, mode, kind, f"`{best['controller']}` "
                             + format_rate(best["successes"], best["n"]),
                             f"`{f['controller']}` " + format_rate(f["successes"], f["n"]),
                             verdict))
    out += [_table(("level", "mode", "kind", "best", "best fuzzy", "fuzzy is"), body), "\n"]
    design = _load("renders/fuzzy_design/design.json", SCHEMAS["renders/fuzzy_design/design.json"])
    if design is not None:
        out.append("\n## The tuning table\n\n`python docs/studies/fuzzy_design.py --json "
                   "renders/fuzzy_design/design.json`: every lever on the tuning seeds "
                   f"{design['seeds']} ({design['poses']} poses at rest nominal; 32 of them "
                   "on 8 plants under medium and hard), k/n [95 % interval] and the median "
                   "settle time; settle / T\\*: median and worst over the 64 states of a "
                   "tuning grid at rest (`ratio_grid` of the study: the evaluation set's "
                   "8 x 8 grid at other angles, T\\* in "
                   "`renders/fuzzy_design/tuning_limits.json`), '-' where not measured.\n\n")
        cols = ("none", "medium", "medium compensated", "hard", "hard compensated")

        def fmt(c):
            lo, hi = wilson_interval(c["successes"], c["n"])
            settle = "never" if c["median_settle"] is None else f"{c['median_settle']:.2f} s"
            return f"{c['successes']}/{c['n']} [{100 * lo:.0f}, {100 * hi:.0f}], {settle}"
        def ratio(c):
            if c is None:
                return "-"
            med, worst = (("never" if v is None else f"{v:.2f}")
                          for v in (c["median"], c["worst"]))
            return f"{med}, {worst} ({c['successes']}/{c['n']})"
        out.append(_table(("variant", *cols, "settle / T\\*", "synthesis"),
                          [(_cell(r["variant"]), *[fmt(r[c]) for c in cols],
                            ratio(r.get("ratio")), f"{r['synthesis_seconds']:.1f} s")
                           for r in design["rows"]]))
        out.append("\n")
    out.append(_near_gain_block())
    return "".join(out)


def _near_gain_block() -> str:
    """The near-goal gain study (docs/studies/near_gain.py): per tried policy its plain
    read-out, the gain chosen and the registry name that ships it."""
    from twolink.policy.registry import SHIPPED

    data = _load(NEAR_GAIN, SCHEMAS[NEAR_GAIN])
    if data is None or not data["runs"]:
        return ""
    cols = ("none", "medium", "medium compensated", "hard", "hard compensated")
    grid = data["grid"]
    out = ["\n## The near-goal gain\n\n`python docs/studies/near_gain.py`: each design "
           "below with the read-out's near-goal gain (joint i's torque times g + (1 − g) "
           "min(|θ_i| / A, 1), `twolink.policy.readout`) at every A in "
           + ", ".join(f"{a:g}" for a in grid["angles_deg"]) + " degrees and g in "
           + ", ".join(f"{g:g}" for g in grid["gains"]) + ", on the tuning table's seeds "
           "and columns (successes). The gain chosen keeps every nominal pose and has the "
           "most successes summed over the four challenge columns (ties: the larger g, "
           "then the smaller A); a second choice has the most successes under `hard` with "
           "compensation alone. The `medium` column is nearly full for every gain, so for "
           "some designs `--medium-wide` measures `medium` without compensation again on "
           "all 48 poses and 32 plants of the tuning seeds (*medium, wide*, of 1536), and a "
           "third choice has the most successes there.\n\n"]
    body = []

    def wide(cells):
        return str(cells["medium_wide"]) if "medium_wide" in cells else ""
    for run in data["runs"]:
        base = SHIPPED[run["policy"]]
        body.append((f"`{run['policy']}`", "—", *[str(run["base"][c]) for c in cols],
                     f"{sum(run['base'][c] for c in cols[1:])}", wide(run["base"]), ""))
        for criterion, pick in run["chosen"].items():
            if pick is None:
                body.append(("", f"{criterion}: none keeps every nominal pose",
                             *[""] * 7, ""))
                continue
            row = next(r for r in run["rows"] if (r["angle_deg"], r["gain"])
                       == (pick["angle_deg"], pick["gain"]))
            ships = [n for n, e in SHIPPED.items() if e.near_gain == pick["gain"]
                     and e.near_deg == pick["angle_deg"]
                     and e.synthesis_options() | {"readout": None}
                     == base.synthesis_options() | {"readout": None}]
            body.append(("", f"{criterion}: A {pick['angle_deg']:g}°, g {pick['gain']:g}",
                         *[str(row["cells"][c]) for c in cols],
                         f"{sum(row['cells'][c] for c in cols[1:])}", wide(row["cells"]),
                         ", ".join(f"`{n}`" for n in ships) or "not shipped"))
    n = {"none": 48}
    parts = [(run["policy"], run["parts"]) for run in data["runs"] if "parts" in run]
    tail = ""
    if parts:
        rows = []
        for name, part in parts:
            for what, cells in part["runs"].items():
                rows.append((f"`{name}`", f"{what} alone",
                             f"{cells['plain read-out']}/256", f"{cells['with the gain']}/256",
                             f"{cells['pd_deadzone']}/256"))
        lifts = []
        for name, part in parts:
            gain = {k: c["with the gain"] - c["plain read-out"] for k, c in part["runs"].items()}
            top = max(gain, key=gain.get)
            lifts.append(f"`{name}` most under its {top} ({gain[top]:+d} of 256)")
        tail = ("\n\nWhich part of `hard` the gain answers (`--parts`: each design without and "
                "with its all-round gain, beside `pd_deadzone`, under each part of the level "
                "alone, on the tuning table's 32 poses and 8 plants, plain). The gain helps "
                + "; ".join(lifts) + ".\n\n"
                + _table(("design", "challenge", "plain read-out", "with the gain",
                          "`pd_deadzone`"), rows))
    out.append(_table(("design", "near-goal gain", *[f"{c} (/{n.get(c, 256)})" for c in cols],
                       "challenge sum", "medium, wide (/1536)", "shipped as"), body))
    return "".join(out) + tail + "\n"
