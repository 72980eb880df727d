"""Figures of the model-mismatch report: one-step error heat maps, closed-loop success and
settle times, robustness curves, and the N-link section's table. Each policy keeps one
colour in every figure (its place in the registry), whatever the subset of policies or the
order results arrived in."""
from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import LogNorm  # noqa: E402

from twolink._imports import renamed  # noqa: E402
from twolink.arm.parameters import HORIZON  # noqa: E402
from twolink.artifacts import atomic_path  # noqa: E402
from twolink.fqi import fuzzy  # noqa: E402
from twolink.policy.registry import TWO_LINK  # noqa: E402
from twolink.sim.metrics import score_keys  # noqa: E402
from twolink.studies.mismatch.model_error import PREDICTIONS  # noqa: E402
from twolink.studies.mismatch.plan import UNITS  # noqa: E402

_PLANT_STYLES = {"simplified": ":", "full": "--", "mujoco": "-"}


def policy_color(name: str) -> str:
    """The colour of policy ``name`` in every figure: fixed by its registry position."""
    names = list(TWO_LINK)
    return f"C{names.index(name) if name in names else len(names)}"


def _save(fig, path: Path) -> str:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=90, format="png")
    plt.close(fig)
    return path.name


def heatmap_figure(err, path: Path) -> str:
    """Max |speed error| of each prediction over (theta1, dtheta1) and (theta2, dtheta2)."""
    ang = np.rad2deg(fuzzy.angle_axis("t").centers)
    spd = np.rad2deg(fuzzy.speed_axis("s").centers)
    titles = {"simplified": "(11) vs MuJoCo", "full": "(6) vs MuJoCo",
              "agent2_assumption": "agent 2 on (6), link 1 at rest, vs MuJoCo"}
    fig, axes = plt.subplots(len(PREDICTIONS), 2, figsize=(10, 3.2 * len(PREDICTIONS)))
    for r, name in enumerate(PREDICTIONS):
        for col, link in enumerate((1, 2)):
            ax = axes[r, col]
            h = np.maximum(err.heat(name, link), 1e-17)
            im = ax.imshow(h.T, origin="lower", aspect="auto", cmap="viridis",
                           norm=LogNorm(vmin=1e-16, vmax=10.0))
            ax.set_xticks(range(len(ang)), [f"{v:.0f}" for v in ang], fontsize=7)
            ax.set_yticks(range(len(spd)), [f"{v:.0f}" for v in spd], fontsize=7)
            ax.set_xlabel(f"theta{link} bin centre [deg]")
            ax.set_ylabel(f"dtheta{link} [deg/s]")
            ax.set_title(f"{titles[name]}: max |speed error| [rad/s]", fontsize=9)
            fig.colorbar(im, ax=ax)
    fig.tight_layout()
    return _save(fig, path)


def closed_loop_figure(report: dict, settle: dict, path: Path) -> str:
    """Success rate per policy x plant, and the settle-time distribution on each plant."""
    cl, plants = report["closed_loop"], report["plants"]
    pols = list(cl)
    fig, (a, b) = plt.subplots(1, 2, figsize=(13, 4.2))
    w = 0.8 / len(plants)
    for j, plant in enumerate(plants):
        a.bar(np.arange(len(pols)) + (j - 1) * w, [cl[p][plant]["success_rate"] for p in pols],
              w, label=plant)
    a.set_xticks(range(len(pols)), pols, rotation=20, fontsize=8)
    a.set_ylabel("success rate")
    a.set_ylim(0, 1.05)
    a.set_title(f"success over the evaluation set "
                f"({report['evaluation_set']['closed_loop']} states)")
    a.legend(fontsize=8)
    for p in pols:
        for plant in ("simplified", "mujoco"):
            st = np.sort(settle[(p, plant)])
            frac = np.arange(1, len(st) + 1) / len(st)
            fin = np.isfinite(st)
            b.step(np.append(st[fin], HORIZON),
                   np.append(frac[fin], frac[fin][-1] if fin.any() else 0.0),
                   _PLANT_STYLES[plant], color=policy_color(p), where="post",
                   label=f"{p} ({plant})")
    b.set_xlabel("settle time [s]")
    b.set_ylabel("fraction of initial states settled")
    b.set_xlim(0, HORIZON)
    b.set_title("settle-time distribution: dotted simplified, solid MuJoCo")
    b.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    return _save(fig, path)


def robustness_figure(report: dict, keys, path: Path, title: str) -> str:
    """Success rate against perturbation size, one panel per curve, one line per policy."""
    curves = report["robustness"]["curves"]
    threshold = report["robustness"]["threshold"]
    n = len(keys)
    ncol = min(4, n)
    nrow = math.ceil(n / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(3.6 * ncol, 2.9 * nrow), squeeze=False)
    for ax, key in zip(axes.ravel(), keys):
        for p in curves:
            pts = curves[p].get(key, {})
            if pts:
                ax.plot([float(s) for s in pts], list(pts.values()), "o-", ms=3,
                        color=policy_color(p), label=p)
        ax.axhline(threshold, color="grey", lw=0.8, ls=":")
        ax.set_title(key.replace("parameter:", "parameter "), fontsize=9)
        ax.set_xlabel(UNITS[key.split(":")[0]], fontsize=8)
        ax.set_ylim(-0.03, 1.03)
    for ax in axes.ravel()[n:]:
        ax.axis("off")
    axes[0, 0].set_ylabel("success rate")
    axes[0, 0].legend(fontsize=6)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


