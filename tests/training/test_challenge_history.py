"""`twolink train --challenge LEVEL --history K`: a medium-level PPO smoke run with a
history of 3 resumes bit for bit (the plants, delays and histories in flight included);
the level and history are recorded in the curve, the checkpoint and the agent file; a
checkpoint of another level refuses to resume; an agent of history 3 driven through
``evaluate`` sees exactly the observations the training env gave; bad inputs and agent
files whose history disagrees with their header are one line, exit 2, nothing written."""
from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from twolink.cli import main  # noqa: E402
from twolink.control.sb3_agent import sb3_agent  # noqa: E402
from twolink.sim.controller import ControllerError  # noqa: E402
from twolink.training import checkpoint  # noqa: E402
from twolink.training.config import EVAL_SEED, TrainConfig, train_stream  # noqa: E402
from twolink.training.run import CLOCKS, build, train  # noqa: E402

import io  # noqa: E402

import torch  # noqa: E402

#: 4 arms x 32 steps per update, 4 updates, 3 evaluations under medium (8 plants x 65).
SMOKE = dict(algo="ppo", links=2, steps=512, envs=4, n_steps=32, eval_every=256,
             challenge="medium", history=3)
AGENT = "ppo_2links_medium_h3_seed0.zip"


class Stop(Exception):
    pass


def _weights(path):
    with zipfile.ZipFile(path) as z:
        return torch.load(io.BytesIO(z.read("policy.pth")), weights_only=True)


def _same(a, b) -> bool:
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


def _plain(curve):
    return [{k: v for k, v in p.items() if k not in CLOCKS} for p in curve]


@pytest.fixture(scope="module")
def whole_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("whole_medium")
    return train(TrainConfig(**SMOKE), out), out


def test_a_resumed_challenge_run_is_bit_for_bit_the_uninterrupted_one(whole_run, tmp_path):
    record, whole = whole_run
    seen = []

    def stop(line):
        seen.append(line)
        if len(seen) == 2:
            raise Stop

    with pytest.raises(Stop):
        train(TrainConfig(**SMOKE), tmp_path, progress=stop)
    assert not (tmp_path / AGENT).exists()
    resumed = train(None, tmp_path, resume=True)
    assert [p["steps"] for p in resumed["curve"]] == [0, 256, 512]
    assert _plain(resumed["curve"]) == _plain(record["curve"])
    assert _same(_weights(tmp_path / AGENT), _weights(whole / AGENT))
    a, ta = checkpoint.load(tmp_path / "checkpoint.pt")
    b, tb = checkpoint.load(whole / "checkpoint.pt")
    assert a["plain"] == b["plain"]
    for key in ("plants", "history"):
        for k in ta["episodes"][key]:
            if k != "names":
                assert np.array_equal(ta["episodes"][key][k], tb["episodes"][key][k])


def test_the_level_and_history_are_recorded(whole_run, tmp_path, capsys):
    record, out = whole_run
    curve = json.loads((out / "curve.json").read_text())
    assert curve["config"]["challenge"] == "medium" and curve["config"]["history"] == 3
    assert curve["evaluation"]["challenge"] == "medium"
    assert curve["evaluation"]["seed"] == EVAL_SEED
    assert [p["n"] for p in curve["curve"]] == [8 * 65] * 3
    header, _ = checkpoint.load(out / "checkpoint.pt")
    assert header["config"]["challenge"] == "medium"
    with zipfile.ZipFile(out / AGENT) as z:
        meta = json.loads(z.read("twolink.json"))
    assert (meta["challenge"], meta["history"]) == ("medium", 3)
    assert meta["observation_layout"]["size"] == 3 * 6 + 2 * 2
    # A checkpoint of another level (or history) refuses to resume.
    copy = tmp_path / "other"
    copy.mkdir()
    (copy / "checkpoint.pt").write_bytes((out / "checkpoint.pt").read_bytes())
    assert "checkpoint of a run with challenge 'medium', not 'hard'" in _err(
        capsys, ["train", "--resume", "--challenge", "hard", "--out", str(copy)])
    assert "checkpoint of a run with history 3, not 2" in _err(
        capsys, ["train", "--resume", "--history", "2", "--out", str(copy)])


