"""What the arm's tasks mean, independent of any RL API (dm_env, Gymnasium, PettingZoo).

The regulation task of the paper: drive the arm to the origin of the state space. The
``centralized`` task has one controller that sees the whole state and gets reward (15);
the ``decentralized`` task has one agent per joint, agent i on link i, each with its own
observation and reward (17): for two links the agents of (18), for N links
the same construction one hop at a time (:func:`observation_names`). Every environment
of the package builds its episodes from these pieces, so the same option means the same
thing in all.

Arms of N = 2 .. 6 links (:func:`arm`): two links are Table I and behave exactly as
before; more links are :func:`twolink.arm.parameters.links_parameters`. Episodes last
:func:`horizon` seconds by default (5 s for two links as in the paper, 8 s beyond).
"""
from __future__ import annotations

import functools
import math
import warnings

import numpy as np

from twolink.arm.parameters import (  # noqa: F401
    LINKS_HORIZON,
    HORIZON,
    LINK_RULES,
    PAPER_X0,
    TABLE_I,
    ArmParameters,
    LinksParameters,
    links_parameters,
    check_links,
    horizon,
    state_names,
)
from twolink.arm.integrate import wrap_angle
from twolink.arm.parameters import GOAL_ANGLE, GOAL_SPEED
from twolink.arm.task import centralized_reward, in_goal_band
from twolink.policy.fuzzy_policy import check_links_match
from twolink.sim.challenges import Challenge
from twolink.sim.challenges import challenge as challenge_named
from twolink.sim.perturbations import perturbed, random_perturbation
from twolink.sim.plants import check_states
from twolink.validate import choice, is_real, numbers

TASKS = ("centralized", "decentralized")
#: Episode length (s) of arms of three links or more: their tapered outer motors (half
#: the torque per link) need longer than the paper's 5 s to bring all links to rest.
INITIAL_STATES = ("paper", "random")
#: The message of a bad episode length (a :func:`twolink.validate.real` template).
BAD_TIME_LIMIT = "{what} must be a positive number of seconds, got {value!r}"


def observation_names(links: int = 2) -> dict:
    """What each observation of an arm of ``links`` links holds, component by component:
    ``'state'`` (the whole state, centralized task) and ``'agent1'`` .. ``'agentN'``
    (decentralized task).

    Two links: the agents of (18), agent 1 (theta1, dtheta1, theta2), agent 2 (theta2,
    dtheta2). N >= 3 links: agent i < N sees its own angle and speed and its outer
    neighbour's, (theta_i, dtheta_i, theta_{i+1}, dtheta_{i+1}) (the one-hop context the
    N-link agents read: the neighbour's speed is what keeps a middle
    link from limit-cycling); agent N, the outermost, sees (theta_N, dtheta_N). The
    torque tau_{i+1} agent i also reads is chosen in the same sample (outermost agent
    first, as (18) orders agent 2 before agent 1), so no observation holds it: a policy
    hands it on directly (:func:`twolink.envs.dm.policy_action`)."""
    n = check_links(links)
    names = {"state": state_names(n)}
    for i in range(1, n + 1):
        own = (f"theta{i}", f"dtheta{i}")
        if i == n:
            names[f"agent{i}"] = own
        elif n == 2:
            names[f"agent{i}"] = own + (f"theta{i + 1}",)
        else:
            names[f"agent{i}"] = own + (f"theta{i + 1}", f"dtheta{i + 1}")
    return names


#: What each observation of the two-link arm holds (agent 1 and agent 2 of (18)).
OBSERVATION_NAMES = observation_names(2)


