"""Closed-loop rollouts and the metrics of docs/conventions.md (the plants: test_plants.py)."""
import numpy as np
import pytest

from twolink.arm.parameters import GOAL_ANGLE, PAPER_X0, TS
from twolink.sim.metrics import (
    discounted_return,
    evaluation_set,
    settle_time,
    success,
    summary,
    trajectory_gap,
)
from twolink.sim.plants import PLANTS, make_plant
from twolink.sim.rollout import MAX_DURATION, Trajectory, rollout, steps_for


@pytest.mark.parametrize("name", ["centralized", "decentralized"])
def test_paper_policies_stabilise_the_simplified_plant(name, request):
    """From x0 each paper policy settles (the centralized one within 1.5 s, paper: about
    1.2 s), or, decentralized, parks at rest a hair outside the 5 deg band (an edge
    stall, README), i.e. with the paper's "steady-state offsets within 5 deg"."""
    from twolink.sim.metrics import stalled_at_band_edge
    policy = request.getfixturevalue(name)
    tr = rollout(policy, make_plant("simplified"), PAPER_X0)
    s = summary(tr)
    if name == "centralized" or s["success"]:
        assert s["success"] and 0.5 <= s["settle_time"] <= 1.5
        assert np.all(np.abs(s["final_offsets_deg"]) <= 5.0)
    else:
        assert stalled_at_band_edge(tr)
        assert np.all(np.abs(s["final_offsets_deg"]) <= 5.1)


def test_batched_rollout_equals_one_at_a_time(centralized):
    x0 = evaluation_set()[:6]
    plant = make_plant("simplified")
    batch = rollout(centralized, plant, x0, duration=1.0)
    for i in range(len(x0)):
        one = rollout(centralized, plant, x0[i], duration=1.0)
        np.testing.assert_array_equal(batch.x[i], one.x)
        np.testing.assert_array_equal(batch.u[i], one.u)


def test_unknown_plant():
    with pytest.raises(ValueError, match="unknown plant 'real'"):
        make_plant("real")


def test_rollout_rejects_bad_x0(centralized):
    for plant in PLANTS:
        with pytest.raises(ValueError, match="x0 must have 4 components"):
            rollout(centralized, make_plant(plant), [1.0, 2.0])
    with pytest.raises(ValueError, match="x0 contains NaN"):
        rollout(centralized, make_plant("simplified"), [np.nan, 0, 0, 0])
    with pytest.raises(ValueError, match="duration"):
        rollout(centralized, make_plant("simplified"), PAPER_X0, duration=-1)
    with pytest.raises(ValueError, match="x0 has a speed of magnitude 100"):
        rollout(centralized, make_plant("mujoco"), [0, 0, 100, 0])


def test_horizon_is_bounded_before_allocating(centralized):
    assert steps_for(MAX_DURATION) == round(MAX_DURATION / TS)
    for duration in (1e12, MAX_DURATION + 1, float("inf")):
        with pytest.raises(ValueError, match="duration must be"):
            steps_for(duration)
    with pytest.raises(ValueError, match=r"100000 states x 72000 sample periods need .* GiB"):
        rollout(centralized, make_plant("simplified"), np.zeros((100000, 4)),
                duration=MAX_DURATION)


def test_trajectory_carries_label_and_kind(decentralized):
    plant = make_plant("simplified")
    tr = rollout(decentralized, plant, evaluation_set()[:3], duration=0.2,
                 label="decentralized_propagated")
    assert (tr.plant, tr.label, tr.kind) == ("simplified", "decentralized_propagated",
                                             "decentralized")
    row = tr[1]
    assert (row.plant, row.label, row.kind) == (tr.plant, tr.label, tr.kind)
    np.testing.assert_array_equal(row.x, tr.x[1])
    assert rollout(decentralized, plant, PAPER_X0, duration=0.1).label == "decentralized"


def _traj(inside):
    inside = np.asarray(inside, dtype=bool)
    k = len(inside)
    x = np.where(inside[:, None], 0.0, 1.0) * np.ones((k, 4))
    r = np.where(inside[1:], 0.0, -0.5)
    return Trajectory(np.arange(k) * TS, x, np.zeros((k - 1, 2)), r, np.zeros((k - 1, 2)))


