"""`twolink scaling`: Table II extended to N links (measurement, report, command)."""
import json
import os

import numpy as np
import pytest

from twolink.arm.parameters import TABLE_I
from twolink.cli import main
from twolink.policy.fuzzy_policy import load_policy
from twolink.sim.metrics import random_poses, success
from twolink.sim.plants import make_plant
from twolink.sim.rollout import rollout
from twolink.studies.scaling import measure as scaling
from twolink.studies.scaling.report import FILES, markdown, tables, write
from twolink.studies.scaling.synthesis import ProcessDied, in_fresh_process
from twolink.viz.formatting import format_rate

GIB = 2**30


def test_horizons_grow_past_two_links():
    assert scaling.horizon(2) == 5.0 and scaling.horizons(2) == (5.0,)
    for n in (3, 6):
        assert scaling.horizon(n) == scaling.LONG_HORIZON == 8.0
        assert scaling.horizons(n) == (5.0, 8.0)


def test_plan_measures_two_links_once_and_quick_stops_at_four():
    cells = scaling.plan([3, 2], ["tapered", "copied"])
    three = ["centralized", "decentralized", "decentralized_levels", "decentralized_argmax",
             "pd"]
    assert cells == [(2, "tapered", "centralized"), (2, "tapered", "decentralized")] + \
        [(3, r, s) for r in ("tapered", "copied") for s in three]
    with pytest.raises(ValueError, match="quick runs go up to 4 links"):
        scaling.plan([2, 5], ["tapered"], quick=True)
    with pytest.raises(ValueError, match="unknown link rule 'diagonal'"):
        scaling.plan([2], ["diagonal"])


def test_centralized_refused_over_the_cap_with_its_estimate():
    row = scaling.measure(4, "tapered", "centralized", max_bytes=GIB)
    est = scaling.estimate(4)
    assert row.status == "refused" and row.synthesis is None and row.evaluation is None
    assert est["q_values"] == 12**4 * 7**4 * 81 == row.estimate["q_values"]
    assert row.note == f"refused: needs {est['peak_bytes'] / GIB:.1f} GiB > cap 1.0 GiB"
    # Under the cap, quick skips the three-link synthesis but keeps its estimate.
    quick = scaling.measure(3, "copied", "centralized", max_bytes=8 * GIB, quick=True)
    assert quick.status == "not run (quick)" and quick.synthesis is None
    assert quick.estimate["q_values"] == 592704 * 27


def test_truncated_run_is_the_shorter_rollout():
    policy = load_policy("decentralized_full")
    x0 = random_poses(2, 3, 7)
    with make_plant("mujoco", TABLE_I) as plant:
        long = rollout(policy, plant, x0, duration=8.0)
        short = rollout(policy, plant, x0, duration=5.0)
    cut = scaling.truncated(long, 5.0)
    for field in ("t", "x", "u", "r", "r_links"):
        np.testing.assert_array_equal(getattr(cut, field), getattr(short, field))
    with pytest.raises(ValueError, match="cannot cut"):
        scaling.truncated(short, 8.0)


@pytest.fixture(scope="module")
def two_link_rows():
    """Both two-link rows measured here (tracemalloc), 6 poses."""
    return [scaling.measure(2, "tapered", s, poses=6, peak="tracemalloc")
            for s in scaling.SCHEMES]


def test_two_link_rows_are_the_shipped_full_model_policies(two_link_rows):
    sizes = {"centralized": 63504, "decentralized": 252 + 9072}
    x0 = random_poses(2, 6, scaling.EVAL_SEED + 2)
    for row in two_link_rows:
        s = row.synthesis
        assert row.status == "run" and row.rule == "Table I"
        assert s.q_values == sizes[row.scheme] and s.matches_shipped_policy is True
        assert s.shipped_policy == f"{row.scheme}_full"
        shipped = load_policy(f"{row.scheme}_full")
        assert s.sweeps == {a.name: a.info["iterations"] for a in shipped.agents}
        assert 0 < s.peak_bytes < 512 * 2**20 and s.peak_method == "tracemalloc"
        # The success count is that of the shipped file's own rollout from the same poses.
        with make_plant("mujoco", TABLE_I) as plant:
            ok = success(rollout(shipped, plant, x0, duration=5.0))
        cell = row.evaluation.horizons["5"]
        assert (cell["successes"], cell["n"]) == (int(ok.sum()), 6)
        assert list(row.evaluation.horizons) == ["5"]


