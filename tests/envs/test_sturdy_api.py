"""API arguments of the wrong type raise a TypeError, of a wrong value a ValueError, each
naming the argument: x0 given as a dict or a word, text or negative seeds, a discrete
action out of range, an absurd render size and a speed_max of the wrong length."""
import numpy as np
import pytest

import twolink  # noqa: F401  (registers the environments)
from twolink import validate
from twolink.envs import dm
from twolink.envs.gym import TwoLinkEnv, TwoLinkVectorEnv
from twolink.envs.pettingzoo import parallel_env
from twolink.sim.metrics import random_poses
from twolink.sim.plants import make_plant
from twolink.sim.rollout import rollout


def _raises(error, message, call):
    with pytest.raises(error) as exc:
        call()
    assert str(exc.value) == message
    return exc.value


@pytest.mark.parametrize("x0, message", [
    ({"theta1": 1}, "x0 must be real numbers, got a dict: {'theta1': 1}"),
    ("abc", "x0 must be real numbers, got a str: 'abc'"),
    (None, "x0 must be real numbers, got None: None"),
    ([1, "a", 0, 0], "x0 must be real numbers, got values of dtype <U21: [1, 'a', 0, 0]"),
])
def test_rollout_x0_of_the_wrong_type(centralized, x0, message):
    _raises(TypeError, message, lambda: rollout(centralized, make_plant("simplified"), x0,
                                                duration=0.1))


def test_environment_x0_of_the_wrong_type_or_word():
    bad = {"a": 1}
    _raises(TypeError, "x0 must be real numbers, got a dict: {'a': 1}", lambda: TwoLinkEnv(x0=bad))
    _raises(TypeError, "x0 must be real numbers, got a dict: {'a': 1}", lambda: dm.load(
        "centralized", x0=bad))
    _raises(TypeError, "x0 must be real numbers, got a dict: {'a': 1}", lambda: parallel_env(
        x0=bad))
    _raises(ValueError, "x0 must be 'paper', 'random' or a state (4,), got 'abc'",
            lambda: TwoLinkEnv(x0="abc"))
    with TwoLinkEnv() as env:
        _raises(TypeError, "x0 must be real numbers, got a dict: {'a': 1}",
                lambda: env.reset(options={"x0": bad}))
    vec = TwoLinkVectorEnv(2)
    try:
        _raises(TypeError, "x0 must be real numbers, got a dict: {'a': 1}",
                lambda: vec.reset(options={"x0": bad}))
    finally:
        vec.close()


def test_text_and_negative_seeds():
    with TwoLinkEnv() as env:
        _raises(TypeError, "seed must be an int or None, got 'abc'", lambda: env.reset(seed="abc"))
        _raises(ValueError, "seed must be a non-negative whole number (at most 2**63 - 1), "
                            "got -1", lambda: env.reset(seed=-1))
    vec = TwoLinkVectorEnv(2)
    try:
        _raises(TypeError, "seed must be an int, None or a list of 2 seeds, got 'abc'",
                lambda: vec.reset(seed="abc"))
        _raises(TypeError, "seed[1] must be an int or None, got 'a'",
                lambda: vec.reset(seed=[1, "a"]))
    finally:
        vec.close()
    _raises(TypeError, "seed must be an int or None, got 'abc'",
            lambda: dm.load("centralized", seed="abc"))
    _raises(ValueError, "seed must be a non-negative whole number (at most 4294967295), "
                        "got 4294967296", lambda: dm.load("centralized", seed=2**32))
    env = parallel_env()
    try:
        _raises(TypeError, "seed must be an int or None, got 'abc'", lambda: env.reset(seed="abc"))
    finally:
        env.close()


@pytest.mark.parametrize("seed, error, message", [
    (-1, ValueError, "seed must be a non-negative whole number (at most 2**63 - 1), got -1"),
    ("abc", TypeError, "seed must be an int or a numpy Generator, got 'abc'"),
    (1.0, TypeError, "seed must be an int or a numpy Generator, got 1.0"),
])
def test_random_poses_seed(seed, error, message):
    _raises(error, message, lambda: random_poses(2, 3, seed))


def test_random_poses_good_seeds_unchanged():
    assert random_poses(2, 3, 7).shape == (3, 4)
    np.testing.assert_array_equal(random_poses(2, 3, np.random.default_rng(7)),
                                  random_poses(2, 3, 7))


@pytest.mark.parametrize("action, error, message", [
    (9, ValueError, "action must be a discrete action index in [0, 8], got 9"),
    (-1, ValueError, "action must be a discrete action index in [0, 8], got -1"),
    (10**30, ValueError, "action must be a discrete action index in [0, 8], got " + "1" + "0" * 30),
    (2.5, TypeError, "action must be a whole number (a discrete action index in [0, 8]), got 2.5"),
    ("3", TypeError, "action must be a whole number (a discrete action index in [0, 8]), got '3'"),
])
def test_a_discrete_action_out_of_range_or_type(action, error, message):
    with TwoLinkEnv(actions="discrete") as env:
        env.reset(seed=0)
        _raises(error, message, lambda: env.step(action))
        obs, *_ = env.step(np.int64(4))                   # a good one still steps
        assert obs.shape == (4,)


def test_a_vector_of_discrete_actions_with_a_huge_one():
    vec = TwoLinkVectorEnv(2, actions="discrete")
    try:
        vec.reset(seed=0)
        _raises(ValueError, "action must be a discrete action index in [0, 8], got " + "1" + "0" * 30,
                lambda: vec.step([1, 10**30]))
    finally:
        vec.close()


@pytest.mark.parametrize("size, error, message", [
    ((100_000, 100_000), ValueError, "render_size width must be from 1 to 4096 pixels, got 100000"),
    ((320, 5000), ValueError, "render_size height must be from 1 to 4096 pixels, got 5000"),
    ((320.5, 240), TypeError, "render_size width must be an int (pixels), got 320.5"),
    ("320x240", TypeError, "render_size must be (width, height), got '320x240'"),
])
def test_an_absurd_render_size_is_refused_at_construction(size, error, message):
    _raises(error, message, lambda: TwoLinkEnv(render_mode="rgb_array", render_size=size))


@pytest.mark.parametrize("speed_max, error, message", [
    ([1, 2, 3], ValueError, "speed_max must have 1 or 2 values (one per link), got 3"),
    ("fast", TypeError, "speed_max must be real numbers, got a str: 'fast'"),
    ([1.0, np.nan], ValueError, "speed_max contains NaN or infinite values"),
    ([1.0, -2.0], ValueError, "speed_max must be positive (rad/s), got [1.0, -2.0]"),
])
def test_speed_max_of_the_wrong_count(speed_max, error, message):
    _raises(error, message, lambda: dm.load("centralized", speed_max=speed_max))


def test_speed_max_one_or_two_values_still_work():
    for v in (3.0, [3.0, 4.0]):
        env = dm.load("centralized", speed_max=v)
        assert env.task._bound[2:].tolist() == np.broadcast_to(v, (2,)).tolist()


def test_the_shared_checks_raise_typed_errors_naming_the_argument():
    _raises(TypeError, "seed must be an int or None, got True", lambda: validate.seed(True))
    _raises(TypeError, "width must be an int (pixels), got None",
            lambda: validate.pixels(None, "width", 10))
    assert validate.count_of(2, "speed_max", 3).tolist() == [2.0, 2.0, 2.0]
    assert validate.seed(None) is None and validate.seed(np.int64(3)) == 3
