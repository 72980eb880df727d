"""Closed-loop rollouts of a policy on a plant, batched over initial states.

At each sample k the policy sees x_k, the plant holds tau_k over Ts and returns x_{k+1};
the rewards r_{k+1} of (15) and (17) are evaluated on x_{k+1}.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from twolink.parameters import HORIZON, TS
from twolink.plants import Plant, check_states
from twolink.reward import agent_reward, centralized_reward


@dataclasses.dataclass
class Trajectory:
    """Times (K+1,), states (..., K+1, 4), torques (..., K, 2), rewards (..., K) of (15)
    and per-link rewards (..., K, 2) of (17)."""

    t: np.ndarray
    x: np.ndarray
    u: np.ndarray
    r: np.ndarray
    r_links: np.ndarray
    plant: str = ""
    policy: str = ""

    @property
    def steps(self) -> int:
        return len(self.t) - 1

    def __getitem__(self, i) -> "Trajectory":
        """The trajectory of batch row ``i``."""
        return Trajectory(self.t, self.x[i], self.u[i], self.r[i], self.r_links[i],
                          self.plant, self.policy)


def steps_for(duration: float) -> int:
    """Number of sample periods in ``duration`` seconds."""
    if not np.isfinite(duration) or duration <= 0:
        raise ValueError(f"duration must be a positive number of seconds, got {duration}")
    return max(1, int(round(duration / TS)))


def rollout(policy, plant: Plant, x0, *, duration: float = HORIZON,
            observe=None) -> Trajectory:
    """Run ``policy`` on ``plant`` from x0 (4,) or a batch (B, 4) for ``duration`` seconds.

    ``observe(k, x)`` may return the state the policy sees (for noise or delays); by
    default it sees the true state.
    """
    x0 = check_states(x0, what="x0")
    n = steps_for(duration)
    xs = np.empty(x0.shape[:-1] + (n + 1, 4))
    us = np.empty(x0.shape[:-1] + (n, 2))
    x = x0
    xs[..., 0, :] = x
    for k in range(n):
        seen = x if observe is None else observe(k, x)
        u = policy(seen)
        x = plant.step(x, u)
        us[..., k, :] = u
        xs[..., k + 1, :] = x
    nxt = xs[..., 1:, :]
    r_links = np.stack([agent_reward(nxt, 1), agent_reward(nxt, 2)], -1)
    return Trajectory(np.arange(n + 1) * TS, xs, us, centralized_reward(nxt), r_links,
                      getattr(plant, "name", ""), getattr(policy, "kind", ""))
