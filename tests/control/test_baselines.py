"""The classical baselines (twolink.control.baselines): shapes and saturation, the LQR's
stabilising gain, the PD's decentralization, the shipped gains and their provenance, a
rollout from the paper's x0 on MuJoCo, the dict round trip and one-line errors."""
import json
import math

import numpy as np
import pytest
import scipy.linalg

from twolink.arm.dynamics import full_acceleration
from twolink.arm.parameters import PAPER_X0, TABLE_I, TS
from twolink.control.baselines import (
    BASELINES,
    ProximateTimeOptimal,
    SaturatedLQR,
    SaturatedPD,
    baseline,
    from_description,
    load_gains,
)
from twolink.control.baselines.common import joint_inertia
from twolink.control.baselines.lqr import discrete_linearisation, linearisation
from twolink.control.baselines.search import RowPlant, coordinate_search, run_candidates
from twolink.control.baselines.tuning import SPECS, TUNING_SEEDS
from twolink.sim.challenges import LEVELS
from twolink.sim.metrics import random_poses, settle_time, success
from twolink.sim.perturbations import ActuationDelay
from twolink.sim.plants import make_plant
from twolink.sim.rollout import rollout

NAMES = list(BASELINES)


@pytest.fixture(scope="module")
def states():
    rng = np.random.default_rng(7)
    x = np.empty((200, 4))
    x[:, :2] = rng.uniform(-math.pi, math.pi, (200, 2))
    x[:, 2:] = rng.uniform(-2 * math.pi, 2 * math.pi, (200, 2))
    return x


@pytest.mark.parametrize("name", NAMES)
def test_shapes_and_saturation(name, states):
    ctrl = baseline(name)
    u = ctrl(states)
    assert u.shape == (200, 2) and np.all(np.isfinite(u))
    assert np.all(np.abs(u) <= TABLE_I.tau_max + 1e-12)
    assert baseline(name)(states[0]).shape == (2,)
    assert baseline(name)(states.reshape(10, 20, 4)).shape == (10, 20, 2)
    # far from the goal every law pushes at full torque
    far = np.array([[2.5, 2.5, 0.0, 0.0], [-2.5, -2.5, 0.0, 0.0]])
    np.testing.assert_allclose(np.abs(baseline(name)(far)), [TABLE_I.tau_max] * 2)
    assert np.all(np.sign(baseline(name)(far)) == -np.sign(far[:, :2]))
    assert np.all(baseline(name)(np.zeros((3, 4))) == 0.0)


@pytest.mark.parametrize("name", ["lqr", "lqr_delay"])
def test_the_lqr_gain_stabilises_the_linearisation(name):
    ctrl = baseline(name)
    eig = np.linalg.eigvals(ctrl.closed_loop_matrix())
    assert np.max(np.abs(eig)) < 1.0
    assert ctrl.K.shape == (2, 4 + 2 * ctrl.delay)


@pytest.mark.parametrize("delay", [0, 1, 3])
def test_any_positive_weights_stabilise(delay, rng):
    for _ in range(5):
        ctrl = SaturatedLQR(10 ** rng.uniform(-2, 3, 4), 10 ** rng.uniform(-1, 2, 2),
                            delay=delay)
        assert np.max(np.abs(np.linalg.eigvals(ctrl.closed_loop_matrix()))) < 1.0


def test_the_linearisation_is_that_of_the_full_model():
    a, b = linearisation(TABLE_I)
    eps = 1e-6
    x0, u0 = np.zeros(4), np.zeros(2)
    for j in range(4):
        dx = np.zeros(4)
        dx[j] = eps
        num = (full_acceleration(TABLE_I, x0 + dx, u0) - full_acceleration(TABLE_I, x0 - dx, u0))
        np.testing.assert_allclose(a[2:, j], num / (2 * eps), atol=1e-6)
    for j in range(2):
        du = np.zeros(2)
        du[j] = eps
        num = full_acceleration(TABLE_I, x0, du) - full_acceleration(TABLE_I, x0, -du)
        np.testing.assert_allclose(b[2:, j], num / (2 * eps), rtol=1e-6)
    ad, bd = discrete_linearisation(TABLE_I)
    big = np.zeros((6, 6))                # ZOH: expm([[A, B], [0, 0]] Ts)
    big[:4, :4], big[:4, 4:] = a, b
    e = scipy.linalg.expm(big * TS)
    np.testing.assert_allclose(ad, e[:4, :4], atol=1e-12)
    np.testing.assert_allclose(bd, e[:4, 4:], atol=1e-12)


