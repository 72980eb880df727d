"""The opt-in fast paths of twolink.fqi.iteration against the float64 one-thread reference: float32
weights (WEIGHTS) and sweeps split over threads.

float32 tables are the float64 tables rounded once; the sweeps read them with float64
products and sums in index order, so they equal the scipy sweep over the rounded T bit
for bit, and differ from the reference Q by the weights' round-off: below delta / 100 on
the paper's problems. Greedy actions: see ``test_float32_greedy_actions``. Threads change
nothing: each row is summed as with one thread.
"""
import dataclasses
import os

import numpy as np
import pytest
import scipy.sparse as sp
from reference_fqi import fuzzy_q_iteration_robust_reference, fuzzy_q_iteration_scipy

from twolink.arm.parameters import DELTA, TABLE_I
from twolink.synthesis.problems import (
    agent1_problem,
    agent2_problem,
    centralized_problem,
    solve,
)
from twolink.fqi.fuzzy import Axis
from twolink.fqi.iteration import fuzzy_q_iteration, fuzzy_q_iteration_robust
from twolink.fqi.tables import (
    WEIGHTS,
    check_weights,
    fixed_width,
    robust_table,
    transition_matrix,
    transition_table,
)
from twolink.policy.fuzzy_policy import TIE_TOLERANCE, greedy_indices

PAPER = ("centralized", "agent2", "agent1 frozen", "agent1 propagated")
#: Bins whose greedy action (shipped tie rule, tolerance 1e-9) moves with float32 weights:
#: agent 1's 180 bins whose best two Q-values are exactly equal in float64 (README, "How
#: sensitive the paper's policies are to round-off"), no other.
FLIPS_AT_TIE_TOLERANCE = {"centralized": 0, "agent2": 0, "agent1 frozen": 180,
                          "agent1 propagated": 0}


@pytest.fixture(scope="module")
def problems():
    return {"centralized": centralized_problem(), "agent2": agent2_problem(),
            "agent1 frozen": agent1_problem(None),
            "agent1 propagated": agent1_problem(solve(agent2_problem()), context="propagated")}


@pytest.fixture(scope="module")
def solved(problems):
    """Each paper problem swept with float64 and with float32 weights."""
    out = {}
    for name, p in problems.items():
        t64 = transition_table(p.grid, p.next_points)
        t32 = transition_table(p.grid, p.next_points, weights="float32")
        out[name] = (t64, t32, fuzzy_q_iteration(t64, p.rewards),
                     fuzzy_q_iteration(t32, p.rewards))
    return out


def _coarse_models(k):
    axes = (Axis("theta1", tuple(np.deg2rad([-180, -60, 0, 30, 100])), circular=True),
            Axis("dtheta1", tuple(np.deg2rad([-360, 0, 40, 360]))),
            Axis("theta2", tuple(np.deg2rad([-180, -20, 0, 90])), circular=True))
    return [agent1_problem(None, dataclasses.replace(TABLE_I, tau1_max=TABLE_I.tau1_max * s),
                           axes=axes) for s in np.linspace(0.5, 1.5, k)]


@pytest.mark.parametrize("name", PAPER)
def test_float32_table_is_the_float64_table_rounded_once(problems, solved, name):
    p = problems[name]
    t64, t32, _, _ = solved[name]
    assert (t64.weights, t32.weights) == WEIGHTS
    assert t32.weight.dtype == np.float32 and t32.index.dtype == np.int32
    np.testing.assert_array_equal(t32.index, t64.index)
    np.testing.assert_array_equal(t32.weight, t64.weight.astype(np.float32))
    assert t32.nbytes == t64.nbytes * 2 // 3 and t32.state_shape == p.grid.shape
    via_csr = fixed_width(transition_matrix(p.grid, p.next_points), p.grid.shape,
                          weights="float32")
    np.testing.assert_array_equal(via_csr.weight, t32.weight)
    assert t64.astype("float32").weight.tobytes() == t32.weight.tobytes()
    assert t32.astype("float32") is t32


@pytest.mark.parametrize("name", PAPER)
def test_float32_sweeps_are_the_scipy_sweeps_of_the_rounded_matrix(problems, solved, name):
    """Held against the scipy reference on T with float32-rounded memberships: equal bit
    for bit (float64 products, index order), so only the weights were rounded."""
    p = problems[name]
    _, t32, _, res32 = solved[name]
    rounded = transition_matrix(p.grid, p.next_points)
    rounded.data = rounded.data.astype(np.float32).astype(float)
    q_ref, n_ref, hist_ref = fuzzy_q_iteration_scipy(rounded, p.rewards)
    assert res32.iterations == n_ref
    np.testing.assert_array_equal(res32.q, q_ref)
    np.testing.assert_array_equal(res32.history, hist_ref)


