"""The own-motor section of docs/results/scaling.md, from ``renders/links_reach/own_motor.json``
(``docs/studies/links_own_motor.py``): each controller's successes by the poses' own-motor
time at the table's 8 s, and at longer horizons, which tell a pose failed from a pose
settled late.
"""
from __future__ import annotations

from .common import SCHEMAS, _load
from .results_swing_returns import swing_returns_block

#: The own-motor study's data (``docs/studies/links_own_motor.py``).
OWN_MOTOR = "renders/links_reach/own_motor.json"
#: Own-motor time classes of the poses, in seconds (the last bound is the deadline, 7 s).
OWN_MOTOR_EDGES = (3.0, 5.0, 7.0)
#: The own-motor study's controllers, by scaling row name, and their column titles; the
#: catalogue's learned agents a run records follow under their own names.
OWN_MOTOR_COLUMNS = (("decentralized", "decentralized"), ("decentralized_levels", "5 levels"),
                     ("decentralized_argmax", "5 levels, argmax"), ("pd", "per-joint PD"))


def _columns(data: dict) -> list:
    """(key, title) of every controller some run records: the table's four (those every
    run has), then each learned agent once, in the order the runs name them."""
    cols = [c for c in OWN_MOTOR_COLUMNS if all(c[0] in r["success"] for r in data["runs"])]
    for run in data["runs"]:
        cols += [(n, f"`{n}`") for n in run.get("learned", ()) if (n, f"`{n}`") not in cols]
    return cols


def own_motor_block(report: dict) -> str:
    """The own-motor study: each controller's successes by the poses' own-motor time,
    the poses over the deadline named with the reach study's answers for them, then the
    same poses at the longer horizons (:func:`_later_block`)."""
    import numpy as np

    from twolink.arm.task import own_motor_speed
    from twolink.arm.parameters import links_parameters
    from twolink.viz.formatting import format_rate

    from .results_scaling import REACH

    data = _load(OWN_MOTOR, SCHEMAS[OWN_MOTOR])
    if data is None or not data["runs"]:
        return ""
    reach = _load(REACH, SCHEMAS[REACH]) or {"runs": []}
    reached = {(r["links"], r["rule"]): r for r in reach["runs"]}
    rows = {(r["scheme"], r["rule"], r["links"]): r for r in report["rows"]}
    columns = _columns(data)
    fuzzy = [c for c in columns if c in OWN_MOTOR_COLUMNS]
    edges = (0.0,) + OWN_MOTOR_EDGES + (np.inf,)
    deadline = OWN_MOTOR_EDGES[-1]
    names = ([f"≤ {edges[1]:g} s"]
             + [f"{a:g}–{b:g} s" for a, b in zip(edges[1:-2], edges[2:-1])]
             + [f"> {deadline:g} s"])
    out = ["## What a joint's own motor can do\n\n",
           "With every other joint held, joint i turns about a fixed axis and its motion "
           "reduces to J_i θ̈_i = τ_i − b_i θ̇_i, so from rest it never turns faster than "
           "τ_i max / b_i (`twolink.arm.task.own_motor_speed`). Tapered links halve the "
           "torque per link and keep link 2's damping: "
           + "; ".join(f"at N = {n} joint {n} turns at most "
                       f"{own_motor_speed(links_parameters(n, 'tapered'))[-1]:.3g} rad/s"
                       for n in sorted({r["links"] for r in data["runs"]
                                        if r["rule"] == "tapered"}))
           + ". A pose's *own-motor time* is the largest over its joints of |θ_i| over that "
           "speed (`own_motor_seconds`), a lower bound on the time its slowest joint needs "
           f"on its own. Above {deadline:g} s (settled 1 s before the end of 8 s) a pose can "
           "succeed only if the other joints' motion turns that joint too. "
           "`python docs/studies/links_own_motor.py --links N --rule R [--agent FILE ...]` "
           "runs the table's controllers, the catalogue's learned agents of the arm and the "
           "saved agents it is given (named by their file, e.g. the final agents of runs of "
           "`twolink learners`) again on the table's poses and records each pose's success "
           "beside its own-motor time (— : the controller was not run on that arm):\n\n",
           "| N | links | own-motor time | poses | "
           + " | ".join(t for _, t in columns) + " |\n|---|---|---|---|"
           + "---|" * len(columns) + "\n"]
    notes = []
    for run in data["runs"]:
        n, rule = run["links"], run["rule"]
        own = np.asarray(run["own_motor_s"])
        cls = np.digitize(own, edges[1:-1], right=True)
        for c, name in enumerate(names):
            m = cls == c
            if not m.any():
                continue
            cells = [format_rate(int(np.asarray(run["success"][k])[m].sum()), int(m.sum()))
                     if k in run["success"] else "—" for k, _ in columns]
            out.append(f"| {n} | {rule} | {name} | {int(m.sum())} | " + " | ".join(cells)
                       + " |\n")
        late = own > deadline
        slow = np.asarray(run["slowest_joint"])[late]
        ran = [(k, t) for k, t in columns if k in run["success"]]
        line = (f"{rule} N = {n}: {int(late.sum())} of {run['poses']} poses are over "
                f"{deadline:g} s")
        if late.any():
            joints = sorted(set(slow.tolist()))
            line += (" (set by joint " + " or ".join(map(str, joints)) + "); the controllers "
                     "settle " + ", ".join(
                         f"{int(np.asarray(run['success'][k])[late].sum())}" for k, _ in
                         ran) + " of them (" + ", ".join(t for _, t in ran) + ")")
            r = reached.get((n, rule))
            if r:
                k = r["poses"]
                hit = late[:k]
                ok = sum(a["reachable"] for a, h in zip(r["answers"], hit) if h)
                line += (f"; of the first {k}, which the reach study solved, {int(hit.sum())} "
                         f"are over {deadline:g} s and {ok} of those are reachable")
        same = all(
            (key := (scheme, rule, n)) in rows and rows[key]["status"] == "run"
            and rows[key]["evaluation"]["horizons"]["8"]["successes"]
            == sum(run["success"][scheme]) and run["poses"] == rows[key]["evaluation"]["poses"]
            for scheme, _ in fuzzy)
        notes.append(line + (" (the table's controllers' totals equal its rows)" if same else
                             " (the table's controllers' totals differ from its rows)") + ".")
    out.append("\n" + "\n".join(f"- {t}" for t in notes) + "\n\n")
    return ("".join(out) + _later_block(data, columns, deadline)
            + _swing_block(data, columns, deadline) + swing_returns_block())


