"""The PettingZoo environments: PettingZoo's own API tests, the contracts of the dm_env
tests, and the trajectory held bit for bit against ``rollout`` and the dm_env task."""
from __future__ import annotations

import gc
import weakref
from pathlib import Path

import numpy as np
import pettingzoo
import pytest
from dm_control.utils.rewards import tolerance
from pettingzoo.test import api_test, parallel_api_test, parallel_seed_test, seed_test
from pettingzoo.utils import conversions

from twolink.arm import mjcf
from twolink.arm.parameters import PAPER_X0, REWARD_GOAL, TABLE_I
from twolink.arm.task import agent_reward, centralized_reward
from twolink.envs import dm as twolink_env
from twolink.envs import pettingzoo as tpz
from twolink.envs.core import OBSERVATION_NAMES, shaped_reward
from twolink.sim.challenges import Challenge
from twolink.sim.perturbations import ActuationDelay, ObservationDelay, perturbed
from twolink.sim.plants import MujocoPlant
from twolink.sim.rollout import rollout
from twolink.viz.render import Renderer

X0 = [0.5, -2.0, 1.0, 0.0]


def _drive(env, policy):
    """States, joint torques and rewards of one episode of a parallel env under a policy."""
    obs, _ = env.reset()
    xs, us, rs = [env.state()], [], []
    while env.agents:
        a = tpz.policy_actions(policy, obs)
        obs, rewards, _, _, _ = env.step(a)
        xs.append(env.state())
        us.append(np.concatenate([a[agent] for agent in tpz.AGENTS]))
        rs.append([rewards[agent] for agent in tpz.AGENTS])
    return np.array(xs), np.array(us), np.array(rs)


# --------------------------------------------------------------------------- API
def test_module_follows_pettingzoo_conventions():
    assert tpz.pettingzoo is pettingzoo and pettingzoo.__name__ == "pettingzoo"  # top level
    assert Path(pettingzoo.__file__).parent.name == "pettingzoo"
    par = tpz.parallel_env()
    assert isinstance(par, pettingzoo.ParallelEnv)
    aec = tpz.env()
    assert isinstance(aec, pettingzoo.AECEnv) and isinstance(aec.unwrapped, tpz.ParallelArm)
    assert isinstance(tpz.raw_env(), conversions.parallel_to_aec_wrapper)
    assert isinstance(conversions.aec_to_parallel(aec), tpz.ParallelArm)


def test_agents_one_per_joint():
    assert tpz.AGENTS == ("link1", "link2") and len(tpz.AGENTS) == len(mjcf.JOINTS)
    env = tpz.parallel_env()
    assert env.possible_agents == list(tpz.AGENTS) and env.agents == []
    assert [env.observation_space(a).shape for a in tpz.AGENTS] == [(3,), (2,)]
    assert [env.action_space(a).high.tolist() for a in tpz.AGENTS] == [[0.2], [0.1]]
    env = tpz.parallel_env(link1_tau2="previous")
    assert [env.observation_space(a).shape for a in tpz.AGENTS] == [(4,), (2,)]


_CONFIGS = [dict(), dict(x0="random", angle_noise=0.02, speed_noise=0.1, perturbation=0.2,
                         delay=1, reward="sum", link1_tau2="previous", time_limit=1.0)]


@pytest.mark.parametrize("kwargs", _CONFIGS)
def test_parallel_api_test(kwargs):
    parallel_api_test(tpz.parallel_env(**kwargs), num_cycles=200)


@pytest.mark.parametrize("kwargs", _CONFIGS)
def test_api_test_on_the_aec_form(kwargs):
    api_test(conversions.parallel_to_aec(tpz.parallel_env(**kwargs)), num_cycles=200)


def test_seed_tests():
    kwargs = dict(x0="random", angle_noise=0.05, perturbation=0.3, time_limit=1.0)
    seed_test(lambda: tpz.env(**kwargs), num_cycles=30)
    parallel_seed_test(lambda: tpz.parallel_env(**kwargs), num_cycles=30)


