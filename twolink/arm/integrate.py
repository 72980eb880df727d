"""Sampling the continuous-time models over one period Ts (zero-order hold, RK4).

The conventions of docs/conventions.md: torques clipped to +-tau_max and held over Ts; fixed-step
RK4 substeps inside Ts; at the end of every Ts the angles wrap to [-pi, pi) and the
speeds saturate at +-dtheta_max. States are (..., 2N) and torques (..., N) for an arm of
N = ``p.links`` links (N = 2: the paper's arm).
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np

from twolink.arm.parameters import TS, ArmParameters, ChainParameters

#: RK4 substeps per sample period used by every numpy plant (see README, integration error).
SUBSTEPS = 10

#: A two-link arm (Table I) or an N-link chain: anything with ``links``, ``tau_max`` and
#: ``speed_max``.
Parameters = ArmParameters | ChainParameters
Acceleration = Callable[[Parameters, np.ndarray, np.ndarray], np.ndarray]


def wrap_angle(a):
    """Wrap angles to [-pi, pi)."""
    return np.mod(np.asarray(a, dtype=float) + math.pi, 2.0 * math.pi) - math.pi


def finish_sample(p: Parameters, x: np.ndarray, *, speed_max=None) -> np.ndarray:
    """Wrap the angles and saturate the speeds at the end of a sample period.

    ``x`` has shape (..., 2N) with N = ``p.links``. ``speed_max`` (broadcastable to
    x[..., N:], e.g. one row per perturbed plant) overrides ``p.speed_max``.
    """
    n = p.links
    out = np.empty_like(x)
    out[..., :n] = wrap_angle(x[..., :n])
    vmax = p.speed_max if speed_max is None else speed_max
    out[..., n:] = np.clip(x[..., n:], -vmax, vmax)
    return out


def rk4(accel: Acceleration, p: Parameters, x: np.ndarray, tau: np.ndarray,
        duration: float, substeps: int) -> np.ndarray:
    """Integrate dx/dt = [dtheta, accel(x, tau)] over ``duration`` with RK4 substeps
    (x of shape (..., 2N), N = ``p.links``)."""
    h = duration / substeps
    n = p.links

    def f(s):
        return np.concatenate([s[..., n:], accel(p, s, tau)], -1)

    for _ in range(substeps):
        k1 = f(x)
        k2 = f(x + 0.5 * h * k1)
        k3 = f(x + 0.5 * h * k2)
        k4 = f(x + h * k3)
        x = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return x


def _check_shapes(p: Parameters, x: np.ndarray, tau: np.ndarray) -> tuple:
    """The common batch shape of states (..., 2N) and torques (..., N), N = ``p.links``."""
    n = p.links
    if x.ndim < 1 or x.shape[-1] != 2 * n:
        raise ValueError(f"states must have shape (..., {2 * n}) for a {n}-link arm, "
                         f"got {x.shape}")
    if tau.ndim < 1 or tau.shape[-1] != n:
        raise ValueError(f"torques must have shape (..., {n}) for a {n}-link arm, "
                         f"got {tau.shape}")
    try:
        return np.broadcast_shapes(x.shape[:-1], tau.shape[:-1])
    except ValueError:
        raise ValueError(f"states of shape {x.shape} and torques of shape {tau.shape} "
                         f"do not broadcast") from None


def sample_step(accel: Acceleration, p: Parameters, x: np.ndarray, tau: np.ndarray,
                *, ts: float = TS, substeps: int = SUBSTEPS) -> np.ndarray:
    """x_{k+1} = f(x_k, u_k): one sample period of a model, batched over leading axes:
    states (..., 2N), torques (..., N), N = ``p.links``."""
    x = np.asarray(x, dtype=float)
    tau = np.asarray(tau, dtype=float)
    batch = _check_shapes(p, x, tau)
    tau = np.clip(tau, -p.tau_max, p.tau_max)
    n = p.links
    x = np.broadcast_to(x, batch + (2 * n,))
    tau = np.broadcast_to(tau, batch + (n,))
    return finish_sample(p, rk4(accel, p, x, tau, ts, substeps))


def integration_error(accel: Acceleration, p: Parameters, x: np.ndarray, tau: np.ndarray,
                      *, substeps: int = SUBSTEPS, reference_substeps: int = 1000) -> dict:
    """Error of one sample period with ``substeps`` against a much finer RK4 reference.

    Returned per component as the max and RMS absolute difference over the batch
    (angles compared after wrapping the difference).
    """
    a = sample_step(accel, p, x, tau, substeps=substeps)
    b = sample_step(accel, p, x, tau, substeps=reference_substeps)
    n = p.links
    d = a - b
    d[..., :n] = wrap_angle(d[..., :n])
    d = np.abs(d).reshape(-1, 2 * n)
    return {"substeps": substeps, "reference_substeps": reference_substeps,
            "max": d.max(0).tolist(), "rms": np.sqrt((d**2).mean(0)).tolist()}


# --------------------------------------------------------------------------- compiled
#: The models :func:`sample_step_compiled` knows, by the names of ``dynamics.MODELS``.
COMPILED_MODELS = ("simplified", "full")


def sample_step_compiled(model: str, p: ArmParameters, x: np.ndarray, tau: np.ndarray, *,
                         ts: float = TS, substeps: int = SUBSTEPS,
                         freeze_link2: bool = False) -> np.ndarray:
    """:func:`sample_step` of ``dynamics.MODELS[model]`` (the horizontal arm) compiled:
    one pass per (state, torque) pair, the same operations in the same order, so equal to
    the numpy path bit for bit where libm's sin and cos are numpy's (tests hold it to it).

    ``freeze_link2`` multiplies the accelerations by [1, 0] (link 2 held, as agent 1's
    frozen context does).
    """
    if model not in COMPILED_MODELS:
        raise ValueError(f"no compiled model {model!r}; choose one of {', '.join(COMPILED_MODELS)}")
    if p.links != 2:
        raise ValueError(f"the compiled step is for two links; use sample_step for a "
                         f"{p.links}-link arm")
    if isinstance(p, ChainParameters):
        p = p.as_arm()
    if not isinstance(substeps, (int, np.integer)) or substeps < 1:
        raise ValueError(f"substeps must be a positive integer, got {substeps}")
    x = np.asarray(x, dtype=float)
    tau = np.asarray(tau, dtype=float)
    batch = np.broadcast_shapes(x.shape[:-1], tau.shape[:-1])
    xs = np.ascontiguousarray(np.broadcast_to(x, batch + (4,))).reshape(-1, 4)
    us = np.ascontiguousarray(np.broadcast_to(tau, batch + (2,))).reshape(-1, 2)
    from twolink.arm import (
        _integrate_kernel as integrate_kernel,  # numba loads on first use, not on import
    )

    out = np.empty_like(xs)
    integrate_kernel.rk4_pairs(
        xs, us, COMPILED_MODELS.index(model), float(p.P1), float(p.P2), float(p.P3),
        float(p.b1), float(p.b2), float(p.tau1_max), float(p.tau2_max),
        float(p.dtheta1_max), float(p.dtheta2_max), float(ts), int(substeps),
        1.0, 0.0 if freeze_link2 else 1.0, freeze_link2, out)
    return out.reshape(batch + (4,))
