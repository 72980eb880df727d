"""`twolink train --algo ippo|mappo` (twolink.training.marl, skrl): smoke runs at 2 and 3
links, the curve, the saved agent as a decentralized controller that `twolink evaluate`
scores, exact resume, and bad inputs as one line."""
from __future__ import annotations

import builtins
import json
import shutil

import numpy as np
import pytest

pytest.importorskip("torch")
pytest.importorskip("skrl")

import torch  # noqa: E402

from twolink.arm.parameters import state_names  # noqa: E402
from twolink.cli import main  # noqa: E402
from twolink.control.controllers import resolve_controller  # noqa: E402
from twolink.control.marl_agent import agent_observation, load_marl_agent  # noqa: E402
from twolink.envs.multi_agent import agent_components, agent_observations  # noqa: E402
from twolink.sim.controller import ControllerError  # noqa: E402
from twolink.training import checkpoint, marl_state  # noqa: E402
from twolink.training.marl import MarlConfig, train  # noqa: E402
from twolink.training.run import CLOCKS  # noqa: E402

SMALL = dict(envs=8, n_steps=64, eval_every=2048, steps=2048)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """IPPO and MAPPO at 2 and 3 links, 2048 steps each (4 updates, 2 evaluations)."""
    out = {}
    for algo in ("ippo", "mappo"):
        for links in (2, 3):
            folder = tmp_path_factory.mktemp(f"{algo}{links}")
            config = MarlConfig(algo=algo, links=links, seed=5, observe="neighbours", **SMALL)
            out[algo, links] = (train(config, folder), folder)
    return out


def _err(capsys, argv) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


@pytest.mark.parametrize("algo", ["ippo", "mappo"])
@pytest.mark.parametrize("links", [2, 3])
def test_a_smoke_run_gives_a_curve_and_a_controller(runs, algo, links):
    record, folder = runs[algo, links]
    curve = json.loads((folder / "curve.json").read_text())
    assert curve["done"] is True and curve["steps"] == 2048
    assert [p["steps"] for p in curve["curve"]] == [0, 2048]
    assert all(p["n"] == (65 if links == 2 else 64) for p in curve["curve"])
    assert curve["env"]["reward"] == ("shaped" if algo == "ippo" else "shaped_team")
    assert curve["versions"]["skrl"] == "2.1.1"
    agent = folder / f"{algo}_{links}links_neighbours_seed5.marl.pt"
    assert curve["agent"] == agent.name and agent.is_file()
    ctrl = resolve_controller(str(agent), links=links)
    x = np.random.default_rng(0).uniform(-1, 1, (7, 2 * links))
    tau = ctrl(x)
    limit = load_marl_agent(agent).tau_max
    assert tau.shape == (7, links) and np.all(np.abs(tau) <= limit + 1e-12)
    assert ctrl.name == agent.name[:-len(".marl.pt")]


def test_the_policies_learned_something(runs, tmp_path):
    """The saved weights are not the initial ones of the same seed (updates happened)."""
    _, folder = runs["ippo", 2]
    saved = torch.load(folder / "ippo_2links_neighbours_seed5.marl.pt",
                       weights_only=True)["policies"]
    fresh = marl_state.Learner(MarlConfig(algo="ippo", links=2, seed=5, **SMALL), torch)
    try:
        init = fresh.policy_state()
    finally:
        fresh.close()
    assert set(saved) == {"link1", "link2"}
    assert not torch.equal(saved["link1"]["0.weight"], init["link1"]["0.weight"])


def test_mappo_critics_see_the_whole_state_ippo_critics_their_own(tmp_path):
    for algo, width in (("ippo", None), ("mappo", 9)):
        learner = marl_state.Learner(MarlConfig(algo=algo, links=3, observe="local", **SMALL),
                                     torch)
        try:
            for a in learner.agents:
                assert learner.models[a]["policy"].net[0].in_features == 3   # cos, sin, speed
                critic = learner.models[a]["value"].net[0].in_features
                assert critic == (width or 3)
        finally:
            learner.close()


@pytest.mark.parametrize("observe", ["local", "neighbours", "global"])
def test_the_controller_observes_as_the_env(observe):
    """Each agent's observation in the controller is the env's (cos_sin) bit for bit."""
    names = state_names(4)
    x = np.random.default_rng(1).uniform(-3, 3, (5, 8))
    env = agent_observations(x, 4, observe, "cos_sin")
    for i, comp in enumerate(agent_components(4, observe)):
        cols = [names.index(c) for c in comp]
        mine = agent_observation(x, cols, [c.startswith("theta") for c in comp])
        assert np.array_equal(mine, env[i])