def robust_figure(section: dict, settle: dict, path: Path) -> str:
    """The robust section: success with its 95 % Wilson interval per policy, level and
    mode (top row), and the settle-time distribution under each level (bottom row; solid
    with compensation, dashed without)."""
    res, levels = section["results"], list(section["levels"])
    pols = list(res)
    modes = [m for m in ("plain", "compensated") if any(m in section["modes"][p] for p in pols)]
    fig, axes = plt.subplots(2, len(levels), figsize=(3.9 * len(levels), 7.2), squeeze=False)
    w = 0.8 / len(modes)
    for col, level in enumerate(levels):
        a, b = axes[0, col], axes[1, col]
        for j, mode in enumerate(modes):
            at = [i for i, p in enumerate(pols) if mode in res[p][level]]
            got = [score_keys(res[pols[i]][level][mode]) for i in at]
            rates = [r["rate"] for r in got]
            # error bars from the interval; max(0, .) absorbs round-off at k = 0 or k = n
            lo = [max(0.0, r["rate"] - r["wilson_95"][0]) for r in got]
            hi = [max(0.0, r["wilson_95"][1] - r["rate"]) for r in got]
            a.bar(np.array(at) + (j - (len(modes) - 1) / 2) * w, rates, w,
                  yerr=[lo, hi], capsize=2, color=[policy_color(pols[i]) for i in at],
                  alpha=1.0 if mode == "compensated" else 0.45,
                  hatch="" if mode == "compensated" else "//", label=mode)
        a.set_xticks(range(len(pols)), pols, rotation=35, ha="right", fontsize=7)
        a.set_ylim(0, 1.05)
        a.set_title(f"{level}: success [95 % Wilson]", fontsize=9)
        for p in pols:
            for mode in res[p][level]:
                st = np.sort(settle[(p, level, mode)])
                frac = np.arange(1, len(st) + 1) / len(st)
                fin = np.isfinite(st)
                b.step(np.append(st[fin], HORIZON),
                       np.append(frac[fin], frac[fin][-1] if fin.any() else 0.0),
                       "-" if mode == "compensated" else "--", color=policy_color(p),
                       where="post", lw=1.0, label=f"{p} ({mode})")
        b.set_xlim(0, HORIZON)
        b.set_ylim(0, 1.02)
        b.set_xlabel("settle time [s]")
        b.set_title(f"{level}: settle-time distribution", fontsize=9)
    axes[0, 0].set_ylabel("success rate (hatched: plain)")
    axes[1, 0].set_ylabel("fraction of rows settled")
    axes[1, -1].legend(fontsize=5, ncol=1, loc="lower right")
    fig.suptitle(f"robust section: {section['plants']} plants per random level x "
                 f"{section['states']} states, seed {section['seed']}; solid/opaque: "
                 "compensated", fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


def links_markdown(section: dict, command: str) -> str:
    """The N-link section (:func:`twolink.studies.mismatch.links.measure`) as Markdown: per policy
    and plant the successes with their 95 % interval and the median settle time."""
    from twolink.viz.formatting import format_rate

    n, plants = section["links"], section["plants"]
    lines = [f"# Model mismatch, {n}-link arm ({section['rule']} links)", "",
             f"`{command}`", "",
             f"Closed loop from {section['poses']} random poses at rest (angles uniform in "
             f"[-pi, pi), seed {section['seed']}, never tuned on), {section['duration']:g} s "
             f"horizon, success = settled in every link's goal band 1 s before the end. The "
             f"policies were synthesised on the full {n}-link model; MuJoCo runs the "
             f"generated {n}-link MJCF.", "",
             "| policy | " + " | ".join(f"success on {p}" for p in plants)
             + " | " + " | ".join(f"median settle on {p} [s]" for p in plants)
             + " | same outcome | max RMS gap (angle rad, speed rad/s) |",
             "|---" * (2 * len(plants) + 3) + "|"]
    for label, by in section["results"].items():
        gap = section["gap"][label]
        by = {p: score_keys(by[p]) for p in plants}        # also a section of older keys
        rates = [format_rate(by[p]["successes"], by[p]["n"]) for p in plants]
        settle = ["never" if by[p]["median_settle"] is None else f"{by[p]['median_settle']:.2f}"
                  for p in plants]
        lines.append(f"| {label} | " + " | ".join(rates) + " | " + " | ".join(settle)
                     + f" | {gap['same_outcome']}/{section['poses']} | "
                     f"{gap['angle_rms']:.3g}, {gap['speed_rms']:.3g} |")
    return "\n".join(lines) + "\n"


#: The names of 0.1 that said *chain*, kept until the next release (with a
#: DeprecationWarning; twolink._imports.renamed).
__getattr__ = renamed(__name__, {
    "chain_markdown": "links_markdown"
})
