"""The read-out of a policy from measured states: a dead zone on the readings.

Policy (14) maps a state to torques through the greedy actions of the bins around it. On
readings with noise a state near the goal band moves among bins whose greedy actions
differ in sign, and the torque chatters. A :class:`Readout` shrinks the readings towards
zero before the agents see them, as the dead zone of ``pd_deadzone``
(:mod:`twolink.control.baselines.pd`) does for its angle error:

    s' = sign(s) max(|s| - dead_zone, 0)

for every speed (``speed_dead_zone``, rad/s) and every wrapped angle
(``angle_dead_zone_deg``, degrees). A speed reading inside the dead zone reads as rest, so
the policy's action at rest holds the arm still instead of answering the noise.

Far from the goal a second rule may apply (``argmax_beyond_deg``): where an agent reads
an angle beyond that many degrees, it takes the action of the largest interpolated Q (12),
argmax_u sum_m mu_m(x) Q(m, u), instead of the membership-weighted greedy actions (14).
Where neighbouring bins choose opposite torques (the two ways round a joint, near
+-180 deg) the weighted average of (14) cancels to almost no torque and the arm drifts;
the argmax picks one of them. Near the goal (14) stays, so the torque stays smooth there.

Near the goal a third rule may lower the torque (``near_gain`` g < 1, ``near_deg`` A):
joint i's torque is multiplied by

    s_i = g + (1 - g) min(|theta_i| / A, 1),

theta_i its own wrapped angle as read (before any dead zone), so the torque falls
linearly from full at A degrees to g times (14)'s at the goal. (14) is near time-optimal
for a model that is read exactly and answers at once: with readings late, its full torque
near the goal overshoots the band and the arm limit-cycles around it; with readings
noisy, it answers the noise with large torques that push the arm out of the band, as a PD
with too high a gain does. The gain applies to the torques the policy sends; agents that
read a neighbour's torque (18) read it as (14) gives it.

A policy records its read-out in ``meta["readout"]``; without one it reads the states
as they are and acts by (14) everywhere.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Optional

import numpy as np

from twolink.arm.parameters import GOAL_ANGLE, GOAL_SPEED
from twolink.validate import real


#: The smallest angle of the argmax rule: beyond the goal band by a bin's width.
MIN_ARGMAX_DEG = 10.0
_FIELDS = ("speed_dead_zone", "angle_dead_zone_deg", "argmax_beyond_deg", "near_gain",
           "near_deg")
#: The range of the near-goal rule's angle A (degrees): from the goal band's edge to 180.
NEAR_DEG_RANGE = (math.degrees(GOAL_ANGLE), 180.0)


@dataclasses.dataclass(frozen=True)
class Readout:
    """Dead zones on the readings of a policy: speeds in rad/s, angles in degrees, each in
    [0, the goal band's half-width] (a wider dead zone would hide the band's edge); the
    argmax rule beyond ``argmax_beyond_deg`` degrees (None: off; else from
    :data:`MIN_ARGMAX_DEG` to 180); the near-goal gain ``near_gain`` in (0, 1] (1: off),
    reached at the goal from full torque at ``near_deg`` degrees (:data:`NEAR_DEG_RANGE`;
    needed when the gain is below 1)."""

    speed_dead_zone: float = 0.0
    angle_dead_zone_deg: float = 0.0
    argmax_beyond_deg: Optional[float] = None
    near_gain: float = 1.0
    near_deg: Optional[float] = None

    def __post_init__(self):
        object.__setattr__(self, "speed_dead_zone", real(
            self.speed_dead_zone, "speed dead zone", 0.0, GOAL_SPEED))
        object.__setattr__(self, "angle_dead_zone_deg", real(
            self.angle_dead_zone_deg, "angle dead zone", 0.0, math.degrees(GOAL_ANGLE)))
        if self.argmax_beyond_deg is not None:
            object.__setattr__(self, "argmax_beyond_deg", real(
                self.argmax_beyond_deg, "argmax_beyond_deg", MIN_ARGMAX_DEG, 180.0))
        object.__setattr__(self, "near_gain", real(
            self.near_gain, "near_gain", 0.0, 1.0, open_low=True))
        if self.near_deg is not None:
            object.__setattr__(self, "near_deg", real(
                self.near_deg, "near_deg", *NEAR_DEG_RANGE))
        if self.near_gain < 1.0 and self.near_deg is None:
            raise ValueError(f"a near-goal gain of {self.near_gain:g} needs near_deg, the "
                             f"angle (degrees) at which the torque is full again")

    @property
    def active(self) -> bool:
        """Whether the read-out changes anything."""
        return self.shrinks or self.argmax_beyond_deg is not None or self.scales

    @property
    def scales(self) -> bool:
        """Whether the near-goal gain lowers any torque."""
        return self.near_gain < 1.0

    def gain(self, x: np.ndarray, links: int) -> Optional[np.ndarray]:
        """The near-goal gains s_i (..., N) of the readings x (..., 2N) (None when off)."""
        if not self.scales:
            return None
        theta = np.abs(np.mod(x[..., :links] + math.pi, 2 * math.pi) - math.pi)
        ramp = np.minimum(theta / math.radians(self.near_deg), 1.0)
        return self.near_gain + (1.0 - self.near_gain) * ramp

    @property
    def shrinks(self) -> bool:
        return self.speed_dead_zone > 0 or self.angle_dead_zone_deg > 0

    def far(self, points: np.ndarray, inputs: tuple) -> Optional[np.ndarray]:
        """Rows of an agent's ``points`` (..., d) (inputs named ``inputs``) that read an
        angle beyond :attr:`argmax_beyond_deg` (None when the rule is off)."""
        if self.argmax_beyond_deg is None:
            return None
        angles = [k for k, n in enumerate(inputs) if n.startswith("theta")]
        theta = np.mod(points[..., angles] + math.pi, 2 * math.pi) - math.pi
        return np.any(np.abs(theta) > math.radians(self.argmax_beyond_deg), axis=-1)

    def apply(self, x: np.ndarray, links: int) -> np.ndarray:
        """The readings x (..., 2N) the agents see (a new array; x itself when inactive)."""
        if not self.shrinks:
            return x
        x = np.array(x, dtype=float)
        if self.angle_dead_zone_deg > 0:
            theta = np.mod(x[..., :links] + math.pi, 2 * math.pi) - math.pi
            x[..., :links] = _shrink(theta, math.radians(self.angle_dead_zone_deg))
        if self.speed_dead_zone > 0:
            x[..., links:] = _shrink(x[..., links:], self.speed_dead_zone)
        return x

    def as_dict(self) -> dict:
        out = {"speed_dead_zone": self.speed_dead_zone,
               "angle_dead_zone_deg": self.angle_dead_zone_deg}
        if self.argmax_beyond_deg is not None:
            out["argmax_beyond_deg"] = self.argmax_beyond_deg
        if self.scales:
            out["near_gain"], out["near_deg"] = self.near_gain, self.near_deg
        return out

    @classmethod
    def from_dict(cls, data) -> "Readout":
        if not isinstance(data, dict) or set(data) - set(_FIELDS):
            raise ValueError(f"a policy's readout must be a dict of {', '.join(_FIELDS)}, "
                             f"got {data!r}")
        return cls(**data)


def _shrink(v: np.ndarray, width: float) -> np.ndarray:
    return np.sign(v) * np.maximum(np.abs(v) - width, 0.0)
