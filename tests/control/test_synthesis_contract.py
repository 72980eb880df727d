"""What agent 1's two contexts mean (docs/concepts/agents.md), on the problem builders,
with concrete numbers.

(a) frozen: theta2 and tau2 stay as they are over agent 1's transition;
(b) propagated: link 2 moves from dtheta2 = 0 under tau2, and the next tau2 is agent 2's
    policy at the new link-2 state.
Under (11) with theta2 held, link 1 is a linear ODE with a closed-form solution, and so is
link 2 from rest under a constant tau2; the builders' transitions are held against those.
"""
import math

import numpy as np
import pytest

from twolink.arm.dynamics import simplified_acceleration
from twolink.arm.integrate import sample_step
from twolink.arm.parameters import TABLE_I, TS
from twolink.synthesis.problems import agent1_problem, agent2_problem, solve

P = TABLE_I
DEG = math.pi / 180.0
#: The bin (theta1, dtheta1, theta2, tau2) = (-30 deg, 30 deg/s, 80 deg, +0.1 N m), action
#: tau1 = +0.2 N m (index 2 of [-0.2, 0, 0.2]).
BIN = (3, 4, 10, 2)
ACTION = 2


@pytest.fixture(scope="module")
def agent2():
    return solve(agent2_problem())


def _bin(problem, index=BIN):
    m = int(np.ravel_multi_index(index, problem.grid.shape))
    return m, problem.grid.centers()[m]


def _link1_with_theta2_held(theta1, dtheta1, theta2, tau1, tau2, t=TS):
    """(11) for link 1 with theta2 constant: ddtheta1 = a - k dtheta1, solved exactly."""
    c = math.cos(theta2)
    d = P.P1 + P.P2 + 2 * P.P3 * c
    k = P.b1 / d
    a = (P.P2 * tau1 - (P.P2 + P.P3 * c) * tau2) / (P.P2 * d)
    v_inf = a / k
    e = math.exp(-k * t)
    return theta1 + v_inf * t + (dtheta1 - v_inf) * (1 - e) / k, v_inf + (dtheta1 - v_inf) * e


def _link2_from_rest(theta2, tau2, t=TS):
    """(11) for link 2 from dtheta2 = 0: ddtheta2 = tau2/P2 - b2 dtheta2, solved exactly."""
    v_inf = tau2 / (P.P2 * P.b2)
    e = math.exp(-P.b2 * t)
    return theta2 + v_inf * (t - (1 - e) / P.b2), v_inf * (1 - e)


def test_the_contract_bin_is_what_it_says():
    problem = agent1_problem(None)
    m, c = _bin(problem)
    np.testing.assert_allclose(c, [-30 * DEG, 30 * DEG, 80 * DEG, 0.1], rtol=0, atol=1e-15)
    assert problem.actions[ACTION, 0] == 0.2


def test_frozen_context_keeps_theta2_and_tau2(agent2):
    problem = agent1_problem(None, context="frozen")
    m, c = _bin(problem)
    theta1, dtheta1, theta2, tau2 = c
    nxt = problem.next_points[m, ACTION]
    # theta2 and tau2 stay where they were (theta2 up to the angle wrap's round-off),
    # although tau2 = 0.1 would swing link 2
    assert abs(nxt[2] - theta2) <= 1e-15 and nxt[3] == tau2 == 0.1
    # link 1 moves as (11) does with theta2 held and tau2 acting on it
    t1, v1 = _link1_with_theta2_held(theta1, dtheta1, theta2, 0.2, tau2)
    np.testing.assert_allclose(nxt[:2], [t1, v1], rtol=0, atol=1e-10)
    np.testing.assert_allclose(nxt[:2], [-0.4958907, 0.5827037], rtol=0, atol=1e-6)
    # every transition of the frozen context: theta2 and tau2 unchanged
    c_all = problem.grid.centers()
    np.testing.assert_allclose(problem.next_points[..., 2],
                               np.broadcast_to(c_all[:, None, 2], problem.rewards.shape),
                               rtol=0, atol=1e-15)
    np.testing.assert_array_equal(problem.next_points[..., 3],
                                  np.broadcast_to(c_all[:, None, 3], problem.rewards.shape))
    # and agent 2 plays no part in it
    other = agent1_problem(agent2, context="frozen")
    np.testing.assert_array_equal(other.next_points, problem.next_points)


