"""`twolink train` (twolink.training): a smoke run resumed after an interruption gives
bit for bit the curve and weights of an uninterrupted one; a 3-link run's agent is a
3-link controller; bad inputs and foreign checkpoints are one line, exit 2; a finished
run is never written over. Skipped where Stable-Baselines3 is not installed."""
from __future__ import annotations

import io
import json
import zipfile

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
import torch  # noqa: E402

from twolink.cli import main  # noqa: E402
from twolink.control.controllers import resolve_controller  # noqa: E402
from twolink.training import checkpoint  # noqa: E402
from twolink.training.config import TrainConfig  # noqa: E402
from twolink.training.run import CLOCKS, train  # noqa: E402

#: A PPO smoke run: 4 arms x 32 steps per update (128 steps), 6 updates, 3 evaluations.
SMOKE = dict(algo="ppo", links=2, steps=768, envs=4, n_steps=32, eval_every=256)


def _weights(path):
    with zipfile.ZipFile(path) as z:
        return torch.load(io.BytesIO(z.read("policy.pth")), weights_only=True)


def _same(a, b) -> bool:
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


def _plain(curve):
    return [{k: v for k, v in p.items() if k not in CLOCKS} for p in curve]


class Stop(Exception):
    pass


def _interrupted(config, out, after: int):
    """Run ``config`` into ``out`` and stop it after the ``after``-th evaluation."""
    seen = []

    def stop(line):
        seen.append(line)
        if len(seen) == after:
            raise Stop

    with pytest.raises(Stop):
        train(config, out, progress=stop)


@pytest.fixture(scope="module")
def whole_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("whole")
    return train(TrainConfig(**SMOKE), out), out


@pytest.mark.parametrize("after", [1, 2])
def test_a_resumed_run_is_bit_for_bit_the_uninterrupted_one(whole_run, tmp_path, after):
    record, whole = whole_run
    _interrupted(TrainConfig(**SMOKE), tmp_path, after)
    assert not (tmp_path / "ppo_2links_seed0.zip").exists()
    assert len(json.loads((tmp_path / "curve.json").read_text())["curve"]) == after
    resumed = train(None, tmp_path, resume=True)
    assert [p["steps"] for p in resumed["curve"]] == [0, 256, 512, 768]
    assert _plain(resumed["curve"]) == _plain(record["curve"])
    assert resumed["resumed_at"] == [256 * (after - 1)]
    assert _same(_weights(tmp_path / "ppo_2links_seed0.zip"),
                 _weights(whole / "ppo_2links_seed0.zip"))
    a, _ = checkpoint.load(tmp_path / "checkpoint.pt")
    b, _ = checkpoint.load(whole / "checkpoint.pt")
    assert a["plain"] == b["plain"]              # counters, generators, arms: the same
    assert resumed["best"] == record["best"]     # the best point and its agent, too
    assert _same(_weights(tmp_path / record["best"]["agent"]),
                 _weights(whole / record["best"]["agent"]))


def test_the_best_agent_is_the_policy_of_the_curves_best_point(whole_run, tmp_path):
    record, out = whole_run
    curve, best = record["curve"], record["best"]
    top = max(p["successes"] for p in curve)
    latest = max(p["steps"] for p in curve if p["successes"] == top)
    assert (best["steps"], best["successes"], best["n"]) == (latest, top, 65)
    assert best["agent"] == "ppo_2links_seed0.best.zip"
    agent = resolve_controller(str(out / best["agent"]))
    assert agent.meta["steps"] == best["steps"]            # the policy of that point
    from twolink.sim.evaluation import evaluate
    assert evaluate(agent, nthread=1).score.successes == best["successes"]


def test_the_comparison_can_fail(whole_run, tmp_path):
    """A resumed run whose torch generator was not restored ends on other weights."""
    record, whole = whole_run
    _interrupted(TrainConfig(**SMOKE), tmp_path, 2)
    header, tensors = checkpoint.load(tmp_path / "checkpoint.pt")
    tensors["torch_rng"] = torch.manual_seed(12345).get_state()
    checkpoint.save(tmp_path / "checkpoint.pt", header, tensors)
    train(None, tmp_path, resume=True)
    assert not _same(_weights(tmp_path / "ppo_2links_seed0.zip"),
                     _weights(whole / "ppo_2links_seed0.zip"))


def test_the_curve_and_the_agent(whole_run):
    record, out = whole_run
    on_disk = json.loads((out / "curve.json").read_text())
    assert on_disk["done"] is True and on_disk["steps"] == 768
    assert on_disk["agent"] == "ppo_2links_seed0.zip"
    for p in on_disk["curve"]:
        assert p["n"] == 65 and 0 <= p["successes"] <= 65
        assert p["wilson_95"][0] <= p["rate"] <= p["wilson_95"][1]
        assert p["cpu_s"] >= 0 and p["wall_s"] >= 0
    assert on_disk["curve"][-1]["steps_per_s"] > 0
    agent = resolve_controller(str(out / "ppo_2links_seed0.zip"))
    x = np.array([[-1.0, -3.0, 0.0, 0.0], [0.5, 0.2, 0.1, -0.1]])
    u = agent(x)
    assert u.shape == (2, 2) and np.all(np.abs(u) <= [200, 50])


