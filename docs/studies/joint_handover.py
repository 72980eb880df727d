"""A decentralized handover, joint by joint, measured on the tuning seeds: can the fastest
decentralized design hand each joint to a robust design and meet the recommended
decentralized targets?

The centralized handover (:class:`twolink.control.handover.Handover`) switches on the
whole state, so it cannot serve a decentralized design. :class:`JointHandover` switches
each joint's torque alone, on that joint's reading only, so each agent keeps to its own
information: joint i takes ``hold``'s torque once its reading has stayed within
``rescue_deg`` of the goal for ``rescue_s`` seconds (a rescue; with ``band``, also once
it reads inside the goal band (15)), and ``approach``'s again once it reads beyond
``exit_deg``.

``python docs/studies/joint_handover.py [--json FILE]`` runs ``decentralized_edge_locked``
(the fastest decentralized design, 1.56 x T* on the leaderboard, 66 % under ``medium``
plain) alone and handing over to each robust decentralized design of :data:`HOLDS` with
each switch of :data:`SWITCHES`, on the tuning table's cells
(``docs/studies/fading_gain.py``'s ``measure``: 48 poses nominal, the settle / T* of the
tuning grid, 32 poses on 8 plants under ``medium`` plain and ``hard`` compensated; all
from the tuning seeds, never the leaderboard's), and says which rows meet the
decentralized targets (:data:`fading_gain.TARGETS`: 48/48, settle / T* <= 1.6, ``medium``
plain >= 97 %, ``hard`` compensated >= 90 %). About 3 min on this machine; writes
``renders/fuzzy_design/joint_handover.json``.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
    sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402
from fading_gain import TARGETS, measure  # noqa: E402

from twolink.arm.parameters import TS  # noqa: E402
from twolink.artifacts import provenance, write_json  # noqa: E402
from twolink.control.controllers import resolve_controller  # noqa: E402
from twolink.control.fading import band_readings, goal_angles  # noqa: E402
from twolink.control.handover import Regions  # noqa: E402
from twolink.sim.controller import ControllerError, reset_controller  # noqa: E402

SCHEMA, VERSION = "twolink.joint_handover", 1
APPROACH = "decentralized_edge_locked"
#: The hold designs tried: the robust decentralized designs.
HOLDS = ("decentralized_locked_gain_medium", "decentralized_locked",
         "decentralized_locked_gain", "decentralized_edge_gain_hard",
         "decentralized_edge_gain")
#: The switches tried: (rescue_deg, rescue_s, exit_deg, band).
SWITCHES = ((10.0, 2.0, 30.0, False), (15.0, 1.0, 30.0, False), (15.0, 3.0, 30.0, False),
            (15.0, 2.0, 30.0, True), (5.0, 1.0, 30.0, True))
DEFAULT_JSON = Path("renders/fuzzy_design/joint_handover.json")


class JointHandover:
    """``approach``'s torque on each joint until that joint's reading has stayed within
    ``rescue_deg`` for ``rescue_s`` s (or, with ``band``, reads inside the goal band),
    then ``hold``'s until it reads beyond ``exit_deg`` (module docstring). Both designs
    drive the same arm and see every sample."""

    kind = "decentralized"

    def __init__(self, approach, hold, *, rescue_deg: float, rescue_s: float,
                 exit_deg: float, band: bool, name: str = "joint_handover"):
        links = {getattr(c, "links", 2) for c in (approach, hold)}
        if len(links) != 1:
            raise ControllerError(f"{name}: its designs drive arms of "
                                  f"{' and '.join(map(str, sorted(links)))} links")
        if not 0 < rescue_deg <= exit_deg <= 180:
            raise ValueError(f"{name}: need 0 < rescue_deg <= exit_deg <= 180, got "
                             f"{rescue_deg}, {exit_deg}")
        self.approach, self.hold, self.links, self.name = approach, hold, links.pop(), name
        self.rescue_deg, self.exit_deg, self.band = rescue_deg, exit_deg, band
        self.rescue_samples = max(1, round(rescue_s / TS))
        self.meta = dict(getattr(approach, "meta", None) or {})
        self.on = self.dwell = None

    def reset(self, n: int) -> None:
        self.on = np.zeros((n, self.links), dtype=bool)
        self.dwell = np.zeros((n, self.links), dtype=int)
        reset_controller(self.approach, n)
        reset_controller(self.hold, n)

    def __call__(self, x) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        if self.on is None or self.on.shape[0] != x.shape[0]:
            self.reset(x.shape[0])
        theta = goal_angles(x, self.links)
        near = (theta <= math.radians(self.rescue_deg)) & ~self.on
        self.dwell = np.where(near, self.dwell + 1, 0)
        start = self.dwell >= self.rescue_samples
        if self.band:
            start |= band_readings(x, self.links, Regions())[0]
        self.on = (self.on | start) & (theta <= math.radians(self.exit_deg))
        fast = np.asarray(self.approach(x), dtype=float)
        slow = np.asarray(self.hold(x), dtype=float)
        return np.where(self.on, slow, fast)


def meets(cells: dict) -> bool:
    """Whether tuning cells meet every decentralized target."""
    ratio_max, medium_min, hard_min = TARGETS["decentralized"]
    n = cells["n_challenge"]
    return (cells["none"] == cells["n_none"] and cells["ratio_median"] is not None
            and cells["ratio_median"] <= ratio_max and cells["medium"] >= medium_min * n
            and cells["hard compensated"] >= hard_min * n)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", type=Path, default=DEFAULT_JSON, help=f"default {DEFAULT_JSON}")
    ap.add_argument("--holds", nargs="+", default=list(HOLDS), metavar="NAME",
                    help="the hold designs (default: all of HOLDS)")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    fast = resolve_controller(APPROACH)
    alone = measure(fast)
    print(f"{APPROACH} alone: {alone}", flush=True)
    rows = []
    for hold in args.holds:
        slow = resolve_controller(hold)
        for rescue_deg, rescue_s, exit_deg, band in SWITCHES:
            switch = {"rescue_deg": rescue_deg, "rescue_s": rescue_s, "exit_deg": exit_deg,
                      "band": band}
            cells = measure(JointHandover(fast, slow, **switch))
            rows.append({"hold": hold, "switch": switch, "cells": cells,
                         "meets": meets(cells)})
            print(f"{hold} {switch}: {cells}", flush=True)
    met = [r for r in rows if r["meets"]]
    print(f"{len(met)} of {len(rows)} handovers meet every decentralized target on the "
          "tuning cells", flush=True)
    out = {"schema": SCHEMA, "version": VERSION, "approach": APPROACH,
           "approach_alone": alone, "targets": TARGETS["decentralized"], "rows": rows,
           "meeting": len(met), "seconds": round(time.perf_counter() - t0, 1),
           "provenance": provenance()}
    args.json.parent.mkdir(parents=True, exist_ok=True)
    write_json(args.json, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
