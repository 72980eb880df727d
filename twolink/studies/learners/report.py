"""The learners' study, read: one row per arm and learner (seeds pooled), and its figure.

For each row of :func:`rows`: the seeds run; success of the final agents on the fresh
poses (counts pooled over seeds, the Wilson 95 % interval) and on the scaling table's
poses; the interquartile mean over seeds of the fresh success rate with a 95 % percentile
bootstrap interval; success on the same fresh poses run on the rigid-body model (6)
(the transfer gap: a model-trained learner's MuJoCo score against this; runs recorded
before it was measured have none) and run for 16 s instead of 8 s (``fresh_late``: a pose
missed at 8 s but settled by 16 s was late, not lost; runs recorded before it have none
until ``docs/studies/learners_late.py`` scores their agents) (rliable's protocol for few runs, Agarwal et al. 2021: IQM by
``scipy.stats.trim_mean(·, 0.25)``, resampled by ``scipy.stats.bootstrap``); the
environment steps each seed took to reach 90 % of the ceiling on the curve's poses (the
first evaluation at or above it; ``None`` where it never did); the median settle time;
and the cost: wall and CPU seconds per run, CPU microseconds per environment step
(updates and the curve's evaluations included), peak resident memory and the parameters
the agent file holds. The ceiling of an arm is the reach study's reachable share of the
table's poses (:func:`ceilings`, 1 where it was not run).
"""
from __future__ import annotations

import math
from collections import defaultdict

import numpy as np

from twolink.sim.metrics import wilson_interval

#: Fraction of the ceiling a learner must reach on the curve to count as learnt.
OF_CEILING = 0.9
#: Bootstrap resamples of the IQM's interval, and their seed.
RESAMPLES, BOOT_SEED = 2000, 0


def learner_name(algo: str, observe: str, base: str = "none", plant: str = "mujoco") -> str:
    """How the table names a learner: ``PPO (centralized)``, ``IPPO (local) + PD``,
    ``PPO (centralized), trained on the model``..."""
    name = "PPO (centralized)" if algo == "ppo" else f"{algo.upper()} ({observe})"
    return (name + (" + PD" if base == "pd" else "")
            + ("" if plant == "mujoco" else f", trained on the {plant}"))


def ceilings(reach: dict | None) -> dict:
    """{(links, rule): reachable share} of the reach study's data (``twolink.links_reach``)."""
    if not reach:
        return {}
    return {(r["links"], r["rule"]): r["reachable"] / r["poses"] for r in reach["runs"]
            if r["poses"]}


def iqm(rates) -> tuple:
    """(IQM, low, high): the interquartile mean of per-seed rates and its 95 % percentile
    bootstrap interval (a single seed: the rate, no interval)."""
    from scipy import stats

    x = np.asarray(rates, dtype=float)
    point = float(stats.trim_mean(x, 0.25))
    if len(x) < 2 or np.all(x == x[0]):
        return point, point, point
    res = stats.bootstrap((x,), lambda a, axis=-1: stats.trim_mean(a, 0.25, axis=axis),
                          n_resamples=RESAMPLES, method="percentile", vectorized=True,
                          random_state=np.random.default_rng(BOOT_SEED))
    return point, float(res.confidence_interval.low), float(res.confidence_interval.high)


def steps_to(curve: list, level: float):
    """Environment steps of the first curve point at or above ``level`` (None: never)."""
    for p in curve:
        if p["rate"] >= level - 1e-12:
            return p["steps"]
    return None


