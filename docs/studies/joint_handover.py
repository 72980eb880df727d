"""A decentralized handover, joint by joint or on a clock, measured on the tuning seeds:
can the fastest decentralized design hand the arm to a robust design and meet the
recommended decentralized targets?

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
plain >= 97 %, ``hard`` compensated >= 90 %).

Then the same handovers on a clock (:class:`twolink.control.handover.TimedHandover`):
``decentralized_edge_locked`` for the first ``after_s`` seconds of :data:`CLOCKS`, the
hold design from then on. The switch reads no state, so every agent switches its own
joint at the same instant without a message. Each row fast enough on the cells (48/48,
settle / T* within the target) is also measured on the wider tuning-side set of
``docs/studies/handover.py`` (:func:`handover.wide`: the 65 evaluation states on 32
plants of the tuning plant seed, the leaderboard's protocol on plants it never uses).
:func:`pick` names the row the catalogue ships as ``decentralized_handover``: among the
rows fast enough on the cells whose ``hard`` compensated successes on the wide set meet
their target, the most ``medium`` plain successes there, then the most ``hard``
compensated, then the fastest, then the earliest switch. It meets every target when its
``medium`` plain successes meet theirs too; otherwise it is the closest such row, and the
JSON says so (``pick_meets``).

Last, a fading gain on the approach's own table (:func:`fade_rows`): at the switch time
of the best clock row (:func:`pick` over the clock rows alone), the hold design is
``decentralized_edge_locked``'s Q-tables read through each read-out of :data:`FADES` (a
speed dead zone and a near-goal gain, :class:`twolink.policy.readout.Readout`), so the
arm keeps the approach's table and only its torque near the goal fades once the clock
has run. These rows are measured as the clock rows (cells, then the wide set), and the
pick is made again over the clock rows and these together.

About 25 min on this machine; writes ``renders/fuzzy_design/joint_handover.json``.
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

import itertools  # noqa: E402

import numpy as np  # noqa: E402
from fading_gain import TARGETS, measure  # noqa: E402
from handover import wide  # noqa: E402

from twolink.arm.parameters import TS  # noqa: E402
from twolink.artifacts import provenance, write_json  # noqa: E402
from twolink.control.controllers import resolve_controller  # noqa: E402
from twolink.control.fading import band_readings, goal_angles  # noqa: E402
from twolink.control.handover import Regions, TimedHandover  # noqa: E402
from twolink.policy.fuzzy_policy import load_policy  # noqa: E402
from twolink.policy.readout import Readout  # noqa: E402
from twolink.sim.controller import ControllerError, reset_controller  # noqa: E402

SCHEMA, VERSION = "twolink.joint_handover", 3
APPROACH = "decentralized_edge_locked"
#: The hold designs tried: the robust decentralized designs.
HOLDS = ("decentralized_locked_gain_medium", "decentralized_locked",
         "decentralized_locked_gain", "decentralized_edge_gain_hard",
         "decentralized_edge_gain")
#: The switches tried: (rescue_deg, rescue_s, exit_deg, band).
SWITCHES = ((10.0, 2.0, 30.0, False), (15.0, 1.0, 30.0, False), (15.0, 3.0, 30.0, False),
            (15.0, 2.0, 30.0, True), (5.0, 1.0, 30.0, True))
#: The clock handovers' switch times (s after the rollout begins).
CLOCKS = (1.5, 2.0, 2.5, 3.0, 3.5, 4.0)
#: The fading read-outs tried on the approach's own table: speed dead zone (rad/s),
#: near-goal gain and the angle (deg) from which the torque is full again; the argmax
#: rule stays the approach's (:func:`fade_readout`).
FADES = tuple(itertools.product((0.02, 0.04, 0.06), (0.1, 0.2, 0.3), (90.0, 120.0, 180.0)))
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


def fast_enough(cells: dict) -> bool:
    """Whether tuning cells meet the nominal and speed targets (48/48, settle / T*)."""
    return (cells["none"] == cells["n_none"] and cells["ratio_median"] is not None
            and cells["ratio_median"] <= TARGETS["decentralized"][0])


def wide_meets(w: dict) -> bool:
    """Whether the wide set meets the ``medium`` plain and ``hard`` compensated targets."""
    _, medium_min, hard_min = TARGETS["decentralized"]
    return w["medium"] >= medium_min * w["n"] and w["hard compensated"] >= hard_min * w["n"]


def pick(rows: list) -> dict | None:
    """The clock row the catalogue ships (module docstring): among ``rows`` fast enough on
    the cells whose wide ``hard`` compensated successes meet their target, the most wide
    ``medium`` plain successes, then ``hard`` compensated, then the lowest median
    settle / T* on the cells, then the earliest switch; None when no row qualifies."""
    hard_min = TARGETS["decentralized"][2]
    ok = [r for r in rows if r["wide"] is not None and fast_enough(r["cells"])
          and r["wide"]["hard compensated"] >= hard_min * r["wide"]["n"]]
    if not ok:
        return None
    return min(ok, key=lambda r: (-r["wide"]["medium"], -r["wide"]["hard compensated"],
                                  r["cells"]["ratio_median"], r["after_s"]))


def fade_readout(speed_dead_zone: float, near_gain: float, near_deg: float) -> Readout:
    """The read-out of a fade row: the approach's argmax rule with the given speed dead
    zone and near-goal gain."""
    base = load_policy(APPROACH).readout
    return Readout(speed_dead_zone=speed_dead_zone,
                   argmax_beyond_deg=base.argmax_beyond_deg, near_gain=near_gain,
                   near_deg=near_deg)


def measured(hold, after_s: float, fast) -> tuple[dict, dict | None]:
    """The cells of the clock handover ``fast`` -> ``hold`` after ``after_s`` s, and its
    wide set when it is fast enough on them (else None)."""
    h = TimedHandover(fast, hold, after_s)
    cells = measure(h)
    return cells, (wide(h) if fast_enough(cells) else None)


def fade_rows(after_s: float, fast, fades=FADES) -> list:
    """The fade rows (module docstring): the approach's table through each read-out of
    ``fades``, handed over to after ``after_s`` s."""
    table = load_policy(APPROACH)
    rows = []
    for dead_zone, gain, deg in fades:
        readout = fade_readout(dead_zone, gain, deg)
        cells, w = measured(table.with_readout(readout), after_s, fast)
        rows.append({"hold": APPROACH, "readout": readout.as_dict(), "after_s": after_s,
                     "cells": cells, "wide": w, "meets": w is not None and wide_meets(w)})
        print(f"{APPROACH} through {readout.as_dict()} after {after_s:g} s: {cells}, "
              f"wide {w}", flush=True)
    return rows


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
    print(f"{len(met)} of {len(rows)} handovers joint by joint meet every decentralized "
          "target on the tuning cells", flush=True)
    clock_rows = []
    for hold in args.holds:
        slow = resolve_controller(hold)
        for after_s in CLOCKS:
            cells, w = measured(slow, after_s, fast)
            clock_rows.append({"hold": hold, "after_s": after_s, "cells": cells,
                               "wide": w, "meets": w is not None and wide_meets(w)})
            print(f"{hold} after {after_s:g} s: {cells}, wide {w}", flush=True)
    best_clock = pick(clock_rows)
    print(f"{sum(r['meets'] for r in clock_rows)} of {len(clock_rows)} handovers on a "
          f"clock meet them (speed on the cells, robustness on the wide set); the best: "
          f"{best_clock and (best_clock['hold'], best_clock['after_s'])}", flush=True)
    fades = [] if best_clock is None else fade_rows(best_clock["after_s"], fast)
    chosen = pick(clock_rows + fades)
    print(f"{sum(r['meets'] for r in fades)} of {len(fades)} fades meet them; pick: "
          f"{chosen and (chosen['hold'], chosen.get('readout'), chosen['after_s'])} "
          f"(meets every target: {bool(chosen and chosen['meets'])})", flush=True)
    out = {"schema": SCHEMA, "version": VERSION, "approach": APPROACH,
           "approach_alone": alone, "targets": TARGETS["decentralized"], "rows": rows,
           "meeting": len(met), "clock_rows": clock_rows, "best_clock": best_clock,
           "fade_rows": fades, "pick": chosen,
           "pick_meets": bool(chosen and chosen["meets"]),
           "seconds": round(time.perf_counter() - t0, 1), "provenance": provenance()}
    args.json.parent.mkdir(parents=True, exist_ok=True)
    write_json(args.json, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
