"""What a finer fuzzy grid buys: the paper's bins subdivided ``refine`` times.

For every kind (centralized (16), decentralized (18), agent 1 frozen), synthesis model
(the simplified model (11) and the full model (6)) and refinement (1: the paper's grid;
k: k - 1 evenly spaced centres inserted between neighbouring centres, 12k angle bins and
6k + 1 speed bins, :meth:`twolink.fqi.fuzzy.Axis.refined`), this script measures

* synthesis: Q size, nnz(T), synchronous sweeps, wall time, and the peak of traced
  allocations (tracemalloc: numpy and scipy arrays; the process's RSS high-water mark is
  given too, configurations run from small to large);
* closed loop, on the simplified plant (11) and on MuJoCo: settle time from the paper's
  x0, success (k/n, 95 % Wilson interval) and edge stalls over the evaluation set, over
  ``--states`` random poses at rest (angles uniform in [-pi, pi), drawn from ``--seed``),
  and over the same poses seen through Gaussian observation noise (``--noise-deg`` on the
  angles, ``--noise-deg`` x 0.02 rad/s on the speeds, as ``twolink mismatch``'s noise
  cells; row i's noise from the i-th child of SeedSequence([seed, 1])); the median settle
  time of the random poses that succeed.

``--sweeps serial`` synthesises with serial sweeps instead (the shipped policies are
synchronous). Nothing is tuned: every configuration runs the same sets. Prints tables;
``--json PATH`` also merges the run into PATH (schema ``twolink.grid_study``, version 1:
one entry of ``runs`` per set of options, a rerun with the same options replaces its
entry), from which ``python docs/generate.py`` writes docs/results/finer-grids.md.

Run: .venv/bin/python docs/studies/grid_study.py [--refine 1 2 3] [--states 200] [--seed 7]
     [--noise-deg 1] [--models simplified full] [--sweeps synchronous|serial]
     [--json renders/grid_study/grid_study.json]
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import resource
import sys
import time
import tracemalloc

import numpy as np
from tqdm import tqdm

from twolink.arm.parameters import HORIZON
from twolink.artifacts import check_outputs, provenance, read_runs, write_json
from twolink.synthesis.problems import KINDS, SWEEPS, table_sizes
from twolink.synthesis.problems import SYNTHESIS_MODELS as MODELS
from twolink.synthesis.synthesize import synthesize
from twolink.policy.fuzzy_policy import MAX_Q_BYTES
from twolink.sim.cells import SPEED_PER_DEG
from twolink.sim.metrics import (
    evaluation_set,
    settle_time,
    stalled_at_band_edge,
    success,
)
from twolink.sim.perturbations import ObservationNoise, row_generators
from twolink.sim.plants import make_plant
from twolink.sim.rollout import rollout, steps_for
from twolink.viz.formatting import format_rate

#: Most random poses per run (each is a 5 s rollout on two plants, three times).
MAX_STATES = 100_000
#: What the --json file calls itself; docs/generate.py refuses any other.
SCHEMA, VERSION = "twolink.grid_study", 1


@dataclasses.dataclass
class Outcome:
    """Success of one batch of rollouts: k of n, edge stalls among the failures."""

    successes: int
    states: int
    edge_stalls: int
    median_settle: float | None = None


@dataclasses.dataclass
class Row:
    kind: str
    model: str
    refine: int
    q_size: int
    nnz: int
    sweeps: dict
    synthesis_seconds: float
    peak_traced_mib: float
    rss_max_mib: float
    closed_loop: dict          # plant -> {"x0_settle", "evaluation", "random", "noisy"}


def random_poses(states: int, seed: int) -> np.ndarray:
    """``states`` poses at rest, both angles uniform in [-pi, pi), from ``seed``."""
    x = np.zeros((states, 4))
    x[:, :2] = np.random.default_rng(seed).uniform(-np.pi, np.pi, (states, 2))
    return x


def _outcome(traj) -> Outcome:
    ok = success(traj)
    st = settle_time(traj)[ok]
    return Outcome(int(ok.sum()), int(len(ok)), int(stalled_at_band_edge(traj).sum()),
                   float(np.median(st)) if len(st) else None)


def _tail(traj, seconds: float = 1.0) -> dict:
    """Link 2 over the last ``seconds`` of the x0 rollout (row 0): its angle range [deg],
    its speed range [rad/s] and its mean |torque| [N m]."""
    k = int(round(seconds / (traj.t[1] - traj.t[0])))
    x, u = traj.x[0, -k:], traj.u[0, -k:]
    return {"seconds": seconds,
            "theta2_deg": [float(np.rad2deg(x[:, 1]).min()), float(np.rad2deg(x[:, 1]).max())],
            "dtheta2": [float(x[:, 3].min()), float(x[:, 3].max())],
            "mean_abs_torque2": float(np.mean(np.abs(u[:, 1])))}


def measure_one(kind, model, refine, plants, *, poses, seed, noise_deg,
                sweeps="synchronous") -> Row:
    tracemalloc.start()
    t0 = time.perf_counter()
    policy = synthesize(kind, model=model, refine=refine, sweeps=sweeps, progress=True)
    seconds = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    ev_states = evaluation_set()
    closed = {}
    for name, plant in plants.items():
        ev = rollout(policy, plant, ev_states)
        rnd = rollout(policy, plant, poses)
        noise = ObservationNoise(math.radians(noise_deg), noise_deg * SPEED_PER_DEG,
                                 rngs=row_generators([seed, 1], len(poses)),
                                 block=steps_for(HORIZON))
        noisy = rollout(policy, plant, poses, observe=lambda k, x: noise(x))
        x0_settle = float(settle_time(ev)[0])       # row 0 of the evaluation set is x0
        closed[name] = {"x0_settle": x0_settle if math.isfinite(x0_settle) else None,
                        "x0_tail": _tail(ev),
                        "evaluation": dataclasses.asdict(_outcome(ev)),
                        "random": dataclasses.asdict(_outcome(rnd)),
                        "noisy": dataclasses.asdict(_outcome(noisy))}
    return Row(kind, model, refine, sum(int(a.info["q_size"]) for a in policy.agents),
               sum(int(a.info["transition_nnz"]) for a in policy.agents),
               {a.name: int(a.info["iterations"]) for a in policy.agents}, seconds, peak, rss,
               closed)


def measure(refines, *, states: int, seed: int, noise_deg: float, models=MODELS,
            sweeps: str = "synchronous") -> list[Row]:
    poses = random_poses(states, seed)
    configs = sorted(((k, m, r) for r in refines for k in KINDS for m in models),
                     key=lambda c: (c[2], c[0] == "centralized", c[1]))
    rows = []
    with make_plant("simplified") as simplified, make_plant("mujoco") as mj:
        plants = {"simplified": simplified, "mujoco": mj}
        for kind, model, refine in tqdm(configs, desc="grid study", unit=" config"):
            rows.append(measure_one(kind, model, refine, plants, poses=poses, seed=seed,
                                    noise_deg=noise_deg, sweeps=sweeps))
    return rows


def _rate(o: dict) -> str:
    return f"{format_rate(o['successes'], o['states'])} e{o['edge_stalls']}"


def print_tables(rows, *, states, seed, noise_deg, sweeps="synchronous") -> None:
    print(f"synthesis ({sweeps} sweeps; peak: traced numpy/scipy allocations, "
          "RSS: process high-water mark so far)")
    print(f"{'kind':<14}{'model':<11}{'refine':>6}{'Q size':>10}{'nnz(T)':>12}"
          f"{'sweeps':>16}{'time [s]':>10}{'peak [MiB]':>12}{'RSS [MiB]':>11}")
    for r in rows:
        sw = "/".join(str(v) for v in r.sweeps.values())
        print(f"{r.kind:<14}{r.model:<11}{r.refine:>6}{r.q_size:>10}{r.nnz:>12}{sw:>16}"
              f"{r.synthesis_seconds:>10.2f}{r.peak_traced_mib:>12.0f}{r.rss_max_mib:>11.0f}")
    print()
    print(f"closed loop, 5 s: x0 settle time; success k/n = % [Wilson 95 %] eN (N failures "
          f"are edge stalls) over the evaluation set (65), {states} random poses at rest "
          f"(seed {seed}), the same poses with observation noise ({noise_deg:g} deg, "
          f"{noise_deg * SPEED_PER_DEG:g} rad/s); median settle time of the random "
          f"successes")
    head = (f"{'kind':<14}{'model':<11}{'refine':>6} {'plant':<11}{'x0 settle':>10}  "
            f"{'evaluation set':<32}{'random poses':<34}{'with noise':<34}{'median':>7}")
    print(head)
    for r in rows:
        for plant, c in r.closed_loop.items():
            x0 = "never" if c["x0_settle"] is None else f"{c['x0_settle']:.2f} s"
            med = c["random"]["median_settle"]
            med = "-" if med is None else f"{med:.2f} s"
            print(f"{r.kind:<14}{r.model:<11}{r.refine:>6} {plant:<11}{x0:>10}  "
                  f"{_rate(c['evaluation']):<32}{_rate(c['random']):<34}"
                  f"{_rate(c['noisy']):<34}{med:>7}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--refine", type=int, nargs="+", default=[1, 2, 3],
                        help="refinement factors (default 1 2 3)")
    parser.add_argument("--states", type=int, default=200,
                        help="random poses at rest (default 200)")
    parser.add_argument("--seed", type=int, default=7, help="seed of the random poses (default 7)")
    parser.add_argument("--noise-deg", type=float, default=1.0,
                        help="observation noise std on the angles, degrees (default 1)")
    parser.add_argument("--models", nargs="+", choices=MODELS, default=list(MODELS),
                        help="synthesis models (default: simplified full)")
    parser.add_argument("--sweeps", choices=SWEEPS, default="synchronous",
                        help="Alg. 1's sweeps (default synchronous, as the shipped policies)")
    parser.add_argument("--json", default=None, metavar="PATH",
                        help="also merge the run into PATH (versioned JSON)")
    args = parser.parse_args(argv)
    if not 1 <= args.states <= MAX_STATES:
        parser.error(f"--states must be from 1 to {MAX_STATES}")
    if any(r < 1 for r in args.refine):
        parser.error("--refine factors must be positive whole numbers")
    for r in args.refine:              # what a policy file may hold bounds the grid
        biggest = max(n for k in KINDS for n in table_sizes(k, r).values())
        if biggest * 8 > MAX_Q_BYTES:
            parser.error(f"--refine {r}: a Q-table of {biggest} values is over the "
                         f"{MAX_Q_BYTES >> 20} MiB a policy may hold")
    if args.json:
        try:
            check_outputs({"--json": args.json})
            old = read_runs(args.json, SCHEMA, VERSION)
        except (OSError, ValueError) as exc:
            parser.error(str(exc))
    if not (math.isfinite(args.noise_deg) and args.noise_deg >= 0):
        parser.error("--noise-deg must be a non-negative number")
    start = time.perf_counter()
    rows = measure(sorted(set(args.refine)), states=args.states, seed=args.seed,
                   noise_deg=args.noise_deg, models=args.models, sweeps=args.sweeps)
    seconds = time.perf_counter() - start
    print_tables(rows, states=args.states, seed=args.seed, noise_deg=args.noise_deg,
                 sweeps=args.sweeps)
    if args.json:
        options = {"refine": sorted(set(args.refine)), "states": args.states,
                   "seed": args.seed, "noise_deg": args.noise_deg,
                   "models": list(args.models), "sweeps": args.sweeps}
        run = {"options": options, "seconds": seconds,
               "rss_max_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
               "speed_noise": args.noise_deg * SPEED_PER_DEG,
               # the largest Q-table of each refinement, one past the largest measured
               "largest_q_table": {str(r): max(n for k in KINDS
                                               for n in table_sizes(k, r).values())
                                   for r in range(1, max(options["refine"]) + 2)},
               "rows": [dataclasses.asdict(r) for r in rows]}
        kept = [r for r in old["runs"] if r["options"] != options]
        write_json(args.json, {"schema": SCHEMA, "version": VERSION,
                               "max_q_bytes": MAX_Q_BYTES, "provenance": provenance(),
                               "runs": kept + [run]})
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
