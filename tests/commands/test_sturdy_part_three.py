"""Bad command lines and inputs are one error line (exit 2) naming the problem: unknown
options of every subcommand, tampered learning checkpoints, absurd parameter files,
negative pose seeds and a mismatch report folder that is a file."""
import dataclasses
import subprocess
import sys

import pytest

from twolink.arm import parameter_file
from twolink.arm.parameters import TABLE_I
from twolink.cli import main
from twolink.commands import SUMMARIES


def _cli(capsys, *argv):
    try:
        code = main(list(map(str, argv)))
    except SystemExit as exc:            # argparse's own errors
        code = exc.code
    return code, capsys.readouterr().err


# ------------------------------------------------------------------ unknown options
@pytest.mark.parametrize("command", sorted(SUMMARIES))
def test_an_unknown_option_is_one_line_for_every_subcommand(capsys, command):
    code, err = _cli(capsys, command, "--zzqx")
    assert code == 2
    assert err == (f"twolink {command}: error: unknown option --zzqx "
                   f"(see twolink {command} --help)\n")


@pytest.mark.parametrize("argv, line", [
    (["evaluate", "centralized", "--foo", "--bar=3"],
     "twolink evaluate: error: unknown options --foo, --bar (see twolink evaluate --help)"),
    (["evaluate", "centralized", "--plantss", "3"],
     "twolink evaluate: error: unknown option --plantss (did you mean --plants?) "
     "(see twolink evaluate --help)"),
    (["evaluate", "centralized", "extra"],
     "twolink evaluate: error: unexpected argument 'extra' (see twolink evaluate --help)"),
    (["evaluate", "centralized", "--plants", "x"],
     "twolink evaluate: error: argument --plants: invalid int value: 'x' "
     "(see twolink evaluate --help)"),
    (["--foo"], "twolink: error: unknown option --foo (see twolink --help)"),
    (["rollout", "--x0", "-1", "-3", "0", "0", "--bogus"],
     "twolink rollout: error: unknown option --bogus (see twolink rollout --help)"),
])
def test_bad_command_lines_are_one_line(capsys, argv, line):
    code, err = _cli(capsys, *argv)
    assert code == 2
    assert err == line + "\n"


def test_the_installed_command_exits_2_with_one_line(tmp_path):
    res = subprocess.run([sys.executable, "-m", "twolink.cli", "evaluate", "--foo"],
                         capture_output=True, text=True, cwd=tmp_path)
    assert res.returncode == 2
    assert res.stderr == ("twolink evaluate: error: unknown option --foo "
                          "(see twolink evaluate --help)\n")
    assert res.stdout == ""


# ------------------------------------------------------------------ learn --resume
@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory):
    folder = tmp_path_factory.mktemp("learn")
    path = folder / "ck.npz"
    assert main(["learn", "--task", "centralized", "--steps", "400", "--arms", "4",
                 "--eval-every", "400", "-o", str(path), "--json"]) == 0
    return path


def _tampered(checkpoint, tmp_path, change):
    from twolink.synthesis.learning import META_KEY
    from twolink.policy.fuzzy_policy import Policy
    policy = Policy.load(checkpoint)
    change(policy.meta[META_KEY])
    path = tmp_path / "bad.npz"
    policy.save(path)
    return path


@pytest.mark.parametrize("change, why", [
    (lambda i: i["resume"].__setitem__("x", [0.0] * 7),
     "x must hold 16 finite numbers (4 per arm), got 7 values"),
    (lambda i: i["resume"].__setitem__("x", i["resume"]["x"][:40]), "x of 30 bytes, expected 128"),
    (lambda i: i["resume"].__setitem__("clock", [1, 2, 3]),
     "clock must be a list of 4 non-negative whole numbers"),
    (lambda i: i["resume"].__setitem__("clock", "abc"),
     "clock must be a list of 4 non-negative whole numbers"),
    (lambda i: i.__setitem__("learn_seconds", "5"),
     "learn_seconds must be a finite non-negative number, got '5'"),
    (lambda i: i.__setitem__("learn_seconds", -1.0),
     "learn_seconds must be a finite non-negative number, got -1.0"),
    (lambda i: i.__setitem__("iterations", "12"),
     "iterations must be a non-negative whole number, got '12'"),
    (lambda i: i.__setitem__("iterations", 1.5),
     "iterations must be a non-negative whole number, got 1.5"),
    (lambda i: i.__setitem__("curve", "abc"), "curve must be a list of evaluations"),
])
def test_a_tampered_checkpoint_is_refused_up_front_naming_the_file(
        checkpoint, tmp_path, capsys, monkeypatch, change, why):
    from twolink.synthesis import learning
    path = _tampered(checkpoint, tmp_path, change)
    monkeypatch.setattr(learning.Learner, "__init__",
                        lambda *a, **k: pytest.fail("built a learner from a bad checkpoint"))
    code, err = _cli(capsys, "learn", "--resume", path, "--steps", "800")
    assert code == 2
    assert err.startswith(f"twolink learn: error: --resume {path}: malformed learning "
                          f"checkpoint ("), err
    assert why in err and err.count("\n") == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.npz"]


