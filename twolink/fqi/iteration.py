"""Fuzzy Q-iteration, Alg. 1 of the paper.

Q_{l+1}(m, u) = rho(c_m, u) + gamma * sum_m~ mu_m~(f(c_m, u)) max_u~ Q_l(m~, u~)

The transitions f(c_m, u_j) of every (bin centre, action) pair are computed once and
stored as the membership matrix T of shape (N_X * N_U, N_X) (:mod:`twolink.fqi.tables`:
a scipy CSR matrix, a fixed-width :class:`~twolink.fqi.tables.TransitionTable`, or K
models side by side in a :class:`~twolink.fqi.tables.RobustTable`; float64 or float32
weights, :data:`~twolink.fqi.tables.WEIGHTS`). Synchronous and robust sweeps can split
their bins over threads (``threads=``; the same Q bit for bit).
Sweeps are synchronous (Q_{l+1} from Q_l, as printed) or serial (each Q(m, u) overwritten
at once, bins in Matlab's column-major order, as ApproxRL's ``fuzzyqi.m`` can run them).
``tests/reference_fqi.py`` holds the plain loop of Alg. 1 and the scipy sweep this is
checked against.
"""
from __future__ import annotations

import dataclasses
import os
import time
from concurrent.futures import ThreadPoolExecutor
from contextlib import nullcontext
from typing import Callable, Optional, Sequence, Union

import numpy as np
import scipy.sparse as sp

from twolink.arm.parameters import DELTA, GAMMA
from twolink.fqi import _kernel as fqi_kernel
from twolink.fqi.tables import (
    RobustTable,
    TransitionTable,
    check_state_shape,
    check_weights,
    fixed_width,
    weights_as,
)
from twolink.validate import whole

SWEEPS = ("synchronous", "serial")
ROBUST_MODES = ("worst", "mean")


@dataclasses.dataclass
class QIterationResult:
    """Outcome of Alg. 1: Q of shape (N_X, N_U), sweeps done, the change per sweep."""

    q: np.ndarray
    iterations: int
    history: np.ndarray
    converged: bool
    seconds: float


def fuzzy_q_iteration(transitions: Union[sp.spmatrix, TransitionTable], rewards: np.ndarray,
                      *, gamma: float = GAMMA, delta: float = DELTA,
                      max_iterations: int = 10000, min_iterations: int = 0,
                      callback: Optional[Callable[[int, float], None]] = None,
                      sweeps: str = "synchronous",
                      state_shape: Optional[tuple] = None,
                      weights: Optional[str] = None, threads: int = 1) -> QIterationResult:
    """Sweeps of Alg. 1 from Q_0 = 0 until max|Q_l - Q_{l-1}| <= delta.

    ``rewards`` has shape (N_X, N_U): rho(c_m, u_j). ``sweeps="synchronous"`` computes
    Q_{l+1} from Q_l throughout (as printed); ``"serial"`` overwrites each Q(m, u) at once,
    bins in the column-major (Matlab, first index fastest) order of the grid's shape and
    actions inner, each update using the max over actions of the current Q. Serial sweeps
    need the grid's shape: from a :func:`~twolink.fqi.tables.transition_table` or as
    ``state_shape``. ``min_iterations`` forces at least that many sweeps (for benchmarks
    doing equal work); ``callback(l, change)`` is called after each sweep. ``weights``
    (:data:`~twolink.fqi.tables.WEIGHTS`) is the precision the sweeps read T in: None, the
    table's own (a sparse T: float64); ``"float32"`` rounds a float64 table's weights
    first. ``threads`` > 1 splits each synchronous sweep's bins over that many threads (the
    same Q bit for bit; serial sweeps are sequential by definition).
    """
    table, rewards = _check(transitions, rewards, gamma, delta, state_shape, weights)
    if sweeps not in SWEEPS:
        raise ValueError(f"unknown sweeps {sweeps!r}; choose one of {', '.join(SWEEPS)}")
    threads = check_threads(threads)
    if sweeps == "serial" and threads > 1:
        raise ValueError("serial sweeps overwrite Q in order and cannot be split over "
                         "threads: use threads=1")
    n_x, n_u = rewards.shape
    if sweeps == "serial":
        if table.state_shape is None:
            raise ValueError("serial sweeps visit the bins in the grid's column-major order: "
                             "pass a transition_table(grid, ...) or state_shape=grid.shape")
        order = np.arange(n_x).reshape(table.state_shape).ravel(order="F")
    r = rewards.reshape(-1)
    if sweeps == "serial":
        def kernel(q, q_next, v, v_next, history, done, step):
            return fqi_kernel.serial_sweeps(table.index, table.weight, r, q, v, order, gamma,
                                            delta, history, done, step, min_iterations)
    else:
        def kernel(q, q_next, v, v_next, history, done, step):
            return fqi_kernel.synchronous_sweeps(table.index, table.weight, r, q, q_next, v,
                                                 v_next, gamma, delta, history, done, step,
                                                 min_iterations)

        def rows(q, q_next, v, v_next, lo, hi):
            return fqi_kernel.synchronous_rows(table.index, table.weight, r, q, q_next, v,
                                               v_next, gamma, lo, hi)
    with _pool(threads) as pool:
        run = _threaded(rows, pool, n_x, threads, delta, min_iterations) if threads > 1 \
            else kernel
        return iterate(run, (n_x, n_u), in_place=sweeps == "serial", delta=delta,
                        max_iterations=max_iterations, min_iterations=min_iterations,
                        callback=callback)


