"""Fuzzy Q-iteration, Alg. 1 of the paper.

Q_{l+1}(m, u) = rho(c_m, u) + gamma * sum_m~ mu_m~(f(c_m, u)) max_u~ Q_l(m~, u~)

The transitions f(c_m, u_j) of every (bin centre, action) pair are computed once and
stored as the membership matrix T of shape (N_X * N_U, N_X): as a scipy CSR matrix
(:func:`transition_matrix`, for peers and references) or in the fixed-width layout the
compiled sweeps read (:class:`TransitionTable`, at most 2**d memberships per row; K models
side by side for the robust sweeps: :class:`RobustTable`). The weights are float64, the
reference, or float32 on request (:data:`WEIGHTS`: a third fewer bytes, Q within the
weights' round-off). Synchronous and robust sweeps can split their bins over threads
(``threads=``; the same Q bit for bit).
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

from twolink import fqi_kernel
from twolink.fuzzy import Grid
from twolink.parameters import DELTA, GAMMA

SWEEPS = ("synchronous", "serial")
ROBUST_MODES = ("worst", "mean")
#: Precisions of the fixed-width tables' weights: ``float64`` (the reference: each row summed
#: in index order, Q equal to the scipy path bit for bit) or ``float32`` (opt-in: each
#: membership rounded once to float32, a third less memory for T; the products and sums
#: stay float64 in index order, so Q moves by the weights' round-off only, below
#: delta / 100 on the paper's problems: ``tests/test_fast_sweeps.py``). float32 saves
#: memory more than time: with T in the cache a sweep is bound by instructions per entry
#: and the conversion adds one; with T streamed from memory it gains a little (README,
#: *Performance*).
WEIGHTS = ("float64", "float32")


def check_weights(weights: str) -> np.dtype:
    """The numpy dtype of a :data:`WEIGHTS` name, or a ValueError naming the choices."""
    if not isinstance(weights, str) or weights not in WEIGHTS:
        raise ValueError(f"unknown weights {weights!r}; choose one of {', '.join(WEIGHTS)}")
    return np.dtype(weights)


def transition_matrix(grid: Grid, next_points: np.ndarray) -> sp.csr_matrix:
    """Sparse T with T[m * N_U + j, m~] = mu_m~(f(c_m, u_j)).

    ``next_points`` has shape (N_X, N_U, d): the state reached from each bin centre
    under each action, already in the grid's coordinates.
    """
    n_x, n_u, d = _check_points(grid, next_points)
    idx, w = grid.memberships(next_points.reshape(n_x * n_u, d))
    k = idx.shape[1]
    indptr = np.arange(0, n_x * n_u * k + 1, k)
    t = sp.csr_matrix((w.reshape(-1), idx.reshape(-1), indptr), shape=(n_x * n_u, n_x))
    t.sum_duplicates()
    t.eliminate_zeros()
    return t


def _checked_layout(table, axes: str) -> None:
    """Store ``table.index`` as contiguous int32 and ``table.weight`` as float64 (float32
    weights stay float32, :data:`WEIGHTS`) of one shape with the axes named in ``axes``.
    The compiled sweeps do not check bounds, so a table whose bin indices would read
    outside V is refused here."""
    index = np.ascontiguousarray(table.index, dtype=np.int32)
    weight = np.asarray(table.weight)
    weight = np.ascontiguousarray(weight, dtype=np.float32 if weight.dtype == np.float32
                                  else float)
    if index.ndim != axes.count(",") + 1 or index.shape != weight.shape:
        raise ValueError(f"index {index.shape} and weight {weight.shape} must be one "
                         f"{axes} shape")
    if index.size and (index.min() < 0 or index.max() >= table.n_states):
        raise ValueError(f"bin indices must lie in [0, {table.n_states})")
    object.__setattr__(table, "index", index)
    object.__setattr__(table, "weight", weight)


@dataclasses.dataclass(frozen=True)
class TransitionTable:
    """T in fixed width: row m * N_U + j lists the bins m~ with mu_m~(f(c_m, u_j)) > 0
    in increasing order (``index``, int32) and their memberships (``weight``, float64 or
    float32: :data:`WEIGHTS`), padded with zero weights to the widest row; ``state_shape``
    is the grid's shape when known (serial sweeps visit the bins in its column-major
    order)."""

    index: np.ndarray
    weight: np.ndarray
    n_states: int
    state_shape: Optional[tuple] = None

    def __post_init__(self):
        _checked_layout(self, "(rows, width)")
        object.__setattr__(self, "state_shape", _shape(self.state_shape, self.n_states))

    @property
    def shape(self) -> tuple:
        return (self.index.shape[0], self.n_states)

    @property
    def nnz(self) -> int:
        return int(np.count_nonzero(self.weight))

    @property
    def nbytes(self) -> int:
        return self.index.nbytes + self.weight.nbytes

    @property
    def weights(self) -> str:
        """The weights' precision, a :data:`WEIGHTS` name."""
        return self.weight.dtype.name

    def astype(self, weights: str) -> "TransitionTable":
        """This table with its weights in ``weights`` (:data:`WEIGHTS`): itself when they
        are already, a copy rounded to float32; float32 weights cannot be made float64
        again (their lost digits would pass for the reference's), a ValueError."""
        weight = _weights_as(self.weight, check_weights(weights).name)
        return self if weight is self.weight else dataclasses.replace(self, weight=weight)

    def tocsr(self) -> sp.csr_matrix:
        rows = np.repeat(np.arange(self.shape[0]), self.index.shape[1])
        t = sp.csr_matrix((self.weight.reshape(-1), (rows, self.index.reshape(-1))),
                          shape=self.shape)
        t.eliminate_zeros()
        return t


