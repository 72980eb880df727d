"""Identification: the regressor of (6) against the dynamics, the experiment against the
MuJoCo plant, the fit against hidden plants, refusals, and the command end to end."""
import dataclasses
import json

import numpy as np
import pytest

from twolink.arm import dynamics, parameter_file
from twolink.arm.parameters import TABLE_I, TS
from twolink.cli import main
from twolink.sim import excitation, identify
from twolink.sim.perturbations import perturbed
from twolink.sim.plants import make_plant

ARM = perturbed(TABLE_I, m1=0.12, m2=-0.15, c2=0.18, I1=-0.1, I2=0.2, l1=0.05, b1=-0.17,
                b2=0.19)


def _samples(p, rng, n=200):
    x = np.concatenate([rng.uniform(-np.pi, np.pi, (n, 2)), rng.uniform(-6, 6, (n, 2))], -1)
    tau = rng.uniform(-1, 1, (n, 2)) * p.tau_max
    return x, tau, dynamics.full_acceleration(p, x, tau)


def test_regressor_is_the_full_model_and_least_squares_recovers_it_exactly(rng):
    x, tau, acc = _samples(ARM, rng)
    Y = identify.regressor(x[:, :2], x[:, 2:], acc)
    assert Y.shape == (200, 2, 5)
    np.testing.assert_allclose(Y @ identify.theta(ARM), tau, rtol=0, atol=1e-15)
    np.testing.assert_allclose(identify.least_squares(Y, tau), identify.theta(ARM), rtol=1e-8)
    M = dynamics.mass_matrix(ARM, x[:, 1])
    Phi = identify.momentum_regressor(x[:, :2], x[:, 2:])
    np.testing.assert_allclose(Phi @ identify.theta(ARM), np.einsum("nij,nj->ni", M, x[:, 2:]),
                               rtol=0, atol=1e-16)


def test_least_squares_refuses_data_without_motion(rng):
    x, tau, acc = _samples(ARM, rng)
    with pytest.raises(identify.IdentificationError, match="cannot determine"):
        identify.least_squares(identify.regressor(x[:, :2], 0 * x[:, 2:], 0 * acc), 0 * tau)


def test_realise_gives_the_fitted_values_and_keeps_table_i_where_it_can():
    p = identify.realise(identify.theta(ARM))
    np.testing.assert_allclose(identify.theta(p), identify.theta(ARM), rtol=1e-13)
    for name in ("l1", "l2", "m1", "c1", "g", "tau1_max", "tau2_max", "dtheta1_max"):
        assert getattr(p, name) == getattr(TABLE_I, name)
    assert identify.realise(identify.theta(TABLE_I)) == pytest.approx(TABLE_I)
    big_p3 = dict(zip(identify.IDENTIFIABLE, identify.theta(TABLE_I)), P3=0.008)
    q = identify.realise(big_p3)          # Table I's c2 would make I1 negative
    assert q.c2 != TABLE_I.c2 and q.I1 > 0 and q.I2 > 0 and q.P3 == pytest.approx(0.008)
    with pytest.raises(ValueError, match="no arm with Table I"):
        identify.realise(dict(big_p3, P3=0.0095))


def test_experiment_is_the_mujoco_plant_read_every_timestep():
    log = excitation.run_experiment(ARM, duration=10.0, angle_noise_deg=0.0, seed=3)
    m = log.readings_per_period
    assert (m, log.dt, log.ts, log.angles.shape) == (10, TS / 10, TS, (2001, 2))
    assert not any(f.name in ("params", "plant") for f in dataclasses.fields(log))
    x = np.r_[log.angles[0], 0.0, 0.0]
    ends, speeds = [x[:2]], [x[2:]]
    with make_plant("mujoco", ARM) as plant:
        for u in log.torques:
            x = plant.step(x, u)
            ends.append(x[:2])
            speeds.append(x[2:])
    np.testing.assert_allclose(log.angles[::m], ends, rtol=0, atol=1e-12)
    # The excitation keeps the speeds clear of the limit the plant would clip them at.
    assert np.all(np.abs(speeds) < 0.85 * ARM.speed_max)
    assert set(np.unique(np.abs(log.torques) / TABLE_I.tau_max)) <= {0.0, 1.0}
    again = excitation.run_experiment(ARM, duration=10.0, angle_noise_deg=0.0, seed=3)
    np.testing.assert_array_equal(again.angles, log.angles)


