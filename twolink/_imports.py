"""Import machinery: old module paths kept importable, and hooks run around a
third-party module's first import.

Old paths: 
twolink moved its flat modules of 0.1 into subpackages by layer, and split ``control``
into ``synthesis``, ``limits`` and ``control`` (CHANGELOG.md lists the moves). ``import twolink.<old name>`` still works: :data:`MOVED` maps each old name to
its new module, and the finder :func:`install` puts on ``sys.meta_path`` returns the new
module itself (no copy) under the old name, with a ``DeprecationWarning``.
``twolink.policy`` and ``twolink.fqi`` are packages now and need no alias.

Old names: a module whose public names were renamed (the N-link arm's *chain* names of
0.1 became *links* names) keeps the old ones for one release with
``__getattr__ = renamed(__name__, {old: new})`` (:func:`renamed`): each old name returns
the new name's object itself, with a ``DeprecationWarning``.

Hooks: :func:`around_import` runs a function while a module (mujoco, gymnasium) is first
executed and another once it has loaded, whoever imports it, so that ``import twolink``
itself never has to import it.
"""
from __future__ import annotations

import contextlib
import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import sys
import warnings

#: Old module (``twolink.<key>``) -> new module (``twolink.<value>``).
MOVED = {
    "parameters": "arm.parameters",
    "dynamics": "arm.dynamics",
    "integrate": "arm.integrate",
    "integrate_kernel": "arm._integrate_kernel",
    "mjcf": "arm.mjcf",
    "parameter_file": "arm.parameter_file",
    "reward": "arm.task",
    "fuzzy": "fqi.fuzzy",
    "fqi_factored": "fqi.factored",
    "fqi_kernel": "fqi._kernel",
    "fqi_factored_kernel": "fqi._factored_kernel",
    "registry": "policy.registry",
    "plants": "sim.plants",
    "perturbations": "sim.perturbations",
    "challenges": "sim.challenges",
    "estimation": "sim.estimation",
    "identify": "sim.identify",
    "rollout": "sim.rollout",
    "metrics": "sim.metrics",
    "robustness": "sim.evaluation",
    "sweeps": "sim.cells",
    "sweep_store": "sim.cell_store",
    "trajectory_io": "sim.trajectory_file",
    "chain_agents": "synthesis.links_decentralized",
    "chain_centralized": "synthesis.links_centralized",
    "learning": "synthesis.learning",
    "tasks": "envs.core",
    "env": "envs.dm",
    "gym_env": "envs.gym",
    "pettingzoo": "envs.pettingzoo",
    "compensated_env": "envs.compensated",
    "render": "viz.render",
    "video": "viz.video",
    "plots": "viz.plots",
    "formatting": "viz.formatting",
    "learning_curves": "viz.learning_curves",
    "reproduce": "studies.reproduce.measure",
    "reproduce_table": "studies.reproduce.table",
    "paper": "studies.reproduce.paper",
    "mismatch": "studies.mismatch.measure",
    "mismatch_plan": "studies.mismatch.plan",
    "mismatch_report": "studies.mismatch.report",
    "mismatch_figures": "studies.mismatch.figures",
    "model_error": "studies.mismatch.model_error",
    "chain_mismatch": "studies.mismatch.links",
    "throughput": "studies.throughput",
    "robustness_study": "studies.robustness",
    "scaling": "studies.scaling.measure",
    "scaling_report": "studies.scaling.report",
    # control/ split by what a thing is (synthesis/, limits/, control/).
    "control.synthesis": "synthesis.synthesize",
    "control.problems": "synthesis.problems",
    "control.links_centralized": "synthesis.links_centralized",
    "control.links_decentralized": "synthesis.links_decentralized",
    "control.learning": "synthesis.learning",
    "control.learning_setup": "synthesis.learning_setup",
    "control.time_optimal": "limits",
    "control.time_optimal.links": "limits.links",
    "control.time_optimal.nlp": "limits.nlp",
    "control.time_optimal.search": "limits.search",
    "control.time_optimal.symbolic": "limits.symbolic",
    "control.time_optimal.table": "limits.table",
    "control.time_optimal.mpc": "control.mpc",
}


class _MovedFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    def find_spec(self, fullname, path=None, target=None):
        package, _, name = fullname.partition(".")
        if package != "twolink" or name not in MOVED:
            return None
        return importlib.machinery.ModuleSpec(fullname, self)

    def create_module(self, spec):
        new = "twolink." + MOVED[spec.name.partition(".")[2]]
        warnings.warn(f"{spec.name} moved to {new}; the old path goes in the next release",
                      DeprecationWarning, stacklevel=3)
        module = importlib.import_module(new)
        self._specs = getattr(self, "_specs", {})
        self._specs[new] = module.__spec__
        return module

    def exec_module(self, module):
        # importlib set the module's __spec__ to the old name's: give it back its own.
        module.__spec__ = self._specs[module.__name__]


def install() -> None:
    """Put the finder of old module paths on ``sys.meta_path`` (once)."""
    if not any(isinstance(f, _MovedFinder) for f in sys.meta_path):
        sys.meta_path.append(_MovedFinder())


def renamed(module: str, names: dict):
    """A module-level ``__getattr__`` for ``module`` (its ``__name__``) that answers each old
    name of ``names`` (old -> new) with the object of the new name, warning
    ``DeprecationWarning``; any other name is an AttributeError, as without it."""
    def __getattr__(name: str):
        new = names.get(name)
        if new is None:
            raise AttributeError(f"module {module!r} has no attribute {name!r}")
        warnings.warn(f"{module}.{name} is now {module}.{new}; the old name goes in the "
                      "next release", DeprecationWarning, stacklevel=2)
        return getattr(sys.modules[module], new)

    __getattr__.renamed = dict(names)
    return __getattr__


class _Around(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds ``name`` with the other finders and wraps its execution."""

    def __init__(self, name, during, after):
        self.name, self.during, self.after, self._loader = name, during, after, None

    def find_spec(self, fullname, path=None, target=None):
        if fullname != self.name:
            return None
        sys.meta_path.remove(self)
        try:
            spec = importlib.util.find_spec(fullname)
        except (ImportError, ValueError):
            spec = None
        if spec is None or spec.loader is None:
            sys.meta_path.insert(0, self)
            return None
        self._loader, spec.loader = spec.loader, self
        return spec

    def create_module(self, spec):
        return self._loader.create_module(spec)

    def exec_module(self, module):
        with self.during():
            self._loader.exec_module(module)
        self.after(module)


def around_import(name: str, after, during=None) -> None:
    """Call ``after(module)`` once ``name`` is imported (now, if it already is), with the
    context manager ``during()`` around its first execution."""
    if name in sys.modules:
        after(sys.modules[name])
        return
    if not any(isinstance(f, _Around) and f.name == name for f in sys.meta_path):
        sys.meta_path.insert(0, _Around(name, during or contextlib.nullcontext, after))
