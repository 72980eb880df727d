"""N-link agents load through twolink.control.sb3_agent only with the arm they name;
`--plant model` trains on the numpy full model; the training benchmark's rows. Skipped
where Stable-Baselines3 is not installed."""
from __future__ import annotations

import json
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from twolink.arm.parameters import links_parameters  # noqa: E402
from twolink.control.sb3_agent import sb3_agent  # noqa: E402
from twolink.envs.sb3 import TwoLinkSB3VecEnv  # noqa: E402
from twolink.sim.controller import ControllerError  # noqa: E402
from twolink.sim.plants import ModelPlant  # noqa: E402
from twolink.training.config import TrainConfig  # noqa: E402
from twolink.training.run import build, save_agent, train  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))   # benchmarks/


@pytest.fixture(scope="module")
def four_links(tmp_path_factory):
    """An untrained 4-link copied-rule PPO agent saved as `twolink train` saves it."""
    config = TrainConfig(links=4, rule="copied", envs=2, n_steps=8)
    model, env = build(config)
    path = tmp_path_factory.mktemp("agents") / "four.zip"
    save_agent(model, path, config)
    env.close()
    return model, path


def _rewrite(src, dest, member=None, text=None):
    with zipfile.ZipFile(src) as z, zipfile.ZipFile(dest, "w") as out:
        for name in z.namelist():
            if name != "twolink.json":
                out.writestr(name, z.read(name))
        if member is not None:
            out.writestr(member, text)
    return dest


def test_an_n_link_agent_scales_by_its_arms_tau_max(four_links):
    model, path = four_links
    agent = sb3_agent(path)
    assert (agent.links, agent.rule, agent.observation) == (4, "copied", "cos_sin")
    x = np.random.default_rng(1).uniform(-1, 1, (7, 8))
    from twolink.arm.observations import features
    action, _ = model.predict(features(x, "cos_sin"), deterministic=True)
    np.testing.assert_allclose(agent(x),
                               np.clip(action, -1, 1) * links_parameters(4, "copied").tau_max,
                               rtol=0, atol=1e-12)
    assert agent.meta["links"] == 4


def test_the_arm_must_be_named_and_agree(four_links, tmp_path):
    _, path = four_links
    bare = _rewrite(path, tmp_path / "bare.zip")
    with pytest.raises(ControllerError, match="a 4-link agent must name its arm's link rule "
                                              "in a twolink.json member") as e:
        sb3_agent(bare)
    assert "\n" not in str(e.value)
    wrong = _rewrite(path, tmp_path / "wrong.zip", "twolink.json", json.dumps(
        {"schema": "twolink.agent", "version": 1, "links": 3, "rule": "tapered"}))
    with pytest.raises(ControllerError, match="its twolink.json says 3 links, its action "
                                              "space 4"):
        sb3_agent(wrong)
    junk = _rewrite(path, tmp_path / "junk.zip", "twolink.json", "not json")
    with pytest.raises(ControllerError, match="is not a twolink.agent version 1 record"):
        sb3_agent(junk)


def test_plant_model_trains_on_the_numpy_full_model(tmp_path):
    config = TrainConfig(plant="model", links=3, steps=64, envs=2, n_steps=32, eval_every=64)
    model, env = build(config)
    assert isinstance(env.plant, ModelPlant) and env.plant.name == "full"
    env.close()
    record = train(config, tmp_path)
    assert record["env"]["plant"] == "full" and record["evaluation"]["plant"] == "mujoco"
    assert [p["steps"] for p in record["curve"]] == [0, 64]


def test_the_full_plant_refuses_a_plant_drawn_per_episode():
    with pytest.raises(ValueError, match="plant='full' steps one fixed plant"):
        TwoLinkSB3VecEnv(2, plant="full", perturbation=0.1)


def test_the_training_benchmark_rows():
    from benchmarks import training

    rows, summary = training.bench_training(
        links=(2,), envs=2, n_steps=8, updates=1,
        model_recipe=dict(envs=4, batch_size=16, epochs=1, std_floor=0.2))
    names = [r.name for r in rows]
    assert names[:4] == ["training, updates included: CPU per env step",
                         "vector env alone: CPU per env step",
                         "physics alone: CPU per env step", "training / physics"]
    light = [r for r in rows if "lighter recipe (batch size 1024, net 64x64)" in r.section]
    assert [r.name for r in light] == ["training, updates included: CPU per env step",
                                       "training / physics"]
    assert summary["ppo_2_light"]["train_us"] == light[0].value
    more = [k for k in summary if isinstance(k, str)]      # + IPPO/MAPPO rows where skrl is
    model = [r for r in rows if "on the model (6)" in r.section]
    assert len(names) == 4 + 2 * len(more) + 2 * len(model) // 4
    if model:                                 # MAPPO on the model, beside MuJoCo and physics
        m = summary["mappo_2_model"]
        assert [r.value for r in model[:3]] == [m["train_us"], m["mujoco_train_us"],
                                                m["plant_us"]]
        assert model[3].value == pytest.approx(m["train_us"] / m["plant_us"])
    assert all(summary[k]["train_us"] > 0 for k in more)
    assert all(np.isfinite(r.value) and r.value > 0 for r in rows)
    assert summary[2]["train_us"] == rows[0].value
