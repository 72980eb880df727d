"""The read-out of a policy from measured states: a dead zone on the readings.

Policy (14) maps a state to torques through the greedy actions of the bins around it. On
readings with noise a state near the goal band moves among bins whose greedy actions
differ in sign, and the torque chatters. A :class:`Readout` shrinks the readings towards
zero before the agents see them, as the dead zone of ``pd_deadzone``
(:mod:`twolink.control.baselines.pd`) does for its angle error:

    s' = sign(s) max(|s| - dead_zone, 0)

for every speed (``speed_dead_zone``, rad/s) and every wrapped angle
(``angle_dead_zone_deg``, degrees). A speed reading inside the dead zone reads as rest, so
the policy's action at rest holds the arm still instead of answering the noise. A policy
records its read-out in ``meta["readout"]``; without one it reads the states as they are.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from twolink.arm.parameters import GOAL_ANGLE, GOAL_SPEED
from twolink.validate import real


@dataclasses.dataclass(frozen=True)
class Readout:
    """Dead zones on the readings of a policy: speeds in rad/s, angles in degrees, each in
    [0, the goal band's half-width] (a wider dead zone would hide the band's edge)."""

    speed_dead_zone: float = 0.0
    angle_dead_zone_deg: float = 0.0

    def __post_init__(self):
        object.__setattr__(self, "speed_dead_zone", real(
            self.speed_dead_zone, "speed dead zone", 0.0, GOAL_SPEED))
        object.__setattr__(self, "angle_dead_zone_deg", real(
            self.angle_dead_zone_deg, "angle dead zone", 0.0, math.degrees(GOAL_ANGLE)))

    @property
    def active(self) -> bool:
        return self.speed_dead_zone > 0 or self.angle_dead_zone_deg > 0

    def apply(self, x: np.ndarray, links: int) -> np.ndarray:
        """The readings x (..., 2N) the agents see (a new array; x itself when inactive)."""
        if not self.active:
            return x
        x = np.array(x, dtype=float)
        if self.angle_dead_zone_deg > 0:
            theta = np.mod(x[..., :links] + math.pi, 2 * math.pi) - math.pi
            x[..., :links] = _shrink(theta, math.radians(self.angle_dead_zone_deg))
        if self.speed_dead_zone > 0:
            x[..., links:] = _shrink(x[..., links:], self.speed_dead_zone)
        return x

    def as_dict(self) -> dict:
        return {"speed_dead_zone": self.speed_dead_zone,
                "angle_dead_zone_deg": self.angle_dead_zone_deg}

    @classmethod
    def from_dict(cls, data) -> "Readout":
        if not isinstance(data, dict) or set(data) - {"speed_dead_zone", "angle_dead_zone_deg"}:
            raise ValueError(f"a policy's readout must be a dict of speed_dead_zone and "
                             f"angle_dead_zone_deg, got {data!r}")
        return cls(**data)


def _shrink(v: np.ndarray, width: float) -> np.ndarray:
    return np.sign(v) * np.maximum(np.abs(v) - width, 0.0)
