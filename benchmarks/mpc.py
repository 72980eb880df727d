"""Milliseconds per control step of the receding-horizon time-optimal MPC
(:class:`twolink.control.mpc.TimeOptimalMPC`), one arm on MuJoCo.

For each initial state: one closed-loop run to build the solvers of every horizon it
meets (CasADi's expansion costs about a second per horizon), then a timed run of the same
state: the first step (the search for the fewest samples N and its plan) and every later
step (one warm-started IPOPT solve), against the sample period Ts = 0.05 s, which real
time allows. Beside them the run's settle time and the shipped limit T* of the state.
``python -m benchmarks.mpc [--quick]``; a section of ``benchmarks.run`` too. Needs CasADi
(``pip install 'twolink[limits]'``); without it the section has no rows.
"""
from __future__ import annotations

import math

import numpy as np

from benchmarks.common import Row
from twolink.arm.parameters import TS

SECTION = "mpc"
#: Initial states of the full mode: the paper's x0 and two of the evaluation set.
FULL_STATES = ((-1.0, -3.0, 0.0, 0.0), (-2.6179938779914944, 1.5707963267948966, 0.0, 0.0),
               (-0.17453292519943295, 0.7853981633974483, 0.0, 0.0))
#: The quick mode's state (near the band: few horizons to build).
QUICK_STATES = FULL_STATES[2:]


def _limit(x0) -> float:
    from twolink.studies.leaderboard.limits import state_limits

    limits, _ = state_limits(np.asarray([x0]))
    return math.nan if limits is None else float(limits[0])


def bench_mpc(*, states=FULL_STATES, duration: float = 2.5, expand: bool = True,
              max_iter: int | None = None) -> tuple[list[Row], dict]:
    """Rows of ms per step (first, median, 95th percentile, most) per state; ``expand``
    as :class:`~twolink.control.mpc.TimeOptimalMPC` takes it, ``max_iter``
    caps IPOPT's iterations per re-solve (default: the limit's 200)."""
    from twolink.control.mpc import FAST_OPTIONS, TimeOptimalMPC
    from twolink.limits.symbolic import CasadiMissing
    from twolink.sim.metrics import settle_time
    from twolink.sim.plants import MujocoPlant
    from twolink.sim.rollout import rollout

    options = dict(FAST_OPTIONS, **({} if max_iter is None else {"ipopt.max_iter": max_iter}))
    try:
        c = TimeOptimalMPC(expand=expand, options=options)
    except CasadiMissing:
        return [], {"skipped": "CasADi is not installed"}
    cap = "" if max_iter is None else f", re-solves capped at {max_iter} iterations"
    rows, summary = [], {}
    for x0 in states:
        x = np.asarray([x0], dtype=float)
        for _ in range(2):                       # the first run builds the solvers
            with MujocoPlant(nthread=1) as plant:
                traj = rollout(c, plant, x, duration=duration)
        ms = np.asarray(c.timings[0]) * 1e3
        later = ms[1:]
        settle = float(settle_time(traj)[0])
        sec = f"{SECTION}: x0 = [{', '.join(f'{v:.3g}' for v in x0)}], {len(ms)} steps{cap}"
        limit = _limit(x0)
        rows += [
            Row(sec, "first step (search and plan)", ms[0], "ms", "solvers already built"),
            Row(sec, "later steps: median", float(np.median(later)), "ms",
                "one warm-started IPOPT solve"),
            Row(sec, "later steps: 95th percentile", float(np.percentile(later, 95)), "ms"),
            Row(sec, "later steps: most", float(later.max()), "ms",
                f"real time: at most {TS * 1e3:g} ms"),
            Row(sec, "steps over Ts", float(np.mean(ms > TS * 1e3)), "share",
                "first step included"),
        ]
        if math.isfinite(settle):
            rows.append(Row(sec, "settle time on MuJoCo", settle, "s",
                            f"limit T* {limit:.2f} s" if math.isfinite(limit) else ""))
        summary[str(tuple(x0))] = {"first_ms": float(ms[0]),
                                   "median_ms": float(np.median(later)),
                                   "p95_ms": float(np.percentile(later, 95)),
                                   "max_ms": float(later.max()),
                                   "over_ts": float(np.mean(ms > TS * 1e3)),
                                   "settle": settle if math.isfinite(settle) else None,
                                   "limit": limit if math.isfinite(limit) else None}
    summary["real_time"] = all(v["max_ms"] <= TS * 1e3 and v["first_ms"] <= TS * 1e3
                               for k, v in summary.items() if isinstance(v, dict))
    return rows, summary


def main(argv=None) -> int:
    import argparse
    import os

    from benchmarks.common import format_table

    ap = argparse.ArgumentParser(prog="python -m benchmarks.mpc",
                                 description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true",
                    help="one state near the band, 1 s (about 10 s)")
    args = ap.parse_args(argv)
    kw = {"states": QUICK_STATES, "duration": 1.0} if args.quick else {}
    rows, summary = bench_mpc(**kw)
    if rows and not args.quick:                 # the re-solves capped: still the limit?
        rows += bench_mpc(states=FULL_STATES[:1], max_iter=5)[0]
    if not rows:
        print(f"mpc benchmark skipped: {summary['skipped']}")
        return 0
    print(format_table(rows))
    print(f"load average {os.getloadavg()}; real time (every step <= {TS * 1e3:g} ms): "
          f"{'yes' if summary['real_time'] else 'no'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