def test_deterministic_under_a_seed():
    kwargs = dict(x0="random", angle_noise=0.02, speed_noise=0.1, perturbation=0.2, delay=2)
    runs = []
    for seed in (7, 7, 8):
        env = tpz.parallel_env(**kwargs)
        obs, _ = env.reset(seed=seed)
        seen = [obs]
        for _ in range(20):
            obs, *_ = env.step({a: env.action_space(a).high * 0.5 for a in env.agents})
            seen.append(obs)
        runs.append((env.params, env.state(), seen))
        env.close()
    (p7, x7, o7), (q7, y7, s7), (p8, x8, _) = runs
    assert p7 == q7 and p7 != p8
    np.testing.assert_array_equal(x7, y7)
    assert not np.array_equal(x7, x8)
    for a, b in zip(o7, s7):
        for agent in tpz.AGENTS:
            np.testing.assert_array_equal(a[agent], b[agent])


def test_api_and_seed_tests_on_the_sequential_aec_form():
    """The AEC form of (18) (``link1_tau2='current'``), natively an AECEnv."""
    kwargs = dict(x0="random", angle_noise=0.02, delay=1, reward="centralized",
                  time_limit=1.0)
    api_test(tpz.env(link1_tau2="current", **kwargs), num_cycles=200)
    seed_test(lambda: tpz.env(link1_tau2="current", **kwargs), num_cycles=30)
    aec = tpz.env(link1_tau2="current")
    assert isinstance(aec.unwrapped, tpz.SequentialArm)
    assert aec.possible_agents == ["link2", "link1"]             # link2 acts first
    assert isinstance(tpz.raw_env(link1_tau2="current"), tpz.SequentialArm)


def test_unknown_reset_options_are_ignored_with_a_warning():
    env, plain = tpz.parallel_env(), tpz.parallel_env()
    with pytest.warns(UserWarning, match=r"ignoring unknown reset option\(s\) 'options'; "
                                         r"known: 'x0'"):
        obs, _ = env.reset(seed=0, options={"options": 1})
    expected, _ = plain.reset(seed=0)
    assert all(np.array_equal(obs[a], expected[a]) for a in obs)


def test_the_checkers_run_on_the_aec_env_users_get():
    api_test(tpz.env(), num_cycles=100)


# --------------------------------------------------------------------------- same numbers
@pytest.mark.parametrize("x0", ["paper", X0])
def test_trajectory_equals_rollout_and_the_dm_env_task(decentralized, x0):
    """The shipped policy through the PettingZoo env, the dm_env task and ``rollout`` on the
    MuJoCo plant: the same states, torques and rewards (17), bit for bit."""
    xs, us, rs = _drive(tpz.parallel_env(x0=x0), decentralized)
    start = np.array(PAPER_X0 if x0 == "paper" else x0)
    with MujocoPlant(nthread=1) as plant:
        traj = rollout(decentralized, plant, start)
    np.testing.assert_array_equal(xs, traj.x)
    np.testing.assert_array_equal(us, traj.u)
    np.testing.assert_array_equal(rs, traj.r_links)
    dm = twolink_env.load("decentralized", x0=x0)
    ts = dm.reset()
    dm_xs = [dm.physics.state()]
    while not ts.last():
        ts = dm.step(twolink_env.policy_action(decentralized, ts.observation))
        dm_xs.append(dm.physics.state())
    np.testing.assert_array_equal(xs, np.array(dm_xs))


def test_aec_form_retraces_the_parallel_env(decentralized):
    aec = tpz.env(x0=X0)
    aec.reset()
    xs, actions = [aec.unwrapped.state()], {}
    for agent in aec.agent_iter():
        _, _, terminated, truncated, _ = aec.last()
        if terminated or truncated:
            aec.step(None)
            continue
        if not actions:   # a new cycle: observations are those of the last parallel step
            actions = tpz.policy_actions(decentralized, {a: aec.observe(a) for a in tpz.AGENTS})
        aec.step(actions.pop(agent))
        if not actions:
            xs.append(aec.unwrapped.state())
    expected, _, _ = _drive(tpz.parallel_env(x0=X0), decentralized)
    np.testing.assert_array_equal(np.array(xs), expected)


