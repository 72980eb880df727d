"""docs/studies/training_side.py: a centralized agent's training-side scores and its
nominal settle over T*, the same figure the leaderboard reports; bad input in one line."""
from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3")

ROOT = Path(__file__).resolve().parents[2]
PATH = ROOT / "docs/studies/training_side.py"


def _module():
    spec = importlib.util.spec_from_file_location("training_side", PATH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_nominal_settle_is_the_leaderboards(tmp_path, capsys):
    from twolink.control.learned import learned_agent_path

    try:
        learned_agent_path("sac_mixed")
    except Exception as exc:                     # a checkout without renders/
        pytest.skip(str(exc))
    out = tmp_path / "side.json"
    assert _module().main(["mixed=sac_mixed", "-o", str(out)]) == 0
    row = json.loads(out.read_text())["rows"]["mixed"]
    board = json.loads((ROOT / "renders/leaderboard/leaderboard.json").read_text())
    none = next(r for r in board["rows"]
                if r["controller"] == "sac_mixed" and r["level"] == "none")
    assert row["none"]["successes"] == none["successes"] == 65
    assert row["none"]["settle_over_tstar_median"] == pytest.approx(
        none["settle_ratio_median"], abs=1e-12)
    assert row["medium"]["n"] == row["hard"]["n"] == 8 * 65
    assert 0 < row["hard"]["successes"] <= row["medium"]["successes"] <= 520
    assert "mixed: none 65/65 at" in capsys.readouterr().out


def test_bad_input_is_one_line_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "side.json"
    module = _module()
    assert module.main(["sac_mixed", "-o", str(out)]) == 2
    assert "'sac_mixed' is not NAME=AGENT" in capsys.readouterr().err
    assert module.main(["x=no/such/agent.zip", "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("training_side: x: ")
    assert not out.exists()
