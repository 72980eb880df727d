"""``twolink evaluate``: one controller under one challenge level on MuJoCo.

Any controller: a shipped policy, a classical baseline, a policy file, ``module:callable``
or ``path/to/file.py:callable`` (a callable mapping states (n, 4) to torques (n, 2):
twolink.sim.controller). Prints k/n with the 95 % Wilson interval, the worst plant, the
median settle time and settle / T*, the settle time over the time-optimal limit of each
initial state. The controller runs plain (it reads the challenge's readings as they are)
unless --compensate puts the delay predictor and observer in front of it. A progress bar
(samples Ts simulated) goes to stderr, as lines when it is not a terminal, unless --json.
The controller gets read-only copies of the states; what it prints goes to stderr, so
--json output stays valid; --timeout ends a call that runs too long.
"""
from __future__ import annotations

import json
import math

from twolink.commands import SUMMARIES
from twolink.sim.challenges import LEVELS
from twolink.sim.controller import MAX_TIMEOUT, MIN_TIMEOUT

STATE_SETS = ("full", "quick")


def add_parser(sub):
    p = sub.add_parser("evaluate", help=SUMMARIES["evaluate"],
                       description=" ".join(__doc__.replace("``", "").split("\n\n")[1].split()))
    p.add_argument("controller", metavar="CONTROLLER",
                   help="shipped policy or baseline name, a policy .npz, module:callable or "
                        "path/to/file.py:callable")
    p.add_argument("--challenge", default="none", metavar="LEVEL",
                   help=f"challenge level ({', '.join(LEVELS)}; default none)")
    p.add_argument("--compensate", action="store_true",
                   help="run behind the delay predictor and observer (the controller must "
                        "name its model in meta['model']); default: plain")
    p.add_argument("--plants", type=int, default=32, metavar="K",
                   help="plants drawn for a level that perturbs the plant (default 32)")
    p.add_argument("--seed", type=int, default=2026, metavar="S",
                   help="seed of the plants, noise and faults (default 2026)")
    p.add_argument("--states", choices=STATE_SETS, default="full",
                   help="initial states: the 65 of the evaluation set (full) or every 13th "
                        "(quick)")
    p.add_argument("--json", action="store_true",
                   help="print the result as JSON (and no progress bar)")
    p.add_argument("--timeout", type=float, default=None, metavar="SECONDS",
                   help=f"end the run (exit status 2) when one call of the controller takes "
                        f"longer than this, from {MIN_TIMEOUT:g} to {MAX_TIMEOUT:g} s "
                        f"(default: no limit)")
    return p


def result(controller: str, *, challenge: str = "none", compensate: bool = False,
           plants: int = 32, seed: int = 2026, states: str = "full",
           progress: bool = False, timeout: float | None = None) -> dict:
    """The JSON of ``twolink evaluate``; ``progress`` shows the evaluation's bar
    (:func:`twolink.sim.progress.progress_bar`) on stderr; ``timeout`` limits each call
    of the controller to that many seconds (:class:`twolink.sim.controller.Checked`)."""
    import numpy as np

    from twolink.control.controllers import resolve_controller
    from twolink.sim.cells import states_of
    from twolink.sim.challenges import challenge as challenge_named
    from twolink.sim.controller import check_timeout, checked
    from twolink.sim.evaluation import evaluate
    from twolink.studies.leaderboard.limits import state_limits
    from twolink.studies.leaderboard.measure import settle_ratios

    ch = challenge_named(challenge)
    if not 1 <= plants <= 10_000:
        raise ValueError(f"--plants must be from 1 to 10000, got {plants}")
    if not 0 <= seed < 2**63:
        raise ValueError(f"--seed must be a whole number from 0 to 2**63 - 1, got {seed}")
    timeout = check_timeout(timeout, "--timeout")
    c = checked(resolve_controller(controller), timeout=timeout)
    x0 = states_of(states)
    limits, source = state_limits(x0)
    ev = evaluate(c, x0=x0, challenge=ch, seed=seed, compensate=compensate,
                  count=plants if ch.perturbs_plant() else 1, label=c.name,
                  progress=progress)
    out = {"controller": c.name, "challenge": ch.name,
           "mode": "compensated" if compensate else "plain", "states": len(x0),
           "plants": len(ev.params), "seed": seed, **ev.score.as_dict(), "limits": source}
    if limits is not None:
        ratio = settle_ratios(ev.settle, ev.success, limits)
        med, worst = float(np.median(ratio)), float(ratio.max())
        out["settle_ratio_median"] = med if math.isfinite(med) else None
        out["settle_ratio_worst"] = worst if math.isfinite(worst) else None
    return out


def run(args) -> int:
    from twolink.viz.formatting import format_rate

    r = result(args.controller, challenge=args.challenge, compensate=args.compensate,
               plants=args.plants, seed=args.seed, states=args.states,
               progress=not args.json, timeout=args.timeout)
    if args.json:
        print(json.dumps(r, indent=2))
        return 0
    worst = ("" if r["worst_plant"] is None else
             f"; worst plant {r['worst_plant_successes']}/{r['n'] // r['plants']}")
    settle = "never" if r["median_settle"] is None else f"{r['median_settle']:.2f} s"
    line = (f"{r['controller']} under {r['challenge']} ({r['mode']}): "
            f"{format_rate(r['successes'], r['n'])}{worst}; median settle {settle}")
    if "settle_ratio_median" in r:
        def fmt(v):
            return "never" if v is None else f"{v:.2f}"
        line += (f"; settle / T* {fmt(r['settle_ratio_median'])} median, "
                 f"{fmt(r['settle_ratio_worst'])} worst")
    print(line)
    return 0
