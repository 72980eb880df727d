"""`twolink rollout`: every plant, JSON summary, saved trajectories, figure, bad input."""
import json
import math
import subprocess
import sys

import numpy as np
import pytest

from twolink.cli import main
from twolink.sim.metrics import summary, trajectory_gap
from twolink.sim.plants import PLANTS, make_plant
from twolink.sim.rollout import rollout
from twolink.sim.trajectory_file import CSV_COLUMNS, load_npz

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _run(capsys, *argv):
    code = main(["rollout", *map(str, argv)])
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.mark.parametrize("plant", PLANTS)
def test_rollout_each_plant_json_matches_library(plant, tmp_path, capsys, centralized):
    code, out, _ = _run(capsys, "--plant", plant, "--duration", 1.5, "--json",
                        "--prefix", tmp_path / "run")
    assert code == 0
    rep = json.loads(out)
    (entry,) = rep["runs"]
    x0 = [-1.0, -3.0, 0.0, 0.0]
    direct = rollout(centralized, make_plant(plant), x0, duration=1.5)
    want = summary(direct)
    assert entry["plant"] == plant and entry["policy"] == "centralized"
    assert entry["return"] == pytest.approx(want["return"])
    assert entry["final_offsets_deg"] == pytest.approx(want["final_offsets_deg"])
    assert entry["settle_time"] == want["settle_time"]
    assert entry["success"] == want["success"]
    if plant == "simplified":
        assert "gap_to_simplified" not in entry
    else:
        ref = rollout(centralized, make_plant("simplified"), x0, duration=1.5)
        gap = trajectory_gap(direct, ref)
        assert entry["gap_to_simplified"]["angle_rms"] == pytest.approx(float(gap["angle_rms"]))
        assert entry["gap_to_simplified"]["angle_rms"] > 0
    # Saved trajectory: NPZ equal to the library rollout, CSV one row per sample.
    saved = load_npz(tmp_path / "run.npz")[("centralized", plant)]
    np.testing.assert_array_equal(saved.x, direct.x)
    np.testing.assert_array_equal(saved.u, direct.u)
    np.testing.assert_array_equal(saved.r, direct.r)
    lines = (tmp_path / "run.csv").read_text().splitlines()
    assert lines[0].split(",") == list(CSV_COLUMNS)
    assert len(lines) == 1 + direct.steps + 1
    last = lines[-1].split(",")
    assert float(last[CSV_COLUMNS.index("theta2")]) == direct.x[-1, 1]
    assert last[CSV_COLUMNS.index("tau1")] == ""      # no command after the last sample
    assert (tmp_path / "run_fig3.png").read_bytes()[:8] == PNG_MAGIC


def test_rollout_overlays_policies_and_plants_in_one_figure(tmp_path, capsys):
    fig = tmp_path / "cmp.png"
    code, out, _ = _run(capsys, "--policy", "centralized", "--policy", "decentralized",
                        "--plant", "simplified", "--plant", "mujoco", "--duration", 1.0,
                        "--figure", fig, "--csv", tmp_path / "t.csv", "--npz", tmp_path / "t.npz")
    assert code == 0
    assert out.count(" on simplified") == 2 and out.count(" on mujoco") == 2
    assert "gap to simplified" in out
    runs = load_npz(tmp_path / "t.npz")
    assert set(runs) == {(p, q) for p in ("centralized", "decentralized")
                         for q in ("simplified", "mujoco")}
    from PIL import Image
    im = Image.open(fig)
    assert im.format == "PNG" and im.width > im.height   # two columns (one: 5.2 x 9 in)
    rows = (tmp_path / "t.csv").read_text().splitlines()[1:]
    assert {tuple(r.split(",")[:2]) for r in rows} == set(runs)


def test_rollout_x0_degrees_and_random_seed(tmp_path, capsys):
    code, out, _ = _run(capsys, "--x0=-57.29577951308232,-171.88733853924697,0,0",
                        "--degrees", "--duration", 0.5, "--plant", "simplified", "--json",
                        "--no-save")
    assert code == 0
    rep = json.loads(out)
    assert rep["x0"] == pytest.approx([-1, -3, 0, 0])
    assert "outputs" not in rep
    xs = []
    for seed in (3, 3, 4):
        _, out, _ = _run(capsys, "--x0", "random", "--seed", seed, "--duration", 0.2,
                         "--plant", "simplified", "--json", "--no-save")
        xs.append(json.loads(out)["x0"])
    assert xs[0] == xs[1] != xs[2]
    assert all(-math.pi <= v < math.pi for v in xs[2][:2]) and xs[2][2:] == [0, 0]