def test_settle_time_success_and_return():
    tr = _traj([0, 0, 1, 0, 1, 1, 1])
    assert settle_time(tr) == pytest.approx(4 * TS)
    assert settle_time(_traj([0, 1, 1, 1, 0])) == np.inf
    assert settle_time(_traj([1, 1, 1])) == 0.0
    assert discounted_return(tr) == pytest.approx(-0.5 * (1 + 0.98**2))
    long = _traj([0] * 10 + [1] * 91)          # 5 s horizon, settles at 0.5 s
    assert success(long)
    late = _traj([0] * 90 + [1] * 11)          # settles at 4.5 s > 5 s - 1 s
    assert not success(late)


def test_goal_band_edges():
    tr = _traj([1, 1])
    tr.x[:] = [GOAL_ANGLE, -GOAL_ANGLE, 0.1, -0.1]
    assert settle_time(tr) == 0.0
    tr.x[1, 0] = GOAL_ANGLE * 1.001
    assert settle_time(tr) == np.inf


def test_trajectory_gap_wraps_angles(centralized):
    tr = rollout(centralized, make_plant("simplified"), PAPER_X0, duration=0.5)
    shifted = Trajectory(tr.t, tr.x.copy(), tr.u, tr.r, tr.r_links)
    shifted.x[:, :2] += 2 * np.pi
    gap = trajectory_gap(tr, shifted)
    assert gap["angle_rms"] == pytest.approx(0.0, abs=1e-12) and gap["speed_rms"] == 0.0


def test_evaluation_set_is_fixed():
    ev = evaluation_set()
    assert ev.shape == (65, 4)
    np.testing.assert_array_equal(ev[0], PAPER_X0)
    assert np.all(ev[1:, 2:] == 0)


def test_stalled_at_band_edge_is_a_diagnostic_beside_success():
    from twolink.sim.metrics import stalled_at_band_edge
    parked = _traj([0] * 101)
    parked.x[:] = [GOAL_ANGLE * 1.005, 0.0, 0.0, 0.0]     # at rest, 0.025 deg outside
    assert not success(parked) and stalled_at_band_edge(parked)
    far = _traj([0] * 101)
    far.x[:] = [GOAL_ANGLE * 2, 0.0, 0.0, 0.0]             # at rest, 5 deg outside
    assert not stalled_at_band_edge(far)
    moving = _traj([0] * 101)
    moving.x[:] = [GOAL_ANGLE * 1.005, 0.0, 0.5, 0.0]      # near the edge but moving
    assert not stalled_at_band_edge(moving)
    assert not stalled_at_band_edge(_traj([0] * 10 + [1] * 91))   # a success is no stall


def test_paper_policy_failures_on_the_simplified_plant_are_edge_stalls(centralized):
    from twolink.sim.metrics import stalled_at_band_edge
    tr = rollout(centralized, make_plant("simplified"), evaluation_set())
    failed = ~success(tr)
    assert 0 < failed.sum() < len(failed)
    np.testing.assert_array_equal(stalled_at_band_edge(tr), failed)
    assert np.abs(tr.u[failed, -1]).max() < 1e-4          # (14) barely pushes there


@pytest.mark.parametrize("k, n, lo, hi", [(0, 10, 0.0, 0.2775), (5, 10, 0.2366, 0.7634),
                                           (10, 10, 0.7225, 1.0)])
def test_wilson_interval_matches_published_values(k, n, lo, hi):
    from twolink.sim.metrics import wilson_interval
    from twolink.viz.formatting import format_rate
    got = wilson_interval(k, n)
    assert got == pytest.approx((lo, hi), abs=5e-4)
    assert format_rate(k, n).startswith(f"{k}/{n} = ")
    with pytest.raises(ValueError, match="successes <= n"):
        wilson_interval(11, 10)


def test_a_duration_under_one_sample_period_is_refused():
    from twolink.sim.rollout import steps_for

    with pytest.raises(ValueError, match=r"duration must be at least one sample period "
                                         r"\(0.05 s\), got 1e-09"):
        steps_for(1e-9)
    assert steps_for(0.05) == 1 and steps_for(0.026) == 1 and steps_for(5.0) == 100
