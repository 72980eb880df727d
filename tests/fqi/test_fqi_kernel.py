"""The compiled sweeps (twolink.fqi._kernel) against the scipy sweep and plain loops of Alg. 1."""
import dataclasses

import numpy as np
import pytest
import scipy.sparse as sp
from reference_fqi import (
    fuzzy_q_iteration_robust_reference,
    fuzzy_q_iteration_scipy,
    fuzzy_q_iteration_serial_reference,
)

from twolink.arm.parameters import TABLE_I
from twolink.synthesis.problems import (
    agent1_problem,
    agent2_problem,
    centralized_problem,
    solve,
)
from twolink.fqi.fuzzy import Axis, Grid
from twolink.fqi.iteration import fuzzy_q_iteration, fuzzy_q_iteration_robust
from twolink.fqi.tables import (
    RobustTable,
    TransitionTable,
    fixed_width,
    robust_table,
    transition_matrix,
    transition_table,
)
from twolink.policy.fuzzy_policy import TIE_TOLERANCE, greedy_indices


def _coarse_agent1(context="frozen", agent2=None):
    axes = (Axis("theta1", tuple(np.deg2rad([-180, -60, 0, 30, 100])), circular=True),
            Axis("dtheta1", tuple(np.deg2rad([-360, 0, 40, 360]))),
            Axis("theta2", tuple(np.deg2rad([-180, -20, 0, 90])), circular=True))
    return agent1_problem(agent2, context=context, axes=axes)


@pytest.fixture(scope="module")
def agent2():
    return solve(agent2_problem())


@pytest.fixture(scope="module")
def paper_problems(agent2):
    return {"centralized": centralized_problem(), "agent2": agent2_problem(),
            "agent1 frozen": agent1_problem(None),
            "agent1 propagated": agent1_problem(agent2, context="propagated")}


PAPER = ("centralized", "agent2", "agent1 frozen", "agent1 propagated")


@pytest.mark.parametrize("name", PAPER)
def test_table_is_the_csr_matrix_in_fixed_width(paper_problems, name):
    p = paper_problems[name]
    table = transition_table(p.grid, p.next_points)
    csr = transition_matrix(p.grid, p.next_points)
    assert table.index.dtype == np.int32 and table.state_shape == p.grid.shape
    assert table.index.shape[1] <= 2 ** len(p.grid.axes)
    via_csr = fixed_width(csr, p.grid.shape)
    np.testing.assert_array_equal(table.index, via_csr.index)
    np.testing.assert_array_equal(table.weight, via_csr.weight)
    t = table.tocsr()
    assert t.nnz == csr.nnz == table.nnz
    np.testing.assert_array_equal(t.indptr, csr.indptr)
    np.testing.assert_array_equal(t.indices, csr.indices)
    np.testing.assert_array_equal(t.data, csr.data)


@pytest.mark.parametrize("name", PAPER)
def test_compiled_sweeps_equal_the_scipy_sweeps_bit_for_bit(paper_problems, name):
    p = paper_problems[name]
    q_ref, n_ref, hist_ref = fuzzy_q_iteration_scipy(transition_matrix(p.grid, p.next_points),
                                                     p.rewards)
    res = fuzzy_q_iteration(transition_table(p.grid, p.next_points), p.rewards)
    assert res.converged and res.iterations == n_ref
    np.testing.assert_array_equal(res.q, q_ref)
    np.testing.assert_array_equal(res.history, hist_ref)
    np.testing.assert_array_equal(greedy_indices(res.q, TIE_TOLERANCE),
                                  greedy_indices(q_ref, TIE_TOLERANCE))


def test_a_csr_matrix_and_a_table_give_the_same_sweeps():
    p = _coarse_agent1()
    a = fuzzy_q_iteration(transition_matrix(p.grid, p.next_points), p.rewards)
    b = fuzzy_q_iteration(transition_table(p.grid, p.next_points), p.rewards)
    seen = []
    c = fuzzy_q_iteration(transition_table(p.grid, p.next_points), p.rewards,
                          callback=lambda ell, ch: seen.append((ell, ch)))
    assert a.iterations == b.iterations == c.iterations
    np.testing.assert_array_equal(a.q, b.q)
    np.testing.assert_array_equal(a.q, c.q)
    assert seen == list(zip(range(1, c.iterations + 1), c.history))


