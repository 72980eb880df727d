"""`twolink reproduce` (the main job) and `twolink synthesize` / `twolink mjcf`."""
import json

import numpy as np
import pytest

from twolink import paper
from twolink.cli import main
from twolink.policy import Policy


@pytest.fixture(scope="module")
def reproduced(tmp_path_factory):
    out = tmp_path_factory.mktemp("reproduce")
    fig = out / "fig3.png"
    report = out / "report.json"
    import io
    import contextlib
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(["reproduce", "--json", "--figure", str(fig), "--report", str(report)])
    assert code == 0
    return json.loads(buf.getvalue()), fig, report


def test_reproduce_reports_table_ii_sizes_and_iterations(reproduced):
    rep, _, _ = reproduced
    s = rep["synthesis"]
    assert s["centralized"]["agents"]["centralized"]["q_size"] == 63504
    assert s["decentralized"]["agents"]["agent1"]["q_size"] == 9072
    assert s["decentralized"]["agents"]["agent2"]["q_size"] == 252
    for variant in s.values():
        for agent in variant["agents"].values():
            assert 10 < agent["iterations"] < 1000
            assert agent["cpu_seconds"] > 0
        assert variant["matches_shipped_policy"] is True
    assert rep["paper"]["iterations"] == paper.ITERATIONS


def test_reproduce_stabilises_the_simplified_plant_and_reports_mujoco(reproduced):
    rep, _, _ = reproduced
    for name in ("centralized", "decentralized"):
        sim = rep["rollouts"][name]["simplified"]
        assert sim["success"] and sim["settle_time"] <= 1.5
        assert np.all(np.abs(sim["final_offsets_deg"]) <= 5.0)
        assert "settle_time" in rep["rollouts"][name]["mujoco"]


def test_reproduce_reports_the_evaluation_set(reproduced):
    rep, _, _ = reproduced
    for variant in ("centralized", "decentralized", "decentralized_propagated"):
        sim = rep["evaluation_set"][variant]["simplified"]
        assert sim["states"] == 65 and 0.3 < sim["success_rate"] < 1.0
        assert sim["failures_stalled_at_band_edge"] == sim["failures"]
        assert rep["evaluation_set"][variant]["mujoco"]["success_rate"] < sim["success_rate"]


def test_reproduce_reports_integration_error(reproduced):
    rep, _, _ = reproduced
    for model in ("simplified", "full"):
        err = rep["integration_error"][model]
        assert err["substeps"] == 10 and 0 <= max(err["max"]) < 1e-5


def test_reproduce_writes_figure_and_report(reproduced):
    rep, fig, report = reproduced
    assert fig.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and fig.stat().st_size > 20000
    assert json.loads(report.read_text())["synthesis"] == rep["synthesis"]


def test_reproduce_table_is_printed(tmp_path, capsys):
    assert main(["reproduce", "--duration", "2", "--figure", str(tmp_path / "f.png")]) == 0
    out = capsys.readouterr().out
    assert "Q-table size, centralized" in out and "63504" in out and "~18300" in out


def test_synthesize_writes_a_loadable_policy(tmp_path, capsys):
    path = tmp_path / "a.npz"
    assert main(["synthesize", "decentralized", "--context", "propagated", "-o", str(path),
                 "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    pol = Policy.load(path)
    assert pol.meta["context"] == "propagated"
    assert info["agents"]["agent1"]["iterations"] == pol.agents[1].info["iterations"]


def test_cli_errors_are_one_line(tmp_path, capsys):
    assert main(["synthesize", "centralized", "-o", str(tmp_path / "nope" / "c.npz")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("twolink synthesize: error:") and "does not exist" in err
    assert len(err.splitlines()) == 1
    assert not (tmp_path / "nope").exists()
    assert main(["synthesize", "centralized", "--gamma", "1.5", "-o", str(tmp_path / "c.npz")]) == 2
    assert "gamma" in capsys.readouterr().err
    assert not (tmp_path / "c.npz").exists()


def test_mjcf_command_regenerates_the_committed_model(tmp_path):
    from twolink.resources import model_file
    out = tmp_path / "arm.xml"
    assert main(["mjcf", "-o", str(out)]) == 0
    assert out.read_text() == model_file().read_text()


def test_written_files_get_the_usual_mode(tmp_path):
    import os
    from twolink.artifacts import write_text
    mask = os.umask(0o022)
    try:
        path = write_text(tmp_path / "a.txt", "x")
    finally:
        os.umask(mask)
    assert path.stat().st_mode & 0o777 == 0o644


def test_bad_mujoco_gl_gives_one_line(tmp_path):
    import os
    import subprocess
    import sys
    env = dict(os.environ, MUJOCO_GL="bogus")
    res = subprocess.run([sys.executable, "-m", "twolink.cli", "mjcf", "-o",
                          str(tmp_path / "m.xml")], capture_output=True, text=True, env=env)
    assert res.returncode == 2
    assert res.stderr.strip().splitlines() == [res.stderr.strip()]
    assert "MUJOCO_GL='bogus'" in res.stderr
    assert not (tmp_path / "m.xml").exists()
