"""Sets of files are written all or none; saved reports and package data are checked
before any work, and their errors name the file; outputs never land in the package."""
import errno
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from twolink.artifacts import STAGING_PREFIX, staged_set
from twolink.cli import main
from twolink.resources import limits_file
from twolink.studies.leaderboard import report as lb_report

ROW = {"controller": "pd", "level": "none", "mode": "plain", "successes": 3, "n": 5,
       "rate": 0.6, "wilson_95": [0.23, 0.88], "worst_plant": None,
       "worst_plant_successes": None, "median_settle": 1.5, "settle_ratio_median": 1.7,
       "settle_ratio_worst": None, "mean_abs_torque": 0.2, "seconds": 0.1}
REPORT = {"command": "twolink leaderboard --quick", "states": 5, "plants": 4, "seed": 2026,
          "horizon": 5.0, "limits": "T* of the shipped time-optimal table, full model (6)",
          "levels": ["none"], "rows": [ROW]}


def _snapshot(folder: Path) -> dict:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


@pytest.fixture
def saved(tmp_path):
    out = tmp_path / "lb"
    lb_report.write(REPORT, out)
    return out


@pytest.mark.parametrize("error", [OSError(errno.ENOSPC, "No space left on device"),
                                   KeyboardInterrupt()])
def test_a_set_cut_short_leaves_the_previous_set_and_no_staging(saved, monkeypatch, error):
    before = _snapshot(saved)
    assert set(before) == {"leaderboard.md", "leaderboard.json", "leaderboard.png"}

    def fail(report, path):              # the last file of the set cannot be written
        raise error

    monkeypatch.setattr(lb_report, "figure", fail)
    changed = {**REPORT, "rows": [{**ROW, "controller": "other"}]}
    with pytest.raises(type(error)):
        lb_report.write(changed, saved)
    assert _snapshot(saved) == before
    assert not any(p.name.startswith(STAGING_PREFIX) for p in saved.parent.rglob("*"))


def test_a_new_folder_appears_whole_or_not_at_all(tmp_path):
    with pytest.raises(OSError):
        with staged_set(tmp_path / "new") as stage:
            (stage / "a.txt").write_text("a")
            raise OSError(errno.ENOSPC, "No space left on device")
    assert list(tmp_path.iterdir()) == []
    with staged_set(tmp_path / "new") as stage:
        (stage / "a.txt").write_text("a")
        (stage / "b.txt").write_text("b")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["new"]
    assert _snapshot(tmp_path / "new") == {"a.txt": b"a", "b.txt": b"b"}


def test_a_failed_rename_puts_the_replaced_files_back(tmp_path, monkeypatch):
    out = tmp_path / "out"
    out.mkdir()
    (out / "a.txt").write_text("old a")
    (out / "b.txt").write_text("old b")
    (out / "keep.txt").write_text("kept")
    real = os.replace

    def replace(src, dst):
        if Path(dst) == out / "b.txt" and STAGING_PREFIX in str(src):
            raise OSError(errno.EIO, "Input/output error")
        return real(src, dst)

    monkeypatch.setattr(os, "replace", replace)
    with pytest.raises(OSError):
        with staged_set(out) as stage:
            (stage / "a.txt").write_text("new a")
            (stage / "b.txt").write_text("new b")
    assert _snapshot(out) == {"a.txt": b"old a", "b.txt": b"old b", "keep.txt": b"kept"}


def _cli(*argv, timeout=120):
    t0 = time.monotonic()
    res = subprocess.run([sys.executable, "-m", "twolink.cli", *argv], capture_output=True,
                         text=True, timeout=timeout)
    return res, time.monotonic() - t0


@pytest.mark.parametrize("corrupt, message", [
    (lambda r: r["rows"][0].update(successes="many"), "row 1 has successes 'many'"),
    (lambda r: r["rows"].append({**ROW, "level": "none", "mean_abs_torque": "NaN"}),
     "row 2 has mean_abs_torque"),
    (lambda r: r.update(seed=-5), "seed must be a whole number from 0"),
    (lambda r: r.update(plants=10**6), "plants must be a whole number from 1 to 10000"),
    (lambda r: r["rows"][0].pop("mode"), "row 1 has no mode"),
])
def test_merge_refuses_a_corrupted_report_before_measuring(saved, corrupt, message):
    path = saved / "leaderboard.json"
    data = json.loads(path.read_text())
    corrupt(data)
    path.write_text(json.dumps(data))
    before = _snapshot(saved)
    res, seconds = _cli("leaderboard", "--quick", "--merge", "--only", "--controller", "lqr",
                        "--levels", "none", "--out", str(saved))
    assert res.returncode == 2, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and f"leaderboard report {path}: " in lines[0], lines
    assert message in lines[0], lines
    assert seconds < 30 and "[1/" not in res.stderr       # no row was measured
    assert _snapshot(saved) == before


def test_merge_names_a_truncated_report(saved):
    path = saved / "leaderboard.json"
    path.write_text(path.read_text()[:50])
    before = _snapshot(saved)
    assert main(["leaderboard", "--quick", "--merge", "--only", "--controller", "lqr",
                 "--out", str(saved)]) == 2
    assert _snapshot(saved) == before


def test_a_truncated_limits_file_is_named(tmp_path, monkeypatch, capsys):
    broken = tmp_path / "limits.json"
    broken.write_text(limits_file().read_text()[:200])
    monkeypatch.setattr("twolink.resources.limits_file", lambda: broken)
    assert main(["limits"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{broken}: not valid JSON (" in err[0], err


def test_outputs_through_a_symlink_into_the_package_data_are_refused(tmp_path):
    data = limits_file().parent
    before = _snapshot(data)
    link = tmp_path / "link"
    link.symlink_to(data, target_is_directory=True)
    for argv in (["leaderboard", "--quick", "--only", "--controller", "pd", "--levels", "none",
                  "--out", str(link)],
                 ["limits", "--x0", "0.3", "0.3", "0", "0", "-o",
                  str(link / "limits.json")],
                 ["mismatch", "--links", "3", "--out", str(link)],
                 ["scaling", "--quick", "-o", str(link)]):
        res, _ = _cli(*argv)
        assert res.returncode == 2, (argv, res.stderr)
        assert "resolves into twolink's shipped files" in res.stderr, (argv, res.stderr)
        assert res.stderr.count("\n") == 1, res.stderr
    assert _snapshot(data) == before


@pytest.mark.parametrize("path", ["twolink-results/x", "twolink-results/leaderboard/x",
                                  "renders/leaderboard-quick/x", "renders/scaling-quick/x",
                                  "renders/mismatch-quick/x", "renders/rollout.csv",
                                  "renders/centralized_mujoco.mp4", "identified.json",
                                  "learned_fqi.npz", "twolink.xml",
                                  f"renders/leaderboard/{STAGING_PREFIX}abc/x"])
def test_default_outputs_are_ignored_by_git(path):
    root = Path(__file__).resolve().parents[2]
    res = subprocess.run(["git", "check-ignore", "-q", path], cwd=root)
    assert res.returncode == 0, f"{path} is not ignored"