def test_propagated_context_moves_link2_from_rest_and_asks_agent2(agent2):
    problem = agent1_problem(agent2, context="propagated")
    m, c = _bin(problem)
    theta1, dtheta1, theta2, tau2 = c
    nxt = problem.next_points[m, ACTION]
    t2, v2 = _link2_from_rest(theta2, tau2)
    np.testing.assert_allclose(nxt[2], t2, rtol=0, atol=1e-10)
    assert nxt[2] - theta2 == pytest.approx(0.0227197, abs=1e-7)   # link 2 swings 1.3 deg
    np.testing.assert_allclose(v2, 0.9087, atol=1e-4)
    # the next tau2 is agent 2's policy (14) at the new link-2 state
    np.testing.assert_allclose(nxt[3], agent2.act(np.array([t2, v2]))[0], rtol=0, atol=1e-9)
    # link 1 moves with link 2 swinging from dtheta2 = 0 under tau2, as (11) says
    joint = sample_step(simplified_acceleration, P, np.array([theta1, theta2, dtheta1, 0.0]),
                        np.array([0.2, tau2]))
    np.testing.assert_array_equal(nxt[:2], joint[[0, 2]])
    frozen = agent1_problem(None, context="frozen").next_points[m, ACTION]
    assert abs(nxt[0] - frozen[0]) > 1e-6


def test_propagated_next_tau2_is_agent2s_action_for_every_transition(agent2):
    problem = agent1_problem(agent2, context="propagated")
    c = problem.grid.centers()
    x = np.zeros((len(c), 4))
    x[:, 0], x[:, 2], x[:, 1] = c[:, 0], c[:, 1], c[:, 2]
    tau = np.zeros((len(c), 3, 2))
    tau[:, :, 0] = problem.actions[None, :, 0]
    tau[:, :, 1] = c[:, 3:4]
    nxt = sample_step(simplified_acceleration, P, x[:, None, :], tau)
    np.testing.assert_array_equal(problem.next_points[..., 3],
                                  agent2.act(nxt[..., [1, 3]])[..., 0])
    # link 2 starts from rest: with tau2 = 0 it does not move at all
    still = c[:, 3] == 0.0
    np.testing.assert_allclose(problem.next_points[still, :, 2],
                               np.broadcast_to(c[still, None, 2], (still.sum(), 3)),
                               rtol=0, atol=1e-15)


def test_agent2_sees_link2_alone():
    problem = agent2_problem()
    m = int(np.ravel_multi_index((6, 3), problem.grid.shape))      # theta2 = 0, dtheta2 = 0
    for j, tau2 in enumerate((-0.1, 0.0, 0.1)):
        t2, v2 = _link2_from_rest(0.0, tau2)
        np.testing.assert_allclose(problem.next_points[m, j], [t2, v2], rtol=0, atol=1e-10)
    assert problem.rewards[m].tolist() == [-0.5, 0.0, -0.5]


def test_an_absurd_refinement_is_refused_before_any_allocation():
    import subprocess
    import sys

    from twolink.synthesis.problems import table_sizes
    from twolink.synthesis.synthesize import synthesize

    with pytest.raises(ValueError, match="refine must be a whole number from 1 to 16"):
        synthesize("centralized", refine=10**9)
    res = subprocess.run([sys.executable, "-m", "twolink.cli", "synthesize", "centralized",
                          "--refine", "1000000000", "-o", "x.npz"], capture_output=True,
                         text=True, timeout=60)
    assert res.returncode == 2 and res.stderr.count("\n") == 1
    assert "refine must be a whole number from 1 to 16" in res.stderr or \
        "is over the 64 MiB" in res.stderr
    assert table_sizes("decentralized", 2) == {"agent2": 24 * 13 * 3,
                                              "agent1": 24 * 13 * 24 * 9}
