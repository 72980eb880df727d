"""Sampling the continuous-time models over one period Ts (zero-order hold, RK4).

The conventions of docs/conventions.md: torques clipped to +-tau_max and held over Ts; fixed-step
RK4 substeps inside Ts; at the end of every Ts the angles wrap to [-pi, pi) and the
speeds saturate at +-dtheta_max. States are (..., 2N) and torques (..., N) for an arm of
N = ``p.links`` links (N = 2: the paper's arm).
"""
from __future__ import annotations

import functools
import math
from typing import Callable

import numpy as np

from twolink.arm.parameters import TS, ArmParameters, LinksParameters, as_links

#: RK4 substeps per sample period used by every numpy plant (see README, integration error).
SUBSTEPS = 10

#: A two-link arm (Table I) or an arm of N links: anything with ``links``, ``tau_max`` and
#: ``speed_max``.
Parameters = ArmParameters | LinksParameters
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
    if isinstance(p, LinksParameters):
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


# --------------------------------------------------------------------------- stability
#: RK4's stability limit on the negative real axis: a mode dx/dt = -lambda x stays bounded
#: under RK4 substeps of length h only while h * lambda is below this (2.7853).
RK4_LIMIT = 2.785
#: MuJoCo compiles no moving body lighter than this (its mjMINVAL; kg and kg m^2).
MUJOCO_MIN_MASS = 1e-15


def _check_poses(links: int) -> np.ndarray:
    """Joint angles at which :func:`sampling_rate` evaluates M(theta) of an arm of three or
    more links: every joint at 0 or pi, and 64 fixed random poses."""
    corners = np.array(np.meshgrid(*[[0.0, math.pi]] * links)).reshape(links, -1).T
    rng = np.random.default_rng(0)
    return np.concatenate([corners, rng.uniform(-math.pi, math.pi, (64, links))])


def sampling_rate(p: Parameters) -> tuple[float, int]:
    """(lambda, k): the fastest rate (1/s) of the damped arm's linear part, the largest
    eigenvalue of M(theta)^-1 diag(b) (two links: over theta2 on a fine circle, in closed
    form; more: over the poses of :func:`_check_poses`), and the link whose joint alone
    (the others free) is fastest, b_k (M^-1)_kk. Infinity (and the lightest link) where
    M(theta) is singular or not finite. Cached per parameter set."""
    return _sampling_rate(as_links(p))


@functools.lru_cache(maxsize=1024)
def _sampling_rate(c: LinksParameters) -> tuple[float, int]:
    lightest = int(np.argmin(np.asarray(c.masses) + np.asarray(c.inertias))) + 1
    with np.errstate(all="ignore"):
        if c.links == 2:
            a = c.as_arm()
            cos = np.cos(np.linspace(-math.pi, math.pi, 129))
            m11, m12, m22 = a.P1 + a.P2 + 2.0 * a.P3 * cos, a.P2 + a.P3 * cos, a.P2
            det = m11 * m22 - m12 * m12
            tr = (m22 * a.b1 + m11 * a.b2) / det
            rates = tr / 2.0 + np.sqrt(np.maximum(tr * tr / 4.0 - a.b1 * a.b2 / det, 0.0))
            joint = np.array([(a.b1 * m22 / det).max(), (a.b2 * m11 / det).max()])
            if not (np.all(det > 0) and np.all(np.isfinite(rates))):
                return math.inf, lightest
            return float(rates.max()), int(np.argmax(joint)) + 1
        from twolink.arm import dynamics

        b = np.sqrt(np.asarray(c.dampings))
        m = dynamics.links_mass_matrix(c, _check_poses(c.links))
        try:
            if not np.all(np.isfinite(m)):
                raise np.linalg.LinAlgError
            np.linalg.cholesky(m)
            inv = np.linalg.inv(m)
            rates = np.linalg.eigvalsh(b[:, None] * inv * b[None, :])
        except np.linalg.LinAlgError:
            return math.inf, lightest
    if not np.all(np.isfinite(rates)):
        return math.inf, lightest
    joint = np.asarray(c.dampings) * np.diagonal(inv, axis1=-2, axis2=-1).max(0)
    return float(rates.max()), int(np.argmax(joint)) + 1


def check_masses(p: Parameters) -> None:
    """A ValueError naming the link if a link's mass or inertia is under
    :data:`MUJOCO_MIN_MASS`: an all but massless link, which no plant simulates (MuJoCo
    refuses to compile it, the models divide by zero)."""
    c = as_links(p)
    for k, (mass, inertia) in enumerate(zip(c.masses, c.inertias), 1):
        if mass < MUJOCO_MIN_MASS or inertia < MUJOCO_MIN_MASS:
            raise ValueError(f"link {k} is all but massless (mass {mass:g} kg, inertia "
                             f"{inertia:g} kg m^2; at least {MUJOCO_MIN_MASS:g} each): no "
                             f"plant simulates it")


def check_sampling(p: Parameters, *, ts: float = TS, substeps: int = SUBSTEPS) -> None:
    """A ValueError unless the full model (6) (N links: its rigid-body generalisation) with
    parameters ``p`` stays bounded under RK4 substeps of ts / substeps, the integration of
    every numpy plant and of MuJoCo: the substep times :func:`sampling_rate` below
    :data:`RK4_LIMIT`. A link too light for its damping (its inertia over its damping far
    under the substep) fails it; so does a mass matrix that is singular in floating point."""
    c = as_links(p)
    check_masses(c)
    rate, k = sampling_rate(c)
    h = ts / substeps
    if not rate * h < RK4_LIMIT:
        what = "its mass matrix M(theta) is singular" if math.isinf(rate) else (
            f"the damped arm's fastest rate, {rate:.3g} 1/s (M(theta)^-1 diag(b)), times "
            f"the RK4 substep of {h * 1e3:g} ms is {rate * h:.3g}")
        raise ValueError(f"link {k} is too light for its damping (mass {c.masses[k - 1]:g} "
                         f"kg, inertia {c.inertias[k - 1]:g} kg m^2, damping "
                         f"{c.dampings[k - 1]:g}): {what}, over RK4's stability limit "
                         f"{RK4_LIMIT}, so the full model (6) and MuJoCo diverge")