def test_episodes_draw_new_plants_from_the_training_stream():
    """Consecutive episodes of an arm run on different plants; the same seed draws the
    same ones; the arms' generators are seeded from train_stream(seed), never 2026."""
    config = TrainConfig(**dict(SMOKE, history=1))
    plants = []
    for _ in range(2):
        model, env = build(config)
        env.reset()
        seen = [list(env.plant.params)]
        for _ in range(100):                    # one episode of 5 s: every arm resets
            env.step(np.zeros((4, 2), np.float32))
        seen.append(list(env.plant.params))
        env.close()
        plants.append(seen)
    assert plants[0] == plants[1]                   # deterministic from the seed
    assert all(a != b for a, b in zip(plants[0][0], plants[0][1]))     # a new plant each
    assert len(set(plants[0][0])) == 4                                 # and per arm
    assert train_stream(0) not in (0, 2026)
    from gymnasium.utils import seeding
    from twolink.sim.challenges import challenge
    first = challenge("medium").plant(seeding.np_random(train_stream(0))[0])
    assert plants[0][0][0] == first


def test_an_agent_with_history_sees_in_evaluate_what_the_env_gave(whole_run):
    """Drive the training env (history 3, no noise) and the saved agent through
    twolink.sim.evaluation.evaluate from the same states: the policy's inputs agree bit
    for bit at every sample of the episode."""
    from twolink.envs.history import HistoryVecEnv
    from twolink.envs.sb3 import TwoLinkSB3VecEnv
    from twolink.sim.evaluation import evaluate

    _, out = whole_run
    agent = sb3_agent(out / AGENT)
    x0 = np.array([[-1.0, -3.0, 0.0, 0.0], [0.5, 0.2, 0.0, 0.0], [2.0, -1.0, 0.0, 0.0]])
    seen = []
    predict = agent.policy.predict

    def spy(obs, deterministic=True):
        seen.append(np.array(obs))
        return predict(obs, deterministic=deterministic)

    agent.policy.predict = spy
    evaluate(agent, x0=x0, nthread=1)
    env = HistoryVecEnv(TwoLinkSB3VecEnv(3, observation="cos_sin", actions="normalized",
                                         reward="shaped", nthread=1), 3)
    env.set_options([{"x0": x} for x in x0])
    obs = env.reset()
    for k in range(100):
        assert np.array_equal(obs, seen[k]), k
        action, _ = predict(obs, deterministic=True)
        obs, _, done, infos = env.step(action)
    assert done.all()
    assert np.array_equal(infos[0]["terminal_observation"][:6], seen[99][0, 6:12])
    env.close()
    # The comparison can fail: a fresh history differs from one mid-episode.
    assert not np.array_equal(seen[0], seen[1])


def _err(capsys, argv) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


def test_bad_inputs_are_one_line_and_write_nothing(tmp_path, capsys):
    out = tmp_path / "run"
    cases = [
        (["--challenge", "extreme"], "--challenge level must be one of 'none', 'easy'"),
        (["--history", "0"], "--history must be a whole number from 1 to 16, got '0'"),
        (["--history", "17"], "--history must be a whole number from 1 to 16"),
        (["--history", "-3"], "--history must be a whole number from 1 to 16"),
        (["--history", "two"], "--history must be a whole number"),
        (["--challenge", "medium", "--seed", "2026"],
         "seed 2026 is an evaluation seed (the leaderboard's and evaluate's 2026"),
        (["--challenge", "hard", "--seed", str(EVAL_SEED)],
         "training seeds must differ from the evaluation seeds"),
        (["--challenge", "easy", "--links", "3"], "challenge levels perturb the two-link arm"),
        (["--challenge", "easy", "--plant", "model"], "train it on --plant mujoco"),
    ]
    for argv, message in cases:
        assert message in _err(capsys, ["train", *argv, "--steps", "128", "--out", str(out)])
        assert not out.exists()
    with pytest.raises(ValueError, match="history must be a whole number of samples from 1 "
                                         "to 16, got 0"):
        TrainConfig(history=0)