@pytest.mark.parametrize("argv, message", [
    (["--policy", "nope"], "unknown policy 'nope'"),
    (["--policy", "missing/file.npz"], "does not exist"),
    (["--x0", "1,2,3"], "--x0 must be four numbers"),
    (["--x0", "a", "b", "c", "d"], "--x0 must be four numbers"),
    (["--x0", "1", "2", "nan", "0"], "NaN"),
    (["--duration", "0"], "duration must be a positive"),
    (["--figure", "{tmp}/fig.jpg"], "use a .png"),
    (["--prefix", "{tmp}/no/such/dir/run"], "does not exist"),
    (["--prefix", "{tmp}/afile/run"], "afile is not a directory"),
    (["--npz", "{tmp}"], "is a directory"),
    (["--x0", "2e10", "0", "0", "0"], "--x0 has an angle of magnitude 2e+10 rad, beyond the bound"),
    (["--x0", "0", "0", "1e9", "0"], "--x0 has a speed of magnitude 1e+09 rad/s, beyond the bound"),
    (["--duration", "1e12"], "duration must be at most 3600 s"),
    (["--csv", "{tmp}/x.png", "--figure", "{tmp}/x.png"], "--csv and --figure both write"),
    (["--npz", "{tmp}/afile/../r.npz", "--csv", "{tmp}/r.npz"], "does not exist"),
    (["--prefix", "{tmp}/r", "--npz", "{tmp}/r.csv"], "--csv and --npz both write"),
    (["--policy", "centralized", "--policy", "{tmp}/centralized.npz"], "share the label"),
    (["--challenge", "extreme"], "unknown challenge 'extreme'; choose one of none, easy, "
                                 "medium, hard"),
    (["--delay", "10"], "a delay of 10 samples is not shorter than the horizon of 10 samples"),
    (["--challenge", "hard", "--duration", "0.1"], "a delay of 2 samples is not shorter"),
    (["--delay", "-1"], "--delay must be a non-negative whole number"),
    (["--angle-noise-deg", "-0.5"], "--angle-noise-deg must be a non-negative number of degrees"),
    (["--angle-noise-deg", "nan"], "--angle-noise-deg must be a non-negative number of degrees"),
    (["--challenge", "medium", "--delay", "1"], "give either --challenge or --delay"),
    (["--challenge", "easy", "--seed", "-3"], "--seed must be a non-negative"),
])
def test_rollout_bad_input_one_line_error_no_files(argv, message, tmp_path, capsys):
    (tmp_path / "afile").write_text("x")
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    if not any(a in ("-o", "--out", "--prefix") for a in argv):
        argv += ["--prefix", str(tmp_path / "run")]
    code, out, err = _run(capsys, "--duration", 0.5, *argv)
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("twolink rollout: error: ")
    assert message in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


def test_rollout_cli_entry_point_exit_status(tmp_path):
    res = subprocess.run([sys.executable, "-m", "twolink.cli", "rollout", "--x0", "1", "2",
                          "--prefix", str(tmp_path / "r")], capture_output=True, text=True)
    assert res.returncode == 2
    assert res.stderr.strip().splitlines() == [
        "twolink rollout: error: --x0 must be four numbers (theta1 theta2 dtheta1 dtheta2), "
        "got 2: '1 2'"]
    assert list(tmp_path.iterdir()) == []


def test_rollout_output_directory_gets_the_default_names(tmp_path, capsys):
    """An existing folder, or DIR/ (a trailing slash) made when missing, gets rollout.*;
    DIR/ under a missing folder is one line, and nothing is made."""
    (tmp_path / "results").mkdir()
    for prefix in (tmp_path / "results", f"{tmp_path / 'new'}/"):
        code, _, err = _run(capsys, "--plant", "simplified", "--duration", 0.2, "-o", prefix)
        assert code == 0 and err == "", err
    for d in ("results", "new"):
        assert sorted(p.name for p in (tmp_path / d).iterdir()) == [
            "rollout.csv", "rollout.npz", "rollout_fig3.png"]
    code, _, err = _run(capsys, "--plant", "simplified", "--duration", 0.2,
                        "-o", f"{tmp_path / 'missing' / 'new'}/")
    assert code == 2 and err.count("\n") == 1 and "does not exist" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["new", "results"]


def test_mujoco_instability_fails_the_run_loudly(tmp_path, capsys, monkeypatch):
    from twolink.sim import plants
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(plants, "MAX_ANGLE", 1e12)     # let MuJoCo see a state it rejects
    code, out, err = _run(capsys, "--x0", "2e10", "0", "0", "0", "--plant", "mujoco",
                          "--prefix", tmp_path / "r")
    assert code == 2 and "success" not in out
    assert err.count("\n") == 1 and "MuJoCo went unstable" in err and "x0 = [+2e+10" in err
    assert list(tmp_path.iterdir()) == []                # no MUJOCO_LOG.TXT, no outputs


