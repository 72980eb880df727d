"""The handover sections of docs/results/fuzzy-designs.md, from
``renders/fuzzy_design/handover.json`` (``docs/studies/handover.py``), the handover's rows
of the committed leaderboard, and ``renders/fuzzy_design/joint_handover.json``
(``docs/studies/joint_handover.py``, the decentralized handover joint by joint)."""
from __future__ import annotations

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
    return "".join(out) + "\n"
