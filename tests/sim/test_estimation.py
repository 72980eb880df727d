"""Run-time compensation (twolink.sim.estimation, twolink.envs.compensated): the batched
predictor and observer held against a one-row-at-a-time reference loop, exact prediction
on the exact model, the observer's error, pass-through, restarts and bad input."""
from __future__ import annotations

import math

import numpy as np
import pytest

from twolink.arm.dynamics import full_acceleration
from twolink.arm.integrate import sample_step, wrap_angle
from twolink.arm.parameters import TABLE_I
from twolink.sim.estimation import (
    Compensator,
    StateEstimator,
    compensated,
    observer_gain,
)
from twolink.sim.perturbations import (
    ActuationDelay,
    ObservationDelay,
    ObservationNoise,
    row_generators,
)
from twolink.sim.plants import make_plant
from twolink.sim.rollout import rollout

X0 = np.array([[-1.0, -3.0, 0.0, 0.0], [0.5, -0.2, 0.3, -1.0], [2.0, 1.0, -0.5, 0.5]])


@pytest.fixture(scope="module")
def policy():
    from twolink.policy.fuzzy_policy import load_policy
    return load_policy("centralized_full")


def reference_commands(policy, readings, *, d, o, gain, observer):
    """One row at a time, as the module docstring reads: the observer's predictor-corrector
    on x_{k-o}, then the model rolled from k - o to k + d over the applied torques
    a_j = u_{j-d} (zero before the first command). Returns commands and predictions."""
    def f(x, u):
        return sample_step(full_acceleration, TABLE_I, x, u)

    steps, rows = readings.shape[:2]
    us, zs = np.zeros((steps, rows, 2)), np.zeros((steps, rows, 4))
    for i in range(rows):
        issued = []
        x_hat = None
        last_y = None

        def applied(j):
            return issued[j - d] if j - d >= 0 else np.zeros(2)

        for k in range(steps):
            y = readings[k, i]
            m = max(k - o, 0)                  # the time the reading is of
            if x_hat is None or not observer:
                x_hat = y.copy()
            else:
                prior = f(x_hat, applied(m - 1)) if k > o else x_hat.copy()
                e = y - prior
                e[:2] = wrap_angle(e[:2])
                if np.array_equal(y, last_y):
                    e[:] = 0.0
                for j in (0, 1):
                    c = prior[[j, 2 + j]] + gain @ e[[j, 2 + j]]
                    prior[j], prior[2 + j] = c
                prior[:2] = wrap_angle(prior[:2])
                x_hat = prior
            last_y = y
            z = x_hat
            for j in range(m, k + d):
                z = f(z, applied(j))
            u = policy(z)
            issued.append(u)
            us[k, i], zs[k, i] = u, z
    return us, zs


@pytest.mark.parametrize("d,o,observer", [(1, 0, False), (2, 1, False), (1, 0, True),
                                          (1, 2, True)])