def check_threads(threads) -> int:
    """``threads`` as an int in [1, this machine's cores], or a ValueError."""
    cores = max(1, os.cpu_count() or 1)
    return whole(threads, "threads", 1, cores, message="{what} must be a whole number in "
                 "[{low}, {high}] (this machine's cores), got {value!r}")


def _pool(threads: int):
    return ThreadPoolExecutor(max_workers=threads) if threads > 1 else nullcontext()


def _threaded(rows, pool, n_x: int, threads: int, delta: float, min_iterations: int):
    """A sweep kernel for :func:`iterate` that runs ``rows(q, q_next, v, v_next, lo, hi)``
    (a compiled one-sweep kernel over the bins [lo, hi), releasing the GIL) on ``threads``
    disjoint ranges of bins at once, the change the largest of theirs."""
    cuts = np.linspace(0, n_x, threads + 1).astype(int)

    def kernel(q, q_next, v, v_next, history, done, step):
        n = 0
        while n < step:
            parts = pool.map(lambda k, q=q, q_next=q_next, v=v, v_next=v_next:
                             rows(q, q_next, v, v_next, cuts[k], cuts[k + 1]), range(threads))
            change = max(parts)
            q, q_next, v, v_next = q_next, q, v_next, v
            history[done + n] = change
            n += 1
            if change <= delta and done + n >= min_iterations:
                break
        return n
    return kernel


def iterate(kernel, shape, *, in_place: bool, delta: float, max_iterations: int,
             min_iterations: int, callback) -> QIterationResult:
    """Run a compiled sweep ``kernel`` from Q_0 = 0 until the change is <= ``delta``: all
    sweeps in one call, or one per call when there is a ``callback(l, change)``. A kernel
    that is not ``in_place`` writes Q_{l+1} into the other buffer; an odd number of its
    sweeps leaves the newest Q there."""
    n_x, n_u = shape
    start = time.perf_counter()
    q, q_next = np.zeros(n_x * n_u), np.empty(n_x * n_u)
    v, v_next = np.zeros(n_x), np.empty(n_x)
    history = np.empty(max(0, max_iterations))
    step = max_iterations if callback is None else 1
    done = 0
    converged = False
    while done < max_iterations:
        n = kernel(q, q_next, v, v_next, history, done, step)
        if n % 2 and not in_place:
            q, q_next, v, v_next = q_next, q, v_next, v
        done += n
        if callback is not None:
            callback(done, float(history[done - 1]))
        if history[done - 1] <= delta and done >= min_iterations:
            converged = True
            break
    return QIterationResult(q.reshape(n_x, n_u), done, history[:done].copy(), converged,
                            time.perf_counter() - start)


