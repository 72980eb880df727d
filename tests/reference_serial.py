"""A plain reference for serial (in-place) sweeps of fuzzy Q-iteration, apart from the
fast path.

ApproxRL's ``fuzzyqi.m`` with its ``'serial'`` option overwrites each Q(m, j) as soon as
it is computed: bins outer, in Matlab's linear order (first grid index fastest), actions
inner, every update reading the current Q, so later updates of a sweep already see
earlier ones. A sweep's change is max |Q after - Q before| over the whole table. Slow;
for tests only.
"""
from __future__ import annotations

import itertools

import numpy as np
from reference_fqi import dense_memberships


def matlab_order(shape) -> list[int]:
    """Flat (C-order) bin indices in Matlab's linear order over ``shape``: the first
    index varies fastest."""
    strides = [int(np.prod(shape[k + 1:])) for k in range(len(shape))]
    order = []
    for rev in itertools.product(*[range(n) for n in reversed(shape)]):
        idx = rev[::-1]
        order.append(sum(i * s for i, s in zip(idx, strides)))
    return order


def serial_q_iteration_reference(grid, next_points, rewards, *, gamma: float = 0.98,
                                 delta: float = 0.01, order=None,
                                 max_iterations: int = 10000):
    """Serial sweeps from Q_0 = 0: for m in ``order`` (default Matlab's), for each action
    j, Q(m, j) <- rho(c_m, u_j) + gamma sum_m~ mu_m~(f(c_m, u_j)) max_u~ Q(m~, u~), with
    the Q of this very moment. Stops at max |change over a sweep| <= delta.
    Returns (Q, sweeps)."""
    n_x, n_u = rewards.shape
    mu = [[[(m_t, w) for m_t, w in enumerate(dense_memberships(grid, next_points[m, j])) if w]
           for j in range(n_u)] for m in range(n_x)]
    order = matlab_order(grid.shape) if order is None else list(order)
    q = [[0.0] * n_u for _ in range(n_x)]
    ell = 0
    while True:
        before = [row[:] for row in q]
        for m in order:
            for j in range(n_u):
                total = 0.0
                for m_t, w in mu[m][j]:
                    total += w * max(q[m_t])
                q[m][j] = float(rewards[m, j]) + gamma * total
        ell += 1
        change = max(abs(a - b) for row_a, row_b in zip(q, before) for a, b in zip(row_a, row_b))
        if change <= delta or ell >= max_iterations:
            return np.array(q), ell
