"""The plant contract, over every plant: shapes, batching, the conventions of
docs/conventions.md (wrap, saturation, clipping), determinism, refusal of bad input and loud failure."""
import math
import os
import warnings

import numpy as np
import pytest
from reference_plants import MujocoStepLoop

from twolink.arm.parameters import PAPER_X0, TABLE_I
from twolink.sim import plants as plants_mod
from twolink.sim.plants import (
    MAX_ANGLE,
    PLANTS,
    SPEED_BOUND,
    MujocoPlant,
    SimulationError,
    make_plant,
)
from twolink.sim.rollout import rollout

VMAX = TABLE_I.speed_max
TMAX = TABLE_I.tau_max


@pytest.fixture(scope="module", params=PLANTS)
def plant(request):
    with make_plant(request.param, nthread=2) if request.param == "mujoco" \
            else make_plant(request.param) as p:
        yield p


def _states(rng, n):
    x = rng.uniform(-3, 3, (n, 4))
    x[:, 2:] *= 2
    return x


def test_shapes_and_broadcast_torques(plant, rng):
    x = _states(rng, 6)
    assert plant.step(x[0], [0.1, -0.05]).shape == (4,)
    assert plant.step(x, [0.1, -0.05]).shape == (6, 4)
    assert plant.step(x.reshape(2, 3, 4), np.zeros((2, 3, 2))).shape == (2, 3, 4)
    np.testing.assert_array_equal(plant.step(x, [0.1, -0.05]),
                                  plant.step(x, np.tile([0.1, -0.05], (6, 1))))


def test_batch_equals_row_by_row(plant, rng):
    x, tau = _states(rng, 8), rng.uniform(-0.2, 0.2, (8, 2))
    batch = plant.step(x, tau)
    rows = np.stack([plant.step(x[i], tau[i]) for i in range(8)])
    np.testing.assert_array_equal(batch, rows)
    np.testing.assert_array_equal(plant.step(x.reshape(2, 4, 4), tau.reshape(2, 4, 2)),
                                  batch.reshape(2, 4, 4))


def test_angles_wrap_and_speeds_saturate(plant, rng):
    x = _states(rng, 200)
    x[:50, :2] *= 300                                  # far outside [-pi, pi)
    x[50:100, 2:] = rng.choice([-1, 1], (50, 2)) * SPEED_BOUND * VMAX   # at the bound
    out = plant.step(x, rng.uniform(-0.2, 0.2, (200, 2)))
    assert np.all(out[:, :2] >= -math.pi) and np.all(out[:, :2] < math.pi)
    assert np.all(np.abs(out[:, 2:]) <= VMAX)
    assert np.any(np.abs(out[50:100, 2:]) == VMAX)     # saturated, exactly at the limit


def test_torques_are_clipped(plant, rng):
    x = _states(rng, 10)
    big = np.tile([5.0, -7.0], (10, 1))
    np.testing.assert_array_equal(plant.step(x, big), plant.step(x, [TMAX[0], -TMAX[1]]))


def test_deterministic(plant, rng):
    x, tau = _states(rng, 10), rng.uniform(-0.2, 0.2, (10, 2))
    a = plant.step(x, tau)
    with make_plant(plant.name) as other:
        np.testing.assert_array_equal(a, other.step(x, tau))
    np.testing.assert_array_equal(a, plant.step(x, tau))


@pytest.mark.parametrize("x, tau, message", [
    (np.zeros(3), np.zeros(2), "4 components"),
    (np.zeros(4), np.zeros(3), "2 components"),
    ([0.0, np.nan, 0.0, 0.0], np.zeros(2), "NaN"),
    ([0.0, 0.0, np.inf, 0.0], np.zeros(2), "NaN or infinite"),
    ([0.0, 0.0, 0.0, 0.0], [np.nan, 0.0], "torque contains NaN"),
    ([2e10, 0.0, 0.0, 0.0], np.zeros(2), "beyond the bound 1000 rad"),
    ([0.0, -1.01 * MAX_ANGLE, 0.0, 0.0], np.zeros(2), "angle"),
    ([0.0, 0.0, 1e9, 0.0], np.zeros(2), "beyond the bound 62.83 rad/s"),
    ([0.0, 0.0, 0.0, -1.01 * SPEED_BOUND * VMAX[1]], np.zeros(2), "speed"),
])
def test_bad_input_is_refused(plant, x, tau, message):
    with pytest.raises(ValueError, match=message):
        plant.step(x, tau)


def test_mujoco_batch_equals_mj_step_loop(rng):
    x, tau = _states(rng, 40), rng.uniform(-0.3, 0.3, (40, 2))
    with make_plant("mujoco") as plant, MujocoStepLoop() as ref:
        np.testing.assert_array_equal(plant.step(x, tau), ref.step(x, tau))


