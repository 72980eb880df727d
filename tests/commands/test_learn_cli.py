"""``twolink learn``: a short run writes a loadable checkpoint, a figure and JSON; bad input
is one line and exit 2 with nothing written; --resume continues a checkpoint."""
from __future__ import annotations

import json

import numpy as np
import pytest

from twolink.cli import main
from twolink.policy.fuzzy_policy import load_policy


def _learn(tmp_path, *extra):
    return main(["learn", "--task", "decentralized", "--steps", "32", "--arms", "8",
                 "--eval-every", "16", "--episode", "5", "-o", str(tmp_path / "run.npz"),
                 *extra])


def test_short_run_writes_a_loadable_checkpoint_figure_and_json(tmp_path, capsys):
    assert _learn(tmp_path, "--json", "--seed", "3") == 0
    out = json.loads(capsys.readouterr().out)
    assert [e["steps"] for e in out["curve"]] == [0, 16, 32]
    assert out["config"]["seed"] == 3 and out["config"]["learner"] == "decentralized"
    assert out["config"]["average"] == 200_000.0 and out["config"]["init_scale"] == 1.0
    assert out["config"]["hysteresis"] == 0.1
    assert 0 <= out["final"]["successes"] <= out["final"]["n"] == 65
    assert out["model_based"]["policy"] == "decentralized"
    policy = load_policy(str(tmp_path / "run.npz"))
    assert policy.kind == "decentralized"
    info = policy.meta["learning"]
    assert info["steps"] == 32 and info["config"]["seed"] == 3
    assert "epsilon-greedy" in info["exploration"]
    assert (tmp_path / "run_curve.png").read_bytes()[:4] == b"\x89PNG"
    assert policy([[-1.0, -3.0, 0.0, 0.0]]).shape == (1, 2)


@pytest.mark.slow
def test_warm_start_begins_at_half_the_given_q_unless_told(tmp_path, capsys):
    init = load_policy("decentralized")
    for extra, scale in (([], 0.5), (["--init-scale", "1", "--force"], 1.0)):
        assert _learn(tmp_path, "--init", "decentralized", "--average", "0", "--hysteresis",
                      "0", "--steps", "8",
                      "--eval-every", "8", "--json", *extra) == 0
        assert json.loads(capsys.readouterr().out)["config"]["init_scale"] == scale
    q = load_policy(str(tmp_path / "run.npz")).agents[0].q     # theta itself
    assert 0 < np.abs(q - init.agents[0].q).max() < 5


@pytest.mark.slow
def test_resume_continues_to_the_new_total(tmp_path, capsys):
    assert _learn(tmp_path, "--json") == 0
    capsys.readouterr()
    assert main(["learn", "--resume", str(tmp_path / "run.npz"), "--steps", "48",
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert [e["steps"] for e in out["curve"]] == [0, 16, 32, 48]
    assert load_policy(str(tmp_path / "run.npz")).meta["learning"]["steps"] == 48


def test_an_output_that_is_a_directory_is_named(tmp_path, capsys):
    assert main(["learn", "--task", "decentralized", "-o", str(tmp_path)]) == 2
    assert f"-o {tmp_path} is a directory" in capsys.readouterr().err


@pytest.mark.slow
def test_resume_refuses_new_settings_and_a_forged_iteration_count(tmp_path, capsys):
    assert _learn(tmp_path, "--json") == 0
    capsys.readouterr()
    ckpt = tmp_path / "run.npz"
    assert main(["learn", "--resume", str(ckpt), "--arms", "4", "--alpha", "0.9",
                 "--seed", "5"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("twolink learn: error: --arms, --seed, "
                                               "--alpha: a resumed run keeps the settings")
    policy = load_policy(str(ckpt))
    policy.meta["learning"]["iterations"] = -10**12
    forged = tmp_path / "forged.npz"
    policy.save(forged)
    assert main(["learn", "--resume", str(forged), "--steps", "48"]) == 2
    assert "malformed learning checkpoint (iterations must be a non-negative whole " \
        "number, got -1000000000000)" in \
        capsys.readouterr().err


@pytest.mark.parametrize("args, message", [
    (["--steps", "0"], "steps must be a whole number in [1, 100,000,000], got 0"),
    (["--steps", "-10"], "steps must be a whole number"),
    (["--steps", "1.5"], "--steps must be a whole number, got '1.5'"),
    (["--seed", "-1"], "--seed must be a non-negative whole number"),
    (["--seed", "x"], "--seed must be a whole number, got 'x'"),
    (["--arms", "0"], "arms must be a whole number"),
    (["--arms", "100000"], "arms must be a whole number in [1, 1,024]"),
    (["--alpha", "0"], "learning rate alpha must be a number in (0, 1]"),
    (["--alpha", "3"], "learning rate alpha must be a number in (0, 1]"),
    (["--init", "centralized"], "--init policy is a centralized policy; the decentralized"),
    (["--independent", "--init", "decentralized"], "agent agent1 reads a grid over"),
    (["--init", "nosuch"], "unknown policy 'nosuch'"),
    (["--init-scale", "0.5"], "--init-scale applies to a warm start (--init) only"),
    (["--init", "decentralized", "--init-scale", "0"],
     "warm-start scale must be a number in (0, 1]"),
    (["--average", "-5"], "theta average (control steps) must be a number"),
    (["--hysteresis", "nan"], "hysteresis margin must be a number in [0, 100]"),
])
def test_bad_input_is_one_line_and_writes_nothing(tmp_path, capsys, args, message):
    assert _learn(tmp_path, *args) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("twolink learn: error: ") and message in err
    assert len(err.splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


def test_existing_checkpoint_is_kept_without_force(tmp_path, capsys):
    (tmp_path / "run.npz").write_bytes(b"keep")
    assert _learn(tmp_path) == 2
    assert "exists; give --force" in capsys.readouterr().err
    assert (tmp_path / "run.npz").read_bytes() == b"keep"


def test_task_required_and_independent_only_decentralized(capsys):
    assert main(["learn", "--steps", "32"]) == 2
    assert "--task is required" in capsys.readouterr().err
    assert main(["learn", "--task", "centralized", "--independent"]) == 2
    assert "--independent applies to --task decentralized" in capsys.readouterr().err


@pytest.mark.slow
def test_sigterm_keeps_the_last_complete_checkpoint_and_it_resumes(tmp_path):
    import signal
    import subprocess
    import sys
    import time

    ckpt = tmp_path / "run.npz"
    proc = subprocess.Popen(
        [sys.executable, "-m", "twolink.cli", "learn", "--task", "decentralized", "--steps",
         "8000", "--arms", "8", "--eval-every", "40", "--episode", "5", "-o", str(ckpt)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        while not ckpt.exists() and time.monotonic() < deadline:
            time.sleep(0.2)
        assert ckpt.exists(), "no checkpoint within 60 s"
        time.sleep(1.0)
    finally:
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143 and "terminated" in err
    steps = load_policy(str(ckpt)).meta["learning"]["steps"]
    assert steps % 40 == 0 and steps < 8000
    assert [p.name for p in tmp_path.iterdir()] == ["run.npz"]    # no temporary left
    assert main(["learn", "--resume", str(ckpt), "--steps", str(steps + 40)]) == 0
    assert load_policy(str(ckpt)).meta["learning"]["steps"] == steps + 40
