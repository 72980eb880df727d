"""Stable-Baselines3 on the arm: SB3's checker on what users get, the SB3 VecEnv over the
batched MuJoCo env against single environments, and a few learning steps of PPO and SAC
under VecCheckNan. Skipped where SB3 is not installed (``pip install 'twolink[rl]'``)."""
from __future__ import annotations

import subprocess
import sys
import warnings

import gymnasium
import numpy as np
import pytest

from twolink.envs import gym as gym_env

sb3 = pytest.importorskip("stable_baselines3")
from stable_baselines3.common.env_checker import check_env  # noqa: E402
from stable_baselines3.common.vec_env import VecCheckNan, VecMonitor  # noqa: E402

from twolink.envs import sb3 as tsb3  # noqa: E402


def _check(env, **kwargs):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env, **kwargs)
    return [str(w.message) for w in caught]


def test_sb3_checker_passes_on_what_users_get_with_rendering():
    """check_env on gymnasium.make's object (its wrappers on), rendering included."""
    env = gymnasium.make(gym_env.ENV_ID, render_mode="rgb_array")
    try:
        env.reset(seed=0)
        env.render()
    except Exception as exc:                          # no EGL on this machine
        env.close()
        pytest.skip(str(exc))
    messages = _check(env, skip_render_check=False)
    # The default Box is the paper's torques (float64, +-tau_max): SB3 only advises.
    assert all("action space" in m or "dtype float64" in m for m in messages), messages
    env.close()


@pytest.mark.parametrize("kwargs", [dict(), dict(observation="cos_sin", reward="shaped"),
                                    dict(x0="random", challenge="medium")])
def test_sb3_checker_has_no_action_space_warning_on_normalized_actions(kwargs):
    env = gymnasium.make(gym_env.ENV_ID, actions="normalized", **kwargs)
    messages = _check(env, skip_render_check=True)
    assert not [m for m in messages if "action" in m.lower()], messages
    env.close()
    assert _check(gymnasium.make(gym_env.DISCRETE_ID), skip_render_check=True) == []


def _single_episodes(kwargs, seed, n, steps):
    """Per arm i, the observations, rewards and final infos of TwoLinkEnv seeded s + i."""
    out = []
    for i in range(n):
        env = gym_env.TwoLinkEnv(**kwargs)
        obs, _ = env.reset(seed=seed + i)
        rows = []
        for k in range(steps):
            a = _actions(k, n, kwargs)[i]
            nxt, r, _, trunc, info = env.step(a)
            if trunc:
                first, _ = env.reset()
                rows.append((first, r, True, nxt, info["is_success"]))
            else:
                rows.append((nxt, r, False, None, None))
        out.append(rows)
        env.close()
    return out


def _actions(k, n, kwargs):
    rng = np.random.default_rng(k)
    if kwargs.get("actions") == "discrete":
        return rng.integers(0, 9, n)
    return rng.uniform(-1, 1, (n, 2)).astype(np.float32) * (
        1.0 if kwargs.get("actions") == "normalized" else 0.5)


@pytest.mark.parametrize("kwargs", [
    dict(x0="random", actions="normalized", reward="shaped", time_limit=0.4),
    dict(x0="random", actions="discrete", observation="cos_sin", time_limit=0.3,
         perturbation=0.2, angle_noise=0.01),
    dict(x0="random", challenge="hard", time_limit=0.35),
    dict(x0=np.zeros(4), time_limit=1.2)], ids=["normalized", "discrete", "hard", "rest"])
