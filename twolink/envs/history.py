"""Observation histories as wrappers: memory for delays and noise.

:class:`HistoryVecEnv` (a Stable-Baselines3 ``VecEnvWrapper`` of
:class:`twolink.envs.sb3.TwoLinkSB3VecEnv`) and :class:`HistoryEnv` (a Gymnasium
wrapper of :class:`twolink.envs.gym.TwoLinkEnv`) hand the agent, instead of the present
observation, the last K observations and the last K - 1 actions, concatenated in the
layout of :mod:`twolink.control.history`::

    [o_{t-K+1}, ..., o_t,  a_{t-K+1}, ..., a_{t-1}]        (K d + (K - 1) m numbers)

oldest first, zeros before an episode's first observation; an episode started by an
autoreset starts from zeros again (its ``terminal_observation`` is the ended episode's
history). The actions recorded are those given, clipped to the action space (a Box:
``actions='box'`` or ``'normalized'``), which is what the arm applies and what
:class:`twolink.control.sb3_agent.SB3Agent` records when it runs a saved agent of
history K as a controller. The observation space is the Box of the stacked bounds.
"""
from __future__ import annotations

import gymnasium
import numpy as np
from gymnasium import spaces

from twolink.control.history import ObservationHistory, check_history


def history_space(observation_space, action_space, k: int) -> spaces.Box:
    """The Box of history observations of length ``k`` over these spaces (both Boxes of
    one dimension; one ValueError line otherwise)."""
    k = check_history(k)
    for name, space in (("observation", observation_space), ("action", action_space)):
        if not (isinstance(space, spaces.Box) and len(space.shape) == 1):
            raise ValueError(f"an observation history needs a one-dimensional Box {name} "
                             f"space, got {space}")
    low = np.concatenate([np.tile(observation_space.low.astype(float), k),
                          np.tile(action_space.low.astype(float), k - 1)])
    high = np.concatenate([np.tile(observation_space.high.astype(float), k),
                           np.tile(action_space.high.astype(float), k - 1)])
    return spaces.Box(low, high, (len(low),), np.float64)


def _clipped(actions, space) -> np.ndarray:
    return np.clip(np.asarray(actions, dtype=float), space.low, space.high)


try:
    from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper
except ImportError:                                   # the rl extras are optional
    VecEnv = VecEnvWrapper = None

if VecEnvWrapper is not None:
    class HistoryVecEnv(VecEnvWrapper):
        """A Stable-Baselines3 ``VecEnv`` whose observations are histories of length
        ``k`` (see the module docstring); ``history`` is the buffer
        (:class:`twolink.control.history.ObservationHistory`)."""

        def __init__(self, venv, k: int):
            space = history_space(venv.observation_space, venv.action_space, k)
            self.history = ObservationHistory(venv.num_envs, venv.observation_space.shape[0],
                                              venv.action_space.shape[0], k)
            super().__init__(venv, observation_space=space)

        def reset(self) -> np.ndarray:
            obs = self.venv.reset()
            self.history.reset()
            return self.history.observe(obs)

        def step_async(self, actions: np.ndarray) -> None:
            self.history.act(_clipped(actions, self.venv.action_space))
            self.venv.step_async(actions)

        def step_wait(self):
            obs, rewards, dones, infos = self.venv.step_wait()
            ended = np.flatnonzero(dones)
            last = np.array(obs, dtype=float)
            for i in ended:
                last[i] = infos[i]["terminal_observation"]
            out = self.history.observe(last)
            if len(ended):
                for i in ended:
                    infos[i]["terminal_observation"] = out[i].copy()
                self.history.reset(ended)
                out[ended] = self.history.observe(obs[ended], ended)
            return out, rewards, dones, infos
else:                                                 # pragma: no cover
    HistoryVecEnv = None


class HistoryEnv(gymnasium.Wrapper):
    """A Gymnasium environment (one arm, a Box action space) whose observations are
    histories of length ``k`` (see the module docstring)."""

    def __init__(self, env, k: int):
        super().__init__(env)
        self.observation_space = history_space(env.observation_space, env.action_space, k)
        self.history = ObservationHistory(1, env.observation_space.shape[0],
                                          env.action_space.shape[0], k)

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        self.history.reset()
        return self.history.observe(obs[None])[0], info

    def step(self, action):
        self.history.act(_clipped(action, self.env.action_space)[None])
        obs, reward, terminated, truncated, info = self.env.step(action)
        return self.history.observe(obs[None])[0], reward, terminated, truncated, info


def with_history(env, k: int):
    """``env`` with observation histories of length ``k`` (``env`` itself for k = 1): a
    :class:`HistoryVecEnv` for a Stable-Baselines3 ``VecEnv``, else a :class:`HistoryEnv`."""
    k = check_history(k)
    if k == 1:
        return env
    if VecEnvWrapper is not None and isinstance(env, VecEnv):
        return HistoryVecEnv(env, k)
    return HistoryEnv(env, k)
