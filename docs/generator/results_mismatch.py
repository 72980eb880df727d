"""docs/results/mismatch.md, from ``renders/mismatch/report.json`` (:func:`mismatch_page`),
with the robust section judged against :data:`~generator.targets.ROBUST_TARGETS`.
"""
from __future__ import annotations

from .common import _cell, _order, _stamp, _table
from .targets import robust_targets


def _float_keys(d):
    """``d`` with its keys read back as the floats JSON wrote as strings ("0.1" -> 0.1)."""
    return {float(k): v for k, v in d.items()}


def _in_report_order(report: dict) -> dict:
    """The mismatch report with its dicts in the order the study measured them (policies
    in registry order, plants and levels in the study's), not JSON's sorted keys."""
    from twolink.sim.challenges import LEVELS

    pol, plants = report["policies"], report["plants"]
    comps = ("theta1", "theta2", "dtheta1", "dtheta2")
    ol = dict(report["open_loop"])
    ol["summary"] = {k: _order(v, comps) for k, v in
                     _order(ol["summary"], ("simplified", "full", "agent2_assumption")).items()}
    rb = {k: _order(v, pol) if k in ("margins", "curves", "counts", "joint_worst_plant")
          else v for k, v in report["robustness"].items()}
    out = dict(report, open_loop=ol, robustness=rb,
               closed_loop={p: _order(v, plants) for p, v in
                            _order(report["closed_loop"], pol).items()},
               gap_closure=_order(report["gap_closure"], pol))
    if "robust" in report:
        rs = dict(report["robust"])
        rs["levels"] = _order(rs["levels"], LEVELS)
        rs["results"] = {p: {level: _order(by_mode, rs["modes"].get(p, ()))
                             for level, by_mode in _order(v, LEVELS).items()}
                         for p, v in _order(rs["results"], pol).items()}
        out["robust"] = rs
    return out


def _robust_targets_block(section: dict) -> str:
    from twolink.viz.formatting import format_rate

    rows = [(_cell(text), "never" if value is None else f"{value:.3f}", format_rate(k, n),
             plants, "met" if met else "**missed**")
            for text, value, k, n, plants, met in robust_targets(section)]
    body = (_table(("target", "measured", "success k/n [95 % Wilson]", "plants", "verdict"),
                   rows) if rows else "No target policy was measured.")
    return ("### Targets\n\nWhat the robust policies should reach (the targets live in "
            "`docs/generate.py`, which judges this report's data against them):\n\n"
            + body + "\n")


def mismatch_page(report: dict) -> str:
    from twolink.studies.mismatch.report import markdown

    if "robust" in report:     # targets a report stored once are judged here instead
        report = dict(report, robust={k: v for k, v in report["robust"].items()
                                      if k != "targets"})

    # The report is JSON now: its perturbation sizes, float keys when measured, are strings.
    rb = dict(report["robustness"])
    rb["joint_worst_plant"] = {p: _float_keys(w) for p, w in rb.get("joint_worst_plant", {}).items()}
    rb["counts"] = {p: {f: _float_keys(v) if isinstance(v, dict) else v for f, v in c.items()}
                    for p, c in rb.get("counts", {}).items()}
    report = _in_report_order(dict(report, robustness=rb))
    figures = {k: f"../renders/mismatch/{v}" for k, v in report["figures"].items()}
    text = markdown(report, figures, report["command"])
    text = text.replace("report.json holds them all.",
                        "`renders/mismatch/report.json` holds them all.", 1)
    if "robust" in report:
        block = _robust_targets_block(report["robust"])
        at = text.find("\n## Sweep throughput")
        text = text + "\n" + block if at < 0 else text[:at] + "\n" + block + text[at:]
    return "".join([
        _stamp("renders/mismatch/report.json"), text.rstrip("\n"), "\n\n",
        "How to run the study, its plans and executors: [Model mismatch]"
        "(../guides/mismatch.md). Re-create the data with `twolink mismatch` (it writes "
        "`renders/mismatch/`), then `python docs/generate.py`.\n"])
