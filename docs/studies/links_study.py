"""Development study of the N-link decentralized agents (twolink.synthesis.links_decentralized).

Synthesises the agents of an N-link arm under a construction (the defaults, or options
given on the command line) and measures success on the MuJoCo N-link plant from random
poses at rest drawn from DEVELOPMENT seeds (500-599; the final evaluation seed of the
scaling table is not used here): success = settled in every link's goal band 1 s before
the end, at 5 s and at 8 s, with counts and 95 % Wilson intervals; also the median settle
time and the synthesis time.

    .venv/bin/python docs/studies/links_study.py --links 3 --rule tapered --seeds 500 501
    .venv/bin/python docs/studies/links_study.py --links 3 --lock-inner none --json
"""
from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from twolink.arm.parameters import (
    HORIZON,
    LINK_RULES,
    LINKS_HORIZON,
    MAX_LINKS,
    MIN_LINKS,
    links_parameters,
)
from twolink.arm.task import in_goal_band
from twolink.synthesis import links_decentralized as decentralized
from twolink.sim.metrics import random_poses, settle_time, success
from twolink.sim.plants import make_plant
from twolink.sim.rollout import rollout
from twolink.viz.formatting import format_rate

#: The development seeds this study may draw poses from.
DEV_SEEDS = range(500, 600)
#: The horizons measured: the paper's 5 s and the N >= 3 horizon 8 s.
HORIZONS = (HORIZON, LINKS_HORIZON)


def evaluate(policy, p, seeds, count: int) -> dict:
    """Success at each horizon and the settle times, from ``count`` poses per seed."""
    x0 = np.concatenate([random_poses(p.links, count, s) for s in seeds])
    out = {"poses": int(len(x0))}
    with make_plant("mujoco", p) as plant:
        traj = rollout(policy, plant, x0, duration=max(HORIZONS))
    if not np.array_equal(_success_within(traj, max(HORIZONS)), success(traj)):
        raise RuntimeError("success within the horizon disagrees with metrics.success")
    for h in HORIZONS:
        out[f"success_{h:g}s"] = int(np.sum(_success_within(traj, h)))
    st = settle_time(traj)
    out["median_settle_s"] = float(np.median(st)) if np.isfinite(np.median(st)) else None
    return out


def _success_within(traj, horizon: float) -> np.ndarray:
    """Success of the first ``horizon`` seconds of a longer run (the plant is
    deterministic, so a run of ``horizon`` seconds): in the goal band from 1 s before the
    horizon up to it."""
    k = int(round(horizon / (traj.t[1] - traj.t[0])))
    inside = in_goal_band(traj.x[..., :k + 1, :])
    stays = np.flip(np.logical_and.accumulate(np.flip(inside, -1), -1), -1)
    last = int(round((horizon - 1.0) / (traj.t[1] - traj.t[0])))
    return stays[..., last]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--links", type=int, default=3, help=f"{MIN_LINKS}..{MAX_LINKS}")
    ap.add_argument("--rule", choices=LINK_RULES, default="tapered")
    ap.add_argument("--seeds", type=int, nargs="+", default=[500, 501],
                    help="development seeds (500-599)")
    ap.add_argument("--count", type=int, default=64, help="poses per seed")
    ap.add_argument("--context", choices=decentralized.CONTEXTS)
    ap.add_argument("--speed-context", choices=("yes", "no"))
    ap.add_argument("--extra-speed-bins", choices=decentralized.EXTRA_BINS)
    ap.add_argument("--lock-inner", choices=decentralized.LOCKS)
    ap.add_argument("--beyond", choices=decentralized.BEYOND)
    ap.add_argument("--json", action="store_true", help="print the result as JSON")
    args = ap.parse_args(argv)
    bad = [s for s in args.seeds if s not in DEV_SEEDS]
    if bad:
        ap.error(f"seeds {bad} are not development seeds (500-599)")
    p = links_parameters(args.links, args.rule)
    options = {"context": args.context, "extra_speed_bins": args.extra_speed_bins,
               "lock_inner": args.lock_inner, "beyond": args.beyond,
               "speed_context": None if args.speed_context is None
               else args.speed_context == "yes"}
    t0 = time.perf_counter()
    policy = decentralized.synthesize_links(p, progress=not args.json, **options)
    seconds = time.perf_counter() - t0
    result = {"links": args.links, "rule": args.rule, "seeds": args.seeds,
              "construction": policy.meta["construction"], "synthesis_s": seconds,
              "sweeps": {a.name: a.info["iterations"] for a in policy.agents}}
    result.update(evaluate(policy, p, args.seeds, args.count))
    if args.json:
        print(json.dumps(result))
        return 0
    print(f"N = {args.links} {args.rule}: {result['construction']}")
    print(f"  synthesis {seconds:.1f} s, sweeps {result['sweeps']}")
    for h in HORIZONS:
        print(f"  success at {h:g} s: {format_rate(result[f'success_{h:g}s'], result['poses'])}")
    print(f"  median settle time: {result['median_settle_s']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
