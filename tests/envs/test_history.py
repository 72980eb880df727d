"""Observation histories (twolink.control.history, twolink.envs.history): the layout (K
observations then K - 1 actions, oldest first), zeros at an episode's start and again
after an autoreset, the terminal observation of the ended episode, the Gymnasium
wrapper, and bad history lengths as one line."""
from __future__ import annotations

import numpy as np
import pytest

from twolink.control.history import ObservationHistory, check_history, history_layout
from twolink.envs.gym import TwoLinkEnv


def test_the_layout_oldest_first_zero_padded():
    h = ObservationHistory(2, 3, 2, 3)
    first = h.observe(np.array([[1, 2, 3], [4, 5, 6]]))
    assert first.shape == (2, 3 * 3 + 2 * 2) == (2, history_layout(3, 3, 2)["size"])
    assert first[0].tolist() == [0, 0, 0, 0, 0, 0, 1, 2, 3, 0, 0, 0, 0]
    h.act(np.array([[0.5, -0.5], [1, 1]]))
    second = h.observe(np.array([[7, 8, 9], [1, 1, 1]]))
    assert second[0].tolist() == [0, 0, 0, 1, 2, 3, 7, 8, 9, 0, 0, 0.5, -0.5]
    h.reset([0])
    assert h.stacked()[0].tolist() == [0] * 13 and h.stacked()[1].any()


@pytest.mark.parametrize("k", [0, -1, 17, 2.5, "3", None, True])
def test_bad_history_lengths_are_one_line(k):
    with pytest.raises(ValueError, match="history must be a whole number of samples from "
                                         "1 to 16"):
        check_history(k)


def test_the_sb3_wrapper_resets_on_autoreset():
    pytest.importorskip("stable_baselines3")
    from twolink.envs.history import HistoryVecEnv, with_history
    from twolink.envs.sb3 import TwoLinkSB3VecEnv

    base = TwoLinkSB3VecEnv(2, observation="cos_sin", actions="normalized", nthread=1,
                            time_limit=0.15)                  # 3 samples per episode
    env = with_history(base, 2)
    assert isinstance(env, HistoryVecEnv) and env.observation_space.shape == (6 + 6 + 2,)
    assert with_history(base, 1) is base
    obs = env.reset()
    assert np.all(obs[:, :6] == 0) and np.all(obs[:, 12:] == 0)
    actions = np.array([[0.5, -2.0], [0.1, 0.2]], np.float32)     # -2 is clipped to -1
    obs, _, done, _ = env.step(actions)
    assert obs[0, 12:].tolist() == [0.5, -1.0]
    assert np.array_equal(obs[:, :6], env.history.observations[:, 0])
    env.step(actions)
    obs, _, done, infos = env.step(actions)
    assert done.all()
    terminal = infos[0]["terminal_observation"]
    assert terminal.shape == (14,) and terminal[:6].any() and terminal[12:].tolist() == [0.5, -1.0]
    assert np.all(obs[:, :6] == 0) and np.all(obs[:, 12:] == 0) and obs[:, 6:12].any()
    assert env.observation_space.contains(obs[0])
    env.close()


def test_the_gymnasium_wrapper():
    from twolink.envs.history import HistoryEnv, with_history

    env = with_history(TwoLinkEnv(actions="normalized"), 3)
    assert isinstance(env, HistoryEnv) and env.observation_space.shape == (3 * 4 + 2 * 2,)
    obs, _ = env.reset(seed=1)
    assert obs[:8].tolist() == [0] * 8 and obs[8:12].tolist() == [-1.0, -3.0, 0.0, 0.0]
    obs, *_ = env.step(np.array([1.0, 0.25], np.float32))
    assert obs[4:8].tolist() == [-1.0, -3.0, 0.0, 0.0] and obs[14:].tolist() == [1.0, 0.25]
    assert env.observation_space.contains(obs)
    obs, _ = env.reset()
    assert obs[:8].tolist() == [0] * 8 and obs[12:].tolist() == [0] * 4
    with pytest.raises(ValueError, match="one-dimensional Box action space"):
        with_history(TwoLinkEnv(actions="discrete"), 2)