def _own_action(agent, names, observation):
    """A policy agent's torque from one agent's own observation (components ``names``)."""
    seen = dict(zip(names, observation))
    return agent.act(np.array([seen[n] for n in agent.inputs]))


@pytest.mark.parametrize("x0", ["paper", X0])
def test_sequential_aec_form_is_the_papers_ordering(decentralized, x0):
    """With link1_tau2='current' each agent of the shipped policy acts on its own AEC
    observation alone (link1 reads tau2 from it, (18)) and retraces ``rollout``."""
    agents = {a.name: a for a in decentralized.agents}
    names = {"link2": OBSERVATION_NAMES["agent2"], "link1": OBSERVATION_NAMES["agent1"] + ("tau2",)}
    aec = tpz.env(link1_tau2="current", x0=x0)
    aec.reset()
    xs, us, tau = [aec.unwrapped.state()], [], {}
    for agent in aec.agent_iter():
        observation, _, terminated, truncated, _ = aec.last()
        if terminated or truncated:
            aec.step(None)
            continue
        tau[agent] = _own_action(agents[agent.replace("link", "agent")], names[agent], observation)
        if agent == "link1":
            assert observation[3] == tau["link2"][0]       # the tau2 of this very sample
        aec.step(tau[agent])
        if agent == "link1":
            xs.append(aec.unwrapped.state())
            us.append(np.concatenate([tau["link1"], tau["link2"]]))
    start = np.array(PAPER_X0 if x0 == "paper" else x0)
    with MujocoPlant(nthread=1) as plant:
        traj = rollout(decentralized, plant, start)
    np.testing.assert_array_equal(np.array(xs), traj.x)
    np.testing.assert_array_equal(np.array(us), traj.u)


def test_sequential_aec_form_refuses_bad_actions_turn_untouched():
    aec = tpz.env(link1_tau2="current", x0=X0)
    aec.reset()
    for agent in tpz.AGENTS:                                 # observations are copies
        aec.observe(agent)[:] = 99.0
        assert not np.any(aec.observe(agent) == 99.0)
    with pytest.raises(ValueError, match="action of link2 contains NaN"):
        aec.step(np.array([np.nan]))
    assert aec.agent_selection == "link2"
    aec.step(np.array([0.5]))                     # shown as commanded, applied clipped
    assert aec.agent_selection == "link1" and aec.observe("link1")[3] == 0.5
    with pytest.raises(ValueError, match=r"action of link1 must have shape \(1,\)"):
        aec.step(np.zeros(2))
    assert aec.agent_selection == "link1"
    np.testing.assert_array_equal(aec.unwrapped.state(), X0)  # nothing stepped
    with pytest.raises(ValueError, match="impossible in a parallel step"):
        tpz.parallel_env(link1_tau2="current")


def test_perturbed_noisy_delayed_env_equals_rollout_with_the_same_perturbations(decentralized):
    change = {"m2": 0.3, "b1": -0.4}
    env = tpz.parallel_env(perturbation=change, delay=2)
    xs, _, _ = _drive(env, decentralized)
    assert env.params == perturbed(TABLE_I, **change)
    with MujocoPlant(env.params, nthread=1) as plant:
        traj = rollout(ActuationDelay(decentralized, 2), plant, np.array(PAPER_X0))
    np.testing.assert_array_equal(xs, traj.x)
    np.testing.assert_array_equal(traj.u[:2], 0.0)   # nothing arrives for two periods


