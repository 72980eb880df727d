"""Parameter files: round trip, and every kind of bad file refused with one line."""
import json

import pytest

from twolink.arm import parameter_file as pf
from twolink.arm.parameters import TABLE_I
from twolink.sim.perturbations import perturbed

ARM = perturbed(TABLE_I, m2=0.13, c2=-0.07, I1=0.11, b1=-0.05, b2=0.17)


def _identified(p):
    return {k: {"value": getattr(p, k), "std_error": 1e-3 * getattr(p, k)} for k in pf.DYNAMIC}


def _write(tmp_path, name="arm.json", params=ARM):
    path = tmp_path / name
    pf.save(path, params, provenance={"identified": _identified(params), "seed": 7})
    return path


def _rewrite(path, edit):
    record = json.loads(path.read_text())
    edit(record)
    path.write_text(json.dumps(record))


def _rehash(record):
    record["sha256"] = pf._content_hash(record)


def test_round_trip_gives_the_same_parameters_and_provenance(tmp_path):
    path = _write(tmp_path)
    content = pf.read(path)
    assert pf.load(path) == ARM
    assert content.provenance["seed"] == 7
    assert content.provenance["identified"]["P3"]["value"] == ARM.P3
    record = json.loads(path.read_text())
    assert record["format"] == pf.FORMAT and record["format_version"] == pf.FORMAT_VERSION
    assert record["dynamic"] == pf.dynamic_values(ARM)
    assert len(record["sha256"]) == 64 and content.sha256 == record["sha256"]


@pytest.mark.parametrize("edit, message", [
    (lambda r: r["parameters"].update(m2=1.5), "does not match the file's sha256"),
    (lambda r: r.update(sha256="0" * 64), "does not match the file's sha256"),
    (lambda r: r.update(format="twolink-policy"), "not a parameter file"),
    (lambda r: r.update(format_version=99), "format version 99"),
])
def test_edited_and_foreign_files_are_refused(tmp_path, edit, message):
    path = _write(tmp_path)
    _rewrite(path, edit)
    with pytest.raises(pf.ParameterFileError, match=message):
        pf.load(path)


@pytest.mark.parametrize("edit, message", [
    (lambda r: r["parameters"].update(m2=-1.0), "m2 must be positive"),
    (lambda r: r["parameters"].update(m2="heavy"), "m2 must be a number"),
    (lambda r: r["parameters"].pop("l2"), "must name exactly"),
    (lambda r: r["parameters"].update(l3=0.1), "must name exactly"),
    (lambda r: r["dynamic"].update(P1=1.0), "P1 = 1.0 recorded"),
    (lambda r: r["provenance"]["identified"]["b2"].update(value=0.5), "identified b2"),
    (lambda r: r["provenance"]["identified"]["b2"].update(std_error=-1), "std_error"),
    (lambda r: r.update(provenance=[]), "'provenance' must be an object"),
])
def test_inconsistent_files_are_refused_even_with_a_valid_hash(tmp_path, edit, message):
    path = _write(tmp_path)
    _rewrite(path, lambda r: (edit(r), _rehash(r)))
    with pytest.raises(pf.ParameterFileError, match=message):
        pf.load(path)


def test_corrupted_missing_and_oversized_files_are_refused(tmp_path):
    path = _write(tmp_path)
    text = path.read_text()
    path.write_text(text[: len(text) // 2])
    with pytest.raises(pf.ParameterFileError, match="not valid JSON"):
        pf.load(path)
    path.write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(pf.ParameterFileError, match="not valid JSON"):
        pf.load(path)
    path.write_text(text.replace('"m2": ' + repr(ARM.m2), '"m2": NaN'))
    with pytest.raises(pf.ParameterFileError, match="not valid JSON"):
        pf.load(path)
    with pytest.raises(pf.ParameterFileError, match="no such file"):
        pf.load(tmp_path / "missing.json")
    with pytest.raises(pf.ParameterFileError, match="is a directory"):
        pf.load(tmp_path)
    big = tmp_path / "big.json"
    big.write_text(" " * (pf.MAX_BYTES + 1))
    with pytest.raises(pf.ParameterFileError, match="more than a parameter file may hold"):
        pf.load(big)


def test_save_refuses_bad_provenance_and_writes_nothing(tmp_path):
    path = tmp_path / "arm.json"
    with pytest.raises(ValueError, match="finite JSON"):
        pf.save(path, ARM, provenance={"noise": float("nan")})
    wrong = _identified(ARM)
    wrong["P1"]["value"] *= 1.01
    with pytest.raises(ValueError, match="identified P1 does not match"):
        pf.save(path, ARM, provenance={"identified": wrong})
    with pytest.raises(ValueError, match="must be ArmParameters"):
        pf.save(path, ARM.as_dict(), provenance={})
    assert list(tmp_path.iterdir()) == []
