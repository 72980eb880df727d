"""A handover between two designs: a fast one brings the arm into the goal band, a robust
one holds it there.

The fastest centralized design, ``centralized_9levels``, settles at 1.22 T* nominally,
but under delays and noise its full-torque answers near the goal push the arm out of the
band again; the designs with a near-goal gain hold the band under ``hard`` but approach
slowly. :class:`Handover` runs ``approach`` until the reading of every joint lies within
``enter_deg`` degrees and ``enter_speed`` rad/s of the goal (by default the goal band of
(15): the arm has settled), then ``hold`` until a reading of any joint lies beyond
``exit_deg`` or ``exit_speed`` (hysteresis: exit >= enter), then ``approach`` again. Both
controllers are called on every sample, so each keeps its own state (a history, a fading
gain) whichever acts. The switch reads the whole state, so a handover is a centralized
controller whatever its parts are.

A rescue (``rescue_deg``, off by default) catches the other way a fast design fails on a
mismatched plant: a limit cycle *around* the goal band that never enters it (amplitudes
of 5-10 deg at 1-3 rad/s under ``medium``). When every joint has read within
``rescue_deg`` of the goal for ``rescue_s`` seconds in a row without the hold acting,
``hold`` takes over until the arm enters the enter region (then the hold's own
hysteresis applies). A nominal approach crosses that region in well under a second, so
the rescue leaves the fast design's settle times alone.

:class:`TimedHandover` switches on a clock instead: ``approach`` for the first ``after_s``
seconds of a rollout, ``hold`` from then on. Its switch reads no state, only the time since
the rollout began, which every agent keeps alike without a message, so a timed handover
between two decentralized designs is itself decentralized: each agent runs the two
designs' agents of its own joint and switches at the same instant.

:data:`HANDOVERS` holds the shipped handovers, catalogue entries by name
(:mod:`twolink.control.catalogue`); :func:`handover_policy` makes one from the names of
its two designs and its regions, as a catalogue entry's data gives them.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from twolink.arm.parameters import GOAL_ANGLE, GOAL_SPEED, TS
from twolink.control.fading import band_readings, check_band, goal_angles
from twolink.sim.controller import ControllerError, reset_controller
from twolink.validate import real

#: The longest wait (s) a switch may name: a rescue's dwell, a timed handover's switch.
MAX_SWITCH_S = 60.0


@dataclasses.dataclass(frozen=True)
class Regions:
    """Where a :class:`Handover` hands over: ``enter_*`` (every joint inside: to
    ``hold``), ``exit_*`` (any joint beyond: back to ``approach``) and the rescue
    (``rescue_deg``, None: none; every joint within it for ``rescue_s`` seconds: to
    ``hold`` until the enter region); checked on creation."""

    enter_deg: float = math.degrees(GOAL_ANGLE)
    enter_speed: float = GOAL_SPEED
    exit_deg: float = 10.0
    exit_speed: float = 0.3
    rescue_deg: float | None = None
    rescue_s: float = 1.0

    def __post_init__(self):
        check_band(self)
        if self.rescue_deg is not None:
            real(self.rescue_deg, "rescue_deg", self.enter_deg, 180.0)
        real(self.rescue_s, "rescue_s", TS, MAX_SWITCH_S)

    @property
    def rescue_samples(self) -> int:
        """The rescue's dwell in samples Ts."""
        return max(1, round(self.rescue_s / TS))

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


class Handover:
    """``approach`` until the arm enters ``regions``' enter region, ``hold`` until it
    leaves the exit region (module docstring); ``name`` labels it. Both controllers map
    states (n, 2N) to torques (n, N) for the same N; where both name the model they were
    designed on (``meta["model"]``, what ``--compensate`` predicts with) it must be one."""

    kind = "centralized"

    def __init__(self, approach, hold, regions: Regions | None = None, *,
                 name: str = "handover"):
        regions = Regions() if regions is None else regions
        if not isinstance(regions, Regions):
            raise TypeError(f"regions must be a Regions, got {type(regions).__name__}")
        links, metas = _pair(approach, hold, name)
        self.approach, self.hold, self.regions = approach, hold, regions
        self.links, self.name = links, name
        self.meta = {**metas[0], "handover": {
            "approach": getattr(approach, "name", "approach"),
            "hold": getattr(hold, "name", "hold"), **regions.as_dict()}}
        self.held = self.rescued = self.dwell = None

    def reset(self, n: int) -> None:
        """``n`` rows, each with ``approach`` acting; both designs reset."""
        self.held = np.zeros(n, dtype=bool)
        self.rescued = np.zeros(n, dtype=bool)
        self.dwell = np.zeros(n, dtype=int)
        reset_controller(self.approach, n)
        reset_controller(self.hold, n)

    def __call__(self, x) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        n = self.links
        if self.held is None or self.held.shape[0] != x.shape[0]:
            self.reset(x.shape[0])
        r = self.regions
        inside, beyond = band_readings(x, n, r)
        settled = inside.all(1)
        self.held = (self.held | settled) & ~beyond.any(1)
        if r.rescue_deg is not None:
            near = ((goal_angles(x, n) <= math.radians(r.rescue_deg)).all(1)
                    & ~self.held & ~self.rescued)
            self.dwell = np.where(near, self.dwell + 1, 0)
            self.rescued = (self.rescued | (self.dwell >= r.rescue_samples)) & ~settled
        fast = np.asarray(self.approach(x), dtype=float)
        slow = np.asarray(self.hold(x), dtype=float)
        return np.where((self.held | self.rescued)[:, None], slow, fast)


