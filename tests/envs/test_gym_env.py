"""The Gymnasium environments: Gymnasium's own checker on every registered variant,
contracts (determinism, no aliasing, bad input, close), the trajectory against the
rollout code and the dm_env environment, and the batched vector environment against N
single environments stepped by Gymnasium's ``SyncVectorEnv``."""
from __future__ import annotations

import re
import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from gymnasium.vector import AutoresetMode, SyncVectorEnv

from twolink.arm.parameters import (
    HORIZON,
    PAPER_X0,
    REWARD_GOAL,
    REWARD_OTHER,
    TABLE_I,
    TS,
)
from twolink.synthesis.problems import centralized_actions
from twolink.envs import gym as gym_env
from twolink.sim.challenges import LEVELS, Challenge
from twolink.sim.perturbations import perturbed
from twolink.sim.plants import MujocoPlant
from twolink.sim.rollout import rollout

IDS = (gym_env.ENV_ID, gym_env.DISCRETE_ID)
CHALLENGES = dict(x0="random", angle_noise=0.02, speed_noise=0.05, perturbation=0.2, delay=1)
#: Every part of a challenge on, faults frequent enough to fire within a few steps.
HARSH = Challenge("harsh", spread=0.3, torque_limit=-0.2, action_delay=1, observation_delay=2,
                  angle_noise_deg=1.0, speed_noise=0.05, dropout=0.3, stuck=0.1)


def _drive(env, policy, **reset):
    """States, torques, rewards and truncation flags of one episode under ``policy``."""
    obs, _ = env.reset(**reset)
    xs, us, rs, truncs = [env.unwrapped.state], [], [], []
    truncated = False
    while not truncated:
        u = gym_env.policy_action(policy, obs)
        obs, r, terminated, truncated, _ = env.step(u)
        assert terminated is False
        xs.append(env.unwrapped.state)
        us.append(u)
        rs.append(r)
        truncs.append(truncated)
    return np.array(xs), np.array(us), np.array(rs), truncs


@pytest.mark.parametrize("observation", gym_env.OBSERVATIONS)
@pytest.mark.parametrize("env_id", IDS)
def test_gymnasium_checker_passes_on_every_variant(env_id, observation):
    """check_env, through gymnasium.make (so rgb_array rendering is checked too), with
    no warning on the noiseless variants."""
    for kwargs in ({}, CHALLENGES):
        env = gymnasium.make(env_id, observation=observation, **kwargs)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            check_env(env.unwrapped)
        env.close()
        if not kwargs:
            assert [str(w.message) for w in caught] == []


def test_spaces_and_registration():
    env = gymnasium.make(gym_env.ENV_ID)
    assert env.action_space == gymnasium.spaces.Box(-TABLE_I.tau_max, TABLE_I.tau_max,
                                                    (2,), np.float64)
    assert env.observation_space.shape == (4,)
    env.close()
    env = gymnasium.make("twolink.envs.gym:" + gym_env.DISCRETE_ID, observation="cos_sin")
    assert env.action_space == gymnasium.spaces.Discrete(9)
    assert env.observation_space.shape == (6,)
    env.close()
    vec = gymnasium.make_vec(gym_env.ENV_ID, num_envs=3)        # the batched one by default
    assert isinstance(vec, gym_env.TwoLinkVectorEnv) and vec.num_envs == 3
    assert vec.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    vec.close()


def test_trajectory_equals_rollout_and_the_dm_env_environment(centralized):
    """The shipped policy through the environment retraces ``rollout`` on the MuJoCo plant
    and the dm_env environment, bit for bit; reward (15), truncated at 5 s, never
    terminated."""
    env = gymnasium.make(gym_env.ENV_ID)
    xs, us, rs, truncs = _drive(env, centralized, seed=0)
    env.close()
    with MujocoPlant(nthread=1) as plant:
        traj = rollout(centralized, plant, np.array(PAPER_X0), duration=HORIZON)
    np.testing.assert_array_equal(xs, traj.x)
    np.testing.assert_array_equal(us, traj.u)
    np.testing.assert_array_equal(rs, traj.r)
    assert truncs == [False] * (round(HORIZON / TS) - 1) + [True]

    from twolink.envs import dm as dm_env_module
    dm = dm_env_module.load("centralized")
    ts, states = dm.reset(), []
    for u in us:
        ts = dm.step(u)
        states.append(dm.physics.state())
    assert ts.last()
    np.testing.assert_array_equal(np.array(states), xs[1:])