def arm(params=None, *, links=None, rule=None) -> ArmParameters | LinksParameters:
    """The nominal arm of an environment: ``params`` as given (a two-link
    :class:`LinksParameters` as its :class:`ArmParameters`, so two links always run the
    same code), else Table I for two links, else ``links_parameters(links, rule)`` (rule default
    ``'tapered'``). ``links`` defaults to that of ``params``, else 2; a ValueError when
    it contradicts ``params``, is out of range, or ``rule`` is unknown or given with
    ``params``."""
    n = None if links is None else check_links(links)
    if rule is not None and rule not in LINK_RULES:
        raise ValueError(f"unknown link rule {rule!r}; choose one of {', '.join(LINK_RULES)}")
    if params is None:
        n = 2 if n is None else n
        return TABLE_I if n == 2 else links_parameters(n, rule or "tapered")
    if not isinstance(params, (ArmParameters, LinksParameters)):
        raise ValueError(f"params must be ArmParameters or LinksParameters, got "
                         f"{type(params).__name__}")
    if rule is not None:
        raise ValueError("give either params or rule: the link rule only builds an arm "
                         "when no params are given")
    if n is not None and params.links != n:
        raise ValueError(f"params describe a {params.links}-link arm, but links={n}")
    if isinstance(params, LinksParameters) and params.links == 2:
        return params.as_arm()
    return params


def check_two_link_options(links: int, **options) -> None:
    """A ValueError naming the options given that exist for the two-link arm only
    (a perturbation or challenge of Table I's constants, Gaussian observation noise)
    when the arm has ``links`` > 2 links. ``options``: name -> value (None or 0: not
    given)."""
    if links == 2:
        return
    given = [k for k, v in options.items() if v is not None and not
             (is_real(v, numpy=False) and v == 0)]
    if given:
        what = "is a two-link option" if len(given) == 1 else "are two-link options"
        raise ValueError(f"{', '.join(given)} {what} (Table I's constants, the 4-component "
                         f"state); this arm has {links} links")


def check_task(task: str) -> str:
    if task not in TASKS:
        raise ValueError(f"unknown task {task!r}; choose one of {', '.join(TASKS)}")
    return task


def check_x0(x0, links: int = 2):
    """``'paper'`` (two links only), ``'random'``, ``'slow'`` or ``'mixed'`` (more than
    two links: :mod:`twolink.envs.starts`) or a copy of one finite state (2N,); else a
    TypeError naming x0 for a value that is neither a word nor numbers (a dict), or a
    ValueError for another word or a bad state."""
    from twolink.envs.starts import STARTS

    n = check_links(links)
    if isinstance(x0, str):
        if n == 2 and x0 not in INITIAL_STATES:
            raise ValueError(f"x0 must be 'paper', 'random' or a state (4,), got {x0!r}")
        if n > 2 and x0 == "paper":
            raise ValueError(f"x0='paper' is the two-link arm's {list(PAPER_X0)}; an arm of "
                             f"{n} links starts from 'random' or a state ({2 * n},)")
        if n > 2 and x0 != "random" and x0 not in STARTS:
            raise ValueError(f"x0 must be 'random', 'slow', 'mixed' or a state ({2 * n},), "
                             f"got {x0!r}")
        return x0
    numbers(x0, "x0")                    # a TypeError naming x0 for a dict, None, ...
    x0 = check_states(x0, what="x0", links=n)
    if x0.shape != (2 * n,):
        raise ValueError(f"x0 must be one state of shape ({2 * n},), got shape {x0.shape}")
    return wrap_angles(x0)


def wrap_angles(x: np.ndarray) -> np.ndarray:
    """A copy of states x (..., 2N) with every angle outside [-pi, pi) wrapped into it, as
    the arm wraps its angles at the end of every sample period; angles already inside are
    kept bit for bit (so the paper's x0 starts exactly as ``rollout`` starts it)."""
    x = np.array(x, dtype=float)
    n = x.shape[-1] // 2
    a = x[..., :n]
    outside = (a < -math.pi) | (a >= math.pi)
    x[..., :n] = np.where(outside, wrap_angle(a), a)
    return x


def check_x0_speeds(x0, speed_max) -> np.ndarray:
    """``x0`` (one state (2N,) or many (..., 2N)) unless a speed exceeds the arm's speed
    limit ``speed_max`` (one per link), where the arm saturates its speeds at the end of
    every sample period: a first observation beyond it would lie outside the declared
    observation space. A one-line ValueError naming the worst speed otherwise."""
    x0 = np.asarray(x0, dtype=float)
    n = x0.shape[-1] // 2
    speeds = np.abs(x0[..., n:]).reshape(-1, n)
    limit = np.broadcast_to(np.asarray(speed_max, dtype=float), speeds.shape)
    over = speeds > limit
    if np.any(over):
        worst = int(np.argmax(np.where(over, speeds, -1.0)))
        raise ValueError(f"x0 has a speed of magnitude {speeds.flat[worst]:.4g} rad/s, beyond "
                         f"the arm's speed limit {limit.flat[worst]:.4g} rad/s (the arm "
                         f"saturates its speeds there)")
    return x0


