"""Guided learning (twolink.studies.guided, docs/studies/links_guided.py): the
demonstration poses, the actions a demonstration asks of a residual agent, the files'
checks, and the clone step end to end on a demonstration made here (the solver itself is
the reach study's, tested there)."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from twolink.arm.parameters import links_parameters
from twolink.arm.task import own_motor_seconds
from twolink.artifacts import write_json
from twolink.control.residual import base_controller
from twolink.studies.guided import clone as C
from twolink.studies.guided import demos as D

ROOT = Path(__file__).resolve().parents[2]
SIX = links_parameters(6, "tapered")


def test_demonstration_poses_are_beyond_the_reach_and_one_stream_each():
    a = D.pose(SIX, D.DEMO_SEED, 3)
    assert np.array_equal(a, D.pose(SIX, D.DEMO_SEED, 3))       # any order, any process
    assert not np.array_equal(a, D.pose(SIX, D.DEMO_SEED, 4))
    assert own_motor_seconds(SIX, a[:6]).max() > 7.0 and np.all(a[6:] == 0)


def _demo(i, torques, states, ok=True):
    return {"schema": D.SCHEMA, "version": D.VERSION, "links": 6, "rule": "tapered",
            "seed": D.DEMO_SEED, "index": i, "x0": states[0].tolist(), "reachable": True,
            "solve_s": 1.0, "torques": torques.tolist(), "states": states.tolist(),
            "replay_success": ok}


def test_a_demonstrations_actions_are_its_torques_less_the_pd_over_tau_max():
    pd = base_controller("pd", SIX)
    rng = np.random.default_rng(0)
    states = np.concatenate([rng.uniform(-3, 3, (5, 6)), rng.uniform(-1, 1, (5, 6))], 1)
    torques = rng.uniform(-1, 1, (5, 6)) * SIX.tau_max * 1.5
    obs, act = C.demo_pairs([_demo(0, torques, states)], SIX, pd)
    assert obs.shape == (5, 18) and obs.dtype == np.float32
    want = np.clip((torques - pd(states)) / SIX.tau_max, -1, 1)
    np.testing.assert_allclose(act, want, rtol=1e-6)
    np.testing.assert_allclose(obs[:, :2], np.stack([np.cos(states[:, 0]),
                                                     np.sin(states[:, 0])], 1), rtol=1e-6)


def test_load_keeps_the_replayed_ones_and_refuses_a_foreign_file(tmp_path):
    s = np.zeros((2, 12))
    write_json(D.path_of(tmp_path, 0), _demo(0, np.zeros((2, 6)), s))
    write_json(D.path_of(tmp_path, 1), _demo(1, np.zeros((2, 6)), s, ok=False))
    assert [d["index"] for d in D.load(tmp_path)] == [0]
    D.path_of(tmp_path, 2).write_text(json.dumps({"schema": "other", "version": 1}))
    with pytest.raises(ValueError, match="pose_0002.json is not a twolink.guided_demo"):
        D.load(tmp_path)


def test_clone_end_to_end_on_a_made_demonstration(tmp_path):
    pytest.importorskip("stable_baselines3")
    from twolink.control.sb3_agent import SB3Agent
    from twolink.sim.plants import make_plant
    from twolink.sim.rollout import rollout

    x0 = D.pose(SIX, D.DEMO_SEED, 0)
    pd = base_controller("pd", SIX)
    with make_plant("mujoco", SIX) as plant:          # a demonstration: the PD's own run
        traj = rollout(pd, plant, x0[None], duration=1.0)
    states, torques = traj.x[0, :20], traj.u[0, :20]
    (tmp_path / "demos").mkdir()
    write_json(D.path_of(tmp_path / "demos", 0), _demo(0, torques, states))
    out = tmp_path / "cloned.zip"
    r = subprocess.run([sys.executable, str(ROOT / "docs/studies/links_guided.py"), "clone",
                        "--folder", str(tmp_path / "demos"), "--epochs", "3", "-o", str(out)],
                       capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    result = json.loads(r.stdout.strip().splitlines()[-1])
    assert result["demonstrations"] == 1
    assert result["after"]["demo"] < result["before"]["demo"]
    agent = SB3Agent(out)                                 # a controller of six links
    assert (agent.links, agent.base_name) == (6, "pd")
    assert agent(x0[None]).shape == (1, 6)
    bad = subprocess.run([sys.executable, str(ROOT / "docs/studies/links_guided.py"), "clone",
                          "--folder", str(tmp_path / "none"), "-o", str(out)],
                         capture_output=True, text=True, cwd=tmp_path)
    assert bad.returncode == 2 and "no demonstration whose replay succeeded" in bad.stderr
    assert len(bad.stderr.strip().splitlines()) == 1


def test_replay_gives_its_torques_then_none_and_restarts_on_reset():
    torques = np.arange(12, dtype=float).reshape(2, 3, 2)       # 2 rows, 3 samples, 2 joints
    replay, x = D.Replay(torques), np.zeros((2, 4))
    got = [replay(x) for _ in range(4)]
    np.testing.assert_array_equal(np.stack(got[:3], 1), torques)
    assert np.all(got[3] == 0) and got[3].shape == (2, 2)
    replay.reset(2)
    np.testing.assert_array_equal(replay(x), torques[:, 0])
