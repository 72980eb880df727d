"""Measuring the shipped baselines with the one evaluation call
(:func:`twolink.sim.evaluation.evaluate`, MuJoCo), on the evaluation set and on seeds
other than the tuning's:

    python -m twolink.control.baselines.measure                       # nominal, 65 states
    python -m twolink.control.baselines.measure --challenge medium --count 32 --seed 0
    python -m twolink.control.baselines.measure --challenge hard --count 32 --seed 0 \\
        --compensate

Each line: successes of runs with the 95 % Wilson interval, the median settle time and
the worst plant. ``--json PATH`` writes the figures.
"""
from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np

from twolink.artifacts import provenance, write_json
from twolink.control.baselines.registry import BASELINES, baseline
from twolink.control.baselines.tuning import TUNING_SEEDS
from twolink.sim.challenges import LEVELS
from twolink.sim.evaluation import evaluate
from twolink.sim.metrics import wilson_interval


def measure(name: str, *, challenge: str = "none", count: int | None = None, seed: int = 0,
            compensate: bool = False, x0=None) -> dict:
    """One baseline's figures under ``challenge`` (``count`` plants, ``seed``); a refusal
    of the evaluation (e.g. no model to compensate with) comes back as ``refused``."""
    if seed in TUNING_SEEDS:
        raise ValueError(f"seed {seed} is a tuning seed ({TUNING_SEEDS}); report on another")
    ctrl = baseline(name)
    t0 = time.perf_counter()
    try:
        ev = evaluate(ctrl, challenge=challenge, compensate=compensate, count=count,
                      seed=seed, x0=x0, label=name)
    except ValueError as exc:
        return {"baseline": name, "challenge": challenge, "compensated": compensate,
                "refused": str(exc)}
    ok = np.asarray(ev.success, dtype=bool)
    settle = np.asarray(ev.settle, dtype=float)
    ok2 = ok.reshape(-1, ok.shape[-1])
    k, n = int(ok.sum()), int(ok.size)
    lo, hi = wilson_interval(k, n)
    med = float(np.median(settle))
    per_plant = ok2.sum(axis=1)
    return {"baseline": name, "challenge": challenge, "compensated": compensate,
            "seed": seed, "plants": int(ok2.shape[0]), "states": int(ok2.shape[1]),
            "successes": k, "n": n, "rate": k / n, "wilson_95": [lo, hi],
            "median_settle": round(med, 9) if math.isfinite(med) else None,
            "worst_plant": int(np.argmin(per_plant)),
            "worst_plant_successes": int(per_plant.min()),
            "seconds": round(time.perf_counter() - t0, 1)}


def line(r: dict) -> str:
    head = f"{r['baseline']:<12} {r['challenge']:<7} {'comp' if r['compensated'] else 'raw ':<5}"
    if "refused" in r:
        return f"{head} refused: {r['refused']}"
    lo, hi = r["wilson_95"]
    med = "inf" if r["median_settle"] is None else f"{r['median_settle']:.2f} s"
    return (f"{head} {r['successes']}/{r['n']} = {100 * r['rate']:.1f} % "
            f"[{100 * lo:.1f}, {100 * hi:.1f}]  median settle {med}  worst plant "
            f"{r['worst_plant_successes']}/{r['states']}  ({r['seconds']:.0f} s)")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m twolink.control.baselines.measure",
                                 description="Evaluate the shipped baselines on MuJoCo.")
    ap.add_argument("names", nargs="*", metavar="NAME",
                    help=f"baselines (default: all of {', '.join(BASELINES)})")
    ap.add_argument("--challenge", default="none", choices=list(LEVELS))
    ap.add_argument("--count", type=int, help="plants (default: evaluate's, 32 for a "
                    "challenge that perturbs the plant)")
    ap.add_argument("--seed", type=int, default=0, help="plants, noise and faults (never a "
                    f"tuning seed {TUNING_SEEDS})")
    ap.add_argument("--compensate", action="store_true",
                    help="drive through the observer/predictor (twolink.sim.estimation)")
    ap.add_argument("--json", help="write the figures to this path")
    args = ap.parse_args(argv)
    unknown = [n for n in args.names if n not in BASELINES]
    if unknown:
        ap.error(f"unknown baseline(s) {', '.join(unknown)}; choose from {', '.join(BASELINES)}")
    out = []
    for name in args.names or list(BASELINES):
        r = measure(name, challenge=args.challenge, count=args.count, seed=args.seed,
                    compensate=args.compensate)
        print(line(r), flush=True)
        out.append(r)
    if args.json:
        write_json(args.json, {"figures": out, "provenance": provenance()})
    return 0


if __name__ == "__main__":
    sys.exit(main())
