"""The synthesis design options: torque levels, bin layouts and the read-out dead zone,
checked before any work and recorded in the policy file."""
import math

import numpy as np
import pytest

from twolink.arm.parameters import GOAL_ANGLE, TABLE_I
from twolink.arm.task import action_levels, check_levels
from twolink.cli import main
from twolink.synthesis.problems import check_size, table_sizes
from twolink.synthesis.synthesize import synthesize
from twolink.fqi import fuzzy
from twolink.policy.fuzzy_policy import Policy, load_policy
from twolink.policy.readout import Readout
from twolink.policy.registry import SHIPPED


def test_levels_are_evenly_spaced_and_the_paper_keeps_its_three():
    assert action_levels(0.2).tolist() == [-0.2, 0.0, 0.2]
    assert np.allclose(action_levels(0.2, 5), [-0.2, -0.1, 0.0, 0.1, 0.2])
    assert np.allclose(action_levels(0.1, 2), [-0.1, 0.1])
    for bad in (1, 10, 2.5, True, "5"):
        with pytest.raises(ValueError, match="levels must be a whole number from 2 to 9"):
            check_levels(bad)


def test_the_goal_layout_puts_centres_at_and_inside_the_band():
    ang = np.rad2deg(fuzzy.angle_axis("a", "goal").centers)
    spd = np.rad2deg(fuzzy.speed_axis("s", "goal").centers)
    assert {-5.0, -2.0, 0.0, 2.0, 5.0} <= set(np.round(ang, 9))
    assert np.all(np.abs(spd[np.abs(spd) <= 5.0]) <= math.degrees(0.1))
    assert fuzzy.angle_axis("a").size == 12 and fuzzy.angle_axis("a", "goal").size == 16
    with pytest.raises(ValueError, match="unknown bin layout 'fine'; choose one of paper, goal, edge"):
        fuzzy.angle_axis("a", "fine")


def test_the_edge_layout_brackets_the_band_edge_without_a_centre_on_it():
    ang = np.rad2deg(fuzzy.angle_axis("a", "edge").centers)
    edge = math.degrees(GOAL_ANGLE)
    assert fuzzy.angle_axis("a", "edge").size == 22
    assert np.min(np.abs(np.abs(ang) - edge)) >= 1.0
    inside = ang[np.abs(ang) < edge]
    assert sorted(np.round(inside, 9)) == [-4.0, 0.0, 4.0]
    assert np.min(np.abs(ang)[np.abs(ang) > edge]) == 9.0
    # beyond 10 deg the centres are the paper's halved once
    halved = np.rad2deg(fuzzy.angle_axis("a").refined(2).centers)
    assert set(np.round(ang[np.abs(ang) > 10], 9)) == set(np.round(halved[np.abs(halved) > 10], 9))
    assert np.array_equal(fuzzy.speed_axis("s", "edge").centers, fuzzy.speed_axis("s").centers)
    assert table_sizes("decentralized", levels=7, bins="edge") == {
        "agent2": 22 * 7 * 7, "agent1": 22 * 7 * 22 * 7 * 7}


def test_table_sizes_follow_levels_and_bins():
    assert table_sizes("centralized") == {"centralized": 63504}
    assert table_sizes("centralized", levels=5, bins="goal") == {"centralized": 16 ** 2 * 13 ** 2 * 25}
    assert table_sizes("decentralized", levels=7) == {"agent2": 84 * 7, "agent1": 1008 * 7 * 7}
    with pytest.raises(ValueError, match=r"Q-table of \d+ values \(396 MiB\) is over the 64 MiB"):
        check_size("centralized", refine=2, levels=9, bins="goal")


def test_a_designed_policy_records_its_design_and_reads_through_its_dead_zone(tmp_path):
    policy = synthesize("decentralized", model="full", levels=5,
                        readout=Readout(speed_dead_zone=0.05))
    a2, a1 = policy.agents
    assert a2.q.shape == (84, 5) and a1.q.shape == (1008 * 5, 5)
    assert a1.grid.axes[-1].centers == tuple(action_levels(TABLE_I.tau2_max, 5))
    assert policy.meta["levels"] == 5 and "bins" not in policy.meta
    assert policy.meta["readout"] == {"speed_dead_zone": 0.05, "angle_dead_zone_deg": 0.0}
    plain = Policy(policy.kind, policy.agents, {k: v for k, v in policy.meta.items()
                                                 if k != "readout"})
    x = np.array([[0.3, -0.2, 0.08, -0.04], [1.0, 2.0, -0.5, 0.3]])
    shrunk = x.copy()
    shrunk[:, 2:] = np.sign(x[:, 2:]) * np.maximum(np.abs(x[:, 2:]) - 0.05, 0.0)
    assert np.array_equal(policy(x), plain(shrunk))
    assert not np.array_equal(policy(x), plain(x))
    loaded = Policy.load(policy.save(tmp_path / "p.npz"))
    assert loaded.readout == policy.readout and np.array_equal(loaded(x), policy(x))


