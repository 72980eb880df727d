"""The model-mismatch report: open-loop error, closed-loop gap, its closure, robustness.

1. open loop - one-step error of (11), (6) and agent 2's assumption against MuJoCo
   (:mod:`twolink.model_error`), beside the RK4 integration error of the numpy plants;
2. closed loop - each policy on each plant over the evaluation set: success rate,
   settle-time distribution, return, trajectory gap to MuJoCo;
3. closing the gap - the policies synthesised on (6) against the paper's, on MuJoCo;
4. robustness - sweeps of :mod:`twolink.sweeps` and a margin per policy and family.

Every number is recomputed from rollouts when the report is built; only finished sweep
cells of the same policy files are reused from the results file (resume).
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from twolink import dynamics
from twolink.artifacts import provenance
from twolink.integrate import integration_error
from twolink.metrics import (discounted_return, evaluation_set, settle_time, success,
                             trajectory_gap)
from twolink.model_error import PREDICTIONS, one_step_error
from twolink.parameters import HORIZON, TABLE_I, TS
from twolink.perturbations import PERTURBABLE
from twolink.plants import MujocoPlant, make_plant
from twolink.policy import load_policy
from twolink.rollout import rollout
from twolink.sweeps import Cell, policy_digest, run_sweep, states_of

#: Policies compared, in report order: the paper's three, then the two synthesised on (6).
POLICIES = ("centralized", "decentralized", "decentralized_propagated",
            "centralized_full", "decentralized_full")
PLANTS = ("simplified", "full", "mujoco")
#: Which policy synthesised on (6) answers which paper policy.
COUNTERPART = {"centralized": "centralized_full", "decentralized": "decentralized_full",
               "decentralized_propagated": "decentralized_full"}
THRESHOLD = 0.95

#: Perturbation sizes per family (relative changes; noise in degrees; delay in samples).
SIZES = {
    False: {"parameter": (-0.5, -0.2, -0.1, 0.1, 0.2, 0.5),
            "joint": (0.1, 0.2, 0.3, 0.5), "noise": (0.25, 0.5, 1.0, 2.0, 5.0),
            "delay": (1.0, 2.0), "torque_limit": (-0.5, -0.3, -0.2, -0.1, 0.2)},
    True: {"parameter": (-0.5, 0.5), "joint": (0.2,), "noise": (2.0,), "delay": (1.0,),
           "torque_limit": (-0.5,)},
}
DRAWS = {False: 4, True: 2}
UNITS = {"parameter": "relative change", "joint": "relative change (each parameter)",
         "noise": "angle noise std [deg]", "delay": "samples", "torque_limit": "relative change"}


def sweep_cells(policies=POLICIES, *, quick: bool = False) -> list[Cell]:
    """Every cell of the robustness sweep (the nominal cell included)."""
    states = "quick" if quick else "full"
    sizes = SIZES[quick]
    cells = []
    for pol in policies:
        cells.append(Cell(pol, "nominal", states=states))
        for name in PERTURBABLE:
            cells += [Cell(pol, "parameter", s, name, states=states) for s in sizes["parameter"]]
        cells += [Cell(pol, "joint", s, draws=DRAWS[quick], states=states) for s in sizes["joint"]]
        for fam in ("noise", "delay", "torque_limit"):
            cells += [Cell(pol, fam, s, states=states) for s in sizes[fam]]
    return cells


# --------------------------------------------------------------------------- 1. open loop
def open_loop(*, nthread=None) -> tuple[dict, object]:
    err = one_step_error(TABLE_I, nthread=nthread)
    x = err.centers[:, None, :].repeat(len(err.actions), 1)
    tau = np.broadcast_to(err.actions[None], x.shape[:-1] + (2,))
    integ = integration_error(dynamics.full_acceleration, TABLE_I, x, tau,
                              reference_substeps=100)
    return {"transitions": int(x.shape[0] * x.shape[1]), "summary": err.summary(),
            "integration_error_full": integ}, err


# --------------------------------------------------------------------------- 2. closed loop
def _stats(st: np.ndarray) -> dict:
    fin = st[np.isfinite(st)]
    q = (lambda v: float(np.quantile(fin, v)) if len(fin) else None)
    return {"settled": float(len(fin) / len(st)), "median": q(0.5), "p90": q(0.9),
            "max": float(fin.max()) if len(fin) else None}


def closed_loop(policies=POLICIES, *, nthread=None, progress=False) -> tuple[dict, dict]:
    """Each policy on each plant from the evaluation set: metrics, and settle times."""
    x0 = evaluation_set()
    out, settle = {}, {}
    mj = MujocoPlant(TABLE_I, nthread=nthread)
    try:
        for name in policies:
            policy = load_policy(name)
            trajs = {}
            out[name] = {}
            for plant_name in PLANTS:
                plant = mj if plant_name == "mujoco" else make_plant(plant_name)
                tr = rollout(policy, plant, x0, duration=HORIZON)
                trajs[plant_name] = tr
                st = settle_time(tr)
                settle[(name, plant_name)] = st
                out[name][plant_name] = {
                    "success_rate": float(success(tr).mean()),
                    "x0_settle_time": float(st[0]) if math.isfinite(st[0]) else None,
                    "settle_time": _stats(st),
                    "mean_return": float(discounted_return(tr).mean())}
            for plant_name in ("simplified", "full"):
                gap = trajectory_gap(trajs[plant_name], trajs["mujoco"])
                out[name][plant_name]["gap_to_mujoco"] = {
                    k: float(v.mean()) for k, v in gap.items()}
            if progress:
                print(f"  closed loop: {name} done", flush=True)
    finally:
        mj.close()
    return out, settle


def gap_closure(closed: dict) -> dict:
    """For each paper policy: success on MuJoCo before and after synthesis on (6)."""
    out = {}
    for paper, full in COUNTERPART.items():
        if paper not in closed or full not in closed:
            continue
        a, b = closed[paper], closed[full]
        gap = a["simplified"]["success_rate"] - a["mujoco"]["success_rate"]
        out[paper] = {"full_model_policy": full,
                      "success_simplified_plant": a["simplified"]["success_rate"],
                      "success_mujoco": a["mujoco"]["success_rate"],
                      "success_mujoco_full_model_policy": b["mujoco"]["success_rate"],
                      "gain_on_mujoco": b["mujoco"]["success_rate"] - a["mujoco"]["success_rate"],
                      "gap_simplified_minus_mujoco": gap,
                      "x0_settle_time_mujoco": a["mujoco"]["x0_settle_time"],
                      "x0_settle_time_mujoco_full_model_policy": b["mujoco"]["x0_settle_time"]}
    return out


# --------------------------------------------------------------------------- 4. robustness
def robustness(results: dict, policies=POLICIES) -> dict:
    """Success rate against perturbation size, per policy and family (and parameter)."""
    curves: dict = {}
    for rec in results.values():
        c = rec["cell"]
        if c["policy"] not in policies:
            continue
        fam = c["family"]
        key = f"parameter:{c['name']}" if fam == "parameter" else fam
        curves.setdefault(c["policy"], {}).setdefault(key, {})[c["size"]] = rec["success_rate"]
    for pol, fams in curves.items():
        nominal = fams.pop("nominal", {}).get(0.0)
        for key, pts in fams.items():
            if nominal is not None:
                pts.setdefault(0.0, nominal)      # size 0 of every family is the nominal cell
            fams[key] = {float(s): pts[s] for s in sorted(pts)}
        fams["nominal"] = nominal
    return curves


def margin(curve: dict, threshold: float = THRESHOLD):
    """Largest tested |size| such that every tested size no larger in magnitude (either
    sign) keeps success >= threshold; None when the unperturbed plant already falls short."""
    if curve.get(0.0) is None or curve[0.0] < threshold:
        return None
    best = 0.0
    for m in sorted({abs(s) for s in curve}):
        if not all(v >= threshold for s, v in curve.items() if abs(s) <= m):
            break
        best = m
    return best


def margins(curves: dict, threshold: float = THRESHOLD) -> dict:
    out = {}
    for pol, fams in curves.items():
        m = {key: margin(pts, threshold) for key, pts in fams.items() if key != "nominal"}
        params = [m[k] for k in m if k.startswith("parameter:")]
        m["every_parameter_alone"] = (None if any(v is None for v in params) else
                                      min(params)) if params else None
        out[pol] = m
    return out


# --------------------------------------------------------------------------- throughput
def throughput(*, rows: int, samples: int, nthread: int, repeats: int = 3) -> dict:
    """Closed-loop batched rollout steps per second against one open-loop
    ``mujoco.rollout`` call over the same number of MuJoCo steps, measured in one run."""
    from mujoco import rollout as mj_rollout
    import mujoco

    x0 = np.tile(evaluation_set(), (math.ceil(rows / 65), 1))[:rows]
    policy = load_policy("centralized_full")
    plant = MujocoPlant(TABLE_I, nthread=nthread)
    closed = open_ = math.inf
    try:
        nstep = plant.nstep * samples
        state0 = np.zeros((rows, plant.nstate))
        state0[:, 1:5] = x0
        control = np.zeros((rows, nstep, 2))
        datas = [mujoco.MjData(plant.model) for _ in range(nthread)]
        with mj_rollout.Rollout(nthread=nthread if nthread > 1 else 0) as pool:
            for _ in range(repeats):              # interleaved, best of each: fair on a busy machine
                t0 = time.perf_counter()
                rollout(policy, plant, x0, duration=samples * TS)
                closed = min(closed, time.perf_counter() - t0)
                t0 = time.perf_counter()
                pool.rollout(plant.model, datas, state0, control, nstep=nstep)
                open_ = min(open_, time.perf_counter() - t0)
    finally:
        plant.close()
    steps = rows * samples * plant.nstep
    return {"rows": rows, "samples": samples, "mujoco_steps": steps, "nthread": nthread,
            "repeats": repeats,
            "closed_loop_seconds": closed, "open_loop_seconds": open_,
            "closed_loop_steps_per_s": steps / closed, "open_loop_steps_per_s": steps / open_,
            "ratio_closed_to_open": open_ / closed}


# --------------------------------------------------------------------------- the report
def build(*, quick: bool = False, policies=POLICIES, results_path=None, executor="local",
          workers=None, address=None, nthread=None, progress=False) -> tuple[dict, dict]:
    """Measure 1-4 and the throughput; returns the JSON-ready report and plot data."""
    policies = tuple(policies)
    loaded = {name: load_policy(name) for name in policies}      # bad names fail first
    digests = {name: policy_digest(p) for name, p in loaded.items()}
    t_start = time.perf_counter()
    log = (lambda msg: print(msg, flush=True)) if progress else (lambda msg: None)
    stages = {}

    def stage(name):
        log(f"{name} ...")
        stages[name] = time.perf_counter()

    stage("open_loop")
    ol, err = open_loop(nthread=nthread)
    stage("closed_loop")
    cl, settle = closed_loop(policies, nthread=nthread, progress=progress)
    stage("sweep")
    cells = sweep_cells(policies, quick=quick)
    results = run_sweep(cells, results_path, executor=executor, workers=workers,
                        address=address, progress=progress, digests=digests)
    curves = robustness(results, policies)
    stage("throughput")
    tp = throughput(rows=130 if quick else 520, samples=20 if quick else 100,
                    nthread=nthread or 2, repeats=2 if quick else 3)
    stage("end")
    names = list(stages)
    stage_seconds = {a: stages[b] - stages[a] for a, b in zip(names, names[1:])}
    report = {
        "quick": quick, "policies": list(policies), "plants": list(PLANTS),
        "evaluation_set": {"closed_loop": int(len(evaluation_set())),
                           "sweeps": int(len(states_of("quick" if quick else "full")))},
        "open_loop": ol, "closed_loop": cl, "gap_closure": gap_closure(cl),
        "robustness": {"threshold": THRESHOLD, "sizes": SIZES[quick], "units": UNITS,
                       "joint_draws": DRAWS[quick], "cells": len(cells), "curves": curves,
                       "margins": margins(curves)},
        "throughput": tp, "policy_digests": digests,
        "seconds": time.perf_counter() - t_start, "stage_seconds": stage_seconds,
        "provenance": provenance()}
    return report, {"error": err, "settle": settle}


def summary(report: dict) -> dict:
    """What ``twolink mismatch --json`` prints."""
    return {"success_rate": {p: {pl: v["success_rate"] for pl, v in d.items()}
                             for p, d in report["closed_loop"].items()},
            "open_loop": report["open_loop"]["summary"],
            "integration_error_full": report["open_loop"]["integration_error_full"],
            "gap_closure": report["gap_closure"],
            "margins": report["robustness"]["margins"],
            "throughput": report["throughput"], "quick": report["quick"],
            "seconds": report["seconds"], "stage_seconds": report["stage_seconds"]}


# --------------------------------------------------------------------------- figures
def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _save(fig, path: Path) -> str:
    from twolink.artifacts import atomic_path
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=90, format="png")
    _plt().close(fig)
    return path.name


def heatmap_figure(err, path: Path) -> str:
    """Max |speed error| of each prediction over (theta1, dtheta1) and (theta2, dtheta2)."""
    from matplotlib.colors import LogNorm
    plt = _plt()
    from twolink import fuzzy
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
    plt = _plt()
    cl = report["closed_loop"]
    pols = list(cl)
    fig, (a, b) = plt.subplots(1, 2, figsize=(13, 4.2))
    w = 0.8 / len(PLANTS)
    for j, plant in enumerate(PLANTS):
        a.bar(np.arange(len(pols)) + (j - 1) * w, [cl[p][plant]["success_rate"] for p in pols],
              w, label=plant)
    a.set_xticks(range(len(pols)), pols, rotation=20, fontsize=8)
    a.set_ylabel("success rate")
    a.set_ylim(0, 1.05)
    a.set_title("success over the evaluation set (65 states)")
    a.legend(fontsize=8)
    styles = {"simplified": ":", "full": "--", "mujoco": "-"}
    for i, p in enumerate(pols):
        for plant in ("simplified", "mujoco"):
            st = np.sort(settle[(p, plant)])
            frac = np.arange(1, len(st) + 1) / len(st)
            fin = np.isfinite(st)
            b.step(np.append(st[fin], HORIZON), np.append(frac[fin], frac[fin][-1] if fin.any()
                                                            else 0.0),
                   styles[plant], color=f"C{i}", where="post",
                   label=f"{p} ({plant})")
    b.set_xlabel("settle time [s]")
    b.set_ylabel("fraction of initial states settled")
    b.set_xlim(0, HORIZON)
    b.set_title("settle-time distribution: dotted simplified, solid MuJoCo")
    b.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    return _save(fig, path)


def robustness_figure(report: dict, keys, path: Path, title: str) -> str:
    """Success rate against perturbation size, one panel per family, one line per policy."""
    plt = _plt()
    curves = report["robustness"]["curves"]
    n = len(keys)
    ncol = min(4, n)
    nrow = math.ceil(n / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(3.6 * ncol, 2.9 * nrow), squeeze=False)
    for ax, key in zip(axes.ravel(), keys):
        for i, p in enumerate(curves):
            pts = curves[p].get(key, {})
            if pts:
                ax.plot(list(pts), list(pts.values()), "o-", ms=3, color=f"C{i}", label=p)
        ax.axhline(THRESHOLD, color="grey", lw=0.8, ls=":")
        fam = key.split(":")[0]
        ax.set_title(key.replace("parameter:", "parameter "), fontsize=9)
        ax.set_xlabel(UNITS[fam], fontsize=8)
        ax.set_ylim(-0.03, 1.03)
    for ax in axes.ravel()[n:]:
        ax.axis("off")
    axes[0, 0].set_ylabel("success rate")
    axes[0, 0].legend(fontsize=6)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


# --------------------------------------------------------------------------- markdown
def _pct(v):
    return "-" if v is None else f"{100 * v:.1f} %"


def _num(v, fmt="{:.3g}", none="never"):
    return none if v is None else fmt.format(v)


def _table(header, rows) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(lines)


def markdown(report: dict, figures: dict, command: str) -> str:
    """The report as Markdown; every number comes from ``report``."""
    ol, cl, rb = report["open_loop"], report["closed_loop"], report["robustness"]
    out = ["# Model mismatch and robustness", "",
           f"Produced by `{command}` in {report['seconds']:.0f} s "
           f"(twolink {report['provenance']['twolink_version']}, "
           f"MuJoCo {report['provenance']['mujoco_version']}, "
           f"{report['provenance']['cpu_count']} CPUs). The numbers below are recomputed "
           "from rollouts each time; report.json holds them all.", "",
           "## 1. Open-loop model error", "",
           f"One sample period (Ts = 0.05 s) from every bin centre of the centralized grid "
           f"under every action ({ol['transitions']} transitions), each prediction minus "
           "MuJoCo (angles in rad, speeds in rad/s).", ""]
    rows = []
    for name, comps in ol["summary"].items():
        for comp, v in comps.items():
            rows.append((name, comp, f"{v['max']:.3g}", f"{v['rms']:.3g}"))
    out += [_table(("prediction", "component", "max |error|", "RMS error"), rows), ""]
    ie = ol["integration_error_full"]
    out += [f"Integration accuracy of the numpy plants (RK4, {ie['substeps']} substeps, against "
            f"{ie['reference_substeps']} substeps) over the same transitions: max "
            f"{max(ie['max']):.2g}. MuJoCo runs the same RK4 step, so (6) agrees with it to "
            f"round-off (max {max(v['max'] for v in ol['summary']['full'].values()):.2g}), "
            "well inside integration accuracy; the simplified model (11) is off by up to "
            f"{max(v['max'] for v in ol['summary']['simplified'].values()):.3g} rad/s "
            "in one sample.", "", f"![one-step error heat maps]({figures['heatmaps']})", ""]
    out += ["## 2. Closed-loop gap", "",
            f"Each policy on each plant from the {report['evaluation_set']['closed_loop']} "
            "states of the evaluation set (paper x0 + 8x8 grid of angle pairs at rest), "
            "5 s horizon. Gap = RMS over time of the wrapped angle difference to the MuJoCo "
            "trajectory from the same x0, mean over states.", ""]
    rows = []
    for p, d in cl.items():
        for plant, v in d.items():
            st = v["settle_time"]
            gap = v.get("gap_to_mujoco", {}).get("angle_rms")
            rows.append((p, plant, _pct(v["success_rate"]), _num(v["x0_settle_time"]),
                         _pct(st["settled"]), _num(st["median"], none="-"),
                         _num(st["p90"], none="-"), f"{v['mean_return']:.2f}",
                         "-" if gap is None else f"{gap:.3g}"))
    out += [_table(("policy", "plant", "success", "settle from x0 [s]", "settled",
                    "median settle [s]", "p90 settle [s]", "mean return",
                    "angle gap to MuJoCo [rad]"), rows), "",
            f"![closed loop]({figures['closed_loop']})", ""]
    out += ["## 3. Closing the gap: synthesis on the full model (6)", "",
            "`centralized_full` is the centralized policy synthesised on (6). "
            "`decentralized_full` keeps the paper's information structure: agent 2 sees only "
            "link 2 and assumes link 1 at rest (dtheta1 = 0, tau1 = 0) in its model (6); "
            "agent 1 uses (6) with link 2 held at rest over its transition (frozen context). "
            "The open-loop cost of agent 2's assumption is the `agent2_assumption` row above.",
            ""]
    rows = []
    for p, g in report["gap_closure"].items():
        rows.append((p, _pct(g["success_simplified_plant"]), _pct(g["success_mujoco"]),
                     g["full_model_policy"], _pct(g["success_mujoco_full_model_policy"]),
                     f"{100 * g['gain_on_mujoco']:+.1f} pp",
                     f"{_num(g['x0_settle_time_mujoco'])} -> "
                     f"{_num(g['x0_settle_time_mujoco_full_model_policy'])}"))
    out += [_table(("paper policy", "success, simplified plant", "success, MuJoCo",
                    "synthesised on (6)", "its success, MuJoCo", "gain on MuJoCo",
                    "settle from x0 on MuJoCo [s]"), rows), ""]
    out += ["## 4. Robustness", "",
            f"MuJoCo plant perturbed; success over {report['evaluation_set']['sweeps']} initial "
            f"states per plant; {rb['cells']} cells. Margin = the largest tested perturbation "
            f"such that every tested size up to it (both signs) keeps success >= "
            f"{100 * rb['threshold']:.0f} %; `none` = the policy falls short of that "
            "already on the nominal plant. Joint: all parameters at once, uniform in "
            f"[-size, size], {rb['joint_draws']} random plants per size. Noise: angle std in "
            "degrees, speed std scaled so that 5 deg <-> 0.1 rad/s.", ""]
    fams = ("every_parameter_alone", "joint", "noise", "delay", "torque_limit")
    rows = []
    for p, m in rb["margins"].items():
        rows.append([p, _pct(rb["curves"][p]["nominal"])] +
                    [_num(m.get(f), "{:g}", none="none") for f in fams])
    out += [_table(("policy", "nominal success", "each parameter alone", "joint", "noise [deg]",
                    "delay [samples]", "torque limit"), rows), ""]
    rows = []
    for p, m in rb["margins"].items():
        rows.append([p] + [_num(m.get(f"parameter:{n}"), "{:g}", none="none")
                           for n in PERTURBABLE])
    out += ["Margin per parameter (relative change):", "",
            _table(["policy"] + list(PERTURBABLE), rows), "",
            f"![robustness, parameters]({figures['robustness_parameters']})", "",
            f"![robustness, other]({figures['robustness_other']})", ""]
    tp = report["throughput"]
    out += ["## Sweep throughput", "",
            f"{tp['rows']} rollouts x {tp['samples']} samples = {tp['mujoco_steps']} MuJoCo "
            f"steps, {tp['nthread']} threads: closed loop (batched policy + `mujoco.rollout` "
            f"per sample) {tp['closed_loop_steps_per_s']:.3g} steps/s, open-loop "
            f"`mujoco.rollout` of the same steps {tp['open_loop_steps_per_s']:.3g} steps/s: "
            f"ratio {tp['ratio_closed_to_open']:.2f}.", ""]
    return "\n".join(out)


def write(report: dict, data: dict, outdir: Path, command: str) -> dict:
    """Figures, report.json and report.md under ``outdir`` (each written atomically)."""
    from twolink.artifacts import write_json, write_text
    figures = {
        "heatmaps": heatmap_figure(data["error"], outdir / "model_error.png"),
        "closed_loop": closed_loop_figure(report, data["settle"], outdir / "closed_loop.png"),
        "robustness_parameters": robustness_figure(
            report, [f"parameter:{n}" for n in PERTURBABLE],
            outdir / "robustness_parameters.png", "success vs one Table I parameter changed"),
        "robustness_other": robustness_figure(
            report, ["joint", "noise", "delay", "torque_limit"], outdir / "robustness_other.png",
            "success vs joint random parameters, state noise, actuation delay, torque limits"),
    }
    report = dict(report, figures=figures, command=command)
    write_json(outdir / "report.json", report)
    write_text(outdir / "report.md", markdown(report, figures, command) + "\n")
    return report
