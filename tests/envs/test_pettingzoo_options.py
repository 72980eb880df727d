"""The PettingZoo env's learner options (reward, actions, observation, observe) on the
objects users get, and the batched multi-agent env against ParallelArm bit for bit."""
from __future__ import annotations

import itertools
import warnings

import numpy as np
import pytest
from pettingzoo.test import api_test, parallel_api_test, parallel_seed_test, seed_test

from twolink.arm.observations import features
from twolink.arm.parameters import GOAL_ANGLE, GOAL_SPEED, state_names
from twolink.arm.task import in_goal_band
from twolink.control.catalogue import load
from twolink.envs import pettingzoo as tpz
from twolink.envs.core import (
    AGENT_ACTION_OPTIONS,
    AGENT_REWARD_OPTIONS,
    OBSERVE_OPTIONS,
    observation_names,
    shaped_reward,
    shaped_time_reward,
)
from twolink.envs.gym import TwoLinkEnv
from twolink.envs.pettingzoo_batched import BatchedParallelArms, batched_parallel_env

COMBOS = list(itertools.product(AGENT_REWARD_OPTIONS, AGENT_ACTION_OPTIONS, OBSERVE_OPTIONS,
                                (2, 3), ("state", "cos_sin")))


@pytest.mark.parametrize("reward, actions, observe, links, observation", COMBOS)
def test_pettingzoo_checkers_pass_for_every_combination(reward, actions, observe, links,
                                                        observation):
    kw = dict(reward=reward, actions=actions, observe=observe, links=links,
              observation=observation)
    env = tpz.parallel_env(**kw)
    assert type(env) is tpz.ParallelArm
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")         # the checkers' "infinite bound" warnings
        parallel_api_test(env, num_cycles=60)
        parallel_seed_test(lambda: tpz.parallel_env(**kw), num_cycles=20)


@pytest.mark.parametrize("observe", OBSERVE_OPTIONS)
def test_the_sequential_aec_form_takes_the_options(observe):
    kw = dict(link1_tau2="current", links=3, actions="normalized", observe=observe,
              reward="shaped", observation="cos_sin")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        api_test(tpz.env(**kw), num_cycles=60)
        seed_test(lambda: tpz.env(**kw), num_cycles=20)


@pytest.mark.parametrize("links", [2, 3])
def test_what_each_observation_model_holds(links):
    envs = {o: tpz.parallel_env(links=links, observe=o, x0="random") for o in OBSERVE_OPTIONS}
    cos_sin = tpz.parallel_env(links=links, observe="global", observation="cos_sin",
                               x0="random")
    obs = {o: e.reset(seed=5)[0] for o, e in envs.items()}
    trig = cos_sin.reset(seed=5)[0]
    x = envs["local"].state()
    names = state_names(links)
    hop = observation_names(links)
    for i, a in enumerate(tpz.agents(links), 1):
        np.testing.assert_array_equal(obs["local"][a], x[[i - 1, links + i - 1]])
        np.testing.assert_array_equal(obs["global"][a], x)
        want = [x[names.index(c)] for c in hop[f"agent{i}"]]      # today's default
        np.testing.assert_array_equal(obs["neighbours"][a], want)
        np.testing.assert_array_equal(trig[a], features(x, "cos_sin"))
        assert envs["local"].observation_space(a).shape == (2,)
        assert envs["global"].observation_space(a).shape == (2 * links,)
        assert cos_sin.observation_space(a).shape == (3 * links,)
    gym = TwoLinkEnv(links=links, observation="cos_sin", x0=x)
    np.testing.assert_array_equal(gym.reset()[0], trig["link1"])


def test_neighbours_cos_sin_replaces_each_angle_in_place():
    env = tpz.parallel_env(observation="cos_sin", x0=[0.3, -1.2, 0.5, -0.25])
    obs, _ = env.reset()
    np.testing.assert_allclose(obs["link1"], [np.cos(0.3), np.sin(0.3), 0.5, np.cos(-1.2),
                                              np.sin(-1.2)])
    np.testing.assert_allclose(obs["link2"], [np.cos(-1.2), np.sin(-1.2), -0.25])
    high = env.observation_space("link1").high
    np.testing.assert_array_equal(high[[0, 1, 3, 4]], 1.0)