def test_beyond_the_argmax_angle_a_policy_acts_by_the_largest_interpolated_q():
    base = synthesize("centralized", model="full", levels=5, bins="goal")
    rule = Readout(argmax_beyond_deg=30.0)
    policy = Policy(base.kind, base.agents, {**base.meta, "readout": rule.as_dict()})
    agent = base.agents[0]
    rng = np.random.default_rng(5)
    x = np.c_[rng.uniform(-np.pi, np.pi, (400, 2)), rng.uniform(-3, 3, (400, 2))]
    far = np.any(np.abs(x[:, :2]) > np.radians(30.0), axis=1)
    assert 0 < far.sum() < len(x)
    q = agent.q_values(x[far])
    assert np.array_equal(policy(x)[far], agent.actions[np.argmax(q, axis=1)])
    assert np.array_equal(policy(x)[~far], base(x)[~far])
    # (14) averages opposite greedy torques to a small one somewhere; the argmax never does
    assert np.min(np.abs(base(x)[far][:, 0])) < 0.05
    assert set(np.round(np.abs(policy(x)[far][:, 0]), 9)) <= {0.0, 0.1, 0.2}


def test_the_paper_design_leaves_meta_as_it_was():
    policy = synthesize("decentralized", model="full")
    assert not {"levels", "bins", "readout"} & set(policy.meta)


@pytest.mark.parametrize("bad, match", [
    ({"speed_dead_zone": 0.2}, r"speed dead zone must be a number in \[0, 0.1\]"),
    ({"angle_dead_zone_deg": -1}, r"angle dead zone must be a number in \[0, 5"),
    ({"speed_dead_zone": float("nan")}, "speed dead zone must be"),
    ({"argmax_beyond_deg": 5.0}, r"argmax_beyond_deg must be a number in \[10, 180\]"),
])
def test_a_dead_zone_wider_than_the_band_is_refused(bad, match):
    with pytest.raises(ValueError, match=match):
        Readout(**bad)


def test_the_near_goal_gain_ramps_each_joint_by_its_own_angle(tmp_path):
    """tau_i = (g + (1 - g) min(|theta_i| / A, 1)) times (14)'s, theta_i as read (before
    the dead zone), on the torques sent: at the goal g times, beyond A untouched."""
    base = synthesize("decentralized", model="full", levels=5,
                      readout=Readout(speed_dead_zone=0.05))
    rule = Readout(speed_dead_zone=0.05, near_gain=0.25, near_deg=40.0)
    assert rule.as_dict() == {"speed_dead_zone": 0.05, "angle_dead_zone_deg": 0.0,
                              "near_gain": 0.25, "near_deg": 40.0}
    policy = Policy(base.kind, base.agents, {**base.meta, "readout": rule.as_dict()})
    rng = np.random.default_rng(11)
    x = np.c_[rng.uniform(-np.pi, np.pi, (500, 2)), rng.uniform(-3, 3, (500, 2))]
    x[:5, :2] = np.radians([[0, 0], [10, -20], [40, -40], [90, 3], [-179, 179]])
    theta = np.abs(x[:, :2])
    s = 0.25 + 0.75 * np.minimum(theta / np.radians(40.0), 1.0)
    np.testing.assert_allclose(policy(x), s * base(x), rtol=0, atol=1e-15)
    np.testing.assert_allclose(s[:3], [[0.25, 0.25], [0.4375, 0.625], [1.0, 1.0]])
    wrapped = x.copy()
    wrapped[:, :2] += 2 * np.pi                              # read as wrapped angles
    np.testing.assert_allclose(policy(wrapped), policy(x), atol=1e-12)
    loaded = Policy.load(policy.save(tmp_path / "g.npz"))
    assert loaded.readout == rule and np.array_equal(loaded(x), policy(x))
    assert Readout(near_gain=1.0).as_dict() == Readout().as_dict()   # 1: off, not recorded
    assert not Readout(near_gain=1.0).active and rule.active


