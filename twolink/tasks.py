"""What the arm's tasks mean, independent of any RL API (dm_env, Gymnasium, PettingZoo).

The regulation task of the paper: drive the arm to the origin of the state space. The
``centralized`` task has one controller that sees the whole state and gets reward (15);
the ``decentralized`` task has the two agents of (18), agent 1 on link 1 and agent 2 on
link 2, each with its own observation and reward (17). Every environment of the package
builds its episodes from these pieces, so the same option means the same thing in all.
"""
from __future__ import annotations

import numpy as np

from twolink.challenges import Challenge, challenge as challenge_named
from twolink.parameters import PAPER_X0, STATE_NAMES, ArmParameters
from twolink.perturbations import perturbed, random_perturbation
from twolink.plants import check_states

TASKS = ("centralized", "decentralized")
#: What each observation holds, component by component (agent 1 and agent 2 of (18)).
OBSERVATION_NAMES = {
    "state": STATE_NAMES,
    "agent1": ("theta1", "dtheta1", "theta2"),
    "agent2": ("theta2", "dtheta2"),
}
INITIAL_STATES = ("paper", "random")


def check_task(task: str) -> str:
    if task not in TASKS:
        raise ValueError(f"unknown task {task!r}; choose one of {', '.join(TASKS)}")
    return task


def check_x0(x0):
    """``'paper'``, ``'random'`` or a copy of one finite state (4,), or a ValueError."""
    if isinstance(x0, str):
        if x0 not in INITIAL_STATES:
            raise ValueError(f"x0 must be 'paper', 'random' or a state (4,), got {x0!r}")
        return x0
    x0 = check_states(x0, what="x0")
    if x0.shape != (4,):
        raise ValueError(f"x0 must be one state of shape (4,), got shape {x0.shape}")
    return x0.copy()


def initial_state(x0, random) -> np.ndarray:
    """The episode's first state for a checked ``x0`` option: the paper's [-1, -3, 0, 0],
    angles uniform in [-pi, pi) at rest drawn from ``random`` (a ``RandomState`` or
    ``Generator``), or the given state."""
    if isinstance(x0, str) and x0 == "random":
        return np.concatenate([random.uniform(-np.pi, np.pi, 2), np.zeros(2)])
    return np.array(PAPER_X0 if isinstance(x0, str) else x0, dtype=float)


def check_action(action, tau_max: np.ndarray, *, rows: int | None = None) -> np.ndarray:
    """A joint action [tau1, tau2] as float64, clipped to +-tau_max; a ValueError for a
    wrong shape, non-numbers, NaN or infinite values. ``rows``: a batch of that many
    joint actions, shape (rows, 2)."""
    action = getattr(action, "continuous_actions", action)
    try:
        a = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"action must be numbers [tau1, tau2], got {action!r}") from None
    shape = (2,) if rows is None else (rows, 2)
    if a.shape != shape:
        raise ValueError(f"action must have shape {shape} [tau1, tau2], got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"action contains NaN or infinite values: {a.tolist()}")
    return np.clip(a, -tau_max, tau_max)


def perturbed_params(params: ArmParameters, perturbation, random) -> ArmParameters:
    """``params`` under ``perturbation``: None, a dict of relative changes
    (``{'m2': 0.2}``), or a size s in [0, 1) for one random joint change drawn from
    ``random``."""
    if perturbation is None:
        return params
    if isinstance(perturbation, dict):
        return perturbed(params, **perturbation)
    if isinstance(perturbation, (int, float)) and not isinstance(perturbation, bool):
        return random_perturbation(random, float(perturbation), base=params)
    raise ValueError(f"perturbation must be a dict of relative changes or a size in [0, 1), "
                     f"got {perturbation!r}")


def check_challenge(challenge, **separate) -> Challenge | None:
    """The ``challenge`` option of an environment: None, or the
    :class:`twolink.challenges.Challenge` it names (``'easy'``, ``'medium'``, ``'hard'``,
    ...). A challenge sets the plant, delays and noise itself, so a ValueError when any of
    the ``separate`` options (``perturbation``, noise levels, ``delay``) is also given."""
    if challenge is None:
        return None
    given = [k for k, v in separate.items()
             if (v is not None if k == "perturbation" else v != 0)]
    if given:
        raise ValueError(f"give either challenge or {', '.join(given)}: a challenge sets the "
                         f"plant, delays and noise itself")
    return challenge_named(challenge)


def observe(x: np.ndarray, key: str) -> np.ndarray:
    """The observation ``key`` of :data:`OBSERVATION_NAMES` from a state (..., 4)."""
    idx = [STATE_NAMES.index(n) for n in OBSERVATION_NAMES[key]]
    return np.asarray(x)[..., idx]


def check_reset_options(options, allowed) -> dict:
    """The ``reset(options=...)`` of an environment: None or a dict whose keys are all in
    ``allowed``; a ValueError naming the unknown keys otherwise."""
    if options is None:
        return {}
    if not isinstance(options, dict):
        raise ValueError(f"options must be a dict, got {type(options).__name__}")
    unknown = sorted(set(options) - set(allowed), key=str)
    if unknown:
        raise ValueError(f"unknown reset option(s) {', '.join(map(repr, unknown))}; "
                         f"known: {', '.join(map(repr, allowed))}")
    return options
