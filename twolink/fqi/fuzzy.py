"""Fuzzy partition of the state: triangular membership functions (12)-(13).

An :class:`Axis` is one state component's bins (circular for angles, clamped at the
ends otherwise). A :class:`Grid` is the product of several axes; its memberships are
returned sparsely, at most 2**d non-zeros per point, as (flat bin index, weight) pairs.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from twolink.arm.task import action_levels

#: Bin centres of the paper (docs/conventions.md), in degrees and degrees per second.
ANGLE_BINS_DEG = (-180.0, -130.0, -80.0, -30.0, -15.0, -5.0, 0.0, 5.0, 15.0, 30.0, 80.0, 130.0)
SPEED_BINS_DEG = (-360.0, -180.0, -30.0, 0.0, 30.0, 180.0, 360.0)
#: Bins concentrated where the task is decided, the goal band |theta| <= 5 deg and
#: |dtheta| <= 0.1 rad/s (5.7 deg/s): centres at the band's edge and inside it, spacing
#: growing away from it. 16 angle and 13 speed bins against the paper's 12 and 7.
GOAL_ANGLE_BINS_DEG = (-180.0, -120.0, -70.0, -40.0, -20.0, -10.0, -5.0, -2.0, 0.0,
                       2.0, 5.0, 10.0, 20.0, 40.0, 70.0, 120.0)
GOAL_SPEED_BINS_DEG = (-360.0, -180.0, -90.0, -40.0, -15.0, -5.0, 0.0, 5.0, 15.0, 40.0,
                       90.0, 180.0, 360.0)
#: Angle bins with no centre on the goal band's edge: the paper's centres halved once
#: (:meth:`Axis.refined` (2)) with 2.5, 5 and 10 deg replaced by one centre inside the
#: band (4 deg) and one outside it (9 deg); 22 centres, the speeds keep the paper's 7.
#: A centre on the edge (the paper's +-5 deg) is inside the band, its greedy action at
#: rest is zero torque, and (14) barely pushes a joint resting just outside the band:
#: the arm parks there under torque loss and noise (``metrics.stalled_at_band_edge``).
#: With 9 deg outside the band, a joint at 5.3 deg takes 26 % of that bin's push.
EDGE_ANGLE_BINS_DEG = (-180.0, -155.0, -130.0, -105.0, -80.0, -55.0, -30.0, -22.5, -15.0,
                       -9.0, -4.0, 0.0, 4.0, 9.0, 15.0, 22.5, 30.0, 55.0, 80.0, 105.0,
                       130.0, 155.0)
#: Named bin layouts: (angle centres, speed centres), degrees and degrees per second.
BIN_LAYOUTS = {"paper": (ANGLE_BINS_DEG, SPEED_BINS_DEG),
               "goal": (GOAL_ANGLE_BINS_DEG, GOAL_SPEED_BINS_DEG),
               "edge": (EDGE_ANGLE_BINS_DEG, SPEED_BINS_DEG)}
#: The two extra speed bins (deg/s, at -+ this value) that N-link agents add to some speed
#: axes (:mod:`twolink.synthesis.links_decentralized`; the paper's two-link agents do not use them).
EXTRA_SPEED_DEG = 6.0


@dataclasses.dataclass(frozen=True)
class Axis:
    """Triangular fuzzy bins over one variable.

    ``centers`` are increasing; a ``circular`` axis has period 2*pi and its last bin
    neighbours its first (the angle axes, pi == -pi); otherwise values beyond the end
    centres belong fully to the end bins.
    """

    name: str
    centers: tuple
    circular: bool = False

    def __post_init__(self):
        c = np.asarray(self.centers, dtype=float)
        if c.ndim != 1 or len(c) < 2 or not np.all(np.isfinite(c)):
            raise ValueError(f"axis {self.name}: need at least two finite centres")
        if np.any(np.diff(c) <= 0):
            raise ValueError(f"axis {self.name}: centres must increase strictly")
        if self.circular and c[-1] - c[0] >= 2 * math.pi:
            raise ValueError(f"axis {self.name}: circular centres must span less than 2*pi")
        object.__setattr__(self, "centers", tuple(float(v) for v in c))

    @property
    def size(self) -> int:
        return len(self.centers)

    def memberships(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Membership (13) of values ``v``: indices and weights of shape (..., 2).

        Each value belongs to at most two neighbouring bins; the weights sum to one.
        """
        c = np.asarray(self.centers)
        v = np.asarray(v, dtype=float)
        n = len(c)
        if self.circular:
            ext = np.append(c, c[0] + 2 * math.pi)
            v = np.mod(v - c[0], 2 * math.pi) + c[0]
            lo = np.clip(np.searchsorted(ext, v, side="right") - 1, 0, n - 1)
            w_hi = (v - ext[lo]) / (ext[lo + 1] - ext[lo])
            hi = (lo + 1) % n
        else:
            v = np.clip(v, c[0], c[-1])
            lo = np.clip(np.searchsorted(c, v, side="right") - 1, 0, n - 2)
            w_hi = (v - c[lo]) / (c[lo + 1] - c[lo])
            hi = lo + 1
        w_hi = np.clip(w_hi, 0.0, 1.0)
        return np.stack([lo, hi], -1), np.stack([1.0 - w_hi, w_hi], -1)

    def dense(self, v: np.ndarray) -> np.ndarray:
        """Memberships of ``v`` in every bin, shape (..., size) (for tests and plots)."""
        idx, w = self.memberships(v)
        out = np.zeros(np.shape(v) + (self.size,))
        np.put_along_axis(out, idx[..., :1], w[..., :1], -1)
        tmp = np.take_along_axis(out, idx[..., 1:], -1) + w[..., 1:]
        np.put_along_axis(out, idx[..., 1:], tmp, -1)
        return out

    def refined(self, k: int) -> "Axis":
        """This axis with k - 1 evenly spaced centres inserted between neighbouring centres
        (across the pi == -pi seam too when circular): 12 -> 12k angle bins, 7 -> 6k + 1
        speed bins. ``refined(1)`` is the axis itself."""
        if not isinstance(k, (int, np.integer)) or k < 1:
            raise ValueError(f"refinement factor must be a positive integer, got {k}")
        c = np.asarray(self.centers)
        ext = np.append(c, c[0] + 2 * math.pi) if self.circular else c
        pts = [ext[i] + (ext[i + 1] - ext[i]) * j / k
               for i in range(len(ext) - 1) for j in range(k)]
        if not self.circular:
            pts.append(c[-1])
        return Axis(self.name, tuple(pts), self.circular)

    def refined_size(self, k: int) -> int:
        """The number of centres of :meth:`refined` ``(k)``, computed without building it."""
        n = len(self.centers)
        return n * k if self.circular else (n - 1) * k + 1

    def as_dict(self) -> dict:
        return {"name": self.name, "centers": list(self.centers), "circular": self.circular}


