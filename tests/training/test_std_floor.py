"""`twolink train --algo ppo|ippo|mappo --std-floor S`: each policy's noise starts at S and
is held at S or more while it learns (skrl: clipped where the distribution is made; SB3's
PPO: raised back before every rollout); the floor names the run, is part of its identity,
and bad values or SAC are one line with exit 2 and nothing written."""
from __future__ import annotations

import math

import pytest

from twolink.cli import main
from twolink.training.marl import HYPERPARAMETERS, MarlConfig, run_name


def test_the_floor_sets_the_initial_and_the_smallest_log_std():
    hp = MarlConfig(std_floor=0.37).hyperparameters()
    assert hp["log_std_init"] == hp["min_log_std"] == pytest.approx(math.log(0.37))
    hp = MarlConfig().hyperparameters()
    assert (hp["log_std_init"], hp["min_log_std"]) == (0.0, -20.0)
    assert HYPERPARAMETERS["min_log_std"] == -20.0            # the table is not touched
    assert run_name(MarlConfig(observe="local", challenge="medium", history=3,
                               action_rate=1, std_floor=0.37, seed=1)) == \
        "ippo_2links_local_medium_h3_ar1_sf0.37_seed1"
    assert "std_floor" in MarlConfig.IDENTITY
    old = MarlConfig().as_dict()
    del old["std_floor"]                                       # a checkpoint from before it
    assert MarlConfig.from_dict(old).std_floor is None


def test_the_policy_noise_never_falls_below_the_floor():
    torch = pytest.importorskip("torch")
    pytest.importorskip("skrl")
    from gymnasium import spaces

    from twolink.training.marl_state import _models

    hp = MarlConfig(std_floor=0.2).hyperparameters()
    Policy, _ = _models(torch, [8], "Tanh", hp["log_std_init"], hp["min_log_std"])
    box = spaces.Box(-1.0, 1.0, (3,))
    policy = Policy(box, spaces.Box(-1.0, 1.0, (1,)), "cpu")
    with torch.no_grad():
        policy.log_std.fill_(-5.0)                  # as if learning had driven it down
    _, out = policy.act({"observations": torch.zeros(4, 3)})
    assert float(out["log_std"].exp().min()) == pytest.approx(0.2)


@pytest.mark.parametrize("args, message", [
    (["--algo", "sac", "--std-floor", "0.3"], "--std-floor is for --algo ppo|ippo|mappo"),
    (["--algo", "ppo", "--std-floor", "2"], "--std-floor must be a number from 0.01 to 1"),
    (["--algo", "ippo", "--std-floor", "0"], "--std-floor must be a number from 0.01 to 1"),
    (["--algo", "mappo", "--std-floor", "nan"], "--std-floor must be a number from 0.01"),
    (["--algo", "ippo", "--std-floor", "inf"], "--std-floor must be a number from 0.01"),
])
def test_bad_floor_is_one_line_exit_2_nothing_written(tmp_path, capsys, args, message):
    out = tmp_path / "run"
    assert main(["train", *args, "--steps", "64", "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err
    assert not out.exists()


def test_a_resume_with_another_floor_is_refused(tmp_path, capsys):
    pytest.importorskip("skrl")
    out = tmp_path / "run"
    common = ["train", "--algo", "ippo", "--observe", "local", "--steps", "128", "--envs",
              "4", "--n-steps", "32", "--eval-every", "128", "-o", str(out)]
    assert main([*common, "--std-floor", "0.37", "--json"]) == 0
    capsys.readouterr()
    (out / "ippo_2links_local_sf0.37_seed0.marl.pt").unlink()   # as if stopped before the end
    assert main([*common[:-2], "--steps", "256", "-o", str(out), "--std-floor", "0.5",
                 "--resume"]) == 2
    assert "std_floor 0.37, not 0.5" in capsys.readouterr().err


def test_a_ppo_resume_with_a_floor_is_refused(tmp_path, capsys):
    pytest.importorskip("stable_baselines3")
    out = tmp_path / "ppo"
    assert main(["train", "--steps", "128", "--envs", "4", "--n-steps", "32",
                 "--eval-every", "128", "-o", str(out)]) == 0
    capsys.readouterr()
    (out / "ppo_2links_seed0.zip").unlink()                    # as if stopped before the end
    assert main(["train", "--resume", "-o", str(out), "--steps", "256",
                 "--std-floor", "0.3"]) == 2
    assert "a checkpoint of a run with std_floor None, not 0.3" in capsys.readouterr().err


def test_the_ppo_floor_names_the_run_and_sac_has_none():
    from twolink.training.config import TrainConfig
    from twolink.training.run import run_name

    assert run_name(TrainConfig(links=6, base="pd", std_floor=0.2, seed=3)) == \
        "ppo_6links_pd_sf0.2_seed3"
    assert "std_floor" in TrainConfig.IDENTITY
    old = TrainConfig().as_dict()
    del old["std_floor"]                                       # a checkpoint from before it
    assert TrainConfig.from_dict(old).std_floor is None
    with pytest.raises(ValueError, match="std_floor is for ppo, ippo and mappo"):
        TrainConfig(algo="sac", std_floor=0.2)
    with pytest.raises(ValueError, match="std_floor must be a number from 0.01 to 1"):
        TrainConfig(std_floor=0.0)


def test_every_ppo_rollout_is_sampled_at_the_floor_or_above():
    pytest.importorskip("stable_baselines3")
    import torch
    from stable_baselines3.common.callbacks import BaseCallback, CallbackList

    from twolink.training.config import TrainConfig
    from twolink.training.run import build
    from twolink.training.std_floor import floor_callback

    config = TrainConfig(std_floor=0.3, envs=4, n_steps=16, steps=128)
    model, env = build(config)
    try:
        assert torch.allclose(model.policy.log_std, torch.full((2,), math.log(0.3)))
        with torch.no_grad():
            model.policy.log_std.fill_(-5.0)               # as if updates had driven it down
        seen = []

        class Record(BaseCallback):
            def _on_step(self) -> bool:
                seen.append(float(self.model.policy.log_std.min()))
                return True

        model.learn(64, callback=CallbackList([floor_callback(0.3), Record()]))
    finally:
        env.close()
    assert len(seen) == 16 and min(seen) == pytest.approx(math.log(0.3))


def test_a_ppo_run_with_a_floor_trains_and_saves_its_agent(tmp_path, capsys):
    pytest.importorskip("stable_baselines3")
    out = tmp_path / "ppo"
    assert main(["train", "--std-floor", "0.3", "--steps", "128", "--envs", "4",
                 "--n-steps", "32", "--eval-every", "128", "-o", str(out)]) == 0
    assert (out / "ppo_2links_sf0.3_seed0.zip").is_file()
