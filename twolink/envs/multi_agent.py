"""What each agent of the multi-agent task observes and earns, for one arm or a batch.

One definition for :class:`twolink.envs.pettingzoo.ParallelArm` (one arm) and
:class:`twolink.envs.pettingzoo_batched.BatchedParallelArms` (many arms in one MuJoCo
call), so both give the same numbers bit for bit. Agent ``linkI`` drives joint I.

Observations (``observe``, :data:`twolink.envs.core.OBSERVE_OPTIONS`): ``'neighbours'``
the components of :func:`twolink.envs.core.observation_names` ((18) for two links: link1
(theta1, dtheta1, theta2), link2 (theta2, dtheta2); for N links linkI, I < N, (theta_I,
dtheta_I, theta_{I+1}, dtheta_{I+1}) and linkN (theta_N, dtheta_N)); ``'local'`` (theta_I,
dtheta_I); ``'global'`` the whole state [theta1 .. thetaN, dtheta1 .. dthetaN]. With
``observation='cos_sin'`` (the Gymnasium env's name, :data:`twolink.arm.observations.OBSERVATIONS`)
every angle theta_k is replaced in place by (cos theta_k, sin theta_k): ``'global'`` then
is exactly the Gymnasium env's cos/sin observation.

Rewards (:data:`twolink.envs.core.AGENT_REWARD_OPTIONS`): (17) per link, (15) or the sum
of (17) to every agent, the per-link shaped reward :func:`shaped_link_rewards`, or the
arm's :func:`twolink.envs.core.shaped_reward` to every agent; the ``_time`` variants less
:data:`twolink.envs.core.TIME_PENALTY` per sample outside the band (the link's own, the
arm's: :func:`twolink.envs.core.shaped_time_reward`).
"""
from __future__ import annotations

import functools

import numpy as np
from gymnasium import spaces

from twolink.arm.parameters import GOAL_ANGLE, GOAL_SPEED, check_links, state_names
from twolink.arm.task import agent_reward, centralized_reward, link_in_band
from twolink.envs.core import (
    SHAPED_ANGLE_MARGIN,
    SHAPED_OUTSIDE_MAX,
    SHAPED_SIGMOID,
    SHAPED_SPEED_MARGIN,
    SHAPED_VALUE_AT_MARGIN,
    TIME_PENALTY,
    check_policy_links,
    observation_names,
    shaped_reward,
    shaped_time_reward,
)


@functools.lru_cache(maxsize=None)
def agent_components(links: int, observe: str) -> tuple:
    """Per agent (link1 .. linkN, in order) the state components it observes, before any
    cos/sin: a tuple of N tuples of names of :func:`twolink.arm.parameters.state_names`."""
    n = check_links(links)
    if observe == "global":
        return (state_names(n),) * n
    if observe == "local":
        return tuple((f"theta{i}", f"dtheta{i}") for i in range(1, n + 1))
    if observe == "neighbours":
        names = observation_names(n)
        return tuple(names[f"agent{i}"] for i in range(1, n + 1))
    raise ValueError(f"unknown observe {observe!r}")


@functools.lru_cache(maxsize=None)
def _columns(links: int, observe: str) -> tuple:
    """Per agent: the state columns it reads, and which of them are angles."""
    names = state_names(links)
    return tuple((tuple(names.index(c) for c in comp),
                  tuple(c.startswith("theta") for c in comp))
                 for comp in agent_components(links, observe))


def agent_observations(x, links: int, observe: str, observation: str) -> list:
    """Every agent's observation of (measured) states x (..., 2N): a list of N fresh
    float64 arrays (..., d_I), agent link1 first (see the module docstring)."""
    x = np.asarray(x, dtype=np.float64)
    out = []
    for cols, angle in _columns(links, observe):
        if observation == "state":
            out.append(x[..., list(cols)])
            continue
        parts = []
        for c, a in zip(cols, angle):
            v = x[..., c]
            parts += [np.cos(v), np.sin(v)] if a else [v]
        out.append(np.stack(parts, -1))
    return out


def agent_bounds(links: int, observe: str, observation: str, bound: np.ndarray) -> list:
    """Per agent the upper bounds of its observation (lower ones are their negatives),
    from the state's bounds ``bound`` (2N,) (inf where noise may carry a reading past
    them); a cos or a sin is always within [-1, 1]."""
    out = []
    for cols, angle in _columns(links, observe):
        high = []
        for c, a in zip(cols, angle):
            high += [1.0, 1.0] if (a and observation == "cos_sin") else [float(bound[c])]
        out.append(np.array(high))
    return out