def test_noiseless_data_give_the_parameters_to_a_fraction_of_a_percent():
    fit = identify.fit(excitation.run_experiment(ARM, angle_noise_deg=0.0, seed=5))
    errors = np.abs(list(fit.relative_errors(ARM).values()))
    assert errors.max() < 2e-3, fit.relative_errors(ARM)


@pytest.mark.parametrize("seed", [101, 102])
def test_one_degree_noise_meets_the_two_percent_target_on_hidden_plants(seed):
    log = excitation.experiment(seed, spread=0.2, duration=10.0, angle_noise_deg=1.0)
    fit = identify.fit(log)
    truth = excitation.hidden_plant(seed, 0.2)
    assert truth != TABLE_I
    for name, error in fit.relative_errors(truth).items():
        assert abs(error) < 0.02, (name, error)
        assert abs(error) * truth.__getattribute__(name) < 5 * fit.std_errors[name] + 1e-12
    assert 0.8 < fit.noise_deg_estimate < 1.2


@pytest.mark.parametrize("noise", [0.0, 1.0])
def test_zero_input_is_refused(noise):
    log = excitation.experiment(0, excitation="zero", angle_noise_deg=noise, duration=2.0)
    with pytest.raises(identify.IdentificationError, match="the arm hardly moved"):
        identify.fit(log)


@pytest.mark.parametrize("change, message", [
    (dict(angles=np.zeros((5, 2))), "need angles of shape"),
    (dict(angles=np.full((11, 2), np.nan)), "must be finite"),
    (dict(torques=np.zeros((1, 3))), "torques must have shape"),
    (dict(dt=0.003), "not a whole number"),
])
def test_bad_logs_are_refused(change, message):
    good = dict(dt=0.005, ts=0.05, angles=np.zeros((11, 2)), torques=np.zeros((1, 2)))
    with pytest.raises(ValueError, match=message):
        excitation.Log(**{**good, **change})


def test_identify_writes_a_file_synthesis_can_load(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["identify", "--seed", "7", "--reveal", "--json", "--bootstrap", "4"]) == 0
    result = json.loads(capsys.readouterr().out)
    params = parameter_file.load(tmp_path / "identified.json")
    for name, entry in result["identified"].items():
        assert getattr(params, name) == pytest.approx(entry["value"], rel=1e-12)
        assert abs(result["relative_error"][name]) < 0.02
    content = parameter_file.read(tmp_path / "identified.json")
    assert content.provenance["experiment"]["seed"] == 7
    assert "l2" in content.provenance["not_identifiable"]
    before = (tmp_path / "identified.json").read_bytes()
    assert main(["identify", "--seed", "8"]) == 2                 # kept without --force
    assert "exists" in capsys.readouterr().err
    assert (tmp_path / "identified.json").read_bytes() == before


def test_help_names_every_option_and_excitation(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["identify", "--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    for word in ("--seed", "--spread", "--duration", "--angle-noise-deg", "--reveal", "--force",
                 *excitation.EXCITATIONS):
        assert word in out


@pytest.mark.parametrize("argv, message", [
    (["--excitation", "zero"], "the arm hardly moved"),
    (["--duration", "1e9"], "duration must lie in"),
    (["--angle-noise-deg", "-1"], "angle noise must lie in"),
    (["--spread", "0.9"], "spread must lie in"),
    (["--bootstrap", "100000"], "bootstrap must be"),
    (["-o", "missing/x.json"], "does not exist"),
])
def test_bad_input_is_one_line_and_writes_nothing(tmp_path, monkeypatch, capsys, argv, message):
    monkeypatch.chdir(tmp_path)
    short = [] if "--duration" in argv else ["--duration", "2"]
    assert main(["identify", *argv, *short]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert list(tmp_path.iterdir()) == []
