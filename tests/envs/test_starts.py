"""x0 'slow' and 'mixed' (twolink.envs.starts, `twolink train --start`): the poses drawn are
beyond the own motors' reach (all of them, or about half plus the uniform draw's share),
at rest, reproducible from the seed; arms without such poses and the two-link arm refuse
them in one line; IPPO/MAPPO runs start their arms from them."""
from __future__ import annotations

import numpy as np
import pytest

from twolink.arm.parameters import links_parameters
from twolink.arm.task import own_motor_seconds
from twolink.cli import main
from twolink.envs.starts import check_slow_starts, deadline, slow_pose, start_pose
from twolink.training.config import TrainConfig
from twolink.training.run import run_name

SIX = links_parameters(6, "tapered")


def _own(states):
    return own_motor_seconds(SIX, np.asarray(states)[..., :6]).max(axis=-1)


def test_slow_poses_are_beyond_the_deadline_at_rest_and_seeded():
    assert deadline(SIX) == 7.0
    rng = np.random.default_rng(5)
    poses = np.array([slow_pose(SIX, rng) for _ in range(200)])
    assert poses.shape == (200, 12) and np.all(poses[:, 6:] == 0.0)
    assert np.all(_own(poses) > 7.0) and np.all(np.abs(poses[:, :6]) <= np.pi)
    again = np.array([slow_pose(SIX, np.random.default_rng(5)) for _ in range(1)])
    assert np.array_equal(again[0], poses[0])


def test_mixed_draws_half_slow_plus_the_uniform_share():
    rng = np.random.default_rng(11)
    poses = np.array([start_pose("mixed", SIX, rng) for _ in range(2000)])
    uniform = np.random.default_rng(12).uniform(-np.pi, np.pi, (20000, 6))
    share = float(np.mean(_own(uniform) > 7.0))            # about 0.29 at six links
    expected = 0.5 + 0.5 * share
    assert 0.2 < share < 0.4
    assert abs(np.mean(_own(poses) > 7.0) - expected) < 0.04


def test_the_vector_env_starts_every_arm_beyond_the_deadline():
    from twolink.envs.gym import TwoLinkVectorEnv

    env = TwoLinkVectorEnv(32, links=6, x0="slow")
    env.reset(seed=3)
    assert np.all(_own(env.states) > 7.0)
    env.close()
    sb3 = pytest.importorskip("stable_baselines3")             # the training env too
    assert sb3
    from twolink.envs.sb3 import TwoLinkSB3VecEnv

    env = TwoLinkSB3VecEnv(32, links=6, x0="mixed", observation="cos_sin",
                           actions="normalized", reward="shaped", nthread=1)
    env.seed(3)
    env.reset()
    assert 0.5 < np.mean(_own(env.states) > 7.0) < 0.9


@pytest.mark.parametrize("links, rule", [(5, "tapered"), (4, "copied"), (3, "tapered")])
def test_arms_without_slow_poses_refuse_them(links, rule):
    with pytest.raises(ValueError, match=rf"x0='slow': no pose of this {links}-link arm is "
                                         r"beyond its own motors' reach"):
        check_slow_starts("slow", links_parameters(links, rule))
    check_slow_starts("random", links_parameters(links, rule))          # no error


def test_the_two_link_env_refuses_the_words():
    from twolink.envs.gym import TwoLinkEnv

    with pytest.raises(ValueError, match="x0 must be 'paper', 'random' or a state"):
        TwoLinkEnv(x0="mixed")


def test_the_training_config_names_and_checks_the_start():
    config = TrainConfig(links=6, base="pd", start="mixed")
    assert config.env_options()["x0"] == "mixed" and "start" in TrainConfig.IDENTITY
    assert run_name(config) == "ppo_6links_pd_mixed_seed0"
    assert TrainConfig(links=6).env_options()["x0"] == "random"
    with pytest.raises(ValueError, match="start='slow': no pose of this 5-link arm"):
        TrainConfig(links=5, start="slow")


@pytest.mark.parametrize("argv, message", [
    (["--links", "5", "--start", "mixed"], "start='mixed': no pose of this 5-link arm"),
    (["--algo", "mappo", "--links", "5", "--start", "slow"],
     "start='slow': no pose of this 5-link arm"),
])
def test_bad_starts_are_one_line_exit_2_nothing_written(tmp_path, capsys, argv, message):
    out = tmp_path / "run"
    assert main(["train", *argv, "--steps", "128", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1
    assert not out.exists()


def test_a_multi_agent_run_names_checks_and_starts_from_them():
    from twolink.envs.pettingzoo_batched import batched_parallel_env
    from twolink.training.marl import MarlConfig, run_name as marl_name

    config = MarlConfig(algo="mappo", links=6, start="slow", envs=8)
    assert config.env_options()["x0"] == "slow" and "start" in MarlConfig.IDENTITY
    assert marl_name(config) == "mappo_6links_neighbours_slow_seed0"
    assert MarlConfig(links=6).env_options()["x0"] == "random"
    env = batched_parallel_env(8, **config.env_options())
    env.reset(seed=config.arm_seed())
    assert np.all(_own(env.state()) > 7.0) and np.all(env.state()[:, 6:] == 0.0)
    mixed = batched_parallel_env(64, **MarlConfig(links=6, start="mixed").env_options())
    mixed.reset(seed=11)
    assert 16 <= int(np.sum(_own(mixed.state()) > 7.0)) <= 60    # half, plus uniform's share
    with pytest.raises(ValueError, match="start='mixed': no pose of this 4-link arm"):
        MarlConfig(links=4, rule="copied", start="mixed")
    with pytest.raises(ValueError, match="start must be one of"):
        MarlConfig(links=6, start="fast")


def test_the_multi_agent_and_dm_envs_start_beyond_the_deadline_too():
    from twolink.envs.pettingzoo import parallel_env

    env = parallel_env(links=6, x0="slow")
    env.reset(seed=4)
    assert _own(env.state()) > 7.0
    with pytest.raises(ValueError, match="x0='mixed': no pose of this 5-link arm"):
        parallel_env(links=5, x0="mixed")
    dm = pytest.importorskip("twolink.envs.dm")
    ts = dm.load("centralized", links=6, x0="slow", seed=2).reset()
    assert ts.observation["state"].shape == (12,) and _own(ts.observation["state"]) > 7.0
