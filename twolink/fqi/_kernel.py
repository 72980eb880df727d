"""Compiled sweeps of fuzzy Q-iteration (Alg. 1) over a fixed-width transition table.

T is held as ``index`` (rows, K) int32 and ``weight`` (rows, K) float64, row
m * N_U + j listing the bins m~ with mu_m~(f(c_m, u_j)) > 0 in increasing order and
padded with zero weights: every row of (12)-(13) has at most 2**d memberships, so no
row pointers are needed. Each row is summed in index order from 0.0, as scipy's CSR
product sums a canonical matrix, so the sweeps give the scipy path's Q bit for bit.
``weight`` may also be float32 (numba compiles the kernels once per precision): each
product is then float64(w) * V and the sum stays float64 in index order, so Q differs
from the reference by the weights' round-off only.

The sums stay in index order (the scipy path's order): on the paper's centralized problem
a sweep is bound by the instructions per entry (three loads: index, weight, gathered V; a
multiply, an add), so reordering them buys nothing; fewer entries per Q-value do, which
is why the centralized synthesis reads T factored along theta1
(:mod:`twolink.fqi._factored_kernel`). The gathered V is subscripted with unsigned
integers (the table's indices are checked to lie in [0, N_X) before any sweep), so numba
emits no negative-index test per entry. docs/performance.md has the measurements.

The ``*_sweeps`` kernels run ``sweeps`` sweeps (or stop at max |change| <= delta once
``min_done`` sweeps are done) and write each sweep's change into ``history``; they return
the number done. Callers loop over calls to report progress between them. The ``*_rows``
kernels run one sweep over a range of bins, for threads sharing a sweep.
"""
from __future__ import annotations

import numpy as np
from numba import uint64 as _u

from twolink._numba import cache_wanted, njit

#: Whether the kernels' compiled code is cached (see :mod:`twolink._numba`).
CACHE = cache_wanted(__file__)
_jit = njit(__file__)


@_jit
def synchronous_rows(index, weight, rewards, q, q_next, v, v_next, gamma, m_start, m_stop):
    """One synchronous sweep of the bins [m_start, m_stop): Q'(m, j) = rho + gamma
    sum_k w V(idx) into ``q_next``, max_j Q'(m, j) into ``v_next``; returns the largest
    |Q' - Q| among them. Disjoint ranges may run in parallel threads (``nogil``); each row
    is summed the same way whatever the split, so Q does not depend on it."""
    n_rows, width = index.shape
    n_u = n_rows // v.shape[0]
    change = 0.0
    for m in range(m_start, m_stop):
        best = -np.inf
        for j in range(n_u):
            row = m * n_u + j
            s = 0.0
            for k in range(width):
                s += weight[row, k] * v[_u(index[row, k])]
            new = rewards[row] + gamma * s
            d = abs(new - q[row])
            if d > change:
                change = d
            q_next[row] = new
            if new > best:
                best = new
        v_next[m] = best
    return change


@_jit
def synchronous_sweeps(index, weight, rewards, q, q_next, v, v_next, gamma, delta,
                       history, start, sweeps, min_done):
    """Synchronous sweeps: Q'(m, j) = rho + gamma sum_k w V(idx), V = max_u Q, fused
    (:func:`synchronous_rows` over all bins).

    ``q`` (rows,) holds Q_start and ``v`` (N_X,) max_u Q_start; ``q_next`` and
    ``v_next`` are scratch. The arrays swap roles every sweep: after an odd number of
    sweeps the newest Q and V are in ``q_next`` and ``v_next``.
    """
    n_x = v.shape[0]
    done = 0
    while done < sweeps:
        change = synchronous_rows(index, weight, rewards, q, q_next, v, v_next, gamma, 0, n_x)
        q, q_next = q_next, q
        v, v_next = v_next, v
        history[start + done] = change
        done += 1
        if change <= delta and start + done >= min_done:
            break
    return done


@_jit
def serial_sweeps(index, weight, rewards, q, v, order, gamma, delta, history,
                  start, sweeps, min_done):
    """Serial (in-place, Gauss-Seidel) sweeps: states in ``order``, actions inner, each
    Q(m, j) overwritten at once and V(m) = max_u Q(m, u) refreshed after it."""
    n_rows, width = index.shape
    n_x = v.shape[0]
    n_u = n_rows // n_x
    done = 0
    while done < sweeps:
        change = 0.0
        for i in range(n_x):
            m = order[i]
            for j in range(n_u):
                row = m * n_u + j
                s = 0.0
                for k in range(width):
                    s += weight[row, k] * v[_u(index[row, k])]
                new = rewards[row] + gamma * s
                d = abs(new - q[row])
                if d > change:
                    change = d
                q[row] = new
                best = q[m * n_u]
                for jj in range(1, n_u):
                    if q[m * n_u + jj] > best:
                        best = q[m * n_u + jj]
                v[m] = best
        history[start + done] = change
        done += 1
        if change <= delta and start + done >= min_done:
            break
    return done