def test_evaluate_scores_the_saved_agent(runs, capsys):
    _, folder = runs["mappo", 3]
    agent = folder / "mappo_3links_neighbours_seed5.marl.pt"
    assert main(["evaluate", str(agent), "--links", "3", "--poses", "4"]) == 0
    out = capsys.readouterr().out
    assert "mappo_3links_neighbours_seed5 on 3 links" in out and "/4 =" in out
    assert "drives an arm of 3 links" in _err(capsys, ["evaluate", str(agent)])


def _resumed_equals_whole(tmp_path, common: dict, steps: int):
    """A run of ``steps`` and the same run stopped at 64 and resumed by the command: their
    final policies are equal; (whole record, resumed curve, final policies)."""
    whole = train(MarlConfig(steps=steps, **common), tmp_path / "whole")
    train(MarlConfig(steps=64, **common), tmp_path / "part")
    record = json.loads((tmp_path / "part" / "curve.json").read_text())
    (tmp_path / "part" / record["agent"]).unlink()              # as if stopped at 64
    assert main(["train", "--resume", "-o", str(tmp_path / "part"), "--steps",
                 str(steps)]) == 0
    resumed = json.loads((tmp_path / "part" / "curve.json").read_text())
    a = torch.load(tmp_path / "whole" / whole["agent"], weights_only=True)["policies"]
    b = torch.load(tmp_path / "part" / resumed["agent"], weights_only=True)["policies"]
    assert all(torch.equal(a[k][n], b[k][n]) for k in a for n in a[k])
    return whole, resumed, a


@pytest.mark.parametrize("algo", ["ippo", "mappo"])
def test_a_resumed_run_is_bit_for_bit_the_uninterrupted_one(tmp_path, algo):
    common = dict(algo=algo, links=3, envs=4, n_steps=16, eval_every=64, seed=3,
                  observe="local")
    whole, resumed, a = _resumed_equals_whole(tmp_path, common, 192)
    strip = [{k: v for k, v in p.items() if k not in CLOCKS} for p in whole["curve"]]
    assert strip == [{k: v for k, v in p.items() if k not in CLOCKS}
                     for p in resumed["curve"]]
    assert resumed["resumed_at"] == [64]
    assert resumed["best"] == whole["best"]             # the best point's agent, too
    a_best = torch.load(tmp_path / "whole" / whole["best"]["agent"], weights_only=True)
    b_best = torch.load(tmp_path / "part" / resumed["best"]["agent"], weights_only=True)
    assert all(torch.equal(a_best["policies"][k][n], b_best["policies"][k][n])
               for k in a_best["policies"] for n in a_best["policies"][k])
    # the comparison can fail: another seed gives other weights
    other = train(MarlConfig(steps=64, **dict(common, seed=4)), tmp_path / "other")
    c = torch.load(tmp_path / "other" / other["agent"], weights_only=True)["policies"]
    assert not torch.equal(c["link1"]["0.weight"], a["link1"]["0.weight"])


