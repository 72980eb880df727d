"""Rewards (15) and (17): 0 inside the goal band, -0.5 outside it; the discrete torque
levels; how fast a joint's own motor can bring it home (:func:`own_motor_seconds`).

For an arm of N links (states x = [theta_1..theta_N, dtheta_1..dtheta_N], shape (..., 2N))
the goal band of (15) holds every link in its band, and agent i's reward (17) looks at
link i alone.
"""
from __future__ import annotations

import numpy as np

from twolink.arm.integrate import wrap_angle
from twolink.arm.parameters import (
    GOAL_ANGLE,
    GOAL_SPEED,
    REWARD_GOAL,
    REWARD_OTHER,
    ArmParameters,
    LinksParameters,
    as_links,
)
from twolink.validate import whole


def link_in_band(theta, dtheta) -> np.ndarray:
    """|theta| <= 5 deg and |dtheta| <= 0.1 rad/s, elementwise (angles already wrapped)."""
    return (np.abs(theta) <= GOAL_ANGLE) & (np.abs(dtheta) <= GOAL_SPEED)


def _links(x: np.ndarray) -> int:
    """N of states x (..., 2N), N >= 2; else a clear ValueError."""
    if x.ndim == 0 or x.shape[-1] < 4 or x.shape[-1] % 2:
        raise ValueError(f"states must have 2N components [theta_1..theta_N, "
                         f"dtheta_1..dtheta_N] with N >= 2, got shape {x.shape}")
    return x.shape[-1] // 2


def in_goal_band(x) -> np.ndarray:
    """Every link inside the goal band, for states x of shape (..., 2N)."""
    x = np.asarray(x)
    n = _links(x)
    inside = link_in_band(x[..., 0], x[..., n])
    for i in range(1, n):
        inside = inside & link_in_band(x[..., i], x[..., n + i])
    return inside


def centralized_reward(x) -> np.ndarray:
    """Reward (15) of states x (..., 2N)."""
    return np.where(in_goal_band(x), REWARD_GOAL, REWARD_OTHER)


def agent_reward(x, link: int) -> np.ndarray:
    """Reward (17) of agent ``link`` (1 to N) for states x (..., 2N)."""
    x = np.asarray(x)
    n = _links(x)
    if link not in tuple(range(1, n + 1)):
        span = "1 or 2" if n == 2 else f"1 to {n}"
        raise ValueError(f"link must be {span}, got {link}")
    i = link - 1
    return np.where(link_in_band(x[..., i], x[..., n + i]), REWARD_GOAL, REWARD_OTHER)


#: Torque levels per joint of the paper's (16) and (18); the most a synthesis may ask for.
PAPER_LEVELS = 3
MAX_LEVELS = 9


def check_levels(levels) -> int:
    """``levels`` if it is a whole number from 2 to :data:`MAX_LEVELS`, else a ValueError."""
    return whole(levels, "levels", 2, MAX_LEVELS)


def action_levels(tau_max: float, levels: int = PAPER_LEVELS) -> np.ndarray:
    """The discrete torques of one joint: ``levels`` values evenly spaced over
    [-tau_max, tau_max]. The paper's (16) and (18): 3 levels, {-tau_max, 0, tau_max};
    an odd count always holds 0 (the torque that lets the arm rest in the band)."""
    levels = check_levels(levels)
    if levels == PAPER_LEVELS:
        return np.array([-tau_max, 0.0, tau_max])
    return np.array([tau_max * (2 * j / (levels - 1) - 1) for j in range(levels)])


def own_motor_speed(p: ArmParameters | LinksParameters) -> np.ndarray:
    """The fastest each joint turns on its own motor with every other joint held, shape (N,).

    With joints j != i locked the links beyond joint i move as one rigid body about a
    fixed axis, so :func:`twolink.arm.dynamics.links_acceleration` reduces to
    J_i ddtheta_i = tau_i - b_i dtheta_i: the bias C vanishes (M_ii does not depend on
    theta_i) and J_i is the
    inertia of links i..N about joint i. From rest the speed then stays below
    tau_i max / b_i, and within the joint's speed limit: min(tau_i max / b_i,
    speed limit_i) (every damping is positive: :class:`LinksParameters` checks it)."""
    c = as_links(p)
    tau = np.asarray(c.tau_max, dtype=float)
    b = np.asarray(c.dampings, dtype=float)
    limit = np.asarray(c.speed_limits, dtype=float)
    return np.minimum(tau / b, limit)


def own_motor_seconds(p: ArmParameters | LinksParameters, angles) -> np.ndarray:
    """A lower bound on the seconds joint i's own motor needs to bring it from the wrapped
    angle theta_i (at rest) to 0 with every other joint held: |theta_i| /
    :func:`own_motor_speed`, shape of ``angles`` (..., N). Moving the other joints can
    shorten it (their reactions turn joint i too); a decentralized controller whose
    joints do not help each other cannot."""
    c = as_links(p)
    a = np.asarray(angles, dtype=float)
    if a.ndim < 1 or a.shape[-1] != c.links:
        raise ValueError(f"angles must have shape (..., {c.links}) for a {c.links}-link "
                         f"arm, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError("angles must be finite")
    return np.abs(wrap_angle(a)) / own_motor_speed(c)


def inner_excursion(angles) -> np.ndarray:
    """How far the inner joints swing away from the goal: for angle paths (..., K+1, N)
    (N >= 2), the largest over joints 1..N-1 and samples of |wrap(theta_i(t))| less
    |wrap(theta_i(0))|, at least 0, shape (...). A controller that only drives every joint
    home reads 0 (up to overshoot); turning a slow outer joint by the reactions of the
    inner ones, as the time-optimal answers of :mod:`twolink.limits.links` do, swings
    them out first."""
    a = np.asarray(angles, dtype=float)
    if a.ndim < 2 or a.shape[-1] < 2 or a.shape[-2] < 1:
        raise ValueError(f"angles must have shape (..., K+1, N) with N >= 2, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError("angles must be finite")
    far = np.abs(wrap_angle(a[..., :-1]))
    return np.maximum(far.max(axis=-2) - far[..., 0, :], 0.0).max(axis=-1)
