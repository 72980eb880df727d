"""The N-link arm as an RL environment (issue 11): the dm_env tasks, the Gymnasium
environments and the PettingZoo environment for N = 3, 4 (specs, shapes, determinism,
PettingZoo's and Gymnasium's own checkers), a 3-link policy through each of them held
bit for bit against ``rollout`` on the MuJoCo plant, and the refusals."""
from __future__ import annotations

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from pettingzoo.test import api_test, parallel_api_test
from pettingzoo.utils.wrappers import OrderEnforcingWrapper

from twolink.arm.parameters import REWARD_GOAL, REWARD_OTHER, TABLE_I, TS, links_parameters
from twolink.arm.task import agent_reward, centralized_reward
from twolink.envs import core as tasks
from twolink.envs import dm as twolink_env
from twolink.envs import gym as gym_env
from twolink.envs import pettingzoo as tpz
from twolink.envs.compensated import CompensatedObservation
from twolink.policy.fuzzy_policy import load_policy
from twolink.sim.metrics import random_poses
from twolink.sim.plants import MujocoPlant
from twolink.sim.rollout import rollout

LINKS = (3, 4)
#: The poses the 3-link policy starts from, and how long it runs (2 s = 40 steps).
POSES = random_poses(3, 3, seed=11)
DURATION = 2.0


@pytest.fixture(scope="module")
def policy3():
    return load_policy("decentralized_3link")


@pytest.fixture(scope="module")
def reference(policy3):
    """The 3-link policy from POSES on the MuJoCo plant, through ``rollout``."""
    with MujocoPlant(links_parameters(3), nthread=1) as plant:
        return rollout(policy3, plant, POSES, duration=DURATION)


class _ApiProbe(tpz.ParallelArm):
    """PettingZoo's API tests open with ``reset(options={'options': 1})`` only to see that
    reset takes options; the arm refuses unknown keys, so that probe reads as none."""

    def reset(self, seed=None, options=None):
        return super().reset(seed=seed, options=None if options == {"options": 1} else options)


# --------------------------------------------------------------------------- tasks
def test_observation_names_extend_the_two_link_agents():
    assert tasks.observation_names(2) == tasks.OBSERVATION_NAMES
    assert tasks.OBSERVATION_NAMES["agent1"] == ("theta1", "dtheta1", "theta2")
    names = tasks.observation_names(4)
    assert names["state"] == ("theta1", "theta2", "theta3", "theta4",
                              "dtheta1", "dtheta2", "dtheta3", "dtheta4")
    assert names["agent2"] == ("theta2", "dtheta2", "theta3", "dtheta3")
    assert names["agent4"] == ("theta4", "dtheta4")
    assert [tasks.horizon(n) for n in (2, 3, 6)] == [5.0, 8.0, 8.0]
    x = np.arange(8.0)
    np.testing.assert_array_equal(tasks.observe(x, "agent3"), [2.0, 6.0, 3.0, 7.0])


# --------------------------------------------------------------------------- dm_env
@pytest.mark.parametrize("links", LINKS)
@pytest.mark.parametrize("task", twolink_env.TASKS)
def test_dm_env_specs_shapes_and_rewards(task, links):
    env = twolink_env.load(task, links=links, seed=0, time_limit=0.5)
    assert env.action_spec().shape == (links,)
    np.testing.assert_array_equal(env.action_spec().maximum, links_parameters(links).tau_max)
    spec = env.observation_spec()
    keys = ["state"] if task == "centralized" else [f"agent{i}" for i in range(1, links + 1)]
    assert list(spec) == keys
    rng = np.random.default_rng(1)
    ts, steps = env.reset(), 0
    x0 = env.physics.state()
    assert x0.shape == (2 * links,) and np.all(x0[links:] == 0.0)      # 'random': at rest
    while not ts.last():
        for key, value in ts.observation.items():
            spec[key].validate(value)
        tau_max = links_parameters(links).tau_max
        ts = env.step(rng.uniform(-tau_max, tau_max))
        steps += 1
        x = env.physics.state()
        want = (centralized_reward(x) if task == "centralized"
                else [agent_reward(x, i) for i in range(1, links + 1)])
        np.testing.assert_array_equal(ts.reward, want)
        assert np.all((REWARD_OTHER <= ts.reward) & (ts.reward <= REWARD_GOAL))
        env.task.reward_spec().validate(np.asarray(ts.reward))
    assert steps == 10
    if task == "decentralized":
        x = dict(zip(tasks.observation_names(links)["state"], env.physics.state()))
        for key in keys:
            np.testing.assert_array_equal(
                ts.observation[key], [x[c] for c in tasks.observation_names(links)[key]])