def rows(data: dict, ceiling: dict | None = None) -> list:
    """One dict per (links, rule, algo, observe) of the study's runs; see the module
    docstring."""
    ceiling = ceiling or {}
    groups = defaultdict(list)
    for r in data.get("runs", []):
        run = r["run"]
        groups[(run["links"], run["rule"], run["algo"], run["observe"],
                run.get("base", "none"), run.get("plant", "mujoco"))].append(r)
    out = []
    for (links, rule, algo, observe, base, plant), runs in sorted(groups.items(), key=lambda kv: (
            kv[0][0], kv[0][1] != "tapered", kv[0][5] != "mujoco", kv[0][4] != "none",
            kv[0][2] != "ppo", kv[0][2], kv[0][3])):
        runs.sort(key=lambda r: r["run"]["seed"])
        top = ceiling.get((links, rule), 1.0)
        fresh_k = sum(r["fresh"]["successes"] for r in runs)
        fresh_n = sum(r["fresh"]["n"] for r in runs)
        table_k = sum(r["table"]["successes"] for r in runs)
        table_n = sum(r["table"]["n"] for r in runs)
        point, lo, hi = iqm([r["fresh"]["rate"] for r in runs])
        settles = [r["fresh"]["median_settle"] for r in runs
                   if r["fresh"]["median_settle"] is not None]
        on_model = [r["fresh_model"] for r in runs if "fresh_model" in r]
        model_k, model_n = (sum(m["successes"] for m in on_model),
                            sum(m["n"] for m in on_model))
        late = [r["fresh_late"] for r in runs if "fresh_late" in r]
        late_k, late_n = sum(m["successes"] for m in late), sum(m["n"] for m in late)
        out.append({
            "links": links, "rule": rule, "algo": algo, "observe": observe, "base": base,
            "plant": plant, "learner": learner_name(algo, observe, base, plant),
            "seeds": [r["run"]["seed"] for r in runs],
            "steps": max(r["steps"] for r in runs),
            "fresh": {"successes": fresh_k, "n": fresh_n,
                      "wilson_95": list(wilson_interval(fresh_k, fresh_n)),
                      "per_seed": [r["fresh"]["rate"] for r in runs],
                      "iqm": point, "iqm_95": [lo, hi]},
            "table": {"successes": table_k, "n": table_n,
                      "wilson_95": list(wilson_interval(table_k, table_n))},
            # the same fresh poses on the model (6), for the seeds scored there
            "fresh_model": None if not on_model else {
                "successes": model_k, "n": model_n, "seeds": len(on_model),
                "wilson_95": list(wilson_interval(model_k, model_n))},
            # the same fresh poses run for 16 s, for the seeds scored so
            "fresh_late": None if not late else {
                "successes": late_k, "n": late_n, "seeds": len(late),
                "wilson_95": list(wilson_interval(late_k, late_n))},
            "ceiling": ceiling.get((links, rule)),
            "steps_to_90pct_ceiling": [steps_to(r["curve"], OF_CEILING * top) for r in runs],
            "median_settle_s": float(np.median(settles)) if settles else None,
            "wall_s": float(np.mean([r["wall_s"] for r in runs])),
            "cpu_s": float(np.mean([r["cpu_s"] for r in runs])),
            "cpu_us_per_step": float(np.mean([1e6 * r["cpu_s"] / r["steps"] for r in runs])),
            "peak_rss_bytes": max((r["peak_rss_bytes"] or 0) for r in runs) or None,
            "parameters": runs[0]["parameters"]})
    return out


def _rate(k, n, ci) -> str:
    return f"{k}/{n} = {100 * k / n:.1f} % [{100 * ci[0]:.1f}, {100 * ci[1]:.1f}]" if n else "—"


def _steps(values) -> str:
    return ", ".join("never" if v is None else f"{v / 1e6:.2f} M" for v in values)


