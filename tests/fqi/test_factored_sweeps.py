"""The factored layout of T (twolink.fqi.factored) on the paper's two-link problems: the
same memberships as the fixed table, the sweeps held against the scipy reference and the
robust reference, threads and the width-8 kernel bit for bit, refusals of what does not
factor, and the synthesis recording which layout it used."""
import dataclasses

import numpy as np
import pytest
from reference_fqi import fuzzy_q_iteration_robust_reference, fuzzy_q_iteration_scipy

from twolink.arm.parameters import GAMMA, TABLE_I
from twolink.synthesis.problems import LAYOUTS, agent2_problem, centralized_problem, solve
from twolink.synthesis.synthesize import synthesize
from twolink.fqi import _factored_kernel as fqi_factored_kernel
from twolink.fqi import fuzzy
from twolink.fqi.factored import (
    PARALLEL_MIN_WORK,
    default_threads,
    factored_q_iteration,
    factored_q_iteration_robust,
    factored_table,
    sweep_work,
)
from twolink.fqi.tables import transition_matrix
from twolink.policy.fuzzy_policy import greedy_indices


@pytest.fixture(scope="module")
def central():
    """The paper's centralized problem with the transitions the synthesis uses (compiled
    RK4 over one theta1 slice, shifted), its factored table and plain T."""
    problem = centralized_problem(compiled=True)
    return problem, factored_table(problem.grid, problem.next_points), \
        transition_matrix(problem.grid, problem.next_points)


def test_the_factored_table_holds_the_fixed_tables_memberships(central):
    problem, table, t = central
    assert table.shape == t.shape == (7056 * 9, 7056)
    assert table.n_first == 12 and table.n_slice == 588 and table.index.shape == (588 * 9, 8)
    expanded = table.tocsr()
    assert expanded.nnz == t.nnz == table.nnz
    # the products are rounded in another order (theta1 last): equal to the last bit or two
    assert abs(expanded - t).max() < 1e-15
    assert table.nbytes < 0.2 * (t.data.nbytes + t.indices.nbytes)


def test_numpy_transitions_factor_too():
    """The numpy RK4 of every centre (the agents' and the reference's path) gives blocks
    that agree off theta1 bit for bit, so they factor as they are."""
    problem = centralized_problem()
    table = factored_table(problem.grid, problem.next_points)
    assert abs(table.tocsr() - transition_matrix(problem.grid, problem.next_points)).max() \
        < 1e-15


def test_sweeps_follow_the_scipy_reference(central):
    problem, table, t = central
    q_ref, sweeps, history = fuzzy_q_iteration_scipy(t, problem.rewards)
    result = factored_q_iteration(table, problem.rewards)
    assert result.converged and result.iterations == sweeps == 80
    np.testing.assert_allclose(result.history, history, rtol=0, atol=1e-12)
    assert np.abs(result.q - q_ref).max() < 1e-12
    np.testing.assert_array_equal(greedy_indices(result.q), greedy_indices(q_ref))


def test_threads_and_the_width8_kernel_leave_q_bit_for_bit(central):
    problem, table, _ = central
    one = factored_q_iteration(table, problem.rewards, threads=1)
    two = factored_q_iteration(table, problem.rewards, threads=2)
    seen = []
    stepped = factored_q_iteration(table, problem.rewards, threads=2,
                                   callback=lambda ell, change: seen.append(change))
    np.testing.assert_array_equal(one.q, two.q)
    np.testing.assert_array_equal(one.q, stepped.q)
    np.testing.assert_array_equal(seen, one.history)
    # the written-out width-8 sums against the general loop: one zero-weight column more
    rng = np.random.default_rng(0)
    v = rng.normal(size=table.n_states)
    q = rng.normal(size=table.n_states * 9)
    r = problem.rewards.reshape(-1)
    wide = (np.concatenate([table.index, table.index[:, :1]], axis=1),
            np.concatenate([table.weight, np.zeros((len(table.weight), 1))], axis=1))
    outs = []
    for kernel, (index, weight) in ((fqi_factored_kernel.factored_sweep8,
                                     (table.index, table.weight)),
                                    (fqi_factored_kernel.factored_sweep, wide)):
        q_next, v_next = np.empty_like(q), np.empty_like(v)
        change = kernel(index, weight, table.index1, table.weight1, r, q, q_next, v, v_next,
                        GAMMA, 0, table.n_slice)
        outs.append((change, q_next, v_next))
    assert outs[0][0] == outs[1][0] > 0
    np.testing.assert_array_equal(outs[0][1], outs[1][1])
    np.testing.assert_array_equal(outs[0][2], outs[1][2])


