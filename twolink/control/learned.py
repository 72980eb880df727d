"""The learned agents shipped in the repository, by name.

:data:`LEARNED_AGENTS` maps a name to its Stable-Baselines3 save, a path relative to the
repository root (``renders/deep_rl/`` of a source checkout; a wheel does not hold them).
:func:`twolink.control.controllers.resolve_controller` accepts these names, so
``twolink evaluate ppo_seed0`` runs the committed PPO agent through
:class:`twolink.control.sb3_agent.SB3Agent`. No command loads a saved agent that it was
not given by name or path: the leaderboard's default rows hold the agents of this table
whose file exists (:func:`default_learned_agents`), never a folder's ``*.zip``.
"""
from __future__ import annotations

from pathlib import Path

from twolink.sim.controller import ControllerError

#: Name -> the agent's SB3 save, relative to the repository root.
LEARNED_AGENTS = {"ppo_seed0": "renders/deep_rl/ppo_seed0.zip"}


def learned_agent_names() -> tuple:
    """The names of :data:`LEARNED_AGENTS`."""
    return tuple(LEARNED_AGENTS)


def _file_of(name: str) -> Path | None:
    """The file of the learned agent ``name`` in the source checkout, or None when the
    package runs without one or the file is missing."""
    from twolink.resources import source_checkout

    root = source_checkout()
    if root is None:
        return None
    path = root / LEARNED_AGENTS[name]
    return path if path.is_file() else None


def learned_agent_path(name: str) -> Path:
    """The file of the learned agent ``name`` (:data:`LEARNED_AGENTS`), resolved against
    the repository root; a one-line ControllerError for an unknown name or a missing file."""
    if name not in LEARNED_AGENTS:
        raise ControllerError(f"unknown learned agent {name!r}; the shipped ones are "
                              f"{', '.join(LEARNED_AGENTS)}")
    path = _file_of(name)
    if path is None:
        raise ControllerError(f"learned agent {name} is the file {LEARNED_AGENTS[name]} of a "
                              f"source checkout of the repository, and this one has none")
    return path


def learned_agent(name: str):
    """The controller of the learned agent ``name``
    (:class:`twolink.control.sb3_agent.SB3Agent`, labelled ``name``)."""
    from twolink.control.sb3_agent import sb3_agent

    return sb3_agent(learned_agent_path(name), name)


def default_learned_agents(exclude=()) -> list:
    """The learned agents a default leaderboard runs: the names of :data:`LEARNED_AGENTS`
    whose file exists, where Stable-Baselines3 imports (none otherwise, silently). A name
    in ``exclude``, or whose file an ``exclude`` ``.zip`` path names, is left out."""
    present = [n for n in LEARNED_AGENTS if _file_of(n) is not None]
    if not present:
        return []
    try:
        import stable_baselines3  # noqa: F401
    except ImportError:
        return []
    given = {str(Path(s).resolve()) for s in exclude if isinstance(s, str) and s.endswith(".zip")}
    return [n for n in present
            if n not in exclude and str(_file_of(n).resolve()) not in given]
