"""Continuous-time dynamics of the two-link arm, vectorised over a leading batch axis.

State x = [theta1, theta2, dtheta1, dtheta2], torque tau = [tau1, tau2].
Each ``*_acceleration`` function returns d(dtheta)/dt of shape (..., 2). The ``links_*``
functions are the N-link arm (x = [theta_1..theta_N, dtheta_1..dtheta_N], tau of N),
of which (6)-(9) are the two-link case.
"""
from __future__ import annotations

import numpy as np

from twolink._imports import renamed
from twolink.arm.parameters import ArmParameters, LinksParameters, as_links


def mass_matrix(p: ArmParameters, theta2: np.ndarray) -> np.ndarray:
    """M(theta) of (7), shape (..., 2, 2)."""
    c = np.cos(theta2)
    m11 = p.P1 + p.P2 + 2.0 * p.P3 * c
    m12 = p.P2 + p.P3 * c
    m22 = np.full_like(m11, p.P2)
    return np.stack([np.stack([m11, m12], -1), np.stack([m12, m22], -1)], -2)


def coriolis_forces(p: ArmParameters, x: np.ndarray) -> np.ndarray:
    """Coriolis/centrifugal part of C(theta, dtheta) dtheta in (8), shape (..., 2).

    The printed (8) has P3*dtheta2*sin(theta2) in row 2, column 1; the rigid-body
    equations (and MuJoCo, see tests/arm/test_mjcf.py) have P3*dtheta1*sin(theta2) there,
    which is what this function uses (dM/dt - 2C is then skew-symmetric).
    """
    h = p.P3 * np.sin(x[..., 1])
    d1, d2 = x[..., 2], x[..., 3]
    return np.stack([-h * (2.0 * d1 * d2 + d2 * d2), h * d1 * d1], -1)


def gravity_forces(p: ArmParameters, x: np.ndarray) -> np.ndarray:
    """G(theta) of (9) for the vertical variant, shape (..., 2)."""
    t1, t2 = x[..., 0], x[..., 1]
    s12 = np.sin(t1 + t2)
    return np.stack([-p.g1 * np.sin(t1) - p.g2 * s12, -p.g2 * s12], -1)


def full_acceleration(p: ArmParameters, x: np.ndarray, tau: np.ndarray,
                      *, gravity: bool = False) -> np.ndarray:
    """Rigid-body model (6)-(9): M ddtheta = tau - C dtheta - G.

    C is the Coriolis/centrifugal matrix plus diag(b1, b2); G = 0 for the horizontal
    arm of the paper unless ``gravity`` is set.
    """
    rhs = tau - coriolis_forces(p, x)
    rhs = rhs - np.stack([p.b1 * x[..., 2], p.b2 * x[..., 3]], -1)
    if gravity:
        rhs = rhs - gravity_forces(p, x)
    c = np.cos(x[..., 1])
    m11 = p.P1 + p.P2 + 2.0 * p.P3 * c
    m12 = p.P2 + p.P3 * c
    m22 = p.P2
    det = m11 * m22 - m12 * m12
    a1 = (m22 * rhs[..., 0] - m12 * rhs[..., 1]) / det
    a2 = (m11 * rhs[..., 1] - m12 * rhs[..., 0]) / det
    return np.stack([a1, a2], -1)