def fixed_width(transitions: sp.spmatrix, state_shape: Optional[tuple] = None, *,
                weights: str = "float64") -> TransitionTable:
    """The :class:`TransitionTable` of a sparse T (summed duplicates, zeros dropped), its
    weights in ``weights`` (:data:`WEIGHTS`)."""
    dtype = check_weights(weights)
    t = sp.csr_matrix(transitions, dtype=float, copy=True)
    t.sum_duplicates()
    t.eliminate_zeros()
    n_rows, n_states = t.shape
    counts = np.diff(t.indptr)
    width = max(1, int(counts.max(initial=0)))
    rows = np.repeat(np.arange(n_rows), counts)
    cols = np.arange(t.nnz) - np.repeat(t.indptr[:-1], counts)
    index = np.zeros((n_rows, width), dtype=np.int32)
    weight = np.zeros((n_rows, width), dtype=dtype)
    index[rows, cols] = t.indices
    weight[rows, cols] = t.data
    _pad_with_first(index, counts)
    return TransitionTable(index, weight, n_states, _shape(state_shape, n_states))


def transition_table(grid: Grid, next_points: np.ndarray, *,
                     weights: str = "float64") -> TransitionTable:
    """T of :func:`transition_matrix` written straight into the fixed-width layout by a
    compiled pass over the points (equal entry for entry, bit for bit, to
    ``fixed_width(transition_matrix(...), weights=weights)``); ``weights="float32"``
    rounds each membership once, as it is written (:data:`WEIGHTS`)."""
    dtype = check_weights(weights)
    n_x, n_u, d = _check_points(grid, next_points)
    index = np.empty((n_x * n_u, 2 ** d), dtype=np.int32)
    weight = np.empty((n_x * n_u, 2 ** d), dtype=dtype)
    width = _membership_rows(grid, next_points, index, weight)
    if width < 2 ** d:
        index = np.ascontiguousarray(index[:, :width])
        weight = np.ascontiguousarray(weight[:, :width])
    return TransitionTable(index, weight, grid.size, grid.shape)


def _membership_rows(grid: Grid, next_points: np.ndarray, index: np.ndarray,
                     weight: np.ndarray) -> int:
    """Fill ``index``/``weight`` (rows, 2**d), views allowed, with the memberships of the
    points (:func:`fqi_kernel.membership_rows`); returns the widest row's count."""
    n_x, n_u, d = next_points.shape
    sizes = np.array(grid.shape, dtype=np.int64)
    centers = np.zeros((d, int(sizes.max())))
    for a, axis in enumerate(grid.axes):
        centers[a, :axis.size] = axis.centers
    circular = np.array([axis.circular for axis in grid.axes])
    points = np.ascontiguousarray(next_points, dtype=float).reshape(n_x * n_u, d)
    counts = fqi_kernel.membership_rows(points, centers, sizes, circular, index, weight)
    return max(1, int(counts.max(initial=0)))


@dataclasses.dataclass(frozen=True)
class RobustTable:
    """The K models' T side by side, as the robust sweeps read them: row m * N_U + j of
    model k is ``index[row, k]``/``weight[row, k]`` (rows, K, width), each model's row as
    in :class:`TransitionTable` (increasing bins, zero-weight padding, float64 or float32
    weights)."""

    index: np.ndarray
    weight: np.ndarray
    n_states: int

    def __post_init__(self):
        _checked_layout(self, "(rows, models, width)")

    @property
    def models(self) -> int:
        return self.index.shape[1]

    @property
    def nbytes(self) -> int:
        return self.index.nbytes + self.weight.nbytes

    @property
    def weights(self) -> str:
        """The weights' precision, a :data:`WEIGHTS` name."""
        return self.weight.dtype.name

    @property
    def nnz(self) -> int:
        return int(np.count_nonzero(self.weight))

    def table(self, k: int) -> TransitionTable:
        """Model k's :class:`TransitionTable` (a copy)."""
        return TransitionTable(self.index[:, k], self.weight[:, k], self.n_states)