def test_bad_inputs_are_one_line(runs, tmp_path, capsys):
    assert "--observe must be one of 'local', 'neighbours', 'global', got 'east'" in _err(
        capsys, ["train", "--algo", "ippo", "--observe", "east"])
    assert "a challenge draws a new plant every episode: train it on --plant mujoco" in _err(
        capsys, ["train", "--algo", "mappo", "--plant", "model", "--challenge", "medium"])
    assert "links" in _err(capsys, ["train", "--algo", "ippo", "--links", "7",
                                    "-o", str(tmp_path / "x")])
    # a checkpoint of another algo or arm
    _, folder = runs["mappo", 3]
    part = tmp_path / "part"
    shutil.copytree(folder, part)
    (part / "mappo_3links_neighbours_seed5.marl.pt").unlink()
    assert "with algo 'mappo', not 'ippo'" in _err(
        capsys, ["train", "--resume", "--algo", "ippo", "-o", str(part)])
    assert "with links 3, not 2" in _err(
        capsys, ["train", "--resume", "--algo", "mappo", "--links", "2", "-o", str(part)])
    assert "with observe 'neighbours', not 'local'" in _err(
        capsys, ["train", "--resume", "--observe", "local", "-o", str(part)])
    # the checkpoint alone (no curve): its header says it is a multi-agent run
    alone = tmp_path / "alone"
    alone.mkdir()
    shutil.copy(part / "checkpoint.pt", alone / "checkpoint.pt")
    assert "with links 3, not 2" in _err(
        capsys, ["train", "--resume", "--links", "2", "-o", str(alone)])
    with pytest.raises(ValueError, match="checkpoint of a mappo run .skrl., not of a ppo or "
                                         "sac run: resume it with --algo mappo"):
        checkpoint.load(alone / "checkpoint.pt")
    # a Stable-Baselines3 run's checkpoint, and a truncated one
    checkpoint.save(tmp_path / "sb3.pt", {"config": {"algo": "ppo"}}, {})
    with pytest.raises(ValueError, match="checkpoint of a ppo run .Stable-Baselines3."):
        marl_state.load(tmp_path / "sb3.pt")
    data = (part / "checkpoint.pt").read_bytes()
    (part / "checkpoint.pt").write_bytes(data[:len(data) // 2])
    assert "is not a readable twolink training checkpoint" in _err(
        capsys, ["train", "--resume", "--algo", "mappo", "-o", str(part)])


def test_bad_agent_files_are_one_line(runs, tmp_path):
    _, folder = runs["ippo", 2]
    good = folder / "ippo_2links_neighbours_seed5.marl.pt"
    cut = tmp_path / "cut.marl.pt"
    cut.write_bytes(good.read_bytes()[:500])
    foreign = tmp_path / "foreign.marl.pt"
    torch.save({"weights": torch.zeros(3)}, foreign)
    obj = torch.load(good, weights_only=True)
    header = json.loads(obj["header"])
    bad_links = tmp_path / "links.marl.pt"
    torch.save(dict(obj, header=json.dumps(dict(header, links=9))), bad_links)
    bad_sizes = tmp_path / "sizes.marl.pt"
    torch.save(dict(obj, header=json.dumps(dict(header, hidden=[32, 64]))), bad_sizes)
    nan = tmp_path / "nan.marl.pt"
    obj["policies"]["link2"]["0.bias"][0] = float("nan")
    torch.save(obj, nan)
    for path, why in ((cut, "truncated or foreign"), (foreign, "no twolink.marl_agent header"),
                      (bad_links, "links 9"), (bad_sizes, "weights of link1 do not fit"),
                      (nan, "weights of link2 hold NaN"),
                      (tmp_path / "none.marl.pt", "no multi-agent save")):
        with pytest.raises(ControllerError) as exc:
            resolve_controller(str(path))
        assert why in str(exc.value) and "\n" not in str(exc.value), (path, exc.value)


def test_a_missing_skrl_is_one_line_naming_the_extra(tmp_path, capsys, monkeypatch):
    real = builtins.__import__

    def no_skrl(name, *args, **kwargs):
        if name == "skrl" or name.startswith("skrl."):
            raise ImportError(f"No module named {name!r}")
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_skrl)
    err = _err(capsys, ["train", "--algo", "ippo", "--steps", "10",
                        "-o", str(tmp_path / "r")])
    assert "needs skrl, the marl extra: pip install 'twolink[marl]'" in err
    assert not (tmp_path / "r").exists()


def test_value_norm_standardizes_the_critics_returns_and_resumes_exactly(tmp_path, capsys):
    common = dict(algo="mappo", links=3, envs=4, n_steps=16, eval_every=64, seed=3,
                  value_norm=True)
    assert MarlConfig(**common).as_dict()["value_norm"] is True
    whole, _, _ = _resumed_equals_whole(tmp_path, common, 128)
    assert whole["agent"] == "mappo_3links_neighbours_vn_seed3.marl.pt"
    _, tensors = marl_state.load(tmp_path / "whole" / "checkpoint.pt")
    scaler = tensors["value_scalers"]["link1"]
    assert scaler["current_count"] > 1 and scaler["running_variance"] > 0
    alone = tmp_path / "alone"                   # the checkpoint alone, resumed without it
    alone.mkdir()
    shutil.copy(tmp_path / "whole" / "checkpoint.pt", alone / "checkpoint.pt")
    with pytest.raises(ValueError, match="with value_norm True, not False"):
        train(MarlConfig(steps=192, **dict(common, value_norm=False)), alone, resume=True)
    capsys.readouterr()
    assert "--value-norm is for --algo ippo|mappo" in _err(
        capsys, ["train", "--value-norm", "-o", str(tmp_path / "ppo")])
    with pytest.raises(ValueError, match="value_norm must be true or false"):
        MarlConfig(value_norm="yes")
