"""twolink: a MuJoCo testbed for Busoniu, De Schutter & Babuska (ICARCV 2006).

The package is layered, lower never importing higher: :mod:`twolink.arm` (the arm and
its models), :mod:`twolink.fqi` (fuzzy Q-iteration), :mod:`twolink.policy`,
:mod:`twolink.sim` (plants, challenges, rollouts, evaluation), :mod:`twolink.control`
(synthesis, N-link agents, online learning), :mod:`twolink.viz`, :mod:`twolink.envs`,
:mod:`twolink.studies` and :mod:`twolink.commands`. The names below are the shallow
public API; each loads its module on first use, so ``import twolink`` stays instant.
Importing twolink registers the Gymnasium ids ``twolink/TwoLink-v0`` and
``twolink/TwoLinkDiscrete-v0`` (:mod:`twolink.envs.registration`).
"""
from __future__ import annotations

import importlib as _importlib

from twolink import _imports, gl
from twolink.artifacts import VERSION as __version__
from twolink.envs import registration as _registration

#: Public name -> the module defining it.
_API = {
    "TABLE_I": "twolink.arm.parameters",
    "ArmParameters": "twolink.arm.parameters",
    "load_policy": "twolink.policy.fuzzy_policy",
    "Policy": "twolink.policy.fuzzy_policy",
    "shipped_policies": "twolink.policy.fuzzy_policy",
    "synthesize": "twolink.synthesis.synthesize",
    "make_plant": "twolink.sim.plants",
    "rollout": "twolink.sim.rollout",
    "Trajectory": "twolink.sim.rollout",
    "Challenge": "twolink.sim.challenges",
    "challenge": "twolink.sim.challenges",
    "evaluate": "twolink.sim.evaluation",
    "per_state": "twolink.sim.controller",
    "ControllerError": "twolink.sim.controller",
    "resolve_controller": "twolink.control.controllers",
    "evaluation_set": "twolink.sim.metrics",
}
__all__ = ["__version__", *_API]


def __getattr__(name: str):
    if name in _API:
        value = getattr(_importlib.import_module(_API[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'twolink' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_API))


_imports.install()
gl.install()
_registration.install()