@pytest.mark.parametrize("name", ["pd", "pd_deadzone", "bang_bang"])
def test_decentralization(name, states):
    """Joint i's torque depends on theta_i and dtheta_i only."""
    ctrl = baseline(name)
    u = ctrl(states)
    shuffled = states.copy()
    shuffled[:, [1, 3]] = states[::-1][:, [1, 3]]      # other joint 2 states
    np.testing.assert_array_equal(ctrl(shuffled)[:, 0], u[:, 0])
    shuffled = states.copy()
    shuffled[:, [0, 2]] = states[::-1][:, [0, 2]]
    np.testing.assert_array_equal(ctrl(shuffled)[:, 1], u[:, 1])


def test_the_lqr_is_centralized():
    u = baseline("lqr")(np.array([[0.0, 0.1, 0.0, 0.0]]))
    assert u[0, 0] != 0.0


def test_the_dead_zone():
    pd = SaturatedPD([1.0, 0.5], [0.1, 0.02], dead_zone_deg=3.0)
    inside = np.array([[math.radians(2.9), math.radians(-2.9), 0.3, -0.2]])
    np.testing.assert_allclose(pd(inside), [[-0.03, 0.004]])
    edge = math.radians(3.0)
    out = np.array([[edge + 0.01, -edge - 0.01, 0.0, 0.0]])
    np.testing.assert_allclose(pd(out), [[-0.01, 0.005]])               # shrink: continuous
    cut = SaturatedPD([1.0, 0.5], [0.1, 0.02], dead_zone_deg=3.0, dead_zone_kind="cut")
    np.testing.assert_allclose(cut(out), [[-(edge + 0.01), 0.5 * (edge + 0.01)]])
    np.testing.assert_allclose(cut(inside), pd(inside))


def test_the_ptos_law_is_continuous_and_linear_near_the_goal():
    ctrl = ProximateTimeOptimal([0.8, 0.6], [6.0, 9.0])
    edge = ctrl.linear_zone
    below, above = ctrl.curve(edge * (1 - 1e-9)), ctrl.curve(edge * (1 + 1e-9))
    np.testing.assert_allclose(below, above, rtol=1e-6)
    small = np.array([[1e-3, -2e-3, 1e-3, 2e-3]])
    j = joint_inertia()
    pd = -j * (ctrl.k1 * small[0, :2] + ctrl.k2 * small[0, 2:])
    np.testing.assert_allclose(ctrl(small)[0], pd)


def test_the_shipped_gains_load_with_their_provenance():
    doc = load_gains()
    assert set(doc["controllers"]) == set(BASELINES) == set(SPECS)
    assert doc["twolink_version"] and doc["created_by"].startswith("python -m")
    for name, entry in doc["controllers"].items():
        t = entry["tuning"]
        assert t["pose_seed"] in TUNING_SEEDS and t["optimised"] and t["states"]
        assert "random_poses" in t["states"]
        assert t["challenge"] == SPECS[name].challenge
        assert t["score"]["successes"] <= t["score"]["n"]
        ctrl = baseline(name)
        assert ctrl.name == name and isinstance(ctrl, BASELINES[name].cls)
    assert baseline("pd_deadzone").dead_zone_deg > 0
    assert baseline("lqr_delay").delay == LEVELS["medium"].action_delay
    assert baseline("pd").meta["model"] == "full"


@pytest.mark.parametrize("name", ["lqr", "pd"])
def test_a_rollout_from_the_paper_x0_settles_on_mujoco(name):
    with make_plant("mujoco", TABLE_I) as plant:
        traj = rollout(baseline(name), plant, np.array([PAPER_X0]))
    assert bool(success(traj)[0]), settle_time(traj)
    assert settle_time(traj)[0] < 5.0


@pytest.mark.parametrize("name", NAMES)
def test_dict_round_trip(name, states):
    ctrl = baseline(name)
    d = ctrl.as_dict()
    back = type(ctrl).from_dict(json.loads(json.dumps(d)))
    assert back.as_dict() == d and back.name == name
    np.testing.assert_array_equal(back(states), baseline(name)(states))
    assert from_description(d).as_dict() == d


