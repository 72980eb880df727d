"""Fuzzy Q-iteration, Alg. 1 of the paper.

Q_{l+1}(m, u) = rho(c_m, u) + gamma * sum_m~ mu_m~(f(c_m, u)) max_u~ Q_l(m~, u~)

The transitions f(c_m, u_j) of every (bin centre, action) pair are computed once and
stored as a sparse membership matrix T of shape (N_X * N_U, N_X); each synchronous
sweep is then one sparse matrix-vector product. ``tests/reference_fqi.py`` holds the
plain loop of Alg. 1 this is checked against.
"""
from __future__ import annotations

import dataclasses
import time
from typing import Callable, Optional

import numpy as np
import scipy.sparse as sp

from twolink.fuzzy import Grid
from twolink.parameters import DELTA, GAMMA


def transition_matrix(grid: Grid, next_points: np.ndarray) -> sp.csr_matrix:
    """Sparse T with T[m * N_U + j, m~] = mu_m~(f(c_m, u_j)).

    ``next_points`` has shape (N_X, N_U, d): the state reached from each bin centre
    under each action, already in the grid's coordinates.
    """
    n_x, n_u, d = next_points.shape
    if n_x != grid.size or d != len(grid.axes):
        raise ValueError(f"next_points of shape {next_points.shape} do not match a grid "
                         f"of {grid.size} bins over {len(grid.axes)} dimensions")
    idx, w = grid.memberships(next_points.reshape(n_x * n_u, d))
    k = idx.shape[1]
    indptr = np.arange(0, n_x * n_u * k + 1, k)
    t = sp.csr_matrix((w.reshape(-1), idx.reshape(-1), indptr), shape=(n_x * n_u, n_x))
    t.sum_duplicates()
    t.eliminate_zeros()
    return t


@dataclasses.dataclass
class QIterationResult:
    """Outcome of Alg. 1: Q of shape (N_X, N_U), sweeps done, the change per sweep."""

    q: np.ndarray
    iterations: int
    history: np.ndarray
    converged: bool
    seconds: float


def fuzzy_q_iteration(transitions: sp.csr_matrix, rewards: np.ndarray, *,
                      gamma: float = GAMMA, delta: float = DELTA, max_iterations: int = 10000,
                      min_iterations: int = 0,
                      callback: Optional[Callable[[int, float], None]] = None
                      ) -> QIterationResult:
    """Synchronous sweeps of Alg. 1 from Q_0 = 0 until max|Q_l - Q_{l-1}| <= delta.

    ``rewards`` has shape (N_X, N_U): rho(c_m, u_j). ``min_iterations`` forces at least
    that many sweeps (for benchmarks doing equal work); ``callback(l, change)`` is
    called after each sweep.
    """
    rewards = np.asarray(rewards, dtype=float)
    n_x, n_u = rewards.shape
    if transitions.shape != (n_x * n_u, n_x):
        raise ValueError(f"transition matrix of shape {transitions.shape} does not match "
                         f"rewards of shape {rewards.shape}")
    if not (0.0 < gamma < 1.0):
        raise ValueError(f"gamma must lie in (0, 1), got {gamma}")
    if not delta > 0.0:
        raise ValueError(f"delta must be positive, got {delta}")
    start = time.perf_counter()
    r = rewards.reshape(-1)
    q = np.zeros(n_x * n_u)
    q_new = np.empty_like(q)
    diff = np.empty_like(q)
    v = np.empty(n_x)
    history = []
    converged = False
    iterations = 0
    while iterations < max_iterations:
        _row_max(q.reshape(n_x, n_u), v)
        np.multiply(transitions @ v, gamma, out=q_new)
        q_new += r
        np.subtract(q_new, q, out=diff)
        change = float(np.abs(diff, out=diff).max())
        q, q_new = q_new, q
        iterations += 1
        history.append(change)
        if callback is not None:
            callback(iterations, change)
        if change <= delta and iterations >= min_iterations:
            converged = True
            break
    return QIterationResult(q.reshape(n_x, n_u), iterations, np.asarray(history),
                            converged, time.perf_counter() - start)


def _row_max(q: np.ndarray, out: np.ndarray) -> np.ndarray:
    """max over actions of Q (N_X, N_U) into ``out`` (N_X,), as N_U column-wise maxima:
    several times faster than ``q.max(axis=1)`` over a short last axis."""
    np.copyto(out, q[:, 0])
    for j in range(1, q.shape[1]):
        np.maximum(out, q[:, j], out=out)
    return out
