"""Centralized synthesis for N links: the estimate and the refusal, the factored sweep held
against a plain sparse T built from every grid centre, and N = 2 against the shipped
``centralized_full``."""
import math

import numpy as np
import pytest
from reference_fqi import fuzzy_q_iteration_reference

from twolink.arm import dynamics
from twolink.arm.integrate import sample_step
from twolink.arm.parameters import DELTA, GAMMA, TABLE_I, links_parameters
from twolink.arm.task import centralized_reward
from twolink.synthesis.links_centralized import (
    actions,
    check_size,
    estimate,
    factored_problem,
    grid,
    synthesize_centralized,
)
from twolink.fqi import fuzzy
from twolink.fqi.factored import FactoredTable, factored_q_iteration
from twolink.fqi.tables import transition_matrix
from twolink.policy.fuzzy_policy import Policy, load_policy


def _coarse(links: int) -> fuzzy.Grid:
    """A small grid of (16)'s shape: 4 angle bins (0 among them), 3 speed bins."""
    ang = tuple(np.deg2rad((-180.0, -60.0, 0.0, 60.0)))
    spd = tuple(np.deg2rad((-360.0, 0.0, 360.0)))
    return fuzzy.Grid(tuple(fuzzy.Axis(f"theta{k}", ang, True) for k in range(1, links + 1))
                      + tuple(fuzzy.Axis(f"dtheta{k}", spd) for k in range(1, links + 1)))


def _reference(p, g):
    """Every centre integrated as it is (theta_1 included, no slice), T from
    fqi.transition_matrix, and Alg. 1's synchronous sweeps as printed with scipy:
    Q' = rho + gamma T max_u Q until max |Q' - Q| <= delta. Returns (T, Q, sweeps)."""
    acts = actions(p)
    accel = dynamics.full_acceleration if p.links == 2 else dynamics.links_acceleration
    params = p.as_arm() if p.links == 2 else p
    nxt = sample_step(accel, params, g.centers()[:, None, :], acts[None, :, :])
    t = transition_matrix(g, nxt)
    rho = centralized_reward(nxt).reshape(-1)
    q = np.zeros(g.size * len(acts))
    for sweeps in range(1, 10000):
        new = rho + GAMMA * (t @ q.reshape(g.size, -1).max(axis=1))
        change = np.abs(new - q).max()
        q = new
        if change <= DELTA:
            return t, q.reshape(g.size, -1), sweeps
    raise AssertionError("the reference did not converge")


@pytest.mark.parametrize("links", [2, 3])
def test_factored_sweep_equals_a_plain_sparse_t(links):
    p = links_parameters(links, "copied")
    g = _coarse(links)
    t_ref, q_ref, sweeps = _reference(p, g)
    table, rewards, _ = factored_problem(p, g)
    assert table.shape == t_ref.shape and table.nnz == t_ref.nnz
    assert abs(table.tocsr() - t_ref).max() < 1e-12
    result = factored_q_iteration(table, rewards)
    assert result.converged and result.iterations == sweeps
    np.testing.assert_allclose(result.q, q_ref, rtol=0, atol=1e-12)
    assert np.ptp(q_ref) > 1.0          # the goal is reached from some bins, not from others
    one = factored_q_iteration(table, rewards, threads=1)
    np.testing.assert_array_equal(one.q, result.q)


def test_two_links_follow_alg1_as_printed():
    """The factored sweep against the plain loop of Alg. 1 with memberships from (13)
    (tests/reference_fqi.py), every centre integrated as it is."""
    p = links_parameters(2)
    g = _coarse(2)
    acts = actions(p)
    nxt = sample_step(dynamics.full_acceleration, p.as_arm(), g.centers()[:, None, :],
                      acts[None, :, :])
    q_ref, sweeps = fuzzy_q_iteration_reference(g, nxt, centralized_reward(nxt))
    table, rewards, _ = factored_problem(p, g)
    result = factored_q_iteration(table, rewards)
    assert result.iterations == sweeps
    np.testing.assert_allclose(result.q, q_ref, rtol=0, atol=1e-12)


def test_two_links_give_the_shipped_centralized_full(tmp_path):
    shipped = load_policy("centralized_full").agents[0]
    pol = synthesize_centralized(TABLE_I)
    agent = pol.agents[0]
    assert pol.kind == "centralized" and pol.meta["links"] == 2 and pol.links == 2
    assert agent.inputs == ("theta1", "theta2", "dtheta1", "dtheta2")
    assert agent.outputs == ("tau1", "tau2")
    np.testing.assert_array_equal(agent.actions, shipped.actions)
    assert agent.info["iterations"] == shipped.info["iterations"] == pol.meta["iterations"]
    assert agent.info["transition_nnz"] == shipped.info["transition_nnz"] == pol.meta["nnz"]
    # the two-link synthesis stores T factored too (issue 13): the same Q bit for bit
    np.testing.assert_array_equal(agent.q, shipped.q)
    assert pol.meta["parameters"] == TABLE_I.as_dict() and pol.meta["model"] == "full"
    assert set(pol.meta["timings"]) >= {"model_seconds", "table_seconds", "sweep_seconds",
                                        "cpu_seconds"}
    assert pol.meta["bytes"]["stored_bytes"] == estimate(2).stored_bytes
    back = Policy.load(pol.save(tmp_path / "centralized_2.npz"))
    np.testing.assert_array_equal(back.agents[0].q, agent.q)


