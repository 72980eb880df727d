"""`twolink train --algo ippo|mappo --challenge LEVEL --history K --action-rate C`: the
refusals, the arms' training stream, each agent's own history in the learner and in the
saved controller (stateful within an episode, reset per rollout), the per-agent and team
action-rate penalty, the header's round trip and a loader that refuses a mismatched
history, a smoke run under medium that resumes bit for bit, and `twolink evaluate` of its
agent under medium. Skipped without torch and skrl."""
from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("torch")
pytest.importorskip("skrl")

import torch  # noqa: E402

from twolink.cli import main  # noqa: E402
from twolink.control.history import history_layout  # noqa: E402
from twolink.control.marl_agent import agent_observation, load_marl_agent  # noqa: E402
from twolink.envs.pettingzoo_batched import batched_parallel_env  # noqa: E402
from twolink.sim.controller import ControllerError  # noqa: E402
from twolink.sim.evaluation import evaluate  # noqa: E402
from twolink.sim.metrics import evaluation_set  # noqa: E402
from twolink.training import marl, marl_state  # noqa: E402
from twolink.training.action_rate import agent_penalties  # noqa: E402
from twolink.training.config import EVAL_PLANTS, EVAL_SEED, train_stream  # noqa: E402
from twolink.training.marl import MarlConfig, train  # noqa: E402
from twolink.training.run import CLOCKS  # noqa: E402

LEVEL = dict(challenge="medium", history=3, action_rate=1.0, observe="local", seed=1)
SMALL = dict(envs=8, n_steps=64, eval_every=1024)


@pytest.fixture
def one_plant(monkeypatch):
    """The curve's evaluation on one plant of the level instead of 8 (a faster test; the
    protocol is otherwise the same and recorded as such)."""
    monkeypatch.setattr(marl, "EVAL_PLANTS", 1)


def _err(capsys, argv) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


def test_refusals_are_one_line(tmp_path, capsys):
    with pytest.raises(ValueError, match="perturb the two-link arm of Table I; this run has 3"):
        MarlConfig(links=3, challenge="medium")
    assert "this run has 4 links" in _err(capsys, [
        "train", "--algo", "mappo", "--links", "4", "--challenge", "hard",
        "-o", str(tmp_path / "a")])
    for k in ("0", "17", "two"):
        assert "--history must be a whole number from 1 to 16" in _err(
            capsys, ["train", "--algo", "ippo", "--history", k, "-o", str(tmp_path / "b")])
    with pytest.raises(ValueError, match="history must be a whole number of samples"):
        MarlConfig(history=0)
    for seed in (2026, 20061122):
        assert f"seed {seed} is an evaluation seed" in _err(capsys, [
            "train", "--algo", "ippo", "--challenge", "medium", "--seed", str(seed),
            "-o", str(tmp_path / "c")])
    assert MarlConfig(seed=2026).seed == 2026            # refused under a challenge only
    assert "--action-rate must be a number from 0 to 100" in _err(
        capsys, ["train", "--algo", "mappo", "--action-rate", "-1", "-o", str(tmp_path / "d")])
    assert "challenge level must be one of" in _err(
        capsys, ["train", "--algo", "ippo", "--challenge", "brutal", "-o", str(tmp_path / "e")])
    assert not any(tmp_path.iterdir())


def test_names_and_the_curve_protocol_are_ppos():
    c = MarlConfig(algo="mappo", **LEVEL)
    assert marl.run_name(c) == "mappo_2links_local_medium_h3_ar1_seed1"
    assert marl.run_name(MarlConfig(observe="local", seed=2)) == "ippo_2links_local_seed2"
    p = marl.evaluation_protocol(c)
    assert (p["challenge"], p["plants"], p["seed"]) == ("medium", EVAL_PLANTS, EVAL_SEED)
    assert c.env_options()["challenge"] == "medium"
    assert c.arm_seed() == train_stream(1) != 1 and MarlConfig(seed=1).arm_seed() == 1


