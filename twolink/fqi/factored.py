"""Fuzzy Q-iteration (Alg. 1) over a grid whose first axis the dynamics ignore.

The horizontal arm's dynamics (6) do not depend on theta_1, so the reached points of the
B theta_1 blocks of the grid differ in theta_1 only. The transition matrix T (rows
m * N_U + j, memberships (12)-(13) of f(c_m, u_j)) then factors: the memberships of every
other axis (2**(d-1) pairs) are stored once per slice bin and action, and only theta_1's two
per block (:class:`FactoredTable`). The memberships T would hold are the same; a
(slice bin, action) row stores 12 * 2**(d-1) + B * 24 bytes instead of B * 12 * 2**d.
:func:`factored_q_iteration` sweeps it with the compiled kernels
(:mod:`twolink.fqi._factored_kernel`; :func:`factored_q_iteration_robust` over K models at
once), on one thread or, for sweeps of :data:`PARALLEL_MIN_WORK` gathered values and more,
two; :meth:`FactoredTable.tocsr` gives the plain T that tests hold the sweeps against.
Both centralized syntheses use it: the paper's two-link problem
(:func:`factored_table`, ``twolink.synthesis.synthesize`` layout "factored") and the N-link one
(:class:`FactoredBuilder`, block by block, ``twolink.synthesis.links_centralized``).
"""
from __future__ import annotations

import dataclasses
import os
from typing import Callable, Optional, Sequence

import numpy as np
import scipy.sparse as sp

from twolink.arm.parameters import DELTA, GAMMA
from twolink.fqi import _factored_kernel as fqi_factored_kernel
from twolink.fqi.fuzzy import Grid
from twolink.fqi.iteration import ROBUST_MODES, QIterationResult, iterate
from twolink.validate import whole

#: :meth:`FactoredTable.tocsr` refuses to expand a table past this many non-zeros.
MAX_CSR_NNZ = 50_000_000


@dataclasses.dataclass(frozen=True)
class FactoredTable:
    """T of a grid of B first-axis blocks of S slice bins (bin m = i * S + r), N_U actions.

    ``index``/``weight`` (S * N_U, W): for pair row r * N_U + a, the slice bins (int32) and
    memberships of the reached point on the axes after the first; ``index1``/``weight1``
    (S * N_U, B, 2): for each block i, the first-axis bins (int32) and memberships of the
    first-axis value reached from block i. T[(i S + r) N_U + a, t S + s] is the sum of
    weight1[.., i, k] * weight[.., j] over k, j with index1 = t and index = s.
    """

    index: np.ndarray
    weight: np.ndarray
    index1: np.ndarray
    weight1: np.ndarray
    n_actions: int

    def __post_init__(self):
        index = np.ascontiguousarray(self.index, dtype=np.int32)
        weight = np.ascontiguousarray(self.weight, dtype=float)
        index1 = np.ascontiguousarray(self.index1, dtype=np.int32)
        weight1 = np.ascontiguousarray(self.weight1, dtype=float)
        n_u = self.n_actions
        whole(n_u, "n_actions", 1)
        if index.ndim != 2 or index.shape != weight.shape or index.shape[0] % n_u:
            raise ValueError(f"index {index.shape} and weight {weight.shape} must be one "
                             f"(S * {n_u}, width) shape")
        if index1.ndim != 3 or index1.shape != weight1.shape \
                or index1.shape[::2] != (index.shape[0], 2):
            raise ValueError(f"index1 {index1.shape} and weight1 {weight1.shape} must be one "
                             f"({index.shape[0]}, B, 2) shape")
        n_slice, n_first = index.shape[0] // n_u, index1.shape[1]
        if index.size and (index.min() < 0 or index.max() >= n_slice):
            raise ValueError(f"slice bin indices must lie in [0, {n_slice})")
        if index1.size and (index1.min() < 0 or index1.max() >= n_first):
            raise ValueError(f"first-axis bin indices must lie in [0, {n_first})")
        for name, value in (("index", index), ("weight", weight), ("index1", index1),
                            ("weight1", weight1)):
            object.__setattr__(self, name, value)
        object.__setattr__(self, "n_actions", int(n_u))

    @property
    def n_slice(self) -> int:
        return self.index.shape[0] // self.n_actions

    @property
    def n_first(self) -> int:
        return self.index1.shape[1]

    @property
    def n_states(self) -> int:
        return self.n_first * self.n_slice

    @property
    def shape(self) -> tuple:
        """The shape of the T this table stands for: (N_X * N_U, N_X)."""
        return (self.n_states * self.n_actions, self.n_states)

    @property
    def nnz(self) -> int:
        """Non-zeros of T: per row, the non-zero products of both factors."""
        rest = np.count_nonzero(self.weight, axis=1).astype(np.int64)
        first = np.count_nonzero(self.weight1, axis=2).sum(axis=1, dtype=np.int64)
        return int(rest @ first)

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in (self.index, self.weight, self.index1, self.weight1))

    def tocsr(self) -> sp.csr_matrix:
        """T as a scipy CSR matrix (duplicates summed, zeros dropped), for small grids."""
        n_rows, width = self.index.shape
        if n_rows * self.n_first * 2 * width > MAX_CSR_NNZ:
            raise ValueError(f"a T of {n_rows * self.n_first * 2 * width} memberships is too "
                             f"large to expand (at most {MAX_CSR_NNZ})")
        s = self.n_slice
        pair = np.arange(n_rows)
        rows = (np.arange(self.n_first)[None, :] * s * self.n_actions + pair[:, None])
        cols = self.index1[:, :, :, None].astype(np.int64) * s + self.index[:, None, None, :]
        vals = self.weight1[:, :, :, None] * self.weight[:, None, None, :]
        rows = np.broadcast_to(rows[:, :, None, None], vals.shape)
        t = sp.csr_matrix((vals.reshape(-1), (rows.reshape(-1), cols.reshape(-1))),
                          shape=self.shape)
        t.sum_duplicates()
        t.eliminate_zeros()
        return t


