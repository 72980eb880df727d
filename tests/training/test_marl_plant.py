"""IPPO/MAPPO on the model (6): ``plant='model'`` steps the batched multi-agent env's arms
on the numpy full model instead of MuJoCo; evaluation stays on MuJoCo."""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

pytest.importorskip("skrl")
torch = pytest.importorskip("torch")

from twolink.arm.parameters import links_parameters  # noqa: E402
from twolink.cli import main  # noqa: E402
from twolink.envs.pettingzoo_batched import batched_parallel_env  # noqa: E402
from twolink.sim.plants import ModelPlant, MujocoPlant  # noqa: E402
from twolink.training.marl import MarlConfig, run_name, train  # noqa: E402

SMALL = dict(envs=8, n_steps=64, eval_every=1024, steps=1024)


def test_the_batched_env_steps_the_full_model_when_asked():
    x0 = np.array([0.4, -0.3, 0.2, 0.0, 0.1, -0.2])
    actions = {"link1": np.full((2, 1), 0.5), "link2": np.full((2, 1), -1.0),
               "link3": np.full((2, 1), 0.25)}
    states = {}
    for plant in ("full", "mujoco"):
        env = batched_parallel_env(2, links=3, rule="tapered", plant=plant, reward="shaped",
                                   actions="normalized")
        env.reset(seed=0, options={"x0": x0})
        env.step(actions)
        states[plant] = env.state()
        assert isinstance(env._arms.plant, ModelPlant if plant == "full" else MujocoPlant)
        env.close()
    params = links_parameters(3, "tapered")
    tau = np.array([0.5, -1.0, 0.25]) * params.tau_max
    expected = ModelPlant("full", params).step(x0[None], tau[None])[0]
    np.testing.assert_allclose(states["full"], np.tile(expected, (2, 1)), rtol=0, atol=1e-12)
    # the MJCF arm is the model (6): one sample period agrees far below the goal band
    np.testing.assert_allclose(states["full"], states["mujoco"], rtol=0, atol=1e-6)


def test_a_run_on_the_model_is_named_recorded_and_resumes_only_as_itself(tmp_path, capsys):
    config = MarlConfig(algo="mappo", links=3, seed=5, plant="model", **SMALL)
    assert run_name(config) == "mappo_3links_neighbours_model_seed5"
    record = train(config, tmp_path / "model")
    curve = json.loads((tmp_path / "model" / "curve.json").read_text())
    assert curve["env"]["plant"] == "full" and curve["config"]["plant"] == "model"
    assert curve["evaluation"]["plant"] == "mujoco"           # scored on MuJoCo
    assert record["agent"] == "mappo_3links_neighbours_model_seed5.marl.pt"
    assert (tmp_path / "model" / record["agent"]).is_file()
    part = tmp_path / "part"
    shutil.copytree(tmp_path / "model", part)
    (part / record["agent"]).unlink()              # an interrupted run: its checkpoint
    assert main(["train", "--resume", "--algo", "mappo", "--plant", "mujoco", "--steps",
                 "2048", "-o", str(part)]) == 2
    assert "with plant 'model', not 'mujoco'" in capsys.readouterr().err