def test_per_row_mujoco_equals_mj_step_loop(rng):
    plist = [TABLE_I, TABLE_I.scaled(m2=1.3), TABLE_I.scaled(b1=0.05, dtheta1_max=3.0)]
    x, tau = _states(rng, 3), rng.uniform(-0.3, 0.3, (3, 2))
    with MujocoPlant(plist, nthread=1) as plant:
        np.testing.assert_array_equal(plant.step(x, tau), MujocoStepLoop(plist).step(x, tau))


def test_full_and_mujoco_agree_to_round_off(rng):
    x, tau = _states(rng, 300), rng.uniform(-0.25, 0.25, (300, 2))
    with make_plant("full") as full, make_plant("mujoco") as mj:
        d = full.step(x, tau) - mj.step(x, tau)
    d[:, :2] = (d[:, :2] + np.pi) % (2 * np.pi) - np.pi
    assert np.abs(d).max() < 1e-12


def test_plants_are_context_managers():
    with make_plant("mujoco") as plant:
        plant.step(np.zeros(4), np.zeros(2))
    with pytest.raises(RuntimeError, match="closed"):
        plant.step(np.zeros(4), np.zeros(2))
    with make_plant("simplified") as plant:
        pass
    plant.step(np.zeros(4), np.zeros(2))          # nothing to release


def test_mujoco_warning_fails_loudly_and_writes_no_log(monkeypatch, tmp_path, centralized):
    import mujoco
    handler = mujoco.get_mju_user_warning()          # None, or one a library installed
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(plants_mod, "MAX_ANGLE", 1e12)   # let a state through MuJoCo refuses
    with make_plant("mujoco", nthread=2) as plant:
        x = np.array([PAPER_X0, [2e10, 0.0, 0.0, 0.0], PAPER_X0])
        with pytest.raises(SimulationError) as err:
            plant.step(x, np.zeros(2))
        assert err.value.rows == (1,)
        msg = str(err.value)
        assert "batch row 1" in msg and "+2e+10" in msg and "QPOS" in msg and "\n" not in msg
        with pytest.raises(SimulationError, match=r"rollout from x0 = \[\+2e\+10, \+0, \+0, "
                                                  r"\+0\] failed at t = 0.00 s: MuJoCo"):
            rollout(centralized, plant, [2e10, 0.0, 0.0, 0.0], duration=0.5)
        # The plant still works afterwards, and MuJoCo's own handler is back.
        np.testing.assert_array_equal(plant.step(x[[0]], np.zeros(2)),
                                      make_plant("full").step(x[[0]], np.zeros(2)))
    assert mujoco.get_mju_user_warning() is handler
    assert os.listdir(tmp_path) == []                 # no MUJOCO_LOG.TXT


def test_numpy_blow_up_fails_loudly_without_runtime_warnings(monkeypatch):
    monkeypatch.setattr(plants_mod, "SPEED_BOUND", np.inf)
    with make_plant("full") as plant, warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(SimulationError, match=r"non-finite state from x = \[\+0, \+0, "
                                                  r"\+1e\+300, \+0\] \(batch row 1\)"):
            plant.step(np.array([[0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 1e300, 0.0]]), np.zeros(2))


@pytest.mark.parametrize("nthread", [0, -1, 1000, 2.0, "2", True])
def test_nthread_is_bounded_in_one_line(nthread):
    with pytest.raises(ValueError, match=r"^nthread must be a whole number from 1 to "
                                         rf"{plants_mod.MAX_NTHREAD} \(") as err:
        MujocoPlant(TABLE_I, nthread=nthread)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("nthread", [-1, 1000])
def test_evaluate_refuses_nthread_before_any_work(nthread, monkeypatch):
    from twolink.sim import evaluation

    monkeypatch.setattr(evaluation, "MujocoPlant", None)     # never reached
    with pytest.raises(ValueError, match="^nthread must be a whole number from 1 to"):
        evaluation.evaluate("centralized", nthread=nthread)


@pytest.mark.parametrize("name", PLANTS)
@pytest.mark.parametrize("values, message", [
    (dict(m2=1e-320, I2=1e-320), "link 2 is all but massless"),
    (dict(m1=1e-300, I1=1e-300), "link 1 is all but massless"),
    (dict(m2=1e-9, I2=1e-9), "link 2 is too light for its damping"),
])
def test_massless_and_too_light_plants_are_one_value_error(name, values, message):
    p = TABLE_I.scaled(**{k: v / getattr(TABLE_I, k) for k, v in values.items()})
    if name == "simplified" and "too light" in message:
        with make_plant(name, p) as plant:        # (11) has no damping over inertia
            assert np.isfinite(plant.step(np.zeros(4), np.zeros(2))).all()
        return
    with pytest.raises(ValueError, match=message) as err:
        make_plant(name, p)
    assert "\n" not in str(err.value)
