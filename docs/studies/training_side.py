"""Centralized agents on the training side: each level's score and the nominal settle over T*.

``python docs/studies/training_side.py NAME=AGENT [NAME=AGENT ...] -o FILE.json`` runs
each agent (an SB3 ``.zip`` path or a catalogue name) from the 65 states of the evaluation
set for 5 s on MuJoCo:

* nominally (level ``none``): successes of 65 and the median settle time over the
  state's time-optimal limit T* (:func:`twolink.studies.leaderboard.limits.state_limits`,
  failures as never settled), the leaderboard's ``settle / T*``;
* under ``medium`` and ``hard``: successes of 520 on the 8 plants of seed 20061122, the
  plants every training curve is scored on
  (:data:`twolink.training.config.EVAL_PLANTS`, :data:`~twolink.training.config.EVAL_SEED`),
  never the leaderboard's seed 2026 nor the fresh check's 31415.

It compares training recipes for the centralized target of the learned rows (65/65
nominally at ≤ 1.5 × T*, ≥ 99 % ``medium``, ≥ 90 % ``hard``) without looking at the
plants that judge the shipped row. The training guide quotes its output,
``renders/challenge_agents/sac_mixed_levers.json`` and ``sac_mixed_gain_levers.json``
(the ``--action-gain`` runs).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import numpy as np  # noqa: E402

from twolink.artifacts import write_json  # noqa: E402
from twolink.control.controllers import resolve_controller  # noqa: E402
from twolink.sim.controller import ControllerError  # noqa: E402
from twolink.sim.evaluation import evaluate  # noqa: E402
from twolink.sim.metrics import evaluation_set  # noqa: E402
from twolink.studies.leaderboard.limits import state_limits  # noqa: E402
from twolink.studies.leaderboard.measure import settle_ratios  # noqa: E402
from twolink.training.config import EVAL_PLANTS, EVAL_SEED  # noqa: E402

LEVELS = ("medium", "hard")


def measure(spec: str) -> dict:
    """The training-side figures of the controller ``spec`` (see the module docstring)."""
    agent = resolve_controller(spec)
    x0 = evaluation_set()
    limits, _ = state_limits(x0)
    nominal = evaluate(agent, x0=x0, nthread=1)
    ratio = settle_ratios(nominal.settle, nominal.success, limits)
    out = {"none": {"successes": nominal.score.successes, "n": nominal.score.n,
                    "settle_over_tstar_median": float(np.median(ratio))}}
    for level in LEVELS:
        s = evaluate(agent, x0=x0, challenge=level, seed=EVAL_SEED, count=EVAL_PLANTS,
                     nthread=1).score
        out[level] = {"successes": s.successes, "n": s.n,
                      "worst_plant_successes": s.worst_plant_successes}
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("agents", nargs="+", metavar="NAME=AGENT")
    ap.add_argument("-o", "--out", type=Path, required=True, metavar="FILE.json")
    args = ap.parse_args(argv)
    pairs = []
    for item in args.agents:
        name, sep, spec = item.partition("=")
        if not sep or not name or not spec:
            print(f"training_side: {item!r} is not NAME=AGENT", file=sys.stderr)
            return 2
        pairs.append((name, spec))
    rows = {}
    for name, spec in pairs:
        try:
            rows[name] = dict(measure(spec), agent=Path(spec).name)
        except (ControllerError, ValueError, OSError) as exc:
            print(f"training_side: {name}: {exc}", file=sys.stderr)
            return 2
        r = rows[name]
        print(f"{name}: none {r['none']['successes']}/65 at "
              f"{r['none']['settle_over_tstar_median']:.3f} T*, "
              + ", ".join(f"{lv} {r[lv]['successes']}/{r[lv]['n']}" for lv in LEVELS),
              flush=True)
    write_json(args.out, {"plants": {"seed": EVAL_SEED, "count": EVAL_PLANTS},
                          "rows": rows})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