@_jit
def robust_rows(index, weight, rewards, q, q_next, v, v_next, gamma, worst, m_start, m_stop):
    """One synchronous sweep over K models of the bins [m_start, m_stop), as
    :func:`synchronous_rows`: ``index``/``weight`` (rows, K, width) (a row's K models side
    by side, one stream through memory), ``rewards`` (rows, K); Q'(m, j) = min_k
    (``worst``) or mean_k of rho_k + gamma T_k V (the mean as the sum over k in order,
    divided by K). Returns the largest |Q' - Q| among them."""
    n_rows, n_models, width = index.shape
    n_u = n_rows // v.shape[0]
    change = 0.0
    for m in range(m_start, m_stop):
        best = -np.inf
        for j in range(n_u):
            row = m * n_u + j
            acc = np.inf if worst else 0.0
            for c in range(n_models):
                s = 0.0
                for k in range(width):
                    s += weight[row, c, k] * v[_u(index[row, c, k])]
                val = rewards[row, c] + gamma * s
                if worst:
                    if val < acc:
                        acc = val
                else:
                    acc += val
            new = acc if worst else acc / n_models
            d = abs(new - q[row])
            if d > change:
                change = d
            q_next[row] = new
            if new > best:
                best = new
        v_next[m] = best
    return change


@_jit
def robust_sweeps(index, weight, rewards, q, q_next, v, v_next, gamma, delta, history,
                  start, sweeps, min_done, worst):
    """Synchronous sweeps over K models (:func:`robust_rows` over all bins); the arrays
    swap roles as in :func:`synchronous_sweeps`."""
    n_x = v.shape[0]
    done = 0
    while done < sweeps:
        change = robust_rows(index, weight, rewards, q, q_next, v, v_next, gamma, worst, 0,
                             n_x)
        q, q_next = q_next, q
        v, v_next = v_next, v
        history[start + done] = change
        done += 1
        if change <= delta and start + done >= min_done:
            break
    return done


@_jit
def membership_rows(points, centers, sizes, circular, index, weight):
    """The memberships (12)-(13) of ``points`` (rows, d) written as rows of the fixed-width
    table: ``index``/``weight`` (rows, 2**d) get the bins with non-zero membership in
    increasing order, zero-padded; returns each row's count. ``centers`` (d, max size)
    holds every axis's centres (row a: the first ``sizes[a]``), as :class:`twolink.fqi.fuzzy.Axis`
    computes them: the same operations in the same order, so the weights are equal bit for
    bit to :meth:`twolink.fqi.fuzzy.Grid.memberships` (a float32 ``weight`` gets each product
    rounded once, as it is stored)."""
    n_rows, d = points.shape
    two_pi = 2.0 * np.pi
    lo = np.empty(d, dtype=np.int64)
    hi = np.empty(d, dtype=np.int64)
    w_lo = np.empty(d)
    w_hi = np.empty(d)
    counts = np.empty(n_rows, dtype=np.int64)
    flat = np.empty(2 ** d, dtype=np.int64)
    prod = np.empty(2 ** d)
    for i in range(n_rows):
        for a in range(d):
            n = sizes[a]
            c0 = centers[a, 0]
            v = points[i, a]
            if circular[a]:
                v = np.mod(v - c0, two_pi) + c0
                j = np.searchsorted(centers[a, :n], v, side="right") - 1
                j = min(max(j, 0), n - 1)
                upper = c0 + two_pi if j == n - 1 else centers[a, j + 1]
                w = (v - centers[a, j]) / (upper - centers[a, j])
                h = (j + 1) % n
            else:
                v = min(max(v, c0), centers[a, n - 1])
                j = np.searchsorted(centers[a, :n], v, side="right") - 1
                j = min(max(j, 0), n - 2)
                w = (v - centers[a, j]) / (centers[a, j + 1] - centers[a, j])
                h = j + 1
            w = min(max(w, 0.0), 1.0)
            # the pair in increasing bin order, so products come out sorted
            if h < j:
                lo[a], hi[a], w_lo[a], w_hi[a] = h, j, w, 1.0 - w
            else:
                lo[a], hi[a], w_lo[a], w_hi[a] = j, h, 1.0 - w, w
        # C-order product over the axes, as Grid.memberships builds it
        flat[0] = 0
        prod[0] = 1.0
        size = 1
        for a in range(d):
            n = sizes[a]
            for t in range(size - 1, -1, -1):
                f, p = flat[t], prod[t]
                flat[2 * t] = f * n + lo[a]
                prod[2 * t] = p * w_lo[a]
                flat[2 * t + 1] = f * n + hi[a]
                prod[2 * t + 1] = p * w_hi[a]
            size *= 2
        c = 0
        for t in range(size):
            if prod[t] != 0.0:
                index[i, c] = flat[t]
                weight[i, c] = prod[t]
                c += 1
        counts[i] = c
        for t in range(c, size):
            index[i, t] = index[i, 0] if c > 0 else 0
            weight[i, t] = 0.0
    return counts