def test_dm_env_defaults_and_determinism():
    env = twolink_env.load("decentralized", links=3, seed=4)
    assert env._step_limit == tasks.horizon(3) / TS == 160
    a, b = (twolink_env.load("centralized", links=3, seed=s, time_limit=0.3) for s in (4, 4))
    c = twolink_env.load("centralized", links=3, seed=5, time_limit=0.3)
    runs = []
    for e in (a, b, c):
        e.reset()
        runs.append([e.step(np.full(3, 0.05)).observation["state"] for _ in range(6)])
    np.testing.assert_array_equal(runs[0], runs[1])
    assert not np.array_equal(runs[0], runs[2])
    slow = twolink_env.load("centralized", links=3, seed=0, speed_max=1.0)
    slow.reset()
    for _ in range(10):
        slow.step(slow.action_spec().maximum)
    assert slow.task.params.speed_limits == (1.0,) * 3
    assert np.abs(slow.physics.speeds()).max() == 1.0                 # the limit binds
    two = twolink_env.load("centralized", params=links_parameters(2))        # two links are Table I
    assert two.task.params == TABLE_I and two.reset().observation["state"].tolist() == \
        [-1.0, -3.0, 0.0, 0.0]


@pytest.mark.parametrize("task", twolink_env.TASKS)
def test_policy_through_dm_env_equals_rollout(task, policy3, reference):
    for row, x0 in enumerate(POSES):
        env = twolink_env.load(task, links=3, x0=x0, time_limit=DURATION)
        ts = env.reset()
        xs, us, rs = [env.physics.state()], [], []
        while not ts.last():
            u = twolink_env.policy_action(policy3, ts.observation)
            ts = env.step(u)
            xs.append(env.physics.state())
            us.append(u)
            rs.append(ts.reward)
        np.testing.assert_array_equal(xs, reference.x[row])
        np.testing.assert_array_equal(us, reference.u[row])
        np.testing.assert_array_equal(rs, reference.r[row] if task == "centralized"
                                      else reference.r_links[row])


# --------------------------------------------------------------------------- Gymnasium
@pytest.mark.parametrize("observation, actions, size, n_actions", [
    ("state", "box", 6, None), ("cos_sin", "discrete", 9, 27)])
def test_gymnasium_checker_and_spaces(observation, actions, size, n_actions):
    env = gym_env.TwoLinkEnv(links=3, observation=observation, actions=actions)
    check_env(env, skip_render_check=True)
    assert env.observation_space.shape == (size,)
    if n_actions is None:
        assert env.action_space.shape == (3,)
    else:
        assert env.action_space.n == n_actions
        np.testing.assert_array_equal(env._arms.table[-1], links_parameters(3).tau_max)
    assert env._arms.steps == 160
    obs, _ = env.reset(seed=3)
    again, _ = gym_env.TwoLinkEnv(links=3, observation=observation, actions=actions).reset(seed=3)
    np.testing.assert_array_equal(obs, again)
    env.close()


def test_gymnasium_four_links_and_render():
    env = gym_env.TwoLinkEnv(links=4, rule="copied", time_limit=0.1, render_mode="rgb_array",
                             render_size=(160, 120))
    obs, _ = env.reset(seed=0)
    assert obs.shape == (8,) and env.action_space.shape == (4,)
    obs, r, terminated, truncated, _ = env.step(np.zeros(4))
    assert obs.shape == (8,) and r == REWARD_OTHER and not terminated and not truncated
    assert env.plant.params == links_parameters(4, "copied")
    frame = env.render()
    assert frame.shape == (120, 160, 3) and frame.std() > 10
    env.close()


