"""The scaling table presented: Markdown and a log-scale figure from the report of
:func:`twolink.studies.scaling.measure.scaling` (its :meth:`~twolink.studies.scaling.measure.Scaling.report`, or the
``scaling.json`` written beside them). Presentation only: nothing is measured here."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from twolink.artifacts import atomic_path, staged_set, write_json, write_text  # noqa: E402
from twolink.studies.scaling.measure import (  # noqa: E402
    ALL_SCHEMES,
    LEVER_ARGMAX_DEG,
    LEVER_LEVELS,
)
from twolink.viz.formatting import format_rate  # noqa: E402

#: The files :func:`write` writes into its folder.
FILES = {"markdown": "scaling.md", "figure": "scaling.png", "json": "scaling.json"}
_COLORS = {"centralized": "C0", "decentralized": "C1", "decentralized_levels": "C2",
           "decentralized_argmax": "C4", "pd": "C3"}
#: How the table names each row kind.
LABELS = {"centralized": "centralized", "decentralized": "decentralized",
          "decentralized_levels": f"decentralized, {LEVER_LEVELS} levels",
          "decentralized_argmax": f"decentralized, {LEVER_LEVELS} levels, argmax beyond "
                                  f"{LEVER_ARGMAX_DEG:g}°",
          "pd": "per-joint PD"}
_RULE_STYLES = {"Table I": "-", "tapered": "-", "copied": "--"}


def count(n) -> str:
    """A whole number with groups of three, 16 003 008; from 10^12 on as 1.05e+18."""
    return f"{int(n):,}".replace(",", " ") if n < 1e12 else f"{n:.3g}"


def size(b) -> str:
    """Bytes as KiB, MiB or GiB."""
    for unit, scale in (("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if b >= scale:
            return f"{b / scale:.3g} {unit}" if b < 100 * scale else f"{b / scale:.0f} {unit}"
    return f"{int(b)} B"


def seconds(s) -> str:
    return f"{s:.3g} s" if s < 100 else f"{s:.0f} s"


def _rows(report: dict, rule: str) -> list:
    """The rows of one rule's table: the two-link rows (Table I) first, then the rule's."""
    return [r for r in report["rows"] if r["rule"] in ("Table I", rule)]


def _success(row: dict, h: float) -> str:
    ev = row.get("evaluation")
    cell = (ev or {}).get("horizons", {}).get(f"{h:g}")
    return format_rate(cell["successes"], cell["n"]) if cell else "—"


def _settle(row: dict) -> str:
    ev = row.get("evaluation")
    if not ev:
        return "—"
    cell = ev["horizons"][max(ev["horizons"], key=float)]
    return "never (most)" if cell["median_settle"] is None else f"{cell['median_settle']:.2f} s"


def _line(row: dict, short: float, long: float) -> list:
    s, est = row.get("synthesis"), row.get("estimate") or {}
    n, scheme = row["links"], LABELS.get(row["scheme"], row["scheme"])
    if row["scheme"] == "pd":
        q = nnz = peak = time = sweeps = "—"
    elif s:
        q, nnz = count(s["q_values"]), count(s["nnz"])
        peak = size(s["peak_bytes"])
        if est.get("peak_bytes"):
            peak += f" (est. {size(est['peak_bytes'])})"
        time = f"{seconds(s['wall_seconds'])} / {seconds(s['cpu_seconds'])}"
        sweeps = " / ".join(str(a["sweeps"]) for a in s["agents"])
    else:
        q = count(est["q_values"]) if "q_values" in est else "—"
        nnz = f"≈ {count(est['nnz'])} (est.)" if "nnz" in est else "—"
        peak, time, sweeps = row.get("note") or row["status"], "—", "—"
    return [str(n), scheme, q, nnz, peak, time, sweeps, _success(row, short),
            _success(row, long) if n > 2 else "—", _settle(row)]


def _table(header: list, rows: list) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(out)


def tables(report: dict) -> str:
    """One Markdown table per link rule (the two-link rows are Table I's, in each)."""
    o = report["options"]
    short, long = o["horizon_short"], o["horizon_long"]
    header = ["N", "scheme", "Q-values", "nnz(T)", "peak memory", "synthesis wall / CPU",
              "sweeps (agent N…1)", f"success at {short:g} s", f"success at {long:g} s",
              "median settle"]
    parts = []
    for rule in o["rules"]:
        parts.append(f"### {rule} links\n\n"
                     + _table(header, [_line(r, short, long) for r in _rows(report, rule)]))
    return "\n\n".join(parts)


def _shipped(report: dict) -> list:
    """A bullet on the rows that rebuild a shipped policy: equal to its file or not."""
    got = {r["synthesis"]["shipped_policy"]: r["synthesis"]["matches_shipped_policy"]
           for r in report["rows"] if (r.get("synthesis") or {}).get("shipped_policy")}
    if not got:
        return []
    same = [f"`{n}`" for n, ok in got.items() if ok]
    other = [f"`{n}`" for n, ok in got.items() if not ok]
    return ["- **Shipped policies**: "
            + (f"the rows of {', '.join(same)} equal the committed files bit for bit"
               if same else "")
            + ("; " if same and other else "")
            + (f"the rows of {', '.join(other)} do **not** equal the committed files "
               f"(or the files are missing)" if other else "") + "."]


def _constructions(report: dict) -> list:
    """A bullet naming how the decentralized agents of N >= 3 links were built, per rule."""
    how = {}
    for r in report["rows"]:
        s = r.get("synthesis")
        if r["scheme"] == "decentralized" and r["links"] > 2 and s:
            how.setdefault(r["rule"], s["construction"])
    if not how:
        return []
    out = ["- **Decentralized agents, N ≥ 3**: "
           + "; ".join(f"{rule} links: {text}" for rule, text in how.items()) + "."]
    if any(r["scheme"] == "decentralized_levels" for r in report["rows"]):
        out.append(f"- **Decentralized, {LEVER_LEVELS} levels**: the same agents with "
                   f"{LEVER_LEVELS} torque levels per joint instead of three (the "
                   "`levels` option of `synthesize_links`).")
    if any(r["scheme"] == "decentralized_argmax" for r in report["rows"]):
        out.append(f"- **Decentralized, {LEVER_LEVELS} levels, argmax beyond "
                   f"{LEVER_ARGMAX_DEG:g}°**: the {LEVER_LEVELS}-level agents read "
                   f"through the argmax of Q wherever an agent reads an angle beyond "
                   f"{LEVER_ARGMAX_DEG:g}° (the `readout` option of `synthesize_links`, "
                   "`twolink.policy.readout`), chosen on the tapered five-link arm's "
                   "development poses (`twolink.studies.scaling.synthesis.LEVER_ARGMAX_DEG`)."
                   " Near ±180° neighbouring bins turn a joint opposite ways and (14) "
                   "averages their torques to almost none.")
    pd = [f"N = {r['links']} {r['rule']}: {r['note'].split(': ', 1)[-1]}"
          for r in report["rows"] if r["scheme"] == "pd" and r.get("note")]
    if pd:
        out.append("- **Per-joint PD** (`twolink.control.links_pd`, a saturated "
                   "PD per joint seeing only its own angle and speed; no synthesis): "
                   + "; ".join(pd) + ".")
    return out


def _load(o: dict) -> str:
    load = o.get("load_average")
    if not load:
        return ""
    return (f", shared: load average {load['before'][0]:.1f} (1 min) before the run, "
            f"{load['after'][0]:.1f} after")


def markdown(report: dict, command: str, figure: str = FILES["figure"]) -> str:
    """The report as Markdown: what was measured and how, and the tables."""
    o = report["options"]
    prov = report["provenance"]
    method = {"process": "measured in a fresh process per synthesis: the growth of its "
                         "peak resident set (VmHWM, reset through /proc/self/clear_refs "
                         "after `malloc_trim`) over its resident set just before the "
                         "synthesis, after the imports and a warm-up two-link "
                         "decentralized synthesis that loads the compiled kernels",
              "tracemalloc": "tracemalloc's peak during the synthesis (numpy arrays and "
                             "Python objects; numba's own allocations are not seen)"}
    lines = [
        "# Scaling: Table II extended to N links", "",
        f"Generated by `{command}`. For N = 2…{max(o['links'])} links "
        f"({', '.join(o['rules'])} links beyond Table I's two) and both schemes: the "
        "centralized policy (16) and one decentralized agent per joint (18).", "",
        "- **Q-values, nnz(T)**: the sizes of Alg. 1's Q-tables and transition tables, "
        "summed over the agents. Centralized rows not run show the estimate "
        "(`twolink.synthesis.links_centralized.estimate`), made before any work.",
        f"- **Peak memory**: {method[o['peak_method']]}; beside it the estimate made "
        "before the work (decentralized: the largest agent's transitions).",
        "- **Synthesis**: wall and CPU seconds of the whole synthesis call (model "
        "transitions, T and the sweeps), in that process; sweeps of Alg. 1 per agent, "
        "agent N first.",
        f"- **Success** on MuJoCo from {o['poses']} random poses at rest "
        f"(`metrics.random_poses(N, {o['poses']}, {o['seed']} + N)`), with counts and "
        f"95 % Wilson intervals: settled (every link within 5° and 0.1 rad/s) at least "
        f"1 s before the end. The horizon is {o['horizon_short']:g} s for N = 2 (the "
        f"paper's) and {o['horizon_long']:g} s for N ≥ 3 (a tapered link has half the "
        "torque of the link before it; copied links make the inner motors turn heavier "
        f"outer links); the {o['horizon_short']:g} s success is the first seconds of the same "
        "runs. Median settle time over all poses at the "
        "row's horizon (\"never\" when more than half never settle).",
        f"- **Centralized cap**: {size(o['max_bytes'])} of estimated peak "
        f"(this machine: {size(o['machine_bytes'])}); above it a row is refused with "
        "its estimate." + (" Quick run: centralized N ≥ 3 is not synthesised."
                           if o["quick"] else ""),
        "- **N = 2** rows are the registry's `centralized_full` and `decentralized_full` "
        "(synthesised on the full model (6), measured once: Table I whatever the rule); "
        "the paper's own Table II figures for the simplified model (11) are in "
        "`twolink reproduce`.",
        *_shipped(report),
        *_constructions(report), "",
        tables(report), "",
        f"![scaling]({figure})", "",
        *([f"Quick run ({o['poses']} poses): indicative only.", ""] if o["quick"] else []),
        f"Machine: {prov.get('cpu_count')} CPUs ({prov.get('processor') or prov['machine']}), "
        f"{size(o['machine_bytes'])}{_load(o)}; twolink {prov['twolink_version']}, MuJoCo "
        f"{prov['mujoco_version']}, numpy {prov['numpy_version']}, Python {prov['python']}.",
        ""]
    return "\n".join(lines)


def _series(report: dict, rule: str, scheme: str, pick) -> tuple:
    """(N, value, measured?) of one rule and scheme; ``pick(row)`` gives (value, measured)
    or None."""
    pts = [(r["links"],) + got for r in _rows(report, rule)
           if r["scheme"] == scheme and (got := pick(r)) is not None]
    return tuple(np.array(v) for v in zip(*pts)) if pts else (np.array([]),) * 3


def _q(row):
    s, e = row.get("synthesis"), row.get("estimate") or {}
    return (s["q_values"], True) if s else ((e["q_values"], False) if "q_values" in e else None)


def _nnz(row):
    s, e = row.get("synthesis"), row.get("estimate") or {}
    return (s["nnz"], True) if s else ((e["nnz"], False) if "nnz" in e else None)


def _mem(row):
    s, e = row.get("synthesis"), row.get("estimate") or {}
    return (max(s["peak_bytes"], 1), True) if s else \
        ((e["peak_bytes"], False) if "peak_bytes" in e else None)


def _plot_log(ax, report, rule, scheme, pick, marker, label):
    n, v, measured = _series(report, rule, scheme, pick)
    if not len(n):
        return
    c, ls = _COLORS[scheme], _RULE_STYLES[rule]
    ax.plot(n, v, ls, color=c, lw=1.0, alpha=0.6)
    m = measured.astype(bool)
    ax.plot(n[m], v[m], marker, color=c, ls="none", label=f"{label}, {scheme}")
    if (~m).any():
        ax.plot(n[~m], v[~m], marker, mfc="none", color=c, ls="none", ms=9)


def figure(report: dict, path) -> Path:
    """Three panels against N: Q-values and nnz(T), peak memory (hollow: the estimate of
    a centralized problem not run, with the cap), success at the long horizon with its
    95 % Wilson interval (dotted: at 5 s). Sizes and memory are drawn for the first rule."""
    o = report["options"]
    rule0 = o["rules"][0]
    fig, (a, b, c) = plt.subplots(1, 3, figsize=(15, 4.6))
    for scheme in ("centralized", "decentralized"):
        _plot_log(a, report, rule0, scheme, _q, "o", "Q-values")
        _plot_log(a, report, rule0, scheme, _nnz, "s", "nnz(T)")
        _plot_log(b, report, rule0, scheme, _mem, "^", "peak memory")
    b.axhline(o["max_bytes"], color="grey", ls=":", lw=1)
    b.text(min(o["links"]), o["max_bytes"] * 0.6, f"cap {size(o['max_bytes'])}", fontsize=8,
           color="grey", va="top")
    for ax, title, unit in ((a, "table sizes", "count"), (b, "peak memory", "bytes")):
        ax.set_yscale("log")
        ax.set_title(f"{title} ({rule0} links; hollow: estimate, not run)", fontsize=9)
        ax.set_ylabel(unit)
        ax.legend(fontsize=7)
    markers = ("o", "s", "D")
    for ri, rule in enumerate(o["rules"]):
        for si, scheme in enumerate(s for s in ALL_SCHEMES
                                    if any(r["scheme"] == s for r in report["rows"])):
            shift = 0.05 * (si - 1) + 0.025 * ri
            for long, style in ((True, _RULE_STYLES[rule]), (False, ":")):
                pts = []
                for r in _rows(report, rule):
                    ev = r.get("evaluation")
                    if r["scheme"] != scheme or not ev:
                        continue
                    hs = sorted(ev["horizons"], key=float)
                    if not long and len(hs) == 1:
                        continue
                    cell = ev["horizons"][hs[-1] if long else hs[0]]
                    pts.append((r["links"], cell["rate"], *cell["wilson_95"]))
                if not pts:
                    continue
                n, rate, lo, hi = (np.array(v) for v in zip(*pts))
                err = [np.maximum(0, rate - lo), np.maximum(0, hi - rate)]
                what = "row's horizon" if long else f"{o['horizon_short']:g} s"
                c.errorbar(n + shift, rate, yerr=err if long else None,
                           fmt=markers[ri % len(markers)] if long else "x", ls=style,
                           color=_COLORS[scheme], capsize=3, ms=5, lw=1,
                           alpha=1.0 if long else 0.6,
                           label=f"{LABELS.get(scheme, scheme)}, {rule}, {what}")
    c.set_ylim(-0.03, 1.05)
    c.set_ylabel("success rate [95 % Wilson]")
    c.set_title(f"success on MuJoCo, {o['poses']} poses ({o['horizon_short']:g} s for "
                f"N = 2, {o['horizon_long']:g} s beyond; dotted: {o['horizon_short']:g} s)",
                fontsize=9)
    c.legend(fontsize=6)
    for ax in (a, b, c):
        ax.set_xlabel("links N")
        ax.set_xticks(o["links"])
        ax.grid(alpha=0.3)
    fig.tight_layout()
    path = Path(path)
    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=100, format="png")
    finally:
        plt.close(fig)
    return path


def write(report: dict, outdir, command: str) -> dict:
    """Write :data:`FILES` into ``outdir`` (made if missing), all of them or none
    (:func:`twolink.artifacts.staged_set`): the JSON report (with the command), the
    figure and the Markdown. Returns their paths."""
    outdir = Path(outdir)
    report = {**report, "command": command}
    with staged_set(outdir) as stage:
        write_json(stage / FILES["json"], report)
        figure(report, stage / FILES["figure"])
        write_text(stage / FILES["markdown"], markdown(report, command, FILES["figure"]))
    return {k: outdir / name for k, name in FILES.items()}