def test_the_arms_draw_from_the_training_stream():
    """The learner's arms start as a batched env reset with train_stream(seed): arm i on
    the plant of seed train_stream(seed) + i, none of them an evaluation plant."""
    learner = marl_state.Learner(MarlConfig(algo="ippo", envs=4, n_steps=8, **LEVEL), torch)
    ref = batched_parallel_env(4, **learner.config.env_options())
    try:
        learner.learn(4, 32)                                    # one vector step
        ref.reset(seed=train_stream(1))
        mine, theirs = learner.env._live().plant.params, ref._live().plant.params
        assert mine == theirs and len(set(mine)) == 4
        from twolink.sim.challenges import LEVELS
        assert not set(mine) & set(LEVELS["medium"].plants(EVAL_PLANTS, EVAL_SEED))
    finally:
        learner.close()
        ref.close()


def test_each_agent_sees_its_own_history_in_training_and_in_the_controller():
    learner = marl_state.Learner(MarlConfig(algo="mappo", envs=4, n_steps=8, **LEVEL), torch)
    try:
        for a in learner.agents:        # local: cos, sin, speed -> 3 * 3 + 2 numbers
            assert learner.models[a]["policy"].net[0].in_features == 11
            assert learner.models[a]["value"].net[0].in_features == 6     # the whole state
        ctrl = learner.controller()
        x = [np.random.default_rng(i).uniform(-2, 2, (5, 4)) for i in range(4)]
        ctrl.reset(5)
        first = [ctrl(v) for v in x]
        # by hand: each agent's last 3 observations and 2 actions, zeros before the start
        hist = learner.histories.__class__(learner.agents, 5, {a: 3 for a in learner.agents}, 3)
        for k, v in enumerate(x):
            h = hist.start({a: agent_observation(v, ctrl.columns[i], ctrl.angles[i])
                            for i, a in enumerate(learner.agents)}) if k == 0 else None
            if k:
                obs = {a: agent_observation(v, ctrl.columns[i], ctrl.angles[i])
                       for i, a in enumerate(learner.agents)}
                h, _ = hist.step(obs, obs, np.zeros(5, bool))
            acts = {}
            for i, a in enumerate(learner.agents):
                with torch.no_grad():
                    out = ctrl.nets[i](torch.as_tensor(h[a], dtype=torch.float32))
                acts[a] = out.double().numpy()
                want = np.clip(acts[a][:, 0], -1, 1) * ctrl.tau_max[i]
                assert np.array_equal(first[k][:, i], want)
            hist.act(acts)
        assert hist.buffers["link1"].actions.any()
        again = [ctrl(v) for v in x]                     # the history carries on ...
        assert not np.array_equal(again[0], first[0])
        ctrl.reset(5)                                    # ... until a new episode
        assert np.array_equal(ctrl(x[0]), first[0])
    finally:
        learner.close()


def test_the_action_rate_penalty_per_agent_and_per_team():
    a, last = np.array([[0.5, -1.0], [2.0, 0.0]]), np.array([[0.0, 0.0], [0.5, 0.5]])
    own = agent_penalties(a, last, 2.0)
    assert np.allclose(own, [[0.5, 2.0], [0.5, 0.5]])          # clipped to [-1, 1]
    assert np.allclose(agent_penalties(a, last, 2.0, team=True), [[1.25, 1.25], [0.5, 0.5]])
    # in the learner: the rewards recorded are the env's less the penalty
    got = {}
    for c in (0.0, 3.0):
        learner = marl_state.Learner(MarlConfig(algo="ippo", envs=4, n_steps=8, **dict(
            LEVEL, action_rate=c)), torch)
        seen = []
        learner.agent.record_transition = lambda **k: seen.append(
            (k["actions"], k["rewards"], k["truncated"]))
        learner.agent.post_interaction = lambda **k: None
        try:
            learner.learn(12, 32)
        finally:
            learner.close()
        got[c] = seen
    prev = np.zeros((4, 2))
    for (acts, r0, _), (acts3, r3, _) in zip(got[0.0], got[3.0]):
        a = np.concatenate([acts3[k].numpy() for k in ("link1", "link2")], 1)
        assert np.array_equal(a, np.concatenate([acts[k].numpy() for k in ("link1", "link2")], 1))
        pen = agent_penalties(a.astype(float), prev, 3.0)
        for i, k in enumerate(("link1", "link2")):
            assert np.allclose(r0[k].numpy()[:, 0] - r3[k].numpy()[:, 0], pen[:, i], atol=1e-5)
        prev = np.clip(a.astype(float), -1, 1)
    assert pen.max() > 0.01