@pytest.mark.parametrize("make", [
    lambda: SaturatedPD([-1.0, 1.0], [0.1, 0.1]),
    lambda: SaturatedPD([1.0, 1.0], [float("nan"), 0.1]),
    lambda: SaturatedPD([1.0, 1.0], [0.1, 0.1], dead_zone_deg=-1),
    lambda: SaturatedPD([1.0, 1.0], [0.1, 0.1], dead_zone_kind="soft"),
    lambda: SaturatedPD([1.0], [0.1, 0.2, 0.3]),
    lambda: SaturatedLQR([1, 1, 1, -1], [1, 1]),
    lambda: SaturatedLQR([1, 1, 1, 1], [float("nan"), 1]),
    lambda: SaturatedLQR([1, 1, 1, 1], [1, 1], delay=-1),
    lambda: ProximateTimeOptimal([0.5, 0.5], [0.0, 4.0]),
    lambda: ProximateTimeOptimal([float("inf"), 0.5], [4.0, 4.0]),
    lambda: SaturatedPD.from_dict({"kp": [1, 1], "kd": [0, 0], "gain": 3}),
    lambda: SaturatedPD.from_dict(baseline("lqr").as_dict()),
])
def test_bad_gains_give_one_line_errors(make):
    with pytest.raises(ValueError) as err:
        make()
    assert "\n" not in str(err.value) and str(err.value)


def test_the_delay_aware_lqr_remembers_and_resets():
    ctrl = baseline("lqr_delay")
    x = np.array([[0.5, -0.5, 0.0, 0.0]])
    first = ctrl(x)
    assert not np.array_equal(ctrl(x), first)           # the pipelined torque counts
    ctrl.reset(1)
    np.testing.assert_array_equal(ctrl(x), first)
    act = ActuationDelay(baseline("lqr_delay"), 1)
    with make_plant("full", TABLE_I) as plant:
        traj = rollout(act, plant, np.array([PAPER_X0]))
    assert bool(success(traj)[0])


def test_the_row_plant_is_the_full_plant():
    """The tuning's per-row numpy plant steps as the full plant does."""
    x0 = random_poses(2, 6, seed=3)
    ctrl = baseline("lqr")
    with make_plant("full", TABLE_I) as plant:
        ref = rollout(ctrl, plant, x0, duration=1.0)
    got = rollout(ctrl, RowPlant([TABLE_I] * 6), x0, duration=1.0)
    np.testing.assert_allclose(got.x, ref.x, atol=1e-12)


def test_candidates_side_by_side_meet_the_same_noise():
    """Two copies of a controller in one batch under the medium challenge get the same
    outcomes (the same noise per (plant, pose)), and a candidate's outcome does not
    depend on the candidates beside it."""
    x0 = random_poses(2, 4, seed=5)
    plants = LEVELS["medium"].plants(2, 9)
    a, b = baseline("pd_deadzone"), baseline("pd_deadzone")
    ok, settle = run_candidates([a, b, baseline("pd")], x0, plants, LEVELS["medium"], seed=9)
    assert ok.shape == (3, 2, 4)
    np.testing.assert_array_equal(settle[0], settle[1])
    _, settle1 = run_candidates([baseline("pd_deadzone")], x0, plants, LEVELS["medium"],
                                  seed=9)
    np.testing.assert_array_equal(settle1[0], settle[0])


def test_the_shipped_points_rebuild_the_shipped_controllers():
    """The provenance's tuned point, through the tuning's parametrisation, is the shipped
    controller (the file was written by the tuning, not by hand)."""
    for name, entry in load_gains()["controllers"].items():
        rebuilt = SPECS[name].build(entry["tuning"]["point"], name)
        assert rebuilt.as_dict() == entry["controller"]


def test_coordinate_search_finds_the_best_grid_point():
    target = {"a": 3, "b": 0.5}

    def evaluate(points):
        return [{"successes": -abs(p["a"] - target["a"]) - abs(p["b"] - target["b"]),
                 "median_settle": 1.0, "mean_settle_capped": 1.0} for p in points]

    point, best, history = coordinate_search(evaluate, {"a": 1, "b": 2.0},
                                             {"a": [1, 2, 3, 4], "b": [0.5, 1.0, 2.0]})
    assert point == target and best["successes"] == 0 and history
