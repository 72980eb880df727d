"""The exploration-noise floor of a Gaussian policy: ``std_floor`` S keeps the standard
deviation of every policy's noise at S or more, in units of its normalized action (1: the
whole torque limit), and starts it at S.

IPPO/MAPPO (skrl) clamp it where the distribution is made (skrl's ``min_log_std``, set by
:meth:`twolink.training.marl.MarlConfig.hyperparameters`). PPO (Stable-Baselines3) learns
one state-independent ``log_std`` per action: :func:`floor_callback` raises it to
log S before every rollout, so every action sampled is at least that noisy, and the
update that follows starts from the noise the rollout was sampled with. SAC's noise is
an output of its network: it has no floor here.
"""
from __future__ import annotations

import math

from twolink.validate import in_range

#: The range of ``std_floor``: each policy's exploration noise, in units of its normalized
#: action (1: the whole torque limit).
STD_FLOOR_RANGE = (0.01, 1.0)


def check_std_floor(value) -> float:
    """``value`` as a float if it lies in :data:`STD_FLOOR_RANGE`; else one line."""
    return in_range(value, "std_floor", STD_FLOOR_RANGE,
                    "the policy's noise in units of its normalized action")


def raise_log_std(policy, floor: float) -> None:
    """Raise every entry of ``policy.log_std`` (an SB3 Gaussian policy's) below log
    ``floor`` to it, in place."""
    import torch

    with torch.no_grad():
        policy.log_std.clamp_(min=math.log(floor))


def floor_callback(floor: float):
    """An SB3 callback that applies :func:`raise_log_std` at the start of every rollout."""
    from stable_baselines3.common.callbacks import BaseCallback

    class StdFloor(BaseCallback):
        def _on_rollout_start(self) -> None:
            raise_log_std(self.model.policy, floor)

        def _on_step(self) -> bool:
            return True

    return StdFloor()
