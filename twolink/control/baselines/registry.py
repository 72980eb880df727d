"""The shipped baselines: :data:`BASELINES` builds each from the tuned gains of
``gains.json`` (written by ``python -m twolink.control.baselines.tuning --write``, found
through :mod:`importlib.resources`, so a wheel finds it too)."""
from __future__ import annotations

import copy
import dataclasses
import functools
import importlib.resources
import json

from twolink.control.baselines.bang_bang import ProximateTimeOptimal
from twolink.control.baselines.lqr import SaturatedLQR
from twolink.control.baselines.pd import SaturatedPD

#: The data file of the tuned gains, in this package.
GAINS_FILE = "gains.json"
#: Its format tag.
GAINS_FORMAT = "twolink-baseline-gains/1"
#: Controller classes by their ``type``.
TYPES = {cls.TYPE: cls for cls in (SaturatedPD, SaturatedLQR, ProximateTimeOptimal)}


def gains_path():
    """The shipped gains file (a :class:`importlib.resources` traversable)."""
    return importlib.resources.files(__package__) / GAINS_FILE


@functools.lru_cache(maxsize=1)
def _shipped() -> dict:
    path = gains_path()
    if not path.is_file():
        raise FileNotFoundError(f"no shipped baseline gains at {path}; write them with "
                                "`python -m twolink.control.baselines.tuning --write`")
    return check_gains(json.loads(path.read_text()))


def check_gains(data) -> dict:
    """``data`` if it is a gains document (format tag and a controller per entry)."""
    if not isinstance(data, dict) or data.get("format") != GAINS_FORMAT:
        raise ValueError(f"not a baseline gains document (format {GAINS_FORMAT!r})")
    entries = data.get("controllers")
    if not isinstance(entries, dict) or not all(
            isinstance(e, dict) and isinstance(e.get("controller"), dict)
            for e in entries.values()):
        raise ValueError("a gains document maps names to entries holding a 'controller'")
    return data


def load_gains() -> dict:
    """The shipped gains document (a copy): controllers with their tuning provenance."""
    return copy.deepcopy(_shipped())


def from_description(data: dict):
    """The controller an ``as_dict()`` describes (its ``type`` picks the class)."""
    if not isinstance(data, dict) or data.get("type") not in TYPES:
        raise ValueError(f"a controller description needs a type, one of "
                         f"{', '.join(TYPES)}; got {data!r:.80}")
    return TYPES[data["type"]].from_dict(data)


@dataclasses.dataclass(frozen=True)
class Entry:
    """How to build one shipped baseline: its class and what it is for; calling it
    builds a fresh controller from the shipped gains (or from ``gains``, a document)."""

    name: str
    cls: type
    description: str
    kind: str = "decentralized"     # "centralized" (reads the whole state) or per joint

    def __call__(self, gains: dict | None = None):
        doc = _shipped() if gains is None else check_gains(gains)
        entry = doc["controllers"].get(self.name)
        if entry is None:
            raise ValueError(f"the gains document holds no {self.name!r}; it has "
                             f"{', '.join(doc['controllers'])}")
        ctrl = self.cls.from_dict(entry["controller"])
        if ctrl.name != self.name:
            raise ValueError(f"the gains of {self.name!r} describe a controller named "
                             f"{ctrl.name!r}")
        return ctrl


#: The shipped baselines by name.
BASELINES = {e.name: e for e in (
    Entry("pd", SaturatedPD, "saturated decentralized PD, tuned on the nominal arm"),
    Entry("pd_deadzone", SaturatedPD, "saturated decentralized PD with an angle dead zone, "
          "tuned on medium-challenge plants without compensation"),
    Entry("lqr", SaturatedLQR, "saturated discrete LQR of the ZOH linearisation of (6), "
          "tuned on the nominal arm", "centralized"),
    Entry("lqr_delay", SaturatedLQR, "saturated LQR augmented with the last torque (the "
          "medium challenge's one-sample actuation delay), tuned on medium plants",
          "centralized"),
    Entry("bang_bang", ProximateTimeOptimal, "per-joint proximate time-optimal "
          "(bang-bang with a linear zone), tuned on the nominal arm"),
)}


def baseline(name: str, gains: dict | None = None):
    """A fresh shipped baseline by name (see :data:`BASELINES`)."""
    if name not in BASELINES:
        raise ValueError(f"unknown baseline {name!r}; choose one of {', '.join(BASELINES)}")
    return BASELINES[name](gains)
