"""A plain reference for fuzzy Q-iteration (Alg. 1), written apart from the fast path.

Memberships come straight from (13) as printed (no searchsorted, no sparse products), and
the sweep is the loop of Alg. 1 over m, u_j and m~. Slow; for tests only, as mujoco keeps
``py_rollout`` beside ``rollout_test.py``.
"""
from __future__ import annotations

import math

import numpy as np


def axis_memberships(centers, circular: bool, v: float) -> list[float]:
    """mu_n(v) of (13) for every bin n of one axis.

    A clamped axis has shoulders at its ends (values beyond the end centres belong fully
    to the end bins). A circular axis (period 2*pi) is (13) on the centres followed by the
    first centre again, 2*pi on, whose membership goes back to the first bin.
    """
    c = [float(x) for x in centers]
    if circular:
        v = c[0] + math.fmod(v - c[0], 2 * math.pi)
        if v < c[0]:
            v += 2 * math.pi
        ext = c + [c[0] + 2 * math.pi]
        mu = [_triangle(ext, n, v) for n in range(len(ext))]
        mu[0] += mu.pop()
        return mu
    v = min(max(v, c[0]), c[-1])
    return [_triangle(c, n, v) for n in range(len(c))]


def _triangle(c, n, v):
    """(13) as printed: max(0, min((v - c[n-1]) / (c[n] - c[n-1]), (c[n+1] - v) / (c[n+1] - c[n])))
    with one-sided triangles at the ends."""
    rising = 1.0 if n == 0 else (v - c[n - 1]) / (c[n] - c[n - 1])
    falling = 1.0 if n == len(c) - 1 else (c[n + 1] - v) / (c[n + 1] - c[n])
    return max(0.0, min(rising, falling, 1.0))


def dense_memberships(grid, point) -> np.ndarray:
    """mu_m(point) for every bin m of ``grid`` (C order over its axes): products of (13)."""
    mu = [1.0]
    for axis, v in zip(grid.axes, point):
        one = axis_memberships(axis.centers, axis.circular, float(v))
        mu = [a * b for a in mu for b in one]
    return np.array(mu)


def fuzzy_q_iteration_reference(grid, next_points, rewards, *, gamma: float = 0.98,
                                delta: float = 0.01, max_iterations: int = 10000):
    """Alg. 1 as printed: Q_{l+1}(m, u) = rho(c_m, u) + gamma sum_m~ mu_m~(f(c_m, u))
    max_u~ Q_l(m~, u~), synchronous sweeps from Q_0 = 0, stopping at max |change| <= delta.
    Returns (Q, sweeps)."""
    n_x, n_u = rewards.shape
    # mu_m~(f(c_m, u_j)), kept as the (m~, weight) pairs where it is not zero
    mu = [[[(m_t, w) for m_t, w in enumerate(dense_memberships(grid, next_points[m, j])) if w]
           for j in range(n_u)] for m in range(n_x)]
    q = [[0.0] * n_u for _ in range(n_x)]
    ell = 0
    while True:
        q_next = [[0.0] * n_u for _ in range(n_x)]
        for m in range(n_x):
            for j in range(n_u):
                total = 0.0
                for m_t, w in mu[m][j]:
                    total += w * max(q[m_t])
                q_next[m][j] = float(rewards[m, j]) + gamma * total
        ell += 1
        change = max(abs(a - b) for row_a, row_b in zip(q_next, q) for a, b in zip(row_a, row_b))
        q = q_next
        if change <= delta or ell >= max_iterations:
            return np.array(q), ell


def fuzzy_q_iteration_serial_reference(grid, next_points, rewards, *, gamma: float = 0.98,
                                       delta: float = 0.01, max_iterations: int = 10000):
    """Alg. 1 with serial (in-place) sweeps, as ApproxRL's ``fuzzyqi.m`` 'serial' option:
    the bins in Matlab's linear order over the grid (first index fastest), the actions
    inner, every Q(m, u) overwritten at once and read back through max_u~ Q(m~, u~) by
    the updates after it. Returns (Q, sweeps)."""
    n_x, n_u = rewards.shape
    shape = [a.size for a in grid.axes]
    strides = [int(np.prod(shape[i + 1:])) for i in range(len(shape))]   # C-order bin index
    order = []
    for linear in range(n_x):                                            # Matlab's ind2sub
        rest, m = linear, 0
        for size, stride in zip(shape, strides):
            m += (rest % size) * stride
            rest //= size
        order.append(m)
    mu = [[[(m_t, w) for m_t, w in enumerate(dense_memberships(grid, next_points[m, j])) if w]
           for j in range(n_u)] for m in range(n_x)]
    q = [[0.0] * n_u for _ in range(n_x)]
    ell = 0
    while True:
        change = 0.0
        for m in order:
            for j in range(n_u):
                total = 0.0
                for m_t, w in mu[m][j]:
                    total += w * max(q[m_t])
                new = float(rewards[m, j]) + gamma * total
                change = max(change, abs(new - q[m][j]))
                q[m][j] = new
        ell += 1
        if change <= delta or ell >= max_iterations:
            return np.array(q), ell


def fuzzy_q_iteration_scipy(transitions, rewards, *, gamma: float = 0.98, delta: float = 0.01,
                            max_iterations: int = 10000):
    """Synchronous sweeps as numpy passes over a scipy CSR T (the package's first fast path,
    kept as the reference the compiled sweeps are held against bit for bit):
    V = max_u Q, Q' = gamma (T @ V) + rho, change = max |Q' - Q|. Returns (Q, sweeps, history)."""
    n_x, n_u = rewards.shape
    r = np.asarray(rewards, dtype=float).reshape(-1)
    q = np.zeros(n_x * n_u)
    history = []
    while len(history) < max_iterations:
        v = q.reshape(n_x, n_u).max(axis=1)
        q_new = np.multiply(transitions @ v, gamma)
        q_new += r
        history.append(float(np.abs(q_new - q).max()))
        q = q_new
        if history[-1] <= delta:
            break
    return q.reshape(n_x, n_u), len(history), np.array(history)


def fuzzy_q_iteration_robust_reference(transitions, rewards, *, mode: str, gamma: float = 0.98,
                                       delta: float = 0.01, max_iterations: int = 10000):
    """Synchronous sweeps over K models in numpy: Q' = min_k or mean_k (rho_k + gamma T_k V),
    each T_k a scipy matrix. Returns (Q, sweeps)."""
    n_x, n_u = rewards[0].shape
    q = np.zeros((n_x, n_u))
    for ell in range(1, max_iterations + 1):
        v = q.max(axis=1)
        per_model = np.stack([np.asarray(r, dtype=float) + gamma * (t @ v).reshape(n_x, n_u)
                              for t, r in zip(transitions, rewards)])
        q_new = per_model.min(axis=0) if mode == "worst" else per_model.sum(axis=0) / len(rewards)
        change = np.abs(q_new - q).max()
        q = q_new
        if change <= delta:
            break
    return q, ell