class FactoredBuilder:
    """Fills a :class:`FactoredTable` of ``grid`` (its first axis the one the dynamics
    ignore) block by block of slice bins, so the reached points never need to be held all
    at once."""

    def __init__(self, grid: Grid, n_actions: int):
        if len(grid.axes) < 2:
            raise ValueError("a factored table needs a grid of at least two axes")
        self.first = grid.axes[0]
        self.rest = Grid(tuple(grid.axes[1:]))
        rows = self.rest.size * n_actions
        width = 2 ** len(self.rest.axes)
        self.n_actions = n_actions
        self._index = np.empty((rows, width), dtype=np.int32)
        self._weight = np.empty((rows, width))
        self._index1 = np.empty((rows, self.first.size, 2), dtype=np.int32)
        self._weight1 = np.empty((rows, self.first.size, 2))
        self._done = np.zeros(self.rest.size, dtype=bool)

    def add(self, start: int, rest_points: np.ndarray, first_points: np.ndarray) -> None:
        """The reached points of slice bins start..start+n-1: ``rest_points`` (n, N_U, d-1)
        on the axes after the first, ``first_points`` (n, N_U, B) the first-axis value
        reached from each of the B blocks."""
        n = rest_points.shape[0]
        if rest_points.shape != (n, self.n_actions, len(self.rest.axes)) \
                or first_points.shape != (n, self.n_actions, self.first.size) \
                or not 0 <= start <= self.rest.size - n:
            raise ValueError(f"block of {rest_points.shape} and {first_points.shape} at "
                             f"{start} does not fit a slice of {self.rest.size} bins")
        rows = slice(start * self.n_actions, (start + n) * self.n_actions)
        idx, w = self.rest.memberships(rest_points.reshape(-1, len(self.rest.axes)))
        self._index[rows], self._weight[rows] = idx, w
        idx1, w1 = self.first.memberships(first_points.reshape(-1, self.first.size))
        self._index1[rows], self._weight1[rows] = idx1, w1
        self._done[start:start + n] = True

    def table(self) -> FactoredTable:
        """The filled table (a RuntimeError if a slice bin was never added)."""
        if not self._done.all():
            raise RuntimeError(f"{int((~self._done).sum())} slice bins have no transitions")
        return FactoredTable(self._index, self._weight, self._index1, self._weight1,
                             self.n_actions)


