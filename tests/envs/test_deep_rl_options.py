"""What deep RL needs from the environments: the shaped reward, normalized actions,
``is_success`` at the truncation step, autoreset steps that are never goal rewards, and
observation spaces that hold every observation, for every kind of environment."""
from __future__ import annotations

import math

import gymnasium
import numpy as np
import pytest

pytest.importorskip("dm_control")      # the shaped reward's tolerance; twolink.envs.dm
from dm_control.utils.rewards import tolerance  # noqa: E402

from twolink.arm.parameters import GOAL_ANGLE, GOAL_SPEED, REWARD_OTHER, TABLE_I  # noqa: E402
from twolink.arm.task import centralized_reward, in_goal_band  # noqa: E402
from twolink.envs import core  # noqa: E402
from twolink.envs import dm  # noqa: E402
from twolink.envs import gym as gym_env  # noqa: E402
from twolink.envs import pettingzoo as tpz  # noqa: E402
from twolink.sim.challenges import Challenge  # noqa: E402
from twolink.sim.metrics import evaluation_set, success  # noqa: E402
from twolink.sim.plants import MujocoPlant  # noqa: E402
from twolink.sim.rollout import rollout  # noqa: E402

TWO_PI = 2 * math.pi
FAULTY = Challenge("faulty", spread=0.2, action_delay=1, observation_delay=2, dropout=0.3,
                   stuck=0.1)      # faults and delays, no Gaussian noise: bounds hold


# --------------------------------------------------------------------------- shaped reward
def _band_states(rng, count, links=2, inside=True):
    x = np.concatenate([rng.uniform(-GOAL_ANGLE, GOAL_ANGLE, (count, links)),
                        rng.uniform(-GOAL_SPEED, GOAL_SPEED, (count, links))], -1)
    if not inside:
        k = rng.integers(0, 2 * links, count)
        edge = np.where(k < links, GOAL_ANGLE, GOAL_SPEED)
        x[np.arange(count), k] = rng.choice([-1, 1], count) * np.nextafter(edge, np.inf)
    return x


@pytest.mark.parametrize("links", [2, 4])
def test_shaped_reward_is_zero_exactly_in_the_band_and_negative_elsewhere(rng, links):
    inside = _band_states(rng, 500, links)
    assert np.all(core.shaped_reward(inside) == 0.0)
    edge = _band_states(rng, 500, links, inside=False)          # one ulp outside
    assert not in_goal_band(edge).any()
    assert np.all(core.shaped_reward(edge) < 0)
    far = np.concatenate([rng.uniform(-np.pi, np.pi, (2000, links)),
                          rng.uniform(-TWO_PI, TWO_PI, (2000, links))], -1)
    r = core.shaped_reward(far)
    assert np.all((r >= -1) & (r <= 0))
    assert np.array_equal(r == 0, in_goal_band(far))


def test_shaped_reward_is_the_stated_formula(rng):
    """r = mean_i tol(|theta_i|, 5 deg, pi) * tol(|dtheta_i|, 0.1, 2 pi) - 1 (reciprocal)."""
    x = np.concatenate([rng.uniform(-np.pi, np.pi, (300, 2)),
                        rng.uniform(-TWO_PI, TWO_PI, (300, 2))], -1)
    kw = dict(sigmoid="reciprocal", value_at_margin=0.1)
    want = np.mean([tolerance(np.abs(x[:, i]), bounds=(0, GOAL_ANGLE), margin=np.pi, **kw)
                    * tolerance(np.abs(x[:, 2 + i]), bounds=(0, GOAL_SPEED), margin=TWO_PI,
                                **kw) for i in range(2)], 0) - 1
    np.testing.assert_allclose(core.shaped_reward(x), want, rtol=0, atol=1e-12)
    by_hand = lambda v, b, m: np.where(v <= b, 1.0, 1 / (1 + 9 * (v - b) / m))  # noqa: E731
    theta, speed = np.array([1.0, 0.0]), np.array([0.0, 2.0])
    r = (by_hand(1.0, GOAL_ANGLE, np.pi) * 1 + 1 * by_hand(2.0, GOAL_SPEED, TWO_PI)) / 2 - 1
    assert core.shaped_reward(np.concatenate([theta, speed])) == pytest.approx(r, abs=1e-15)


