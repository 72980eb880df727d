"""Residual actions over a base controller as a Stable-Baselines3 wrapper.

:class:`ResidualVecEnv` wraps :class:`twolink.envs.sb3.TwoLinkSB3VecEnv`
(``actions='normalized'``) so that the agent's action a in [-1, 1]^N is a residual over
a base controller (:mod:`twolink.control.residual`): the arm is driven with

    tau = clip(base(x) + tau_max a, -tau_max, tau_max),

x the arms' present states, which are also what the agent observes (the base options
are offered without observation noise or delays; a checkpoint restores the states, so a
resumed run drives the same torques). With a = 0 the arms run the base controller
alone. Observations, rewards, dones and infos pass through unchanged; an observation
history (:class:`twolink.envs.history.HistoryVecEnv`) wraps this wrapper and so records
the agent's own (residual) actions.
"""
from __future__ import annotations

import numpy as np

from twolink.control.residual import residual_torques

try:
    from stable_baselines3.common.vec_env import VecEnvWrapper
except ImportError:                                   # the rl extras are optional
    VecEnvWrapper = None


def _base_env(env):
    while hasattr(env, "venv"):
        env = env.venv
    return env


if VecEnvWrapper is not None:
    class ResidualVecEnv(VecEnvWrapper):
        """The arms of ``venv`` driven by ``base`` (a controller: states -> torques) plus
        the agent's normalized residual (module docstring)."""

        def __init__(self, venv, base):
            arms = _base_env(venv)
            if getattr(arms, "_arms", None) is None or arms._arms.actions != "normalized":
                raise ValueError("a residual over a base controller needs the arms' "
                                 "normalized actions (actions='normalized')")
            if getattr(base, "links", arms.links) != arms.links:
                raise ValueError(f"a base controller of {base.links} links for an arm of "
                                 f"{arms.links}")
            self.base = base
            self.tau_max = np.asarray(arms._arms.params.tau_max, dtype=float)
            super().__init__(venv)

        def reset(self):
            return self.venv.reset()

        def step_async(self, actions) -> None:
            x = _base_env(self.venv).states
            torques = residual_torques(self.base, x, actions, self.tau_max)
            self.venv.step_async(torques / self.tau_max)      # float64: no rounding to float32

        def step_wait(self):
            return self.venv.step_wait()
else:                                                 # pragma: no cover
    ResidualVecEnv = None
