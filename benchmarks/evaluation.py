"""The cost of :func:`twolink.sim.evaluation.evaluate` over a raw rollout of the same runs.

Both run one controller from the same initial states on the nominal MuJoCo arm for the
same horizon, on the same number of threads: ``evaluate`` (protocol checks, the
challenge's sensors and actuation delay, the MuJoCo plant made for its plants, the
metrics) against :func:`twolink.sim.rollout.rollout` on a ``MujocoPlant`` made in the same
timed call. Beside them, open-loop ``mujoco.rollout`` of the same physics steps and
torques (:func:`twolink.studies.throughput.measure`), the engine's limit. Timings take
turns (:func:`benchmarks.common.interleaved_best`), best of ``repeats``.
"""
from __future__ import annotations

import os

import numpy as np

from benchmarks.common import Row, interleaved_best
from twolink.arm.parameters import HORIZON
from twolink.control.controllers import resolve_controller
from twolink.sim.evaluation import evaluate
from twolink.sim.metrics import evaluation_set, settle_time
from twolink.sim.plants import MujocoPlant
from twolink.sim.rollout import rollout, steps_for
from twolink.studies.throughput import measure

SECTION = "evaluation"


def bench_evaluation(*, controllers=("lqr", "centralized"), states: int = 65,
                     horizon: float = HORIZON, repeats: int = 3, nthread=None
                     ) -> tuple[list[Row], dict]:
    """evaluate() against the raw rollout and open-loop mujoco.rollout, per controller."""
    x0 = evaluation_set()[:states]
    nthread = nthread or min(2, os.cpu_count() or 1)
    samples = steps_for(horizon, rows=len(x0))
    rows, summary = [], {}
    for spec in controllers:
        c = resolve_controller(spec)

        def raw(c=c):
            with MujocoPlant(nthread=nthread) as plant:
                return rollout(c, plant, x0, duration=horizon)

        def full(c=c):
            return evaluate(c, x0=x0, horizon=horizon, nthread=nthread, label=c.name)

        best, out = interleaved_best({"raw": raw, "evaluate": full}, repeats)
        same = np.array_equal(np.nan_to_num(settle_time(out["raw"]), nan=-1, posinf=-1),
                              np.nan_to_num(out["evaluate"].settle[0], nan=-1, posinf=-1))
        tp = measure(c, x0, samples=samples, nthread=nthread, repeats=repeats)
        steps = tp.mujoco_steps
        threads = f"{nthread} thread{'s' if nthread > 1 else ''}"
        sec = f"{SECTION}: {c.name}, {len(x0)} states x {samples} Ts, {threads}"
        rows += [
            Row(sec, "evaluate(): seconds", best["evaluate"], "s",
                "checks, sensors, delay line, plant made, metrics"),
            Row(sec, "raw rollout(): seconds", best["raw"], "s",
                "same controller and states, MujocoPlant made in the timed call"),
            Row(sec, "evaluate / raw rollout", best["evaluate"] / best["raw"], "x",
                "1 = no overhead" + ("" if same else "; SETTLE TIMES DIFFER")),
            Row(sec, "evaluate(): physics steps/s", steps / best["evaluate"], "steps/s"),
            Row(sec, "open loop mujoco.rollout: physics steps/s", tp.open_loop_steps_per_s,
                "steps/s", "one call, the same steps and torques"),
            Row(sec, "evaluate / open-loop mujoco.rollout steps/s",
                tp.open_loop_seconds / best["evaluate"], "x", "target >= 0.9"),
        ]
        summary[c.name] = {"evaluate_seconds": best["evaluate"], "raw_seconds": best["raw"],
                           "open_loop_seconds": tp.open_loop_seconds,
                           "ratio": best["evaluate"] / best["raw"], "same_settle": same,
                           "mujoco_steps": steps}
    return rows, summary


def main(argv=None) -> int:
    import argparse

    from benchmarks.common import format_table

    ap = argparse.ArgumentParser(prog="python -m benchmarks.evaluation",
                                 description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="one repeat, 13 states, 2 s")
    args = ap.parse_args(argv)
    kw = {"states": 13, "horizon": 2.0, "repeats": 1} if args.quick else {}
    rows, summary = bench_evaluation(**kw)
    print(format_table(rows))
    for name, s in summary.items():
        print(f"{name}: evaluate {s['evaluate_seconds']:.3f} s, raw rollout "
              f"{s['raw_seconds']:.3f} s, ratio {s['ratio']:.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