@pytest.mark.parametrize("content", [b"seconds: 12\n", b"PK\x03\x04 truncated"])
def test_a_resume_file_that_is_no_checkpoint_is_one_line(tmp_path, capsys, content):
    path = tmp_path / "ck.npz"
    path.write_bytes(content)
    code, err = _cli(capsys, "learn", "--resume", path)
    assert code == 2
    assert err.startswith(f"twolink learn: error: {path} is not a twolink policy file")
    assert err.count("\n") == 1


def test_a_shipped_policy_is_no_checkpoint(tmp_path, capsys):
    from twolink.policy.fuzzy_policy import load_policy
    path = tmp_path / "c.npz"
    load_policy("centralized").save(path)
    code, err = _cli(capsys, "learn", "--resume", path)
    assert code == 2
    assert err == (f"twolink learn: error: --resume {path}: not a learning checkpoint (the "
                   f"policy carries no resume state; checkpoints are written by `twolink "
                   f"learn`)\n")


def test_a_good_checkpoint_still_resumes(checkpoint, tmp_path, capsys):
    out = tmp_path / "more.npz"
    code, err = _cli(capsys, "learn", "--resume", checkpoint, "--steps", "800", "-o", out,
                     "--json")
    assert code == 0, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["more.npz", "more_curve.png"]


# ------------------------------------------------------------------ parameter files
@pytest.mark.parametrize("field, value, accepted", [
    ("tau1_max", 1e300, "accepted 2e-05 to 2000"),
    ("tau2_max", 1e6, "accepted 1e-05 to 1000"),
    ("m1", 1e-9, "accepted 0.000125 to 12500"),
    ("dtheta2_max", 1e9, "accepted 0.000628319 to 62831.9"),
])
def test_synthesize_refuses_an_absurd_parameter_naming_it_and_the_file(
        tmp_path, capsys, field, value, accepted):
    path = tmp_path / "arm.json"
    parameter_file.save(path, dataclasses.replace(TABLE_I, **{field: value}), provenance={})
    code, err = _cli(capsys, "synthesize", "centralized", "--params", path, "-o",
                     tmp_path / "p.npz")
    assert code == 2
    assert err == (f"twolink synthesize: error: {path}: parameter {field} = {value:g} is "
                   f"implausible: {accepted} (Table I's {getattr(TABLE_I, field):g} times "
                   f"1/10000 to 10000)\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["arm.json"]


def test_plausible_parameters_still_load(tmp_path):
    path = tmp_path / "arm.json"
    p = dataclasses.replace(TABLE_I, tau1_max=2.0, m2=5.0)
    parameter_file.save(path, p, provenance={})
    assert parameter_file.load(path) == p


# ------------------------------------------------------------------ seeds
@pytest.mark.parametrize("argv", [
    ["rollout", "--x0", "random", "--no-save"],
    ["rollout", "--links", "3", "--x0", "random", "--no-save"],
    ["render", "--x0", "random", "--duration", "0.1", "--size", "64x48"],
])
def test_a_negative_pose_seed_is_one_line(tmp_path, capsys, monkeypatch, argv):
    monkeypatch.chdir(tmp_path)
    code, err = _cli(capsys, *argv, "--seed", "-1")
    assert code == 2
    assert err == (f"twolink {argv[0]}: error: --seed must be a non-negative whole number "
                   f"(at most 2**63 - 1), got -1\n")
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------ mismatch -o FILE
@pytest.mark.parametrize("extra", [[], ["--quick"], ["--links", "3"]])
def test_mismatch_into_a_file_is_refused(tmp_path, capsys, extra):
    path = tmp_path / "report"
    path.write_text("mine")
    code, err = _cli(capsys, "mismatch", *extra, "-o", path)
    assert code == 2
    assert err == f"twolink mismatch: error: -o/--out {path} is a file; give a folder\n"
    assert path.read_text() == "mine"
    assert [p.name for p in tmp_path.iterdir()] == ["report"]