def _pair(approach, hold, name: str) -> tuple:
    """The links two designs share and their metas; a ControllerError when they drive
    arms of different links or name different models (compensation predicts with one)."""
    links = {getattr(c, "links", 2) for c in (approach, hold)}
    if len(links) != 1:
        raise ControllerError(f"handover {name}: its designs drive arms of "
                              f"{' and '.join(map(str, sorted(links)))} links")
    metas = [dict(getattr(c, "meta", None) or {}) for c in (approach, hold)]
    models = {m["model"] for m in metas if "model" in m}
    if len(models) > 1:
        raise ControllerError(f"handover {name}: its designs name the models "
                              f"{' and '.join(sorted(models))}; compensation predicts "
                              f"with one")
    return links.pop(), metas


class TimedHandover:
    """``approach`` for the first ``after_s`` seconds of a rollout (samples ``k <
    round(after_s / Ts)`` since :meth:`reset`), ``hold`` from then on (module
    docstring). Both designs see every sample. Decentralized when both designs are."""

    def __init__(self, approach, hold, after_s: float, *, name: str = "handover"):
        try:
            real(after_s, "after_s", TS, MAX_SWITCH_S)
        except ValueError as exc:
            raise ControllerError(f"handover {name}: {exc}") from None
        links, metas = _pair(approach, hold, name)
        kinds = {getattr(c, "kind", "centralized") for c in (approach, hold)}
        self.kind = "decentralized" if kinds == {"decentralized"} else "centralized"
        self.approach, self.hold, self.after_s = approach, hold, float(after_s)
        self.links, self.name = links, name
        self.switch_sample = round(self.after_s / TS)
        self.meta = {**metas[0], "handover": {
            "approach": getattr(approach, "name", "approach"),
            "hold": getattr(hold, "name", "hold"), "after_s": self.after_s}}
        self.samples = None

    def reset(self, n: int) -> None:
        """The clock back to 0; both designs reset for ``n`` rows."""
        self.samples = 0
        reset_controller(self.approach, n)
        reset_controller(self.hold, n)

    def __call__(self, x) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        if self.samples is None:
            self.reset(x.shape[0])
        fast = np.asarray(self.approach(x), dtype=float)
        slow = np.asarray(self.hold(x), dtype=float)
        held = self.samples >= self.switch_sample
        self.samples += 1
        return slow if held else fast


@dataclasses.dataclass(frozen=True)
class ShippedHandover:
    """A shipped handover: its two designs (catalogue names), its kind, and either its
    regions (a :class:`Handover`) or, with ``after_s``, the time of its switch (a
    :class:`TimedHandover`; ``regions`` unused)."""

    approach: str
    hold: str
    description: str
    regions: Regions = Regions()
    after_s: float | None = None
    kind: str = "centralized"

    def data(self, name: str) -> dict:
        """The keyword arguments of :func:`handover_policy` for this handover."""
        out = {"approach": self.approach, "hold": self.hold, "name": name}
        if self.after_s is None:
            return {**out, "regions": self.regions.as_dict()}
        return {**out, "after_s": self.after_s}


#: The shipped handovers by catalogue name (tag ``tuned``: the designs and the switch were
#: chosen on the tuning seeds, ``docs/studies/handover.py`` and
#: ``docs/studies/joint_handover.py``).
HANDOVERS = {
    "centralized_handover": ShippedHandover(
        "centralized_9levels", "centralized_robust_edge_gain_medium",
        "centralized_9levels until the arm has settled in the goal band (or has "
        "stayed within 15 deg of the goal for 1 s: a rescue), then "
        "centralized_robust_edge_gain_medium until a joint leaves 10 deg or 0.3 rad/s "
        "(twolink.control.handover)", Regions(rescue_deg=15.0, rescue_s=1.0)),
    "decentralized_handover": ShippedHandover(
        "decentralized_edge_locked", "decentralized_edge_locked_gain",
        "decentralized_edge_locked for the first 3 s of a rollout, then the same agents "
        "with their torque fading near the goal (decentralized_edge_locked_gain); the "
        "switch reads only the clock, so every agent makes it alone "
        "(twolink.control.handover.TimedHandover)", after_s=3.0,
        kind="decentralized"),
}


def handover_policy(approach: str, hold: str, regions: dict | None = None,
                    name: str = "handover", after_s: float | None = None):
    """The handover from the shipped fuzzy policy (or policy file) ``approach`` to
    ``hold`` over ``regions`` (the fields of :class:`Regions`; default the goal band in,
    10 deg or 0.3 rad/s out), or with ``after_s`` the :class:`TimedHandover` that switches
    then: the entry point of the shipped handovers' catalogue entries."""
    from twolink.policy.fuzzy_policy import load_policy

    if after_s is not None:
        if regions is not None:
            raise ControllerError(f"handover {name}: a timed handover (after_s) has no "
                                  f"regions")
        h = TimedHandover(load_policy(approach), load_policy(hold), after_s, name=name)
        h.meta["handover"].update(approach=approach, hold=hold)
        return h

    try:
        spec = Regions(**(regions or {}))
    except TypeError as exc:
        raise ControllerError(f"handover {name}: regions: {exc}") from None
    except ValueError as exc:
        raise ControllerError(f"handover {name}: {exc}") from None
    h = Handover(load_policy(approach), load_policy(hold), spec, name=name)
    h.meta["handover"].update(approach=approach, hold=hold)
    return h
