"""The value-iteration peers of the synthesis benchmarks, handed the MDP of fuzzy
Q-iteration (the same sparse T, the same rewards) and forced to the same number of
sweeps from V_0 = 0: QuantEcon's ``DiscreteDP`` (:func:`quantecon_solver`) and
pymdptoolbox's ``ValueIteration`` (:func:`mdptoolbox_solver`); scipy's CSR product as
the reference (:func:`scipy_sweeps`) and the agreement of a peer's values and greedy
actions with ours (:func:`agreement`).
"""
from __future__ import annotations

import contextlib
import warnings
from unittest import mock

import numpy as np
import scipy.sparse as sp

from twolink.arm.parameters import DELTA, GAMMA


def _index_pairs(n_x: int, n_u: int) -> tuple[np.ndarray, np.ndarray]:
    """State and action index of every row m * N_U + j of T."""
    return np.repeat(np.arange(n_x), n_u), np.tile(np.arange(n_u), n_x)


def quantecon_solver(trans: sp.csr_matrix, rewards: np.ndarray, sweeps: int):
    """QuantEcon ``DiscreteDP`` in its state-action-pairs form on (T, rho): a callable
    doing ``sweeps`` value-iteration sweeps from V_0 = 0, returning (V, greedy action)."""
    from quantecon.markov import DiscreteDP

    n_x, n_u = rewards.shape
    s_idx, a_idx = _index_pairs(n_x, n_u)
    ddp = DiscreteDP(rewards.reshape(-1), trans, GAMMA, s_idx, a_idx)

    def solve():
        res = ddp.solve(method="value_iteration", v_init=np.zeros(n_x),
                        epsilon=1e-300, max_iter=sweeps)
        if res.num_iter != sweeps:
            raise RuntimeError(f"quantecon did {res.num_iter} sweeps, not {sweeps}")
        return res.v, res.sigma

    def sweeps_only():
        v = np.zeros(n_x)
        done = ddp.operator_iteration(ddp.bellman_operator, v, sweeps, tol=-1.0,
                                      Tv=np.empty(n_x))
        if done != sweeps:
            raise RuntimeError(f"quantecon did {done} sweeps, not {sweeps}")
        return v

    return solve, sweeps_only


def _per_action(trans: sp.csr_matrix, n_u: int) -> list:
    return [sp.csr_matrix(trans[j::n_u]) for j in range(n_u)]


def mdptoolbox_solver(trans: sp.csr_matrix, rewards: np.ndarray, sweeps: int, *,
                      full_setup: bool = True):
    """pymdptoolbox ``ValueIteration`` on (T split into per-action (S, S) matrices, rho):
    a callable doing exactly ``sweeps`` sweeps from V_0 = 0, returning (V, greedy action).

    ``full_setup=False`` skips two steps of its constructor that do not change the
    sweeps: the input check (``mdptoolbox.util.check``, a dense comparison per action)
    and the iteration bound (``_boundIter``, a column slice of every P per state); on
    the centralized T they take minutes.
    """
    import mdptoolbox.util
    from mdptoolbox.mdp import ValueIteration

    per_action = _per_action(trans, rewards.shape[1])
    with contextlib.ExitStack() as stack:
        stack.enter_context(warnings.catch_warnings())
        warnings.simplefilter("ignore", sp.SparseEfficiencyWarning)
        if not full_setup:
            stack.enter_context(mock.patch.object(mdptoolbox.util, "check", _no_op))
            stack.enter_context(mock.patch.object(ValueIteration, "_boundIter", _no_op))
        vi = ValueIteration(per_action, rewards, GAMMA, epsilon=DELTA, max_iter=sweeps)

    def solve():
        # Its constructor caps max_iter by an epsilon-optimality bound; force the count
        # and a stopping threshold no span can fall under.
        vi.V, vi.iter, vi.max_iter, vi.thresh = np.zeros(vi.S), 0, sweeps, -1.0
        vi.run()
        if vi.iter != sweeps:
            raise RuntimeError(f"mdptoolbox did {vi.iter} sweeps, not {sweeps}")
        return np.asarray(vi.V), np.asarray(vi.policy)

    return solve


def _no_op(*args, **kwargs):
    return None


def scipy_sweeps(trans: sp.csr_matrix, rewards: np.ndarray, n: int) -> np.ndarray:
    """Q_n of ``n`` synchronous sweeps from Q_0 = 0 by scipy's CSR product: the reference."""
    r = rewards.reshape(-1)
    q = np.zeros(rewards.shape)
    for _ in range(n):
        q = (r + GAMMA * (trans @ q.max(axis=1))).reshape(rewards.shape)
    return q


def agreement(ours_q: np.ndarray, v: np.ndarray, greedy: np.ndarray) -> tuple[float, float]:
    """Max |V_peer - V_ours| relative to max |V_ours|, and the share of bins whose peer
    greedy action is greedy in our Q too (ties, to 1e-12 relative, count as agreement)."""
    v_ours = ours_q.max(axis=1)
    scale = max(1e-300, float(np.max(np.abs(v_ours))))
    rel = float(np.max(np.abs(np.asarray(v) - v_ours)) / scale)
    picked = np.take_along_axis(ours_q, np.asarray(greedy, dtype=int)[:, None], 1)[:, 0]
    same = float(np.mean(picked >= v_ours - 1e-12 * scale))
    return rel, same
