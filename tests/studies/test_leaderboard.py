"""The leaderboard and twolink evaluate: every controller x level x mode through the one
evaluate, against the shipped time-optimal limit; files, JSON and one-line errors."""
import json

import numpy as np
import pytest

from twolink.cli import main
from twolink.sim.metrics import evaluation_set
from twolink.studies.leaderboard.limits import state_limits
from twolink.studies.leaderboard.measure import modes_for, run, settle_ratios

X0 = evaluation_set()[::13]


def pd(x):
    return np.clip(-np.array([1.0, 2.0]) * x[:, :2] - np.array([0.15, 0.05]) * x[:, 2:],
                   [-1.5, -0.1], [1.5, 0.1])


def test_the_limits_of_the_evaluation_set_are_shipped():
    limits, source = state_limits(evaluation_set())
    assert limits.shape == (65,) and np.all(limits > 0) and "time-optimal" in source
    none, why = state_limits(np.array([[0.3, 0.3, 0.0, 0.0]]))
    assert none is None and "has no shipped limit" in why


def test_settle_ratios_count_failures_as_never():
    r = settle_ratios(np.array([[1.0, 2.0]]), np.array([[True, False]]), np.array([0.5, 1.0]))
    assert r[0, 0] == 2.0 and np.isinf(r[0, 1])


def test_a_controller_without_a_model_has_no_compensated_row():
    from twolink.control.controllers import resolve_controller

    assert modes_for(pd, "medium") == ("plain",)
    assert modes_for(resolve_controller("lqr"), "medium") == ("plain", "compensated")
    assert modes_for(resolve_controller("lqr"), "none") == ("plain",)


def test_rows_are_the_evaluations_of_each_controller():
    from twolink.sim.evaluation import evaluate

    limits, _ = state_limits(X0)
    rows = run({"pd": pd}, X0, limits, levels=("none", "medium"), plants=2, seed=5)
    assert [(r.controller, r.level, r.mode) for r in rows] == [("pd", "none", "plain"),
                                                              ("pd", "medium", "plain")]
    direct = evaluate(pd, x0=X0, challenge="medium", count=2, seed=5)
    assert rows[1].score == direct.score
    assert rows[0].mean_abs_torque > 0 and rows[0].settle_ratio_median >= 1.0
    d = rows[1].as_dict()
    assert (d["n"], d["worst_plant"] is not None) == (10, True)


def test_the_command_writes_markdown_json_and_figure(tmp_path, capsys):
    mine = tmp_path / "mine.py"
    mine.write_text("import numpy as np\n"
                    "def pd(x):\n"
                    "    return np.clip(-np.array([1.0, 2.0]) * x[:, :2]"
                    " - np.array([0.15, 0.05]) * x[:, 2:], [-1.5, -0.1], [1.5, 0.1])\n")
    out = tmp_path / "lb"
    assert main(["leaderboard", "--quick", "--only", "--controller", "lqr", "--controller",
                 f"{mine}:pd", "--levels", "none", "medium", "--plants", "2",
                 "--out", str(out)]) == 0
    captured = capsys.readouterr()
    text = captured.out                              # where the added controller ranks
    ranks = [line.split(":")[0] for line in text.splitlines() if " ranks " in line]
    ranks = [r.replace("1 of", "k of").replace("2 of", "k of") for r in ranks]
    assert [r for r in ranks if r.startswith("pd ")] == [        # --only: both are given
        "pd ranks k of 2 under none (plain)", "pd ranks k of 2 under medium (plain)"]
    assert "lqr ranks k of 1 under medium (compensated)" in ranks
    assert "|" not in text
    rows = captured.err.splitlines()                # one line per row, no bar besides
    assert len(rows) == 5 and all(line.startswith(f"[{k}/5] ")
                                  for k, line in enumerate(rows, 1)), rows
    report = json.loads((out / "leaderboard.json").read_text())
    assert {(r["controller"], r["level"], r["mode"]) for r in report["rows"]} == {
        ("lqr", "none", "plain"), ("lqr", "medium", "plain"), ("lqr", "medium", "compensated"),
        ("pd", "none", "plain"), ("pd", "medium", "plain")}
    assert (out / "leaderboard.png").read_bytes()[:4] == b"\x89PNG"
    md = (out / "leaderboard.md").read_text()
    assert "## medium" in md and "| lqr | compensated |" in md and "| pd | plain |" in md


