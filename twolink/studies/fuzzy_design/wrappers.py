"""Controllers around a policy that the tuning table measures and the package does not
ship: a one-step look-ahead on the model far from the goal (:class:`LookAhead`), a hold
region that zeroes a joint's torque near the goal (:class:`Hold`) and the same with
hysteresis (:class:`Hysteresis`).
"""
from __future__ import annotations

import numpy as np

from twolink.arm.parameters import GAMMA, TABLE_I
from twolink.arm.task import centralized_reward
from twolink.policy.fuzzy_policy import Policy
from twolink.synthesis import problems as P


class LookAhead:
    """``policy`` (a centralized one) where every angle reads within ``beyond_deg``
    degrees; beyond that the action of a one-step look-ahead on the full model (6): the
    torque pair u of the policy's action set that maximises rho(f(x, u)) + gamma
    max_u' Q(f(x, u), u'), Q interpolated by (12) at the reached state."""

    def __init__(self, policy: Policy, beyond_deg: float):
        self.policy, self.agent = policy, policy.agents[0]
        self.beyond = np.deg2rad(beyond_deg)
        self.name, self.meta = f"{policy.meta.get('name', 'policy')}_lookahead", dict(policy.meta)

    def look(self, x):
        u = self.agent.actions
        nxt = P.model_step("full", TABLE_I, x[:, None, :], u[None], compiled=True)
        pts = nxt.copy()
        pts[..., :2] = np.mod(pts[..., :2] + np.pi, 2 * np.pi) - np.pi
        value = centralized_reward(nxt) + GAMMA * self.agent.q_values(pts).max(-1)
        return u[np.argmax(value, -1)]

    def __call__(self, x):
        x = np.asarray(x, dtype=float)
        out = self.policy(x)
        far = np.any(np.abs(np.mod(x[:, :2] + np.pi, 2 * np.pi) - np.pi) > self.beyond, -1)
        if np.any(far):
            out[far] = self.look(x[far])
        return out


class Hold:
    """``policy`` with a hold region: joint i's torque is 0 while its link reads within
    ``angle_deg`` degrees and ``speed`` rad/s of the goal."""

    def __init__(self, policy: Policy, angle_deg: float, speed: float):
        self.policy, self.angle, self.speed = policy, np.deg2rad(angle_deg), speed
        self.name, self.meta = "hold", dict(policy.meta)

    def __call__(self, x):
        x = np.asarray(x, dtype=float)
        inside = (np.abs(np.mod(x[:, :2] + np.pi, 2 * np.pi) - np.pi) < self.angle) \
            & (np.abs(x[:, 2:]) < self.speed)
        return np.where(inside, 0.0, self.policy(x))


class Hysteresis:
    """``policy`` with a hold region that has hysteresis: joint i holds (torque 0) from
    the sample its link reads within ``angle_in`` degrees and ``speed_in`` rad/s of the
    goal until it reads beyond ``angle_out`` degrees or ``speed_out`` rad/s. A controller
    with state: ``reset(n)`` releases every joint."""

    def __init__(self, policy: Policy, angle_in: float, speed_in: float, angle_out: float,
                 speed_out: float):
        self.policy, self.held = policy, None
        self.inner = (np.deg2rad(angle_in), speed_in)
        self.outer = (np.deg2rad(angle_out), speed_out)
        self.name, self.meta = "hysteresis", dict(policy.meta)

    def reset(self, n: int) -> None:
        self.held = np.zeros((n, 2), dtype=bool)

    def __call__(self, x):
        x = np.asarray(x, dtype=float)
        if self.held is None or len(self.held) != len(x):
            self.reset(len(x))
        theta, speed = np.abs(np.mod(x[:, :2] + np.pi, 2 * np.pi) - np.pi), np.abs(x[:, 2:])
        inside = (theta <= self.inner[0]) & (speed <= self.inner[1])
        beyond = (theta > self.outer[0]) | (speed > self.outer[1])
        self.held = (self.held | inside) & ~beyond
        return np.where(self.held, 0.0, self.policy(x))