def test_shaped_time_reward_is_the_shaped_reward_less_one_outside_the_band(rng):
    far = np.concatenate([rng.uniform(-np.pi, np.pi, (1000, 2)),
                          rng.uniform(-TWO_PI, TWO_PI, (1000, 2))], -1)
    x = np.concatenate([far, _band_states(rng, 300), _band_states(rng, 300, inside=False)])
    r, shaped = core.shaped_time_reward(x), core.shaped_reward(x)
    out = ~in_goal_band(x)
    assert out.sum() == 1300
    np.testing.assert_array_equal(r[~out], 0.0)
    np.testing.assert_array_equal(r[out], shaped[out] - core.TIME_PENALTY)
    assert np.all((r[out] >= -2) & (r[out] < -1))
    # It is (15) scaled to one per sample outside the band, plus the shaped reward.
    np.testing.assert_allclose(r, shaped + core.TIME_PENALTY * centralized_reward(x)
                               / -REWARD_OTHER, rtol=0, atol=1e-15)
    env = gym_env.TwoLinkEnv(x0="random", reward="shaped_time")
    env.reset(seed=2)
    step = env.step(np.array([1.0, -1.0]))
    assert step[1] == float(core.shaped_time_reward(env.state)) < -1


def test_reward_option_default_is_paper_and_shaped_reads_the_true_state():
    paper, shaped = (gym_env.TwoLinkEnv(x0="random", angle_noise=0.05, reward=r)
                     for r in ("paper", "shaped"))
    assert gym_env.TwoLinkEnv()._arms.reward == "paper"
    for env in (paper, shaped):
        env.reset(seed=4)
    for k in range(20):
        a = np.array([1.0, -1.0]) * (k % 3 - 1)
        r_paper, r_shaped = paper.step(a)[1], shaped.step(a)[1]
        assert r_paper == float(centralized_reward(paper.state))
        assert r_shaped == float(core.shaped_reward(shaped.state))
        np.testing.assert_array_equal(paper.state, shaped.state)
    with pytest.raises(ValueError, match="reward"):
        gym_env.TwoLinkEnv(reward="dense")


# --------------------------------------------------------------------------- actions
def test_normalized_actions_scale_to_the_torque_limits(rng):
    norm = gym_env.TwoLinkEnv(actions="normalized", x0="random")
    box = gym_env.TwoLinkEnv(x0="random")
    space = norm.action_space
    assert (space.dtype, space.shape) == (np.float32, (2,))
    assert np.all(space.low == -1) and np.all(space.high == 1)
    norm.reset(seed=1), box.reset(seed=1)
    for _ in range(15):
        a = rng.uniform(-1.3, 1.3, 2).astype(np.float32)         # beyond +-1: clipped
        o1, r1, *_ = norm.step(a)
        o2, r2, *_ = box.step(np.clip(a.astype(np.float64), -1, 1) * TABLE_I.tau_max)
        np.testing.assert_array_equal(o1, o2)
        assert r1 == r2
    with pytest.raises(ValueError, match="NaN"):
        norm.step(np.array([np.nan, 0], dtype=np.float32))
    vec = gym_env.TwoLinkVectorEnv(3, actions="normalized", nthread=1)
    assert vec.single_action_space == space
    vec.reset(seed=0)
    vec.step(vec.action_space.sample())
    vec.close()


