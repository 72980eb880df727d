"""The compiled sweep of fuzzy Q-iteration (Alg. 1) over a factored transition table.

The grid's first axis (theta_1 of a horizontal arm) is one the dynamics ignore, so the
bins are B blocks of S "slice" bins (m = i * S + r). For slice bin r and action a the
memberships of the reached point on the other axes are shared by all B blocks
(``index``/``weight`` (S * N_U, W), bins within the slice); only the first axis's two
memberships differ per block (``index1``/``weight1`` (S * N_U, B, 2)). Alg. 1 then reads

Q'(i S + r, a) = rho + gamma sum_{k<2} w1[k] G[idx1[k]],  G[t] = sum_j w[j] V(t S + idx[j]),

G computed once per (r, a) for all B blocks t; V = max_u Q and the change norm fused in the
same pass. Synchronous (Q_{l+1} from Q_l, as printed); a ``*_sweep`` call sweeps the slice
rows [r_start, r_stop), so disjoint ranges may run in parallel; the ``*_sweeps`` kernels run
whole sweeps with the slice rows split over ``threads`` numba threads (``prange``, one
parallel region per sweep, no Python between sweeps). Every row is summed the same way
whatever the split, so Q does not depend on ``threads``.

G sums the W memberships of its row from 0.0 in index order (:func:`_blocks`; written out
for W = 8, the paper's four-dimensional grids, with the row's indices and weights held in
registers across the B blocks: the same sums, 15 % faster). Array subscripts are cast to
unsigned integers, so numba emits no negative-index wrap-around test per access: 1.6x
faster (the tables' indices are checked to lie in range before any sweep).

The robust kernels sweep K models at once (Alg. 1 over K transition matrices):
Q'(m, a) = min_k (``worst``) or mean_k (the sum over k in order, divided by K) of
rho_k + gamma T_k V, each model's G computed from its own factored rows.
"""
from __future__ import annotations

import numba
import numpy as np
from numba import prange
from numba import uint64 as _u

from twolink._numba import cache_wanted, njit, njit_parallel

#: Whether the kernel's compiled code is cached (see :mod:`twolink._numba`).
CACHE = cache_wanted(__file__)
_jit = njit(__file__)
_jit_parallel = njit_parallel(__file__)


@numba.njit(inline="always")
def _blocks(v, index, weight, row, c, n_slice, g):
    """G[t] = sum_k w[k] V(t S + idx[k]) over row ``row`` of model ``c`` of
    ``index``/``weight`` (rows, K, W) for every first-axis block t, each summed from 0.0 in
    k order."""
    for t in range(g.shape[0]):
        b = _u(t * n_slice)
        s = 0.0
        for k in range(index.shape[2]):
            s += weight[row, c, k] * v[b + _u(index[row, c, k])]
        g[t] = s


@numba.njit(inline="always")
def _blocks8(v, index, weight, row, c, n_slice, g):
    """:func:`_blocks` written out for width 8 (the paper's four-dimensional grids): the
    row's indices and weights stay in registers across the blocks; the same sums."""
    i0, i1, i2, i3 = _u(index[row, c, 0]), _u(index[row, c, 1]), _u(index[row, c, 2]), \
        _u(index[row, c, 3])
    i4, i5, i6, i7 = _u(index[row, c, 4]), _u(index[row, c, 5]), _u(index[row, c, 6]), \
        _u(index[row, c, 7])
    w0, w1, w2, w3 = weight[row, c, 0], weight[row, c, 1], weight[row, c, 2], weight[row, c, 3]
    w4, w5, w6, w7 = weight[row, c, 4], weight[row, c, 5], weight[row, c, 6], weight[row, c, 7]
    for t in range(g.shape[0]):
        b = _u(t * n_slice)
        s = 0.0
        s += w0 * v[b + i0]
        s += w1 * v[b + i1]
        s += w2 * v[b + i2]
        s += w3 * v[b + i3]
        s += w4 * v[b + i4]
        s += w5 * v[b + i5]
        s += w6 * v[b + i6]
        s += w7 * v[b + i7]
        g[t] = s