@pytest.mark.parametrize("context", ["frozen", "propagated"])
def test_serial_sweeps_equal_the_alg1_loop_in_matlab_order(agent2, context):
    p = _coarse_agent1(context, agent2)
    q_ref, n_ref = fuzzy_q_iteration_serial_reference(p.grid, p.next_points, p.rewards)
    res = fuzzy_q_iteration(transition_table(p.grid, p.next_points), p.rewards,
                            sweeps="serial")
    assert res.converged and res.iterations == n_ref
    np.testing.assert_allclose(res.q, q_ref, rtol=0, atol=1e-12)
    # a callback (one sweep per compiled call) changes nothing
    seen = []
    again = fuzzy_q_iteration(transition_matrix(p.grid, p.next_points), p.rewards,
                              sweeps="serial", state_shape=p.grid.shape,
                              callback=lambda ell, ch: seen.append(ell))
    np.testing.assert_array_equal(again.q, res.q)
    assert seen == list(range(1, res.iterations + 1))


def test_serial_sweeps_reach_the_papers_sweep_counts(paper_problems):
    """Serial sweeps give the paper's 49 (agent 2) and 192 (agent 1) sweeps."""
    counts = {}
    for name in ("centralized", "agent2", "agent1 frozen"):
        p = paper_problems[name]
        res = fuzzy_q_iteration(transition_table(p.grid, p.next_points), p.rewards,
                                sweeps="serial")
        assert res.converged
        counts[name] = res.iterations
    assert counts == {"centralized": 73, "agent2": 49, "agent1 frozen": 192}


def test_serial_and_synchronous_sweeps_reach_the_same_fixed_point():
    p = _coarse_agent1()
    t = transition_table(p.grid, p.next_points)
    a = fuzzy_q_iteration(t, p.rewards, delta=1e-11)
    b = fuzzy_q_iteration(t, p.rewards, delta=1e-11, sweeps="serial")
    assert b.iterations < a.iterations
    np.testing.assert_allclose(a.q, b.q, rtol=0, atol=1e-9)


def _perturbed_models(k):
    """K versions of the coarse agent-1 problem, link 1's torque limit scaled 0.5x to 1.5x."""
    axes = _coarse_agent1().grid.axes[:3]
    return [agent1_problem(None, dataclasses.replace(TABLE_I, tau1_max=TABLE_I.tau1_max * s),
                           axes=axes) for s in np.linspace(0.5, 1.5, k)]


@pytest.mark.parametrize("mode", ["worst", "mean"])
def test_robust_sweeps_equal_a_numpy_reference(mode):
    models = _perturbed_models(3)
    mats = [transition_matrix(p.grid, p.next_points) for p in models]
    rewards = [p.rewards for p in models]
    q_ref, n_ref = fuzzy_q_iteration_robust_reference(mats, rewards, mode=mode)
    tables = [transition_table(p.grid, p.next_points) for p in models]
    res = fuzzy_q_iteration_robust(tables, rewards, mode=mode)
    assert res.converged and res.iterations == n_ref
    np.testing.assert_allclose(res.q, q_ref, rtol=0, atol=1e-12)
    one = fuzzy_q_iteration(tables[1], rewards[1])
    single = fuzzy_q_iteration_robust(tables[1:2], rewards[1:2], mode=mode)
    np.testing.assert_array_equal(single.q, one.q)      # K = 1 is Alg. 1 itself
    if mode == "worst":                                  # the worst case is below each model
        for t, r in zip(tables, rewards):
            assert np.all(res.q <= fuzzy_q_iteration(t, r, delta=1e-9).q + 0.02 / (1 - 0.98))


def test_robust_table_is_the_per_model_tables_side_by_side():
    """robust_table writes every model's memberships in place: model k's rows are
    transition_table's bit for bit (padded to the widest model), and the robust sweeps
    read it to the same Q as from the K tables."""
    models = _perturbed_models(3)
    grid = models[0].grid
    both = robust_table(grid, [p.next_points for p in models])
    tables = [transition_table(p.grid, p.next_points) for p in models]
    assert both.index.shape == (tables[0].shape[0], 3, max(t.index.shape[1] for t in tables))
    for k, t in enumerate(tables):
        w = t.index.shape[1]
        np.testing.assert_array_equal(both.index[:, k, :w], t.index)
        np.testing.assert_array_equal(both.weight[:, k, :w], t.weight)
        assert not both.weight[:, k, w:].any()
        np.testing.assert_array_equal(both.table(k).tocsr().toarray(), t.tocsr().toarray())
    assert both.nnz == sum(t.nnz for t in tables)
    rewards = [p.rewards for p in models]
    for mode in ("worst", "mean"):
        a = fuzzy_q_iteration_robust(both, rewards, mode=mode)
        b = fuzzy_q_iteration_robust(tables, rewards, mode=mode)
        np.testing.assert_array_equal(a.q, b.q)
        assert a.iterations == b.iterations
    with pytest.raises(ValueError, match="at least one model"):
        robust_table(grid, [])
    with pytest.raises(ValueError, match="do not match a grid"):
        robust_table(grid, [models[0].next_points, models[0].next_points[:5]])
    with pytest.raises(ValueError, match="one reward table per transition"):
        fuzzy_q_iteration_robust(both, rewards[:2])
    with pytest.raises(ValueError, match=r"bin indices must lie in \[0, "):
        RobustTable(both.index + grid.size, both.weight, grid.size)