def state_bounds(speed_max) -> np.ndarray:
    """The upper bounds [pi .. pi, speed_max_1 .. speed_max_N] of the true state (the
    lower ones are their negatives): the arm wraps its angles to [-pi, pi) and saturates
    its speeds at +-speed_max at the end of every sample period, and a first state is held
    to the same bounds (:func:`wrap_angles`, :func:`check_x0_speeds`)."""
    v = np.asarray(speed_max, dtype=float)
    return np.concatenate([np.full(len(v), math.pi), v])


# --------------------------------------------------------------------------- rewards
#: Reward options of the Gymnasium and Stable-Baselines3 environments: ``'paper'`` is
#: (15), ``'shaped'`` the dense :func:`shaped_reward`, ``'shaped_time'``
#: :func:`shaped_time_reward` (the shaped reward plus (15) scaled to a cost of one per
#: sample outside the goal band).
REWARD_OPTIONS = ("paper", "shaped", "shaped_time")
#: The tolerances of :func:`shaped_reward`: dm_control's ``rewards.tolerance`` with this
#: sigmoid, its value at the margin, and the margins on |theta_i| (rad) and |dtheta_i|
#: (rad/s).
SHAPED_SIGMOID = "reciprocal"
SHAPED_VALUE_AT_MARGIN = 0.1
SHAPED_ANGLE_MARGIN = math.pi
SHAPED_SPEED_MARGIN = 2.0 * math.pi
#: Largest value of :func:`shaped_reward` outside the goal band.
SHAPED_OUTSIDE_MAX = -1e-12
#: The lowest values of the two rewards: what the vector environment's autoreset steps
#: return (:class:`twolink.envs.gym.TwoLinkVectorEnv`), never a goal reward.
REWARD_FLOOR = {"paper": -0.5, "shaped": -1.0, "shaped_time": -2.0}
#: What :func:`shaped_time_reward` subtracts for every sample outside the goal band.
TIME_PENALTY = 1.0


def shaped_reward(x) -> np.ndarray:
    """A dense reward for deep RL, in the style of dm_control's ``rewards.tolerance``:
    0 exactly in the goal band of (15), negative elsewhere, within [-1, 0].

    For states x (..., 2N) with angles wrapped::

        r(x) = (1/N) sum_i tol(|theta_i|, 5 deg, pi) * tol(|dtheta_i|, 0.1 rad/s, 2 pi) - 1

    where ``tol(v, b, m) = dm_control.utils.rewards.tolerance(v, bounds=(0, b), margin=m,
    sigmoid='reciprocal', value_at_margin=0.1)``: 1 for v <= b, else 1 / (1 + 9 (v - b) / m)
    (0.1 at a distance m beyond the band). The reciprocal sigmoid keeps a slope at the
    band's edge (a Gaussian would be flat there, and the band is narrow). Outside the band
    the value is at most -1e-12 (:data:`SHAPED_OUTSIDE_MAX`; the clamp acts only a few
    ulps from the band's edge, where the tolerance rounds to 1). (15),
    :func:`twolink.arm.task.centralized_reward`, stays the evaluation metric.
    """
    from dm_control.utils.rewards import tolerance

    x = np.asarray(x, dtype=float)
    n = x.shape[-1] // 2
    kw = dict(sigmoid=SHAPED_SIGMOID, value_at_margin=SHAPED_VALUE_AT_MARGIN)
    per_link = [tolerance(np.abs(x[..., i]), bounds=(0.0, GOAL_ANGLE),
                          margin=SHAPED_ANGLE_MARGIN, **kw)
                * tolerance(np.abs(x[..., n + i]), bounds=(0.0, GOAL_SPEED),
                            margin=SHAPED_SPEED_MARGIN, **kw) for i in range(n)]
    r = np.mean(per_link, axis=0) - 1.0
    return np.where(in_goal_band(x), 0.0, np.minimum(r, SHAPED_OUTSIDE_MAX))


