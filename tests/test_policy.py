"""Policies (14), (16), (18): synthesis, files, provenance, and bad files."""
import json

import numpy as np
import pytest

from twolink import paper
from twolink.policy import Policy, PolicyFileError, load_policy
from twolink.registry import SHIPPED
from twolink.synthesis import synthesize


@pytest.mark.parametrize("name, kind, context", [
    ("centralized", "centralized", "frozen"),
    ("decentralized", "decentralized", "frozen"),
    ("decentralized_propagated", "decentralized", "propagated"),
])
def test_resynthesis_reproduces_shipped_policy_exactly(name, kind, context):
    shipped = Policy.load(SHIPPED[name].file)
    fresh = synthesize(kind, context=context)
    assert [a.name for a in fresh.agents] == [a.name for a in shipped.agents]
    for a, b in zip(fresh.agents, shipped.agents):
        np.testing.assert_array_equal(a.q, b.q)
        assert a.info["iterations"] == b.info["iterations"]


def test_q_table_sizes_of_table_ii(centralized, decentralized):
    assert centralized.q_sizes == {"centralized": paper.Q_SIZES["centralized"]}
    assert decentralized.q_sizes == {"agent2": paper.Q_SIZES["agent2"],
                                     "agent1": paper.Q_SIZES["agent1"]}


def test_provenance_is_recorded(decentralized):
    meta = decentralized.meta
    assert meta["gamma"] == 0.98 and meta["delta"] == 0.01 and meta["model"] == "simplified"
    assert meta["parameters"]["m1"] == 1.25 and meta["context"] == "frozen"
    assert "twolink_version" in meta
    assert decentralized.agents[1].info["iterations"] > 0
    assert decentralized.agents[0].grid.names == ("theta2", "dtheta2")
    assert decentralized.agents[1].grid.names == ("theta1", "dtheta1", "theta2", "tau2")


def test_round_trip_is_bit_for_bit(tmp_path, centralized, rng):
    path = centralized.save(tmp_path / "c.npz")
    again = Policy.load(path)
    np.testing.assert_array_equal(again.agents[0].q, centralized.agents[0].q)
    x = rng.uniform(-3, 3, (100, 4))
    np.testing.assert_array_equal(again(x), centralized(x))
    assert again.meta == centralized.meta


def test_policy_at_bin_centres_is_the_greedy_action(centralized):
    agent = centralized.agents[0]
    c = agent.grid.centers()
    greedy = agent.actions[np.argmax(agent.q, axis=1)]
    np.testing.assert_allclose(centralized(c), greedy, atol=1e-12)


def test_policy_interpolates_between_centres(centralized):
    """(14): between two centres the command is the membership-weighted average."""
    agent = centralized.agents[0]
    c = agent.grid.centers()
    a, b = c[0], c[1]                        # neighbours along the last (dtheta2) axis
    mid = 0.25 * a + 0.75 * b
    expected = 0.25 * agent.greedy_actions[0] + 0.75 * agent.greedy_actions[1]
    np.testing.assert_allclose(centralized(mid), expected, atol=1e-12)


def test_ties_break_to_the_first_action(centralized):
    agent = centralized.agents[0]
    tied = agent.__class__(agent.name, agent.grid, agent.actions, np.zeros_like(agent.q),
                           agent.outputs)
    np.testing.assert_array_equal(tied.greedy_actions, np.tile(agent.actions[0], (agent.q.shape[0], 1)))


def test_decentralized_agent1_sees_agent2_torque(decentralized, rng):
    x = rng.uniform(-3, 3, (50, 4))
    a2, a1 = decentralized.agents
    tau2 = a2.act(x[:, [1, 3]])[:, 0]
    tau1 = a1.act(np.stack([x[:, 0], x[:, 2], x[:, 1], tau2], -1))[:, 0]
    np.testing.assert_allclose(decentralized(x), np.stack([tau1, tau2], -1))


def test_foreign_files_are_refused(tmp_path, centralized):
    text = tmp_path / "notes.npz"
    text.write_text("hello")
    with pytest.raises(PolicyFileError, match="not a twolink policy file"):
        Policy.load(text)
    other = tmp_path / "other.npz"
    np.savez(other, weights=np.zeros(3))
    with pytest.raises(PolicyFileError, match="no policy header"):
        Policy.load(other)
    foreign = tmp_path / "foreign.npz"
    np.savez(foreign, header=np.array(json.dumps({"format": "something-else"})))
    with pytest.raises(PolicyFileError, match="not a twolink policy file"):
        Policy.load(foreign)
    with pytest.raises(PolicyFileError, match="does not exist"):
        Policy.load(tmp_path / "missing.npz")


def test_wrong_shapes_are_refused(tmp_path, centralized):
    header = centralized.header()
    bad = tmp_path / "bad.npz"
    np.savez(bad, header=np.array(json.dumps(header)), q_centralized=np.zeros((10, 9)))
    with pytest.raises(PolicyFileError, match="Q must have shape"):
        Policy.load(bad)
    nan = tmp_path / "nan.npz"
    q = centralized.agents[0].q.copy()
    q[0, 0] = np.nan
    np.savez(nan, header=np.array(json.dumps(header)), q_centralized=q)
    with pytest.raises(PolicyFileError, match="NaN"):
        Policy.load(nan)


def test_unknown_policy_name_and_bad_states(centralized):
    with pytest.raises(PolicyFileError, match="unknown policy 'nonsense'"):
        load_policy("nonsense")
    with pytest.raises(ValueError, match="shape"):
        centralized(np.zeros(3))
    with pytest.raises(ValueError, match="NaN"):
        centralized(np.array([0.0, np.nan, 0.0, 0.0]))


def test_unknown_kind_model_or_context():
    with pytest.raises(ValueError, match="unknown policy kind"):
        synthesize("federated")
    with pytest.raises(ValueError, match="unknown synthesis model"):
        synthesize("centralized", model="exact")
    with pytest.raises(ValueError, match="unknown agent-1 context"):
        synthesize("decentralized", context="magic")


def test_save_leaves_no_partial_file(tmp_path, centralized):
    with pytest.raises(OSError, match="does not exist"):
        centralized.save(tmp_path / "no" / "such" / "dir.npz")
    assert list(tmp_path.iterdir()) == []


def test_refined_problems_for_scaling_studies():
    from twolink.synthesis import agent1_problem, agent2_problem
    a2 = agent2_problem(refine=2)
    assert a2.grid.shape == (24, 13) and a2.next_points.shape == (24 * 13, 3, 2)
    a1 = agent1_problem(None, refine=2)
    assert a1.grid.shape == (24, 13, 24, 3) and a1.rewards.shape == (24 * 13 * 24 * 3, 3)
    with pytest.raises(ValueError, match="needs agent 2"):
        agent1_problem(None, context="propagated")
