"""The leaderboard presented: a Markdown table per level, the JSON of every row, and a
figure of success against settle / T* (presentation only)."""
from __future__ import annotations

import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from twolink.artifacts import (  # noqa: E402
    atomic_path,
    provenance,
    staged_set,
    write_json,
    write_text,
)
from twolink.viz.formatting import format_rate  # noqa: E402

FILES = {"markdown": "leaderboard.md", "json": "leaderboard.json",
         "figure": "leaderboard.png"}


def _ratio(v) -> str:
    return "never" if v is None else f"{v:.2f}"


def _settle(v) -> str:
    return "never" if v is None else f"{v:.2f} s"


def ranked(rows: list) -> list:
    """Rows (dicts) of one level, best first: success rate, then median settle / T*."""
    return sorted(rows, key=lambda r: (-r["rate"], r["settle_ratio_median"] is None,
                                       r["settle_ratio_median"] or 0.0, r["controller"]))


def markdown(report: dict) -> str:
    """The report as Markdown: what was run, then one ranked table per level."""
    lines = ["# Leaderboard", "",
             f"`{report['command']}`: {report['states']} initial states, "
             f"{report['plants']} plants per perturbing level, seed {report['seed']}, "
             f"on MuJoCo. Success: settled in the goal band 1 s before the end of "
             f"{report['horizon']:g} s (k/n with the 95 % Wilson interval). settle / T*: "
             f"each run's settle time over the time-optimal limit of its initial state "
             f"({report['limits']}), a failure counting as never settled. "
             "*plain*: the controller reads the challenge's readings as they are; "
             "*compensated*: through the delay predictor and observer "
             "(twolink.sim.estimation), for controllers that name their model.", ""]
    for level in report["levels"]:
        rows = ranked([r for r in report["rows"] if r["level"] == level])
        lines += [f"## {level}", "",
                  "| controller | mode | success | worst plant | median settle | "
                  "settle / T* (median, worst) | mean abs torque [N m] |",
                  "|---|---|---|---|---|---|---|"]
        for r in rows:
            worst = ("-" if r["worst_plant"] is None
                     else f"{r['worst_plant_successes']}/{r['n'] // report['plants']}")
            lines.append(f"| {r['controller']} | {r['mode']} | "
                         f"{format_rate(r['successes'], r['n'])} | {worst} | "
                         f"{_settle(r['median_settle'])} | "
                         f"{_ratio(r['settle_ratio_median'])}, {_ratio(r['settle_ratio_worst'])}"
                         f" | {r['mean_abs_torque']:.3f} |")
        lines.append("")
    return "\n".join(lines)


def figure(report: dict, path: os.PathLike) -> Path:
    """Success rate against median settle / T*, one panel per level."""
    levels = report["levels"]
    fig, axes = plt.subplots(1, len(levels), figsize=(4.2 * len(levels), 3.6), squeeze=False,
                             sharey=True)
    names = sorted({r["controller"] for r in report["rows"]})
    colours = {n: plt.cm.tab20(i % 20) for i, n in enumerate(names)}
    for ax, level in zip(axes[0], levels):
        for r in report["rows"]:
            if r["level"] != level:
                continue
            x = r["settle_ratio_median"]
            x = 6.0 if x is None else min(x, 6.0)
            ax.scatter(x, 100 * r["rate"], color=colours[r["controller"]],
                       marker="o" if r["mode"] == "plain" else "^", s=40)
        ax.set_title(level)
        ax.set_xlabel("median settle / T*  (6: never)")
        ax.set_xlim(0.8, 6.3)
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("success [%]")
    handles = [plt.Line2D([], [], color=colours[n], marker="s", ls="") for n in names]
    handles += [plt.Line2D([], [], color="grey", marker=m, ls="") for m in ("o", "^")]
    fig.legend(handles, [*names, "plain", "compensated"], loc="center right", fontsize=7,
               frameon=False)
    fig.tight_layout(rect=(0, 0, 0.82, 1))
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    return Path(path)


def write(report: dict, out: os.PathLike) -> dict:
    """Write the Markdown, JSON (with provenance) and figure into ``out`` (made if
    missing), all three or none (:func:`twolink.artifacts.staged_set`); their paths."""
    out = Path(out)
    with staged_set(out) as staging:
        write_json(staging / FILES["json"], {**report, "provenance": provenance()})
        write_text(staging / FILES["markdown"], markdown(report) + "\n")
        figure(report, staging / FILES["figure"])
    return {k: out / v for k, v in FILES.items()}
