"""The action gain (:mod:`twolink.control.action_gain`) as a Stable-Baselines3 wrapper.

:class:`ActionGainVecEnv` wraps :class:`twolink.envs.sb3.TwoLinkSB3VecEnv`
(``actions='normalized'``, or a :class:`twolink.envs.residual.ResidualVecEnv` over it) so
that the agent's action a in [-1, 1]^N reaches the arms as ``clip(G a, -1, 1)``:
full torque from |a| = 1/G. Observations, rewards, dones and infos pass through
unchanged; the wrappers above it (the action-rate penalty, an observation history) see
the agent's own a.
"""
from __future__ import annotations

from twolink.control.action_gain import check_action_gain, gained

try:
    from stable_baselines3.common.vec_env import VecEnvWrapper
except ImportError:                                   # the rl extras are optional
    VecEnvWrapper = None


if VecEnvWrapper is not None:
    class ActionGainVecEnv(VecEnvWrapper):
        """The arms of ``venv`` driven by the agent's normalized actions times ``gain``,
        clipped to [-1, 1] (module docstring)."""

        def __init__(self, venv, gain: float):
            self.gain = check_action_gain(gain)
            inner = venv
            while hasattr(inner, "venv"):
                inner = inner.venv
            if getattr(inner, "_arms", None) is None or inner._arms.actions != "normalized":
                raise ValueError("an action gain needs the arms' normalized actions "
                                 "(actions='normalized')")
            super().__init__(venv)

        def reset(self):
            return self.venv.reset()

        def step_async(self, actions) -> None:
            self.venv.step_async(gained(actions, self.gain))

        def step_wait(self):
            return self.venv.step_wait()
else:                                                 # pragma: no cover
    ActionGainVecEnv = None
