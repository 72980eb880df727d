"""The dm_env environments: contracts in the style of dm_control's suite tests, and the
environment trajectory against the rollout code."""
from __future__ import annotations

import dataclasses

import dm_env
import numpy as np
import pytest

from twolink import cli
from twolink.arm.parameters import (
    HORIZON,
    PAPER_X0,
    REWARD_GOAL,
    REWARD_OTHER,
    TABLE_I,
    TS,
)
from twolink.arm.task import agent_reward
from twolink.envs import dm as twolink_env
from twolink.policy.fuzzy_policy import load_policy
from twolink.sim.challenges import Challenge
from twolink.sim.perturbations import PHYSICAL, perturbed
from twolink.sim.plants import MujocoPlant
from twolink.sim.rollout import rollout
from twolink.sim.trajectory_file import load_npz

TASKS = twolink_env.TASKS


def _random_actions(env, rng):
    spec = env.action_spec()
    while True:
        yield rng.uniform(spec.minimum, spec.maximum)


def _episode(env, actions):
    """(timesteps, physics states) of one episode driven by ``actions``."""
    timesteps = [env.reset()]
    states = [env.physics.state()]
    while not timesteps[-1].last():
        timesteps.append(env.step(next(actions)))
        states.append(env.physics.state())
    return timesteps, np.array(states)


def _drive(env, policy):
    """Drive ``env`` through one episode with a policy: states, actions, rewards."""
    ts = env.reset()
    xs, us, rs = [env.physics.state()], [], []
    while not ts.last():
        u = twolink_env.policy_action(policy, ts.observation)
        ts = env.step(u)
        xs.append(env.physics.state())
        us.append(u)
        rs.append(ts.reward)
    return np.array(xs), np.array(us), np.array(rs)


@pytest.mark.parametrize("task", TASKS)
def test_specs_honoured_at_every_step(task):
    env = twolink_env.load(task, seed=3, x0="random", angle_noise=0.01, speed_noise=0.05)
    rng = np.random.default_rng(0)
    obs_spec, act_spec, rew_spec = env.observation_spec(), env.action_spec(), env.reward_spec()
    np.testing.assert_array_equal(act_spec.maximum, TABLE_I.tau_max)
    np.testing.assert_array_equal(act_spec.minimum, -TABLE_I.tau_max)
    timesteps, _ = _episode(env, _random_actions(env, rng))
    assert timesteps[0].first() and timesteps[0].reward is None
    for ts in timesteps:
        assert set(ts.observation) == set(obs_spec)
        for key, spec in obs_spec.items():
            spec.validate(ts.observation[key])
    for ts in timesteps[1:]:
        rew_spec.validate(ts.reward)
        env.discount_spec().validate(ts.discount)
        assert ts.discount == 1.0


@pytest.mark.parametrize("task", TASKS)
def test_deterministic_under_a_seed(task):
    kwargs = dict(x0="random", angle_noise=0.02, speed_noise=0.1, perturbation=0.2)
    runs = []
    for seed in (7, 7, 8):
        env = twolink_env.load(task, seed=seed, **kwargs)
        timesteps, states = _episode(env, _random_actions(env, np.random.default_rng(1)))
        obs = np.array([np.concatenate(list(ts.observation.values())) for ts in timesteps])
        runs.append((obs, states, env.task.params))
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    np.testing.assert_array_equal(runs[0][1], runs[1][1])
    assert runs[0][2] == runs[1][2]
    assert not np.array_equal(runs[0][1], runs[2][1])
    assert runs[0][2] != runs[2][2]


@pytest.mark.parametrize("task", TASKS)
def test_rewards_in_range_and_match_the_goal_band(task):
    env = twolink_env.load(task, seed=0)
    policy = load_policy(task)
    states, _, rewards = _drive(env, policy)
    assert np.all((rewards >= REWARD_OTHER) & (rewards <= REWARD_GOAL))
    # r_{k+1} is 0 exactly where x_{k+1} lies in the goal band ((15) per link for (17)).
    links = np.stack([agent_reward(states[1:], 1), agent_reward(states[1:], 2)], -1)
    expected = links.min(-1) if task == "centralized" else links
    np.testing.assert_array_equal(rewards, expected)
    assert REWARD_OTHER in rewards                                 # x0 is outside the band
    if task == "centralized":                                      # and this policy settles
        assert np.all(rewards[-20:] == REWARD_GOAL)


