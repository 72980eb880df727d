"""Closed-loop rollout throughput against MuJoCo's own limit, measured in one run.

A closed-loop rollout of B initial states over K sample periods does B * K * nstep MuJoCo
steps (nstep = Ts / timestep), one ``mujoco.rollout`` call of nstep steps per sample for
the whole batch, with the policy (14) evaluated in numpy between calls. The open-loop
reference does the same B * K * nstep steps in a single ``mujoco.rollout`` call, with the
torques the closed loop applied. The sweeps' report and ``benchmarks/rollouts.py`` both
measure through :func:`measure`.
"""
from __future__ import annotations

import dataclasses
import math
import time

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

from twolink.arm.parameters import TS
from twolink.sim.plants import MujocoPlant, check_states, physics_state
from twolink.sim.rollout import rollout


@dataclasses.dataclass(frozen=True)
class Throughput:
    """Best-of-``repeats`` wall times of the closed loop, the open-loop reference over the
    same ``mujoco_steps``, and the policy alone over the closed loop's states; the rates
    are steps over those times, and ``ratio_closed_to_open`` = 1 is MuJoCo's own limit."""

    rows: int
    samples: int
    nstep: int
    nthread: int
    repeats: int
    closed_loop_seconds: float
    open_loop_seconds: float
    policy_seconds: float
    mujoco_steps: int = dataclasses.field(init=False)
    closed_loop_steps_per_s: float = dataclasses.field(init=False)
    open_loop_steps_per_s: float = dataclasses.field(init=False)
    ratio_closed_to_open: float = dataclasses.field(init=False)
    policy_share: float = dataclasses.field(init=False)

    def __post_init__(self):
        steps = self.rows * self.samples * self.nstep
        derived = {"mujoco_steps": steps,
                   "closed_loop_steps_per_s": steps / self.closed_loop_seconds,
                   "open_loop_steps_per_s": steps / self.open_loop_seconds,
                   "ratio_closed_to_open": self.open_loop_seconds / self.closed_loop_seconds,
                   "policy_share": self.policy_seconds / self.closed_loop_seconds}
        for name, value in derived.items():
            object.__setattr__(self, name, value)

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


def measure(policy, x0, *, samples: int, nthread: int, repeats: int = 3) -> Throughput:
    """Time ``policy`` closed-loop on MuJoCo from ``x0`` (B, 4) for ``samples`` periods
    against open-loop ``mujoco.rollout`` of the same steps, turn about, best of each."""
    x0 = check_states(x0, what="x0")
    if x0.ndim != 2:
        raise ValueError(f"x0 must be a batch of states (B, 4), got shape {x0.shape}")
    if int(samples) != samples or samples < 1 or int(nthread) != nthread or nthread < 1:
        raise ValueError(f"samples and nthread must be positive whole numbers, got "
                         f"{samples} and {nthread}")
    duration = samples * TS
    with MujocoPlant(nthread=nthread) as plant:
        traj = rollout(policy, plant, x0, duration=duration)
        nstep, model = plant.nstep, plant.model
        state0 = physics_state(x0)
        control = np.repeat(traj.u, nstep, axis=1)
        datas = [mujoco.MjData(model) for _ in range(nthread)]
        runs = {"closed": lambda: rollout(policy, plant, x0, duration=duration),
                "open": lambda: pool.rollout(model, datas, state0, control),
                "policy": lambda: [policy(traj.x[:, k]) for k in range(samples)]}
        best = dict.fromkeys(runs, math.inf)
        with mj_rollout.Rollout(nthread=nthread if nthread > 1 else 0) as pool:
            for _ in range(max(1, repeats)):     # interleaved: each sees the same load
                for key, run in runs.items():
                    t0 = time.perf_counter()
                    out = run()
                    best[key] = min(best[key], time.perf_counter() - t0)
                    if key == "open":
                        state = out[0]
    if state.shape != (len(x0), samples * nstep, state0.shape[1]) or \
            not np.all(np.isfinite(state)):
        raise RuntimeError("open-loop rollout returned an unexpected state array")
    return Throughput(len(x0), samples, nstep, nthread, max(1, repeats),
                      best["closed"], best["open"], best["policy"])