# --------------------------------------------------------------------------- contracts
@pytest.mark.parametrize("reward", tpz.REWARDS)
def test_rewards(reward):
    env = tpz.parallel_env(x0="random", reward=reward)
    env.reset(seed=4)
    for _ in range(30):
        _, rewards, *_ = env.step({a: np.zeros(1) for a in env.agents})
        x = env.state()
        own = [float(agent_reward(x, i)) for i in (1, 2)]
        team = float(shaped_reward(x))
        per_link = [0.0 if own[i] == REWARD_GOAL else min(
            tolerance(abs(x[i]), bounds=(0, np.radians(5)), margin=np.pi,
                      sigmoid="reciprocal", value_at_margin=0.1)
            * tolerance(abs(x[2 + i]), bounds=(0, 0.1), margin=2 * np.pi,
                        sigmoid="reciprocal", value_at_margin=0.1) - 1.0, -1e-12)
            for i in (0, 1)]
        expected = {"individual": own, "paper": own,
                    "centralized": [float(centralized_reward(x))] * 2,
                    "sum": [sum(own)] * 2, "shaped": per_link,
                    "shaped_team": [team] * 2,
                    "shaped_time": [p - (o != REWARD_GOAL) for p, o in zip(per_link, own)],
                    "shaped_team_time": [team - (not all(o == REWARD_GOAL for o in own))]
                    * 2}[reward]
        assert [rewards[a] for a in tpz.AGENTS] == expected
        assert all(type(r) is float for r in rewards.values())


def test_truncated_at_the_time_limit_never_terminated():
    env = tpz.parallel_env(time_limit=0.5)
    env.reset()
    for k in range(1, 11):
        _, _, terminations, truncations, _ = env.step({a: np.zeros(1) for a in env.agents})
        assert not any(terminations.values())
        assert all(truncations.values()) == (k == 10) and any(truncations.values()) == (k == 10)
    assert env.agents == []
    with pytest.raises(RuntimeError, match="call reset"):
        env.step({})
    assert tpz.parallel_env().reset()[0].keys() == set(tpz.AGENTS)


def test_link1_sees_link2s_previous_torque():
    env = tpz.parallel_env(link1_tau2="previous", x0=X0)
    obs, _ = env.reset()
    assert obs["link1"][3] == 0.0
    np.testing.assert_array_equal(obs["link1"][:3], [0.5, 1.0, -2.0])
    for tau2 in (0.05, -0.3, 0.02):
        obs, *_ = env.step({"link1": np.zeros(1), "link2": np.array([tau2])})
        assert obs["link1"][3] == tau2                 # as commanded (the plant clips it)
        np.testing.assert_array_equal(obs["link1"][:3], env.state()[[0, 2, 1]])


def test_observation_noise_spares_the_reward():
    env = tpz.parallel_env(x0=[0.0] * 4, angle_noise=0.5)
    obs, _ = env.reset(seed=0)
    assert obs["link2"][0] != 0.0 and obs["link2"][1] == 0.0
    _, rewards, *_ = env.step({a: np.zeros(1) for a in env.agents})
    assert set(rewards.values()) == {REWARD_GOAL}


def test_reset_x0_option_and_random_x0():
    env = tpz.parallel_env()
    obs, _ = env.reset(options={"x0": X0})
    np.testing.assert_array_equal(obs["link1"], [0.5, 1.0, -2.0])
    np.testing.assert_array_equal(obs["link2"], [-2.0, 0.0])
    np.testing.assert_array_equal(env.reset()[0]["link2"], [-3.0, 0.0])   # back to 'paper'
    env = tpz.parallel_env(x0="random")
    env.reset(seed=3)
    x = env.state()
    assert np.all(np.abs(x[:2]) <= np.pi) and np.all(x[2:] == 0.0)


def test_observations_do_not_alias_internal_memory():
    env = tpz.parallel_env(link1_tau2="previous")
    obs, _ = env.reset()
    before = env.state()
    for o in obs.values():
        o[:] = 99.0
    env.state()[:] = 99.0
    np.testing.assert_array_equal(env.state(), before)
    obs, *_ = env.step({a: np.zeros(1) for a in env.agents})
    assert not np.shares_memory(obs["link1"], obs["link2"])
    after = env.state()
    obs["link1"][:] = obs["link2"][:] = 99.0
    np.testing.assert_array_equal(env.state(), after)
    assert not np.any(env.step({a: np.zeros(1) for a in env.agents})[0]["link2"] == 99.0)


_GOOD = {"link1": np.array([0.1]), "link2": np.array([-0.05])}