@pytest.mark.parametrize("task", TASKS)
@pytest.mark.parametrize("time_limit", [1.0, HORIZON])
def test_episodes_end_at_the_time_limit(task, time_limit):
    env = twolink_env.load(task, time_limit=time_limit)
    assert env.control_timestep() == pytest.approx(TS)
    timesteps, _ = _episode(env, _random_actions(env, np.random.default_rng(0)))
    assert len(timesteps) - 1 == round(time_limit / TS)
    assert [ts.step_type for ts in timesteps[1:-1]] == [dm_env.StepType.MID] * (len(timesteps) - 2)
    assert timesteps[-1].last() and timesteps[-1].discount == 1.0
    assert env.physics.time() == pytest.approx(time_limit)
    assert env.step(np.zeros(2)).first()  # the step after the last one starts a new episode


@pytest.mark.parametrize("task", TASKS)
def test_observations_do_not_alias_internal_buffers(task):
    env = twolink_env.load(task)
    ts = env.reset()
    state = env.physics.state()
    for value in ts.observation.values():
        assert not np.shares_memory(value, env.physics.data.qpos)
        assert not np.shares_memory(value, env.physics.data.qvel)
        value[...] = 123.0
    np.testing.assert_array_equal(env.physics.state(), state)
    ts2 = env.step(np.zeros(2))
    for key, value in ts2.observation.items():
        assert not np.shares_memory(value, ts.observation[key])
        assert np.all(value != 123.0)


@pytest.mark.parametrize("task", TASKS)
def test_actions_outside_the_spec_are_clipped(task):
    big, clipped = twolink_env.load(task), twolink_env.load(task)
    big.reset(), clipped.reset()
    ts_big = big.step(np.array([10.0, -10.0]))
    ts_clipped = clipped.step(np.array([TABLE_I.tau1_max, -TABLE_I.tau2_max]))
    np.testing.assert_array_equal(big.physics.data.ctrl, [TABLE_I.tau1_max, -TABLE_I.tau2_max])
    np.testing.assert_array_equal(big.physics.state(), clipped.physics.state())
    for key in ts_big.observation:
        np.testing.assert_array_equal(ts_big.observation[key], ts_clipped.observation[key])


@pytest.mark.parametrize("task", TASKS)
@pytest.mark.parametrize("bad", [[np.nan, 0.0], [0.0, np.inf]])
def test_nan_actions_refused(task, bad):
    env = twolink_env.load(task)
    env.reset()
    state = env.physics.state()
    with pytest.raises(ValueError, match="NaN or infinite"):
        env.step(np.array(bad))
    np.testing.assert_array_equal(env.physics.state(), state)  # nothing was stepped


@pytest.mark.parametrize("task", TASKS)
@pytest.mark.parametrize("bad", [[0.1], [0.1, 0.0, 0.0], "left"])
def test_malformed_actions_refused(task, bad):
    env = twolink_env.load(task)
    env.reset()
    with pytest.raises(ValueError, match="action"):
        env.step(bad)


@pytest.mark.parametrize("task", TASKS)
def test_environment_trajectory_equals_rollout(task):
    """The shipped policy through the environment retraces ``rollout`` on the MuJoCo plant."""
    policy = load_policy(task)
    xs, us, rewards = _drive(twolink_env.load(task), policy)
    plant = MujocoPlant(nthread=1)
    try:
        traj = rollout(policy, plant, np.array(PAPER_X0), duration=HORIZON)
    finally:
        plant.close()
    np.testing.assert_array_equal(xs, traj.x)
    np.testing.assert_array_equal(us, traj.u)
    np.testing.assert_array_equal(rewards, traj.r if task == "centralized" else traj.r_links)


@pytest.mark.parametrize("task", TASKS)
def test_environment_trajectory_equals_the_rollout_command(task, tmp_path):
    """``twolink rollout --plant mujoco`` and the environment give the same trajectory."""
    x0 = [0.5, -2.0, 1.0, 0.0]
    npz = tmp_path / "run.npz"
    code = cli.main(["rollout", "--policy", task, "--plant", "mujoco",
                     "--x0", *map(str, x0), "--npz", str(npz),
                     "--csv", str(tmp_path / "run.csv"), "--figure", str(tmp_path / "f.png")])
    assert code == 0
    traj = load_npz(npz)[(task, "mujoco")]
    xs, us, rewards = _drive(twolink_env.load(task, x0=x0), load_policy(task))
    np.testing.assert_array_equal(xs, traj.x)
    np.testing.assert_array_equal(us, traj.u)
    np.testing.assert_array_equal(rewards, traj.r if task == "centralized" else traj.r_links)


