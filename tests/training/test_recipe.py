"""`twolink train --batch-size B --epochs E --net W,W`: the recipe reaches the learner
(SB3's saved agent, skrl's agent header), names the run, is part of a run's identity (a
resume with another recipe is refused), and bad values are one line with exit 2 and
nothing written."""
from __future__ import annotations

import json
import zipfile

import pytest

from twolink.cli import main
from twolink.training.config import HYPERPARAMETERS, TrainConfig, check_net
from twolink.training.marl import HYPERPARAMETERS as MARL_HP
from twolink.training.marl import MarlConfig, run_name as marl_run_name
from twolink.training.run import run_name


def test_the_defaults_are_the_algorithms_and_given_values_replace_them():
    hp = TrainConfig(links=6).hyperparameters()
    assert (hp["batch_size"], hp["n_epochs"], hp["net_arch"]) == (256, 10, [256, 256])
    hp = TrainConfig(links=6, batch_size=1024, epochs=5, net=(64, 64)).hyperparameters()
    assert (hp["batch_size"], hp["n_epochs"], hp["net_arch"]) == (1024, 5, [64, 64])
    # PPO's minibatch is held to one rollout (16 arms x 128 steps)
    assert TrainConfig(batch_size=8192).hyperparameters()["batch_size"] == 2048
    assert TrainConfig(algo="sac", batch_size=512, net=[128]).hyperparameters()[
        "batch_size"] == 512
    assert HYPERPARAMETERS["ppo"]["net_arch"] == [256, 256]      # the table is not touched
    m = MarlConfig(envs=64, batch_size=8192, epochs=4, net=(32, 32)).hyperparameters()
    assert (m["batch_size"], m["mini_batches"], m["learning_epochs"], m["hidden"]) == \
        (8192, 1, 4, [32, 32])
    m = MarlConfig().hyperparameters()
    assert (m["batch_size"], m["mini_batches"], m["learning_epochs"], m["hidden"]) == \
        (256, 8, 10, MARL_HP["hidden"])


def test_the_run_name_carries_a_given_recipe_only():
    assert run_name(TrainConfig(links=6, base="pd", batch_size=1024, net=(64, 64))) == \
        "ppo_6links_pd_b1024_net64x64_seed0"
    assert run_name(TrainConfig(links=6, base="pd", epochs=5)) == "ppo_6links_pd_e5_seed0"
    assert marl_run_name(MarlConfig(algo="mappo", links=6, envs=64, batch_size=8192)) == \
        "mappo_6links_neighbours_b8192_seed0"
    for cls in (TrainConfig, MarlConfig):
        assert {"batch_size", "epochs", "net"} <= set(cls.IDENTITY)


def test_a_config_read_back_from_json_has_the_same_recipe():
    c = TrainConfig(links=3, net=(64, 32), batch_size=512)
    back = TrainConfig.from_dict(json.loads(json.dumps(c.as_dict())))
    assert back == c and back.net == (64, 32)
    d = c.as_dict()
    for key in ("batch_size", "epochs", "net"):    # a checkpoint from before the options
        del d[key]
    assert TrainConfig.from_dict(d).net is None


@pytest.mark.parametrize("value", [(), (64,) * 5, (3,), (2048,), (64.0, 64), "64,64",
                                   (True, 64), None])
def test_check_net_refuses_in_one_line(value):
    with pytest.raises(ValueError, match=r"net must be 1 to 4 hidden-layer widths") as e:
        check_net(value)
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("argv, message", [
    (["--batch-size", "4"], "--batch-size must be a whole number from 8 to 65,536, got '4'"),
    (["--batch-size", "1e9"], "--batch-size must be a whole number from 8 to 65,536"),
    (["--epochs", "0"], "--epochs must be a whole number from 1 to 100, got '0'"),
    (["--algo", "sac", "--epochs", "3"], "epochs (passes over each rollout) is PPO's"),
    (["--net", "64,x"], "--net must be 1 to 4 comma-separated widths of 4 to 1024 units"),
    (["--net", "64,64,64,64,64"], "--net must be 1 to 4 comma-separated widths"),
    (["--algo", "mappo", "--net", "99999"], "--net must be 1 to 4 comma-separated widths"),
])
def test_bad_values_are_one_line_exit_2_nothing_written(tmp_path, capsys, argv, message):
    out = tmp_path / "run"
    assert main(["train", *argv, "--steps", "128", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1
    assert not out.exists()


def test_the_saved_ppo_agent_has_the_recipe_and_is_a_controller(tmp_path, capsys):
    pytest.importorskip("stable_baselines3")
    out = tmp_path / "run"
    argv = ["train", "--links", "3", "--steps", "128", "--envs", "4", "--n-steps", "32",
            "--eval-every", "128", "--batch-size", "64", "--epochs", "2", "--net", "32,16",
            "--out", str(out)]
    assert main(argv) == 0
    agent = out / "ppo_3links_b64_e2_net32x16_seed0.zip"
    with zipfile.ZipFile(agent) as z:
        data = json.loads(z.read("data"))
    assert (data["batch_size"], data["n_epochs"]) == (64, 2)
    from twolink.control.sb3_agent import SB3Agent

    weights = SB3Agent(agent).policy.state_dict()
    assert weights["mlp_extractor.policy_net.0.weight"].shape[0] == 32
    assert weights["mlp_extractor.policy_net.2.weight"].shape == (16, 32)
    capsys.readouterr()
    assert main(["evaluate", str(agent), "--links", "3", "--poses", "2", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["n"] == 2
    # a resume that names another recipe is refused, naming the field
    agent.unlink()                                          # as if stopped before the end
    assert main(argv[:-2] + ["--resume", "--net", "64,64", "--out", str(out)]) == 2
    assert "with net (32, 16), not (64, 64)" in capsys.readouterr().err


def test_the_saved_marl_agent_has_its_hidden_layers(tmp_path):
    pytest.importorskip("skrl")
    from twolink.training.marl import train

    record = train(MarlConfig(algo="ippo", links=2, envs=4, n_steps=16, steps=64,
                              eval_every=64, batch_size=64, epochs=1, net=(16,)),
                   tmp_path / "run")
    assert record["agent"] == "ippo_2links_neighbours_b64_e1_net16_seed0.marl.pt"
    from twolink.control.marl_agent import read_marl_file

    header, policies = read_marl_file(tmp_path / "run" / record["agent"])
    assert header["hidden"] == [16]
    assert policies["link1"]["0.weight"].shape[0] == 16