def test_reloaded_runs_keep_their_kind_and_are_plotted_with_its_reward(tmp_path, capsys,
                                                                        monkeypatch):
    code, _, _ = _run(capsys, "--policy", "decentralized_propagated", "--policy", "centralized",
                      "--plant", "simplified", "--duration", 0.5, "-o", tmp_path / "r")
    assert code == 0
    runs = load_npz(tmp_path / "r.npz")
    prop = runs[("decentralized_propagated", "simplified")]
    assert (prop.label, prop.kind, prop.plant) == ("decentralized_propagated", "decentralized",
                                                   "simplified")
    assert runs[("centralized", "simplified")].kind == "centralized"
    from twolink.viz import plots
    figures = []
    monkeypatch.setattr(plots.plt, "close", figures.append)
    plots.fig3({"p": {"": prop}, "c": {"": runs[("centralized", "simplified")]}},
               tmp_path / "f.png")
    reward_axes = figures[0].axes[6:8]                    # row 4 of a 4 x 2 grid
    colors = [[line.get_color() for line in ax.get_lines()] for ax in reward_axes]
    assert colors == [["tab:orange", "tab:blue"], ["k"]]   # (17) per link vs (15)


def test_trajectory_files_without_kinds_get_the_registry_kind(tmp_path, centralized):
    """Files written before kinds were recorded: a shipped name gives its kind."""
    from twolink.sim.trajectory_file import FORMAT
    tr = rollout(centralized, make_plant("simplified"), [-1, -3, 0, 0], duration=0.2)
    arrays = {f"{p}/simplified/{n}": getattr(tr, n) for p in ("decentralized_propagated", "mine")
              for n in ("t", "x", "u", "r", "r_links")}
    header = {"format": FORMAT, "runs": [["decentralized_propagated", "simplified"],
                                         ["mine", "simplified"]], "meta": {}}
    np.savez(tmp_path / "old.npz", header=np.array(json.dumps(header)), **arrays)
    runs = load_npz(tmp_path / "old.npz")
    assert runs[("decentralized_propagated", "simplified")].kind == "decentralized"
    assert runs[("mine", "simplified")].kind == ""
    np.testing.assert_array_equal(runs[("mine", "simplified")].x, tr.x)


def test_default_output_folder_is_made_only_for_a_run_that_writes(tmp_path, capsys,
                                                                  monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("TWOLINK_OUTPUT", raising=False)
    code, _, err = _run(capsys, "--csv", "x.png", "--figure", "x.png", "--duration", 0.2)
    assert code == 2 and "--csv and --figure both write x.png" in err
    assert list(tmp_path.iterdir()) == []                # no empty folder left behind
    code, _, _ = _run(capsys, "--plant", "simplified", "--duration", 0.2)
    assert code == 0
    assert sorted(p.name for p in (tmp_path / "twolink-results").iterdir()) == [
        "rollout.csv", "rollout.npz", "rollout_fig3.png"]


def _outcome(capsys, *argv):
    code, out, _ = _run(capsys, "--policy", "centralized_full", "--no-save", "--json", *argv)
    assert code == 0
    run = json.loads(out)["runs"][0]
    return run["success"], run["settle_time"], run["return"]


def test_compensation_undoes_a_delay_the_policy_fails_under(capsys):
    """From the paper's x0 on MuJoCo: one sample of actuation delay breaks
    centralized_full; the delay predictor restores its nominal settle time."""
    nominal = _outcome(capsys)
    delayed = _outcome(capsys, "--delay", "1")
    fixed = _outcome(capsys, "--delay", "1", "--compensate")
    assert nominal[0] and nominal[1] < 1.5
    assert not delayed[0] and delayed[1] is None and delayed[2] < nominal[2] - 5
    assert fixed[0] and abs(fixed[1] - nominal[1]) <= 0.1 and fixed[2] > delayed[2] + 5
    assert _outcome(capsys, "--compensate") == nominal    # nothing to compensate: the policy


def test_a_challenged_rollout_is_the_evaluation_of_its_first_plant(capsys):
    """--challenge LEVEL --seed S runs evaluate()'s plant 0 from x0, with the same noise."""
    from twolink.arm.parameters import PAPER_X0
    from twolink.sim.evaluation import evaluate

    for comp in (False, True):
        ok, st, ret = _outcome(capsys, "--challenge", "medium", "--seed", "3",
                               *(["--compensate"] if comp else []))
        ev = evaluate("centralized_full", x0=np.array([PAPER_X0]), count=1, seed=3,
                      challenge="medium", compensate=comp)
        assert ok == bool(ev.success[0, 0]) and ret == pytest.approx(ev.returns[0, 0], abs=1e-12)
        assert (st is None) == (not np.isfinite(ev.settle[0, 0]))
        assert st is None or st == pytest.approx(ev.settle[0, 0])
    assert not _outcome(capsys, "--challenge", "medium", "--seed", "3")[0]
    assert _outcome(capsys, "--challenge", "medium", "--seed", "3", "--compensate")[0]
    again = _outcome(capsys, "--challenge", "hard", "--seed", "5")
    assert again == _outcome(capsys, "--challenge", "hard", "--seed", "5")
    assert again != _outcome(capsys, "--challenge", "hard", "--seed", "6")
