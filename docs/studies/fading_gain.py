"""The fading gain (a hold region with hysteresis) on the fastest tuned designs, measured on
the tuning seeds.

``python docs/studies/fading_gain.py [--policies NAME ...] [--json FILE]`` wraps each
named shipped policy in every fading gain of the grid (:data:`GRID`:
:class:`twolink.control.fading.FadingGain`; a joint that has settled in the goal band
has its torque lowered by ``1 / fade_samples`` per sample down to ``floor`` until its
reading leaves ``exit_deg`` / ``exit_speed``) and measures it as the tuning table does
(``docs/studies/fuzzy_design.py``: 48 poses nominal, the settle / T* of the 64-state
tuning grid, 32 poses on 8 plants under ``medium`` without compensation and ``hard`` with
it; all from the tuning seeds, never the leaderboard's). The question it answers: does
a gain that fades once the arm has settled make a fast design robust
(the targets of the recommended designs: ``medium`` plain >= 99 % and ``hard``
compensated >= 95 % centralized, >= 97 % and >= 90 % decentralized) without slowing it
(settle / T* <= 1.25 centralized, 1.6 decentralized)? :func:`verdict` answers it per
policy from the measured rows. The runs merge into the JSON (one per policy); the docs
generator does not read it: ``docs/results/fuzzy-designs.md``'s section on the fading
gain quotes this file's verdicts (re-run to check them). About 1 min per policy and
fade on this machine.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import numpy as np  # noqa: E402

from twolink.artifacts import provenance, read_runs, write_json  # noqa: E402
from twolink.control.fading import Fade, FadingGain  # noqa: E402
from twolink.policy.fuzzy_policy import load_policy  # noqa: E402
from twolink.policy.registry import SHIPPED, TWO_LINK  # noqa: E402
from twolink.sim.evaluation import evaluate  # noqa: E402
from twolink.studies.fuzzy_design.tuning_set import (  # noqa: E402
    CHALLENGE_PLANTS,
    CHALLENGE_POSES,
    PLANT_SEED,
    POSES,
    ratio_grid,
)

SCHEMA, VERSION = "twolink.fading_gain", 1
#: The fades tried: (exit_deg, exit_speed) x floor x fade_samples.
GRID = tuple(Fade(exit_deg=e, exit_speed=s, floor=g, fade_samples=k)
             for e, s in ((7.0, 0.2), (12.0, 0.5)) for g in (0.0, 0.3, 0.6)
             for k in (1, 10))
#: The fastest tuned design of each kind (the tuning table's settle / T*) and the most
#: robust decentralized one.
DEFAULT_POLICIES = ("centralized_9levels", "decentralized_edge_locked",
                    "decentralized_locked")
#: The recommended designs' targets per kind: settle / T* at most, medium plain and hard
#: compensated success at least.
TARGETS = {"centralized": (1.25, 0.99, 0.95), "decentralized": (1.6, 0.97, 0.90)}
DEFAULT_JSON = Path("renders/fuzzy_design/fading_gain.json")


def measure(controller) -> dict:
    """The tuning-table cells of ``controller``: nominal successes of 48 poses, the
    median settle / T* over the tuning grid, medium plain and hard compensated successes
    of 32 poses x 8 plants."""
    out = {"none": int(evaluate(controller, x0=POSES).score.successes), "n_none": len(POSES)}
    states, limit = ratio_grid()
    ratio = evaluate(controller, x0=states).settle.ravel() / limit
    out["ratio_median"] = float(np.median(ratio)) if np.isfinite(np.median(ratio)) else None
    for level, compensate, key in (("medium", False, "medium"),
                                   ("hard", True, "hard compensated")):
        e = evaluate(controller, x0=POSES[:CHALLENGE_POSES], challenge=level,
                     seed=PLANT_SEED, count=CHALLENGE_PLANTS, compensate=compensate)
        out[key], out["n_challenge"] = int(e.score.successes), int(e.score.n)
    return out


def verdict(run: dict) -> dict:
    """Per policy: the base's cells, the best fade by medium plain successes (ties: hard
    compensated, then speed), whether it beats the base there, and whether any fade meets
    every target of the policy's kind."""
    ratio_max, medium_min, hard_min = TARGETS[run["kind"]]

    def meets(c):
        n = c["n_challenge"]
        return (c["none"] == c["n_none"] and c["ratio_median"] is not None
                and c["ratio_median"] <= ratio_max and c["medium"] >= medium_min * n
                and c["hard compensated"] >= hard_min * n)

    rows = run["fades"]
    best = max(rows, key=lambda r: (r["cells"]["medium"], r["cells"]["hard compensated"],
                                    -(r["cells"]["ratio_median"] or 1e9)))
    return {"base": run["base"], "base_meets_targets": meets(run["base"]),
            "best_fade": best["fade"], "best_cells": best["cells"],
            "best_beats_base_on_medium": best["cells"]["medium"] > run["base"]["medium"],
            "fades_meeting_targets": [r["fade"] for r in rows if meets(r["cells"])]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--policies", nargs="+", default=list(DEFAULT_POLICIES), metavar="NAME",
                    help=f"shipped two-link policies (default {' '.join(DEFAULT_POLICIES)})")
    ap.add_argument("--json", type=Path, default=DEFAULT_JSON, help=f"default {DEFAULT_JSON}")
    args = ap.parse_args(argv)
    try:
        for name in args.policies:
            if name not in TWO_LINK:
                raise ValueError(f"unknown two-link shipped policy {name!r}")
        data = read_runs(args.json, SCHEMA, VERSION)
    except ValueError as exc:
        print(f"fading_gain: error: {exc}", file=sys.stderr)
        return 2
    for name in args.policies:
        t0 = time.perf_counter()
        policy = load_policy(name)
        run = {"policy": name, "kind": SHIPPED[name].kind, "base": measure(policy),
               "fades": []}
        print(f"{name}: base {run['base']}", flush=True)
        for fade in GRID:
            cells = measure(FadingGain(policy, fade))
            run["fades"].append({"fade": fade.as_dict(), "cells": cells})
            print(f"  {fade.as_dict()}: {cells}", flush=True)
        run["seconds"] = round(time.perf_counter() - t0, 1)
        run["verdict"] = verdict(run)
        data["runs"] = [r for r in data["runs"] if r["policy"] != name] + [run]
        args.json.parent.mkdir(parents=True, exist_ok=True)
        write_json(args.json, {"schema": SCHEMA, "version": VERSION, "runs": data["runs"],
                               "tuning_seeds": PLANT_SEED, "provenance": provenance()})
        print(json.dumps({name: run["verdict"]}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