def test_policy_through_gymnasium_equals_rollout(policy3, reference):
    steps = reference.steps
    env = gym_env.TwoLinkEnv(links=3, time_limit=DURATION)
    vec = gym_env.TwoLinkVectorEnv(len(POSES), links=3, time_limit=DURATION, nthread=1)
    obs_v, _ = vec.reset(options={"x0": POSES})
    for row, x0 in enumerate(POSES):
        obs, _ = env.reset(options={"x0": x0})
        for k in range(steps):
            obs, _, _, truncated, _ = env.step(gym_env.policy_action(policy3, obs))
            np.testing.assert_array_equal(env.state, reference.x[row, k + 1])
        assert truncated
    for k in range(steps):
        obs_v, r, _, truncated, _ = vec.step(gym_env.policy_action(policy3, obs_v))
        np.testing.assert_array_equal(obs_v, reference.x[:, k + 1])
        np.testing.assert_array_equal(r, reference.r[:, k])
    assert truncated.all()
    env.close()
    vec.close()


# --------------------------------------------------------------------------- PettingZoo
def test_pettingzoo_api_tests_three_links():
    parallel_api_test(_ApiProbe(links=3, x0="random", link1_tau2="previous", time_limit=1.0),
                      num_cycles=30)
    api_test(OrderEnforcingWrapper(tpz.SequentialArm(_ApiProbe(links=3, time_limit=1.0))),
             num_cycles=30)
    aec = tpz.env(links=3, link1_tau2="current")
    assert aec.possible_agents == ["link3", "link2", "link1"]          # outermost first


@pytest.mark.parametrize("links", LINKS)
def test_pettingzoo_agents_one_per_joint(links):
    env = tpz.parallel_env(links=links, link1_tau2="previous")
    names = [f"link{i}" for i in range(1, links + 1)]
    assert env.possible_agents == names and tpz.agents(links) == tuple(names)
    assert [env.observation_space(a).shape for a in names] == [(5,)] * (links - 1) + [(2,)]
    np.testing.assert_array_equal([env.action_space(a).high[0] for a in names],
                                  links_parameters(links).tau_max)
    obs, _ = env.reset(seed=2)
    x = env.state()
    assert x.shape == (2 * links,) and env._steps == 160
    np.testing.assert_array_equal(obs["link2"], [x[1], x[links + 1], x[2], x[links + 2], 0.0])
    torques = {a: np.array([0.01 * i]) for i, a in enumerate(names, 1)}
    obs, rewards, _, truncations, _ = env.step(torques)
    x = env.state()
    assert rewards == {a: float(agent_reward(x, i)) for i, a in enumerate(names, 1)}
    assert obs["link1"][-1] == 0.02 and not any(truncations.values())     # tau2 before
    same, _ = tpz.parallel_env(links=links, link1_tau2="previous").reset(seed=2)
    again, _ = tpz.parallel_env(links=links, link1_tau2="previous").reset(seed=2)
    for a in names:
        np.testing.assert_array_equal(same[a], again[a])


def test_policy_through_pettingzoo_equals_rollout(policy3, reference):
    for row, x0 in enumerate(POSES):
        env = tpz.parallel_env(links=3, x0=x0, time_limit=DURATION)
        obs, _ = env.reset()
        xs, rs = [env.state()], []
        while env.agents:
            obs, rewards, _, _, _ = env.step(tpz.policy_actions(policy3, obs))
            xs.append(env.state())
            rs.append([rewards[a] for a in tpz.agents(3)])
        np.testing.assert_array_equal(xs, reference.x[row])
        np.testing.assert_array_equal(rs, reference.r_links[row])
        env.close()


def test_each_agent_acts_on_its_own_sequential_observation(policy3, reference):
    """In the AEC form with ``link1_tau2='current'`` (turns link3, link2, link1) every
    agent of the 3-link policy acts on its own observation alone: it holds exactly the
    agent's inputs, the neighbour's torque of this very sample last."""
    agents = {f"link{a.name[len('agent'):]}": a for a in policy3.agents}
    for row, x0 in enumerate(POSES[:2]):
        aec = tpz.env(links=3, link1_tau2="current", x0=x0, time_limit=DURATION)
        aec.reset()
        xs, tau = [aec.unwrapped.state()], {}
        for agent in aec.agent_iter():
            observation, _, terminated, truncated, _ = aec.last()
            if terminated or truncated:
                aec.step(None)
                continue
            own = agents[agent]
            assert len(own.inputs) == len(observation)
            tau[agent] = own.act(observation)
            if agent != "link3":
                assert observation[-1] == tau[f"link{int(agent[4:]) + 1}"][0]
            aec.step(tau[agent])
            if agent == "link1":
                xs.append(aec.unwrapped.state())
        np.testing.assert_array_equal(xs, reference.x[row])


