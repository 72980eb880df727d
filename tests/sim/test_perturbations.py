"""Perturbations: one per-row implementation, held against independent row-by-row loops."""
import numpy as np
import pytest

from twolink.envs import dm as twolink_env
from twolink.sim.perturbations import (
    STUCK_SAMPLES,
    ActuationDelay,
    ObservationDelay,
    ObservationNoise,
    ReadingFaults,
    Sensors,
    keyed_generators,
    row_generators,
)

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


# --------------------------------------------------------------------------- faults, delays
DROP, STICK = np.array([0.3, 0.0, 0.5, 0.1, 0.0]), np.array([0.1, 0.0, 0.0, 0.2, 0.05])


def _reference_faults(entropy, row, steps, hold=STUCK_SAMPLES):
    """Row ``row`` alone, one sample at a time, as the docstring of ReadingFaults reads."""
    rng = np.random.Generator(np.random.PCG64(
        np.random.SeedSequence(entropy, spawn_key=(row,))))
    handed, stuck_for = [], 0
    for k in range(steps):
        new = _states(5, k)[row]
        if not (DROP[row] or STICK[row]):
            handed.append(new)
            continue
        u_drop, u_stick = rng.random(), rng.random()
        if k == 0:
            handed.append(new)
        elif stuck_for:
            stuck_for -= 1
            handed.append(handed[-1])
        elif u_stick < STICK[row]:
            stuck_for = hold - 1
            handed.append(handed[-1])
        elif u_drop < DROP[row]:
            handed.append(handed[-1])
        else:
            handed.append(new)
    return handed


@pytest.mark.parametrize("block", [1, 7, 40])
def test_reading_faults_row_by_row_equal_an_independent_loop(block):
    faults = ReadingFaults(DROP, STICK, rngs=row_generators([5, 1], 5), block=block)
    fast = np.stack([faults(_states(5, k)) for k in range(40)], 1)
    repeated = 0
    for row in range(5):
        ref = np.array(_reference_faults([5, 1], row, 40))
        np.testing.assert_array_equal(fast[row], ref, err_msg=row)
        repeated += int(np.sum(np.all(ref[1:] == ref[:-1], axis=-1)))
    assert repeated > 10                              # the faults did fire
    assert np.all(fast[1] == np.stack([_states(5, k)[1] for k in range(40)]))


def test_reading_faults_on_some_rows_equal_the_whole_batch():
    """A vector env observes the rows it resets alone: the same numbers as whole calls."""
    whole = ReadingFaults(DROP, STICK, rngs=row_generators([3], 5))
    part = ReadingFaults(DROP, STICK, rngs=row_generators([3], 5))
    for k in range(30):
        x = _states(5, k)
        out = whole(x)
        got = np.concatenate([part(x[[0, 2, 4]], rows=[0, 2, 4]), part(x[[1, 3]], rows=[1, 3])])
        np.testing.assert_array_equal(got, out[[0, 2, 4, 1, 3]], err_msg=k)


def test_observation_delay_row_by_row_equals_an_independent_queue():
    delays = np.array([0, 1, 2, 3, 1])
    delayed = ObservationDelay(delays)
    fast = [delayed(_states(5, k)) for k in range(7)]
    delayed.restart([3])
    after = [delayed(_states(5, k)) for k in range(7, 10)]
    for row, d in enumerate(delays):
        seen = [_states(5, k)[row] for k in range(7)]
        for k in range(7):
            np.testing.assert_array_equal(fast[k][row], seen[max(0, k - d)], err_msg=(row, k))
    # row 3 restarted at k = 7: its buffer starts full of that reading
    for j, k in enumerate(range(7, 10)):
        np.testing.assert_array_equal(after[j][3], _states(5, 7)[3])
        np.testing.assert_array_equal(after[j][1], _states(5, k - 1)[1])


def test_sensors_chain_noise_then_faults_then_delay():
    rngs = row_generators([8], 5)
    sensors = Sensors(ANGLE, SPEED, DROP, STICK, [1, 0, 2, 1, 0], rngs=rngs,
                      fault_rngs=row_generators([9], 5), block=6)
    noise = ObservationNoise(ANGLE, SPEED, rngs=row_generators([8], 5))
    faults = ReadingFaults(DROP, STICK, rngs=row_generators([9], 5))
    delay = ObservationDelay([1, 0, 2, 1, 0])
    for k in range(12):
        x = _states(5, k)
        np.testing.assert_array_equal(sensors(x), delay(faults(noise(x))), err_msg=k)


def test_keyed_generators_do_not_depend_on_their_neighbours():
    a = keyed_generators([4, 7], [(0, 0), (2, 3)])
    b = keyed_generators([4, 7], [(p, s) for p in range(3) for s in range(5)])
    assert a[1].random() == b[2 * 5 + 3].random() and a[0].random() == b[0].random()
    child = np.random.SeedSequence([4, 7]).spawn(3)[2].spawn(4)[3]
    assert np.random.default_rng(child).random() == keyed_generators([4, 7], [(2, 3)])[0].random()


def test_bad_faults_and_delays_refused():
    with pytest.raises(ValueError, match="dropout probability"):
        ReadingFaults(1.0, 0.0, rngs=[None])
    with pytest.raises(ValueError, match="stuck probability"):
        ReadingFaults(0.0, -0.1, rngs=[None])
    with pytest.raises(ValueError, match="hold"):
        ReadingFaults(0.1, 0.1, rngs=[None], hold=0)
    with pytest.raises(ValueError, match="batch"):
        ReadingFaults(0.1, 0.0, rngs=row_generators(0, 2))(np.zeros((3, 4)))
    with pytest.raises(ValueError, match="block 1"):
        ReadingFaults(0.1, 0.0, rngs=row_generators(0, 2), block=3)(np.zeros((1, 4)), rows=[0])
    for bad in (1.5, -1, np.nan):
        with pytest.raises(ValueError, match="observation delay"):
            ObservationDelay(bad)
    with pytest.raises(ValueError, match="unknown size"):
        ObservationDelay(1)(np.zeros((1, 4)), rows=[0])