# --------------------------------------------------------------------------- is_success
def _episode_successes(time_limit):
    """is_success of the vector env's truncation step for policy (16) from the 65 states."""
    from twolink.policy.fuzzy_policy import load_policy

    policy = load_policy("centralized")
    x0 = evaluation_set()
    vec = gym_env.TwoLinkVectorEnv(len(x0), time_limit=time_limit, nthread=2)
    obs, _ = vec.reset(seed=0, options={"x0": x0})
    while True:
        obs, _, _, truncated, infos = vec.step(gym_env.policy_action(policy, obs))
        if truncated.any():
            assert truncated.all()
            np.testing.assert_array_equal(infos["_is_success"], truncated)
            vec.close()
            ref = rollout(policy, MujocoPlant(), x0, duration=time_limit)
            return infos["is_success"], success(ref)


@pytest.mark.parametrize("time_limit", [5.0, 2.0])
def test_is_success_is_the_success_rule_on_the_rollout(time_limit):
    got, want = _episode_successes(time_limit)
    np.testing.assert_array_equal(got, want)
    assert want.any() and (time_limit == 5.0 or not want.all())


def test_single_env_reports_is_success_at_the_truncation_step_only():
    env = gymnasium.make(gym_env.ENV_ID, x0=np.zeros(4), time_limit=1.5)
    env.reset(seed=0)
    infos = []
    truncated = False
    while not truncated:
        _, _, _, truncated, info = env.step(np.zeros(2))
        infos.append(info)
    assert infos[:-1] == [{}] * (len(infos) - 1)
    assert infos[-1] == {"is_success": True}           # at rest at the origin throughout
    env = gym_env.TwoLinkEnv(x0=np.zeros(4), time_limit=0.5)    # shorter than the 1 s margin
    env.reset()
    for _ in range(9):
        env.step(np.zeros(2))
    assert env.step(np.zeros(2))[4] == {"is_success": False}


# --------------------------------------------------------------------------- autoreset
@pytest.mark.parametrize("reward, floor", [("paper", -0.5), ("shaped", -1.0),
                                           ("shaped_time", -2.0)])
def test_autoreset_steps_return_the_floor_never_a_goal_reward(reward, floor):
    """At rest at the origin every real step earns the goal reward 0; the step after a
    truncation (next-step autoreset) returns the floor and is marked in the infos."""
    vec = gym_env.TwoLinkVectorEnv(2, x0=np.zeros(4), time_limit=0.2, reward=reward,
                                   nthread=1)
    vec.reset(seed=0)
    seen = []
    for _ in range(10):
        obs, r, term, trunc, infos = vec.step(np.zeros((2, 2)))
        seen.append((r.copy(), trunc.copy(), infos.get("autoreset", np.zeros(2, bool))))
    for k, (r, trunc, auto) in enumerate(seen):
        reset_step = k % 5 == 4
        assert auto.tolist() == [reset_step] * 2
        assert r.tolist() == [floor if reset_step else 0.0] * 2
        assert trunc.tolist() == [k % 5 == 3] * 2
    vec.close()


# --------------------------------------------------------------------------- x0
def test_x0_angles_are_wrapped_and_speeds_beyond_the_limit_refused():
    x0 = [TWO_PI + 1.0, -3 * np.pi - 0.5, TWO_PI, -TWO_PI]
    want = np.array([1.0, np.pi - 0.5, TWO_PI, -TWO_PI])
    obs, _ = gym_env.TwoLinkEnv(x0=x0).reset()
    np.testing.assert_allclose(obs, want, atol=1e-12)
    assert gym_env.TwoLinkEnv().observation_space.contains(obs)
    obs, _ = gym_env.TwoLinkEnv().reset(options={"x0": x0})
    np.testing.assert_allclose(obs, want, atol=1e-12)
    assert gym_env.TwoLinkEnv().reset()[0].tolist() == [-1.0, -3.0, 0.0, 0.0]  # bit for bit
    np.testing.assert_allclose(dm.load("centralized", x0=x0).reset().observation["state"],
                               want, atol=1e-12)
    par = tpz.parallel_env(x0=x0)
    par.reset()
    np.testing.assert_allclose(par.state(), want, atol=1e-12)
    bad = [0.0, 0.0, 7.0, 0.0]
    for make in (lambda: gym_env.TwoLinkEnv(x0=bad),
                 lambda: gym_env.TwoLinkVectorEnv(2, x0=bad),
                 lambda: gym_env.TwoLinkEnv().reset(options={"x0": bad}),
                 lambda: gym_env.TwoLinkVectorEnv(2).reset(options={"x0": np.array([bad] * 2)}),
                 lambda: dm.load("centralized", x0=bad),
                 lambda: dm.load("centralized", x0=[0, 0, 2.0, 0], speed_max=1.5),
                 lambda: tpz.parallel_env(x0=bad)):
        with pytest.raises(ValueError, match=r"^x0 has a speed of magnitude \d.* speed limit"):
            make()