def check_bins(bins: str) -> str:
    """``bins`` if it names a layout of :data:`BIN_LAYOUTS`, else a ValueError naming them."""
    if not isinstance(bins, str) or bins not in BIN_LAYOUTS:
        raise ValueError(f"unknown bin layout {bins!r}; choose one of {', '.join(BIN_LAYOUTS)}")
    return bins


def angle_axis(name: str, bins: str = "paper") -> Axis:
    """A circular angle axis with the angle centres of layout ``bins``."""
    return Axis(name, tuple(np.deg2rad(BIN_LAYOUTS[check_bins(bins)][0])), circular=True)


def speed_axis(name: str, bins: str = "paper") -> Axis:
    """A speed axis with the speed centres of layout ``bins``."""
    return Axis(name, tuple(np.deg2rad(BIN_LAYOUTS[check_bins(bins)][1])))


def torque_axis(name: str, tau_max: float, levels: int = 3) -> Axis:
    """A joint's torque levels (:func:`twolink.arm.task.action_levels`) as fuzzy bins
    (agent 1's tau2 input): -tau_max, 0, tau_max for the paper's three."""
    return Axis(name, tuple(action_levels(tau_max, levels)))


@dataclasses.dataclass(frozen=True)
class Grid:
    """Product of fuzzy axes; bin m is the C-order flat index over the axes."""

    axes: tuple

    @property
    def shape(self) -> tuple:
        return tuple(a.size for a in self.axes)

    @property
    def size(self) -> int:
        return int(np.prod(self.shape))

    @property
    def names(self) -> tuple:
        return tuple(a.name for a in self.axes)

    def centers(self) -> np.ndarray:
        """All bin centres c_m, shape (size, d), in flat-index order."""
        mesh = np.meshgrid(*[np.asarray(a.centers) for a in self.axes], indexing="ij")
        return np.stack([m.reshape(-1) for m in mesh], -1)

    def memberships(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Product memberships mu_m(x) of points (..., d): indices and weights (..., 2**d)."""
        points = np.asarray(points, dtype=float)
        d = len(self.axes)
        if points.shape[-1:] != (d,):
            raise ValueError(f"grid over {self.names} needs points of shape (..., {d}), "
                             f"got {points.shape}")
        batch = points.shape[:-1]
        flat = np.zeros(batch + (1,), dtype=np.int64)
        weight = np.ones(batch + (1,))
        for k, axis in enumerate(self.axes):
            idx, w = axis.memberships(points[..., k])
            flat = (flat[..., :, None] * axis.size + idx[..., None, :]).reshape(batch + (-1,))
            weight = (weight[..., :, None] * w[..., None, :]).reshape(batch + (-1,))
        return flat, weight

    def interpolate(self, values: np.ndarray, points: np.ndarray) -> np.ndarray:
        """Sum_m mu_m(x) values[m] for points (..., d); values of shape (size, ...) (12)/(14)."""
        idx, w = self.memberships(points)
        picked = np.asarray(values)[idx]
        return np.einsum("...k,...k->...", w, picked) if picked.ndim == w.ndim else \
            np.einsum("...k,...kj->...j", w, picked)

    def as_dict(self) -> dict:
        return {"axes": [a.as_dict() for a in self.axes]}

    @classmethod
    def from_dict(cls, data: dict) -> "Grid":
        return cls(tuple(Axis(a["name"], tuple(a["centers"]), bool(a["circular"]))
                         for a in data["axes"]))
