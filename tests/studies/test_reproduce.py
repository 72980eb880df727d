"""`twolink reproduce` (the main job) and `twolink synthesize` / `twolink mjcf`."""
import json
from pathlib import Path

import numpy as np
import pytest

from twolink.arm.parameters import HORIZON, PAPER_X0
from twolink.cli import main
from twolink.policy.fuzzy_policy import Policy, load_policy
from twolink.policy.registry import PAPER_POLICIES, SHIPPED
from twolink.sim.metrics import (
    evaluation_set,
    stalled_at_band_edge,
    success,
    summary,
    wilson_interval,
)
from twolink.sim.plants import make_plant
from twolink.sim.rollout import rollout
from twolink.studies.reproduce import paper
from twolink.studies.reproduce.measure import PLANTS
from twolink.studies.reproduce.table import table


@pytest.fixture(scope="module")
def reproduced(tmp_path_factory):
    out = tmp_path_factory.mktemp("reproduce")
    fig = out / "fig3.png"
    report = out / "report.json"
    import contextlib
    import io
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(["reproduce", "--json", "--figure", str(fig), "--report", str(report)])
    assert code == 0
    return json.loads(buf.getvalue()), fig, report


#: The checkout.
ROOT = Path(__file__).resolve().parents[2]

#: Table II's Q-table sizes, per agent.
SIZES = {"centralized": 63504, "agent1": 9072, "agent2": 252}


def test_reproduce_synthesises_the_shipped_policies(reproduced):
    rep, _, _ = reproduced
    s = rep["synthesis"]
    assert list(s) == list(PAPER_POLICIES)
    for name in PAPER_POLICIES:
        shipped = Policy.load(SHIPPED[name].file)
        assert s[name]["matches_shipped_policy"] is True
        assert {a: v["q_size"] for a, v in s[name]["agents"].items()} == \
            {a.name: SIZES[a.name] for a in shipped.agents}
        # The sweep counts are those the shipped files' headers record.
        assert {a: v["iterations"] for a, v in s[name]["agents"].items()} == \
            {a.name: a.info["iterations"] for a in shipped.agents}
        for agent in s[name]["agents"].values():
            assert 0 < agent["cpu_seconds"] < 60
    assert rep["paper"]["iterations"] == paper.ITERATIONS


@pytest.fixture(scope="module")
def recomputed():
    """Rollouts of the shipped policies, from x0 and over the evaluation set."""
    out = {}
    for name in PAPER_POLICIES:
        policy = load_policy(name)
        for plant in PLANTS:
            with make_plant(plant) as p:
                out[(name, plant)] = (rollout(policy, p, PAPER_X0, duration=HORIZON),
                                      rollout(policy, p, evaluation_set(), duration=HORIZON))
    return out


def test_reproduce_rollouts_are_those_of_the_shipped_policies(reproduced, recomputed):
    rep, _, _ = reproduced
    for (name, plant), (tr, ev) in recomputed.items():
        assert rep["rollouts"][name][plant] == json.loads(json.dumps(
            {**summary(tr), "stalled_at_band_edge": bool(stalled_at_band_edge(tr)[()])}))
        ok = success(ev)
        assert rep["evaluation_set"][name][plant] == {
            "states": 65, "successes": int(ok.sum()), "success_rate": float(ok.mean()),
            "wilson_95": list(wilson_interval(int(ok.sum()), 65)), "failures": int((~ok).sum()),
            "failures_stalled_at_band_edge": int(stalled_at_band_edge(ev).sum())}


def test_reproduce_paper_claims_on_the_simplified_plant(reproduced, recomputed):
    rep, _, _ = reproduced
    c = rep["rollouts"]["centralized"]["simplified"]
    assert c["success"] and 0 < c["settle_time"] < 2.0          # paper: about 1.2 s
    for name in PAPER_POLICIES:
        tr, ev = recomputed[(name, "simplified")]
        # Settled from x0, or parked a hair outside the 5 deg band (README: edge stalls).
        assert success(tr) or stalled_at_band_edge(tr)
        assert np.all(np.abs(rep["rollouts"][name]["simplified"]["final_offsets_deg"]) <= 5.1)
        sim = rep["evaluation_set"][name]["simplified"]
        assert sim["failures_stalled_at_band_edge"] == sim["failures"] > 0
        assert rep["evaluation_set"][name]["mujoco"]["success_rate"] < sim["success_rate"]