def test_perturbed_environment_equals_rollout_on_the_perturbed_plant():
    change = {"m2": 0.3, "b1": -0.4, "l1": 0.1}
    params = perturbed(TABLE_I, **change)
    env = twolink_env.load("centralized", perturbation=change, speed_max=4.0)
    assert env.task.params == dataclasses.replace(params, dtheta1_max=4.0, dtheta2_max=4.0)
    assert env.physics.named.model.body_mass["link2"] == pytest.approx(1.3)
    policy = load_policy("centralized")
    xs, us, _ = _drive(env, policy)
    plant = MujocoPlant(env.task.params, nthread=1)
    try:
        traj = rollout(policy, plant, np.array(PAPER_X0))
    finally:
        plant.close()
    np.testing.assert_array_equal(xs, traj.x)
    np.testing.assert_array_equal(us, traj.u)


def test_decentralized_agents_act_on_their_own_observations():
    policy = load_policy("decentralized")
    agent2, agent1 = policy.agents
    assert agent2.name == "agent2" and agent1.name == "agent1"
    env = twolink_env.load("decentralized", seed=5, x0="random")
    ts = env.reset()
    for _ in range(20):
        x = env.physics.state()
        np.testing.assert_array_equal(ts.observation["agent2"], x[[1, 3]])
        np.testing.assert_array_equal(ts.observation["agent1"], x[[0, 2, 1]])
        joint = twolink_env.decentralized_action(
            agent2.act, lambda o1, tau2: agent1.act(np.append(o1, tau2)), ts.observation)
        np.testing.assert_array_equal(joint, twolink_env.policy_action(policy, ts.observation))
        np.testing.assert_array_equal(joint, policy(x))
        ts = env.step(joint)
        reached = env.physics.state()
        np.testing.assert_array_equal(ts.reward, [agent_reward(reached, 1),
                                                  agent_reward(reached, 2)])
    with pytest.raises(ValueError, match="no observation of its own"):
        twolink_env.policy_action(load_policy("centralized"), ts.observation)


def test_state_conventions_and_speed_limit():
    env = twolink_env.load("centralized", seed=2, x0="random", speed_max=1.5)
    timesteps, states = _episode(env, _random_actions(env, np.random.default_rng(2)))
    after = states[1:]
    assert np.all((after[:, :2] >= -np.pi) & (after[:, :2] < np.pi))
    assert np.all(np.abs(after[:, 2:]) <= 1.5)
    assert np.isclose(np.abs(after[:, 2:]).max(), 1.5)  # the limit binds
    for ts, x in zip(timesteps, states):
        np.testing.assert_array_equal(ts.observation["state"], x)  # no noise: exact state


def test_observation_noise_spares_the_reward():
    env = twolink_env.load("centralized", seed=0, x0=[0.0, 0.0, 0.0, 0.0], angle_noise=0.5)
    ts = env.reset()
    np.testing.assert_array_equal(env.physics.state(), 0.0)
    assert np.all(ts.observation["state"][:2] != 0.0)
    np.testing.assert_array_equal(ts.observation["state"][2:], 0.0)
    assert env.step(np.zeros(2)).reward == REWARD_GOAL  # true state stays at the goal


def test_given_and_paper_initial_states():
    x0 = [0.5, -0.25, 1.0, -2.0]
    ts = twolink_env.load("decentralized", x0=x0).reset()
    np.testing.assert_array_equal(ts.observation["agent1"], [0.5, 1.0, -0.25])
    np.testing.assert_array_equal(ts.observation["agent2"], [-0.25, -2.0])
    ts = twolink_env.load("centralized").reset()
    np.testing.assert_array_equal(ts.observation["state"], PAPER_X0)


@pytest.mark.parametrize("kwargs, message", [
    (dict(task_name="reacher"), "unknown task"),
    (dict(task_name="centralized", x0="somewhere"), "x0 must be"),
    (dict(task_name="centralized", x0=[0.0, np.nan, 0.0, 0.0]), "NaN"),
    (dict(task_name="centralized", x0=[[0.0] * 4] * 2), "shape"),
    (dict(task_name="centralized", time_limit=0.0), "time_limit"),
    (dict(task_name="centralized", angle_noise=-1.0), "non-negative"),
    (dict(task_name="centralized", perturbation=1.5), r"\[0, 1\)"),
    (dict(task_name="centralized", perturbation={"mass": 0.1}), "unknown parameter"),
    (dict(task_name="centralized", perturbation="big"), "perturbation must be"),
    (dict(task_name="centralized", speed_max=-1.0), "positive"),
])
def test_bad_options_refused(kwargs, message):
    name = kwargs.pop("task_name")
    with pytest.raises(ValueError, match=message):
        twolink_env.load(name, **kwargs)


