"""The compiled sweep of fuzzy Q-iteration (Alg. 1) over a factored transition table.

The grid's first axis (theta_1 of a horizontal arm) is one the dynamics ignore, so the
bins are B blocks of S "slice" bins (m = i * S + r). For slice bin r and action a the
memberships of the reached point on the other axes are shared by all B blocks
(``index``/``weight`` (S * N_U, W), bins within the slice); only the first axis's two
memberships differ per block (``index1``/``weight1`` (S * N_U, B, 2)). Alg. 1 then reads

Q'(i S + r, a) = rho + gamma sum_{k<2} w1[k] G[idx1[k]],  G[t] = sum_j w[j] V(t S + idx[j]),

G computed once per (r, a) for all B blocks t; V = max_u Q and the change norm fused in the
same pass. Synchronous (Q_{l+1} from Q_l, as printed); one call sweeps the slice rows
[r_start, r_stop), so disjoint ranges may run in parallel threads (``nogil``).
"""
from __future__ import annotations

import numpy as np

from twolink._numba import cache_wanted, njit

#: Whether the kernel's compiled code is cached (see :mod:`twolink._numba`).
CACHE = cache_wanted(__file__)
_jit = njit(__file__)


@_jit
def factored_sweep(index, weight, index1, weight1, rewards, q, q_next, v, v_next, gamma,
                   r_start, r_stop):
    """One synchronous sweep of the slice rows [r_start, r_stop): writes Q_{l+1} into
    ``q_next`` (rows (i S + r) N_U + a) and max_u Q_{l+1} into ``v_next``; returns
    max |Q_{l+1} - Q_l| over the rows swept."""
    n_pairs, width = index.shape
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
            for t in range(n_first):
                base = t * n_slice
                s = 0.0
                for k in range(width):
                    s += weight[row, k] * v[base + index[row, k]]
                g[t] = s
            for i in range(n_first):
                s = weight1[row, i, 0] * g[index1[row, i, 0]] \
                    + weight1[row, i, 1] * g[index1[row, i, 1]]
                qrow = (i * n_slice + r) * n_u + a
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
