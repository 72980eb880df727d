"""docs/studies/links_reach.py resumes: poses already answered in its JSON are kept, only
the missing ones are solved, and the file is rewritten after every chunk."""
import importlib.util
import json
import sys
from pathlib import Path

import pytest

pytest.importorskip("casadi")

PATH = Path(__file__).resolve().parents[2] / "docs" / "studies" / "links_reach.py"


@pytest.fixture(scope="module")
def study():
    spec = importlib.util.spec_from_file_location("links_reach_study", PATH)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def test_a_run_resumes_where_its_file_stops(study, tmp_path, capsys):
    out = tmp_path / "reach.json"
    assert study.main(["--links", "3", "--poses", "2", "--chunk", "1", "--json", str(out)]) == 0
    first = json.loads(out.read_text())["runs"][0]
    assert first["poses"] == 2 and len(first["answers"]) == 2
    assert capsys.readouterr().out.count(f"wrote {out}") == 2       # once per chunk
    assert study.main(["--links", "3", "--poses", "3", "--chunk", "2", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "2 answered already" in text and text.count("  pose ") == 1    # only pose 3
    run = json.loads(out.read_text())["runs"][0]
    assert run["answers"][:2] == first["answers"] and run["poses"] == 3
    assert run["reachable"] == sum(a["reachable"] for a in run["answers"])
    assert run["seconds"] >= first["seconds"]


def test_a_bad_chunk_is_one_line(study, tmp_path, capsys):
    assert study.main(["--links", "3", "--chunk", "0", "--json", str(tmp_path / "r.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("links_reach: error:") and "--chunk" in err
    assert not (tmp_path / "r.json").exists()
