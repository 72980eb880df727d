"""Figures laid out like the paper's Fig. 3: commands, link angles, angular speeds and
rewards against time, one column per panel, several trajectories overlaid per column."""
from __future__ import annotations

import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from twolink.arm.parameters import GOAL_ANGLE, GOAL_SPEED  # noqa: E402
from twolink.artifacts import atomic_path  # noqa: E402
from twolink.sim.rollout import Trajectory  # noqa: E402

#: Link k's colour, link 1 first: those of the arm's links in the MJCF and the videos.
_LINK_COLORS = ("tab:orange", "tab:blue", "tab:green", "tab:purple", "tab:red", "tab:cyan")
_STYLES = ("-", "--", ":", "-.")


def fig3(panels: dict, path: os.PathLike, *, title: str | None = None) -> Path:
    """Write a Fig. 3-style PNG.

    ``panels`` maps a column title to ``{label: Trajectory}``; within a column, each
    label gets its own line style and each link its own colour (N lines per row for an
    N-link arm).
    """
    if not panels:
        raise ValueError("nothing to plot")
    ncol = len(panels)
    fig, axes = plt.subplots(4, ncol, figsize=(5.2 * ncol, 9.0), sharex=True, squeeze=False)
    rows = ("torque [Nm]", "angle [rad]", "speed [rad/s]", "reward [-]")
    for c, (col_title, trajs) in enumerate(panels.items()):
        ax = axes[:, c]
        for s, (label, tr) in enumerate(trajs.items()):
            if not isinstance(tr, Trajectory) or tr.x.ndim != 2:
                raise ValueError(f"{label}: expected a single trajectory")
            ls = _STYLES[s % len(_STYLES)]
            n = tr.x.shape[-1] // 2
            for i in range(n):
                kw = dict(color=_LINK_COLORS[i], ls=ls, lw=1.4)
                name = f"link {i + 1}" + (f", {label}" if len(trajs) > 1 or label else "")
                ax[0].step(tr.t[:-1], tr.u[:, i], where="post", label=name, **kw)
                ax[1].plot(tr.t, tr.x[:, i], **kw)
                ax[2].plot(tr.t, tr.x[:, n + i], **kw)
            if tr.kind == "decentralized":             # per-link rewards (17)
                for i in range(n):
                    ax[3].step(tr.t[1:], tr.r_links[:, i], where="pre", color=_LINK_COLORS[i],
                               ls=ls, lw=1.4)
            else:
                ax[3].step(tr.t[1:], tr.r, where="pre", color="k", ls=ls, lw=1.4,
                           label=f"r (15){', ' + label if label else ''}")
        for a, band in ((ax[1], GOAL_ANGLE), (ax[2], GOAL_SPEED)):
            a.axhspan(-band, band, color="tab:green", alpha=0.15, lw=0)
        ax[0].set_title(col_title)
        ax[0].legend(fontsize=7, ncol=2, loc="upper right")
        for a, name in zip(ax, rows):
            a.set_ylabel(name)
            a.grid(alpha=0.3)
        ax[3].set_ylim(-0.6, 0.1)
        ax[3].set_xlabel("t [s]")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    path = Path(path)
    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=110, format=path.suffix.lstrip(".") or "png")
    finally:
        plt.close(fig)
    return path


def paper_fig3(trajectories: dict, path: os.PathLike, *,
               plants=("simplified", "mujoco")) -> Path:
    """The counterpart of the paper's Fig. 3 from ``{(policy, plant): Trajectory}``:
    (a) centralized, (b) decentralized, one line style per plant (solid: the first)."""
    panels = {title: {plant: trajectories[(name, plant)] for plant in plants}
              for name, title in (("centralized", "(a) centralized"),
                                  ("decentralized", "(b) decentralized"))}
    x0 = trajectories[("centralized", plants[0])].x[0]
    styles = ", ".join(f"{s} {p}" for s, p in zip(("solid", "dashed", "dotted"), plants))
    return fig3(panels, path, title=f"Fig. 3 from x0 = [{', '.join(f'{v:.3g}' for v in x0)}]: "
                                    f"{styles}")
