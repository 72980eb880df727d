"""The handover sections of docs/results/fuzzy-designs.md, from
``renders/fuzzy_design/handover.json`` (``docs/studies/handover.py``), the handover's rows
of the committed leaderboard, and ``renders/fuzzy_design/joint_handover.json``
(``docs/studies/joint_handover.py``, the decentralized handover joint by joint and on a
clock)."""
from __future__ import annotations

import itertools

from .common import SCHEMAS, _load, _table

HANDOVER = "renders/fuzzy_design/handover.json"
JOINT_HANDOVER = "renders/fuzzy_design/joint_handover.json"


def _region(r: dict) -> str:
    return (f"in {r['enter_deg']:g} deg, {r['enter_speed']:g} rad/s; out {r['exit_deg']:g} "
            f"deg, {r['exit_speed']:g} rad/s")


def _rescue(r: dict) -> str:
    if r.get("rescue_deg") is None:
        return "none"
    return f"within {r['rescue_deg']:g} deg for {r['rescue_s']:g} s"


def _cells(c: dict) -> tuple:
    ratio = "never" if c["ratio_median"] is None else f"{c['ratio_median']:.2f}"
    return (f"{c['none']}/{c['n_none']}", ratio, f"{c['medium']}/{c['n_challenge']}",
            f"{c['hard compensated']}/{c['n_challenge']}")


def handover_block(report: dict) -> str:
    """The study's table, its pick on the wider tuning-side set, and the shipped
    handover's leaderboard rows (empty when the study's data are not committed)."""
    from twolink.viz.formatting import format_rate

    data = _load(HANDOVER, SCHEMAS[HANDOVER])
    if data is None:
        return ""
    out = ["\n## The handover\n\n`python docs/studies/handover.py`: "
           f"`{data['approach']}` until the arm enters a region around the goal, then a "
           "robust design until it leaves a wider one (`twolink.control.handover`), "
           "measured on the tuning seeds as the tuning table is. The pick meets the "
           "nominal, speed and `medium` targets on these cells with the most `hard` "
           "compensated successes.\n\n"]
    rows = [(f"`{data['approach']}` alone", "", *_cells(data["approach_alone"]))]
    rows += [(f"`{r['hold']}`", _region(r["regions"]), *_cells(r["cells"]))
             for r in data["rows"]]
    out.append(_table(("hold design", "regions", "nominal", "settle / T*", "medium plain",
                       "hard compensated"), rows))
    pick, final = data.get("pick"), data.get("final")
    if pick and data.get("rescues"):
        a = data["wide_approach_alone"] if final else None
        out.append(f"\n\nThe pick, `{pick['hold']}` ({_region(pick['regions'])}), with "
                   "each rescue (every joint within a region around the goal for a dwell "
                   "without the hold acting: the hold design acts until the arm enters "
                   "the band; it catches limit cycles around the band), on the same cells "
                   "and on the 65 evaluation states x 32 plants of the tuning plant seed "
                   "(*wide*):\n\n")
        out.append(_table(
            ("rescue", "nominal", "settle / T*", "medium plain", "hard compensated",
             "wide medium plain", "wide hard compensated"),
            [(_rescue(r["regions"]), *_cells(r["cells"]),
              format_rate(r["wide"]["medium"], r["wide"]["n"]),
              format_rate(r["wide"]["hard compensated"], r["wide"]["n"]))
             for r in data["rescues"]]))
        if final:
            out.append(f"\n\n`{data['approach']}` alone on the wide set: `medium` plain "
                       f"{format_rate(a['medium'], a['n'])}, `hard` compensated "
                       f"{format_rate(a['hard compensated'], a['n'])}. The final pick (the "
                       "most wide successes among the rescues that meet the targets on "
                       f"the cells), rescue {_rescue(final['regions'])}, is the "
                       "catalogue's `centralized_handover`.")
    mine = {(r["level"], r["mode"]): r for r in report["rows"]
            if r["controller"] == "centralized_handover"}
    if mine:
        cells = []
        for level, mode in (("none", "plain"), ("medium", "plain"), ("medium", "compensated"),
                            ("hard", "plain"), ("hard", "compensated")):
            r = mine.get((level, mode))
            if r is not None:
                ratio = r.get("settle_ratio_median")
                cells.append((f"`{level}`", mode, format_rate(r["successes"], r["n"]),
                              "never" if ratio is None else f"{ratio:.2f}"))
        out.append(f"\n\nOn the leaderboard (seed {report['seed']}, never used in tuning):\n\n")
        out.append(_table(("level", "mode", "successes", "settle / T*"), cells))
    return "".join(out) + "\n"