def test_reproduce_reports_integration_error(reproduced):
    rep, _, _ = reproduced
    err = rep["integration_error"]
    for model in ("simplified", "full"):
        assert err[model]["substeps"] == 10 and err[model]["reference_substeps"] == 100
        assert 0 < max(err[model]["max"]) < 1e-5
    assert max(err["simplified"]["max"]) < max(err["full"]["max"])


def test_reproduce_writes_figure_and_report(reproduced):
    rep, fig, report = reproduced
    assert fig.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and fig.stat().st_size > 20000
    assert rep["figure"] == str(fig)
    assert json.loads(report.read_text())["synthesis"] == rep["synthesis"]


def test_reproduce_table_lists_every_paper_policy(reproduced):
    rep, _, _ = reproduced
    text = table(rep)
    lines = text.splitlines()
    prop = rep["synthesis"]["decentralized_propagated"]["agents"]["agent1"]["iterations"]
    assert any(l.startswith("iterations, agent1 (propagated context)") and
               l.split()[-2:] == [str(paper.ITERATIONS["agent1"]), str(prop)] for l in lines)
    for name in PAPER_POLICIES:
        for plant in PLANTS:
            assert sum(l.startswith(f"settle time [s], {name}, {plant} ") for l in lines) == 1
    serial = rep["synthesis"]["decentralized"]["serial"]
    for agent in ("agent1", "agent2"):          # serial sweeps beside the synchronous ones
        assert any(l.startswith(f"iterations, {agent} (serial sweeps)") and
                   l.split()[-2:] == [str(paper.ITERATIONS[agent]),
                                      str(serial[agent]["iterations"])] for l in lines)
    assert any(l.startswith("iterations, agent1 (propagated context, serial sweeps)")
               for l in lines)
    for agent, size in SIZES.items():
        assert any(l.startswith(f"Q-table size, {agent} ") and l.split()[-2:] == [str(size)] * 2
                   for l in lines)


def test_reproduce_reports_serial_sweeps_beside_the_shipped_synchronous_ones(reproduced):
    """The shipped policies are synchronous (docs/conventions.md); serial sweeps, as ApproxRL's
    fuzzyqi.m runs them, reach the paper's 192 and 49 sweeps of the agents exactly."""
    rep, _, _ = reproduced
    s = rep["synthesis"]
    assert all(s[n]["sweeps"] == "synchronous" for n in PAPER_POLICIES)
    assert s["decentralized"]["serial"]["agent1"]["iterations"] == paper.ITERATIONS["agent1"]
    assert s["decentralized"]["serial"]["agent2"]["iterations"] == paper.ITERATIONS["agent2"]
    assert s["decentralized"]["agents"]["agent1"]["iterations"] != paper.ITERATIONS["agent1"]
    for n in PAPER_POLICIES:                    # in-place updates never need more sweeps here
        for agent, info in s[n]["serial"].items():
            assert info["iterations"] <= s[n]["agents"][agent]["iterations"]


@pytest.mark.slow
def test_reproduce_table_is_printed(tmp_path, capsys):
    assert main(["reproduce", "--duration", "2", "--figure", str(tmp_path / "f.png")]) == 0
    out = capsys.readouterr().out
    assert "Q-table size, centralized" in out and "63504" in out and "~18300" in out
    assert ("fresh synthesis equals the shipped policy bit for bit: centralized yes, "
            "decentralized yes, decentralized_propagated yes") in out
    assert out.rstrip().endswith(f"wrote {tmp_path / 'f.png'}")
    assert "against the paper:" in out and "docs/findings/reproduction.md" in out


