"""One decentralized agent per joint of an N-link arm (twolink.synthesis.links_decentralized, issue 11)."""
import numpy as np
import pytest

from twolink.arm.parameters import DELTA, GAMMA, TABLE_I, TS, links_parameters
from twolink.synthesis import links_decentralized as decentralized
from twolink.synthesis.links_decentralized import (
    LINKS_DEFAULT,
    LINKS_DEFAULTS,
    TWO_LINK_DEFAULT,
    Construction,
    agent_grid,
    agent_problem,
    construction,
    locked_joints,
    synthesize_links,
    transition_bytes,
)
from twolink.synthesis.synthesize import synthesize
from twolink.policy.fuzzy_policy import Policy
from twolink.policy.registry import SHIPPED, TWO_LINK


def test_two_links_give_the_shipped_frozen_agents_bit_for_bit():
    shipped = Policy.load(SHIPPED["decentralized_full"].file)
    fresh = synthesize_links(TABLE_I)
    assert fresh.meta["construction"] == TWO_LINK_DEFAULT.as_dict()
    assert [a.name for a in fresh.agents] == ["agent2", "agent1"]
    for a, b in zip(fresh.agents, shipped.agents):
        assert a.grid == b.grid
        np.testing.assert_array_equal(a.q, b.q)
        assert a.info["iterations"] == b.info["iterations"]


def test_two_links_give_the_propagated_full_model_agents_bit_for_bit():
    ref = synthesize("decentralized", TABLE_I, model="full", context="propagated")
    fresh = synthesize_links(links_parameters(2), context="propagated")
    for a, b in zip(fresh.agents, ref.agents):
        assert a.grid == b.grid
        np.testing.assert_array_equal(a.q, b.q)


def test_three_link_agents_read_their_own_link_and_the_outer_neighbour():
    p = links_parameters(3)
    c = LINKS_DEFAULT
    names = {i: agent_grid(i, p, c).names for i in (3, 2, 1)}
    assert names == {3: ("theta3", "dtheta3"),
                     2: ("theta2", "dtheta2", "theta3", "dtheta3", "tau3"),
                     1: ("theta1", "dtheta1", "theta2", "dtheta2", "tau2")}
    grid = agent_grid(2, p, c)
    assert grid.shape == (12, 9, 12, 9, 3)   # +-6 deg/s on agent N-1's own and context axes
    np.testing.assert_allclose(grid.axes[-1].centers, [-p.tau_max[2], 0, p.tau_max[2]])
    assert sorted(np.rad2deg(grid.axes[1].centers).round(6))[3:6] == [-6.0, 0.0, 6.0]
    assert agent_grid(1, p, c).shape == (12, 7, 12, 9, 3)
    assert agent_grid(3, p, c).shape == (12, 7)
    assert agent_grid(3, links_parameters(4), c).shape == (12, 9, 12, 9, 3)
    assert agent_grid(2, links_parameters(4), c).shape == (12, 7, 12, 9, 3)
    assert agent_grid(2, p, construction(3, extra_speed_bins="none")).shape == (12, 7, 12, 7, 3)
    assert agent_grid(2, p, construction(3, speed_context=False)).names == \
        ("theta2", "dtheta2", "theta3", "tau3")
    # the middle agent locks joint 1, the outermost none, agent 1 has no inner joint
    assert [locked_joints(i, 3, c) for i in (3, 2, 1)] == \
        [(False, False, False), (True, False, False), (False, False, False)]
    assert locked_joints(1, 4, construction(4, beyond="locked")) == (False, False, True, True)
    assert locked_joints(3, 4, c) == (False, True, False, False)
    assert locked_joints(3, 4, construction(4, lock_inner="middle")) == (True, True, False, False)
    assert locked_joints(4, 4, construction(4, lock_inner="all")) == (True, True, True, False)
    # copied links: no speed in the context by default
    assert construction(3, "copied") == LINKS_DEFAULTS["copied"]
    assert agent_grid(2, links_parameters(3, "copied"), LINKS_DEFAULTS["copied"]).names == \
        ("theta2", "dtheta2", "theta3", "tau3")
    assert construction(2, "copied") == TWO_LINK_DEFAULT