def test_default_options_are_todays_env():
    default, explicit = tpz.parallel_env(), tpz.parallel_env(
        reward="individual", actions="box", observation="state", observe="neighbours")
    a, b = default.reset(seed=1)[0], explicit.reset(seed=1)[0]
    assert all(np.array_equal(a[g], b[g]) for g in a)
    for _ in range(20):
        step = {g: np.array([0.1]) for g in default.agents}
        (oa, ra, *_), (ob, rb, *_) = default.step(step), explicit.step(step)
        assert ra == rb and all(np.array_equal(oa[g], ob[g]) for g in oa)
    assert default.observation_space("link1").shape == (3,)


def test_normalized_actions_scale_to_the_torque_limits():
    box, unit = tpz.parallel_env(), tpz.parallel_env(actions="normalized")
    assert unit.action_space("link1").dtype == np.float32
    assert (unit.action_space("link2").low, unit.action_space("link2").high) == (-1.0, 1.0)
    box.reset(seed=0)
    unit.reset(seed=0)
    tau_max = box.params.tau_max
    for k in range(30):
        u = np.array([0.5, -1.0]) if k < 15 else np.array([3.0, -7.0])  # then clipped to +-1
        box.step({"link1": np.array([np.clip(u[0], -1, 1) * tau_max[0]]),
                  "link2": np.array([np.clip(u[1], -1, 1) * tau_max[1]])})
        unit.step({"link1": np.float32([u[0]]), "link2": np.float32([u[1]])})
        np.testing.assert_array_equal(box.state(), unit.state())


@pytest.mark.parametrize("links", [2, 3])
def test_shaped_rewards_per_link_and_for_the_team(links):
    envs = [tpz.parallel_env(links=links, reward=r, x0="random", time_limit=8.0)
            for r in ("shaped", "shaped_team", "shaped_time", "shaped_team_time")]
    per, team, per_time, team_time = envs
    for env in envs:
        env.reset(seed=3)
    pd = load("pd" if links == 2 else "pd_3link_tapered")
    seen_goal = False
    for k in range(120):
        # The tuned per-joint PD brings the links into their bands one by one.
        tau = pd(per.state()[None])[0]
        step = {a: tau[i:i + 1] for i, a in enumerate(per.agents)}
        r, rt, r_time, rt_time = (env.step(step)[1] for env in envs)
        x = per.state()
        for i, a in enumerate(per.possible_agents):
            in_band = abs(x[i]) <= GOAL_ANGLE and abs(x[links + i]) <= GOAL_SPEED
            assert (r[a] == 0.0) == in_band and -1.0 <= r[a] <= 0.0
            seen_goal |= in_band
            assert rt[a] == float(shaped_reward(x))
            # the minimum-time variants: one less outside the link's own band, the arm's
            assert r_time[a] == r[a] - (not in_band)
            assert rt_time[a] == float(shaped_time_reward(x))
            assert rt_time[a] == rt[a] - (not in_goal_band(x))
    assert seen_goal


# --------------------------------------------------------------------------- batched
BATCHED_CASES = [
    dict(),
    dict(links=3, reward="shaped", actions="normalized", observation="cos_sin",
         observe="global", link1_tau2="previous", time_limit=0.6),
    dict(links=3, observe="local", reward="shaped_team", rule="copied", time_limit=0.5),
    dict(links=3, observe="neighbours", reward="shaped_team_time", time_limit=0.5),
    dict(challenge="hard", time_limit=0.5, reward="sum"),
    dict(perturbation=0.3, angle_noise=0.01, delay=1, time_limit=0.4, x0="random",
         link1_tau2="previous"),
]


