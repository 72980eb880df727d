"""Rollout benchmarks: closed-loop batched rollouts on MuJoCo against open-loop
``mujoco.rollout`` of the same model and the same physics steps (the engine's limit
here), measured by :func:`twolink.studies.throughput.measure` (as the mismatch report's
throughput is); and the numpy plants.
"""
from __future__ import annotations

import os

import numpy as np

from benchmarks.common import Row, best_time
from twolink.arm.parameters import TS
from twolink.policy.fuzzy_policy import Policy
from twolink.policy.registry import SHIPPED
from twolink.sim.plants import MujocoPlant, make_plant
from twolink.sim.rollout import steps_for
from twolink.studies.throughput import measure

SECTION = "rollouts"


def _policy():
    """The shipped centralized policy, or one synthesised now if it is missing."""
    path = SHIPPED["centralized"].file
    if path.is_file():
        return Policy.load(path)
    from twolink.synthesis.synthesize import synthesize

    return synthesize("centralized")


def initial_states(batch: int, seed: int = 0) -> np.ndarray:
    """``batch`` initial states: angles uniform over the circle, speeds in +-pi rad/s."""
    rng = np.random.default_rng(seed)
    x0 = np.empty((batch, 4))
    x0[:, :2] = rng.uniform(-np.pi, np.pi, (batch, 2))
    x0[:, 2:] = rng.uniform(-np.pi, np.pi, (batch, 2))
    return x0


def bench_rollouts(*, batch: int = 64, duration: float = 5.0, repeats: int = 3,
                   threads=None) -> tuple[list[Row], dict]:
    """Closed-loop MuJoCo rollouts per thread count, the open-loop limit, numpy plants."""
    policy = _policy()
    x0 = initial_states(batch)
    k = steps_for(duration)
    threads = threads or sorted({1, os.cpu_count() or 1})
    rows, summary = [], {}
    for nthread in threads:
        sec = f"{SECTION}: mujoco, {nthread} thread{'s' if nthread > 1 else ''}"
        tp = measure(policy, x0, samples=k, nthread=nthread, repeats=repeats)
        closed_sps, open_sps = tp.closed_loop_steps_per_s, tp.open_loop_steps_per_s
        rows += [
            Row(sec, "closed loop: physics steps/s", closed_sps, "steps/s",
                f"{batch} states x {k} samples x {tp.nstep} steps, policy (14) each sample"),
            Row(sec, "closed loop: physics steps/s per thread", closed_sps / nthread,
                "steps/s"),
            Row(sec, "closed loop: sample periods/s", batch * k / tp.closed_loop_seconds,
                "samples/s", f"real time x {batch * k * TS / tp.closed_loop_seconds:,.0f}"),
            Row(sec, "closed loop: share in policy (14)", tp.policy_share, "share",
                "numpy interpolation over the fuzzy grid"),
            Row(sec, "open loop mujoco.rollout: physics steps/s", open_sps, "steps/s",
                "one call, same model, same steps and torques"),
            Row(sec, "closed / open loop", tp.ratio_closed_to_open, "x",
                "figure of merit, 1 = the engine's limit"),
        ]
        summary[nthread] = {"closed_steps_per_s": closed_sps, "open_steps_per_s": open_sps,
                            "policy_share": tp.policy_share}

    sec = f"{SECTION}: numpy plants"
    tau = np.asarray(policy(x0))
    for name in ("simplified", "full"):
        plant = make_plant(name)
        t, _ = best_time(lambda: [plant.step(x0, tau) for _ in range(10)], repeats)
        rows.append(Row(sec, f"{name}: sample periods/s", batch * 10 / t, "samples/s",
                        f"batch {batch}, RK4 x {plant.substeps} substeps per Ts"))
        summary[name] = batch * 10 / t
    with MujocoPlant(nthread=1) as plant:
        t, _ = best_time(lambda: [plant.step(x0, tau) for _ in range(10)], repeats)
    rows.append(Row(sec, "mujoco (for comparison): sample periods/s", batch * 10 / t,
                    "samples/s", f"batch {batch}, 1 thread, {plant.nstep} RK4 steps per Ts"))
    return rows, summary