def _switch(s: dict) -> str:
    band = "goal band or " if s["band"] else ""
    return (f"{band}within {s['rescue_deg']:g} deg for {s['rescue_s']:g} s; out "
            f"{s['exit_deg']:g} deg")


def _hold(row: dict) -> str:
    """A clock row's hold design in words: its name, or its table and fading read-out."""
    r = row.get("readout")
    if r is None:
        return f"`{row['hold']}`"
    return (f"`{row['hold']}`'s table through a {r['speed_dead_zone']:g} rad/s speed dead "
            f"zone and a near-goal gain of {r['near_gain']:g} from {r['near_deg']:g} deg")


def joint_handover_block() -> str:
    """The decentralized handover's table (empty when its data are not committed)."""
    data = _load(JOINT_HANDOVER, SCHEMAS[JOINT_HANDOVER])
    if data is None:
        return ""
    ratio, medium, hard = data["targets"]
    out = ["\n## A handover joint by joint (decentralized)\n\n"
           "`python docs/studies/joint_handover.py`: each joint's torque from "
           f"`{data['approach']}` until that joint's own reading switches it to a robust "
           "decentralized design, so each agent keeps to its own information; on the "
           f"tuning cells. The decentralized targets: nominal 48/48, settle / T* <= "
           f"{ratio:g}, `medium` plain >= {100 * medium:g} %, `hard` compensated >= "
           f"{100 * hard:g} %. **{data['meeting']} of {len(data['rows'])} handovers meet "
           "them.**\n\n"]
    rows = [(f"`{data['approach']}` alone", "", *_cells(data["approach_alone"]))]
    rows += [(f"`{r['hold']}`", _switch(r["switch"]), *_cells(r["cells"]))
             for r in data["rows"]]
    out.append(_table(("hold design", "switch", "nominal", "settle / T*", "medium plain",
                       "hard compensated"), rows))
    clock = data["clock_rows"]
    out.append("\n\nThe same hold designs **on a clock** (`twolink.control.handover."
               f"TimedHandover`): `{data['approach']}` for the first seconds of the "
               "rollout, the hold design from then on. The switch reads no state, so "
               "every agent switches its own joint at the same instant without a message. "
               "A row fast enough on the cells is also measured on the wider tuning-side "
               "set (*wide*: the 65 evaluation states on 32 plants of the tuning plant "
               "seed). "
               f"**{sum(r['meets'] for r in clock)} of {len(clock)} meet every target** "
               "(nominal and speed on the cells, `medium` plain and `hard` compensated on "
               "the wide set).\n\n")

    def wide(r, key):
        from twolink.viz.formatting import format_rate
        w = r["wide"]
        return "–" if w is None else format_rate(w[key], w["n"])

    out.append(_table(("hold design", "switch after", "nominal", "settle / T*",
                       "medium plain", "hard compensated", "wide medium plain",
                       "wide hard compensated", "meets"),
                      [(f"`{r['hold']}`", f"{r['after_s']:g} s", *_cells(r["cells"]),
                        wide(r, "medium"), wide(r, "hard compensated"),
                        "yes" if r["meets"] else "no") for r in clock]))
    fades = data.get("fade_rows") or []
    if fades:
        out.append(
            "\n\nLast, **a fading gain on the approach's own table**: at the switch time "
            f"of the best row above ({data['best_clock']['after_s']:g} s), the hold design "
            f"is `{data['approach']}`'s Q-tables read through a speed dead zone and a "
            "near-goal gain (joint i's torque falls from full at the angle given to the "
            "gain times (14)'s at the goal), so the arm keeps the approach's table and "
            "only its torque near the goal fades once the clock has run. "
            f"**{sum(r['meets'] for r in fades)} of {len(fades)} meet every "
            "target.**\n\n")
        out.append(_table(("speed dead zone", "near-goal gain", "full from", "nominal",
                           "settle / T*", "medium plain", "hard compensated",
                           "wide medium plain", "wide hard compensated", "meets"),
                          [(f"{r['readout']['speed_dead_zone']:g} rad/s",
                            f"{r['readout']['near_gain']:g}",
                            f"{r['readout']['near_deg']:g} deg", *_cells(r["cells"]),
                            wide(r, "medium"), wide(r, "hard compensated"),
                            "yes" if r["meets"] else "no") for r in fades]))
    chosen = data["pick"]
    if chosen is None:
        out.append("\n\nNo handover on a clock is fast enough on the cells and meets the "
                   "`hard` compensated target on the wide set.")
    else:
        verdict = ("It meets every decentralized target on the tuning side." if
                   data["pick_meets"] else "It is the closest: no row meets every target "
                   f"(its wide `medium` plain, {wide(chosen, 'medium')}, misses "
                   f"{100 * medium:g} %).")
        out.append("\n\nThe pick, by the study's rule (among the rows fast enough on the "
                   "cells whose wide `hard` compensated meets its target, the most wide "
                   "`medium` plain successes, then `hard` compensated, then speed, then the "
                   f"earliest switch) over both tables: {_hold(chosen)} after "
                   f"{chosen['after_s']:g} s, the catalogue's `decentralized_handover`. "
                   f"{verdict}")
    return "".join(out) + "\n"