def test_perturbed_delayed_environment_equals_rollout_on_that_plant(centralized):
    change = {"m2": 0.3, "b1": -0.4}
    x0 = np.array([0.5, -2.0, 1.0, 0.0])
    env = gym_env.TwoLinkEnv(perturbation=change, delay=2, x0=x0, time_limit=1.0)
    xs, us, _, _ = _drive(env, centralized)
    env.close()
    from twolink.sim.perturbations import ActuationDelay
    with MujocoPlant(perturbed(TABLE_I, **change), nthread=1) as plant:
        traj = rollout(ActuationDelay(centralized, 2), plant, x0, duration=1.0)
    np.testing.assert_array_equal(xs, traj.x)
    np.testing.assert_array_equal(traj.u[:2], 0.0)


def test_discrete_actions_are_the_joint_actions_of_the_paper():
    table = centralized_actions(TABLE_I)
    assert table.shape == (9, 2) and set(table[:, 0]) == {-TABLE_I.tau1_max, 0, TABLE_I.tau1_max}
    disc, box = gymnasium.make(gym_env.DISCRETE_ID), gymnasium.make(gym_env.ENV_ID)
    o1, _ = disc.reset(seed=1)
    o2, _ = box.reset(seed=1)
    for i in [0, 8, 4, 2, 6, 1]:
        o1, r1, *_ = disc.step(i)
        o2, r2, *_ = box.step(table[i])
        np.testing.assert_array_equal(o1, o2)
        assert r1 == r2
    disc.close(), box.close()


def test_cos_sin_features_and_the_policy_adapter(centralized):
    env = gym_env.TwoLinkEnv(observation="cos_sin", x0=np.array([3.0, -2.0, 0.5, -1.0]))
    obs, _ = env.reset()
    x = env.state
    np.testing.assert_array_equal(obs, [np.cos(3.0), np.sin(3.0), np.cos(-2.0), np.sin(-2.0),
                                        0.5, -1.0])
    np.testing.assert_allclose(gym_env.policy_action(centralized, obs, features="cos_sin"),
                               centralized(x), atol=1e-12)
    env.close()


@pytest.mark.parametrize("env_id", IDS)
def test_deterministic_under_a_seed(env_id):
    def episode(seed):
        env = gymnasium.make(env_id, time_limit=0.5, **CHALLENGES)
        env.action_space.seed(7)
        out = [env.reset(seed=seed)[0]]
        for _ in range(10):
            obs, r, _, _, _ = env.step(env.action_space.sample())
            out += [obs, r]
        out.append(env.reset()[0])            # the next episode continues the generator
        env.close()
        return out

    a, b, c = episode(3), episode(3), episode(4)
    for u, v in zip(a, b):
        np.testing.assert_array_equal(u, v)
    assert not np.array_equal(a[0], c[0])


def test_observations_do_not_alias_internal_state():
    env = gym_env.TwoLinkEnv()
    obs, _ = env.reset(seed=0)
    before = env.state
    obs[:] = 99.0
    np.testing.assert_array_equal(env.state, before)
    o1, *_ = env.step(np.zeros(2))
    o2, *_ = env.step(np.zeros(2))
    assert not np.shares_memory(o1, o2)
    env.close()
    vec = gym_env.TwoLinkVectorEnv(2, nthread=1)
    o1, _ = vec.reset(seed=0)
    o2, r, te, tr, _ = vec.step(np.zeros((2, 2)))
    o3, r3, *_ = vec.step(np.zeros((2, 2)))
    assert not np.shares_memory(o2, o3) and not np.shares_memory(r, r3)
    o3[:] = 99.0
    assert np.all(vec.states != 99.0)
    vec.close()