def test_reproduce_ends_with_a_verdict_per_comparison(reproduced):
    """Each comparison is decided from the report's numbers: the shipped run's verdicts,
    then the same report with the decentralized settle time moved to the paper's."""
    import copy

    from twolink.studies.reproduce.table import FINDINGS, verdict_block, verdicts

    rep, _, _ = reproduced
    lines = verdicts(rep)
    by_what = {line.split(":")[0].split(None, 1)[1]: line.split()[0] for line in lines}
    assert by_what["Q-table sizes (Table II)"] == "matches"
    assert by_what["agents' sweep counts"] == "matches"       # serial sweeps: 192 and 49
    assert by_what["centralized sweep count"] == "differs"    # 80/73 against 125
    assert by_what["centralized from x0 on the simplified model"] == "matches"
    dec = rep["rollouts"]["decentralized"]["simplified"]
    assert dec["settle_time"] is None and dec["stalled_at_band_edge"] is True
    line = next(x for x in lines if "decentralized from x0" in x)
    assert line.split()[0] == "differs" and "edge stall" in line
    assert "decentralized_propagated settles in" in line
    assert FINDINGS in verdict_block(rep) and (ROOT / FINDINGS).is_file()
    moved = copy.deepcopy(rep)
    moved["rollouts"]["decentralized"]["simplified"]["settle_time"] = 1.3
    line = next(x for x in verdicts(moved) if "decentralized from x0" in x)
    assert line.startswith("  matches") and "1.3 s" in line
    # Table II's figure is the warm synthesis; the first call is reported apart.
    first = rep["synthesis"]["centralized"]["first_call"]["centralized"]["cpu_seconds"]
    assert 0 < rep["synthesis"]["centralized"]["agents"]["centralized"]["cpu_seconds"] <= \
        first * 1.5
    assert "first synthesis in the process" in table(rep)


@pytest.mark.parametrize("argv, message", [
    (["--figure", "{tmp}/f.png", "--report", "/nonexistent/r.json"],
     "directory /nonexistent does not exist"),
    (["--figure", "{tmp}/x.png", "--report", "{tmp}/x.png"], "--figure and --report both write"),
    (["--figure", "{tmp}/f.jpg"], "use a .png"),
    (["--duration", "1e12", "--figure", "{tmp}/f.png"], "at most 60, got 1e+12"),
    (["--duration", "nan", "--figure", "{tmp}/f.png"], "duration must be a positive"),
])
def test_reproduce_checks_outputs_before_any_work(argv, message, tmp_path, capsys, monkeypatch):
    def synthesised(*args, **kwargs):
        raise AssertionError("reproduce ran")

    monkeypatch.setattr("twolink.commands.reproduce.reproduce", synthesised)
    code = main(["reproduce", *(a.replace("{tmp}", str(tmp_path)) for a in argv)])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and message in err
    assert err.startswith("twolink reproduce: error: ")
    assert list(tmp_path.iterdir()) == []


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


def test_bad_mujoco_gl_only_stops_rendering(tmp_path):
    """The GL backend is chosen when the first renderer is made: commands that do not
    render work with any MUJOCO_GL, render says what is wrong in one line."""
    import os
    import subprocess
    import sys
    env = dict(os.environ, MUJOCO_GL="bogus")
    res = subprocess.run([sys.executable, "-m", "twolink.cli", "mjcf", "-o",
                          str(tmp_path / "m.xml")], capture_output=True, text=True, env=env)
    assert res.returncode == 0 and (tmp_path / "m.xml").is_file()
    res = subprocess.run([sys.executable, "-m", "twolink.cli", "render", "--duration", "0.1",
                          "--size", "64x48", "-o", str(tmp_path / "v.mp4")],
                         capture_output=True, text=True, env=env)
    assert res.returncode == 2
    assert res.stderr.strip().splitlines() == [res.stderr.strip()]
    assert "MUJOCO_GL='bogus'" in res.stderr
    assert not (tmp_path / "v.mp4").exists()
