"""The leaderboard's figure: success rate against median settle / T*, one panel per level.

A point is one controller under one level: filled in the plain mode, hollow with
compensation. The marker says the controller's
family (:data:`MARKERS`: fuzzy, baseline, learned, user), the colour which controller it
is; at most :data:`MAX_LABELLED` controllers get a colour and a legend entry, the others
are small grey dots under one entry. A run that never settles (median settle / T*
infinite) sits in the ``never`` column at the right. The legend lies below the panels,
inside the canvas.
"""
from __future__ import annotations

import math
import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402

from twolink.artifacts import atomic_path  # noqa: E402

#: The marker of each family of controllers.
MARKERS = {"fuzzy": "o", "baseline": "s", "learned": "^", "user": "D"}
#: The most controllers that get a colour and a legend entry of their own.
MAX_LABELLED = 12
#: Twelve colours told apart at a glance (tab10, then black and gold).
COLOURS = [*(plt.cm.tab10(i) for i in range(10)), (0.0, 0.0, 0.0, 1.0),
           (0.9, 0.67, 0.0, 1.0)]


def _x(v, never: float) -> float:
    return never if v is None or not math.isfinite(v) else min(float(v), never)


def leaderboard_figure(report: dict, *, families: dict, labelled, titles: dict | None = None):
    """The figure (a matplotlib Figure, not saved) of ``report``'s rows: a panel per
    level of ``report["levels"]``, the controllers of ``labelled`` (at most
    :data:`MAX_LABELLED`, in legend order) in colour, the family of each from
    ``families`` (``{controller: "fuzzy" | "baseline" | "learned" | "user"}``),
    ``titles`` (``{level: text}``) over the panels."""
    labelled = list(dict.fromkeys(labelled))
    if len(labelled) > MAX_LABELLED:
        raise ValueError(f"{len(labelled)} labelled controllers; at most {MAX_LABELLED}")
    levels = list(report["levels"])
    colour = dict(zip(labelled, COLOURS))
    finite = [r["settle_ratio_median"] for r in report["rows"]
              if r["settle_ratio_median"] is not None]
    xmax = min(max([3.0, *finite]), 6.0)
    never = xmax + 0.6
    cols = 1 if len(levels) == 1 else 2
    nrows = math.ceil(len(levels) / cols)
    names = list(dict.fromkeys(r["controller"] for r in report["rows"]))
    shown = [f for f in MARKERS if any(families.get(n, "user") == f for n in names)]
    n_handles = len(labelled) + any(n not in colour for n in names) + len(shown) + 2
    legend_in = 0.2 * math.ceil(n_handles / 4) + 0.15
    fig, axes = plt.subplots(nrows, cols, figsize=(5.2 * cols, 3.4 * nrows + legend_in),
                             squeeze=False, sharey=True)
    for ax in axes.flat[len(levels):]:
        fig.delaxes(ax)
    by = {(r["controller"], r["level"], r["mode"]): r for r in report["rows"]}
    for ax, level in zip(axes.flat, levels):
        for name in names:
            plain, comp = by.get((name, level, "plain")), by.get((name, level, "compensated"))
            marker = MARKERS.get(families.get(name, "user"), "D")
            if name not in colour:
                for r in (plain, comp):
                    if r is not None:
                        ax.scatter(_x(r["settle_ratio_median"], never), 100 * r["rate"],
                                   s=10, color="0.6", alpha=0.6, zorder=1, linewidths=0)
                continue
            c = colour[name]
            pts = [(_x(r["settle_ratio_median"], never), 100 * r["rate"])
                   for r in (plain, comp) if r is not None]
            if plain is not None:
                ax.scatter(*pts[0], marker=marker, s=46, color=c, edgecolors="k",
                           linewidths=0.4, zorder=3)
            if comp is not None:
                ax.scatter(*pts[-1], marker=marker, s=46, facecolors="none", edgecolors=c,
                           linewidths=1.3, zorder=3)
        ax.set_title((titles or {}).get(level, level), fontsize=9)
        ax.set_xlim(0.8, never + 0.3)
        ax.set_ylim(-4, 104)
        ticks = [t for t in (1, 2, 3, 4, 5, 6) if t <= xmax]
        ax.set_xticks([*ticks, never], [*map(str, ticks), "never"])
        ax.set_xlabel("median settle / T*", fontsize=8)
        ax.grid(alpha=0.3)
        ax.tick_params(labelsize=8)
    for ax in axes[:, 0]:
        ax.set_ylabel("success [%]", fontsize=8)
    handles = [Line2D([], [], color=colour[n], marker=MARKERS.get(families.get(n, "user"), "D"),
                      ls="", markeredgecolor="k", markeredgewidth=0.4, label=n)
               for n in labelled]
    others = [n for n in names if n not in colour]
    if others:
        handles.append(Line2D([], [], color="0.6", marker="o", ls="", markersize=4,
                              label=f"{len(others)} other controllers"))
    handles += [Line2D([], [], color="0.3", marker=MARKERS[f], ls="", label=f) for f in shown]
    handles += [Line2D([], [], color="0.3", marker="o", ls="", label="plain"),
                Line2D([], [], color="0.3", marker="o", ls="", markerfacecolor="none",
                       label="compensated")]
    fig.legend(handles=handles, loc="lower center", ncol=4, fontsize=7.5, frameon=False,
               bbox_to_anchor=(0.5, 0.01))
    fig.tight_layout(rect=(0, legend_in / fig.get_figheight(), 1, 1))
    return fig


def save_png(fig, path: os.PathLike, dpi: int = 110) -> Path:
    """Write ``fig`` as a PNG at ``path`` (atomically) and close it."""
    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=dpi, format="png")
    finally:
        plt.close(fig)
    return Path(path)