def robust_table(grid: Grid, next_points: Sequence[np.ndarray], *,
                 weights: str = "float64") -> RobustTable:
    """The :class:`RobustTable` of K models' points (each (N_X, N_U, d) on ``grid``),
    memberships written straight into place by the compiled pass (no per-model tables, no
    copy): each model's rows equal :func:`transition_table`'s (with the same ``weights``)
    bit for bit."""
    dtype = check_weights(weights)
    if len(next_points) == 0:
        raise ValueError("need the points of at least one model")
    shapes = {_check_points(grid, p) for p in next_points}
    if len(shapes) != 1:
        raise ValueError(f"the models' points differ in shape: {sorted(shapes)}")
    n_x, n_u, d = shapes.pop()
    index = np.empty((n_x * n_u, len(next_points), 2 ** d), dtype=np.int32)
    weight = np.empty((n_x * n_u, len(next_points), 2 ** d), dtype=dtype)
    width = max(_membership_rows(grid, p, index[:, k], weight[:, k])
                for k, p in enumerate(next_points))
    if width < 2 ** d:
        index, weight = index[:, :, :width], weight[:, :, :width]
    return RobustTable(index, weight, grid.size)


def _check_points(grid: Grid, next_points: np.ndarray) -> tuple:
    n_x, n_u, d = next_points.shape
    if n_x != grid.size or d != len(grid.axes):
        raise ValueError(f"next_points of shape {next_points.shape} do not match a grid "
                         f"of {grid.size} bins over {len(grid.axes)} dimensions")
    return n_x, n_u, d


def _check_not_widened(have: np.dtype, want: np.dtype) -> None:
    if want.itemsize > have.itemsize:
        raise ValueError(f"a table of {have.name} weights cannot give {want.name} sweeps: "
                         f"build it with weights={want.name!r}")


def _pad_with_first(index: np.ndarray, counts: np.ndarray) -> None:
    """Padding entries (zero weight) point at the row's first bin, already in cache."""
    pad = np.arange(index.shape[1]) >= counts[:, None]
    index[pad] = np.broadcast_to(index[:, :1], index.shape)[pad]


def _shape(state_shape, n_states: int) -> Optional[tuple]:
    if state_shape is None:
        return None
    state_shape = tuple(int(n) for n in state_shape)
    if int(np.prod(state_shape)) != n_states:
        raise ValueError(f"state shape {state_shape} does not hold {n_states} states")
    return state_shape


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
    need the grid's shape: from a :func:`transition_table` or as ``state_shape``.
    ``min_iterations`` forces at least that many sweeps (for benchmarks doing equal work);
    ``callback(l, change)`` is called after each sweep. ``weights`` (:data:`WEIGHTS`) is
    the precision the sweeps read T in: None, the table's own (a sparse T: float64);
    ``"float32"`` rounds a float64 table's weights first. ``threads`` > 1 splits each
    synchronous sweep's bins over that many threads (the same Q bit for bit; serial
    sweeps are sequential by definition).
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
    if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) \
            or not 1 <= threads <= cores:
        raise ValueError(f"threads must be a whole number in [1, {cores}] (this machine's "
                         f"cores), got {threads!r}")
    return int(threads)


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
    ``transitions`` is the K matrices or tables, or a :class:`RobustTable` of all K;
    ``weights`` and ``threads`` as in :func:`fuzzy_q_iteration`.
    """
    threads = check_threads(threads)
    if mode not in ROBUST_MODES:
        raise ValueError(f"unknown robust mode {mode!r}; choose one of {', '.join(ROBUST_MODES)}")
    n_models = transitions.models if isinstance(transitions, RobustTable) else len(transitions)
    if n_models == 0 or n_models != len(rewards):
        raise ValueError(f"need one reward table per transition matrix, got "
                         f"{n_models} matrices and {len(rewards)} reward tables")
    if isinstance(transitions, RobustTable):
        index, weight = transitions.index, _weights_as(transitions.weight, weights)
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


def _weights_as(weight: np.ndarray, weights: Optional[str]) -> np.ndarray:
    """``weight`` in the precision ``weights`` names (None: as it is)."""
    if weights is None:
        return weight
    dtype = check_weights(weights)
    if dtype == weight.dtype:
        return weight
    _check_not_widened(weight.dtype, dtype)
    return weight.astype(dtype)


def _check(transitions, rewards, gamma, delta, state_shape, weights=None) -> tuple:
    """(TransitionTable in ``weights``, rewards as float (N_X, N_U)), or a clear error."""
    if weights is not None:
        check_weights(weights)
    rewards = _check_rewards(transitions.shape, rewards, gamma, delta)
    n_x = rewards.shape[0]
    if isinstance(transitions, TransitionTable):
        if state_shape is not None:
            transitions = dataclasses.replace(transitions,
                                              state_shape=_shape(state_shape, n_x))
        return (transitions if weights is None else transitions.astype(weights)), rewards
    if not sp.issparse(transitions):
        raise TypeError(f"transitions must be a scipy sparse matrix or a TransitionTable, "
                        f"got {type(transitions).__name__}")
    return fixed_width(transitions, state_shape, weights=weights or "float64"), rewards
