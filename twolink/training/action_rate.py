"""A training-only reward term against chattering torques: the action-rate penalty.

Under a challenge level's actuation delay and sensor noise a policy trained on the shaped
reward alone learns to bring the arm near the goal and then chatter around it: the
deterministic policy of ``twolink train --challenge medium --history 3`` stays within
3 deg of the goal with speeds of 0.1-0.2 rad/s, over the goal band's 0.1 rad/s, on every
state. :class:`ActionRateVecEnv` subtracts from each arm's reward

    c * (1/N) sum_i (a_i,k - a_i,k-1)^2,

the mean squared change of the normalized action (each a_i in [-1, 1]) since the last
step of the same episode (zero before its first action), the "action rate" penalty of
legged-locomotion RL. :func:`wrap` applies it; a multi-agent run applies
:func:`agent_penalties` (each agent its own term; MAPPO's team reward the arm's). ``c``
is ``twolink train --action-rate C`` (0: off, the default).
The evaluation metric is untouched: only the reward the learner trains on changes. The
last actions are part of a checkpoint (``action_rate_state``), so a resumed run
continues exactly.
"""
from __future__ import annotations

import numpy as np

from twolink.validate import real

#: Largest coefficient ``--action-rate`` takes (the shaped reward lies in [-1, 0]).
MAX_ACTION_RATE = 100.0


def check_action_rate(c) -> float:
    """``c`` as a float in [0, :data:`MAX_ACTION_RATE`], else one ValueError line."""
    return real(c, "action_rate", 0.0, MAX_ACTION_RATE)


def penalty(actions, last, c: float) -> np.ndarray:
    """``c`` times the mean squared change per arm of the clipped actions (n, N) from
    ``last`` (n, N)."""
    a = np.clip(np.asarray(actions, dtype=float), -1.0, 1.0)
    return c * np.mean((a - last) ** 2, axis=-1)


def agent_penalties(actions, last, c: float, team: bool = False) -> np.ndarray:
    """The penalties (n, N) of the agents of a multi-agent run (one agent per joint, its
    clipped normalized action a column of ``actions`` (n, N), ``last`` (n, N) the actions
    before): agent i's own ``c (a_i - last_i)^2``, or, ``team`` (one reward shared by the
    agents, MAPPO's), every agent the arm's :func:`penalty`."""
    a = np.clip(np.asarray(actions, dtype=float), -1.0, 1.0)
    if team:
        return np.repeat(penalty(a, last, c)[:, None], a.shape[-1], axis=-1)
    return c * (a - last) ** 2


def wrap(venv, c: float):
    """``venv`` (a Stable-Baselines3 ``VecEnv`` of normalized actions) with the penalty of
    coefficient ``c`` on its rewards: an :class:`ActionRateVecEnv`."""
    return _wrapper_class()(venv, c)


def _wrapper_class():
    from stable_baselines3.common.vec_env import VecEnvWrapper   # the rl extras

    global ActionRateVecEnv
    if ActionRateVecEnv is not None:
        return ActionRateVecEnv

    class _ActionRateVecEnv(VecEnvWrapper):
        """A Stable-Baselines3 ``VecEnv`` whose rewards carry the action-rate penalty of
        coefficient ``c`` (see the module docstring); actions are normalized ([-1, 1])."""

        def __init__(self, venv, c: float):
            self.c = check_action_rate(c)
            self.last = np.zeros((venv.num_envs, venv.action_space.shape[0]))
            self._pending = None
            super().__init__(venv)

        def reset(self) -> np.ndarray:
            self.last[:] = 0.0
            return self.venv.reset()

        def step_async(self, actions: np.ndarray) -> None:
            self._pending = np.clip(np.asarray(actions, dtype=float), -1.0, 1.0)
            self.venv.step_async(actions)

        def step_wait(self):
            obs, rewards, dones, infos = self.venv.step_wait()
            rewards = np.asarray(rewards)
            rewards = rewards - penalty(self._pending, self.last, self.c).astype(rewards.dtype)
            self.last = self._pending.copy()
            self.last[np.asarray(dones, dtype=bool)] = 0.0     # a new episode begins
            return obs, rewards, dones, infos

        def action_rate_state(self) -> dict:
            """The last actions (a copy), for a checkpoint."""
            return {"last": self.last.copy()}

        def set_action_rate_state(self, state: dict) -> None:
            self.last = np.asarray(state["last"], dtype=float).reshape(self.last.shape).copy()

    _ActionRateVecEnv.__name__ = _ActionRateVecEnv.__qualname__ = "ActionRateVecEnv"
    ActionRateVecEnv = _ActionRateVecEnv
    return ActionRateVecEnv


#: The wrapper class, made on first use by :func:`wrap` (Stable-Baselines3 is optional).
ActionRateVecEnv = None