BAD_ACTIONS = [np.zeros(3), np.zeros((1, 2)), np.array([np.nan, 0.0]), np.array([0.0, np.inf]),
               np.array(["0", "0"]), np.array([True, False]), None]


@pytest.mark.parametrize("bad", BAD_ACTIONS, ids=range(len(BAD_ACTIONS)))
def test_bad_actions_refused_and_nothing_stepped(bad):
    env = gym_env.TwoLinkEnv(delay=1)
    env.reset(seed=0)
    env.step(np.array([0.1, -0.1]))
    x, k = env.state, env.unwrapped._arms.k.copy()
    with pytest.raises(ValueError, match="action") as info:
        env.step(bad)
    assert "\n" not in str(info.value)
    np.testing.assert_array_equal(env.state, x)
    np.testing.assert_array_equal(env.unwrapped._arms.k, k)
    ref = gym_env.TwoLinkEnv(delay=1)               # the delay line is untouched too
    ref.reset(seed=0)
    ref.step(np.array([0.1, -0.1]))
    np.testing.assert_array_equal(env.step(np.zeros(2))[0], ref.step(np.zeros(2))[0])
    env.close(), ref.close()


@pytest.mark.parametrize("bad, error", [(9, ValueError), (-1, ValueError), (1.0, TypeError),
                                        (np.array([1, 2]), ValueError), ("3", TypeError)])
def test_bad_discrete_actions_refused(bad, error):
    env = gymnasium.make(gym_env.DISCRETE_ID)
    env.reset(seed=0)
    with pytest.raises(error, match="action"):
        env.step(bad)
    env.close()


@pytest.mark.parametrize("options, message", [
    ({"x0": [1, 2, 3]}, "x0"),
    ({"x0": [0, 0, 100, 0]}, "speed of magnitude"),
    ({"x0": "zero"}, "x0 must be"),
    ("x0", "options must be a dict"),
])
def test_bad_reset_options_refused_and_state_untouched(options, message):
    env = gym_env.TwoLinkEnv(x0="random")
    env.reset(seed=5)
    x, rng_state = env.state, env.np_random.bit_generator.state
    with pytest.raises(ValueError, match=message):
        env.reset(seed=9, options=options)
    np.testing.assert_array_equal(env.state, x)
    assert env.np_random.bit_generator.state == rng_state
    env.close()


@pytest.mark.parametrize("kwargs, message", [
    ({"task": "decentralized"}, "twolink.envs.pettingzoo"),
    ({"observation": "pixels"}, "observation must be"),
    ({"actions": "multi"}, "actions must be"),
    ({"time_limit": -1}, "time_limit"),
    ({"perturbation": 1.5}, "perturbation size"),
    ({"angle_noise": -0.1}, "non-negative"),
    ({"delay": 0.5}, "whole number"),
    ({"delay": True}, "delay must be one number"),
    ({"speed_noise": [0.1, 0.2]}, "speed_noise must be one number"),
    ({"x0": np.zeros((2, 4))}, "x0 must be one state"),
    ({"params": {"m1": 1.0}}, "params must be an ArmParameters"),
    ({"render_mode": "human"}, "render_mode"),
])
def test_bad_constructor_options_refused(kwargs, message):
    with pytest.raises(ValueError, match=message):
        gym_env.TwoLinkEnv(**kwargs)


def test_reset_option_x0_and_time_limit():
    env = gym_env.TwoLinkEnv(time_limit=0.2)
    obs, _ = env.reset(options={"x0": [0.1, 0.2, 0.0, 0.0]})
    np.testing.assert_array_equal(obs, [0.1, 0.2, 0.0, 0.0])
    flags = [env.step(np.zeros(2))[3] for _ in range(4)]
    assert flags == [False, False, False, True]
    with pytest.raises(RuntimeError, match="episode is over"):
        env.step(np.zeros(2))
    obs, _ = env.reset()                               # back to the default x0
    np.testing.assert_array_equal(obs, PAPER_X0)
    env.close()


