"""Perturbations: one per-row implementation, held against independent row-by-row loops."""
import numpy as np
import pytest

from twolink import env as twolink_env
from twolink.perturbations import ActuationDelay, ObservationNoise, row_generators

ANGLE, SPEED = np.array([0.01, 0.02, 0.0, 0.03, 0.0]), np.array([0.1, 0.0, 0.0, 0.2, 0.0])


def _states(rows, k):
    return np.random.default_rng(100 + k).uniform(-1, 1, (rows, 4))


def _reference_noise(entropy, row, steps):
    """Row ``row`` alone: its own generator from the spawn key, all its steps at once."""
    rng = np.random.Generator(np.random.PCG64(
        np.random.SeedSequence(entropy, spawn_key=(row,))))
    scale = np.array([ANGLE[row], ANGLE[row], SPEED[row], SPEED[row]])
    if not scale.any():
        return [_states(5, k)[row] for k in range(steps)]
    return [rng.normal(_states(5, k)[row], scale) for k in range(steps)]


@pytest.mark.parametrize("block", [1, 4, 6, 50])
def test_observation_noise_row_by_row_equals_an_independent_loop(block):
    noise = ObservationNoise(ANGLE, SPEED, rngs=row_generators([4, 2], 5), block=block)
    fast = np.stack([noise(_states(5, k)) for k in range(6)], 1)          # (rows, steps, 4)
    for row in range(5):
        np.testing.assert_array_equal(fast[row], _reference_noise([4, 2], row, 6), err_msg=row)
    assert np.all(fast[2] == np.stack([_states(5, k)[2] for k in range(6)]))   # std 0: exact


def test_a_rows_noise_does_not_depend_on_its_batch_mates():
    rngs = row_generators([9], 5)
    together = ObservationNoise(ANGLE, SPEED, rngs=rngs)
    out = [together(_states(5, k)) for k in range(4)]
    alone = ObservationNoise(ANGLE[3], SPEED[3], rngs=[row_generators([9], 5)[3]])
    for k in range(4):
        np.testing.assert_array_equal(alone(_states(5, k)[3]), out[k][3])


def test_noiseless_rows_never_draw():
    rng = np.random.default_rng(0)
    state = rng.bit_generator.state
    ObservationNoise(0.0, 0.0, rngs=[rng])(np.zeros(4))
    assert rng.bit_generator.state == state


def test_bad_noise_refused():
    with pytest.raises(ValueError, match="non-negative"):
        ObservationNoise(-0.1, 0.0, rngs=[None])
    with pytest.raises(ValueError, match="generators"):
        ObservationNoise(np.ones(3), 0.0, rngs=[None, None])
    with pytest.raises(ValueError, match="block"):
        ObservationNoise(0.1, 0.0, rngs=[None], block=0)
    with pytest.raises(ValueError, match="batch"):
        ObservationNoise(0.1, 0.0, rngs=row_generators(0, 2))(np.zeros((3, 4)))


def _policy(x):
    return np.stack([np.sin(x[..., 0] * 7), x[..., 1] ** 2], -1)


def test_actuation_delay_row_by_row_equals_an_independent_queue():
    delays = np.array([0, 1, 2, 3, 1])
    delayed = ActuationDelay(_policy, delays)
    fast = [delayed(_states(5, k)) for k in range(6)]
    for row, d in enumerate(delays):
        sent = []
        for k in range(6):
            sent.append(_policy(_states(5, k)[row]))
            expect = sent[k - d] if k >= d else np.zeros(2)
            np.testing.assert_array_equal(fast[k][row], expect, err_msg=(row, k))


def test_one_delay_for_every_row_and_bad_delays():
    x = _states(3, 0)
    delayed = ActuationDelay(_policy, 2)
    outs = [delayed(x) for _ in range(3)]
    assert np.all(outs[0] == 0) and np.all(outs[1] == 0)
    np.testing.assert_array_equal(outs[2], _policy(x))
    assert ActuationDelay(_policy, 0)(x) is not None
    for bad in (1.5, -1, [0, np.nan]):
        with pytest.raises(ValueError, match="delay"):
            ActuationDelay(_policy, bad)


def test_environment_noise_is_the_same_perturbation():
    """The env's noise is ObservationNoise on one row, drawing from the task's RandomState."""
    x0 = [0.1, -0.2, 0.3, -0.4]
    env = twolink_env.load("centralized", seed=11, x0=x0, angle_noise=0.02, speed_noise=0.05)
    seen = [env.reset().observation["state"]]
    seen += [env.step(np.zeros(2)).observation["state"] for _ in range(3)]
    rng = np.random.RandomState(11)
    env2 = twolink_env.load("centralized", x0=x0)
    states = [env2.reset().observation["state"]]
    states += [env2.step(np.zeros(2)).observation["state"] for _ in range(3)]
    for s, x in zip(seen, states):
        np.testing.assert_allclose(s, rng.normal(x, [0.02, 0.02, 0.05, 0.05]), rtol=0, atol=1e-15)
