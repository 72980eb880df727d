"""Learning-curve figures: evaluation-set success against MuJoCo control steps, one line
per learner, model-based policies as horizontal lines (presentation only)."""
from __future__ import annotations

import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from twolink.artifacts import atomic_path  # noqa: E402
from twolink.sim.metrics import Score  # noqa: E402

_STYLES = ("-", "--", ":", "-.")


def learning_curves(panels: dict, path: os.PathLike, *, baselines: dict | None = None,
                    target: float | None = 0.9, title: str | None = None) -> Path:
    """Write a PNG of learning curves.

    ``panels`` maps a panel title to ``{label: curve}``, a curve being a list of
    :class:`twolink.synthesis.learning.Evaluation` (or their dicts: ``steps`` and a score's
    keys, read by :meth:`twolink.sim.metrics.Score.from_dict`, so curves stored before the
    one spelling, with ``successes`` and ``n`` only, still draw); success is drawn with its
    95 % Wilson band. ``baselines`` maps a label to a success
    rate in [0, 1] drawn as a horizontal line in every panel; ``target`` a dotted line.
    """
    if not panels or not any(panels.values()):
        raise ValueError("nothing to plot")
    rows = max(len(c) for c in panels.values()) + len(baselines or {}) + 1
    below = rows > 8                   # many curves: the legend goes under the axes
    fig, axes = plt.subplots(1, len(panels), figsize=(6.0 * len(panels),
                                                      4.2 + (0.17 * rows if below else 0)),
                             squeeze=False, sharey=True)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for ax, (panel, curves) in zip(axes[0], panels.items()):
        for c, (label, curve) in enumerate(curves.items()):
            pts = [e if isinstance(e, dict) else e.as_dict() for e in curve]
            if not pts:
                raise ValueError(f"{label}: empty learning curve")
            steps = [p["steps"] for p in pts]
            scores = [Score.from_dict(p) for p in pts]
            rate = [s.rate for s in scores]
            band = [s.wilson_95 for s in scores]
            color = colors[c % len(colors)]
            ax.plot(steps, [100 * r for r in rate], color=color, lw=1.6, label=label,
                    ls=_STYLES[(c // len(colors)) % len(_STYLES)], marker=".")
            ax.fill_between(steps, [100 * b[0] for b in band], [100 * b[1] for b in band],
                            color=color, alpha=0.12, lw=0)
        for b, (label, rate) in enumerate((baselines or {}).items()):
            if not 0 <= rate <= 1:
                raise ValueError(f"baseline {label}: a rate must lie in [0, 1], got {rate}")
            ax.axhline(100 * rate, color="0.35", ls=_STYLES[(b + 1) % len(_STYLES)], lw=1.0,
                       label=f"{label} (model-based)")
        if target is not None:
            ax.axhline(100 * target, color="tab:red", ls=":", lw=0.8,
                       label=f"{100 * target:g} % target")
        ax.set_title(panel)
        ax.set_xlabel("MuJoCo control steps (all arms)")
        ax.set_ylim(-3, 103)
        ax.grid(alpha=0.3)
        if below:
            ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=1,
                      frameon=False)
        else:
            ax.legend(fontsize=7, loc="best")
    axes[0, 0].set_ylabel("evaluation-set success [%] (95 % Wilson band)")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    return path
