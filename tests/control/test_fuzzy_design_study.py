"""docs/studies/fuzzy_design.py: the tuning table's --merge keeps the committed rows and
the order of VARIANTS, and refuses to run without a table to merge into."""
import json
import sys

import pytest
from conftest import load_study


@pytest.fixture
def study(monkeypatch):
    return load_study("fuzzy_design", monkeypatch)


def _row(label, k):
    cell = {"successes": k, "n": 48, "wilson_95": [0.0, 1.0], "median_settle": 1.0}
    return {"variant": label, "synthesis_seconds": 0.1, **{c: cell for c in
                                                           ("none", "medium",
                                                            "medium compensated", "hard",
                                                            "hard compensated")}}


def test_merge_replaces_the_measured_rows_in_the_order_of_the_variants(study, tmp_path,
                                                                       monkeypatch, capsys):
    labels = list(study.VARIANTS)
    first, second, last = labels[0], labels[1], labels[-1]
    table = tmp_path / "design.json"
    table.write_text(json.dumps({"rows": [_row(last, 1), _row(first, 2), _row("gone", 3)]}))
    monkeypatch.setattr(study, "measure", lambda label: _row(label, 40))   # no synthesis
    assert study.main(["--merge", "--json", str(table), "--only", second, first]) == 0
    rows = json.loads(table.read_text())["rows"]
    # measured rows replace the stored ones; a stored row no variant names is dropped
    assert [(r["variant"], r["none"]["successes"]) for r in rows] == [
        (first, 40), (second, 40), (last, 1)]
    assert f"| {second} | 40/48" in capsys.readouterr().out


@pytest.mark.parametrize("argv", [["--merge"], ["--merge", "--only", "x"]])
def test_merge_needs_only_and_an_existing_table(study, tmp_path, capsys, argv):
    labels = [a if a != "x" else next(iter(study.VARIANTS)) for a in argv]
    with pytest.raises(SystemExit) as exc:
        study.main(labels + ["--json", str(tmp_path / "missing.json")])
    assert exc.value.code == 2
    assert "--merge needs --only and an existing --json file" in capsys.readouterr().err
    assert not (tmp_path / "missing.json").exists()
