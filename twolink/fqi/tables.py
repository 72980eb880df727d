"""The transition tables of Alg. 1: T, the memberships mu_m~(f(c_m, u_j)) of the state each
(bin centre, action) pair reaches.

T has shape (N_X * N_U, N_X): as a scipy CSR matrix (:func:`transition_matrix`, for peers
and references) or in the fixed-width layout the compiled sweeps read
(:class:`TransitionTable`, at most 2**d memberships per row; K models side by side for the
robust sweeps: :class:`RobustTable`). The weights are float64, the reference, or float32
on request (:data:`WEIGHTS`: a third fewer bytes, Q within the weights' round-off).
"""
from __future__ import annotations

import dataclasses
from typing import Optional, Sequence

import numpy as np
import scipy.sparse as sp

from twolink.fqi import _kernel as fqi_kernel
from twolink.fqi.fuzzy import Grid

#: Precisions of the fixed-width tables' weights: ``float64`` (the reference: each row summed
#: in index order, Q equal to the scipy path bit for bit) or ``float32`` (opt-in: each
#: membership rounded once to float32, a third less memory for T; the products and sums
#: stay float64 in index order, so Q moves by the weights' round-off only, below
#: delta / 100 on the paper's problems: ``tests/fqi/test_fast_sweeps.py``). float32 saves
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
        object.__setattr__(self, "state_shape", check_state_shape(self.state_shape, self.n_states))

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
        weight = weights_as(self.weight, check_weights(weights).name)
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
    return TransitionTable(index, weight, n_states, check_state_shape(state_shape, n_states))


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


def check_state_shape(state_shape, n_states: int) -> Optional[tuple]:
    """``state_shape`` as a tuple of ints that holds ``n_states`` states (None stays
    None), or a ValueError."""
    if state_shape is None:
        return None
    state_shape = tuple(int(n) for n in state_shape)
    if int(np.prod(state_shape)) != n_states:
        raise ValueError(f"state shape {state_shape} does not hold {n_states} states")
    return state_shape


def weights_as(weight: np.ndarray, weights: Optional[str]) -> np.ndarray:
    """``weight`` in the precision ``weights`` names (None: as it is)."""
    if weights is None:
        return weight
    dtype = check_weights(weights)
    if dtype == weight.dtype:
        return weight
    _check_not_widened(weight.dtype, dtype)
    return weight.astype(dtype)