def _later_block(data: dict, columns: list, deadline: float) -> str:
    """Each controller's successes on every pose and on the poses over the deadline at
    8 s and at the study's longer horizons: a pose failed at 8 s but settled by 12 s or
    16 s was slow, not lost."""
    import numpy as np

    from twolink.viz.formatting import format_rate

    runs = [r for r in data["runs"] if r.get("later")]
    if not runs:
        return ""
    horizons = sorted({h for r in runs for h in r["later"]}, key=float)
    heads = ["8 s"] + [f"{h} s" for h in horizons]
    out = ["### Failed, or settled late?\n\n",
           "The same rollouts run on to " + f"{horizons[-1]} s" + " and cut at each horizon "
           "(success: settled 1 s before the cut, as at 8 s). All poses, then the poses whose "
           f"own-motor time is over {deadline:g} s (— : none is):\n\n",
           "| N | links | controller | " + " | ".join(f"all, {h}" for h in heads) + " | "
           + " | ".join(f"over {deadline:g} s, {h}" for h in heads) + " |\n|---|---|---|"
           + "---|" * (2 * len(heads)) + "\n"]
    for run in runs:
        late = np.asarray(run["own_motor_s"]) > deadline
        for key, title in columns:
            if key not in run["success"]:
                continue
            oks = [np.asarray(run["success"][key])] + [np.asarray(run["later"][h][key])
                                                        for h in horizons]
            cells = ([format_rate(int(ok.sum()), ok.size) for ok in oks]
                     + [f"{int(ok[late].sum())}/{int(late.sum())}" if late.any() else "—"
                        for ok in oks])
            out.append(f"| {run['links']} | {run['rule']} | {title} | " + " | ".join(cells)
                       + " |\n")
    notes = [_learned_note(run, name, horizons, deadline) for run in runs
             for name in run.get("learned", ())]
    return "".join(out) + "\n" + "".join(f"- {n}\n" for n in notes) + ("\n" if notes else "")