#: The handovers' scores on plants of seeds no tuning used, ``twolink evaluate NAME
#: --challenge L [--compensate] --plants 64 --seed S --json`` committed as
#: ``renders/fuzzy_design/NAME.freshS.L[.compensated].json`` (31415 for every handover,
#: 27183 for ``decentralized_handover`` too).
FRESH = "renders/fuzzy_design/{name}.fresh{seed}.{level}{suffix}.json"
FRESH_SEEDS = (31415, 27183)


def handovers_fresh_table() -> str:
    """Each shipped handover's committed fresh-plant scores beside the targets of its kind
    (:data:`targets.FUZZY_TARGETS`) on the perturbed levels; empty when none is
    committed."""
    import json

    from twolink.control.handover import HANDOVERS
    from twolink.viz.formatting import format_rate

    from .common import ROOT
    from .targets import FUZZY_TARGETS

    rows = []
    for name, h in HANDOVERS.items():
        for (kind, level, mode, rate, worst, _), seed in itertools.product(FUZZY_TARGETS,
                                                                           FRESH_SEEDS):
            if kind != h.kind or level == "none":
                continue
            path = ROOT / FRESH.format(name=name, seed=seed, level=level,
                                      suffix=".compensated" if mode == "compensated" else "")
            if not path.is_file():
                continue
            r = json.loads(path.read_text())
            met = r["rate"] >= rate and (worst is None or r["worst_plant_successes"] >= worst)
            target = f"≥ {100 * rate:g} %" + (f", worst plant ≥ {worst}/65" if worst else "")
            rows.append((f"`{name}`", f"`{level}`", mode, str(seed),
                         format_rate(r["successes"], r["n"]),
                         f"{r['worst_plant_successes']}/{r['states']}", target,
                         "met" if met else "**missed**"))
    if not rows:
        return ""
    return _table(("handover", "level", "mode", "plant seed", "successes (64 plants)",
                   "worst plant", "target", ""), rows)
