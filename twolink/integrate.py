"""Sampling the continuous-time models over one period Ts (zero-order hold, RK4).

The conventions of SPEC.md: torques clipped to +-tau_max and held over Ts; fixed-step
RK4 substeps inside Ts; at the end of every Ts the angles wrap to [-pi, pi) and the
speeds saturate at +-dtheta_max.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np

from twolink.parameters import TS, ArmParameters

#: RK4 substeps per sample period used by every numpy plant (see README, integration error).
SUBSTEPS = 10

Acceleration = Callable[[ArmParameters, np.ndarray, np.ndarray], np.ndarray]


def wrap_angle(a):
    """Wrap angles to [-pi, pi)."""
    return np.mod(np.asarray(a, dtype=float) + math.pi, 2.0 * math.pi) - math.pi


def finish_sample(p: ArmParameters, x: np.ndarray, *, speed_max=None) -> np.ndarray:
    """Wrap the angles and saturate the speeds at the end of a sample period.

    ``speed_max`` (broadcastable to x[..., 2:], e.g. one row per perturbed plant)
    overrides ``p.speed_max``.
    """
    out = np.empty_like(x)
    out[..., :2] = wrap_angle(x[..., :2])
    vmax = p.speed_max if speed_max is None else speed_max
    out[..., 2:] = np.clip(x[..., 2:], -vmax, vmax)
    return out


def rk4(accel: Acceleration, p: ArmParameters, x: np.ndarray, tau: np.ndarray,
        duration: float, substeps: int) -> np.ndarray:
    """Integrate dx/dt = [dtheta, accel(x, tau)] over ``duration`` with RK4 substeps."""
    h = duration / substeps

    def f(s):
        return np.concatenate([s[..., 2:], accel(p, s, tau)], -1)

    for _ in range(substeps):
        k1 = f(x)
        k2 = f(x + 0.5 * h * k1)
        k3 = f(x + 0.5 * h * k2)
        k4 = f(x + h * k3)
        x = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return x


def sample_step(accel: Acceleration, p: ArmParameters, x: np.ndarray, tau: np.ndarray,
                *, ts: float = TS, substeps: int = SUBSTEPS) -> np.ndarray:
    """x_{k+1} = f(x_k, u_k): one sample period of a model, batched over leading axes."""
    x = np.asarray(x, dtype=float)
    tau = np.clip(np.asarray(tau, dtype=float), -p.tau_max, p.tau_max)
    batch = np.broadcast_shapes(x.shape[:-1], tau.shape[:-1])
    x = np.broadcast_to(x, batch + (4,))
    tau = np.broadcast_to(tau, batch + (2,))
    return finish_sample(p, rk4(accel, p, x, tau, ts, substeps))


def integration_error(accel: Acceleration, p: ArmParameters, x: np.ndarray, tau: np.ndarray,
                      *, substeps: int = SUBSTEPS, reference_substeps: int = 1000) -> dict:
    """Error of one sample period with ``substeps`` against a much finer RK4 reference.

    Returned per component as the max and RMS absolute difference over the batch
    (angles compared after wrapping the difference).
    """
    a = sample_step(accel, p, x, tau, substeps=substeps)
    b = sample_step(accel, p, x, tau, substeps=reference_substeps)
    d = a - b
    d[..., :2] = wrap_angle(d[..., :2])
    d = np.abs(d).reshape(-1, 4)
    return {"substeps": substeps, "reference_substeps": reference_substeps,
            "max": d.max(0).tolist(), "rms": np.sqrt((d**2).mean(0)).tolist()}