def _learned_note(run: dict, name: str, horizons: list, deadline: float) -> str:
    """What a learned agent's rows say: its successes by 8 s within and beyond the own
    motors' reach, and by the longest horizon on all poses."""
    import numpy as np

    late = np.asarray(run["own_motor_s"]) > deadline
    ok8 = np.asarray(run["success"][name])
    last = np.asarray(run["later"][horizons[-1]][name])
    text = (f"`{name}` ({run['rule']} N = {run['links']}) settles {int(ok8[~late].sum())} of "
            f"the {int((~late).sum())} poses whose own-motor time is at most {deadline:g} s "
            f"by 8 s, and {int(ok8[late].sum())} of the {int(late.sum())} beyond it; by "
            f"{horizons[-1]} s it settles {int(last.sum())} of {last.size}.")
    if last.all() and ok8[~late].mean() >= 0.95:
        text += (" What it misses at 8 s it settles later: its shortfall is speed on the "
                 "poses whose slowest joint must be turned by the others, not poses it "
                 "cannot bring home.")
    return text


def _demo_swings(links: int, rule: str, horizon_s: float = 8.0):
    """:func:`twolink.arm.task.inner_excursion` of every time-optimal answer of the
    demonstration set (:data:`twolink.studies.guided.demos.DEMOS`) for this arm over its
    first ``horizon_s`` seconds (None where there are none)."""
    import numpy as np

    from twolink.arm.parameters import TS
    from twolink.arm.task import inner_excursion
    from twolink.studies.guided.demos import DEMOS, load

    from .common import ROOT

    folder = ROOT / DEMOS
    demos = [d for d in (load(folder) if folder.is_dir() else [])
             if (d["links"], d["rule"]) == (links, rule)]
    if not demos:
        return None
    k = int(round(horizon_s / TS))
    return np.array([float(inner_excursion(np.asarray(d["states"])[:k + 1, :links]))
                     for d in demos])


def _swing_block(data: dict, columns: list, deadline: float) -> str:
    """On the poses over the deadline: each controller's successes by 8 s beside how far
    its inner joints swing away from the goal within 8 s, and the same swing of the
    time-optimal answers, which turn the outer joint by the inner ones' reactions."""
    import numpy as np

    runs = [r for r in data["runs"] if r.get("excursion")
            and (np.asarray(r["own_motor_s"]) > deadline).any()]
    if not runs:
        return ""
    from twolink.studies.guided.demos import DEMOS

    out = ["### Do they swing the inner joints?\n\n",
           "On the poses whose own-motor time is over " f"{deadline:g} s: how far the inner "
           "joints (1 to N − 1) swing away from the goal within 8 s, the largest over "
           "them of |θ_i(t)| − |θ_i(0)| (`twolink.arm.task.inner_excursion`, 0 for a "
           "controller that only drives each joint home), as median and 90th percentile "
           "over the poses. The time-optimal answers are the reach study's solver's "
           "answers replayed on MuJoCo for other poses beyond the own motors' reach (the "
           f"demonstrations of `docs/studies/links_guided.py`, `{DEMOS}`):\n\n",
           "| N | links | controller | settled by 8 s | swing, median | swing, 90th "
           "percentile |\n|---|---|---|---|---|---|\n"]
    for run in runs:
        late = np.asarray(run["own_motor_s"]) > deadline
        for key, title in columns:
            if key not in run["excursion"]:
                continue
            swing = np.asarray(run["excursion"][key])[late]
            ok = int(np.asarray(run["success"][key])[late].sum())
            out.append(f"| {run['links']} | {run['rule']} | {title} | {ok}/{int(late.sum())} "
                       f"| {np.median(swing):.2f} rad | {np.percentile(swing, 90):.2f} rad |\n")
        optimal = _demo_swings(run["links"], run["rule"])
        if optimal is not None:
            out.append(f"| {run['links']} | {run['rule']} | time-optimal answers "
                       f"({optimal.size} poses) | {optimal.size}/{optimal.size} (replayed) | "
                       f"{np.median(optimal):.2f} rad | {np.percentile(optimal, 90):.2f} rad "
                       "|\n")
    return "".join(out) + "\n"