def test_the_problem_of_three_links():
    p = links_parameters(3)
    acts = actions(p)
    assert acts.shape == (27, 3)
    np.testing.assert_array_equal(acts[:3], [[-0.2, -0.1, -0.05], [-0.2, -0.1, 0.0],
                                             [-0.2, -0.1, 0.05]])
    g = grid(3)
    assert g.shape == (12, 12, 12, 7, 7, 7) and g.names[3] == "dtheta1"


def test_the_estimate_before_any_work():
    two, three, four = estimate(2), estimate(3), estimate(4)
    assert (two.states, two.actions, two.q_values) == (7056, 9, 63504)
    assert (three.states, three.actions, three.q_values) == (592704, 27, 16003008)
    assert three.nnz == 16003008 * 64 and three.dense_bytes == 12 * three.nnz
    assert three.dense_bytes > 12e9 and three.stored_bytes < 0.9e9 < three.peak_bytes < 2**31
    assert four.q_values == 49787136 * 81 and four.q_bytes == 8 * four.q_values
    assert three.sweeps_bound == 1 + math.ceil(math.log(DELTA / 0.5) / math.log(GAMMA))
    assert 0 < two.seconds < three.seconds < four.seconds
    assert estimate(6).peak_bytes > 1e17          # for every N, no allocation
    assert estimate(2, refine=2).states == 24 ** 2 * 13 ** 2


def test_refused_over_the_cap_with_the_estimate():
    with pytest.raises(ValueError, match=r"^centralized 4-link synthesis needs about 662 GiB "
                                         r"\(Q-table 30 GiB for 4\.03e\+09 Q-values, T 571 GiB "
                                         r"factored, 11\.3 TiB as a plain sparse matrix; up to "
                                         r"[\d.]+ days of CPU\), over the cap of ") as err:
        synthesize_centralized(links_parameters(4))
    assert "\n" not in str(err.value)
    assert check_size(3, max_bytes=2**31) == estimate(3)
    with pytest.raises(ValueError, match="centralized 2-link synthesis needs about"):
        synthesize_centralized(TABLE_I, max_bytes=1 << 20)


@pytest.mark.parametrize("call, message", [
    (lambda: estimate(7), "links must be a whole number from 2 to 6"),
    (lambda: estimate(3, refine=0), "refine must be a positive whole number"),
    (lambda: check_size(2, max_bytes=-1), "max_bytes must be a positive whole number"),
    (lambda: estimate(3, gamma=1.0), r"gamma must lie in \(0, 1\)"),
    (lambda: synthesize_centralized(TABLE_I, delta=0.0), r"delta must lie in \(0, 0.5\)"),
    (lambda: synthesize_centralized({"links": 3}), "p must be ArmParameters or"),
    (lambda: synthesize_centralized(TABLE_I, threads=0), "threads must be a positive"),
    (lambda: factored_problem(links_parameters(3), grid(2)), "a 3-link grid needs axes"),
])
def test_bad_input_is_one_clear_line(call, message):
    with pytest.raises(ValueError, match=message):
        call()


def test_a_factored_table_refuses_what_the_sweep_could_not_read():
    index = np.zeros((6, 4), dtype=np.int32)
    w = np.full((6, 4), 0.25)
    index1 = np.zeros((6, 2, 2), dtype=np.int32)
    w1 = np.full((6, 2, 2), 0.5)
    table = FactoredTable(index, w, index1, w1, 3)
    assert (table.n_slice, table.n_first, table.n_states) == (2, 2, 4)
    with pytest.raises(ValueError, match=r"slice bin indices must lie in \[0, 2\)"):
        FactoredTable(index + 2, w, index1, w1, 3)
    with pytest.raises(ValueError, match=r"first-axis bin indices must lie in \[0, 2\)"):
        FactoredTable(index, w, index1 - 1, w1, 3)
    with pytest.raises(ValueError, match="rewards of shape"):
        factored_q_iteration(table, np.zeros((4, 2)))
    with pytest.raises(ValueError, match="threads must be a positive whole number"):
        factored_q_iteration(table, np.zeros((4, 3)), threads=0)
    with pytest.raises(ValueError, match="gamma must lie in"):
        factored_q_iteration(table, np.zeros((4, 3)), gamma=1.0)
