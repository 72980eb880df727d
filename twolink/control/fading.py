"""A gain that fades once a joint has settled: a hold region with hysteresis.

Policy (14) is near time-optimal on the way to the goal, and there it should act at full
torque. Once the arm is at the goal, its full torque answers late or noisy readings with
pushes that take the arm out of the band again (a limit cycle around it). The
:class:`FadingGain` wrapper leaves the approach alone and lowers the torque only after a
joint has settled:

* joint i *enters* the hold when its own reading lies within ``enter_deg`` degrees and
  ``enter_speed`` rad/s of the goal (the goal band by default), and *leaves* it when
  its reading lies beyond ``exit_deg`` degrees or ``exit_speed`` rad/s (hysteresis:
  ``exit`` >= ``enter``, so a reading that wanders a little keeps the hold);
* while held, joint i's torque is multiplied by a gain that falls from 1 by
  ``1 / fade_samples`` per sample Ts down to ``floor`` (``fade_samples = 1``: at once);
  on leaving, the gain is 1 again at once.

Each joint uses its own reading only, so a decentralized policy stays decentralized.
The wrapper has state (the hold and the gain of every row and joint): ``reset(n)`` starts
n rows released, as every rollout does.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from twolink.arm.parameters import GOAL_ANGLE, GOAL_SPEED
from twolink.validate import real, whole


def check_band(region) -> None:
    """A ValueError line unless ``region``'s ``enter_deg`` (0 to 180) and ``enter_speed``
    (0 to 2 pi rad/s) are positive and its ``exit_deg``, ``exit_speed`` are at least
    those (hysteresis)."""
    real(region.enter_deg, "enter_deg", 0.0, 180.0, open_low=True)
    real(region.enter_speed, "enter_speed", 0.0, 2 * math.pi, open_low=True)
    real(region.exit_deg, "exit_deg", region.enter_deg, 180.0)
    real(region.exit_speed, "exit_speed", region.enter_speed, 2 * math.pi)


@dataclasses.dataclass(frozen=True)
class Fade:
    """The settings of a fading gain (see the module docstring); checked on creation."""

    exit_deg: float = 10.0
    exit_speed: float = 0.3
    floor: float = 0.3
    fade_samples: int = 10
    enter_deg: float = math.degrees(GOAL_ANGLE)
    enter_speed: float = GOAL_SPEED

    def __post_init__(self):
        check_band(self)
        real(self.floor, "floor", 0.0, 1.0)
        whole(self.fade_samples, "fade_samples", 1, 10_000)

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


def goal_angles(x, links: int) -> np.ndarray:
    """|theta| (n, links) in radians: each joint's reading of the states x (n, 2 links)
    from the goal, the angle wrapped to [-pi, pi)."""
    return np.abs(np.mod(x[:, :links] + math.pi, 2 * math.pi) - math.pi)


def band_readings(x, links: int, region) -> tuple:
    """(inside, beyond), each (n, links): whether each joint's reading of the states x
    (n, 2 links) lies within ``region``'s ``enter_deg`` degrees (the angle wrapped to
    [-pi, pi)) and ``enter_speed`` rad/s of the goal, and whether it lies beyond its
    ``exit_deg`` or ``exit_speed``: the hold regions of :class:`FadingGain` and
    :class:`twolink.control.handover.Handover`."""
    theta = goal_angles(x, links)
    speed = np.abs(x[:, links:])
    inside = (theta <= math.radians(region.enter_deg)) & (speed <= region.enter_speed)
    beyond = (theta > math.radians(region.exit_deg)) | (speed > region.exit_speed)
    return inside, beyond


class FadingGain:
    """``policy`` (any controller: states (n, 2N) -> torques (n, N)) with the fading gain
    ``fade`` (:class:`Fade`, or its dict) on every joint; ``name`` labels it."""

    def __init__(self, policy, fade, *, name: str | None = None, links: int | None = None):
        if isinstance(fade, dict):
            try:
                fade = Fade(**fade)
            except TypeError as exc:
                raise ValueError(f"fade: {exc}") from None
        if not isinstance(fade, Fade):
            raise TypeError(f"fade must be a Fade or a dict of its fields, got "
                            f"{type(fade).__name__}")
        self.policy, self.fade = policy, fade
        self.links = int(links or getattr(policy, "links", 2))
        self.name = name or f"{getattr(policy, 'name', 'policy')}_fading"
        self.meta = {**dict(getattr(policy, "meta", None) or {}), "fade": fade.as_dict()}
        self.held = self.gain = None

    def reset(self, n: int) -> None:
        """Release every joint of ``n`` rows (full gain)."""
        self.held = np.zeros((n, self.links), dtype=bool)
        self.gain = np.ones((n, self.links))
        inner = getattr(self.policy, "reset", None)
        if callable(inner):
            inner(n)

    def __call__(self, x) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        n = self.links
        if self.held is None or self.held.shape[0] != x.shape[0]:
            self.reset(x.shape[0])
        f = self.fade
        inside, beyond = band_readings(x, n, f)
        self.held = (self.held | inside) & ~beyond
        step = (1.0 - f.floor) / f.fade_samples
        self.gain = np.where(self.held, np.maximum(f.floor, self.gain - step), 1.0)
        return np.asarray(self.policy(x), dtype=float) * self.gain


def fading_policy(table: str, fade: dict, readout: dict | None = None) -> FadingGain:
    """The shipped table or policy file ``table`` (read through ``readout`` when given,
    :func:`twolink.policy.fuzzy_policy.policy_with_readout`) behind the fading gain
    ``fade``: a design given as data, as catalogue entries give it."""
    from twolink.policy.fuzzy_policy import load_policy, policy_with_readout

    policy = load_policy(table) if readout is None else policy_with_readout(table, readout)
    return FadingGain(policy, fade, name=f"{table}_fading")
