"""docs/studies/torque_reach.py: the largest torque a controller uses and its share of
full-torque samples early on, measured on the nominal arm; bad input in one line."""
from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PATH = ROOT / "docs/studies/torque_reach.py"


def _module():
    spec = importlib.util.spec_from_file_location("torque_reach", PATH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_bang_bang_reaches_the_limit_and_a_gentle_pd_does_not(tmp_path, capsys):
    out = tmp_path / "reach.json"
    assert _module().main(["bb=bang_bang", "lqr=lqr", "-o", str(out)]) == 0
    rows = json.loads(out.read_text())["rows"]
    assert rows["bb"]["largest_fraction"] == [1.0, 1.0]
    assert all(s > 0.1 for s in rows["bb"]["full_torque_share_first_s"])
    assert rows["bb"]["samples"] == 65 * 100
    # the saturated LQR: every share is a fraction, the largest torque within the limit
    assert all(0.0 <= s <= 1.0 for s in rows["lqr"]["full_torque_share_first_s"])
    assert all(0.0 < v <= 1.0 for v in rows["lqr"]["largest_fraction"])
    assert "bb: largest |tau|/tau_max 1.000, 1.000" in capsys.readouterr().out


def test_the_shipped_sac_mixed_uses_full_torque(tmp_path):
    from twolink.control.learned import learned_agent_path

    pytest.importorskip("stable_baselines3")
    try:
        learned_agent_path("sac_mixed")
    except Exception as exc:                     # a checkout without renders/
        pytest.skip(str(exc))
    out = tmp_path / "reach.json"
    assert _module().main(["s=sac_mixed", "-o", str(out)]) == 0
    row = json.loads(out.read_text())["rows"]["s"]
    assert row["largest_fraction"] == [1.0, 1.0]          # its action gain at work
    assert row["full_torque_share_first_s"][0] > 0.2


def test_bad_input_is_one_line_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "reach.json"
    module = _module()
    assert module.main(["bang_bang", "-o", str(out)]) == 2
    assert "'bang_bang' is not NAME=CONTROLLER" in capsys.readouterr().err
    assert module.main(["x=no_such_controller", "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("torque_reach: x: ")
    assert module.main(["p=pd_3link_tapered", "-o", str(out)]) == 2
    assert "a 3-link controller; this study runs two links" in capsys.readouterr().err
    assert not out.exists()
