"""Every controller by one name: shipped fuzzy policies, classical baselines, policy files,
saved Stable-Baselines3 agents (a PPO or SAC ``.zip``, :mod:`twolink.control.sb3_agent`,
read as data, never unpickled), saved multi-agent arms (an IPPO or MAPPO ``.marl.pt``,
:mod:`twolink.control.marl_agent`, read with ``torch.load(weights_only=True)``), the learned agents shipped in the repository by name
(:data:`twolink.control.learned.LEARNED_AGENTS`, e.g. ``ppo_seed0``) and a user's own
``module:callable`` or ``path/to/file.py:callable``.

:func:`resolve_controller` turns such a name into a controller of the protocol of
:mod:`twolink.sim.controller`, checked (:func:`twolink.sim.controller.checked`); the
commands ``rollout``, ``render``, ``evaluate`` and ``leaderboard`` read their
``--controller`` through it. A class named after the colon is instantiated with no
arguments; anything else named there must be callable. What a user's module prints while
it is imported and its class instantiated goes to stderr (stdout is the commands' output);
an exception or ``sys.exit`` there is one ControllerError line.
"""
from __future__ import annotations

import contextlib
import sys
from pathlib import Path

from twolink.control.entry_points import import_entry_point, is_file_spec
from twolink.policy.fuzzy_policy import load_policy
from twolink.sim.controller import Checked, ControllerError, checked, controller_name


def baseline_names() -> tuple:
    """The shipped classical baselines (:data:`twolink.control.baselines.BASELINES`)."""
    from twolink.control.baselines import BASELINES

    return tuple(BASELINES)


def absolute_spec(spec):
    """``spec`` with the file it names (a ``file.py:callable``'s file, a policy ``.npz``)
    made absolute, so that it names the same file from another working directory (a
    worker process, a Ray node sharing the file system); anything else unchanged."""
    from twolink.control.catalogue import catalogue

    if not isinstance(spec, str) or spec in catalogue():
        return spec
    if spec.endswith((".npz", ".zip", ".marl.pt")):
        return str(Path(spec).resolve())
    where, colon, attr = spec.rpartition(":")
    if colon and where and is_file_spec(where):
        return f"{Path(where).resolve()}:{attr}"
    return spec


def _from_spec(spec: str):
    """The controller ``module:callable`` or ``file.py:callable`` names: the callable, or
    an instance of the class named (made with no arguments, its prints sent to stderr)."""
    obj = import_entry_point(spec, "controller")
    if isinstance(obj, type):
        attr = spec.rpartition(":")[2]
        try:
            with contextlib.redirect_stdout(sys.stderr):
                obj = obj()
        except (Exception, SystemExit) as exc:
            raise ControllerError(f"controller {spec!r}: {attr}() raised "
                                  f"{type(exc).__name__}: {exc}") from None
        if not callable(obj):
            raise ControllerError(f"controller {spec!r} is not callable "
                                  f"({type(obj).__name__})")
    return obj


def resolve_controller(spec, *, links: int = 2, catalogue_files=()) -> Checked:
    """The controller ``spec`` names, checked: a name of the controller catalogue
    (:mod:`twolink.control.catalogue`: shipped policies, baselines, shipped learned
    agents and the entries of ``catalogue_files`` and of ``$TWOLINK_CATALOGUE``), a policy
    ``.npz`` file, a saved SB3 agent ``.zip`` (labelled by its file's stem; read as data,
    see :mod:`twolink.control.sb3_agent`), a multi-agent save ``.marl.pt``
    (:mod:`twolink.control.marl_agent`), ``module:callable`` or ``file.py:callable``
    (labelled by the object's ``name`` when it has one, else the callable's name); or a
    controller object itself. One-line ControllerError (a ValueError) for anything else,
    an unknown name with the closest catalogue names."""
    from twolink.control import catalogue

    if not isinstance(spec, str):
        return checked(spec, links=links)
    if not spec:
        raise ControllerError("controller name is empty")
    if spec.endswith(".npz"):
        return checked(load_policy(spec), name=Path(spec).stem, links=links)
    if spec.endswith(".zip"):
        from twolink.control.sb3_agent import sb3_agent

        return checked(sb3_agent(spec), name=Path(spec).stem, links=links)
    if spec.endswith(".marl.pt"):
        from twolink.control.marl_agent import SUFFIX, load_marl_agent

        agent = load_marl_agent(spec)
        if agent.links != links:
            raise ControllerError(f"{spec} drives an arm of {agent.links} links, not "
                                  f"{links} (give --links {agent.links})")
        return checked(agent, name=Path(spec).name[:-len(SUFFIX)], links=links)
    if ":" in spec:
        obj = _from_spec(spec)
        return checked(obj, name=controller_name(obj, spec.rpartition(":")[2]), links=links)
    cat = catalogue.catalogue(catalogue_files)
    if spec in cat:
        return checked(cat[spec].load(), name=spec, links=links)
    raise ControllerError(f"unknown controller {spec!r}{catalogue.suggest(spec, cat)}; give "
                          f"a name of `twolink controllers`, a policy .npz, an SB3 agent "
                          f".zip, a multi-agent .marl.pt, module:callable or path/to/file.py:callable")