@pytest.mark.parametrize("kw", BATCHED_CASES)
def test_batched_arm_i_is_a_parallel_arm_seeded_s_plus_i(kw):
    arms, seed = 3, 40
    env = batched_parallel_env(arms, **kw)
    singles = [tpz.parallel_env(**kw) for _ in range(arms)]
    obs, infos = env.reset(seed=seed)
    assert infos == {a: {} for a in env.possible_agents}
    want = [e.reset(seed=seed + i)[0] for i, e in enumerate(singles)]
    rng = np.random.default_rng(0)
    episodes = 0
    for _ in range(30):
        for i in range(arms):
            for a in env.agents:
                np.testing.assert_array_equal(obs[a][i], want[i][a])
                assert obs[a].shape == (arms,) + env.observation_space(a).shape
        # Beyond the action space too: box torques clipped by each arm's own plant.
        acts = {a: (1.5 * rng.uniform(-1, 1, (arms, 1)) * env.action_space(a).high)
                .astype(env.action_space(a).dtype) for a in env.agents}
        obs, rewards, terms, truncs, infos = env.step(acts)
        for i, e in enumerate(singles):
            o, r, t, tr, _ = e.step({a: acts[a][i] for a in env.agents})
            np.testing.assert_array_equal(infos["link1"]["final_state"][i], e.state())
            for a in env.agents:
                assert rewards[a][i] == r[a] and truncs[a][i] == tr[a] and not terms[a][i]
                np.testing.assert_array_equal(infos[a]["final_observation"][i], o[a])
            if tr["link1"]:
                episodes += 1
                want[i] = e.reset()[0]          # no seed: the arm's generator goes on
            else:
                want[i] = o
    assert episodes >= arms * (2 if "time_limit" in kw else 0)
    env.close()


def test_batched_autoreset_infos_and_success():
    env = batched_parallel_env(2, x0=[0.02, 0.0, 0.0, 0.0], time_limit=1.5)
    obs, _ = env.reset(seed=0)
    for k in range(30):
        obs, rewards, terms, truncs, infos = env.step(
            {"link1": np.zeros((2, 1)), "link2": np.zeros(2)})
    assert truncs["link2"].tolist() == [True, True]
    assert infos["link1"]["is_success"].tolist() == [True, True]   # resting in the band
    np.testing.assert_array_equal(obs["link2"], [[0.0, 0.0]] * 2)  # the next episode's x0
    assert rewards["link1"].shape == (2,) and rewards["link1"].dtype == np.float64
    assert isinstance(env, BatchedParallelArms) and env.state().shape == (2, 4)


def test_batched_reset_options_and_seeds():
    env = batched_parallel_env(2, links=3)
    x0 = np.array([[0.1, 0.2, 0.3, 0, 0, 0], [-0.1, -0.2, -0.3, 0, 0, 0]])
    obs, _ = env.reset(options={"x0": x0})
    np.testing.assert_array_equal(env.state(), x0)
    np.testing.assert_array_equal(obs["link3"], x0[:, [2, 5]])
    a = env.reset(seed=7)[0]["link1"]
    b = env.reset(seed=7)[0]["link1"]
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a[0], a[1])      # arm 1 draws from seed 8


@pytest.mark.parametrize("actions, message", [
    ([0.0, 0.0], "actions must be a dict"),
    ({"link1": np.zeros((3, 1))}, "missing: 'link2'"),
    ({"link1": np.zeros((3, 1)), "link2": np.zeros((3, 1)), "link9": 0}, "unknown: 'link9'"),
    ({"link1": np.zeros((2, 1)), "link2": np.zeros((3, 1))},
     r"actions of link1 must have shape \(3, 1\)"),
    ({"link1": np.zeros((3, 1)), "link2": np.full(3, np.nan)}, "link2 contain NaN"),
    ({"link1": np.array(["a"] * 3), "link2": np.zeros(3)}, "link1 must be real numbers"),
])
def test_batched_bad_actions_refused_arms_untouched(actions, message):
    env = batched_parallel_env(3)
    env.reset(seed=1)
    before = env.state()
    with pytest.raises(ValueError, match=message):
        env.step(actions)
    np.testing.assert_array_equal(env.state(), before)


@pytest.mark.parametrize("num_arms, kw, error, message", [
    (0, {}, ValueError, "num_arms"),
    (10**6, {}, ValueError, "num_arms"),
    (2, dict(observe="everything"), ValueError, "observe must be one of"),
    (2, dict(render_mode="rgb_array"), TypeError, "render_mode"),
])
def test_batched_bad_options_refused(num_arms, kw, error, message):
    with pytest.raises(error, match=message):
        batched_parallel_env(num_arms, **kw)


def test_batched_needs_a_reset_and_closes():
    env = batched_parallel_env(2)
    with pytest.raises(RuntimeError, match="call reset"):
        env.step({"link1": np.zeros(2), "link2": np.zeros(2)})
    with pytest.raises(ValueError, match="seed"):
        env.reset(seed=-1)
    env.close()
    env.close()
    with pytest.raises(RuntimeError, match="closed"):
        env.reset(seed=0)