@pytest.mark.parametrize("task", TASKS)
def test_render_headless(task):
    env = twolink_env.load(task)
    env.reset()
    frame = env.physics.render(height=120, width=160, camera_id="top")
    assert frame.shape == (120, 160, 3) and frame.dtype == np.uint8
    assert frame.std() > 10  # an image, not a blank buffer
    tip = env.physics.tip_position()
    theta1, theta2 = PAPER_X0[:2]
    expected = [TABLE_I.l1 * np.cos(theta1) + TABLE_I.l2 * np.cos(theta1 + theta2),
                TABLE_I.l1 * np.sin(theta1) + TABLE_I.l2 * np.sin(theta1 + theta2)]
    np.testing.assert_allclose(tip, expected, atol=1e-12)


class _DmEnvContract:
    """dm_env's own contract tests (``dm_env.test_utils.EnvironmentTestMixin``), run on
    each task with episodes short enough that the action sequence reaches LAST."""

    task = ""

    def make_object_under_test(self):
        return twolink_env.load(self.task, seed=0, time_limit=0.5, x0="random")

    def make_action_sequence(self):
        rng = np.random.default_rng(0)
        for _ in range(25):                  # 2.5 episodes of 10 steps
            yield rng.uniform(-TABLE_I.tau_max, TABLE_I.tau_max)


def _dm_env_contract(task):
    import unittest

    from dm_env import test_utils

    return type(f"DmEnvContract_{task}", (_DmEnvContract, test_utils.EnvironmentTestMixin,
                                          unittest.TestCase), {"task": task})


TestDmEnvContractCentralized = _dm_env_contract("centralized")
TestDmEnvContractDecentralized = _dm_env_contract("decentralized")


# --------------------------------------------------------------------------- challenges
_LATE = Challenge("late", spread=0.2, torque_limit=-0.3, action_delay=2, observation_delay=1)


def test_challenge_plant_delays_and_late_readings_against_a_reference():
    """One plant drawn from the seed's RandomState (PHYSICAL order), the nominal action
    spec, torques two samples late, the observation the state of one sample ago."""
    env = twolink_env.load("centralized", seed=4, challenge=_LATE, time_limit=1.0)
    changes = np.random.RandomState(4).uniform(-0.2, 0.2, 10)
    plant = TABLE_I.scaled(**dict(zip(PHYSICAL, 1 + changes)), tau1_max=0.7, tau2_max=0.7)
    assert env.task.params == plant
    assert env.action_spec().maximum.tolist() == TABLE_I.tau_max.tolist()
    rng = np.random.default_rng(0)
    ts = env.reset()
    xs, seen, us = [env.physics.state()], [ts.observation["state"]], []
    while not ts.last():
        us.append(rng.uniform(-TABLE_I.tau_max, TABLE_I.tau_max))
        ts = env.step(us[-1])
        xs.append(env.physics.state())
        seen.append(ts.observation["state"])
    with MujocoPlant(plant, nthread=1) as mj:     # the plant clips to its own limits
        x = xs[0]
        for k in range(len(us)):
            x = mj.step(x, us[k - 2] if k >= 2 else np.zeros(2))
            np.testing.assert_array_equal(x, xs[k + 1], err_msg=k)
    for k, o in enumerate(seen):
        np.testing.assert_array_equal(o, xs[max(0, k - 1)], err_msg=k)
    # a second episode starts afresh: no torque of the first arrives
    env.reset()
    x0 = env.physics.state()
    env.step(TABLE_I.tau_max)
    with MujocoPlant(plant, nthread=1) as mj:
        np.testing.assert_array_equal(env.physics.state(), mj.step(x0, np.zeros(2)))


@pytest.mark.parametrize("task", TASKS)
def test_challenge_levels_deterministic_under_a_seed(task):
    def run(seed):
        env = twolink_env.load(task, seed=seed, challenge="hard", x0="random", time_limit=1.0)
        ts, _ = _episode(env, _random_actions(env, np.random.default_rng(1)))
        return env.task.params, [np.concatenate(list(t.observation.values())) for t in ts]
    (p1, o1), (p2, o2), (p3, _) = run(3), run(3), run(4)
    assert p1 == p2 and p1 != p3
    np.testing.assert_array_equal(np.array(o1), np.array(o2))


def test_challenge_refused_beside_the_separate_options():
    with pytest.raises(ValueError, match="either challenge or perturbation"):
        twolink_env.load("centralized", challenge="easy", perturbation=0.1)
    with pytest.raises(ValueError, match="either challenge or angle_noise"):
        twolink_env.load("centralized", challenge="easy", angle_noise=0.1)
    with pytest.raises(ValueError, match="unknown challenge"):
        twolink_env.load("centralized", challenge="extreme")