@pytest.mark.parametrize("actions, message", [
    ({**_GOOD, "link1": np.zeros(2)}, r"action of link1 must have shape \(1,\)"),
    ({**_GOOD, "link2": 0.05}, r"action of link2 must have shape \(1,\).*shape \(\)"),
    ({**_GOOD, "link1": np.array([[0.1]])}, r"shape \(1, 1\)"),
    ({**_GOOD, "link1": np.array(["a"])}, "action of link1 must be real numbers"),
    ({**_GOOD, "link2": np.array([True])}, "action of link2 must be real numbers"),
    ({**_GOOD, "link2": np.array([1j])}, "action of link2 must be real numbers"),
    ({**_GOOD, "link2": np.array([np.nan])}, "action of link2 contains NaN"),
    ({**_GOOD, "link1": np.array([np.inf])}, "action of link1 contains NaN or infinite"),
    ({**_GOOD, "link3": np.zeros(1)}, "unknown: 'link3'"),
    ({"link1": np.zeros(1)}, "missing: 'link2'"),
    ([0.1, 0.2], "actions must be a dict"),
])
def test_bad_actions_refused_state_untouched(actions, message):
    env = tpz.parallel_env(x0="random", delay=1, angle_noise=0.1, link1_tau2="previous")
    reference = tpz.parallel_env(x0="random", delay=1, angle_noise=0.1, link1_tau2="previous")
    for e in (env, reference):
        e.reset(seed=1)
        e.step(_GOOD)
    with pytest.raises(ValueError, match=message):
        env.step(actions)
    np.testing.assert_array_equal(env.state(), reference.state())
    for _ in range(3):      # the delay line, noise stream and step count are untouched
        got, want = env.step(_GOOD), reference.step(_GOOD)
        np.testing.assert_array_equal(env.state(), reference.state())
        for agent in tpz.AGENTS:
            np.testing.assert_array_equal(got[0][agent], want[0][agent])
    assert env._k == reference._k == 4


@pytest.mark.parametrize("kwargs, message", [
    (dict(reward="team"), "reward must be one of 'paper', 'individual', 'centralized', 'sum', "
                           "'shaped', 'shaped_team'"),
    (dict(link1_tau2="current"), "impossible in a parallel step"),
    (dict(link1_tau2="yes"), "link1_tau2 must be one of"),
    (dict(actions="discrete"), "actions must be one of 'box', 'normalized'"),
    (dict(observation="pixels"), "observation must be one of 'state', 'cos_sin'"),
    (dict(observe="neighbors"), "observe must be one of 'neighbours', 'local', 'global'"),
    (dict(render_mode="human"), "render_mode must be one of 'rgb_array'"),
    (dict(time_limit=0.0), "time_limit must be a positive number"),
    (dict(time_limit=np.inf), "time_limit must be a positive number"),
    (dict(time_limit="5"), "time_limit must be a positive number"),
    (dict(x0="somewhere"), "x0 must be"),
    (dict(x0=[0.0, np.nan, 0.0, 0.0]), "NaN"),
    (dict(x0=[0.0, 0.0, 100.0, 0.0]), "speed of magnitude 100"),
    (dict(perturbation={"mass": 0.1}), "unknown parameter"),
    (dict(perturbation=1.5), r"\[0, 1\)"),
    (dict(angle_noise=-1.0), "non-negative"),
    (dict(delay=1.5), "whole number of samples"),
    (dict(delay=-1), "non-negative whole number"),
    (dict(delay=[1, 2]), "delay must be a whole number of sample periods"),
    (dict(speed_noise=np.ones(2)), "speed_noise must be one standard deviation"),
    (dict(params={"m1": 1.0}), "params must be ArmParameters"),
])
def test_bad_options_refused(kwargs, message):
    with pytest.raises(ValueError, match=message):
        tpz.parallel_env(**kwargs)