# --------------------------------------------------------------------------- bounds
def _noisy(kwargs) -> bool:
    """Whether the options give observation noise (the levels all have some)."""
    return bool(kwargs.get("angle_noise") or kwargs.get("speed_noise")) or \
        kwargs.get("challenge") in ("easy", "medium", "hard")


def _bang_bang(rng, n):
    return rng.choice([-1.0, 0.0, 1.0], n)


GYM_KINDS = [dict(), dict(observation="cos_sin"), dict(actions="normalized"),
             dict(actions="discrete"), dict(perturbation=0.3), dict(challenge=FAULTY),
             dict(perturbation={"m2": 0.2, "dtheta2_max": 0.5}),
             dict(links=3), dict(links=3, observation="cos_sin"),
             dict(angle_noise=0.05, speed_noise=0.1),
             dict(observation="cos_sin", speed_noise=0.1), dict(challenge="hard")]


def _gym_action(space, rng, scale):
    if isinstance(space, gymnasium.spaces.Discrete):
        return int(rng.integers(space.n))
    return (_bang_bang(rng, space.shape[0]) * scale).astype(space.dtype)


@pytest.mark.parametrize("kwargs", GYM_KINDS, ids=lambda k: ",".join(map(str, k)) or "default")
def test_gymnasium_spaces_hold_every_observation(kwargs, rng):
    """Random bang-bang episodes from random and extreme x0: every observation (first,
    autoreset and truncation ones too) lies in the declared space; noiseless spaces are
    bounded (angles [-pi, pi], speeds +-speed_max), and an x0 at the speed limit is in."""
    env = gym_env.TwoLinkEnv(x0="random", time_limit=3.0, **kwargs)
    vec = gym_env.TwoLinkVectorEnv(3, x0="random", time_limit=3.0, nthread=1, **kwargs)
    space, n = env.observation_space, env.links
    noisy = _noisy(kwargs)
    assert np.all(np.isfinite(space.high)) != noisy
    scale = 1.0 if env._arms.actions == "normalized" else env._arms.params.tau_max
    peak = 0.0
    extreme = np.concatenate([np.full(n, -np.pi), np.array(env._arms.speed_max)])
    for options in ({}, {"x0": extreme}):
        obs, _ = env.reset(seed=3, options=options)
        assert space.contains(obs), obs
        peak = max(peak, np.abs(env.state[n:]).max())
        done = False
        while not done:
            obs, _, _, done, _ = env.step(_gym_action(env.action_space, rng, scale))
            assert space.contains(obs), obs
            peak = max(peak, np.abs(env.state[n:]).max())
    obs, _ = vec.reset(seed=5)
    for _ in range(130):                    # across a next-step autoreset
        assert vec.observation_space.contains(obs), obs
        a = np.stack([_gym_action(vec.single_action_space, rng, scale) for _ in range(3)])
        obs = vec.step(a)[0]
    if not noisy:
        assert peak == np.max(env._arms.speed_max)        # the bound is tight
    env.close(), vec.close()


