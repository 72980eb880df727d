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


def _forge(tmp_path, name, **values):
    """A file with ``values`` in place of Table I's, its derived values and hash made to
    agree (as a hostile writer would)."""
    path = _write(tmp_path, name, TABLE_I)

    def edit(r):
        r["parameters"].update(values)
        r["provenance"].pop("identified")
        p = r["parameters"]
        try:
            r["dynamic"].update(P1=p["m1"] * p["c1"] ** 2 + p["m2"] * p["l1"] ** 2 + p["I1"],
                                P2=p["m2"] * p["c2"] ** 2 + p["I2"], P3=p["m2"] * p["l1"] * p["c2"])
        except OverflowError:
            pass
        _rehash(r)
    _rewrite(path, edit)
    return path


@pytest.mark.parametrize("values, message", [
    ({"m1": 10 ** 400}, r"parameter m1 must be a finite number, got an integer of 401 digits"),
    ({"m2": 0}, "parameter m2 must be positive"),
    ({"m2": 5e-324, "I2": 5e-324}, "link 2 is all but massless"),
    ({"m1": 1e-300, "I1": 1e-300, "m2": 1e-300, "I2": 1e-300}, "link 1 is all but massless"),
    # A light link 2: the full model's RK4 diverges (it is not that T does not factor).
    ({"m2": 1e-3, "I2": 1e-6}, r"link 2 is too light for its damping .* over RK4's "
                               r"stability limit"),
])
def test_overflowing_massless_and_unsimulable_arms_are_refused_in_one_line(
        tmp_path, values, message):
    path = _forge(tmp_path, "bad.json", **values)
    with pytest.raises(pf.ParameterFileError, match=message) as err:
        pf.load(path)
    assert "\n" not in str(err.value) and str(path) in str(err.value)


def test_the_rk4_limit_is_where_the_full_model_starts_to_diverge():
    """check_sampling's bound is the true cause: just inside it the full model (6) stays
    bounded from every grid state, just outside it it reaches NaN."""
    import numpy as np

    from twolink.arm.dynamics import full_acceleration
    from twolink.arm.integrate import RK4_LIMIT, check_sampling, sample_step, sampling_rate

    x = np.stack(np.meshgrid(np.linspace(-3, 3, 7), np.linspace(-3, 3, 7), [-6, 0, 6],
                             [-6, 0, 6]), -1).reshape(-1, 4)
    tau = np.array([[0.2, 0.1], [-0.2, 0.1], [0.0, -0.1]])[:, None, :]
    inside, outside = TABLE_I.scaled(m2=0.01, I2=0.01), TABLE_I.scaled(m2=0.004, I2=0.004)
    assert sampling_rate(inside)[0] * 0.005 < RK4_LIMIT < sampling_rate(outside)[0] * 0.005
    check_sampling(inside)
    with pytest.raises(ValueError, match="link 2 is too light"):
        check_sampling(outside)
    with np.errstate(all="ignore"):
        assert np.isfinite(sample_step(full_acceleration, inside, x, tau)).all()
        state = x
        for _ in range(3):
            state = sample_step(full_acceleration, outside, state, tau[0])
        assert not np.isfinite(state).all()


def test_a_fifo_is_refused_without_blocking(tmp_path):
    import os

    fifo = tmp_path / "params.json"
    os.mkfifo(fifo)
    with pytest.raises(pf.ParameterFileError, match=r"is not a regular file \(a FIFO\)"):
        pf.load(fifo)


def test_synthesize_params_fifo_exits_2_in_one_line(tmp_path, capsys):
    """Run in a thread: a FIFO opened for reading would block until a writer comes."""
    import os
    import threading

    from twolink.cli import main

    fifo = tmp_path / "params.json"
    os.mkfifo(fifo)
    codes = []
    run = threading.Thread(target=lambda: codes.append(main(
        ["synthesize", "decentralized", "--params", str(fifo), "-o", str(tmp_path / "p.npz")])),
        daemon=True)
    run.start()
    run.join(30)
    if run.is_alive():                     # unblock the reader before failing
        os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
    err = capsys.readouterr().err
    assert codes == [2] and err.count("\n") == 1, err
    assert "is not a regular file (a FIFO)" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["params.json"]


def test_save_refuses_an_arm_no_plant_simulates(tmp_path):
    with pytest.raises(ValueError, match="link 2 is too light"):
        pf.save(tmp_path / "a.json", TABLE_I.scaled(m2=1e-3, I2=1e-3), provenance={})
    assert list(tmp_path.iterdir()) == []