@numba.njit(inline="always")
def _sweep(blocks, index, weight, index1, weight1, rewards, q, q_next, v, v_next, gamma,
           r_start, r_stop):
    """One synchronous sweep of the slice rows [r_start, r_stop) with G from ``blocks``
    (:func:`_blocks` or :func:`_blocks8`, compiled into the caller)."""
    n_pairs, width = index.shape
    one_index = index.reshape((n_pairs, 1, width))      # one model: the robust tables' shape
    one_weight = weight.reshape((n_pairs, 1, width))
    n_first = index1.shape[1]
    n_slice = v.shape[0] // n_first
    n_u = n_pairs // n_slice
    g = np.empty(n_first)
    best = np.empty(n_first)
    change = 0.0
    for r in range(r_start, r_stop):
        for i in range(n_first):
            best[i] = -np.inf
        for a in range(n_u):
            row = r * n_u + a
            blocks(v, one_index, one_weight, row, 0, n_slice, g)
            for i in range(n_first):
                s = weight1[row, i, 0] * g[_u(index1[row, i, 0])] \
                    + weight1[row, i, 1] * g[_u(index1[row, i, 1])]
                qrow = _u((i * n_slice + r) * n_u + a)
                new = rewards[qrow] + gamma * s
                d = abs(new - q[qrow])
                if d > change:
                    change = d
                q_next[qrow] = new
                if new > best[i]:
                    best[i] = new
        for i in range(n_first):
            v_next[i * n_slice + r] = best[i]
    return change


@_jit
def factored_sweep(index, weight, index1, weight1, rewards, q, q_next, v, v_next, gamma,
                   r_start, r_stop):
    """One synchronous sweep of the slice rows [r_start, r_stop): writes Q_{l+1} into
    ``q_next`` (rows (i S + r) N_U + a) and max_u Q_{l+1} into ``v_next``; returns
    max |Q_{l+1} - Q_l| over the rows swept."""
    return _sweep(_blocks, index, weight, index1, weight1, rewards, q, q_next, v, v_next,
                  gamma, r_start, r_stop)


@_jit
def factored_sweep8(index, weight, index1, weight1, rewards, q, q_next, v, v_next, gamma,
                    r_start, r_stop):
    """:func:`factored_sweep` for tables of width 8 (the same sums, bit for bit)."""
    return _sweep(_blocks8, index, weight, index1, weight1, rewards, q, q_next, v, v_next,
                  gamma, r_start, r_stop)


@_jit_parallel
def factored_sweeps(index, weight, index1, weight1, rewards, q, q_next, v, v_next, gamma,
                    delta, history, start, sweeps, min_done, threads):
    """Synchronous sweeps over a factored table, each split over ``threads`` ranges of
    slice rows run in parallel: at most ``sweeps`` of them, stopping at max |change| <=
    ``delta`` once ``min_done`` are done (counting ``start`` before); each sweep's change
    goes to ``history[start + l]``. ``q``/``v`` hold Q_l and max_u Q_l; the arrays swap
    roles every sweep (after an odd number the newest are in ``q_next``/``v_next``).
    Returns the number of sweeps done."""
    n_slice = v.shape[0] // index1.shape[1]
    eight = index.shape[1] == 8
    parts = np.zeros(threads)
    done = 0
    while done < sweeps:
        for t in prange(threads):
            lo, hi = t * n_slice // threads, (t + 1) * n_slice // threads
            if eight:
                parts[t] = factored_sweep8(index, weight, index1, weight1, rewards, q, q_next,
                                           v, v_next, gamma, lo, hi)
            else:
                parts[t] = factored_sweep(index, weight, index1, weight1, rewards, q, q_next,
                                          v, v_next, gamma, lo, hi)
        change = parts.max()
        q, q_next = q_next, q
        v, v_next = v_next, v
        history[start + done] = change
        done += 1
        if change <= delta and start + done >= min_done:
            break
    return done