def test_rewards_are_15_on_the_true_state():
    env = gym_env.TwoLinkEnv(x0=np.zeros(4), angle_noise=1.0)
    env.reset(seed=0)
    obs, r, *_ = env.step(np.zeros(2))
    assert np.any(np.abs(obs[:2]) > np.radians(5))     # the noisy view is outside the band
    assert r == REWARD_GOAL                            # the arm at rest at the goal is in it
    env.reset(options={"x0": [1.0, 0, 0, 0]})
    assert env.step(np.zeros(2))[1] == REWARD_OTHER
    env.close()


def test_close_frees_the_renderer_and_the_plant():
    env = gymnasium.make(gym_env.ENV_ID, render_mode="rgb_array", render_size=(160, 120))
    env.reset(seed=0)
    try:
        frame = env.render()
    except Exception as exc:            # no EGL on this machine
        pytest.skip(str(exc))
    assert frame.shape == (120, 160, 3) and frame.dtype == np.uint8 and frame.std() > 10
    inner = env.unwrapped
    renderer, plant = inner._renderer, inner.plant
    env.close()
    assert renderer._renderer is None and plant._pool is None and inner._renderer is None
    env.close()                                        # twice is fine
    with pytest.raises(RuntimeError, match="closed"):
        inner.step(np.zeros(2))
    obs, _ = env.reset(seed=3)                          # a closed env starts again
    assert obs.shape == (4,) and env.step(np.zeros(2))[0].shape == (4,)
    assert env.render().shape == (120, 160, 3)
    env.close()
    vec = gym_env.TwoLinkVectorEnv(2)
    plant = vec.plant
    vec.close()
    assert plant._pool is None and vec.closed
    with pytest.raises(RuntimeError, match="closed"):
        vec.step(np.zeros((2, 2)))


@pytest.mark.parametrize("actions, options", [
    ("box", CHALLENGES), ("discrete", CHALLENGES), ("box", dict(x0="random", challenge=HARSH))],
    ids=["box", "discrete", "challenge"])
def test_vector_env_equals_n_single_envs(actions, options):
    """The batched vector environment against Gymnasium's SyncVectorEnv over single
    environments (one plant each), bit for bit, across next-step autoresets, with every
    perturbation on and a per-episode random plant (also a challenge's: observation
    delay, dropped and stuck readings). Only the autoreset steps' rewards differ, by
    design: the reward's floor (-0.5), never SyncVectorEnv's 0 (the goal reward), and
    marked in the infos; the truncation steps' ``is_success`` agree."""
    n, kwargs = 4, dict(actions=actions, time_limit=0.3, **options)
    vec = gym_env.TwoLinkVectorEnv(n, nthread=2, **kwargs)
    ref = SyncVectorEnv([lambda: gym_env.TwoLinkEnv(**kwargs) for _ in range(n)])
    assert vec.single_action_space == ref.single_action_space
    assert vec.single_observation_space == ref.single_observation_space
    o1, _ = vec.reset(seed=11)
    o2, _ = ref.reset(seed=11)
    np.testing.assert_array_equal(o1, o2)
    vec.action_space.seed(0)
    saw_reset, autoreset = False, np.zeros(n, dtype=bool)
    for _ in range(16):
        a = vec.action_space.sample()
        out1, out2 = vec.step(a), ref.step(a)
        for i, (u, v) in enumerate(zip(out1[:4], out2[:4])):
            if i == 1:        # rewards: the floor on autoreset steps, SyncVectorEnv's 0
                np.testing.assert_array_equal(u[~autoreset], v[~autoreset])
                assert np.all(u[autoreset] == -0.5) and np.all(v[autoreset] == 0.0)
            else:
                np.testing.assert_array_equal(u, v)
        info1, info2 = out1[4], out2[4]
        np.testing.assert_array_equal(info1.get("autoreset", np.zeros(n, bool)), autoreset)
        if out1[3].any():
            np.testing.assert_array_equal(info1["_is_success"], out1[3])
            np.testing.assert_array_equal(info1["is_success"], info2["is_success"])
        else:
            assert "is_success" not in info1
        autoreset = out1[3].copy()
        saw_reset |= bool(out1[3].any())
    assert saw_reset
    # a partial reset with new seeds and a given x0
    mask = np.array([True, False, True, False])
    o1, _ = vec.reset(seed=[1, None, 2, None], options={"reset_mask": mask, "x0": np.zeros(4)})
    o2, _ = ref.reset(seed=[1, None, 2, None], options={"reset_mask": mask, "x0": np.zeros(4)})
    np.testing.assert_array_equal(o1, o2)
    for _ in range(3):
        a = vec.action_space.sample()
        for u, v in zip(vec.step(a)[:4], ref.step(a)[:4]):
            np.testing.assert_array_equal(u, v)
    vec.close(), ref.close()


