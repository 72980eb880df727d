"""The model-mismatch measurements: open-loop error, closed-loop gap, its closure, robustness.

1. open loop - one-step error of (11), (6) and agent 2's assumption against MuJoCo
   (:mod:`twolink.studies.mismatch.model_error`), beside the RK4 integration error of the numpy plants;
2. closed loop - each policy on each plant over the evaluation set: success rate,
   settle-time distribution, return, trajectory gap to MuJoCo;
3. closing the gap - the policies synthesised on (6) against the paper's, on MuJoCo;
4. robustness - the sweep of a :mod:`twolink.studies.mismatch.plan` plan (:mod:`twolink.sim.cells`)
   and a margin per policy and family (with its counts, Wilson intervals, the worst of
   the random plants and the worst-case return of each joint size);
5. the robust section - every policy under every challenge level, with and without
   run-time compensation (:mod:`twolink.studies.robustness`);
6. throughput of the batched closed loop (:mod:`twolink.studies.throughput`).

Everything here returns data (plain dicts, JSON-ready, in a fixed order: policies in
registry order, families and parameters in :data:`twolink.studies.mismatch.plan.CURVES` order,
sizes ascending). Figures live in :mod:`twolink.studies.mismatch.figures`, the Markdown in
:mod:`twolink.studies.mismatch.report`. Every number is recomputed from rollouts; only finished
sweep cells of the same policy files are reused from the sweep file (resume).
"""
from __future__ import annotations

import math
import time
from typing import Optional

import numpy as np

from twolink.arm import dynamics
from twolink.arm.integrate import integration_error
from twolink.arm.parameters import HORIZON, TABLE_I
from twolink.artifacts import provenance
from twolink.policy.fuzzy_policy import load_policy
from twolink.policy.registry import COUNTERPART
from twolink.sim.cell_store import CellFile
from twolink.sim.cells import policy_digest, evaluate_cells
from twolink.sim.metrics import (
    discounted_return,
    evaluation_set,
    settle_time,
    success,
    trajectory_gap,
    wilson_interval,
)
from twolink.sim.plants import PLANTS, MujocoPlant, make_plant
from twolink.sim.rollout import rollout
from twolink.studies.mismatch.model_error import one_step_error
from twolink.studies.mismatch.plan import CURVES, UNITS, Plan, axis, report_order
from twolink.studies.robustness import study
from twolink.studies.throughput import measure

#: Success rate a perturbed plant must keep for a size to count inside the margin.
THRESHOLD = 0.95


# --------------------------------------------------------------------------- 1. open loop
def open_loop(*, nthread=None) -> tuple[dict, object]:
    """Summary of the one-step errors (JSON-ready) and the errors themselves."""
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


def closed_loop(policies, *, nthread=None, log=None) -> tuple[dict, dict]:
    """Each policy on each plant from the evaluation set: metrics, and settle times."""
    x0 = evaluation_set()
    out, settle = {}, {}
    with MujocoPlant(TABLE_I, nthread=nthread) as mj:
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
                    "successes": int(success(tr).sum()), "states": int(len(x0)),
                    "x0_settle_time": float(st[0]) if math.isfinite(st[0]) else None,
                    "settle_time": _stats(st),
                    "mean_return": float(discounted_return(tr).mean())}
            for plant_name in ("simplified", "full"):
                gap = trajectory_gap(trajs[plant_name], trajs["mujoco"])
                out[name][plant_name]["gap_to_mujoco"] = {
                    k: float(v.mean()) for k, v in gap.items()}
            if log is not None:
                log(f"  closed loop: {name} done")
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
def _by_curve(results: dict, policies, value) -> dict:
    """``value(record)`` per policy, curve of CURVES and size: policies in registry order,
    curves in CURVES order, sizes ascending, size 0 of every curve the nominal cell,
    ``nominal`` last; the order of ``results`` does not matter."""
    points: dict = {}
    for rec in results.values():
        c = rec["cell"]
        on = axis(c) if c["policy"] in policies else None
        if on is None:
            continue
        key, size = on
        points.setdefault(c["policy"], {}).setdefault(key, {})[size] = value(rec)
    out = {}
    for pol in report_order(points):
        fams = points[pol]
        nominal = fams.get("nominal", {}).get(0.0)
        out[pol] = {}
        for key in CURVES:
            if key in fams:
                pts = dict(fams[key])
                if nominal is not None:
                    pts.setdefault(0.0, nominal)
                out[pol][key] = {s: pts[s] for s in sorted(pts)}
        out[pol]["nominal"] = nominal
    return out


def robustness(results: dict, policies) -> dict:
    """Success rate against perturbation size, per policy and curve of CURVES (in the
    order of :func:`_by_curve`)."""
    return _by_curve(results, policies, lambda rec: rec["success_rate"])


def counts(results: dict, policies) -> dict:
    """``[successes, rows]`` per policy, curve and size, in the order of :func:`robustness`
    (a joint size counts every state of every one of its random plants)."""
    return _by_curve(results, policies,
                     lambda rec: [int(sum(rec["successes"])), len(rec["successes"])])


