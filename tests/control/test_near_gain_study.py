"""docs/studies/near_gain.py: the choice of the near-goal gain (every nominal pose kept,
then the most challenge successes, ties to the least change), the read-out it gives a
shipped policy, and one error line with exit 2 for a bad policy name or a foreign file."""
import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from twolink.policy.fuzzy_policy import load_policy

PATH = Path(__file__).resolve().parents[2] / "docs" / "studies" / "near_gain.py"


@pytest.fixture
def study(monkeypatch):
    monkeypatch.syspath_prepend(str(PATH.parent))
    spec = importlib.util.spec_from_file_location("near_gain", PATH)
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, "near_gain", module)
    spec.loader.exec_module(module)
    return module


def _row(a, g, none, *challenge):
    return {"angle_deg": a, "gain": g,
            "cells": dict(zip(("none", "medium", "medium compensated", "hard",
                               "hard compensated"), (none, *challenge)))}


def test_the_choice_keeps_every_nominal_pose_then_the_most_challenge_successes(study):
    rows = [_row(20, 0.1, 47, 256, 256, 256, 256),       # loses a nominal pose: out
            _row(20, 0.2, 48, 200, 250, 100, 240),
            _row(60, 0.3, 48, 210, 250, 90, 240),       # same sum, larger g: chosen
            _row(40, 0.3, 48, 220, 240, 90, 240)]       # same sum and g, smaller A: chosen
    assert study.choose(rows) is rows[3]
    assert study.choose(rows[:3]) is rows[2]
    assert study.choose(rows[:1]) is None
    assert study.choose(rows, ("hard",)) is rows[1]     # 100 hard successes
    assert study.choices({"rows": rows}) == {
        "challenge sum": {"angle_deg": 40, "gain": 0.3},
        "hard compensated": {"angle_deg": 40, "gain": 0.3}}
    assert study.choices({"rows": rows[:1]}) == {"challenge sum": None,
                                                  "hard compensated": None}


def test_choose_only_rechooses_the_files_runs_without_measuring(study, tmp_path, capsys):
    out = tmp_path / "g.json"
    run = {"policy": "decentralized_edge", "base": {}, "chosen": {},
           "rows": [_row(20, 0.2, 48, 200, 250, 100, 240), _row(60, 0.5, 48, 1, 1, 1, 250)]}
    out.write_text(json.dumps({"schema": study.SCHEMA, "version": study.VERSION,
                               "runs": [run]}))
    assert study.main(["--choose-only", "--json", str(out)]) == 0
    (got,) = json.loads(out.read_text())["runs"]
    assert got["chosen"] == {"challenge sum": {"angle_deg": 20, "gain": 0.2},
                             "hard compensated": {"angle_deg": 60, "gain": 0.5}}
    assert got["rows"] == run["rows"]
    empty = tmp_path / "none.json"
    assert study.main(["--choose-only", "--json", str(empty)]) == 2
    assert "--choose-only needs runs to choose from" in capsys.readouterr().err
    assert not empty.exists()


def test_with_gain_adds_the_rule_to_the_policys_own_read_out(study):
    base = load_policy("decentralized_edge")
    policy = study.with_gain(base, 0.2, 90.0)
    assert policy.readout.near_gain == 0.2 and policy.readout.near_deg == 90.0
    assert policy.readout.speed_dead_zone == base.readout.speed_dead_zone
    x = np.array([[0.0, 0.0, 0.3, -0.2], [2.0, -2.0, 0.0, 0.0]])
    np.testing.assert_allclose(policy(x)[0], 0.2 * base(x)[0])
    np.testing.assert_allclose(policy(x)[1], base(x)[1])


@pytest.mark.parametrize("argv, message", [
    (["--policies", "nonesuch"], "unknown two-link shipped policy 'nonesuch'"),
    (["--policies", "decentralized_3link"], "unknown two-link shipped policy"),
])
def test_bad_policies_are_one_line_and_exit_2(study, tmp_path, capsys, argv, message):
    out = tmp_path / "g.json"
    assert study.main(argv + ["--json", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("near_gain: error:") and message in err
    assert len(err.splitlines()) == 1 and not out.exists()


def test_a_foreign_file_is_refused_and_left_alone(study, tmp_path, capsys):
    out = tmp_path / "g.json"
    out.write_text(json.dumps({"schema": "twolink.links_reach", "version": 1, "runs": []}))
    assert study.main(["--policies", "decentralized_edge", "--json", str(out)]) == 2
    assert "is not a twolink.near_gain version 1 file" in capsys.readouterr().err
    assert json.loads(out.read_text())["schema"] == "twolink.links_reach"


def test_medium_wide_needs_the_grid_first_and_adds_a_third_choice(study, tmp_path, capsys):
    out = tmp_path / "g.json"
    assert study.main(["--medium-wide", "--policies", "decentralized_edge",
                       "--json", str(out)]) == 2
    assert "--medium-wide needs the grid of decentralized_edge" in capsys.readouterr().err
    assert not out.exists()
    rows = [_row(20, 0.2, 48, 200, 250, 100, 240), _row(60, 0.5, 48, 1, 1, 1, 250)]
    rows[0]["cells"]["medium_wide"], rows[1]["cells"]["medium_wide"] = 1500, 1530
    assert study.choices({"rows": rows})["medium (wide)"] == {"angle_deg": 60, "gain": 0.5}


def test_parts_needs_the_grid_first(study, tmp_path, capsys):
    out = tmp_path / "g.json"
    assert study.main(["--parts", "--policies", "decentralized_edge", "--json", str(out)]) == 2
    assert "--parts needs the grid of decentralized_edge" in capsys.readouterr().err
    assert not out.exists()
    assert study.PARTS == ("delays", "noise", "plants", "faults")
    from twolink.sim.challenges import LEVELS
    p = study._parts()
    assert (p["noise"].angle_noise_deg, p["noise"].speed_noise, p["noise"].action_delay) == \
        (LEVELS["hard"].angle_noise_deg, LEVELS["hard"].speed_noise, 0)
    assert (p["delays"].action_delay, p["delays"].observation_delay) == (1, 1)