def fuzzy_q_iteration_robust(transitions: Union[RobustTable,
                                                Sequence[Union[sp.spmatrix, TransitionTable]]],
                             rewards: Sequence[np.ndarray], *, mode: str = "worst",
                             gamma: float = GAMMA, delta: float = DELTA,
                             max_iterations: int = 10000, min_iterations: int = 0,
                             callback: Optional[Callable[[int, float], None]] = None,
                             weights: Optional[str] = None, threads: int = 1
                             ) -> QIterationResult:
    """Synchronous sweeps of Alg. 1 over K models at once, from Q_0 = 0:

    Q_{l+1}(m, u) = min_k (``mode="worst"``) or mean_k (``"mean"``) of
    rho_k(c_m, u) + gamma sum_m~ T_k[(m, u), m~] max_u~ Q_l(m~, u~),

    one transition matrix and one reward table (N_X, N_U) per model k, all on one grid;
    ``transitions`` is the K matrices or tables, or a
    :class:`~twolink.fqi.tables.RobustTable` of all K; ``weights`` and ``threads`` as in
    :func:`fuzzy_q_iteration`.
    """
    threads = check_threads(threads)
    if mode not in ROBUST_MODES:
        raise ValueError(f"unknown robust mode {mode!r}; choose one of {', '.join(ROBUST_MODES)}")
    n_models = transitions.models if isinstance(transitions, RobustTable) else len(transitions)
    if n_models == 0 or n_models != len(rewards):
        raise ValueError(f"need one reward table per transition matrix, got "
                         f"{n_models} matrices and {len(rewards)} reward tables")
    if isinstance(transitions, RobustTable):
        index, weight = transitions.index, weights_as(transitions.weight, weights)
        shape = (index.shape[0], transitions.n_states)
        checked = [_check_rewards(shape, r, gamma, delta) for r in rewards]
    else:
        pairs = [_check(t, r, gamma, delta, None, weights) for t, r in zip(transitions, rewards)]
        checked = [r for _, r in pairs]
    shapes = {r.shape for r in checked}
    if len(shapes) != 1:
        raise ValueError(f"the models' reward tables differ in shape: {sorted(shapes)}")
    n_x, n_u = checked[0].shape
    if not isinstance(transitions, RobustTable):
        width = max(t.index.shape[1] for t, _ in pairs)
        index = np.empty((n_x * n_u, n_models, width), dtype=np.int32)
        dtypes = sorted({t.weight.dtype.name for t, _ in pairs})
        if len(dtypes) != 1:
            raise ValueError(f"the models' tables mix {' and '.join(dtypes)} weights: pass "
                             f"weights= to sweep them in one precision")
        weight = np.zeros((n_x * n_u, n_models, width), dtype=dtypes[0])
        for k, (t, _) in enumerate(pairs):
            w = t.index.shape[1]
            index[:, k, :w], weight[:, k, :w] = t.index, t.weight
            index[:, k, w:] = t.index[:, :1]
    r = np.stack([rr.reshape(-1) for rr in checked], axis=1)

    worst = mode == "worst"

    def kernel(q, q_next, v, v_next, history, done, step):
        return fqi_kernel.robust_sweeps(index, weight, r, q, q_next, v, v_next, gamma, delta,
                                        history, done, step, min_iterations, worst)

    def rows(q, q_next, v, v_next, lo, hi):
        return fqi_kernel.robust_rows(index, weight, r, q, q_next, v, v_next, gamma, worst,
                                      lo, hi)
    with _pool(threads) as pool:
        run = _threaded(rows, pool, n_x, threads, delta, min_iterations) if threads > 1 \
            else kernel
        return iterate(run, (n_x, n_u), in_place=False, delta=delta,
                        max_iterations=max_iterations, min_iterations=min_iterations,
                        callback=callback)


def _check_rewards(shape: tuple, rewards, gamma, delta) -> np.ndarray:
    """Rewards as float (N_X, N_U) matching a T of ``shape``, with gamma and delta in
    range, or a clear error."""
    rewards = np.ascontiguousarray(rewards, dtype=float)
    if rewards.ndim != 2:
        raise ValueError(f"rewards must have shape (N_X, N_U), got {rewards.shape}")
    n_x, n_u = rewards.shape
    if tuple(shape) != (n_x * n_u, n_x):
        raise ValueError(f"transition matrix of shape {tuple(shape)} does not match "
                         f"rewards of shape {rewards.shape}")
    if not (0.0 < gamma < 1.0):
        raise ValueError(f"gamma must lie in (0, 1), got {gamma}")
    if not delta > 0.0:
        raise ValueError(f"delta must be positive, got {delta}")
    return rewards


def _check(transitions, rewards, gamma, delta, state_shape, weights=None) -> tuple:
    """(TransitionTable in ``weights``, rewards as float (N_X, N_U)), or a clear error."""
    if weights is not None:
        check_weights(weights)
    rewards = _check_rewards(transitions.shape, rewards, gamma, delta)
    n_x = rewards.shape[0]
    if isinstance(transitions, TransitionTable):
        if state_shape is not None:
            transitions = dataclasses.replace(transitions,
                                              state_shape=check_state_shape(state_shape, n_x))
        return (transitions if weights is None else transitions.astype(weights)), rewards
    if not sp.issparse(transitions):
        raise TypeError(f"transitions must be a scipy sparse matrix or a TransitionTable, "
                        f"got {type(transitions).__name__}")
    return fixed_width(transitions, state_shape, weights=weights or "float64"), rewards