def test_shipped_three_link_policy_shapes_and_provenance():
    entry = SHIPPED["decentralized_3link"]
    assert (entry.links, entry.rule, entry.kind) == (3, "tapered", "decentralized")
    assert entry.synthesis_options()["links"] == 3
    assert "decentralized_3link" not in TWO_LINK and "decentralized_full" in TWO_LINK
    pol = Policy.load(entry.file)
    assert pol.links == 3 and pol.kind == "decentralized"
    assert [a.name for a in pol.agents] == ["agent3", "agent2", "agent1"]
    assert [a.outputs for a in pol.agents] == [("tau3",), ("tau2",), ("tau1",)]
    assert pol.q_sizes == {"agent3": 12 * 7 * 3, "agent2": 12 * 9 * 12 * 9 * 3 * 3,
                           "agent1": 12 * 7 * 12 * 9 * 3 * 3}
    meta = pol.meta
    assert meta["links"] == 3 and meta["rule"] == "tapered" and meta["model"] == "full"
    assert meta["parameters"] == links_parameters(3).as_dict()
    assert meta["construction"] == LINKS_DEFAULT.as_dict()
    assert meta["context"] == entry.context == "propagated"
    assert (meta["gamma"], meta["delta"], meta["ts"]) == (GAMMA, DELTA, TS)
    assert meta["substeps"] > 0 and "twolink_version" in meta
    for a in pol.agents:
        assert meta["agents"][a.name]["iterations"] == a.info["iterations"] > 0
        assert a.info["converged"]
    u = pol(np.array([[1.0, -2.0, 0.5, 0.0, 0.0, 0.0], [0.0] * 6]))
    assert u.shape == (2, 3)
    assert np.all(np.abs(u) <= links_parameters(3).tau_max + 1e-12)
    np.testing.assert_array_equal(u[1], 0.0)       # at the goal, at rest: no torque


def test_the_middle_agent_holds_its_inner_link_and_feels_the_heavier_outer_links():
    """Agent 2 of three links: with joint 1 locked link 1 does not move, and joint 2's
    effective inertia tau2 / ddtheta2 is larger than in the free reading (where link 1
    recoils and the outer links seem light)."""
    p = links_parameters(3, "copied")
    x = np.zeros((1, 1, 6))
    x[..., 1] = 0.4                                   # theta2
    tau = np.zeros((1, 3, 3))
    tau[0, :, 1] = [-p.tau_max[1], 0.0, p.tau_max[1]]
    locked = decentralized._transitions(p, x, tau, (True, False, False), 3)
    free = decentralized._transitions(p, x, tau, (False, False, False), 3)
    np.testing.assert_array_equal(locked[..., [0, 3]], 0.0)      # theta1, dtheta1
    assert np.all(np.abs(free[0, [0, 2], 3]) > 1e-3)              # free link 1 recoils
    push = TS ** 2 / 2
    inertia_locked = p.tau_max[1] * push / (locked[0, 2, 1] - 0.4)
    inertia_free = p.tau_max[1] * push / (free[0, 2, 1] - 0.4)
    assert inertia_locked > 2.0 * inertia_free > 0


def test_the_propagated_context_runs_the_outer_agents():
    p = links_parameters(3)
    c = construction(3, extra_speed_bins="none", speed_context=False)
    with pytest.raises(ValueError, match="agent 2: the propagated context needs the 1 outer"):
        agent_problem(2, p, c)
    a3 = decentralized.solve(agent_problem(3, p, c))
    pr = agent_problem(2, p, c, [a3])
    assert pr.next_points.shape == (12 * 7 * 12 * 3, 3, 4)
    assert pr.rewards.shape == (12 * 7 * 12 * 3, 3)
    # the next tau3 is agent 3's action at the reached link-3 state (link 1 locked)
    centers = pr.grid.centers()
    x = np.zeros((len(centers), 1, 6))
    x[:, 0, [1, 4, 2]] = centers[:, :3]
    tau = np.zeros((len(centers), 3, 3))
    tau[:, :, 1] = pr.actions[:, 0]
    tau[:, :, 2] = centers[:, 3:]
    reached = decentralized._transitions(p, x, tau, (True, False, False), 3)
    np.testing.assert_array_equal(pr.next_points[..., 3], a3.act(reached[..., [2, 5]])[..., 0])
    np.testing.assert_array_equal(pr.next_points[..., :3], reached[..., [1, 4, 2]])
    np.testing.assert_array_equal(reached[..., [0, 3]], 0.0)
    frozen = agent_problem(2, p, construction(3, context="frozen", speed_context=False,
                                              extra_speed_bins="none"))
    np.testing.assert_array_equal(frozen.next_points[..., 3],
                                  np.broadcast_to(centers[:, None, 3], (len(centers), 3)))
    assert not np.array_equal(frozen.next_points[..., 3], pr.next_points[..., 3])
    assert set(np.unique(np.round(pr.rewards, 9))) <= {0.0, -0.5}