def simplified_acceleration(p: ArmParameters, x: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """Simplified model (11), exactly as printed.

    ddtheta1 = [P2 (tau1 - b1 dtheta1) - (P2 + P3 cos theta2) tau2]
               / (P2 (P1 + P2 + 2 P3 cos theta2))
    ddtheta2 = tau2 / P2 - b2 dtheta2
    """
    c = np.cos(x[..., 1])
    tau1, tau2 = tau[..., 0], tau[..., 1]
    a1 = (p.P2 * (tau1 - p.b1 * x[..., 2]) - (p.P2 + p.P3 * c) * tau2) / (
        p.P2 * (p.P1 + p.P2 + 2.0 * p.P3 * c))
    a2 = tau2 / p.P2 - p.b2 * x[..., 3]
    return np.stack([a1, a2], -1)


#: The continuous-time models by name.
MODELS = {
    "simplified": simplified_acceleration,
    "full": full_acceleration,
}


# --------------------------------------------------------------------------- N links
# The horizontal arm of N links (twolink.arm.parameters.links_parameters), of which (6)-(9) are the
# two-link case. With phi_a = theta_2 + ... + theta_a the angle of link a relative to
# link 1 (phi_1 = 0) and omega_a = dtheta_1 + ... + dtheta_a its angular speed, the
# kinetic energy is 1/2 sum_ab G_ab omega_a omega_b with
#   G_ab = W_ab cos(phi_a - phi_b) + delta_ab I_a,
#   W_ab = sum_{k >= max(a, b)} m_k r_ka r_kb,  r_ka = l_a (a < k), c_a (a = k), 0 (a > k),
# so M = L^T G L (L the lower-triangular matrix of ones: omega = L dtheta), and the
# Coriolis/centrifugal forces are L^T h with h_a = sum_b W_ab sin(phi_a - phi_b) omega_b^2.
# For two links W_11 + I_1 = P1, W_22 + I_2 = P2 and W_12 = P3 of (10).


def links_weights(c: LinksParameters) -> np.ndarray:
    """The constant N x N matrix W of the comment above: the kinetic-energy weights
    W_ab = sum_{k >= max(a, b)} m_k r_ka r_kb of the N-link arm ``c``."""
    n = c.links
    w = np.zeros((n, n))
    for k in range(n):
        r = np.array(c.lengths[:k] + (c.coms[k],))
        w[:k + 1, :k + 1] += c.masses[k] * np.outer(r, r)
    return w


def _columns(a: np.ndarray) -> list:
    """The components along the last axis of ``a`` as contiguous arrays."""
    return list(np.ascontiguousarray(np.moveaxis(a, -1, 0)))


def _relative_angles(theta: list) -> tuple:
    """cos and sin of phi_a (a = 1..N) as lists of arrays (phi_1 = 0 gives None) from
    the joint angles ``theta`` (a list of N arrays)."""
    cos, sin, phi = [None], [None], None
    for t in theta[1:]:
        phi = t if phi is None else phi + t
        # Both from the tangent of the half angle: numpy vectorises tan (SIMD) but not
        # sin and cos, so this is several times faster and exact to a few 1e-16.
        half = np.tan(0.5 * phi)
        sq = half * half
        inv = 1.0 / (1.0 + sq)
        cos.append((1.0 - sq) * inv)
        sin.append((half + half) * inv)
    return cos, sin


def _cos_diff(cos, sin, a, b):
    """cos(phi_a - phi_b) for a < b."""
    return cos[b] if a == 0 else cos[a] * cos[b] + sin[a] * sin[b]


def _sin_diff(cos, sin, a, b):
    """sin(phi_a - phi_b) for a < b."""
    return -sin[b] if a == 0 else sin[a] * cos[b] - cos[a] * sin[b]


def _mass_entries(c: LinksParameters, cos, sin, batch: tuple) -> np.ndarray:
    """M(theta) laid out as (N, N) + batch (each entry contiguous)."""
    n = c.links
    w = links_weights(c)
    g = np.empty((n, n) + batch)
    for a in range(n):
        g[a, a] = w[a, a] + c.inertias[a]
        for b in range(a + 1, n):
            g[a, b] = g[b, a] = w[a, b] * _cos_diff(cos, sin, a, b)
    # M = L^T G L: suffix sums over both link axes.
    for a in range(n - 2, -1, -1):
        g[a] += g[a + 1]
    for b in range(n - 2, -1, -1):
        g[:, b] += g[:, b + 1]
    return g


def _bias(c: LinksParameters, dtheta: list, cos, sin) -> list:
    """C(theta, dtheta) dtheta as a list of N arrays (no damping) from the joint speeds
    ``dtheta`` (a list of N arrays)."""
    n = c.links
    w = links_weights(c)
    omega2, omega = [], None
    for v in dtheta:
        omega = v if omega is None else omega + v
        omega2.append(omega * omega)
    h = [None] * n
    for a in range(n):
        for b in range(a + 1, n):
            s = w[a, b] * _sin_diff(cos, sin, a, b)
            h[a] = s * omega2[b] if h[a] is None else h[a] + s * omega2[b]
            h[b] = -s * omega2[a] if h[b] is None else h[b] - s * omega2[a]
    for a in range(n - 2, -1, -1):   # L^T h: suffix sums
        h[a] = h[a] + h[a + 1]
    return h


def _check_links_state(c: LinksParameters, x: np.ndarray, name: str = "x") -> None:
    n = c.links
    if x.ndim < 1 or x.shape[-1] != 2 * n:
        raise ValueError(f"{name} must have shape (..., {2 * n}) for a {n}-link arm "
                         f"([theta_1..theta_{n}, dtheta_1..dtheta_{n}]), got {x.shape}")


def links_mass_matrix(p: ArmParameters | LinksParameters, theta) -> np.ndarray:
    """M(theta) of the N-link arm, shape (..., N, N); (7) for two links.

    ``theta`` has shape (..., N) (the joint angles; only theta_2..theta_N matter)."""
    c = as_links(p)
    theta = np.asarray(theta, dtype=float)
    if theta.ndim < 1 or theta.shape[-1] != c.links:
        raise ValueError(f"theta must have shape (..., {c.links}) for a {c.links}-link arm, "
                         f"got {theta.shape}")
    cos, sin = _relative_angles(_columns(theta))
    m = _mass_entries(c, cos, sin, theta.shape[:-1])
    return np.ascontiguousarray(np.moveaxis(m, (0, 1), (-2, -1)))


def links_bias(p: ArmParameters | LinksParameters, x) -> np.ndarray:
    """Coriolis/centrifugal forces C(theta, dtheta) dtheta of the N-link arm, shape
    (..., N), as MuJoCo's qfrc_bias of the horizontal arm (no gravity torque, no damping);
    (8) without the damping diag(b) for two links (see :func:`coriolis_forces`)."""
    c = as_links(p)
    x = np.asarray(x, dtype=float)
    _check_links_state(c, x)
    cols = _columns(x)
    cos, sin = _relative_angles(cols[:c.links])
    return np.stack(_bias(c, cols[c.links:], cos, sin), -1)


def _check_locked(locked, n: int) -> list:
    """The indices of the free joints for ``locked`` (None or N booleans)."""
    if locked is None:
        return list(range(n))
    flags = list(locked) if not isinstance(locked, (str, bytes)) else None
    if flags is None or len(flags) != n or \
            not all(isinstance(f, (bool, np.bool_)) for f in flags):
        raise ValueError(f"locked must be a sequence of {n} booleans (one per joint), "
                         f"got {locked!r}")
    free = [k for k, f in enumerate(flags) if not f]
    if not free:
        raise ValueError("locked holds every joint; at least one joint must be free")
    return free


def links_acceleration(p: ArmParameters | LinksParameters, x, tau, *,
                       locked=None) -> np.ndarray:
    """ddtheta of the N-link horizontal arm, shape (..., N): M ddtheta = tau - C dtheta
    - diag(b) dtheta, the N-link form of (6)-(9) (G = 0: the arm is horizontal).

    ``x`` has shape (..., 2N), ``tau`` (..., N) (broadcast against each other).
    ``locked`` (N booleans) holds joints fixed: their ddtheta is 0 and they leave the
    solve, which becomes M_uu ddtheta_u = rhs_u over the free joints u.
    """
    c = as_links(p)
    n = c.links
    x = np.asarray(x, dtype=float)
    tau = np.asarray(tau, dtype=float)
    _check_links_state(c, x)
    if tau.ndim < 1 or tau.shape[-1] != n:
        raise ValueError(f"tau must have shape (..., {n}) for a {n}-link arm, "
                         f"got {tau.shape}")
    free = _check_locked(locked, n)
    try:
        batch = np.broadcast_shapes(x.shape[:-1], tau.shape[:-1])
    except ValueError:
        raise ValueError(f"x of shape {x.shape} and tau of shape {tau.shape} do not "
                         f"broadcast") from None
    cols = _columns(x)
    cos, sin = _relative_angles(cols[:n])
    m = _mass_entries(c, cos, sin, x.shape[:-1])
    bias = _bias(c, cols[n:], cos, sin)
    torque = list(np.moveaxis(tau, -1, 0))
    rhs = [torque[k] - bias[k] - c.dampings[k] * cols[n + k] for k in free]
    # LDL^T of M_uu (symmetric positive definite) in place, a loop over the free joints.
    u = len(free)
    low = [[m[free[i], free[j]] for j in range(u)] for i in range(u)]
    scaled = [[None] * u for _ in range(u)]      # low[i][k] * diag[k]
    diag = [None] * u
    for j in range(u):
        d = low[j][j]
        for k in range(j):
            d -= scaled[j][k] * low[j][k]
        diag[j] = low[j][j] = d
        for i in range(j + 1, u):
            v = low[i][j]
            for k in range(j):
                v -= scaled[i][k] * low[j][k]
            scaled[i][j] = v     # (a scalar when the batch is empty)
            low[i][j] = v / d
    z = [np.broadcast_to(r, batch).copy() for r in rhs]
    for i in range(u):
        for k in range(i):
            z[i] -= low[i][k] * z[k]
    for i in range(u):
        z[i] /= diag[i]
    for i in range(u - 1, -1, -1):
        for k in range(i + 1, u):
            z[i] -= low[k][i] * z[k]
    zero = np.zeros(batch)
    out = [zero] * n
    for i, k in enumerate(free):
        out[k] = z[i]
    return np.stack(out, -1)


#: The names of 0.1 that said *chain*, kept until the next release (with a
#: DeprecationWarning; twolink._imports.renamed).
__getattr__ = renamed(__name__, {
    "chain_weights": "links_weights", "chain_mass_matrix": "links_mass_matrix",
    "chain_bias": "links_bias", "chain_acceleration": "links_acceleration"
})