@pytest.mark.parametrize("name", PAPER)
def test_float32_q_is_within_a_hundredth_of_delta(solved, name):
    _, _, res64, res32 = solved[name]
    assert res32.converged and res32.iterations == res64.iterations
    err = np.abs(res32.q - res64.q).max()
    assert 0 < err < DELTA / 100           # the float32 path was taken, and is close
    assert res32.q.shape == res64.q.shape and res32.q.dtype == np.float64


@pytest.mark.parametrize("name", PAPER)
def test_float32_greedy_actions(solved, name):
    """The tie tolerance 1e-9 lies far below float32 round-off (here up to 2.2e-5 in Q),
    so "the same greedy actions" can only mean: every bin whose best action leads the
    runner-up by more than the Q error keeps it. It does; the bins that move are the ones
    tied within twice the error plus the tolerance (agent 1's 180 exact ties), and with a
    tolerance at the error's size (1e-5, 1e-4 = delta / 100) no bin moves. Read with a
    tolerance of 1e-5 (below every genuine gap, >= 1.6e-5), the float32 Q picks the shipped
    rule's action (float64, 1e-9) in every bin."""
    _, _, res64, res32 = solved[name]
    err = np.abs(res32.q - res64.q).max()
    ref = greedy_indices(res64.q, TIE_TOLERANCE)
    moved = ref != greedy_indices(res32.q, TIE_TOLERANCE)
    assert int(moved.sum()) == FLIPS_AT_TIE_TOLERANCE[name]
    top = np.sort(res64.q, axis=1)
    assert np.all(top[moved, -1] - top[moved, -2] <= 2 * err + TIE_TOLERANCE)
    for tol in (1e-5, DELTA / 100):
        np.testing.assert_array_equal(greedy_indices(res32.q, tol), greedy_indices(res64.q, tol))
    np.testing.assert_array_equal(greedy_indices(res32.q, 1e-5), ref)


def test_default_stays_float64_and_bit_identical(problems, solved):
    p = problems["agent2"]
    t64, t32, res64, _ = solved["agent2"]
    assert t64.weight.dtype == np.float64
    again = fuzzy_q_iteration(t64, p.rewards, weights="float64")
    np.testing.assert_array_equal(again.q, res64.q)
    via_sparse = fuzzy_q_iteration(transition_matrix(p.grid, p.next_points), p.rewards,
                                   weights="float32")
    np.testing.assert_array_equal(via_sparse.q, fuzzy_q_iteration(t32, p.rewards).q)
    rounded_here = fuzzy_q_iteration(t64, p.rewards, weights="float32")
    np.testing.assert_array_equal(rounded_here.q, fuzzy_q_iteration(t32, p.rewards).q)


def test_float32_serial_sweeps_stay_close(problems, solved):
    p = problems["agent2"]
    t64, t32, _, _ = solved["agent2"]
    a = fuzzy_q_iteration(t64, p.rewards, sweeps="serial")
    b = fuzzy_q_iteration(t32, p.rewards, sweeps="serial")
    assert a.iterations == b.iterations == 49
    assert 0 < np.abs(a.q - b.q).max() < DELTA / 100


@pytest.mark.parametrize("mode", ["worst", "mean"])
def test_float32_robust_sweeps(mode):
    models = _coarse_models(3)
    grid, rewards = models[0].grid, [p.rewards for p in models]
    both = robust_table(grid, [p.next_points for p in models], weights="float32")
    both64 = robust_table(grid, [p.next_points for p in models])
    assert both.weights == "float32" and both.nbytes == both64.nbytes * 2 // 3
    np.testing.assert_array_equal(both.weight, both64.weight.astype(np.float32))
    tables = [transition_table(p.grid, p.next_points, weights="float32") for p in models]
    a = fuzzy_q_iteration_robust(both, rewards, mode=mode)
    b = fuzzy_q_iteration_robust(tables, rewards, mode=mode)
    c = fuzzy_q_iteration_robust(both64, rewards, mode=mode, weights="float32")
    np.testing.assert_array_equal(a.q, b.q)
    np.testing.assert_array_equal(a.q, c.q)
    rounded = []
    for p in models:
        t = transition_matrix(p.grid, p.next_points)
        t.data = t.data.astype(np.float32).astype(float)
        rounded.append(t)
    q_ref, n_ref = fuzzy_q_iteration_robust_reference(rounded, rewards, mode=mode)
    assert a.iterations == n_ref
    np.testing.assert_allclose(a.q, q_ref, rtol=0, atol=1e-12)
    exact = fuzzy_q_iteration_robust(both64, rewards, mode=mode)
    assert a.iterations == exact.iterations
    assert 0 < np.abs(a.q - exact.q).max() < DELTA / 100


