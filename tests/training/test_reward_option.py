"""``twolink train --reward shaped_time``: the arms' rewards are the shaped reward less one
outside the goal band, the run is named and checkpointed with it, a resume with another
reward is refused; IPPO's agents learn from their link's shaped reward less one outside
its band, MAPPO's team from the arm's."""
from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from twolink.cli import main  # noqa: E402
from twolink.arm.task import centralized_reward  # noqa: E402
from twolink.envs.core import shaped_time_reward  # noqa: E402
from twolink.training.config import TrainConfig  # noqa: E402
from twolink.training.run import build, run_name, train  # noqa: E402


def _err(capsys, argv) -> str:
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    return err


def test_the_arms_learn_from_the_shaped_time_reward():
    config = TrainConfig(algo="ppo", steps=64, envs=2, n_steps=32, reward="shaped_time")
    model, env = build(config)
    env.reset()
    _, r, _, _ = env.step(np.ones((2, 2), np.float32))
    np.testing.assert_allclose(r, shaped_time_reward(env._live().x), rtol=1e-6)  # float32
    assert np.all(r < -1)                       # random poses start outside the band
    env.close()
    assert run_name(config) == "ppo_2links_rt_seed0"
    assert run_name(TrainConfig(algo="ppo")) == "ppo_2links_seed0"


def test_the_arms_learn_from_the_papers_reward():
    """``--reward paper``: (15) itself, -0.5 outside the goal band and 0 in it."""
    config = TrainConfig(algo="ppo", links=3, steps=64, envs=2, n_steps=32, reward="paper")
    model, env = build(config)
    env.reset()
    _, r, _, _ = env.step(np.ones((2, 3), np.float32))
    np.testing.assert_array_equal(r, centralized_reward(env._live().x))
    assert np.all(r == -0.5)                    # random poses start outside the band
    env.close()
    assert run_name(config) == "ppo_3links_rp_seed0"


def test_the_reward_is_part_of_the_run(tmp_path, capsys):
    config = TrainConfig(algo="ppo", steps=64, envs=2, n_steps=32, eval_every=64,
                         reward="shaped_time")
    run = tmp_path / "run"
    record = train(config, run)
    assert record["config"]["reward"] == "shaped_time"
    assert json.loads((run / "curve.json").read_text())["config"]["reward"] == "shaped_time"
    copy = tmp_path / "copy"          # the checkpoint alone: an interrupted run
    copy.mkdir()
    (copy / "checkpoint.pt").write_bytes((run / "checkpoint.pt").read_bytes())
    assert "checkpoint of a run with reward 'shaped_time', not 'shaped'" in _err(
        capsys, ["train", "--resume", "--reward", "shaped", "--steps", "128",
                 "--out", str(copy)])


def test_bad_rewards_are_one_line(tmp_path, capsys):
    out = tmp_path / "run"
    with pytest.raises(SystemExit) as exit_:
        main(["train", "--reward", "dense", "--out", str(out)])
    assert exit_.value.code == 2
    assert "--reward: invalid choice: 'dense'" in capsys.readouterr().err
    assert not out.exists()
    with pytest.raises(ValueError, match="reward must be one of 'shaped', 'shaped_time', "
                                         "'paper', got 'dense'"):
        TrainConfig(reward="dense")


def test_marl_runs_take_the_shaped_time_reward(tmp_path, capsys):
    pytest.importorskip("skrl")
    from twolink.training.marl import MarlConfig, run_name as marl_name, train as marl_train

    assert MarlConfig(algo="ippo", reward="shaped_time").env_options()["reward"] == \
        "shaped_time"
    assert MarlConfig(algo="mappo", reward="shaped_time").env_options()["reward"] == \
        "shaped_team_time"
    assert MarlConfig(algo="mappo").env_options()["reward"] == "shaped_team"
    config = MarlConfig(algo="mappo", links=3, reward="shaped_time", envs=4, n_steps=32,
                        steps=128, eval_every=128)
    assert marl_name(config) == "mappo_3links_neighbours_rt_seed0"
    run = tmp_path / "run"
    marl_train(config, run)
    curve = json.loads((run / "curve.json").read_text())
    assert curve["config"]["reward"] == "shaped_time"
    assert curve["env"]["reward"] == "shaped_team_time"
    assert (run / "mappo_3links_neighbours_rt_seed0.marl.pt").is_file()
    with pytest.raises(ValueError, match="reward must be one of 'shaped', 'shaped_time'"):
        MarlConfig(algo="ippo", reward="shaped_team")


def test_marl_runs_take_the_papers_reward():
    """IPPO's agents learn from their link's (17), MAPPO's team from (15)."""
    pytest.importorskip("skrl")
    from twolink.envs.multi_agent import agent_rewards
    from twolink.training.marl import MarlConfig, run_name as marl_name

    assert MarlConfig(algo="ippo", reward="paper").env_options()["reward"] == "paper"
    assert MarlConfig(algo="mappo", reward="paper").env_options()["reward"] == "centralized"
    assert marl_name(MarlConfig(algo="ippo", links=6, reward="paper")) == \
        "ippo_6links_neighbours_rp_seed0"
    x = np.zeros((2, 4))
    x[0, 1] = 1.0                               # link 2 off: agent 1 home, the team not
    np.testing.assert_array_equal(agent_rewards(x, "paper"), [[0.0, -0.5], [0.0, 0.0]])
    np.testing.assert_array_equal(agent_rewards(x, "centralized"),
                                  [[-0.5, -0.5], [0.0, 0.0]])