def shaped_time_reward(x) -> np.ndarray:
    """:func:`shaped_reward` minus :data:`TIME_PENALTY` outside the goal band: 0 in the
    band, in [-2, -1) elsewhere: the shaped reward plus (15) rescaled to a cost of
    TIME_PENALTY per sample outside the band. The shaped part guides (it grows
    towards the band) but also costs speed (its speed tolerance), so alone it favours
    slow approaches; the penalty is the minimum-time term of (15) that the fuzzy
    policies are synthesised for, so a sample saved is worth at least as much as any
    change of the shaped part."""
    return shaped_reward(x) - TIME_PENALTY * (~in_goal_band(np.asarray(x, dtype=float)))


#: Reward options of the multi-agent environments (:mod:`twolink.envs.pettingzoo`), what
#: each agent ``linkI`` gets on the state reached: ``'paper'`` (17) of its own link (the
#: paper's decentralized reward; ``'individual'`` is its older name), ``'centralized'``
#: (15) to every agent, ``'sum'`` the sum of every link's (17) to every agent,
#: ``'shaped'`` the dense :func:`shaped_reward` of its own link (per link: 0 when link I
#: is in its goal band, in [-1, 0) outside), ``'shaped_team'`` the Gymnasium env's
#: :func:`shaped_reward` of the whole arm, the same number to every agent;
#: ``'shaped_time'`` and ``'shaped_team_time'`` the same less :data:`TIME_PENALTY` for
#: every sample outside the band (its own link's band, the arm's goal band): the
#: minimum-time term of :func:`shaped_time_reward`.
AGENT_REWARD_OPTIONS = ("paper", "individual", "centralized", "sum", "shaped", "shaped_team",
                        "shaped_time", "shaped_team_time")
#: Action options of the multi-agent environments: ``'box'`` a torque in
#: +-tau_i_max (float64), ``'normalized'`` a float32 Box [-1, 1] scaled to +-tau_i_max
#: (as :data:`twolink.envs.gym_arms.ACTIONS` names them for the Gymnasium env).
AGENT_ACTION_OPTIONS = ("box", "normalized")
#: What each agent of the multi-agent environments observes of the arm (``observe``):
#: ``'neighbours'`` its joint and its outer neighbour's (:func:`observation_names`, (18)
#: for two links; the default), ``'local'`` its own joint only (theta_I, dtheta_I), as the
#: paper's agent 2 does, ``'global'`` the whole state.
OBSERVE_OPTIONS = ("neighbours", "local", "global")


def check_agent_reward(reward) -> str:
    """``reward`` if it is one of :data:`AGENT_REWARD_OPTIONS`, else a ValueError; the
    shaped ones need dm-control (an ImportError now, as :func:`check_reward`)."""
    choice(reward, "reward", AGENT_REWARD_OPTIONS)
    if reward.startswith("shaped"):
        check_reward("shaped")
    return reward


def check_reward(reward) -> str:
    """``reward`` if it is one of :data:`REWARD_OPTIONS`, else a ValueError; for
    ``'shaped'`` an ImportError now, not at the first step, where dm-control is missing."""
    choice(reward, "reward", REWARD_OPTIONS)
    if reward in ("shaped", "shaped_time"):
        try:
            from dm_control.utils import rewards  # noqa: F401
        except ImportError:
            raise ImportError("reward='shaped' uses dm-control's rewards.tolerance; on "
                              "Python 3.13: pip install --no-deps dm-control==1.0.50") from None
    return reward


def reward_of(x, reward: str) -> np.ndarray:
    """Reward ``reward`` (one of :data:`REWARD_OPTIONS`) of states x (..., 2N), float64."""
    if reward == "shaped":
        return shaped_reward(x)
    if reward == "shaped_time":
        return shaped_time_reward(x)
    return centralized_reward(x).astype(np.float64)