def test_vector_env_bad_input_refused_and_nothing_stepped():
    vec = gym_env.TwoLinkVectorEnv(3, nthread=1)
    vec.reset(seed=0)
    x = vec.states
    for bad in (np.zeros((2, 2)), np.zeros(2), np.full((3, 2), np.nan)):
        with pytest.raises(ValueError, match="action"):
            vec.step(bad)
    for options in ({"reset_mask": np.array([1, 0, 0])}, {"reset_mask": [True] * 3},
                    {"x0": np.zeros((2, 4))}):
        with pytest.raises(ValueError):
            vec.reset(options=options)
    with pytest.raises(ValueError, match="list of 3 seeds"):
        vec.reset(seed=[1, 2])
    np.testing.assert_array_equal(vec.states, x)
    vec.close()


def test_vector_env_drives_a_shipped_policy_like_rollout(centralized):
    x0 = np.array([[0.5, -2.0, 1.0, 0.0], list(PAPER_X0), [2.0, 1.0, 0.0, -3.0]])
    vec = gymnasium.make_vec(gym_env.ENV_ID, num_envs=3, time_limit=1.0)
    obs, _ = vec.reset(options={"x0": x0})
    xs = [vec.unwrapped.states]
    for _ in range(20):
        obs, *_ = vec.step(gym_env.policy_action(centralized, obs))
        xs.append(vec.unwrapped.states)
    vec.close()
    with MujocoPlant() as plant:
        traj = rollout(centralized, plant, x0, duration=1.0)
    np.testing.assert_array_equal(np.stack(xs, 1), traj.x)


