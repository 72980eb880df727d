"""docs/studies/links_own_motor.py: each pose's own-motor time beside each controller's
success on the scaling table's poses, merged per arm; bad options and foreign files get
one error line, exit 2 and nothing written."""
import json
import sys

import numpy as np
import pytest
from conftest import load_study

from twolink.arm.task import inner_excursion, own_motor_seconds
from twolink.arm.parameters import links_parameters
from twolink.sim.metrics import random_poses


@pytest.fixture
def study(monkeypatch):
    return load_study("links_own_motor", monkeypatch)


def test_a_run_records_own_motor_times_and_successes_and_merges(study, tmp_path, capsys):
    out = tmp_path / "own.json"
    assert study.main(["--links", "3", "--poses", "3", "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    assert (data["schema"], data["version"]) == (study.SCHEMA, study.VERSION)
    (run,) = data["runs"]
    x0 = random_poses(3, study.POSES, 20061122 + 3)[:3]
    own = own_motor_seconds(links_parameters(3, "tapered"), x0[:, :3])
    np.testing.assert_allclose(run["own_motor_s"], own.max(axis=1), atol=1e-4)
    assert run["slowest_joint"] == [int(j) + 1 for j in own.argmax(axis=1)]
    assert run["learned"] == [] and study.learned(6, "tapered") == ("ppo_pd_6link_tapered",
                                                                 "mappo_6link_tapered")
    assert sorted(run["success"]) == sorted(study.CONTROLLERS)
    assert "decentralized_argmax" in study.CONTROLLERS
    assert all(len(v) == 3 and set(v) <= {0, 1} for v in run["success"].values())
    assert sorted(run["excursion"]) == sorted(study.CONTROLLERS)
    assert all(len(v) == 3 and min(v) >= 0.0 for v in run["excursion"].values())
    assert sorted(run["later"]) == ["12", "16"]
    for by in run["later"].values():                     # settled by 8 s: still by 12, 16 s
        assert sorted(by) == sorted(study.CONTROLLERS)
        assert all(a <= b for k in by for a, b in zip(run["success"][k], by[k]))
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["pd"] == sum(run["success"]["pd"])
    other = dict(run, rule="copied")                     # another arm's run is kept
    data["runs"].append(other)
    out.write_text(json.dumps(data))
    assert study.main(["--links", "3", "--poses", "3", "--json", str(out)]) == 0
    kept = json.loads(out.read_text())["runs"]
    assert [(r["links"], r["rule"]) for r in kept] == [(3, "copied"), (3, "tapered")]


@pytest.mark.parametrize("argv, message", [
    (["--links", "7"], "--links must be a whole number from 3 to 6"),
    (["--links", "3", "--poses", "0"], "--poses must be a whole number from 1 to 256"),
])
def test_bad_options_are_one_line_and_exit_2(study, tmp_path, capsys, argv, message):
    out = tmp_path / "own.json"
    assert study.main(argv + ["--json", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("links_own_motor: error:") and message in err
    assert len(err.splitlines()) == 1 and not out.exists()


def test_a_foreign_file_is_refused_and_left_alone(study, tmp_path, capsys):
    out = tmp_path / "own.json"
    out.write_text(json.dumps({"schema": "twolink.links_reach", "version": 1, "runs": []}))
    before = out.read_text()
    assert study.main(["--links", "3", "--json", str(out)]) == 2
    assert "is not a twolink.links_own_motor version 2 file" in capsys.readouterr().err
    assert out.read_text() == before


@pytest.fixture(scope="module")
def agent_file(tmp_path_factory):
    """A three-link IPPO agent of 128 steps (a saved agent as `twolink train` writes it)."""
    pytest.importorskip("skrl")
    from twolink.training.marl import MarlConfig, train

    folder = tmp_path_factory.mktemp("ippo3")
    record = train(MarlConfig(algo="ippo", links=3, envs=4, n_steps=32, eval_every=128,
                              steps=128, seed=2), folder)
    return folder / record["agent"]


def test_an_agent_file_runs_beside_the_table_under_its_stem(study, agent_file, tmp_path):
    from twolink.control.controllers import resolve_controller
    from twolink.sim.metrics import success
    from twolink.sim.plants import make_plant
    from twolink.sim.pose_scoring import truncated
    from twolink.sim.rollout import rollout

    out = tmp_path / "own.json"
    assert study.main(["--links", "3", "--poses", "3", "--agent", str(agent_file),
                       "--json", str(out)]) == 0
    (run,) = json.loads(out.read_text())["runs"]
    name = "ippo_3links_neighbours_seed2"
    assert run["learned"] == [name] and run["agent_files"] == {name: str(agent_file)}
    x0 = random_poses(3, study.POSES, 20061122 + 3)[:3]
    with make_plant("mujoco", links_parameters(3, "tapered")) as plant:
        traj = rollout(resolve_controller(str(agent_file), links=3), plant, x0, duration=16.0)
    assert run["success"][name] == [int(v) for v in success(truncated(traj, 8.0))]
    assert run["later"]["16"][name] == [int(v) for v in success(truncated(traj, 16.0))]
    swing = inner_excursion(truncated(traj, 8.0).x[..., :3])
    np.testing.assert_allclose(run["excursion"][name], swing, atol=1e-4)


def test_bad_agent_files_are_one_line_exit_2_nothing_written(study, agent_file, tmp_path,
                                                            capsys):
    out = tmp_path / "own.json"
    taken = tmp_path / "pd.marl.pt"
    taken.write_bytes(agent_file.read_bytes())
    junk = tmp_path / "junk.marl.pt"
    junk.write_bytes(b"not a checkpoint")
    for argv, message in [
        (["--links", "3", "--agent", str(tmp_path / "gone.zip")], "gone.zip: no such file"),
        (["--links", "3", "--agent", str(out.with_suffix(".npz"))],
         "an agent is a .zip or .marl.pt file"),
        (["--links", "3", "--agent", str(taken)], "the name 'pd' is taken"),
        (["--links", "3", "--agent", str(agent_file), "--agent", str(agent_file)],
         "the name 'ippo_3links_neighbours_seed2' is taken"),
        (["--links", "4", "--agent", str(agent_file)], "not 4 (give --links 3)"),
        (["--links", "3", "--agent", str(junk)], "junk.marl.pt"),
    ]:
        assert study.main(argv + ["--json", str(out)]) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith("links_own_motor: error:") and message in err, err
        assert len(err.splitlines()) == 1 and not out.exists()