@pytest.mark.parametrize("task", ["centralized", "decentralized"])
@pytest.mark.parametrize("kwargs", [dict(), dict(links=3), dict(speed_max=3.0),
                                    dict(perturbation=0.2), dict(challenge=FAULTY),
                                    dict(angle_noise=0.02), dict(challenge="easy")],
                         ids=lambda k: ",".join(map(str, k)) or "default")
def test_dm_env_specs_hold_every_observation(task, kwargs, rng):
    env = dm.load(task, seed=2, x0="random", time_limit=3.0, **kwargs)
    spec = env.observation_spec()
    noisy = _noisy(kwargs)
    from dm_env import specs
    assert all(isinstance(s, specs.BoundedArray) != noisy for s in spec.values())
    n = env.physics.links
    tau = env.action_spec().maximum
    for _ in range(2):
        ts = env.reset()
        while True:
            for key, s in spec.items():
                s.validate(ts.observation[key])
                if isinstance(s, specs.BoundedArray):
                    assert np.all(ts.observation[key] >= s.minimum)
                    assert np.all(ts.observation[key] <= s.maximum)
            if ts.last():
                break
            ts = env.step(_bang_bang(rng, n) * tau)
    if not noisy:        # the outermost speed's bound: the plant's limit (speed_max)
        speed = env.task.params.speed_max
        assert spec["state" if task == "centralized" else f"agent{n}"].maximum[-1] == speed[-1]


@pytest.mark.parametrize("kwargs", [dict(), dict(link1_tau2="previous"), dict(links=3),
                                    dict(perturbation=0.2), dict(challenge=FAULTY),
                                    dict(angle_noise=0.02, speed_noise=0.1),
                                    dict(link1_tau2="current")],
                         ids=lambda k: ",".join(map(str, k)) or "default")
def test_pettingzoo_spaces_hold_every_observation(kwargs, rng):
    aec = kwargs.get("link1_tau2") == "current"
    env = (tpz.raw_env if aec else tpz.parallel_env)(x0="random", time_limit=2.0, **kwargs)
    noisy = _noisy(kwargs)
    names = list(env.possible_agents)
    for a in names:
        high = env.observation_space(a).high
        state_part = high[:len(high) - (1 if (aec or kwargs.get("link1_tau2") == "previous")
                                          and a != names[0 if aec else -1] else 0)]
        assert np.all(np.isfinite(state_part)) != noisy
    assert np.all(np.isfinite(env.state_space.high))
    for seed in (1, 2):
        if aec:
            env.reset(seed=seed)
            for a in env.agent_iter():
                obs, _, term, trunc, _ = env.last()
                assert env.observation_space(a).contains(obs), (a, obs)
                assert env.state_space.contains(env.state())
                tau = env.action_space(a).high * _bang_bang(rng, 1)
                env.step(None if term or trunc else tau)
            continue
        obs, _ = env.reset(seed=seed)
        while env.agents:
            for a, o in obs.items():
                assert env.observation_space(a).contains(o), (a, o)
            assert env.state_space.contains(env.state())
            actions = {a: env.action_space(a).high * _bang_bang(rng, 1) for a in env.agents}
            obs = env.step(actions)[0]
    env.close()


def test_the_same_bounds_in_every_api():
    """Angles [-pi, pi] and speeds +-speed_max, the same numbers in all three APIs."""
    want = np.array([np.pi, np.pi, TWO_PI, TWO_PI])
    np.testing.assert_array_equal(gym_env.TwoLinkEnv().observation_space.high, want)
    np.testing.assert_array_equal(
        dm.load("centralized").observation_spec()["state"].maximum, want)
    np.testing.assert_array_equal(tpz.parallel_env().state_space.high, want)
    np.testing.assert_array_equal(tpz.parallel_env().observation_space("link1").high,
                                  want[[0, 2, 1]])