def table(rows_: list) -> str:
    """The rows as a Markdown table."""
    out = ["| N | links | learner | seeds | fresh poses at 8 s | IQM over seeds [95 % "
           "bootstrap] | fresh poses by 16 s | fresh poses on the model (6) | table poses at "
           "8 s | ceiling | steps to 90 % of it | median settle | CPU per step | wall per run "
           "| peak memory | parameters |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows_:
        f, t = r["fresh"], r["table"]
        ceiling = "—" if r["ceiling"] is None else f"{100 * r['ceiling']:.0f} %"
        settle = "—" if r["median_settle_s"] is None else f"{r['median_settle_s']:.2f} s"
        mem = "—" if not r["peak_rss_bytes"] else f"{r['peak_rss_bytes'] / 2**20:.0f} MiB"
        m = r.get("fresh_model")
        model = "—" if not m else _rate(m["successes"], m["n"], m["wilson_95"])
        lt = r.get("fresh_late")
        late = "—" if not lt else _rate(lt["successes"], lt["n"], lt["wilson_95"])
        out.append(
            f"| {r['links']} | {r['rule']} | {r['learner']} | {len(r['seeds'])} | "
            f"{_rate(f['successes'], f['n'], f['wilson_95'])} | {100 * f['iqm']:.1f} % "
            f"[{100 * f['iqm_95'][0]:.1f}, {100 * f['iqm_95'][1]:.1f}] | {late} | {model} | "
            f"{_rate(t['successes'], t['n'], t['wilson_95'])} | {ceiling} | "
            f"{_steps(r['steps_to_90pct_ceiling'])} | {settle} | "
            f"{r['cpu_us_per_step']:.0f} µs | {r['wall_s'] / 60:.1f} min | {mem} | "
            f"{r['parameters']:,} |")
    return "\n".join(out)


def figure(data: dict, path, ceiling: dict | None = None):
    """The learning curves (success on the curve's 64 poses against environment steps),
    a panel per arm, a line per learner (mean over seeds, thin lines per seed), the
    ceiling dashed; written to ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ceiling = ceiling or {}
    arms = sorted({(r["run"]["links"], r["run"]["rule"]) for r in data["runs"]},
                  key=lambda a: (a[0], a[1] != "tapered"))
    cols = min(4, max(1, len(arms)))
    nrows = math.ceil(len(arms) / cols) if arms else 1
    fig, axes = plt.subplots(nrows, cols, figsize=(4 * cols, 3.2 * nrows), squeeze=False)
    colours = {}
    for ax, (links, rule) in zip(axes.flat, arms):
        by = defaultdict(list)
        for r in data["runs"]:
            if (r["run"]["links"], r["run"]["rule"]) == (links, rule):
                by[(r["run"]["algo"], r["run"]["observe"], r["run"].get("base", "none"),
                    r["run"].get("plant", "mujoco"))].append(r)
        for key, runs in sorted(by.items()):
            name = learner_name(*key)
            colour = colours.setdefault(name, f"C{len(colours)}")
            for r in runs:
                ax.plot([p["steps"] / 1e6 for p in r["curve"]],
                        [100 * p["rate"] for p in r["curve"]], color=colour, lw=0.6,
                        alpha=0.5)
            steps = [p["steps"] for p in runs[0]["curve"]]
            if all([p["steps"] for p in r["curve"]] == steps for r in runs):
                mean = np.mean([[p["rate"] for p in r["curve"]] for r in runs], axis=0)
                ax.plot(np.asarray(steps) / 1e6, 100 * mean, color=colour, lw=1.8)
        if (links, rule) in ceiling:
            ax.axhline(100 * ceiling[(links, rule)], color="k", ls="--", lw=0.8)
        ax.set_title(f"N = {links} ({rule})")
        ax.set_xlabel("environment steps (M)")
        ax.set_ylabel("success on 64 poses (%)")
        ax.set_ylim(-3, 103)
        ax.grid(alpha=0.3)
    for ax in list(axes.flat)[len(arms):]:
        ax.axis("off")
    handles = [plt.Line2D([], [], color=c, lw=2, label=n) for n, c in colours.items()]
    if handles:
        fig.legend(handles=handles + [plt.Line2D([], [], color="k", ls="--",
                                                 label="ceiling (reach study)")],
                   loc="lower center", ncol=min(6, len(handles) + 1), frameon=False)
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
