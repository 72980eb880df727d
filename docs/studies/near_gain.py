"""The near-goal gain of the read-out, chosen per shipped design on the tuning seeds.

``python docs/studies/near_gain.py [--policies NAME ...] [--json FILE]`` takes each named
shipped policy, gives its read-out every near-goal gain of the grid (:data:`ANGLES_DEG`
x :data:`GAINS`: joint i's torque times g + (1 - g) min(|theta_i| / A, 1),
:class:`twolink.policy.readout.Readout`) and measures it as the tuning table does
(``docs/studies/fuzzy_design.py``: 48 poses nominal, 32 of them on 8 plants under medium
and hard, with and without compensation, all from the tuning seeds). :func:`choose` picks
per policy the gain that keeps every nominal pose and has the most successes summed over
the four challenge columns (ties: the larger g, the smaller A: the least change), and
the gain with the most successes in the hard level with compensation alone (the
decentralized target the all-round gain leaves below the best baseline). The grid's
``medium`` column is nearly full for every gain, so ``--medium-wide`` measures the
policies' gains again under ``medium`` without compensation on all 48 poses and
:data:`WIDE_PLANTS` plants of the tuning seeds (``medium_wide`` in each row) and adds a
third choice by it. ``--parts`` tests the explanation: it measures each policy with
and without its all-round gain, beside ``pd_deadzone``, under each part of the ``hard``
level alone (:data:`PARTS`: its delays, its noise, its plants, its faults). The runs merge
into the JSON file (one per policy; ``--choose-only`` applies :func:`choose` to the
file's runs again without measuring); the docs generator writes the choices into
``docs/results/fuzzy-designs.md``, and the registry ships chosen designs under new
names. About 3 min per policy on this machine.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from twolink.artifacts import provenance, read_runs, write_json  # noqa: E402
from twolink.policy.fuzzy_policy import Policy, load_policy  # noqa: E402
from twolink.policy.registry import SHIPPED, TWO_LINK  # noqa: E402
from twolink.sim.evaluation import evaluate  # noqa: E402
from twolink.studies.fuzzy_design.tuning_set import (  # noqa: E402
    CHALLENGE_PLANTS,
    CHALLENGE_POSES,
    PLANT_SEED,
    POSES,
)

SCHEMA, VERSION = "twolink.near_gain", 1
#: The grid: A, the angle (deg) of full torque again, and g, the gain at the goal.
ANGLES_DEG = (20.0, 40.0, 60.0, 90.0, 120.0, 180.0)
GAINS = (0.1, 0.2, 0.3, 0.5)
#: The columns, as the tuning table names them.
COLUMNS = ("none", "medium", "medium compensated", "hard", "hard compensated")
#: The tuned designs the grid is tried on by default.
DEFAULT_POLICIES = ("decentralized_edge", "decentralized_locked", "decentralized_edge_locked",
                    "centralized_robust_edge", "centralized_9levels")
DEFAULT_JSON = Path("renders/fuzzy_design/near_gain.json")


def with_gain(policy: Policy, gain: float, angle_deg: float) -> Policy:
    """``policy`` with the near-goal gain (``gain``, ``angle_deg``) added to its read-out."""
    meta = dict(policy.meta)
    meta["readout"] = dict(meta.get("readout", {}), near_gain=gain, near_deg=angle_deg)
    return Policy(policy.kind, policy.agents, meta)


def cells(controller) -> dict:
    """Successes of ``controller`` in every column of the tuning table."""
    out = {"none": int(evaluate(controller, x0=POSES).score.successes)}
    for level in ("medium", "hard"):
        for compensate in (False, True):
            e = evaluate(controller, x0=POSES[:CHALLENGE_POSES], challenge=level,
                         seed=PLANT_SEED, count=CHALLENGE_PLANTS, compensate=compensate)
            out[level + (" compensated" if compensate else "")] = int(e.score.successes)
    return out


#: The choices the study makes: a name and the columns whose successes it sums.
CRITERIA = {"challenge sum": COLUMNS[1:], "hard compensated": ("hard compensated",),
            "medium (wide)": ("medium_wide",)}
#: Plants of the wide ``medium`` measurement (``--medium-wide``): the tuning seeds' first 32.
WIDE_PLANTS = 32


def choose(rows: list, columns=COLUMNS[1:], nominal: int = len(POSES)) -> dict:
    """The row that keeps all ``nominal`` poses with the most successes summed over
    ``columns`` (ties: the larger gain, then the smaller angle); None when no row keeps
    them."""
    kept = [r for r in rows if r["cells"]["none"] == nominal]
    if not kept:
        return None
    return max(kept, key=lambda r: (sum(r["cells"][c] for c in columns), r["gain"],
                                    -r["angle_deg"]))


def choices(run: dict) -> dict:
    """Every criterion's choice for one policy's run: {criterion: {angle_deg, gain} or
    None}."""
    out = {}
    for name, columns in CRITERIA.items():
        if not all(c in r["cells"] for r in run["rows"] for c in columns):
            continue                        # not measured for this policy
        pick = choose(run["rows"], columns)
        out[name] = None if pick is None else {"angle_deg": pick["angle_deg"],
                                               "gain": pick["gain"]}
    return out


def _parts() -> dict:
    from twolink.sim.challenges import LEVELS, Challenge

    h = LEVELS["hard"]
    return {"delays": Challenge("delays", action_delay=h.action_delay,
                                observation_delay=h.observation_delay),
            "noise": Challenge("noise", angle_noise_deg=h.angle_noise_deg,
                               speed_noise=h.speed_noise),
            "plants": Challenge("plants", spread=h.spread, torque_limit=h.torque_limit),
            "faults": Challenge("faults", dropout=h.dropout, stuck=h.stuck)}


#: The parts of the ``hard`` level, each alone (``--parts``).
PARTS = tuple(_parts())


def measure_parts(run: dict) -> dict:
    """Successes of ``run``'s policy without and with its all-round gain and of
    ``pd_deadzone`` under each part of ``hard`` alone, on the tuning table's 32 poses and 8
    plants without compensation."""
    from twolink.control.baselines import baseline

    pick = run["chosen"]["challenge sum"]
    base = load_policy(run["policy"])
    controllers = {"plain read-out": base,
                   "with the gain": with_gain(base, pick["gain"], pick["angle_deg"]),
                   "pd_deadzone": baseline("pd_deadzone")}
    out = {}
    for part, challenge in _parts().items():
        out[part] = {k: int(evaluate(c, x0=POSES[:CHALLENGE_POSES], challenge=challenge,
                                     seed=PLANT_SEED, count=CHALLENGE_PLANTS
                                     ).score.successes) for k, c in controllers.items()}
        print(f"{run['policy']}, {part} alone: {out[part]}", flush=True)
    return {"gain": pick["gain"], "angle_deg": pick["angle_deg"], "runs": out}


def wide_medium(controller) -> int:
    """Successes under ``medium`` without compensation on all 48 poses and
    :data:`WIDE_PLANTS` plants of the tuning seeds."""
    return int(evaluate(controller, x0=POSES, challenge="medium", seed=PLANT_SEED,
                        count=WIDE_PLANTS).score.successes)


def add_wide_medium(run: dict) -> dict:
    """``run`` with ``medium_wide`` measured for its base and every row."""
    base = load_policy(run["policy"])
    run["base"]["medium_wide"] = wide_medium(base)
    print(f"{run['policy']}: medium (wide) {run['base']['medium_wide']}", flush=True)
    for row in run["rows"]:
        row["cells"]["medium_wide"] = wide_medium(with_gain(base, row["gain"],
                                                            row["angle_deg"]))
        print(f"  A {row['angle_deg']:g} deg, g {row['gain']:g}: medium (wide) "
              f"{row['cells']['medium_wide']}", flush=True)
    return run


def measure(name: str) -> dict:
    """The grid on the shipped policy ``name``, its plain read-out first."""
    t0 = time.perf_counter()
    base = load_policy(name)
    run = {"policy": name, "base": cells(base), "rows": []}
    print(f"{name}: {run['base']}", flush=True)
    for angle in ANGLES_DEG:
        for gain in GAINS:
            row = {"angle_deg": angle, "gain": gain, "cells": cells(with_gain(base, gain, angle))}
            run["rows"].append(row)
            print(f"  A {angle:g} deg, g {gain:g}: {row['cells']}", flush=True)
    run["seconds"] = round(time.perf_counter() - t0, 1)
    return run


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--policies", nargs="+", default=list(DEFAULT_POLICIES), metavar="NAME",
                    help="shipped two-link policies (default: " + ", ".join(DEFAULT_POLICIES)
                         + ")")
    ap.add_argument("--json", type=Path, default=DEFAULT_JSON, help=f"default {DEFAULT_JSON}")
    ap.add_argument("--choose-only", action="store_true",
                    help="measure nothing: apply the choice to the file's runs again")
    ap.add_argument("--medium-wide", action="store_true",
                    help=f"add medium without compensation on 48 poses x {WIDE_PLANTS} "
                         f"plants to the file's runs of --policies (measured before)")
    ap.add_argument("--parts", action="store_true",
                    help="measure --policies (their grids measured before) with and without "
                         "the all-round gain under each part of hard alone")
    args = ap.parse_args(argv)
    try:
        unknown = [n for n in args.policies if n not in TWO_LINK]
        if unknown:
            raise ValueError(f"unknown two-link shipped policy {unknown[0]!r}; choose from "
                             + ", ".join(TWO_LINK))
        if any(SHIPPED[n].near_gain < 1 for n in args.policies):
            raise ValueError("give policies without a near-goal gain of their own")
        data = read_runs(args.json, SCHEMA, VERSION)
        if args.choose_only and not data["runs"]:
            raise ValueError(f"--choose-only needs runs to choose from; {args.json} has none")
    except ValueError as exc:
        print(f"near_gain: error: {exc}", file=sys.stderr)
        return 2
    runs = {r["policy"]: r for r in data["runs"]}
    for flag, given in (("--medium-wide", args.medium_wide), ("--parts", args.parts)):
        missing = [n for n in args.policies if n not in runs]
        if given and missing:
            print(f"near_gain: error: {flag} needs the grid of {missing[0]} in "
                  f"{args.json} first", file=sys.stderr)
            return 2
    for name in () if args.choose_only or args.parts else dict.fromkeys(args.policies):
        runs[name] = add_wide_medium(runs[name]) if args.medium_wide else measure(name)
    for name, run in runs.items():
        run["chosen"] = choices(run)
        print(json.dumps({"policy": name, "chosen": run["chosen"]}), flush=True)
    for name in dict.fromkeys(args.policies) if args.parts else ():
        runs[name]["parts"] = measure_parts(runs[name])
    order = [n for n in TWO_LINK if n in runs]
    args.json.parent.mkdir(parents=True, exist_ok=True)
    write_json(args.json, {"schema": SCHEMA, "version": VERSION,
                           "grid": {"angles_deg": list(ANGLES_DEG), "gains": list(GAINS)},
                           "runs": [runs[n] for n in order], "provenance": provenance()})
    return 0


if __name__ == "__main__":
    sys.exit(main())