@numba.njit(inline="always")
def _robust_sweep(blocks, index, weight, index1, weight1, rewards, q, q_next, v, v_next,
                  gamma, worst, r_start, r_stop):
    """:func:`factored_robust_sweep` with G from ``blocks`` (:func:`_blocks` or
    :func:`_blocks8`, compiled into the caller)."""
    n_pairs, n_models = index.shape[:2]
    n_first = index1.shape[2]
    n_slice = v.shape[0] // n_first
    n_u = n_pairs // n_slice
    g = np.empty(n_first)
    acc = np.empty(n_first)
    best = np.empty(n_first)
    change = 0.0
    for r in range(r_start, r_stop):
        for i in range(n_first):
            best[i] = -np.inf
        for a in range(n_u):
            row = r * n_u + a
            for i in range(n_first):
                acc[i] = np.inf if worst else 0.0
            for c in range(n_models):
                blocks(v, index, weight, row, c, n_slice, g)
                for i in range(n_first):
                    s = weight1[row, c, i, 0] * g[_u(index1[row, c, i, 0])] \
                        + weight1[row, c, i, 1] * g[_u(index1[row, c, i, 1])]
                    val = rewards[_u((i * n_slice + r) * n_u + a), c] + gamma * s
                    if worst:
                        if val < acc[i]:
                            acc[i] = val
                    else:
                        acc[i] += val
            for i in range(n_first):
                qrow = _u((i * n_slice + r) * n_u + a)
                new = acc[i] if worst else acc[i] / n_models
                d = abs(new - q[qrow])
                if d > change:
                    change = d
                q_next[qrow] = new
                if new > best[i]:
                    best[i] = new
        for i in range(n_first):
            v_next[i * n_slice + r] = best[i]
    return change


@_jit
def factored_robust_sweep(index, weight, index1, weight1, rewards, q, q_next, v, v_next,
                          gamma, worst, r_start, r_stop):
    """One synchronous sweep over K models of the slice rows [r_start, r_stop):
    ``index``/``weight`` (S * N_U, K, W), ``index1``/``weight1`` (S * N_U, K, B, 2),
    ``rewards`` (N_X * N_U, K); Q'(m, a) = min_k (``worst``) or mean_k of
    rho_k + gamma T_k V. Returns max |Q' - Q| over the rows swept."""
    return _robust_sweep(_blocks, index, weight, index1, weight1, rewards, q, q_next, v,
                         v_next, gamma, worst, r_start, r_stop)


@_jit
def factored_robust_sweep8(index, weight, index1, weight1, rewards, q, q_next, v, v_next,
                           gamma, worst, r_start, r_stop):
    """:func:`factored_robust_sweep` for tables of width 8 (the same sums, bit for bit)."""
    return _robust_sweep(_blocks8, index, weight, index1, weight1, rewards, q, q_next, v,
                         v_next, gamma, worst, r_start, r_stop)


@_jit_parallel
def factored_robust_sweeps(index, weight, index1, weight1, rewards, q, q_next, v, v_next,
                           gamma, delta, history, start, sweeps, min_done, worst, threads):
    """:func:`factored_sweeps` over K models (:func:`factored_robust_sweep`)."""
    n_slice = v.shape[0] // index1.shape[2]
    eight = index.shape[2] == 8
    parts = np.zeros(threads)
    done = 0
    while done < sweeps:
        for t in prange(threads):
            lo, hi = t * n_slice // threads, (t + 1) * n_slice // threads
            if eight:
                parts[t] = factored_robust_sweep8(index, weight, index1, weight1, rewards, q,
                                                  q_next, v, v_next, gamma, worst, lo, hi)
            else:
                parts[t] = factored_robust_sweep(index, weight, index1, weight1, rewards, q,
                                                 q_next, v, v_next, gamma, worst, lo, hi)
        change = parts.max()
        q, q_next = q_next, q
        v, v_next = v_next, v
        history[start + done] = change
        done += 1
        if change <= delta and start + done >= min_done:
            break
    return done
