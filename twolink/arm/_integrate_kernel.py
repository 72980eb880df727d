"""Compiled RK4 over many (state, torque) pairs, for :func:`twolink.arm.integrate.sample_step_compiled`.

A module of its own so that importing :mod:`twolink.arm.integrate` does not load numba.
"""
from __future__ import annotations

import numpy as np

from twolink._numba import njit

_jit = njit(__file__)


@_jit
def accel(model, P1, P2, P3, b1, b2, s, t1, t2, out, stage, mask1, mask2, masked):
    """d/dt of s into out[stage]: [dtheta, ddtheta] of (11) (model 0) or (6)-(8) (model 1),
    in the operation order of ``dynamics.simplified_acceleration`` / ``full_acceleration``."""
    d1, d2 = s[2], s[3]
    if model == 0:
        c = np.cos(s[1])
        a1 = (P2 * (t1 - b1 * d1) - (P2 + P3 * c) * t2) / (P2 * (P1 + P2 + 2.0 * P3 * c))
        a2 = t2 / P2 - b2 * d2
    else:
        h = P3 * np.sin(s[1])
        r1 = t1 - -h * (2.0 * d1 * d2 + d2 * d2)
        r2 = t2 - h * d1 * d1
        r1 = r1 - b1 * d1
        r2 = r2 - b2 * d2
        c = np.cos(s[1])
        m11 = P1 + P2 + 2.0 * P3 * c
        m12 = P2 + P3 * c
        det = m11 * P2 - m12 * m12
        a1 = (P2 * r1 - m12 * r2) / det
        a2 = (m11 * r2 - m12 * r1) / det
    if masked:
        a1 = a1 * mask1
        a2 = a2 * mask2
    out[stage, 0] = d1
    out[stage, 1] = d2
    out[stage, 2] = a1
    out[stage, 3] = a2


@_jit
def rk4_pairs(xs, us, model, P1, P2, P3, b1, b2, tau1_max, tau2_max, v1_max, v2_max,
               ts, substeps, mask1, mask2, masked, out):
    h = ts / substeps
    half = 0.5 * h
    sixth = h / 6.0
    two_pi = 2.0 * np.pi
    x = np.empty(4)
    s = np.empty(4)
    k = np.empty((4, 4))
    for i in range(xs.shape[0]):
        t1 = min(max(us[i, 0], -tau1_max), tau1_max)
        t2 = min(max(us[i, 1], -tau2_max), tau2_max)
        for c in range(4):
            x[c] = xs[i, c]
        for _ in range(substeps):
            accel(model, P1, P2, P3, b1, b2, x, t1, t2, k, 0, mask1, mask2, masked)
            for c in range(4):
                s[c] = x[c] + half * k[0, c]
            accel(model, P1, P2, P3, b1, b2, s, t1, t2, k, 1, mask1, mask2, masked)
            for c in range(4):
                s[c] = x[c] + half * k[1, c]
            accel(model, P1, P2, P3, b1, b2, s, t1, t2, k, 2, mask1, mask2, masked)
            for c in range(4):
                s[c] = x[c] + h * k[2, c]
            accel(model, P1, P2, P3, b1, b2, s, t1, t2, k, 3, mask1, mask2, masked)
            for c in range(4):
                x[c] = x[c] + sixth * (k[0, c] + 2.0 * k[1, c] + 2.0 * k[2, c] + k[3, c])
        out[i, 0] = np.mod(x[0] + np.pi, two_pi) - np.pi
        out[i, 1] = np.mod(x[1] + np.pi, two_pi) - np.pi
        out[i, 2] = min(max(x[2], -v1_max), v1_max)
        out[i, 3] = min(max(x[3], -v2_max), v2_max)