def test_batched_compensator_matches_one_row_reference(policy, d, o, observer):
    rng = np.random.default_rng(5)
    steps = 12
    readings = X0 + 0.02 * rng.standard_normal((steps,) + X0.shape)
    readings[4, 1] = readings[3, 1]            # a repeated (dropped) reading
    comp = Compensator(policy, delay=d, observation_delay=o, observer=observer)
    us = np.stack([comp(y) for y in readings])
    zs_ref = reference_commands(policy, readings, d=d, o=o, gain=comp.estimator.gain,
                                observer=observer)
    np.testing.assert_allclose(us, zs_ref[0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(comp.estimator.prediction, zs_ref[1][-1], rtol=0, atol=1e-12)


@pytest.mark.parametrize("d,observer", [(1, False), (3, False), (2, True)])
def test_prediction_equals_the_exact_model_d_steps_ahead(policy, d, observer):
    comp = Compensator(policy, delay=d, observer=observer, model="full", params=TABLE_I)
    predictions = []

    def controller(y):
        u = comp(y)
        predictions.append(comp.estimator.prediction.copy())
        return u

    with make_plant("full") as plant:
        traj = rollout(ActuationDelay(controller, d), plant, X0, duration=1.0)
    z = np.stack(predictions, 1)                # (rows, K, 4): x^_{k+d} made at k
    k = traj.steps
    np.testing.assert_allclose(z[:, :k + 1 - d], traj.x[:, d:], rtol=0, atol=1e-12)
    # and the compensated loop is then the undelayed loop, shifted by d samples
    with make_plant("full") as plant:
        free = rollout(policy, plant, traj.x[:, d], duration=(k - d) * 0.05)
    np.testing.assert_allclose(traj.x[:, d:], free.x, rtol=0, atol=1e-9)


def test_observer_reduces_the_rms_error_of_noisy_readings(policy):
    x0 = np.array([[-1.0, -3.0, 0.0, 0.0], [1.5, 0.8, 0.0, 0.0], [-2.5, 2.0, 0.0, 0.0],
                   [0.3, -1.2, 0.0, 0.0]])
    noise = ObservationNoise(math.radians(1.0), 0.02, rngs=row_generators(11, len(x0)))
    comp = Compensator(policy, observer=True)
    seen, est = [], []

    def observe(k, x):
        y = noise(x)
        seen.append(y)
        return y

    def controller(y):
        u = comp(y)
        est.append(comp.estimator.estimate)
        return u

    with make_plant("full") as plant:
        traj = rollout(controller, plant, x0, duration=3.0, observe=observe)
    true = traj.x[:, :-1].transpose(1, 0, 2)

    def rms(a):
        e = a - true
        e[..., :2] = wrap_angle(e[..., :2])
        return np.sqrt(np.mean(e ** 2, axis=(0, 1)))

    raw, filtered = rms(np.array(seen)), rms(np.array(est))
    assert raw[:2] == pytest.approx(math.radians(1.0), rel=0.25)
    # measured: raw RMS 0.0147, 0.0172 rad and 0.0207, 0.0199 rad/s; filtered 0.0053,
    # 0.0063 rad (0.36 x) and 0.0134, 0.0131 rad/s (0.65 x)
    assert np.all(filtered[:2] < 0.5 * raw[:2]), (raw, filtered)
    assert np.all(filtered[2:] < 0.8 * raw[2:]), (raw, filtered)


def test_nothing_to_compensate_passes_through_bit_for_bit(policy):
    assert compensated(policy) is policy
    assert compensated(policy, delay=0, observation_delay=0, noise=False) is policy
    assert isinstance(compensated(policy, delay=1), Compensator)
    with make_plant("mujoco") as plant:
        plain = rollout(policy, plant, X0, duration=1.0)
        wrapped = rollout(Compensator(policy, observer=False), plant, X0, duration=1.0)
    np.testing.assert_array_equal(plain.x, wrapped.x)
    np.testing.assert_array_equal(plain.u, wrapped.u)
    assert Compensator(policy, delay=1).kind == policy.kind == "centralized"


def test_restarted_rows_behave_as_a_new_compensator(policy):
    rng = np.random.default_rng(3)
    readings = X0 + 0.02 * rng.standard_normal((8,) + X0.shape)
    comp = Compensator(policy, delay=2, observation_delay=1)
    for y in readings[:5]:
        comp(y)
    comp.restart([1])
    fresh = Compensator(policy, delay=2, observation_delay=1)
    also = Compensator(policy, delay=2, observation_delay=1)
    for y in readings[:5]:                     # row 0 and 2 carry on as if never restarted
        also(y)
    for y in readings[5:]:
        u = comp(y)
        np.testing.assert_array_equal(u[1], fresh(y[1:2])[0])
        np.testing.assert_array_equal(u[[0, 2]], also(y)[[0, 2]])


def test_estimator_of_some_rows_matches_the_whole_batch():
    est = StateEstimator(model="full", delay=1, observer=True)
    whole = StateEstimator(model="full", delay=1, observer=True)
    u = np.array([[0.1, -0.05], [0.0, 0.02], [-0.2, 0.1]])
    est.update(X0), whole.update(X0)
    est.record(u), whole.record(u)
    a = est.update(X0[[0, 2]], [0, 2])
    b = est.update(X0[1:2], [1])
    np.testing.assert_array_equal(np.concatenate([a[:1], b, a[1:]]), whole.update(X0))


def test_observation_delay_reads_the_first_reading_while_the_buffer_fills(policy):
    """Against perturbations.ObservationDelay: with no noise and the exact model, the
    prediction is the true state d samples ahead from the first sample on."""
    comp = Compensator(policy, delay=1, observation_delay=2, observer=False,
                       model="full", params=TABLE_I)
    late = ObservationDelay(2)
    preds = []

    def controller(y):
        u = comp(y)
        preds.append(comp.estimator.prediction.copy())
        return u

    with make_plant("full") as plant:
        traj = rollout(ActuationDelay(controller, 1), plant, X0, duration=0.6,
                       observe=lambda k, x: late(x))
    np.testing.assert_allclose(np.stack(preds, 1), traj.x[:, 1:], rtol=0, atol=1e-12)


def test_gain_is_a_kalman_gain():
    g = observer_gain(math.radians(1.0), 0.02)
    assert g.shape == (2, 2) and np.all((g > 0) & (g < 1))
    # much noisier angle readings -> the angle is trusted less
    assert observer_gain(math.radians(5.0), 0.02)[0, 0] < g[0, 0]


@pytest.mark.parametrize("kwargs,match", [
    ({"delay": -1}, "non-negative whole number"),
    ({"delay": 1.5}, "whole number"),
    ({"delay": True}, "whole number"),
    ({"observation_delay": "2"}, "whole number"),
    ({"delay": 10**6}, "beyond"),
    ({"model": "lagrange"}, "unknown prediction model"),
    ({"observer": "yes"}, "True or False"),
    ({"params": {"m1": 1}}, "ArmParameters"),
    ({"angle_noise_deg": float("nan")}, "finite"),
])
def test_bad_options_raise_one_clear_error(policy, kwargs, match):
    with pytest.raises(ValueError, match=match):
        Compensator(policy, **kwargs)


@pytest.mark.parametrize("y,match", [
    (np.zeros(3), r"shape \(4,\) or \(B, 4\)"),
    (np.zeros((2, 3, 4)), r"shape \(4,\) or \(B, 4\)"),
    (np.array([0.0, np.nan, 0.0, 0.0]), "NaN"),
    (np.array(["a", "b", "c", "d"]), "real numbers"),
])
def test_bad_readings_raise_one_clear_error(policy, y, match):
    with pytest.raises(ValueError, match=match):
        Compensator(policy, delay=1)(y)


def test_batch_size_is_fixed_after_the_first_reading(policy):
    comp = Compensator(policy, delay=1)
    comp(X0)
    with pytest.raises(ValueError, match="another batch"):
        comp(X0[:2])
    with pytest.raises(ValueError, match="names no model for the compensator"):
        Compensator(lambda x: np.zeros(2), delay=1)
    est = StateEstimator(model="full")
    with pytest.raises(ValueError, match="before update"):
        est.record(np.zeros(2))
    est.update(X0[0])
    with pytest.raises(ValueError, match="twice without record"):
        est.update(X0[0])


def test_compensation_recovers_a_one_sample_delay_on_mujoco(policy):
    """A number, not a contract: centralized_full with a one-sample actuation delay on
    MuJoCo, 8 states of the evaluation set, settles none of them uncompensated (0 % on
    all 65, README) and all of them compensated."""
    from twolink.sim.metrics import evaluation_set, success
    x0 = evaluation_set()[::8]
    with make_plant("mujoco") as plant:
        plain = success(rollout(ActuationDelay(policy, 1), plant, x0))
        comp = success(rollout(ActuationDelay(compensated(policy, delay=1), 1), plant, x0))
    assert plain.sum() <= 2 and comp.all()


# ------------------------------------------------------------------ environments
@pytest.mark.filterwarnings("ignore:.*infinity:UserWarning",
                            "ignore:.*different from the unwrapped:UserWarning")
def test_gymnasium_wrapper_passes_check_env_and_matches_the_compensator(policy):
    from gymnasium.utils.env_checker import check_env

    from twolink.envs.compensated import CompensatedObservation
    from twolink.envs.gym import TwoLinkEnv

    env = CompensatedObservation(TwoLinkEnv(delay=1, angle_noise=0.01, speed_noise=0.02),
                                 delay=1)
    check_env(env, skip_render_check=True)
    # Driving the wrapped environment equals a compensated policy on the plain one.
    obs, _ = env.reset(seed=4)
    plain = TwoLinkEnv(delay=1, angle_noise=0.01, speed_noise=0.02)
    y, _ = plain.reset(seed=4)
    comp = Compensator(policy, delay=1, model="full", params=TABLE_I)
    for _ in range(20):
        u = comp(y)
        np.testing.assert_array_equal(policy(obs), u)
        obs = env.step(u)[0]
        y = plain.step(u)[0]
    env.close(), plain.close()


def test_gymnasium_wrapper_refuses_cos_sin_observations():
    from twolink.envs.compensated import CompensatedObservation
    from twolink.envs.gym import TwoLinkEnv

    with pytest.raises(ValueError, match="observation='state'"):
        CompensatedObservation(TwoLinkEnv(observation="cos_sin"))


def test_vector_wrapper_restarts_arms_with_their_episodes(policy):
    from twolink.envs.compensated import CompensatedVectorObservation
    from twolink.envs.gym import TwoLinkEnv, TwoLinkVectorEnv

    venv = CompensatedVectorObservation(TwoLinkVectorEnv(2, delay=1, time_limit=0.2,
                                                         x0="random"), delay=1)
    obs, _ = venv.reset(seed=9)
    singles = [TwoLinkEnv(delay=1, time_limit=0.2, x0="random") for _ in range(2)]
    ys = [e.reset(seed=9 + i)[0] for i, e in enumerate(singles)]
    comps = [Compensator(policy, delay=1, model="full", params=TABLE_I) for _ in range(2)]
    for step in range(9):                        # two episodes of 4 steps, a reset step
        us = np.stack([c(y) for c, y in zip(comps, ys)])
        np.testing.assert_allclose(policy(obs), us, rtol=0, atol=1e-12)
        obs, _, _, trunc, _ = venv.step(us)
        if step == 4:                            # autoreset step: the arms start anew
            ys = [e.reset()[0] for e in singles]
            for c in comps:
                c.restart()
        else:
            ys = [e.step(u)[0] for e, u in zip(singles, us)]
            assert trunc.all() == (step in (3, 8))
    venv.close()
    for e in singles:
        e.close()


def test_dm_env_wrapper_replaces_the_state_observation(policy):
    from twolink.envs import dm
    from twolink.envs.compensated import CompensatedEnvironment

    env = CompensatedEnvironment(dm.load("centralized", seed=2, angle_noise=0.01,
                                         speed_noise=0.02, time_limit=0.5))
    plain = dm.load("centralized", seed=2, angle_noise=0.01, speed_noise=0.02, time_limit=0.5)
    ts, tp = env.reset(), plain.reset()
    comp = Compensator(policy, model="full", params=TABLE_I)
    for _ in range(10):
        u = comp(tp.observation["state"])
        np.testing.assert_array_equal(policy(ts.observation["state"]), u)
        ts, tp = env.step(u), plain.step(u)
        assert ts.reward == tp.reward
    with pytest.raises(ValueError, match="centralized task"):
        CompensatedEnvironment(dm.load("decentralized"))


# ------------------------------------------------------------------ the study script
def _study_module():
    import importlib.util
    from pathlib import Path
    path = Path(__file__).resolve().parents[2] / "docs" / "studies" / "compensation_study.py"
    spec = importlib.util.spec_from_file_location("compensation_study", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_study_script_measures_and_refuses_bad_options(capsys):
    study = _study_module()
    rows = study.study(["centralized_full"], seed=3, plants=1, spread=0.2, delay=1,
                       noise_deg=1.0, conditions=("nominal", "delay"))
    got = {(r["condition"], r["compensated"]): r["successes"] for r in rows}
    assert got[("nominal", False)] == got[("nominal", True)] == 65     # pass-through
    assert got[("delay", False)] == 0 and got[("delay", True)] == 65
    for argv, match in ((["--plants", "0"], "--plants"), (["--spread", "1.5"], "--spread"),
                        (["--policies", "nope"], "unknown policy"),
                        (["--process-std", "nan"], "--process-std")):
        with pytest.raises(SystemExit) as exc:
            study.main(argv)
        assert exc.value.code == 2
        assert match in capsys.readouterr().err