def test_registration_needs_the_module_as_gymnasium_loads_no_plugins():
    """In a fresh interpreter the id is unknown until twolink.envs.gym is imported (as the
    Gymnasium guide, docs/guides/gymnasium.md, says); naming the module in the id imports it."""
    import subprocess
    import sys

    code = ("import gymnasium\n"
            "try:\n"
            "    gymnasium.make('twolink/TwoLink-v0')\n"
            "except gymnasium.error.Error as exc:\n"
            "    print('unknown:', type(exc).__name__)\n"
            "env = gymnasium.make('twolink.envs.gym:twolink/TwoLink-v0')\n"
            "print('made:', env.unwrapped.spec.id)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert "unknown: NamespaceNotFound" in out.stdout and "made: twolink/TwoLink-v0" in out.stdout


@pytest.mark.parametrize("n", [0, -3, True, 2.5, gym_env.MAX_ENVS + 1, 10**12])
def test_vector_env_size_is_bounded_before_allocating(n):
    with pytest.raises(ValueError, match=f"num_envs must be a whole number from 1 to "
                                         f"{gym_env.MAX_ENVS}"):
        gym_env.TwoLinkVectorEnv(n)


# --------------------------------------------------------------------------- challenges
def test_a_noise_only_challenge_is_the_noise_options():
    """One implementation: a challenge's noise is the angle_noise/speed_noise option's."""
    ch = Challenge("noise", angle_noise_deg=2.0, speed_noise=0.03)
    a = gym_env.TwoLinkEnv(challenge=ch, x0="random")
    b = gym_env.TwoLinkEnv(angle_noise=np.deg2rad(2.0), speed_noise=0.03, x0="random")
    oa, ob = a.reset(seed=3)[0], b.reset(seed=3)[0]
    np.testing.assert_array_equal(oa, ob)
    assert not np.array_equal(oa, a.unwrapped.state)
    for _ in range(4):
        np.testing.assert_array_equal(a.step(np.array([0.1, -0.05]))[0],
                                      b.step(np.array([0.1, -0.05]))[0])
    a.close(), b.close()


def test_challenge_plant_delays_and_late_readings_against_a_reference(centralized):
    """Under a challenge with no noise: the plant drawn from the episode's generator, the
    torque one sample late, the observation the true state of two samples ago."""
    ch = Challenge("late", spread=0.2, torque_limit=-0.3, action_delay=1, observation_delay=2)
    env = gym_env.TwoLinkEnv(challenge=ch, time_limit=1.0)
    obs, _ = env.reset(seed=5)
    from gymnasium.utils import seeding
    rng = seeding.np_random(5)[0]                       # the episode's generator
    changes = rng.uniform(-0.2, 0.2, 10)
    plant = TABLE_I.scaled(**{n: 1 + c for n, c in zip(
        ("l1", "l2", "m1", "m2", "I1", "I2", "c1", "c2", "b1", "b2"), changes)},
        tau1_max=0.7, tau2_max=0.7)
    assert env.unwrapped.plant.params[0] == plant
    assert env.action_space.high.tolist() == TABLE_I.tau_max.tolist()   # the nominal levels
    xs, seen, us = [env.unwrapped.state], [obs], []
    for _ in range(20):
        u = centralized(obs)
        obs, *_ = env.step(u)
        xs.append(env.unwrapped.state)
        seen.append(obs)
        us.append(u)
    with MujocoPlant(plant, nthread=1) as mj:
        x = xs[0]
        for k in range(20):
            x = mj.step(x, us[k - 1] if k else np.zeros(2))
            np.testing.assert_array_equal(x, xs[k + 1], err_msg=k)
    for k, o in enumerate(seen):
        np.testing.assert_array_equal(o, xs[max(0, k - 2)], err_msg=k)
    env.close()


@pytest.mark.parametrize("level", list(LEVELS))
def test_every_level_runs_and_is_deterministic(level):
    def run():
        env = gym_env.TwoLinkEnv(challenge=level, x0="random", time_limit=0.5)
        out = [env.reset(seed=9)[0]] + [env.step(np.array([0.2, -0.1]))[0] for _ in range(10)]
        env.close()
        return np.array(out)
    np.testing.assert_array_equal(run(), run())


@pytest.mark.parametrize("kwargs, message", [
    (dict(challenge="medium", delay=1), "either challenge or delay"),
    (dict(challenge="hard", perturbation=0.1), "either challenge or perturbation"),
    (dict(challenge="hard", angle_noise=0.1, speed_noise=0.1), "angle_noise, speed_noise"),
    (dict(challenge="brutal"), "unknown challenge 'brutal'; choose one of none, easy"),
])
def test_bad_challenge_options_refused(kwargs, message):
    for make in (gym_env.TwoLinkEnv, lambda **kw: gym_env.TwoLinkVectorEnv(2, **kw)):
        with pytest.raises(ValueError, match=re.escape(message)):
            make(**kwargs)


def test_unknown_reset_options_are_ignored_with_a_warning():
    env, plain = gym_env.TwoLinkEnv(x0="random"), gym_env.TwoLinkEnv(x0="random")
    with pytest.warns(UserWarning, match="ignoring unknown reset option.*'x1'"):
        obs, _ = env.reset(seed=5, options={"x1": 0})
    np.testing.assert_array_equal(obs, plain.reset(seed=5)[0])