def _rewrite(src, dst, **changes):
    with zipfile.ZipFile(src) as z, zipfile.ZipFile(dst, "w") as w:
        for info in z.infolist():
            data = z.read(info)
            if info.filename == "twolink.json":
                meta = json.loads(data)
                meta.update(changes)
                data = json.dumps(meta).encode()
            w.writestr(info, data)
    return dst


def test_an_agent_whose_history_disagrees_with_its_file_is_one_line(whole_run, tmp_path,
                                                                    capsys):
    _, out = whole_run
    agent = out / AGENT
    bad = _rewrite(agent, tmp_path / "k2.zip", history=2)
    with pytest.raises(ControllerError, match="with a history of 2 observes 10 .state. or "
                                              "14 .cos/sin. numbers"):
        sb3_agent(bad)
    with pytest.raises(ControllerError, match="says history 0; a history is a whole number"):
        sb3_agent(_rewrite(agent, tmp_path / "k0.zip", history=0))
    with pytest.raises(ControllerError, match="says history 99"):
        sb3_agent(_rewrite(agent, tmp_path / "k99.zip", history=99))
    layout = dict(json.loads(zipfile.ZipFile(agent).read("twolink.json"))
                  ["observation_layout"], observation_size=4)
    with pytest.raises(ControllerError, match="records the observation layout"):
        sb3_agent(_rewrite(agent, tmp_path / "layout.zip", observation_layout=layout))
    # Without a history in its header, the saved space (22 numbers) is no 2-link observation.
    with pytest.raises(ControllerError, match="with a history of 1 observes 4 .state. or 6"):
        sb3_agent(_rewrite(agent, tmp_path / "k1.zip", history=1, observation_layout=None))
    err = _err(capsys, ["evaluate", str(bad), "--quick"])
    assert "with a history of 2" in err
    # The agent as it was written loads and runs a batch, keeping one history per row.
    good = sb3_agent(agent)
    good.reset(2)
    u = good(np.array([[0.1, 0.2, 0.0, 0.0], [1.0, -1.0, 0.0, 0.0]]))
    assert u.shape == (2, 2) and good._buffer.actions[:, -1].any()


def test_the_resume_comparison_can_fail(whole_run, tmp_path):
    """Resumed without the mid-episode state (plants, delays, histories in flight), the
    run ends elsewhere: the resume test above can fail."""
    record, whole = whole_run
    seen = []

    def stop(line):
        seen.append(line)
        if len(seen) == 2:
            raise Stop

    with pytest.raises(Stop):
        train(TrainConfig(**SMOKE), tmp_path, progress=stop)
    header, tensors = checkpoint.load(tmp_path / "checkpoint.pt")
    del tensors["episodes"]
    checkpoint.save(tmp_path / "checkpoint.pt", header, tensors)
    train(None, tmp_path, resume=True)
    assert not _same(_weights(tmp_path / AGENT), _weights(whole / AGENT))


def test_the_command_names_level_and_history(tmp_path, capsys):
    assert main(["train", "--challenge", "hard", "--history", "2", "--seed", "5", "--steps",
                 "128", "--envs", "4", "--n-steps", "32", "--eval-every", "128", "--out",
                 str(tmp_path)]) == 0
    out = capsys.readouterr()
    assert "ppo on 2 links under hard, history 2, seed 5: 128 steps" in out.out
    assert "train ppo 2 links under hard history 2 seed 5: 128/128 steps" in out.err
    agent = sb3_agent(tmp_path / "ppo_2links_hard_h2_seed5.zip")
    assert agent.history == 2 and agent.meta["history"] == 2
