"""Fuzzy Q-iteration (Alg. 1): the vectorised sweep against a loop that reads like Alg. 1."""
import numpy as np
import pytest
from reference_fqi import dense_memberships, fuzzy_q_iteration_reference

from twolink.arm.dynamics import simplified_acceleration
from twolink.arm.integrate import sample_step
from twolink.arm.parameters import TABLE_I
from twolink.arm.task import agent_reward
from twolink.synthesis.problems import agent1_problem, agent2_problem, solve
from twolink.fqi import iteration as fqi
from twolink.fqi.fuzzy import Axis, Grid, angle_axis, speed_axis, torque_axis
from twolink.fqi.iteration import fuzzy_q_iteration
from twolink.fqi.tables import transition_matrix


def _small_problem():
    """Agent 2's problem on a coarse grid: 5 angle bins x 4 speed bins, 3 actions."""
    grid = Grid((Axis("theta2", tuple(np.deg2rad([-180, -60, 0, 20, 90])), circular=True),
                 Axis("dtheta2", tuple(np.deg2rad([-360, -20, 40, 360])))))
    c = grid.centers()
    x = np.zeros((len(c), 4))
    x[:, 1], x[:, 3] = c[:, 0], c[:, 1]
    actions = np.array([-0.1, 0.0, 0.1])
    tau = np.zeros((3, 2))
    tau[:, 1] = actions
    nxt = sample_step(simplified_acceleration, TABLE_I, x[:, None], tau[None])
    return grid, nxt[..., [1, 3]], agent_reward(nxt, 2)


def test_vectorised_sweeps_equal_alg1_loop():
    grid, next_points, rewards = _small_problem()
    q_ref, it_ref = fuzzy_q_iteration_reference(grid, next_points, rewards)
    res = fuzzy_q_iteration(transition_matrix(grid, next_points), rewards)
    assert res.converged and res.iterations == it_ref
    np.testing.assert_allclose(res.q, q_ref, rtol=0, atol=1e-12)
    assert res.history[-1] <= 0.01 < res.history[-2]
    assert res.history[0] == pytest.approx(0.5)   # Q_1 = rho, Q_0 = 0


def _coarse_agent1(context):
    """Agent 1's problem (its grid includes the tau2 torque axis) on a coarse state grid."""
    axes = (Axis("theta1", tuple(np.deg2rad([-180, -60, 0, 30, 100])), circular=True),
            Axis("dtheta1", tuple(np.deg2rad([-360, 0, 40, 360]))),
            Axis("theta2", tuple(np.deg2rad([-180, -20, 0, 90])), circular=True))
    agent2 = solve(agent2_problem())
    return agent1_problem(agent2, context=context, axes=axes)


@pytest.mark.parametrize("context", ["frozen", "propagated"])
def test_vectorised_sweeps_equal_alg1_loop_on_a_grid_with_a_torque_axis(context):
    problem = _coarse_agent1(context)
    assert problem.grid.names == ("theta1", "dtheta1", "theta2", "tau2")
    assert problem.grid.shape == (5, 4, 4, 3)
    tau2_next = problem.next_points[..., 3]
    if context == "propagated":      # the next tau2 falls between the torque bins
        assert np.mean(~np.isin(tau2_next, [-0.1, 0.0, 0.1])) > 0.3
    q_ref, it_ref = fuzzy_q_iteration_reference(problem.grid, problem.next_points,
                                                problem.rewards)
    res = fuzzy_q_iteration(transition_matrix(problem.grid, problem.next_points),
                            problem.rewards)
    assert res.converged and res.iterations == it_ref
    np.testing.assert_allclose(res.q, q_ref, rtol=0, atol=1e-12)


def test_transition_rows_equal_the_printed_memberships_on_agent1s_grid(rng):
    """Rows of T on the paper's agent-1 grid (theta1, dtheta1, theta2, tau2), propagated
    context, against the memberships of (13) computed independently."""
    agent2 = solve(agent2_problem())
    problem = agent1_problem(agent2, context="propagated")
    t = transition_matrix(problem.grid, problem.next_points).toarray()
    n_u = problem.rewards.shape[1]
    for row in rng.choice(t.shape[0], 200, replace=False):
        m, j = divmod(row, n_u)
        np.testing.assert_allclose(t[row], dense_memberships(problem.grid,
                                                             problem.next_points[m, j]),
                                   rtol=0, atol=1e-14)


def test_reference_memberships_follow_the_fast_path_on_the_paper_axes(rng):
    grid = Grid((angle_axis("a"), speed_axis("s"), torque_axis("tau2", 0.1)))
    pts = np.stack([rng.uniform(-7, 7, 300), rng.uniform(-8, 8, 300),
                    rng.uniform(-0.2, 0.2, 300)], -1)
    pts[:12, 0] = grid.axes[0].centers        # exactly on the centres, pi == -pi included
    pts[12, 0] = np.pi
    idx, w = grid.memberships(pts)
    for p, i_row, w_row in zip(pts, idx, w):
        fast = np.zeros(grid.size)
        np.add.at(fast, i_row, w_row)
        np.testing.assert_allclose(fast, dense_memberships(grid, p), rtol=0, atol=1e-12)


def test_the_reference_lives_in_the_tests():
    assert not hasattr(fqi, "fuzzy_q_iteration_reference")
    assert not hasattr(fqi, "grid_dense_memberships")


def test_transition_rows_are_memberships():
    grid, next_points, _ = _small_problem()
    t = transition_matrix(grid, next_points)
    assert t.shape == (grid.size * 3, grid.size)
    np.testing.assert_allclose(np.asarray(t.sum(axis=1)).ravel(), 1.0)
    assert t.getnnz(axis=1).max() <= 4


def test_fixed_point_satisfies_bellman_equation():
    grid, next_points, rewards = _small_problem()
    t = transition_matrix(grid, next_points)
    res = fuzzy_q_iteration(t, rewards, delta=1e-10)
    q = res.q
    bellman = rewards + 0.98 * (t @ q.max(1)).reshape(q.shape)
    np.testing.assert_allclose(q, bellman, atol=1e-9)
    assert np.all(q <= 0) and np.all(q >= -0.5 / (1 - 0.98) - 1e-9)


def test_min_iterations_forces_equal_work():
    grid, next_points, rewards = _small_problem()
    t = transition_matrix(grid, next_points)
    assert fuzzy_q_iteration(t, rewards, min_iterations=500).iterations == 500


def test_bad_arguments_are_refused():
    grid, next_points, rewards = _small_problem()
    t = transition_matrix(grid, next_points)
    with pytest.raises(ValueError, match="gamma"):
        fuzzy_q_iteration(t, rewards, gamma=1.0)
    with pytest.raises(ValueError, match="does not match"):
        fuzzy_q_iteration(t, rewards[:, :2])