@pytest.mark.parametrize("seed, options, message, error", [
    (None, {"x0": "nowhere"}, "x0 must be", ValueError),
    (None, {"x0": [0.0, 0.0, 0.0]}, "4 components", ValueError),
    (None, "paper", "options must be a dict", ValueError),
    (-1, None, "seed must be a non-negative whole number", ValueError),
    (1.5, None, "seed must be an int or None, got 1.5", TypeError),
])
def test_bad_reset_refused_episode_untouched(seed, options, message, error):
    env = tpz.parallel_env(x0="random", angle_noise=0.1)
    env.reset(seed=2)
    env.step(_GOOD)
    before = env.state()
    with pytest.raises(error, match=message):
        env.reset(seed=seed, options=options)
    np.testing.assert_array_equal(env.state(), before)
    assert env.agents == list(tpz.AGENTS) and env._k == 1


def test_policy_actions_refuses_missing_observations(decentralized):
    with pytest.raises(ValueError, match="observations lack agent"):
        tpz.policy_actions(decentralized, {"link1": np.zeros(3)})
    with pytest.raises(ValueError, match="observation of link2 must be a vector"):
        tpz.policy_actions(decentralized, {"link1": np.zeros(3), "link2": np.zeros(1)})


def test_render_and_close_free_resources():
    env = tpz.parallel_env(render_mode="rgb_array")
    env.reset()
    frame = env.render()
    assert isinstance(env._renderer, Renderer)
    assert frame.shape == (240, 320, 3) and frame.dtype == np.uint8 and frame.std() > 10
    env.step({a: np.ones(1) for a in env.agents})
    assert not np.array_equal(env.render(), frame)        # the arm moved
    renderer, plant = weakref.ref(env._renderer), weakref.ref(env._plant)
    env.close()
    gc.collect()
    assert renderer() is None and plant() is None           # GL context and MuJoCo data freed
    assert env.agents == []
    with pytest.raises(RuntimeError, match="call reset"):
        env.step(_GOOD)
    env.reset()                                             # a closed env can start again
    with pytest.warns(UserWarning, match="without a render_mode"):
        assert tpz.parallel_env().render() is None          # no render_mode: no frame


# --------------------------------------------------------------------------- challenges
def test_challenge_deterministic_under_a_seed_and_a_new_plant_each_episode():
    runs = []
    for seed in (7, 7, 8):
        env = tpz.parallel_env(x0="random", challenge="hard")
        obs, _ = env.reset(seed=seed)
        seen = [obs]
        for _ in range(20):
            obs, *_ = env.step({a: env.action_space(a).high * 0.5 for a in env.agents})
            seen.append(obs)
        first = env.params
        env.reset()
        runs.append((first, env.params, env.state(), seen))
        env.close()
    (p7, n7, x7, o7), (q7, _, y7, s7), (p8, _, _, _) = runs
    assert p7 == q7 and p7 != p8 and p7 != n7
    assert p7.tau2_max == pytest.approx(0.8 * TABLE_I.tau2_max)
    np.testing.assert_array_equal(x7, y7)
    for a, b in zip(o7, s7):
        for agent in tpz.AGENTS:
            np.testing.assert_array_equal(a[agent], b[agent])


def test_challenge_delays_against_rollout(decentralized):
    """Torque one sample late, readings two samples late: the env's states equal a rollout
    with those delays on the episode's plant."""
    ch = Challenge("late", spread=0.1, action_delay=1, observation_delay=2)
    env = tpz.parallel_env(challenge=ch, time_limit=2.0)
    xs, _, _ = _drive(env, decentralized)
    late = ObservationDelay(2)
    with MujocoPlant(env.params, nthread=1) as plant:
        traj = rollout(ActuationDelay(decentralized, 1), plant, np.array(PAPER_X0),
                       duration=2.0, observe=lambda k, x: late(x))
    np.testing.assert_array_equal(xs, traj.x)
    assert np.all(traj.u[0] == 0.0) and np.any(traj.u[1] != 0.0)


def test_challenge_refused_beside_the_separate_options():
    with pytest.raises(ValueError, match="either challenge or delay"):
        tpz.parallel_env(challenge="medium", delay=1)
    with pytest.raises(ValueError, match="unknown challenge"):
        tpz.parallel_env(challenge=3)
