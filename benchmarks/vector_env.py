"""Vector-environment benchmark: ``TwoLinkVectorEnv`` over N arms against raw
``mujoco.rollout`` on the same model and control period, side by side in one run.

Both do the same work: K sample periods of N arms, one ``mujoco.rollout`` call of
nstep = Ts / timestep physics steps per period for all N arms, under the same torques
(drawn once, uniform over the action box). The raw side is the engine alone: a
prepared control array, the state handed from one call to the next, nothing else. The
environment adds what a learner gets: action checks, the end of every period of
docs/conventions.md (wrapped angles, saturated speeds), reward (15), observations, truncation and next-step
autoreset. Gymnasium's ``SyncVectorEnv`` over N single environments (one plant call per
arm) is timed beside them, as what the batched path replaces.
"""
from __future__ import annotations

import os

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

from benchmarks.common import Row, interleaved_best
from twolink.arm.parameters import TABLE_I, TS
from twolink.envs.gym import TwoLinkEnv, TwoLinkVectorEnv
from twolink.sim.plants import physics_state

SECTION = "vector env"


def measure(*, num_envs: int = 64, samples: int = 100, nthread: int = 1,
            repeats: int = 3, sync: bool = True) -> dict:
    """Best-of-``repeats`` wall times (interleaved) of K = ``samples`` steps of the vector
    environment, of the raw rollout calls and (``sync``) of ``SyncVectorEnv``; the rates
    are arm-steps (one arm, one sample period) per second."""
    import gymnasium

    rng = np.random.default_rng(0)
    actions = rng.uniform(-TABLE_I.tau_max, TABLE_I.tau_max, (samples, num_envs, 2))
    kwargs = dict(x0="random", time_limit=samples * TS)
    vec = TwoLinkVectorEnv(num_envs, nthread=nthread, **kwargs)
    model, nstep = vec.plant.model, vec.plant.nstep
    x0, _ = vec.reset(seed=0)
    state0 = physics_state(x0)
    controls = np.repeat(actions[:, :, None, :], nstep, axis=2)      # (K, N, nstep, 2)
    datas = [mujoco.MjData(model) for _ in range(nthread)]
    envs = gymnasium.vector.SyncVectorEnv(
        [lambda: TwoLinkEnv(**kwargs) for _ in range(num_envs)]) if sync else None

    def run_vec():
        vec.reset(seed=0)
        for a in actions:
            vec.step(a)

    def run_raw():
        state = state0
        for control in controls:
            out, _ = pool.rollout(model, datas, state, control, nstep=nstep)
            state = out[:, -1]
        return state

    def run_sync():
        envs.reset(seed=0)
        for a in actions:
            envs.step(a)

    runs = {"vector": run_vec, "raw": run_raw}
    if sync:
        runs["sync"] = run_sync
    try:
        with mj_rollout.Rollout(nthread=nthread if nthread > 1 else 0) as pool:
            best, out = interleaved_best(runs, repeats)
    finally:
        vec.close()
        if envs is not None:
            envs.close()
    if not np.all(np.isfinite(out["raw"])):
        raise RuntimeError("the raw rollout went non-finite")
    arm_steps = num_envs * samples
    result = {"num_envs": num_envs, "samples": samples, "nstep": nstep, "nthread": nthread,
              "repeats": repeats, "seconds": best,
              "vector_steps_per_s": arm_steps / best["vector"],
              "raw_steps_per_s": arm_steps / best["raw"],
              "ratio_vector_to_raw": best["raw"] / best["vector"]}
    if sync:
        result["sync_steps_per_s"] = arm_steps / best["sync"]
        result["ratio_vector_to_sync"] = best["sync"] / best["vector"]
    return result


def bench_vector_env(*, num_envs: int = 64, samples: int = 100, repeats: int = 3,
                     threads=None) -> tuple[list[Row], dict]:
    """The vector environment against raw ``mujoco.rollout``, per thread count."""
    threads = threads or sorted({1, os.cpu_count() or 1})
    rows, summary = [], {}
    for nthread in threads:
        m = measure(num_envs=num_envs, samples=samples, nthread=nthread, repeats=repeats)
        sec = f"{SECTION}: {num_envs} arms, {nthread} thread{'s' if nthread > 1 else ''}"
        work = f"{num_envs} arms x {samples} periods x {m['nstep']} physics steps"
        rows += [
            Row(sec, "TwoLinkVectorEnv: arm-steps/s", m["vector_steps_per_s"], "steps/s",
                f"{work}; checks, (15), observations, autoreset"),
            Row(sec, "raw mujoco.rollout, one call per Ts: arm-steps/s", m["raw_steps_per_s"],
                "steps/s", "same model, same torques, the state handed on"),
            Row(sec, "vector env / raw mujoco.rollout", m["ratio_vector_to_raw"], "x",
                "figure of merit, target >= 0.7"),
            Row(sec, "SyncVectorEnv of single envs: arm-steps/s", m["sync_steps_per_s"],
                "steps/s", "one plant call per arm"),
            Row(sec, "vector env / SyncVectorEnv", m["ratio_vector_to_sync"], "x"),
        ]
        summary[nthread] = m
    return rows, summary
