"""Fuzzy Q-iteration (Alg. 1): the vectorised sweep against a loop that reads like Alg. 1."""
import numpy as np
import pytest

from twolink.fqi import fuzzy_q_iteration, fuzzy_q_iteration_reference, transition_matrix
from twolink.fuzzy import Axis, Grid
from twolink.integrate import sample_step
from twolink.dynamics import simplified_acceleration
from twolink.parameters import TABLE_I
from twolink.reward import agent_reward


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