def test_vec_env_equals_single_envs_with_same_step_autoreset(kwargs):
    n, seed, steps = 3, 21, 30
    vec = tsb3.vec_env(n, nthread=2, **kwargs)
    assert vec.observation_space == gym_env.TwoLinkEnv(**kwargs).observation_space
    assert vec.action_space == gym_env.TwoLinkEnv(**kwargs).action_space
    assert vec.seed(seed) == [seed + i for i in range(n)]
    obs = vec.reset()
    want = _single_episodes(kwargs, seed, n, steps)
    for i in range(n):
        first, _ = gym_env.TwoLinkEnv(**kwargs).reset(seed=seed + i)
        np.testing.assert_array_equal(obs[i], first)
    ended = 0
    for k in range(steps):
        obs, rewards, dones, infos = vec.step(_actions(k, n, kwargs))
        assert rewards.dtype == np.float32 and dones.dtype == np.bool_
        for i in range(n):
            nxt, r, done, terminal, success = want[i][k]
            np.testing.assert_array_equal(obs[i], nxt)
            assert rewards[i] == np.float32(r) and dones[i] == done
            if done:
                ended += 1
                assert set(infos[i]) == {"terminal_observation", "TimeLimit.truncated",
                                         "is_success"}
                np.testing.assert_array_equal(infos[i]["terminal_observation"], terminal)
                assert infos[i]["TimeLimit.truncated"] is True
                assert infos[i]["is_success"] is success
            else:
                assert infos[i] == {}
    assert ended >= n
    vec.close()
    vec.close()
    with pytest.raises(RuntimeError, match="closed"):
        vec.reset()


def test_vec_env_is_success_at_rest_and_options():
    vec = tsb3.vec_env(2, x0=np.zeros(4), time_limit=1.5, nthread=1)
    vec.reset()
    for _ in range(30):
        _, rewards, dones, infos = vec.step(np.zeros((2, 2)))
        assert np.all(rewards == 0.0)              # at rest in the band: no autoreset step
    assert dones.all() and all(i["is_success"] is True for i in infos)
    x0 = np.array([0.5, -0.5, 0.0, 0.0])
    vec.set_options({"x0": x0})
    np.testing.assert_array_equal(vec.reset(), [x0, x0])
    np.testing.assert_array_equal(vec.reset(), np.zeros((2, 4)))   # options last one reset
    assert vec.get_attr("links") == [2, 2] and vec.env_is_wrapped(VecMonitor) == [False] * 2
    assert vec.get_attr("render_mode", indices=1) == [None]
    with pytest.raises(RuntimeError, match="step_async"):
        vec.step_wait()
    with pytest.raises(ValueError, match="action"):
        vec.step(np.zeros((3, 2)))
    vec.close()


def test_ppo_and_sac_learn_a_few_steps_under_vec_check_nan():
    import torch

    torch.set_num_threads(1)
    for algo, kwargs in ((sb3.PPO, dict(n_steps=64, batch_size=64, n_epochs=2)),
                         (sb3.SAC, dict(learning_starts=64, batch_size=32, buffer_size=1000))):
        venv = VecCheckNan(VecMonitor(tsb3.vec_env(4, x0="random", actions="normalized",
                                                    reward="shaped", observation="cos_sin",
                                                    time_limit=1.0, nthread=1)),
                           raise_exception=True)
        model = algo("MlpPolicy", venv, seed=0, verbose=0, device="cpu",
                     policy_kwargs=dict(net_arch=[16, 16]), **kwargs)
        model.learn(256)
        assert model.num_timesteps >= 256
        # SB3 logged the episodes and their success flags (20-step episodes, 4 arms)
        assert len(model.ep_info_buffer) > 0 and len(model.ep_success_buffer) > 0
        action, _ = model.predict(venv.reset(), deterministic=True)
        assert action.shape == (4, 2) and np.all(np.abs(action) <= 1)
        venv.close()


def test_missing_sb3_is_one_line_naming_the_extra():
    code = ("import sys; sys.modules['stable_baselines3'] = None\n"
            "try:\n    import twolink.envs.sb3\n"
            "except ImportError as exc:\n    print(exc)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines() == [
        "twolink.envs.sb3 needs Stable-Baselines3: pip install 'twolink[rl]'"]