def factored_table(grid: Grid, next_points: np.ndarray) -> FactoredTable:
    """The :class:`FactoredTable` of the points reached from every (bin centre, action)
    pair, ``next_points`` (N_X, N_U, d) on ``grid``, whose first axis must be circular and
    ignored by the dynamics: the B first-axis blocks of points must agree on every other
    axis bit for bit (as the horizontal arm's (6) and (11) give them), else a ValueError.
    The memberships are those of :func:`twolink.fqi.iteration.transition_table`; only their sums
    in a sweep are ordered differently (G per block, then the first axis)."""
    next_points = np.asarray(next_points, dtype=float)
    if next_points.ndim != 3 or next_points.shape[0] != grid.size \
            or next_points.shape[2] != len(grid.axes):
        raise ValueError(f"next_points of shape {next_points.shape} do not match a grid of "
                         f"{grid.size} bins over {len(grid.axes)} dimensions")
    first = grid.axes[0]
    if not first.circular:
        raise ValueError(f"a factored table needs a circular first axis, not {first.name}")
    n_x, n_u, d = next_points.shape
    blocks = next_points.reshape(first.size, n_x // first.size, n_u, d)
    rest = blocks[0, ..., 1:]
    if not np.array_equal(blocks[..., 1:], np.broadcast_to(rest, blocks[..., 1:].shape)):
        raise ValueError(f"the reached points of the {first.name} blocks differ on other axes: "
                         f"the dynamics depend on {first.name}, so T does not factor "
                         f"(use twolink.fqi.iteration.transition_table)")
    builder = FactoredBuilder(grid, n_u)
    builder.add(0, rest, np.moveaxis(blocks[..., 0], 0, -1))
    return builder.table()


#: Gathered values per sweep (slice rows x blocks x (memberships + 2)) below which the
#: sweeps run on one thread unless ``threads=`` says otherwise. Such a sweep takes well
#: under a millisecond (the paper's centralized problem: 0.64 M, 0.3 ms), so waking a
#: second thread every sweep costs a good share of it: measured on this 2-core VM, two
#: threads were 1.2-1.5x faster when the other core was idle and 1.5-3x slower when another
#: process kept it busy. Larger sweeps (K models, refined grids, three links) take two.
PARALLEL_MIN_WORK = 2_000_000


def default_threads(work: Optional[int] = None) -> int:
    """Threads the sweeps use: two (one on a one-core machine), or one for sweeps of
    fewer than :data:`PARALLEL_MIN_WORK` gathered values (``work``, when given)."""
    if work is not None and work < PARALLEL_MIN_WORK:
        return 1
    return max(1, min(2, os.cpu_count() or 1))


def sweep_work(table: FactoredTable) -> int:
    """Gathered values one sweep of ``table`` reads: per slice row and block, its
    memberships on the other axes and the first axis's two."""
    return table.index.shape[0] * table.n_first * (table.index.shape[1] + 2)


def _check_threads(threads, work: int) -> int:
    threads = default_threads(work) if threads is None else threads
    return whole(threads, "threads", 1)


def _check_rewards(table: FactoredTable, rewards, gamma: float, delta: float) -> np.ndarray:
    rewards = np.ascontiguousarray(rewards, dtype=float)
    if rewards.shape != (table.n_states, table.n_actions):
        raise ValueError(f"rewards of shape {rewards.shape} do not match a table of "
                         f"{table.n_states} bins and {table.n_actions} actions")
    if not 0.0 < gamma < 1.0:
        raise ValueError(f"gamma must lie in (0, 1), got {gamma}")
    if not delta > 0.0:
        raise ValueError(f"delta must be positive, got {delta}")
    return rewards


def _one_thread(sweep, q, q_next, v, v_next, history, done, step, delta, min_iterations):
    """Up to ``step`` sweeps on this thread, each one compiled call ``sweep(q, q_next, v,
    v_next)`` returning its change (no thread pool: a sweep costs a few microseconds of
    Python more), with the stopping rule and array swaps of the compiled drivers."""
    n = 0
    while n < step:
        change = sweep(q, q_next, v, v_next)
        q, q_next, v, v_next = q_next, q, v_next, v
        history[done + n] = change
        n += 1
        if change <= delta and done + n >= min_iterations:
            break
    return n


def factored_q_iteration(table: FactoredTable, rewards: np.ndarray, *, gamma: float = GAMMA,
                         delta: float = DELTA, max_iterations: int = 10000,
                         min_iterations: int = 0,
                         callback: Optional[Callable[[int, float], None]] = None,
                         threads: Optional[int] = None) -> QIterationResult:
    """Synchronous sweeps of Alg. 1 from Q_0 = 0 until max |Q_l - Q_{l-1}| <= delta, over
    a :class:`FactoredTable`; ``rewards`` (N_X, N_U) rho(c_m, u_j). ``threads`` share each
    sweep's slice rows (default :func:`default_threads` of the sweep's :func:`sweep_work`;
    the same Q bit for bit whatever their number); ``min_iterations`` forces at least that
    many sweeps (benchmarks); ``callback(l, change)`` after each sweep."""
    rewards = _check_rewards(table, rewards, gamma, delta)
    threads = min(_check_threads(threads, sweep_work(table)), table.n_slice)
    r = rewards.reshape(-1)

    def kernel(q, q_next, v, v_next, history, done, step):
        if threads > 1:
            return fqi_factored_kernel.factored_sweeps(
                table.index, table.weight, table.index1, table.weight1, r, q, q_next, v,
                v_next, gamma, delta, history, done, step, min_iterations, threads)
        sweep = fqi_factored_kernel.factored_sweep8 if table.index.shape[1] == 8 \
            else fqi_factored_kernel.factored_sweep
        return _one_thread(lambda *a: sweep(table.index, table.weight, table.index1,
                                            table.weight1, r, *a, gamma, 0, table.n_slice),
                           q, q_next, v, v_next, history, done, step, delta, min_iterations)
    return iterate(kernel, rewards.shape, in_place=False, delta=delta,
                   max_iterations=max_iterations, min_iterations=min_iterations,
                   callback=callback)


def factored_q_iteration_robust(tables: Sequence[FactoredTable], rewards: Sequence[np.ndarray],
                                *, mode: str = "worst", gamma: float = GAMMA,
                                delta: float = DELTA, max_iterations: int = 10000,
                                min_iterations: int = 0,
                                callback: Optional[Callable[[int, float], None]] = None,
                                threads: Optional[int] = None) -> QIterationResult:
    """Synchronous sweeps of Alg. 1 over K models at once, as
    :func:`twolink.fqi.iteration.fuzzy_q_iteration_robust` (Q(m, u) = min_k or mean_k of
    rho_k + gamma T_k V), over K :class:`FactoredTable` of one grid and action set."""
    if mode not in ROBUST_MODES:
        raise ValueError(f"unknown robust mode {mode!r}; choose one of {', '.join(ROBUST_MODES)}")
    if len(tables) == 0 or len(tables) != len(rewards):
        raise ValueError(f"need one reward table per transition table, got {len(tables)} "
                         f"tables and {len(rewards)} reward tables")
    first = tables[0]
    for t in tables[1:]:
        if (t.n_first, t.n_slice, t.n_actions) != (first.n_first, first.n_slice,
                                                   first.n_actions):
            raise ValueError("the models' factored tables differ in shape")
    checked = [_check_rewards(first, rr, gamma, delta) for rr in rewards]
    width = max(t.index.shape[1] for t in tables)
    n_pairs = first.index.shape[0]
    index = np.empty((n_pairs, len(tables), width), dtype=np.int32)
    weight = np.zeros((n_pairs, len(tables), width))
    for k, t in enumerate(tables):
        w = t.index.shape[1]
        index[:, k, :w], weight[:, k, :w] = t.index, t.weight
        index[:, k, w:] = t.index[:, :1]
    index1 = np.ascontiguousarray(np.stack([t.index1 for t in tables], axis=1))
    weight1 = np.ascontiguousarray(np.stack([t.weight1 for t in tables], axis=1))
    r = np.ascontiguousarray(np.stack([rr.reshape(-1) for rr in checked], axis=1))
    threads = min(_check_threads(threads, sum(sweep_work(t) for t in tables)),
                  first.n_slice)
    worst = mode == "worst"

    def kernel(q, q_next, v, v_next, history, done, step):
        if threads > 1:
            return fqi_factored_kernel.factored_robust_sweeps(
                index, weight, index1, weight1, r, q, q_next, v, v_next, gamma, delta,
                history, done, step, min_iterations, worst, threads)
        sweep = fqi_factored_kernel.factored_robust_sweep8 if width == 8 \
            else fqi_factored_kernel.factored_robust_sweep
        return _one_thread(lambda *a: sweep(index, weight, index1, weight1, r, *a, gamma,
                                            worst, 0, first.n_slice),
                           q, q_next, v, v_next, history, done, step, delta, min_iterations)
    return iterate(kernel, checked[0].shape, in_place=False, delta=delta,
                   max_iterations=max_iterations, min_iterations=min_iterations,
                   callback=callback)
