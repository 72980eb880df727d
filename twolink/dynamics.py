"""Continuous-time dynamics of the two-link arm, vectorised over a leading batch axis.

State x = [theta1, theta2, dtheta1, dtheta2], torque tau = [tau1, tau2].
Each ``*_acceleration`` function returns d(dtheta)/dt of shape (..., 2).
"""
from __future__ import annotations

import numpy as np

from twolink.parameters import ArmParameters


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
    equations (and MuJoCo, see tests/test_mjcf.py) have P3*dtheta1*sin(theta2) there,
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