# --------------------------------------------------------------------------- refusals
@pytest.mark.parametrize("make", [
    lambda **kw: twolink_env.load("centralized", **kw),
    lambda **kw: gym_env.TwoLinkEnv(**kw),
    lambda **kw: gym_env.TwoLinkVectorEnv(2, **kw),
    lambda **kw: tpz.parallel_env(**kw),
], ids=["dm_env", "gym", "vector", "pettingzoo"])
@pytest.mark.parametrize("kwargs, message", [
    (dict(links=1), "links must be a whole number from 2 to 6, got 1"),
    (dict(links=7), "links must be a whole number from 2 to 6, got 7"),
    (dict(links=3, rule="straight"), "unknown link rule 'straight'"),
    (dict(links=3, x0=[0.0] * 4), r"x0 must have 6 components \[theta1, theta2, theta3"),
    (dict(links=3, x0="paper"), "two-link arm's"),
    (dict(links=3, x0="here"), r"x0 must be 'random', 'slow', 'mixed' or a state \(6,\)"),
    (dict(links=3, angle_noise=0.1), "angle_noise is a two-link option"),
    (dict(links=3, perturbation={"m2": 0.1}, speed_noise=0.1),
     "perturbation, speed_noise are two-link options"),
    (dict(links=4, challenge="easy"), "this arm has 4 links"),
    (dict(params=links_parameters(3), links=2), "params describe a 3-link arm, but links=2"),
    (dict(params=links_parameters(3), rule="copied"), "give either params or rule"),
])
def test_bad_options_refused(make, kwargs, message):
    with pytest.raises(ValueError, match=message):
        make(**kwargs)


def test_policy_of_another_number_of_links_refused(policy3):
    two = load_policy("decentralized")
    for task in twolink_env.TASKS:
        ts = twolink_env.load(task, links=3).reset()
        with pytest.raises(ValueError, match="policy decentralized is for a 2-link arm, "
                                             "the arm has 3 links"):
            twolink_env.policy_action(two, ts.observation)
        ts = twolink_env.load(task).reset()
        with pytest.raises(ValueError, match="is for a 3-link arm, the arm has 2 links"):
            twolink_env.policy_action(policy3, ts.observation)
    obs, _ = gym_env.TwoLinkEnv(links=3).reset(seed=0)
    with pytest.raises(ValueError, match="for a 2-link arm, the arm has 3 links"):
        gym_env.policy_action(two, obs)
    obs, _ = gym_env.TwoLinkEnv(links=3, observation="cos_sin").reset(seed=0)
    with pytest.raises(ValueError, match="for a 2-link arm, the arm has 3 links"):
        gym_env.policy_action(two, obs, features="cos_sin")
    obs, _ = tpz.parallel_env(links=4).reset(seed=0)
    with pytest.raises(ValueError, match="is for a 3-link arm, the arm has 4 links"):
        tpz.policy_actions(policy3, obs)


def test_bad_actions_and_wrappers_refused():
    env = gym_env.TwoLinkEnv(links=3)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(3,\) \[tau1, tau2, tau3\]"):
        env.step(np.zeros(2))
    vec = gym_env.TwoLinkVectorEnv(2, links=3, nthread=1)
    with pytest.raises(ValueError, match=r"one per arm \(2, 6\)"):
        vec.reset(options={"x0": np.zeros((3, 6))})
    with pytest.raises(ValueError, match="predicts the two-link arm; the wrapped "
                                         "environment's arm has 3 links"):
        CompensatedObservation(env)
    dm = twolink_env.load("decentralized", links=3)
    with pytest.raises(ValueError, match="decentralized_action is the two-link"):
        twolink_env.decentralized_action(None, None, dm.reset().observation)
    par = tpz.parallel_env(links=3)
    par.reset(seed=0)
    with pytest.raises(ValueError, match="missing: 'link3'"):
        par.step({"link1": np.zeros(1), "link2": np.zeros(1)})
    env.close()
    vec.close()