@pytest.mark.parametrize("bad, match", [
    ({"near_gain": 0.0, "near_deg": 40.0}, r"near_gain must be a number in \(0, 1\]"),
    ({"near_gain": 1.5, "near_deg": 40.0}, r"near_gain must be a number in \(0, 1\]"),
    ({"near_gain": 0.5}, "a near-goal gain of 0.5 needs near_deg"),
    ({"near_gain": 0.5, "near_deg": 4.0}, r"near_deg must be a number in \[5, 180\]"),
    ({"near_gain": 0.5, "near_deg": float("inf")}, "near_deg must be"),
])
def test_a_near_goal_gain_outside_its_range_is_refused(bad, match):
    with pytest.raises(ValueError, match=match):
        Readout(**bad)


def test_design_options_are_two_link_only():
    with pytest.raises(ValueError,
                       match="levels, bins, readout and agent2_link1 are two-link options"):
        synthesize("decentralized", links=3, levels=5)
    with pytest.raises(TypeError, match="readout must be a twolink.policy.readout.Readout"):
        synthesize("decentralized", readout={"speed_dead_zone": 0.1})


@pytest.mark.parametrize("argv, match", [
    (["centralized", "--levels", "1"], "--levels must be a whole number from 2 to 9, got 1"),
    (["centralized", "--levels", "x"], "--levels must be a whole number, got 'x'"),
    (["centralized", "--bins", "fine"], "unknown bin layout 'fine'"),
    (["centralized", "--speed-dead-zone", "0.5"], r"--speed-dead-zone must lie in \[0, 0.1\]"),
    (["centralized", "--levels", "9", "--bins", "goal", "--refine", "2"], "over the 64 MiB"),
    (["decentralized", "--links", "3", "--levels", "5"], "--levels: two-link options"),
    (["--ship", "centralized_tuned", "--levels", "5"], "--ship takes everything"),
    (["centralized", "--argmax-beyond-deg", "200"], r"--argmax-beyond-deg must lie in \[10, 180\]"),
    (["centralized", "--model", "full", "--agent2-link1", "locked"],
     "agent2_link1 is how the decentralized agent 2 reads link 1"),
    (["decentralized", "--agent2-link1", "locked"], r"under \(11\) link 2 does not depend"),
    (["decentralized", "--links", "3", "--agent2-link1", "locked"],
     "--agent2-link1: two-link options"),
    (["--ship", "decentralized_edge", "--agent2-link1", "locked"], "--ship takes everything"),
    (["decentralized", "--near-gain", "0.5"], "--near-gain needs --near-deg"),
    (["decentralized", "--near-gain", "0", "--near-deg", "40"],
     r"--near-gain must lie in \(0, 1\], got 0"),
    (["decentralized", "--near-gain", "nan", "--near-deg", "40"],
     "--near-gain must be a number, got .nan."),
    (["decentralized", "--near-gain", "0.5", "--near-deg", "2"],
     r"--near-deg must lie in \[5, 180\] degrees, got 2"),
    (["decentralized", "--near-deg", "40"], "--near-deg goes with --near-gain"),
    (["decentralized", "--links", "3", "--near-gain", "0.5", "--near-deg", "40"],
     "--near-gain, --near-deg: two-link options"),
    (["--ship", "decentralized_edge", "--near-gain", "0.5"], "--ship takes everything"),
])
def test_bad_design_options_are_one_line_exit_2_and_nothing_written(tmp_path, capsys, argv,
                                                                      match):
    out = tmp_path / "p.npz"
    extra = [] if "--ship" in argv else ["-o", str(out)]
    assert main(["synthesize", *argv, *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and __import__("re").search(match, err[0]), err
    assert not out.exists()


def test_the_tuned_designs_are_registered_with_their_options():
    c, d = SHIPPED["centralized_tuned"], SHIPPED["decentralized_tuned"]
    assert c.synthesis_options()["levels"] == 5 and c.synthesis_options()["bins"] == "goal"
    assert c.synthesis_options()["readout"] == Readout(speed_dead_zone=0.08,
                                                       argmax_beyond_deg=30.0)
    assert d.synthesis_options()["levels"] == 7 and d.context == "propagated"
    assert not c.paper and not d.paper and c.tuned and d.tuned
    nine = SHIPPED["centralized_9levels"].synthesis_options()
    assert (nine["levels"], nine["bins"], nine["readout"]) == (
        9, "goal", Readout(speed_dead_zone=0.04, argmax_beyond_deg=45.0))


def test_the_edge_designs_are_the_tuned_designs_on_the_edge_bins():
    for edge, tuned in (("centralized_robust_edge", "centralized_robust_tuned"),
                        ("decentralized_edge", "decentralized_tuned")):
        e, t = SHIPPED[edge].synthesis_options(), SHIPPED[tuned].synthesis_options()
        assert e.pop("bins") == "edge" and "bins" not in t
        assert e == t and SHIPPED[edge].tuned and not SHIPPED[edge].paper


def test_agent2_holding_joint1_sees_link2_swing_alone():
    from twolink.synthesis.problems import agent2_problem, check_link1

    free = agent2_problem(TABLE_I, "full", levels=3)
    held = agent2_problem(TABLE_I, "full", levels=3, link1="locked")
    assert held.next_points.shape == free.next_points.shape == (84, 3, 2)
    # joint 1 held: dtheta2' = -b2/P2 dtheta2 + tau2/P2, solved exactly over Ts
    p, c = TABLE_I, held.grid.centers()
    rows = np.abs(c[:, 1]) < 1.0                     # no speed clamp
    w0, tau = c[rows, 1][:, None], held.actions[None, :, 0]
    k = p.b2 / p.P2
    exact = tau / p.b2 + (w0 - tau / p.b2) * np.exp(-k * 0.05)
    assert np.allclose(held.next_points[rows][..., 1], exact, atol=1e-8)
    # free, link 1 recoils and link 2 turns further under the same torque
    moved = np.abs(free.next_points[..., 1] - held.next_points[..., 1])
    assert moved.max() > 0.05
    with pytest.raises(ValueError, match="unknown reading of link 1 by agent 2 'rigid'; "
                                         "choose one of free, locked"):
        check_link1("rigid")
    with pytest.raises(ValueError, match=r"under \(11\) link 2 does not depend on link 1"):
        agent2_problem(TABLE_I, "simplified", link1="locked")


def test_a_locked_design_records_its_reading_and_the_registry_rebuilds_it(tmp_path):
    e = SHIPPED["decentralized_edge_locked"]
    opts = e.synthesis_options()
    assert opts["agent2_link1"] == "locked" and opts["bins"] == "edge"
    assert main(["synthesize", "decentralized", "--model", "full", "--context", "propagated",
                 "--agent2-link1", "locked", "-o", str(tmp_path / "p.npz")]) == 0
    policy = Policy.load(tmp_path / "p.npz")
    assert policy.meta["agent2_link1"] == "locked"
    paper = synthesize("decentralized", model="full", context="propagated")
    assert "agent2_link1" not in paper.meta
    assert not np.array_equal(policy.agents[0].q, paper.agents[0].q)


@pytest.mark.parametrize("gain, base", [
    ("decentralized_edge_gain", "decentralized_edge"),
    ("decentralized_edge_gain_hard", "decentralized_edge"),
    ("decentralized_locked_gain", "decentralized_locked"),
    ("decentralized_locked_gain_medium", "decentralized_locked"),
    ("decentralized_edge_locked_gain", "decentralized_edge_locked"),
    ("centralized_robust_edge_gain", "centralized_robust_edge"),
    ("centralized_robust_edge_gain_medium", "centralized_robust_edge"),
])
def test_the_gain_designs_are_their_base_with_a_near_goal_gain(gain, base):
    """Each `*_gain` policy is its base design (the same Q-tables in its file) whose
    read-out adds the near-goal gain, and the CLI rebuilds its read-out from the flags."""
    g, b = SHIPPED[gain].synthesis_options(), SHIPPED[base].synthesis_options()
    rg, rb = g.pop("readout"), b.pop("readout")
    assert g == b and SHIPPED[gain].tuned
    assert rg.near_gain < 1 and (rg.speed_dead_zone, rg.argmax_beyond_deg) == \
        (rb.speed_dead_zone, rb.argmax_beyond_deg) and rb.near_gain == 1
    assert SHIPPED[gain].table == SHIPPED[base].table and SHIPPED[base].table_owner == base
    assert SHIPPED[gain].file == SHIPPED[base].file
    pg, pb = load_policy(gain), load_policy(base)
    assert all(a.q is c.q or np.array_equal(a.q, c.q) for a, c in zip(pg.agents, pb.agents))
    assert pg.readout == rg and pb.readout == rb and pg.meta["table"] == SHIPPED[base].table