def test_unknown_or_widened_weights_are_refused():
    models = _coarse_models(2)
    p = models[0]
    t32 = transition_table(p.grid, p.next_points, weights="float32")
    t64 = transition_table(p.grid, p.next_points)
    unknown = r"^unknown weights 'float16'; choose one of float64, float32$"
    with pytest.raises(ValueError, match=unknown):
        transition_table(p.grid, p.next_points, weights="float16")
    with pytest.raises(ValueError, match=unknown):
        robust_table(p.grid, [p.next_points], weights="float16")
    with pytest.raises(ValueError, match=unknown):
        fixed_width(sp.csr_matrix(t64.tocsr()), weights="float16")
    with pytest.raises(ValueError, match=unknown):
        fuzzy_q_iteration(t64, p.rewards, weights="float16")
    with pytest.raises(ValueError, match=unknown):
        fuzzy_q_iteration_robust([t64], [p.rewards], weights="float16")
    with pytest.raises(ValueError, match=unknown):
        t64.astype("float16")
    with pytest.raises(ValueError, match="unknown weights"):
        transition_table(p.grid, p.next_points, weights=np.float32)
    widened = r"^a table of float32 weights cannot give float64 sweeps: build it with " \
              r"weights='float64'$"
    with pytest.raises(ValueError, match=widened):
        fuzzy_q_iteration(t32, p.rewards, weights="float64")
    with pytest.raises(ValueError, match=widened):
        t32.astype("float64")
    both32 = robust_table(p.grid, [m.next_points for m in models], weights="float32")
    with pytest.raises(ValueError, match=widened):
        fuzzy_q_iteration_robust(both32, [m.rewards for m in models], weights="float64")
    with pytest.raises(ValueError, match="mix float32 and float64 weights"):
        fuzzy_q_iteration_robust([t32, t64], [p.rewards, p.rewards])
    assert check_weights("float32") == np.float32


@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="threads=2 needs two cores")
@pytest.mark.parametrize("weights", WEIGHTS)
def test_threaded_sweeps_equal_one_thread_bit_for_bit(problems, weights):
    """Bins split over two threads: every row is summed as with one, so Q, the changes and
    the sweep count are the same bit for bit (plain and robust sweeps)."""
    p = problems["agent1 frozen"]
    t = transition_table(p.grid, p.next_points, weights=weights)
    one = fuzzy_q_iteration(t, p.rewards)
    seen = []
    two = fuzzy_q_iteration(t, p.rewards, threads=2, callback=lambda ell, ch: seen.append(ch))
    assert two.iterations == one.iterations and seen == list(one.history)
    np.testing.assert_array_equal(two.q, one.q)
    np.testing.assert_array_equal(two.history, one.history)
    models = _coarse_models(3)
    both = robust_table(models[0].grid, [m.next_points for m in models], weights=weights)
    for mode in ("worst", "mean"):
        a = fuzzy_q_iteration_robust(both, [m.rewards for m in models], mode=mode)
        b = fuzzy_q_iteration_robust(both, [m.rewards for m in models], mode=mode, threads=2)
        assert a.iterations == b.iterations
        np.testing.assert_array_equal(a.q, b.q)


def test_bad_thread_counts_are_refused():
    p = _coarse_models(1)[0]
    t = transition_table(p.grid, p.next_points)
    cores = os.cpu_count() or 1
    for bad in (0, -1, 2.0, True, cores + 1, 10**9):
        with pytest.raises(ValueError, match=rf"^threads must be a whole number in \[1, {cores}\]"):
            fuzzy_q_iteration(t, p.rewards, threads=bad)
        with pytest.raises(ValueError, match="threads must be a whole number"):
            fuzzy_q_iteration_robust([t], [p.rewards], threads=bad)
    if cores >= 2:
        with pytest.raises(ValueError, match="serial sweeps .* cannot be split over threads"):
            fuzzy_q_iteration(t, p.rewards, sweeps="serial", threads=2)