def test_a_three_link_run_gives_a_three_link_controller(tmp_path, capsys):
    assert main(["train", "--links", "3", "--steps", "128", "--envs", "4", "--n-steps", "32",
                 "--eval-every", "128", "--out", str(tmp_path), "--json"]) == 0
    out = capsys.readouterr()
    record = json.loads(out.out)
    assert [p["n"] for p in record["curve"]] == [64, 64]        # 64 random poses, 8 s
    assert "train ppo 3 links seed 0: 128/128 steps" in out.err
    agent = resolve_controller(str(tmp_path / "ppo_3links_seed0.zip"), links=3)
    u = agent(np.zeros((5, 6)) + 0.3)
    assert u.shape == (5, 3)
    with zipfile.ZipFile(tmp_path / "ppo_3links_seed0.zip") as z:
        assert json.loads(z.read("twolink.json"))["links"] == 3
        assert z.read("data").startswith(b"{")
    with pytest.raises(ValueError, match=r"a 3-link agent maps states \(\.\.\., 6\)"):
        resolve_controller(str(tmp_path / "ppo_3links_seed0.zip"))(np.zeros((1, 4)))


def _err(capsys, argv) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


def test_bad_inputs_are_one_line(tmp_path, capsys):
    assert "--observe is for --algo ippo|mappo" in _err(
        capsys, ["train", "--algo", "ppo", "--observe", "local"])
    assert "--steps must be a whole number" in _err(capsys, ["train", "--steps", "1.5"])
    assert "links" in _err(capsys, ["train", "--links", "7", "--out", str(tmp_path / "a")])
    assert "n_steps (the rollout length per arm) is PPO's" in _err(
        capsys, ["train", "--algo", "sac", "--n-steps", "8"])
    assert "no run in" in _err(capsys, ["train", "--resume", "--out", str(tmp_path / "b")])


def test_foreign_and_truncated_checkpoints_are_one_line(whole_run, tmp_path, capsys):
    _interrupted(TrainConfig(**SMOKE), tmp_path, 2)
    ckpt = tmp_path / "checkpoint.pt"
    good = ckpt.read_bytes()
    assert "checkpoint of a run with links 2, not 3" in _err(
        capsys, ["train", "--resume", "--links", "3", "--out", str(tmp_path)])
    assert "checkpoint of a run with algo 'ppo', not 'sac'" in _err(
        capsys, ["train", "--resume", "--algo", "sac", "--out", str(tmp_path)])
    ckpt.write_bytes(good[: len(good) // 2])
    assert "is not a readable twolink training checkpoint (truncated or foreign" in _err(
        capsys, ["train", "--resume", "--out", str(tmp_path)])
    torch.save({"header": json.dumps({"schema": "other"}), "state": {}}, ckpt)
    assert "is not a twolink training checkpoint" in _err(
        capsys, ["train", "--resume", "--out", str(tmp_path)])
    header, tensors = None, None
    ckpt.write_bytes(good)
    header, tensors = checkpoint.load(ckpt)
    checkpoint.save(ckpt, dict(header, versions=dict(header["versions"],
                                                     stable_baselines3="1.0")), tensors)
    assert "written by Stable-Baselines3 1.0" in _err(
        capsys, ["train", "--resume", "--out", str(tmp_path)])
    # An interrupted run is not started afresh over its checkpoint.
    assert "holds an interrupted run; --resume continues it" in _err(
        capsys, ["train", "--steps", "768", "--out", str(tmp_path)])


def test_a_finished_run_is_never_written_over(whole_run, capsys):
    _, out = whole_run
    before = (out / "curve.json").read_text()
    assert "holds a finished run" in _err(capsys, ["train", "--out", str(out)])
    assert "holds a finished run" in _err(capsys, ["train", "--resume", "--out", str(out)])
    assert (out / "curve.json").read_text() == before


def test_steps_and_evaluations_are_whole_updates():
    c = TrainConfig(algo="ppo", steps=1000, envs=4, n_steps=32, eval_every=300)
    assert (c.unit(), c.total_steps(), c.every()) == (128, 1024, 384)
    s = TrainConfig(algo="sac", steps=10, envs=8)
    assert (s.unit(), s.total_steps(), s.every()) == (8, 16, 10_000)
    with pytest.raises(ValueError, match="algo must be one of 'ppo', 'sac', got 'a2c'"):
        TrainConfig(algo="a2c")
