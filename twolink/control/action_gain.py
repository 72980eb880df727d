"""The action gain of a deep-RL agent: its normalized action a scaled by G before the
torque limit,

    tau = clip(G a, -1, 1) tau_max          (a clipped to [-1, 1] first),

so that full torque lies at |a| = 1/G. SAC's actions are a squashed Gaussian, tanh of the
policy's mean, and its entropy term keeps them off the ends of [-1, 1]: the deterministic
actions of the SAC agents trained with G = 1 stay below the torque limit on every sample
of the nominal runs, while the time-optimal limit T* is bang-bang. ``twolink train
--action-gain G`` trains with the gain (:class:`twolink.envs.action_gain.ActionGainVecEnv`
between the agent and the arms), its agent file records G (``action_gain`` in
``twolink.json``, absent for G = 1) and the loaders apply it. An observation history
and the action-rate penalty see the agent's own action a, before the gain.
"""
from __future__ import annotations

import json

import numpy as np

from twolink.sim.controller import ControllerError
from twolink.validate import real

#: Largest gain ``--action-gain`` takes (above it the action is a switch: full torque
#: from |a| = 0.1).
MAX_ACTION_GAIN = 10.0


def check_action_gain(g) -> float:
    """``g`` as a float in [1, :data:`MAX_ACTION_GAIN`], else one ValueError line."""
    return real(g, "action_gain", 1.0, MAX_ACTION_GAIN)


def gained(action, g: float) -> np.ndarray:
    """The actions ``action`` (..., N) clipped to [-1, 1], times ``g``, clipped again:
    the fraction of the torque limit each joint gets."""
    a = np.clip(np.asarray(action, dtype=float), -1.0, 1.0)
    return a if g == 1.0 else np.clip(g * a, -1.0, 1.0)


def agent_action_gain(path, extra: bytes | None) -> float:
    """The action gain of the agent saved at ``path`` from its ``twolink.json`` bytes
    ``extra`` (1 without the member or the field); one ControllerError line for a gain
    that is not a number in [1, :data:`MAX_ACTION_GAIN`]."""
    meta = json.loads(extra) if extra is not None else {}
    g = meta.get("action_gain", 1.0) if isinstance(meta, dict) else 1.0
    try:
        return check_action_gain(g)
    except (TypeError, ValueError):
        raise ControllerError(f"{path}: its twolink.json says action_gain "
                              f"{str(g)[:30]}; a gain is a number from 1 to "
                              f"{MAX_ACTION_GAIN:g}") from None