def test_bad_arguments_are_refused():
    p = _coarse_agent1()
    t = transition_table(p.grid, p.next_points)
    with pytest.raises(ValueError, match="unknown sweeps"):
        fuzzy_q_iteration(t, p.rewards, sweeps="parallel")
    with pytest.raises(ValueError, match="column-major"):
        fuzzy_q_iteration(transition_matrix(p.grid, p.next_points), p.rewards, sweeps="serial")
    with pytest.raises(ValueError, match="does not hold"):
        fuzzy_q_iteration(t, p.rewards, sweeps="serial", state_shape=(2, 3))
    with pytest.raises(TypeError, match="scipy sparse"):
        fuzzy_q_iteration(np.zeros(t.shape), p.rewards)
    with pytest.raises(ValueError, match="robust mode"):
        fuzzy_q_iteration_robust([t], [p.rewards], mode="best")
    with pytest.raises(ValueError, match="one reward table"):
        fuzzy_q_iteration_robust([t, t], [p.rewards])
    assert isinstance(t, TransitionTable) and sp.issparse(t.tocsr())
    with pytest.raises(ValueError, match="bin indices"):       # the kernels do not check bounds
        TransitionTable(np.array([[0, 3]]), np.array([[0.5, 0.5]]), 3)
    with pytest.raises(ValueError, match="one"):
        TransitionTable(np.array([[0, 1]]), np.array([[1.0]]), 3)


def test_table_equals_the_csr_matrix_at_awkward_points(rng):
    """Far outside the axes, exactly on centres, on pi == -pi and at the clamped ends."""
    from twolink.fqi.fuzzy import angle_axis, speed_axis, torque_axis
    grid = Grid((angle_axis("a"), speed_axis("s"), angle_axis("b"), torque_axis("tau2", 0.1)))
    n = grid.size * 2
    pts = np.stack([rng.uniform(-20, 20, n), rng.uniform(-9, 9, n), rng.uniform(-7, 7, n),
                    rng.uniform(-0.2, 0.2, n)], -1)
    pts[:12, 0] = grid.axes[0].centers
    pts[12:24, 2] = grid.axes[2].centers
    pts[24:31, 1] = grid.axes[1].centers
    pts[31:34, 3] = grid.axes[3].centers
    pts[40:50, 0] = np.pi + 2 * np.pi * np.arange(-5, 5)
    pts[50:60, 2] = np.nextafter(np.pi, 0) - 2 * np.pi * np.arange(10)
    pts[60:80, 1] = [-1e9, 1e9] * 10
    next_points = pts.reshape(grid.size, 2, 4)
    table = transition_table(grid, next_points)
    via_csr = fixed_width(transition_matrix(grid, next_points), grid.shape)
    np.testing.assert_array_equal(table.index, via_csr.index)
    np.testing.assert_array_equal(table.weight, via_csr.weight)


@pytest.mark.parametrize("model", ["simplified", "full"])
@pytest.mark.parametrize("freeze_link2", [False, True])
def test_compiled_transitions_equal_sample_step_bit_for_bit(rng, model, freeze_link2):
    """The compiled RK4 against ``sample_step`` of ``dynamics.MODELS``, over bin centres,
    states far outside the grid (wrapping, saturation) and torques beyond the limits."""
    from twolink.arm import dynamics
    from twolink.arm.integrate import sample_step, sample_step_compiled
    from twolink.synthesis.problems import centralized_actions
    accel = dynamics.MODELS[model]
    if freeze_link2:
        def accel(pp, s, t, inner=accel):
            return inner(pp, s, t) * np.array([1.0, 0.0])
    x = np.concatenate([centralized_problem().grid.centers()[::7],
                        rng.uniform(-12, 12, (500, 4))])
    tau = centralized_actions(TABLE_I) * 1.7
    fast = sample_step_compiled(model, TABLE_I, x[:, None], tau[None],
                                freeze_link2=freeze_link2)
    np.testing.assert_array_equal(fast, sample_step(accel, TABLE_I, x[:, None], tau[None]))
    with pytest.raises(ValueError, match="no compiled model"):
        sample_step_compiled("exact", TABLE_I, x, tau[0])