@pytest.mark.parametrize("argv, match", [
    (["--only", "--controller", "nosuch"], "unknown controller 'nosuch'"),
    (["--levels", "wild"], "unknown challenge 'wild'"),
    (["--plants", "0"], "--plants must be from 1 to 10000"),
    (["--controller", "no_module_xyz:f"], "cannot import controller module"),
])
def test_bad_input_is_one_line_and_writes_nothing(tmp_path, capsys, argv, match):
    out = tmp_path / "lb"
    assert main(["leaderboard", "--quick", "--out", str(out), *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and match in err[0]
    assert not out.exists()


def test_evaluate_prints_the_score_against_the_limit(capsys):
    assert main(["evaluate", "lqr", "--quick", "--json"]) == 0
    out, err = capsys.readouterr()
    r = json.loads(out)
    assert err == ""                                 # --json: no progress bar
    assert (r["controller"], r["challenge"], r["mode"], r["n"]) == ("lqr", "none", "plain", 5)
    assert r["successes"] == 5 and r["settle_ratio_median"] >= 1.0
    assert main(["evaluate", "pd_deadzone", "--challenge", "medium", "--plants", "2",
                 "--quick"]) == 0
    line = capsys.readouterr().out.strip()
    assert line.startswith("pd_deadzone under medium (plain): ") and "settle / T*" in line
    assert main(["evaluate", "nosuch"]) == 2
    assert "unknown controller 'nosuch'" in capsys.readouterr().err


def test_evaluate_logs_its_progress_unless_json(tmp_path, monkeypatch):
    """With stderr a file `twolink evaluate` prints its bar as lines, the last at 100 %
    (the 100 samples Ts of 5 s); with --json it prints none (the test above)."""
    log = tmp_path / "log.txt"
    with open(log, "w") as fh:
        monkeypatch.setattr("sys.stderr", fh)
        assert main(["evaluate", "lqr", "--quick"]) == 0
    lines = log.read_text().splitlines()
    assert lines and all(line.startswith("evaluate lqr:") for line in lines), lines
    assert "100%" in lines[-1] and "100/100" in lines[-1], lines


@pytest.mark.slow
def test_merge_adds_rows_as_a_full_run_would_give_them(tmp_path, capsys):
    both, merged = tmp_path / "both", tmp_path / "merged"
    common = ["leaderboard", "--quick", "--levels", "medium", "--plants", "1"]
    assert main([*common, "--only", "--controller", "pd", "--controller", "lqr", "--out", str(both)]) == 0
    assert main([*common, "--only", "--controller", "pd", "--out", str(merged)]) == 0
    capsys.readouterr()
    assert main(["leaderboard", "--quick", "--merge", "--only", "--controller", "lqr",
                 "--out", str(merged)]) == 0
    keys = ("controller", "level", "mode", "successes", "n", "median_settle",
            "settle_ratio_median", "mean_abs_torque")

    def rows(folder):
        data = json.loads((folder / "leaderboard.json").read_text())
        return sorted(tuple(r[k] for k in keys) for r in data["rows"])

    assert rows(merged) == rows(both) and len(rows(both)) == 4
    assert "lqr" in (merged / "leaderboard.md").read_text()


@pytest.mark.parametrize("argv, match", [
    (["--merge", "--only", "--controller", "pd"], "does not exist; run the leaderboard once"),
    (["--merge"], "--merge needs the controllers to add"),
    (["--merge", "--only", "--controller", "pd", "--plants", "3"], "takes the saved leaderboard's"),
])
def test_merge_refuses_what_it_cannot_join(tmp_path, capsys, argv, match):
    assert main(["leaderboard", "--quick", "--out", str(tmp_path / "none"), *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and match in err[0], err
    assert not (tmp_path / "none").exists()