@pytest.mark.parametrize("algo", ["ippo", "mappo"])
def test_a_run_under_medium_resumes_bit_for_bit(tmp_path, one_plant, capsys, algo):
    whole = train(MarlConfig(algo=algo, steps=2048, **SMALL, **LEVEL), tmp_path / "whole")
    name = f"{algo}_2links_local_medium_h3_ar1_seed1.marl.pt"
    assert whole["agent"] == name and whole["config"]["challenge"] == "medium"
    assert whole["evaluation"]["challenge"] == "medium" and whole["evaluation"]["plants"] == 1
    assert [p["n"] for p in whole["curve"]] == [65, 65, 65]
    train(MarlConfig(algo=algo, steps=1024, **SMALL, **LEVEL), tmp_path / "part")
    (tmp_path / "part" / name).unlink()                       # as if stopped at 1024
    assert main(["train", "--resume", "-o", str(tmp_path / "part"), "--steps", "2048"]) == 0
    resumed = json.loads((tmp_path / "part" / "curve.json").read_text())
    a = torch.load(tmp_path / "whole" / name, weights_only=True)["policies"]
    b = torch.load(tmp_path / "part" / name, weights_only=True)["policies"]
    assert all(torch.equal(a[k][n], b[k][n]) for k in a for n in a[k])
    strip = [{k: v for k, v in p.items() if k not in CLOCKS} for p in whole["curve"]]
    assert strip == [{k: v for k, v in p.items() if k not in CLOCKS}
                     for p in resumed["curve"]]
    assert resumed["resumed_at"] == [1024]
    # a resume checks the run's challenge, history and action rate
    (tmp_path / "part" / name).unlink()
    capsys.readouterr()
    for opt, value, why in (("--history", "2", "with history 3, not 2"),
                            ("--challenge", "hard", "with challenge 'medium', not 'hard'"),
                            ("--action-rate", "2", "with action_rate 1.0, not 2.0")):
        assert why in _err(capsys, ["train", "--resume", opt, value, "-o",
                                    str(tmp_path / "part")])


def test_the_saved_agent_round_trips_and_evaluate_scores_it(tmp_path, one_plant, capsys):
    out = tmp_path / "run"
    assert main(["train", "--algo", "ippo", "--observe", "local", "--challenge", "medium",
                 "--history", "3", "--action-rate", "1", "--seed", "1", "--envs", "8",
                 "--n-steps", "64", "--steps", "1024", "--eval-every", "1024",
                 "-o", str(out)]) == 0
    text = capsys.readouterr()
    assert "under medium, history 3" in text.out and "under medium history 3" in text.err
    path = out / "ippo_2links_local_medium_h3_ar1_seed1.marl.pt"
    obj = torch.load(path, weights_only=True)
    header = json.loads(obj["header"])
    assert (header["challenge"], header["history"], header["action_rate"]) == ("medium", 3, 1.0)
    assert header["observation_layouts"] == [history_layout(3, 3, 1)] * 2
    agent = load_marl_agent(path)
    assert (agent.history, agent.meta["challenge"], agent.meta["history"]) == (3, "medium", 3)
    # twolink evaluate under medium: the score of the stateful controller, reset per rollout
    assert main(["evaluate", str(path), "--challenge", "medium", "--plants", "1", "--quick",
                 "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert (got["challenge"], got["plants"], got["n"]) == ("medium", 1, 5)
    mine = evaluate(load_marl_agent(path), challenge="medium", count=1, seed=2026,
                    x0=evaluation_set()[::13], nthread=1).score
    assert got["successes"] == mine.successes and 0 <= mine.successes <= 5
    # a header whose history or layouts disagree with the weights and columns: one line
    for change, why in (({"history": 2}, "link1's observation layout"),
                        ({"history": 2, "observation_layouts": None}, "weights of link1 do "
                                                                      "not fit"),
                        ({"history": 0}, "history 0"),
                        ({"observation_layouts": [history_layout(3, 4, 1)] * 2},
                         "not that of history 3 over its 3 observed numbers")):
        bad = tmp_path / "bad.marl.pt"
        h = {k: v for k, v in dict(header, **change).items() if v is not None}
        torch.save(dict(obj, header=json.dumps(h)), bad)
        with pytest.raises(ControllerError) as exc:
            load_marl_agent(bad)
        assert why in str(exc.value) and "\n" not in str(exc.value), (change, exc.value)
