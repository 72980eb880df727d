"""Rewards (15) and (17): 0 inside the goal band, -0.5 outside it."""
from __future__ import annotations

import numpy as np

from twolink.parameters import GOAL_ANGLE, GOAL_SPEED, REWARD_GOAL, REWARD_OTHER


def link_in_band(theta, dtheta) -> np.ndarray:
    """|theta| <= 5 deg and |dtheta| <= 0.1 rad/s, elementwise (angles already wrapped)."""
    return (np.abs(theta) <= GOAL_ANGLE) & (np.abs(dtheta) <= GOAL_SPEED)


def in_goal_band(x) -> np.ndarray:
    """Both links inside the goal band, for states x of shape (..., 4)."""
    x = np.asarray(x)
    return link_in_band(x[..., 0], x[..., 2]) & link_in_band(x[..., 1], x[..., 3])


def centralized_reward(x) -> np.ndarray:
    """Reward (15) of states x (..., 4)."""
    return np.where(in_goal_band(x), REWARD_GOAL, REWARD_OTHER)


def agent_reward(x, link: int) -> np.ndarray:
    """Reward (17) of agent ``link`` (1 or 2) for states x (..., 4)."""
    if link not in (1, 2):
        raise ValueError(f"link must be 1 or 2, got {link}")
    x = np.asarray(x)
    i = link - 1
    return np.where(link_in_band(x[..., i], x[..., 2 + i]), REWARD_GOAL, REWARD_OTHER)