def default_x0(links: int = 2) -> str:
    """The default ``x0`` option: the paper's ``'paper'`` for two links, ``'random'``
    beyond (the paper's state is a two-link one)."""
    return "paper" if check_links(links) == 2 else "random"


def initial_state(x0, random, links: int = 2, params=None) -> np.ndarray:
    """The episode's first state for a checked ``x0`` option: the paper's [-1, -3, 0, 0],
    angles uniform in [-pi, pi) at rest (one draw of ``links`` angles from ``random``, a
    ``RandomState`` or ``Generator``), a pose beyond the own motors' reach of the arm
    ``params`` (``'slow'``, ``'mixed'``: :func:`twolink.envs.starts.start_pose`), or the
    given state."""
    if isinstance(x0, str) and x0 == "random":
        return np.concatenate([random.uniform(-np.pi, np.pi, links), np.zeros(links)])
    if isinstance(x0, str) and x0 != "paper":
        from twolink.envs.starts import start_pose

        return start_pose(x0, params, random)
    return np.array(PAPER_X0 if isinstance(x0, str) else x0, dtype=float)


def torque_names(links: int) -> str:
    """``'tau1, tau2'`` .. ``'tau1, ..., tauN'``: the components of a joint action."""
    return ", ".join(f"tau{i}" for i in range(1, links + 1))


def check_action(action, tau_max: np.ndarray, *, rows: int | None = None) -> np.ndarray:
    """A joint action [tau1, .., tauN] (N = len(tau_max)) as float64, clipped to
    +-tau_max; a ValueError for a wrong shape, non-numbers, NaN or infinite values.
    ``rows``: a batch of that many joint actions, shape (rows, N)."""
    action = getattr(action, "continuous_actions", action)
    n = len(tau_max)
    try:
        a = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"action must be numbers [{torque_names(n)}], got {action!r}") from None
    shape = (n,) if rows is None else (rows, n)
    if a.shape != shape:
        raise ValueError(f"action must have shape {shape} [{torque_names(n)}], "
                         f"got shape {a.shape}")
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
    if is_real(perturbation, numpy=False):
        return random_perturbation(random, float(perturbation), base=params)
    raise ValueError(f"perturbation must be a dict of relative changes or a size in [0, 1), "
                     f"got {perturbation!r}")


def check_challenge(challenge, **separate) -> Challenge | None:
    """The ``challenge`` option of an environment: None, or the
    :class:`twolink.sim.challenges.Challenge` it names (``'easy'``, ``'medium'``, ``'hard'``,
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


@functools.lru_cache(maxsize=None)
def _indices(links: int, key: str) -> list:
    names = state_names(links)
    return [names.index(c) for c in observation_names(links)[key]]


def observe(x: np.ndarray, key: str) -> np.ndarray:
    """The observation ``key`` of :func:`observation_names` from states x (..., 2N)."""
    x = np.asarray(x)
    return x[..., _indices(x.shape[-1] // 2, key)]


def check_policy_links(policy, links: int) -> None:
    """A ValueError naming both numbers of links unless ``policy`` (a
    :class:`twolink.policy.fuzzy_policy.Policy`; any other callable passes) is for an arm of ``links``
    links."""
    if hasattr(policy, "links"):
        check_links_match(policy, links)


def check_reset_options(options, allowed) -> dict:
    """The ``reset(options=...)`` of an environment: None or a dict; the keys in
    ``allowed`` are returned, any other key is ignored with a ``UserWarning`` naming it (as
    Gymnasium's own environments ignore options they do not know, and as the API checkers
    of Gymnasium and PettingZoo expect when they probe ``reset(options=...)``)."""
    if options is None:
        return {}
    if not isinstance(options, dict):
        raise ValueError(f"options must be a dict, got {type(options).__name__}")
    unknown = sorted(set(options) - set(allowed), key=str)
    if unknown:
        warnings.warn(f"ignoring unknown reset option(s) {', '.join(map(repr, unknown))}; "
                      f"known: {', '.join(map(repr, allowed))}", UserWarning, stacklevel=3)
    return {k: v for k, v in options.items() if k in allowed}