@pytest.mark.parametrize("mode", ["worst", "mean"])
def test_robust_sweeps_follow_the_robust_reference(mode):
    models = [TABLE_I, dataclasses.replace(TABLE_I, m1=TABLE_I.m1 * 1.3, b1=TABLE_I.b1 * 0.7)]
    problems = [centralized_problem(m, "full", compiled=True) for m in models]
    tables = [factored_table(pr.grid, pr.next_points) for pr in problems]
    rewards = [pr.rewards for pr in problems]
    q_ref, sweeps = fuzzy_q_iteration_robust_reference(
        [transition_matrix(pr.grid, pr.next_points) for pr in problems], rewards, mode=mode)
    result = factored_q_iteration_robust(tables, rewards, mode=mode)
    assert result.converged and result.iterations == sweeps
    assert np.abs(result.q - q_ref).max() < 1e-12
    np.testing.assert_array_equal(greedy_indices(result.q), greedy_indices(q_ref))
    one = factored_q_iteration_robust(tables, rewards, mode=mode, threads=1)
    np.testing.assert_array_equal(one.q, result.q)
    # one model: the nominal sweeps exactly
    np.testing.assert_array_equal(
        factored_q_iteration_robust(tables[:1], rewards[:1], mode=mode).q,
        factored_q_iteration(tables[0], rewards[0]).q)


def test_what_does_not_factor_is_refused(central):
    problem, _, _ = central
    moved = problem.next_points.copy()
    moved[3 * 588 + 10, 4, 2] += 1e-9          # one block's dtheta1 off by a hair
    with pytest.raises(ValueError, match="differ on other axes: the dynamics depend on theta1"):
        factored_table(problem.grid, moved)
    speed_first = fuzzy.Grid((fuzzy.speed_axis("dtheta1"), fuzzy.angle_axis("theta1")))
    with pytest.raises(ValueError, match="needs a circular first axis, not dtheta1"):
        factored_table(speed_first, np.zeros((speed_first.size, 3, 2)))
    with pytest.raises(ValueError, match="do not match a grid of 7056 bins"):
        factored_table(problem.grid, problem.next_points[:, :, :3])
    full_agent2 = agent2_problem(model="full")    # link 1 moves under link 2: depends on theta2
    with pytest.raises(ValueError, match="the dynamics depend on theta2"):
        factored_table(full_agent2.grid, full_agent2.next_points)
    table = factored_table(problem.grid, problem.next_points)
    with pytest.raises(ValueError, match="unknown robust mode 'best'"):
        factored_q_iteration_robust([table], [problem.rewards], mode="best")
    with pytest.raises(ValueError, match="one reward table per transition table"):
        factored_q_iteration_robust([table, table], [problem.rewards])
    with pytest.raises(ValueError, match="unknown layout 'csr'"):
        solve(problem, layout="csr")


def test_synthesis_records_its_layout():
    assert LAYOUTS == ("fixed", "factored")
    central = synthesize("centralized", model="full")
    assert central.agents[0].info["layout"] == "factored"
    assert central.agents[0].info["threads"] == 1          # 0.64 M gathered values a sweep
    assert central.agents[0].info["iterations"] == 78
    serial = synthesize("centralized", model="full", sweeps="serial")
    assert serial.agents[0].info["layout"] == "fixed"
    pair = synthesize("decentralized", model="full")
    assert [a.info["layout"] for a in pair.agents] == ["fixed", "fixed"]
    assert [a.info["threads"] for a in pair.agents] == [1, 1]
    robust = synthesize("centralized", model="full", robust="worst", draws=4, spread=0.1)
    assert robust.agents[0].info["layout"] == "factored"
    assert robust.agents[0].info["threads"] == default_threads(4 * 635_040)


def test_small_sweeps_stay_on_one_thread(central, monkeypatch):
    """The paper's table (0.64 M gathered values per sweep) sweeps on one thread by
    default; K = 8 of them or a refined grid on two (one on a one-core machine)."""
    _, table, _ = central
    assert sweep_work(table) == 588 * 9 * 12 * (8 + 2) < PARALLEL_MIN_WORK
    assert default_threads(sweep_work(table)) == 1
    monkeypatch.setattr("os.cpu_count", lambda: 8)
    assert default_threads(8 * sweep_work(table)) == default_threads() == 2
    monkeypatch.setattr("os.cpu_count", lambda: 1)
    assert default_threads(8 * sweep_work(table)) == 1
    with pytest.raises(ValueError, match="threads must be a positive whole number"):
        factored_q_iteration(table, central[0].rewards, threads=0)
