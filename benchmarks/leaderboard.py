"""The leaderboard's evaluation path against raw ``mujoco.rollout``, and one controller
through every level.

A leaderboard row is :func:`twolink.studies.leaderboard.measure.measure_row`: one
:func:`twolink.sim.evaluation.evaluate` of P plants drawn by the level x n initial states
over the horizon (one ``mujoco.rollout`` call of nstep physics steps per sample period,
the controller called once per sample on the whole batch, the level's noise, faults and
delays, plain or through the compensator), summed up. Its achieved rate is the runs x
samples x nstep physics steps over its wall time. The reference is raw
``mujoco.rollout``: one call of the same per-row models (the plant's own), the same
initial states and the same number of physics steps on the same threads, with a torque
held per row (drawn within the row's limits: MuJoCo's cost does not depend on it).
Row and reference take turns (:func:`benchmarks.common.interleaved_best`), best of
``repeats``. Then the wall time of :func:`twolink.studies.leaderboard.measure.run` for
one controller through every level and mode, and each of its rows' times.
"""
from __future__ import annotations

import os
import time

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

from benchmarks.common import Row, interleaved_best
from twolink.arm.parameters import HORIZON
from twolink.control.controllers import resolve_controller
from twolink.sim.challenges import LEVELS
from twolink.sim.metrics import evaluation_set
from twolink.sim.plants import MujocoPlant, physics_state
from twolink.sim.rollout import steps_for
from twolink.studies.leaderboard.limits import state_limits
from twolink.studies.leaderboard.measure import SEED, measure_row, modes_for, run

SECTION = "leaderboard"


def _states(states: int) -> np.ndarray:
    """``states`` initial states spread over the evaluation set (all 65 at 65)."""
    x0 = evaluation_set()
    return x0[np.linspace(0, len(x0) - 1, states).round().astype(int)]


def raw_rollout(params, x0: np.ndarray, samples: int, nthread: int):
    """A callable doing the physics steps of an evaluation of ``x0`` (n, 4) on every
    plant of ``params`` for ``samples`` sample periods as one ``mujoco.rollout`` call
    on ``nthread`` threads (its pool lives as long as the callable); and the number of
    steps."""
    with MujocoPlant([p for p in params for _ in x0], nthread=nthread) as plant:
        models, nstep = list(plant.models), plant.nstep
    state0 = physics_state(np.tile(x0, (len(params), 1)))
    tau_max = np.stack([p.tau_max for p in params for _ in x0])
    tau = np.random.default_rng(0).uniform(-1, 1, tau_max.shape) * tau_max
    control = np.ascontiguousarray(np.repeat(tau[:, None], samples * nstep, 1))
    datas = [mujoco.MjData(models[0]) for _ in range(nthread)]
    # The output and the thread pool made once, outside the timed call: the reference
    # pays for nothing but the steps (and writing each step's state).
    state = np.empty((len(models), samples * nstep, state0.shape[1]))
    sensordata = np.empty((len(models), samples * nstep, 0))
    pool = mj_rollout.Rollout(nthread=nthread if nthread > 1 else 0)

    def call():
        pool.rollout(models, datas, state0, control, state=state, sensordata=sensordata)
        return state[:, -1]
    return call, len(models) * samples * nstep


def bench_leaderboard(*, controller: str = "lqr", level: str = "medium", plants: int = 32,
                      states: int = 65, repeats: int = 2,
                      through=("lqr",), nthread=None) -> tuple[list[Row], dict]:
    """A leaderboard row of ``controller`` under ``level`` (plain and compensated) against
    raw mujoco.rollout of the same physics steps; ``through`` controllers run through
    every level and mode. Rows run the leaderboard's horizon (5 s)."""
    nthread = nthread or os.cpu_count() or 1
    x0 = _states(states)
    limits, _ = state_limits(x0)
    samples = steps_for(HORIZON)
    c = resolve_controller(controller)
    ch = LEVELS[level]
    params = ch.plants(plants, SEED)
    raw, steps = raw_rollout(params, x0, samples, nthread)
    modes = modes_for(c, level)
    timed = {"raw": raw}
    for mode in modes:
        timed[mode] = (lambda mode=mode: measure_row(c, controller, level, mode, x0, limits,
                                                     plants, SEED, nthread=nthread))
    for mode in modes:          # compiled kernels and first-call costs out of the timing
        measure_row(c, controller, level, mode, x0[:1], limits[:1], 1, SEED,
                    nthread=nthread)
    load = os.getloadavg()[0]
    best, _ = interleaved_best(timed, repeats)
    threads = f"{nthread} thread{'s' if nthread > 1 else ''}"
    sec = (f"{SECTION}: {controller} under {level}, {plants} plants x {len(x0)} states x "
           f"{samples} Ts, {threads}")
    rows = [Row(sec, "raw mujoco.rollout: physics steps/s", steps / best["raw"], "steps/s",
                f"one call, the plants' models, {steps:,} steps")]
    summary = {"controller": controller, "level": level, "plants": plants,
               "states": len(x0), "samples": samples, "nthread": nthread,
               "physics_steps": steps, "raw_seconds": best["raw"],
               "load_average": load, "rows": {}}
    for mode in modes:
        rows += [Row(sec, f"row ({mode}): seconds", best[mode], "s",
                     "measure_row: evaluate under the level, summed up"),
                 Row(sec, f"row ({mode}): physics steps/s", steps / best[mode], "steps/s"),
                 Row(sec, f"row ({mode}) / raw mujoco.rollout steps/s",
                     best["raw"] / best[mode], "x", "target >= 0.85")]
        summary["rows"][mode] = {"seconds": best[mode], "ratio": best["raw"] / best[mode]}
    summary["through"] = {}
    for name in through:
        t0 = time.perf_counter()
        entries = run({name: resolve_controller(name)}, x0, limits, plants=plants)
        wall = time.perf_counter() - t0
        sec = (f"{SECTION}: {name} through every level, {plants} plants x {len(x0)} "
               f"states, {threads}")
        rows.append(Row(sec, "wall time", wall, "s",
                        f"{len(entries)} rows: {', '.join(sorted(LEVELS))} x modes"))
        rows += [Row(sec, f"row {e.level} {e.mode}: seconds", e.seconds, "s")
                 for e in entries]
        summary["through"][name] = {"seconds": wall, "rows": {
            f"{e.level}/{e.mode}": e.seconds for e in entries}}
    return rows, summary


def main(argv=None) -> int:
    import argparse

    from benchmarks.common import format_table

    ap = argparse.ArgumentParser(prog="python -m benchmarks.leaderboard",
                                 description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true",
                    help="12 plants x 13 states")
    args = ap.parse_args(argv)
    kw = {"plants": 12, "states": 13} if args.quick else {}
    rows, _ = bench_leaderboard(**kw)
    print(format_table(rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