def shaped_link_rewards(x) -> np.ndarray:
    """The per-link shaped reward (..., N) of states x (..., 2N): for link I,

        r_I(x) = tol(|theta_I|, 5 deg, pi) * tol(|dtheta_I|, 0.1 rad/s, 2 pi) - 1,

    0 when link I is in its goal band of (17) and at most -1e-12 outside, the tolerances
    of :func:`twolink.envs.core.shaped_reward` (whose mean over the links, outside the
    arm's goal band, is the team reward); within [-1, 0]."""
    from dm_control.utils.rewards import tolerance

    x = np.asarray(x, dtype=float)
    n = x.shape[-1] // 2
    kw = dict(sigmoid=SHAPED_SIGMOID, value_at_margin=SHAPED_VALUE_AT_MARGIN)
    out = []
    for i in range(n):
        th, dth = x[..., i], x[..., n + i]
        r = (tolerance(np.abs(th), bounds=(0.0, GOAL_ANGLE), margin=SHAPED_ANGLE_MARGIN, **kw)
             * tolerance(np.abs(dth), bounds=(0.0, GOAL_SPEED), margin=SHAPED_SPEED_MARGIN,
                         **kw) - 1.0)
        out.append(np.where(link_in_band(th, dth), 0.0, np.minimum(r, SHAPED_OUTSIDE_MAX)))
    return np.stack(out, -1).astype(np.float64)


def agent_rewards(x, reward: str) -> np.ndarray:
    """Every agent's reward (..., N) on the states reached x (..., 2N), float64, for a
    checked ``reward`` option (see the module docstring)."""
    x = np.asarray(x, dtype=float)
    n = x.shape[-1] // 2
    if reward in ("paper", "individual", "sum"):
        own = np.stack([agent_reward(x, i) for i in range(1, n + 1)], -1).astype(np.float64)
        if reward != "sum":
            return own
        return np.repeat(own.sum(-1, keepdims=True), n, -1)
    if reward == "shaped":
        return shaped_link_rewards(x)
    if reward == "shaped_time":
        outside = ~link_in_band(x[..., :n], x[..., n:])
        return shaped_link_rewards(x) - TIME_PENALTY * outside
    team = {"centralized": centralized_reward, "shaped_team": shaped_reward,
            "shaped_team_time": shaped_time_reward}[reward](x)
    return np.repeat(np.asarray(team, dtype=np.float64)[..., None], n, -1)


def float_box(high) -> spaces.Box:
    """The float64 Box [-high, high]."""
    high = np.asarray(high, dtype=np.float64)
    return spaces.Box(-high, high, high.shape, np.float64)


def check_agent_action(agent: str, action) -> np.ndarray:
    """The torque of ``agent`` as float64 (1,), or a ValueError naming the agent."""
    try:
        a = np.asarray(action)
    except Exception:
        a = np.asarray(None)
    if a.dtype.kind not in "fiu":
        raise ValueError(f"action of {agent} must be real numbers, got {action!r} "
                         f"(dtype {a.dtype})")
    if a.shape != (1,):
        raise ValueError(f"action of {agent} must have shape (1,) [its torque], "
                         f"got shape {a.shape}")
    a = a.astype(np.float64)
    if not np.all(np.isfinite(a)):
        raise ValueError(f"action of {agent} contains NaN or infinite values: {a.tolist()}")
    return a


def agents(links: int = 2) -> tuple:
    """The agents of an arm of ``links`` links, one per joint: ``link1`` .. ``linkN``;
    agent ``linkI`` is agent I of (17)-(18)."""
    return tuple(f"link{i}" for i in range(1, check_links(links) + 1))


def task_keys(names) -> dict:
    """Agent ``linkI`` -> its observation ``agentI`` of :func:`twolink.envs.core.observation_names`."""
    return {agent: f"agent{i}" for i, agent in enumerate(names, 1)}


def policy_actions(policy, observations) -> dict:
    """For the default observations and actions (``observe='neighbours'``,
    ``observation='state'``, ``actions='box'``: the torques it returns are in N m):
    ``{agent: action (1,)}`` of a decentralized :class:`twolink.policy.fuzzy_policy.Policy` in the
    ordering of (18): its agent 2 acts on link2's observation first and hands tau2 to
    agent 1, which reads link1's observation (its (18) components) and that tau2. For N
    links the same, agent by agent inward (agent N first); the arm's N is the number of
    ``linkI`` observations, and a policy of another N is refused (ValueError)."""
    from twolink.envs.dm import policy_action  # the one implementation of (18) for policies

    n = sum(1 for key in observations if str(key).startswith("link"))
    names = agents(n) if 2 <= n else agents(2)
    missing = [a for a in names if a not in observations]
    if missing:
        raise ValueError(f"observations lack agent(s) {', '.join(missing)}")
    check_policy_links(policy, len(names))
    keys, wanted = task_keys(names), observation_names(len(names))
    seen = {}
    for a in names:
        o = np.asarray(observations[a], dtype=float)
        k = len(wanted[keys[a]])
        if o.ndim != 1 or len(o) < k:
            raise ValueError(f"observation of {a} must be a vector of at least {k} numbers, "
                             f"got shape {o.shape}")
        seen[keys[a]] = o[:k]
    tau = policy_action(policy, seen)
    return {a: np.array([tau[i]], dtype=np.float64) for i, a in enumerate(names)}
