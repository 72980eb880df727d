"""`twolink train --gamma G`: the discount reaches the learner (SB3's saved agent, skrl's
agent config), names the run, is part of a run's identity, and bad values are one line
with exit 2 and nothing written."""
from __future__ import annotations

import json
import zipfile

import pytest

from twolink.cli import main
from twolink.training.config import HYPERPARAMETERS, TrainConfig, check_gamma
from twolink.training.marl import MarlConfig, run_name as marl_run_name
from twolink.training.run import run_name


def test_the_default_is_the_algorithms_and_a_given_gamma_replaces_it():
    assert TrainConfig().hyperparameters()["gamma"] == HYPERPARAMETERS["ppo"]["gamma"] == 0.98
    assert TrainConfig(gamma=0.995).hyperparameters()["gamma"] == 0.995
    assert TrainConfig(algo="sac", gamma=0.99).hyperparameters()["gamma"] == 0.99
    assert MarlConfig(gamma=0.995).hyperparameters()["gamma"] == 0.995
    assert MarlConfig().hyperparameters()["gamma"] == 0.98


def test_the_run_name_carries_a_given_gamma_only():
    assert run_name(TrainConfig(links=6, base="pd", gamma=0.995)) == "ppo_6links_pd_g0.995_seed0"
    assert run_name(TrainConfig(links=6, base="pd")) == "ppo_6links_pd_seed0"
    assert marl_run_name(MarlConfig(algo="mappo", links=6, observe="global", base="pd",
                                    gamma=0.995)) == "mappo_6links_global_pd_g0.995_seed0"
    assert "gamma" in TrainConfig.IDENTITY and "gamma" in MarlConfig.IDENTITY


def test_a_config_without_gamma_reads_back_as_the_default():
    d = TrainConfig(links=3).as_dict()
    del d["gamma"]                      # a checkpoint written before the option existed
    assert TrainConfig.from_dict(d).gamma is None


@pytest.mark.parametrize("value", [0.3, 1.5, float("nan"), "x", True, None])
def test_check_gamma_refuses_in_one_line(value):
    with pytest.raises(ValueError, match=r"gamma must be a number from 0.5 to 1") as e:
        check_gamma(value)
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("argv, message", [
    (["--gamma", "1.01"], "--gamma must be a number from 0.5 to 1, got '1.01'"),
    (["--gamma", "nan"], "--gamma must be a number from 0.5 to 1, got 'nan'"),
    (["--gamma", "soon"], "--gamma must be a number from 0.5 to 1, got 'soon'"),
    (["--algo", "mappo", "--gamma", "0"], "--gamma must be a number from 0.5 to 1, got '0'"),
])
def test_bad_values_are_one_line_exit_2_nothing_written(tmp_path, capsys, argv, message):
    out = tmp_path / "run"
    assert main(["train", *argv, "--steps", "128", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1
    assert not out.exists()


def test_the_saved_agent_learned_with_the_given_gamma(tmp_path):
    pytest.importorskip("stable_baselines3")
    out = tmp_path / "run"
    assert main(["train", "--steps", "256", "--envs", "4", "--n-steps", "32",
                 "--eval-every", "256", "--gamma", "0.995", "--out", str(out)]) == 0
    agent = out / "ppo_2links_g0.995_seed0.zip"
    with zipfile.ZipFile(agent) as z:
        data = json.loads(z.read("data"))
    assert data["gamma"] == 0.995
    assert json.loads((out / "curve.json").read_text())["config"]["gamma"] == 0.995