def test_memory_estimate_and_refusals():
    assert transition_bytes(links_parameters(6), LINKS_DEFAULT) < decentralized.MAX_BYTES
    with pytest.raises(ValueError, match=r"^the 3-link agents' transitions take about \d+ MiB, "
                                         r"over the 1 MiB a decentralized synthesis may use$"):
        synthesize_links(links_parameters(3), max_bytes=2**20)
    with pytest.raises(ValueError, match="unknown context 'sideways'; choose one of frozen, "
                                         "propagated"):
        construction(3, context="sideways")
    with pytest.raises(ValueError, match="unknown lock_inner 'some'; choose one of none, "
                                         "middle, near, all$"):
        Construction(lock_inner="some")
    with pytest.raises(ValueError, match="gamma must lie in \\(0, 1\\), got 1.5"):
        synthesize_links(links_parameters(3), gamma=1.5)
    with pytest.raises(ValueError, match="delta must be positive, got nan"):
        synthesize_links(links_parameters(3), delta=float("nan"))
    with pytest.raises(ValueError, match="unknown extra_speed_bins"):
        synthesize_links(links_parameters(3), extra_speed_bins="many")
    with pytest.raises(ValueError, match="speed_context must be True or False"):
        Construction(speed_context="yes")
    with pytest.raises(ValueError, match=r"unknown construction option\(s\) \['speed'\]"):
        construction(3, speed=True)
    with pytest.raises(ValueError, match="links must be a whole number from 2 to 6, got 7"):
        synthesize("decentralized", links=7)
    with pytest.raises(ValueError, match="links must be a whole number from 2 to 6, got 1"):
        construction(1)
    with pytest.raises(ValueError, match="unknown link rule 'bent'"):
        synthesize("decentralized", links=3, rule="bent")
    with pytest.raises(ValueError, match="unknown link rule 'bent'; choose one of tapered, "
                                         "copied"):
        construction(3, "bent")
    with pytest.raises(ValueError, match="centralized synthesis of a 3-link arm is "
                                         "twolink.synthesis.links_centralized"):
        synthesize("centralized", links=3)
    with pytest.raises(ValueError, match="model \\(11\\) is the paper's two-link"):
        synthesize("decentralized", model="simplified", links=3)
    with pytest.raises(ValueError, match="a 3-link arm takes none of them"):
        synthesize("decentralized", links=3, robust="worst", draws=2, spread=0.1)
    with pytest.raises(ValueError, match="agent 4: an arm of 3 links has agents 1 to 3"):
        agent_problem(4, links_parameters(3), LINKS_DEFAULT)


def test_an_n_link_policy_records_its_read_out_and_acts_by_it():
    """synthesize_links(readout=...) keeps the agents and records the read-out: beyond the
    argmax angle the agents act by the largest interpolated Q."""
    from twolink.arm.parameters import links_parameters
    from twolink.synthesis.links_decentralized import synthesize_links
    from twolink.policy.fuzzy_policy import greedy_indices
    from twolink.policy.readout import Readout

    p = links_parameters(3, "copied")
    plain = synthesize_links(p)
    read = synthesize_links(p, readout=Readout(argmax_beyond_deg=20.0))
    assert read.meta["readout"] == {"speed_dead_zone": 0.0, "angle_dead_zone_deg": 0.0,
                                    "argmax_beyond_deg": 20.0}
    assert "readout" not in plain.meta
    assert all(np.array_equal(a.q, b.q) for a, b in zip(plain.agents, read.agents))
    x = np.zeros((1, 6))
    x[0, 2] = np.radians(170.0)                      # the outermost joint far from home
    agent3 = read.agents[0]
    q = agent3.q_values(x[:, [2, 5]])
    assert read(x)[0, 2] == agent3.actions[greedy_indices(q, agent3.tie_tolerance)][0, 0]
    with pytest.raises(TypeError, match="readout must be a twolink.policy.readout.Readout"):
        synthesize_links(p, readout={"argmax_beyond_deg": 20.0})
