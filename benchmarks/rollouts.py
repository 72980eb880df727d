"""Rollout benchmarks: closed-loop batched rollouts on MuJoCo against open-loop
``mujoco.rollout`` of the same model and the same physics steps (the engine's limit
here), and the numpy plants.

A closed-loop rollout of B initial states over K sample periods does B * K * nstep
MuJoCo steps (nstep = Ts / timestep = 10), one ``mujoco.rollout`` call of nstep steps
per sample period for the whole batch, with the policy (14) evaluated in numpy between
calls. The open-loop reference does the same B * K * nstep steps in a single call, with
the torques the closed loop applied.
"""
from __future__ import annotations

import os

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

from benchmarks.common import Row, best_time, interleaved_best
from twolink.parameters import TS
from twolink.plants import MujocoPlant, make_plant
from twolink.policy import Policy
from twolink.registry import SHIPPED
from twolink.rollout import rollout, steps_for

SECTION = "rollouts"


def _policy():
    """The shipped centralized policy, or one synthesised now if it is missing."""
    path = SHIPPED["centralized"].file
    if path.is_file():
        return Policy.load(path)
    from twolink.synthesis import synthesize

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
        plant = MujocoPlant(nthread=nthread)
        try:
            traj = rollout(policy, plant, x0, duration=duration)
            physics = batch * k * plant.nstep
            pool = mj_rollout.Rollout(nthread=nthread if nthread > 1 else 0)
            model = plant.model
            nstate = mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS)
            state0 = np.zeros((batch, nstate))
            state0[:, 1:3], state0[:, 3:5] = x0[:, :2], x0[:, 2:]
            control = np.repeat(traj.u, plant.nstep, axis=1)
            datas = [mujoco.MjData(model) for _ in range(nthread)]
            try:
                best, out = interleaved_best({
                    "closed": lambda: rollout(policy, plant, x0, duration=duration),
                    "open": lambda: pool.rollout(model, datas, state0, control),
                    "policy": lambda: [policy(traj.x[:, i]) for i in range(k)]}, repeats)
            finally:
                pool.close()
            t_closed, t_open, t_policy = best["closed"], best["open"], best["policy"]
            state = out["open"][0]
        finally:
            plant.close()
        if state.shape != (batch, k * plant.nstep, nstate) or not np.all(np.isfinite(state)):
            raise RuntimeError("open-loop rollout returned an unexpected state array")
        closed_sps, open_sps = physics / t_closed, physics / t_open
        rows += [
            Row(sec, "closed loop: physics steps/s", closed_sps, "steps/s",
                f"{batch} states x {k} samples x {plant.nstep} steps, policy (14) each sample"),
            Row(sec, "closed loop: physics steps/s per thread", closed_sps / nthread,
                "steps/s"),
            Row(sec, "closed loop: sample periods/s", batch * k / t_closed, "samples/s",
                f"real time x {batch * k * TS / t_closed:,.0f}"),
            Row(sec, "closed loop: share in policy (14)", t_policy / t_closed, "share",
                "numpy interpolation over the fuzzy grid"),
            Row(sec, "open loop mujoco.rollout: physics steps/s", open_sps, "steps/s",
                "one call, same model, same steps and torques"),
            Row(sec, "closed / open loop", closed_sps / open_sps, "x",
                "figure of merit, 1 = the engine's limit"),
        ]
        summary[nthread] = {"closed_steps_per_s": closed_sps, "open_steps_per_s": open_sps,
                            "policy_share": t_policy / t_closed}

    sec = f"{SECTION}: numpy plants"
    tau = np.asarray(policy(x0))
    for name in ("simplified", "full"):
        plant = make_plant(name)
        t, _ = best_time(lambda: [plant.step(x0, tau) for _ in range(10)], repeats)
        rows.append(Row(sec, f"{name}: sample periods/s", batch * 10 / t, "samples/s",
                        f"batch {batch}, RK4 x {plant.substeps} substeps per Ts"))
        summary[name] = batch * 10 / t
    plant = MujocoPlant(nthread=1)
    try:
        t, _ = best_time(lambda: [plant.step(x0, tau) for _ in range(10)], repeats)
    finally:
        plant.close()
    rows.append(Row(sec, "mujoco (for comparison): sample periods/s", batch * 10 / t,
                    "samples/s", f"batch {batch}, 1 thread, {plant.nstep} RK4 steps per Ts"))
    return rows, summary
