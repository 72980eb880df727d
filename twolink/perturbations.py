"""Model mismatch and imperfect observation: perturbed parameters, state noise, delay.

Shared by the robustness sweeps (``twolink mismatch``) and the dm_env tasks, so the
same perturbation means the same thing everywhere. Randomness only through an injected
``numpy.random.Generator``.
"""
from __future__ import annotations

import dataclasses
from typing import Optional

import numpy as np

from twolink.parameters import TABLE_I, ArmParameters

#: Table I parameters a sweep may perturb (the plant's physical constants).
PERTURBABLE = ("l1", "m1", "m2", "I1", "I2", "c1", "c2", "b1", "b2", "tau1_max", "tau2_max")


def perturbed(base: ArmParameters = TABLE_I, **relative: float) -> ArmParameters:
    """Parameters with relative changes, e.g. ``perturbed(m2=+0.2)`` is m2 * 1.2."""
    return base.scaled(**{k: 1.0 + float(v) for k, v in relative.items()})


def random_perturbation(rng: np.random.Generator, size: float,
                        base: ArmParameters = TABLE_I,
                        names: tuple = PERTURBABLE) -> ArmParameters:
    """All ``names`` perturbed jointly, each by a relative change uniform in [-size, size]."""
    if not 0.0 <= size < 1.0:
        raise ValueError(f"perturbation size must lie in [0, 1), got {size}")
    return perturbed(base, **{n: rng.uniform(-size, size) for n in names})


@dataclasses.dataclass
class ObservationNoise:
    """Gaussian noise on the measured state: std of (angle [rad], speed [rad/s])."""

    angle_std: float = 0.0
    speed_std: float = 0.0
    rng: Optional[np.random.Generator] = None

    def __post_init__(self):
        if not (np.isfinite(self.angle_std) and np.isfinite(self.speed_std)) or \
                self.angle_std < 0 or self.speed_std < 0:
            raise ValueError("noise standard deviations must be finite and non-negative")
        if self.rng is None:
            self.rng = np.random.default_rng(0)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        if self.angle_std == 0 and self.speed_std == 0:
            return x
        std = np.array([self.angle_std, self.angle_std, self.speed_std, self.speed_std])
        return x + std * self.rng.standard_normal(np.shape(x))


def torque_limited(base: ArmParameters = TABLE_I, relative: float = 0.0) -> ArmParameters:
    """The plant's torque limits tau1_max and tau2_max both changed by ``relative``.

    The policy keeps commanding its own action levels; the plant clips them.
    """
    return perturbed(base, tau1_max=relative, tau2_max=relative)


class ActuationDelay:
    """A policy whose torque reaches the plant ``samples`` sample periods late.

    Until the first command arrives the actuators hold zero torque. Wraps a batched
    policy; state lives in the wrapper, so make a new one per rollout.
    """

    def __init__(self, policy, samples: int = 1):
        if int(samples) != samples or samples < 0:
            raise ValueError(f"delay must be a non-negative whole number of samples, got {samples}")
        self.policy = policy
        self.samples = int(samples)
        self.kind = getattr(policy, "kind", "")
        self._queue: list = []

    def __call__(self, x) -> np.ndarray:
        u = self.policy(x)
        if self.samples == 0:
            return u
        if not self._queue:
            self._queue = [np.zeros_like(u)] * self.samples
        self._queue.append(u)
        return self._queue.pop(0)