def test_report_files(two_link_rows, tmp_path):
    refused = scaling.measure(4, "tapered", "centralized", max_bytes=GIB)
    result = scaling.Scaling(two_link_rows + [refused], {
        "links": [2, 4], "rules": ["tapered"], "quick": False, "poses": 6,
        "seed": scaling.EVAL_SEED, "max_bytes": GIB, "machine_bytes": 8 * GIB,
        "peak_method": "tracemalloc", "horizon_short": 5.0, "horizon_long": 8.0})
    report = result.report()
    paths = write(report, tmp_path, "twolink scaling --test")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(FILES.values())
    assert json.loads(paths["json"].read_text())["rows"][2]["status"] == "refused"
    md = paths["markdown"].read_text()
    assert "`twolink scaling --test`" in md and refused.note in md and "9 324" in md
    assert ("the rows of `centralized_full`, `decentralized_full` equal the committed files "
            "bit for bit") in md
    k = two_link_rows[1].evaluation.horizons["5"]["successes"]
    assert format_rate(k, 6) in tables(report)
    assert paths["figure"].read_bytes()[:4] == b"\x89PNG"
    # Sweeps per agent, agent N first, also from the JSON read back (its keys are sorted).
    shipped = load_policy("decentralized_full")
    sweeps = " / ".join(str(a.info["iterations"]) for a in shipped.agents)
    assert [a.name for a in shipped.agents] == ["agent2", "agent1"]
    assert f"| {sweeps} |" in markdown(json.loads(paths["json"].read_text()), "x")


def test_pd_row_is_the_tuned_per_joint_pd_on_the_evaluation_poses():
    row = scaling.measure(3, "copied", "pd", poses=2)
    assert row.status == "run" and row.synthesis is None and row.estimate is None
    assert "sat 57 deg, zeta 1.4" in row.note and "random_poses(3, 64, 7100 + 3)" in row.note
    assert row.evaluation.seed == scaling.EVAL_SEED + 3
    assert row.evaluation.horizons["8"]["successes"] == 2     # both poses settle
    line = tables({"options": {"rules": ["copied"], "horizon_short": 5.0,
                               "horizon_long": 8.0}, "rows": [row.as_dict()]})
    assert "| 3 | per-joint PD | — | — | — | — | — | " in line
    with pytest.raises(ValueError, match="the pd rows are for three links and more"):
        scaling.measure(2, "copied", "pd")
    with pytest.raises(ValueError, match="unknown scheme 'lqr'"):
        scaling.measure(3, "copied", "lqr")


def test_peak_measured_in_a_fresh_process():
    row = scaling.measure(2, "copied", "decentralized", poses=2)
    s = row.synthesis
    assert s.peak_method == "process" and s.matches_shipped_policy is True
    # The warm-up loads the compiled kernels first: the figure is the synthesis alone.
    assert 0 < s.peak_bytes < 64 * 2**20
    assert s.cpu_seconds > 0 and s.wall_seconds > 0


@pytest.mark.parametrize("argv, message", [
    (["--links", "1"], "links must be"),
    (["--links", "2", "7"], "links must be"),
    (["--poses", "0"], "poses must be a whole number from 1 to"),
    (["--max-memory", "1e9"], "--max-memory must be more than 0 and at most"),
    (["--max-memory", "nan"], "--max-memory must be more than 0"),
    (["--rules", "diagonal"], "unknown link rule 'diagonal'"),
    (["--quick", "--links", "5"], "quick runs go up to 4 links"),
    (["--seed", "-1"], "seed must be a whole number from 0"),
])
def test_bad_input_is_one_line_and_writes_nothing(argv, message, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["scaling", *argv, "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("twolink scaling: error: ") and message in err
    assert err.count("\n") == 1 and not out.exists()


def test_command_writes_the_report(tmp_path, capsys):
    out = tmp_path / "quick"
    code = main(["scaling", "--quick", "--links", "2", "--poses", "2", "--rules", "copied",
                 "--peak", "tracemalloc", "--max-memory", "2", "-o", str(out), "--json"])
    assert code == 0
    report = json.loads(capsys.readouterr().out)
    assert report["command"] == ("twolink scaling --quick --links 2 --rules copied --poses 2 "
                                 "--max-memory 2 --peak tracemalloc")
    assert [(r["links"], r["scheme"], r["status"]) for r in report["rows"]] == [
        (2, "centralized", "run"), (2, "decentralized", "run")]
    assert report["options"]["max_bytes"] == 2 * GIB and report["options"]["poses"] == 2
    assert sorted(p.name for p in out.iterdir()) == sorted(FILES.values())


def test_fresh_process_hands_back_errors_and_deaths():
    with pytest.raises(ValueError, match="poses must be a whole number"):
        in_fresh_process(scaling.check_poses, (0,))
    with pytest.raises(ProcessDied, match="exit code 3 before answering"):
        in_fresh_process(os._exit, (3,))