def worst_plants(results: dict, policies) -> dict:
    """Joint-perturbation cells: the worst of their random plants, per policy and size.

    A joint cell's rows are its plants (outer) by its initial states (inner); each plant's
    success is counted over its own states, and the plant with the fewest successes is
    reported as ``{"plant": index, "successes": k, "states": n, "plants": draws}``, beside
    the worst-case return (the lowest discounted return of any row, as
    :attr:`twolink.sim.evaluation.Evaluation.worst_return`) and the mean return over every
    row (robust-RL benchmarks report both).
    """
    out: dict = {}
    for rec in results.values():
        c = rec["cell"]
        on = axis(c) if c["policy"] in policies else None
        if on is None or on[0] != "joint":
            continue
        ok = np.asarray(rec["successes"], dtype=bool).reshape(c["plants"], -1)
        k = ok.sum(axis=1)
        worst = int(np.argmin(k))
        out.setdefault(c["policy"], {})[on[1]] = {
            "plant": worst, "successes": int(k[worst]), "states": int(ok.shape[1]),
            "plants": int(c["plants"]), "worst_return": float(min(rec["returns"])),
            "mean_return": float(rec["mean_return"])}
    return {pol: {s: out[pol][s] for s in sorted(out[pol])} for pol in report_order(out)}


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


def margins(curves: dict, threshold: float = THRESHOLD, counted: Optional[dict] = None) -> dict:
    """Margin per policy and curve, and ``every_parameter_alone`` (the smallest of those
    of single parameters; None if any is None).

    With ``counted`` (:func:`counts`), also ``joint_lower_bound``: the joint margin by the
    rule applied to the lower end of each perturbed size's 95 % Wilson interval instead of
    its rate, so a size counts only when its success is known to clear the threshold (the
    nominal plant, one deterministic plant, is judged by its rate as in the rate rule).
    """
    out = {}
    for pol, fams in curves.items():
        m = {key: margin(pts, threshold) for key, pts in fams.items() if key != "nominal"}
        params = [m[k] for k in m if k.startswith("parameter:")]
        m["every_parameter_alone"] = (None if any(v is None for v in params) else
                                      min(params)) if params else None
        joint = (counted or {}).get(pol, {}).get("joint")
        if joint:
            m["joint_lower_bound"] = margin(
                {s: wilson_interval(*kn)[0] if s else kn[0] / kn[1]
                 for s, kn in joint.items()}, threshold)
        out[pol] = m
    return out


# --------------------------------------------------------------------------- the report
def build(plan: Plan, policies, *, store: Optional[CellFile] = None, executor="local",
          workers=None, address=None, nthread=None, log=None, progress: bool = False,
          robust: bool = True, levels=None, seed: Optional[int] = None
          ) -> tuple[dict, dict]:
    """Measure 1-5 and the robust section under ``plan``; returns the JSON-ready report
    and the plot data (one-step errors, settle times). Sweep results go to ``store`` when
    given. The robust section (:mod:`twolink.studies.robustness`) runs every challenge
    level, or ``levels``, from the plan's seed, or ``seed``; ``robust=False`` leaves it out."""
    policies = report_order(policies)
    loaded = {name: load_policy(name) for name in policies}      # bad names fail first
    digests = {name: policy_digest(p) for name, p in loaded.items()}
    t_start = time.perf_counter()
    stages = {}

    def stage(name):
        if log is not None:
            log(f"{name} ...")
        stages[name] = time.perf_counter()

    stage("open_loop")
    ol, err = open_loop(nthread=nthread)
    stage("closed_loop")
    cl, settle = closed_loop(policies, nthread=nthread, log=log)
    stage("sweep")
    cells = plan.cells(policies)
    stored = store.records if store is not None else {}
    reused = sum(1 for c in cells if c.key in stored
                 and stored[c.key].get("policy_digest") == digests.get(c.policy))
    results = evaluate_cells(cells, store=store, executor=executor, workers=workers,
                             address=address, progress=progress, digests=digests)
    curves = robustness(results, policies)
    counted = counts(results, policies)
    if robust:
        stage("robust")
        section, robust_settle = study(policies, plants=plan.robust_plants,
                                       states=plan.robust_states,
                                       seed=plan.robust_seed if seed is None else seed,
                                       levels=levels, progress=progress)
    stage("throughput")
    x0 = np.tile(evaluation_set(), (math.ceil(plan.throughput_rows / 65), 1))
    tp = measure(load_policy(plan.throughput_policy), x0[:plan.throughput_rows],
                 samples=plan.throughput_samples,
                 nthread=nthread or 2, repeats=plan.throughput_repeats)
    stage("end")
    names = list(stages)
    stage_seconds = {a: stages[b] - stages[a] for a, b in zip(names, names[1:])}
    report = {
        "plan": plan.name, "policies": list(policies), "plants": list(PLANTS),
        "evaluation_set": {"closed_loop": int(len(evaluation_set())),
                           "sweeps": plan.sweep_states()},
        "open_loop": ol, "closed_loop": cl, "gap_closure": gap_closure(cl),
        "robustness": {"threshold": THRESHOLD, "sizes": dict(plan.sizes), "units": UNITS,
                       "joint_draws": plan.joint_draws, "cells": len(cells),
                       "reused_cells": reused, "curves": curves,
                       "counts": counted, "margins": margins(curves, counted=counted),
                       "joint_worst_plant": worst_plants(results, policies)},
        "throughput": tp.as_dict(), "policy_digests": digests,
        **({"robust": section} if robust else {}),
        "seconds": time.perf_counter() - t_start, "stage_seconds": stage_seconds,
        "provenance": provenance()}
    data = {"error": err, "settle": settle}
    if robust:
        data["robust_settle"] = robust_settle
    return report, data
