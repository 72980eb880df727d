"""Figures laid out like the paper's Fig. 3: commands, link angles, angular speeds and
rewards against time, one column per panel, several trajectories overlaid per column."""
from __future__ import annotations

import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402

from twolink.arm.parameters import GOAL_ANGLE, GOAL_SPEED  # noqa: E402
from twolink.artifacts import atomic_path  # noqa: E402
from twolink.sim.rollout import Trajectory  # noqa: E402

#: Link k's colour, link 1 first: those of the arm's links in the MJCF and the videos.
_LINK_COLORS = ("tab:orange", "tab:blue", "tab:green", "tab:purple", "tab:red", "tab:cyan")
_STYLES = ("-", "--", ":", "-.")


def broken_at_wraps(t: np.ndarray, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(t, theta) with a NaN inserted between samples where the wrapped angle jumps by
    more than pi (it crossed +-pi), so a plotted line breaks there instead of drawing a
    vertical stroke across the panel."""
    t, theta = np.asarray(t, dtype=float), np.asarray(theta, dtype=float)
    jumps = np.flatnonzero(np.abs(np.diff(theta)) > np.pi) + 1
    return (np.insert(t, jumps, (t[jumps - 1] + t[jumps]) / 2),
            np.insert(theta, jumps, np.nan))


def fig3_figure(panels: dict, *, title: str | None = None):
    """The matplotlib figure of :func:`fig3` (the caller closes it)."""
    if not panels:
        raise ValueError("nothing to plot")
    ncol = len(panels)
    fig, axes = plt.subplots(4, ncol, figsize=(5.2 * ncol, 9.6), sharex=True, squeeze=False,
                             layout="constrained")
    rows = ("torque [Nm]", "angle [rad]", "speed [rad/s]", "reward [-]")
    labels, links, wrapped, per_link, joint = [], 0, False, False, False
    for c, (col_title, trajs) in enumerate(panels.items()):
        ax = axes[:, c]
        for s, (label, tr) in enumerate(trajs.items()):
            if not isinstance(tr, Trajectory) or tr.x.ndim != 2:
                raise ValueError(f"{label}: expected a single trajectory")
            if label not in labels:
                labels.append(label)
            ls = _STYLES[labels.index(label) % len(_STYLES)]
            n = tr.x.shape[-1] // 2
            links = max(links, n)
            for i in range(n):
                kw = dict(color=_LINK_COLORS[i], ls=ls, lw=1.4)
                ax[0].step(tr.t[:-1], tr.u[:, i], where="post", **kw)
                tt, theta = broken_at_wraps(tr.t, tr.x[:, i])
                wrapped |= len(tt) > len(tr.t)
                ax[1].plot(tt, theta, **kw)
                ax[2].plot(tr.t, tr.x[:, n + i], **kw)
            if tr.kind == "decentralized":             # per-link rewards (17)
                per_link = True
                for i in range(n):                     # link 1 widest, so equal ones show
                    ax[3].step(tr.t[1:], tr.r_links[:, i], where="pre", color=_LINK_COLORS[i],
                               ls=ls, lw=1.4 + 1.6 * (n - 1 - i) / max(n - 1, 1), alpha=0.9)
            else:
                joint = True
                ax[3].step(tr.t[1:], tr.r, where="pre", color="k", ls=ls, lw=1.4)
        for a, band in ((ax[1], GOAL_ANGLE), (ax[2], GOAL_SPEED)):
            a.axhspan(-band, band, color="tab:green", alpha=0.15, lw=0)
        ax[0].set_title(col_title)
        for a, name in zip(ax, rows):
            a.set_ylabel(name)
            a.grid(alpha=0.3)
        ax[3].set_ylim(-0.6, 0.1)
        ax[3].set_xlabel("t [s]")
    if wrapped:
        for a in axes[1]:
            for v in (-np.pi, np.pi):
                a.axhline(v, color="0.5", ls=":", lw=0.8)
    fig.legend(handles=_legend_handles(labels, links, wrapped, per_link, joint),
               loc="outside lower center", ncol=min(4, links + len(labels) + 2), fontsize=8,
               frameon=False)
    if title:
        fig.suptitle(title)
    return fig


def _legend_handles(labels, links, wrapped, per_link, joint) -> list:
    """One entry per link colour, per line style and per reward; the wrap marker if any."""
    handles = [Line2D([], [], color=_LINK_COLORS[i], lw=1.4, label=f"link {i + 1}")
               for i in range(links)]
    handles += [Line2D([], [], color="0.3", ls=_STYLES[k % len(_STYLES)], lw=1.4,
                       label=label or "run") for k, label in enumerate(labels)
                if len(labels) > 1 or label]
    if per_link:
        handles.append(Line2D([], [], color="0.3", lw=2.6,
                              label="reward (17) of agent i in link i's colour"))
    if joint:
        handles.append(Line2D([], [], color="k", lw=1.4, label="reward (15)"))
    if wrapped:
        handles.append(Line2D([], [], color="0.5", ls=":", lw=0.8,
                              label="angle wraps at +-pi (line broken)"))
    return handles


def fig3(panels: dict, path: os.PathLike, *, title: str | None = None) -> Path:
    """Write a Fig. 3-style PNG.

    ``panels`` maps a column title to ``{label: Trajectory}``; within a column, each
    label gets its own line style and each link its own colour (N lines per row for an
    N-link arm). Rewards: (15) in black for a centralized policy, (17) per link in the
    link's colour for a decentralized one (link 1's line drawn widest, so that equal
    rewards stay visible). An angle crossing +-pi (it is wrapped to [-pi, pi)) breaks its
    line there (:func:`broken_at_wraps`) and the panel marks +-pi. The legend sits below
    the panels, clear of the traces.
    """
    fig = fig3_figure(panels, title=title)
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
