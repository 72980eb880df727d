"""The project's own set-up: the system-library installer and the CI entry point."""
import os
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = ROOT / "scripts" / "install-system-deps.sh"


def _fake_bin(tmp_path, name, body):
    path = tmp_path / name
    path.write_text(f"#!/bin/sh\n{body}\n")
    path.chmod(0o755)


def test_installer_is_silent_when_the_libraries_are_present():
    res = subprocess.run(["bash", str(SCRIPT)], capture_output=True, text=True)
    assert res.returncode == 0 and res.stderr == "" and res.stdout == ""


def test_installer_sees_libraries_listed_early_in_a_large_linker_cache(tmp_path):
    # A cache far larger than a pipe buffer, the libraries on its first lines: a reader
    # that stops at the first match must not make them look missing.
    libs = "\n".join(f"\t{name} (libc6,x86-64) => /usr/lib/{name}" for name in (
        "libEGL.so.1", "libEGL_mesa.so.0", "libGL.so.1", "libOpenGL.so.0"))
    filler = tmp_path / "filler.txt"
    filler.write_text("\tlibfiller.so.0 (libc6,x86-64) => /usr/lib/libfiller.so.0\n" * 20000)
    _fake_bin(tmp_path, "ldconfig", f"printf '%s\\n' '{libs}'\ncat {filler}")
    _fake_bin(tmp_path, "id", "echo 1000")
    env = dict(os.environ, PATH=f"{tmp_path}:{os.environ['PATH']}")
    res = subprocess.run(["bash", str(SCRIPT)], capture_output=True, text=True, env=env)
    assert res.returncode == 0 and res.stderr == "" and res.stdout == ""


def test_installer_names_every_missing_library_when_it_cannot_install(tmp_path):
    # A machine whose linker cache lists no EGL/GL library, as a non-root user.
    _fake_bin(tmp_path, "ldconfig", "exit 0")
    _fake_bin(tmp_path, "id", "echo 1000")
    env = dict(os.environ, PATH=f"{tmp_path}:{os.environ['PATH']}")
    res = subprocess.run(["bash", str(SCRIPT)], capture_output=True, text=True, env=env)
    assert res.returncode == 0
    line = res.stderr.strip()
    assert len(line.splitlines()) == 1 and "apt-get install" in line
    for pkg in ("libegl1", "libegl-mesa0", "libgl1", "libopengl0"):
        assert pkg in line.split("apt-get install")[1].rstrip(")").split()


def test_ci_runs_the_readme_test_command():
    ci = (ROOT / ".ci" / "run").read_text()
    readme = (ROOT / "README.md").read_text()
    assert "make test" in [line.strip() for line in ci.splitlines()]
    assert "make demo" in readme and "make test" in readme


def test_every_cli_command_is_in_the_readme_and_help(capsys):
    import pytest

    from twolink.cli import COMMANDS, main
    readme = (ROOT / "README.md").read_text()
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    for name in COMMANDS:
        assert f"`twolink {name}" in readme, name
        assert name in out, name


# --------------------------------------------------------------------------- the venv
_FAKE_PYTHON = """#!/bin/sh
# A Python that reports version {version}; `-m venv DIR` makes DIR/bin/python a copy
# of itself; `-m pip ...` is logged.
log={log}
case "$1" in
  -c) case "$2" in *ensurepip*) exit 0;; esac; echo {version};;
  -m) if [ "$2" = venv ]; then mkdir -p "$3/bin"; cp "$0" "$3/bin/python";
      else shift; echo "$*" >> "$log"; fi;;
  -) cat > /dev/null;;
esac
"""


def _fake_python(tmp_path, name, version):
    path = tmp_path / name
    path.write_text(_FAKE_PYTHON.format(version=version, log=tmp_path / "pip.log"))
    path.chmod(0o755)
    return path


def _make_venv(tmp_path, python, *extras):
    return subprocess.run(["bash", str(ROOT / "scripts" / "venv.sh"), str(python),
                           str(tmp_path / "venv"), *extras], capture_output=True, text=True)


def _pip_log(tmp_path):
    log = tmp_path / "pip.log"
    return log.read_text().splitlines() if log.exists() else []


def test_a_venv_of_another_python_is_rebuilt(tmp_path):
    venv = tmp_path / "venv"
    _fake_python(tmp_path, "py312", "3.12.1")
    (venv / "bin").mkdir(parents=True)
    (venv / "bin" / "python").write_bytes((tmp_path / "py312").read_bytes())
    (venv / "bin" / "python").chmod(0o755)
    (venv / "left-over").write_text("")
    res = _make_venv(tmp_path, _fake_python(tmp_path, "py311", "3.11.9"))
    assert res.returncode == 0, res.stderr
    assert "is Python 3.12.1" in res.stderr and "3.11.9" in res.stderr
    assert not (venv / "left-over").exists()
    assert _pip_log(tmp_path) == ["pip install -q --upgrade pip", "pip install -q -e ."]


def test_a_venv_of_the_same_python_is_kept_and_extras_are_asked_for(tmp_path):
    python = _fake_python(tmp_path, "py311", "3.11.9")
    assert _make_venv(tmp_path, python).returncode == 0
    (tmp_path / "venv" / "left-over").write_text("")
    res = _make_venv(tmp_path, python, "test")
    assert res.returncode == 0 and res.stderr == ""
    assert (tmp_path / "venv" / "left-over").exists()
    assert _pip_log(tmp_path)[-1] == "pip install -q -e .[test]"


def test_a_broken_interpreter_is_one_line(tmp_path):
    res = _make_venv(tmp_path, tmp_path / "no-such-python")
    assert res.returncode == 2
    assert res.stderr.strip().splitlines() == [
        f"twolink: {tmp_path / 'no-such-python'} is not a working Python interpreter"]


def _make_n(tmp_path, target, python):
    res = subprocess.run(["make", "-n", "-C", str(ROOT), target, f"PYTHON={python}",
                          f"VENV={tmp_path / 'venv'}"], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    return [line for line in res.stdout.splitlines() if "venv.sh" in line]


def test_make_installs_what_each_target_needs_and_notices_a_new_python(tmp_path):
    py311 = _fake_python(tmp_path, "py311", "3.11.9")
    assert _make_n(tmp_path, "demo", py311) == [f"bash scripts/venv.sh {py311} {tmp_path / 'venv'}"]
    for target in ("test", "bench", "bench-quick"):
        assert _make_n(tmp_path, target, py311) == [
            f"bash scripts/venv.sh {py311} {tmp_path / 'venv'} test"]
    (tmp_path / "venv").mkdir()
    (tmp_path / "venv" / ".installed-3.11.9").write_text("")   # made after pyproject.toml
    assert _make_n(tmp_path, "demo", py311) == []
    assert _make_n(tmp_path, "demo", _fake_python(tmp_path, "py312", "3.12.1")) != []


# --------------------------------------------------------------------------- versions
def test_python_versions_of_pyproject_ci_and_readme_agree():
    import tomllib
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert project["requires-python"] == ">=3.11,<3.14"
    ci = (ROOT / ".ci" / "run").read_text()
    assert "scripts/ci-wheel-smoke.sh" in ci
    proved = {v for v in ("3.11", "3.12", "3.13") if f"find-python.sh {v}" in ci} | {"3.11"}
    assert proved == {"3.11", "3.12", "3.13"}
    readme = (ROOT / "README.md").read_text()
    setup = readme.split("## Set-up: the two commands")[1].split("\n## ")[0]
    for version in proved:
        assert version in setup, version


def test_the_313_dependencies_are_dm_controls_less_labmaze():
    import importlib.metadata
    import tomllib

    from packaging.requirements import Requirement
    deps = [Requirement(d) for d in tomllib.loads(
        (ROOT / "pyproject.toml").read_text())["project"]["dependencies"]]
    py313 = {"python_version": "3.13"}
    ours = {d.name.lower(): d.specifier for d in deps if d.marker and d.marker.evaluate(py313)}
    assert "dm-control" not in {d.name for d in deps if not d.marker or d.marker.evaluate(py313)}
    theirs = {r.name.lower(): r.specifier for r in map(
        Requirement, importlib.metadata.requires("dm-control")) if not r.marker}
    plain = {d.name.lower() for d in deps if not d.marker}
    assert ours == {k: v for k, v in theirs.items()
                    if k not in plain | {"labmaze", "setuptools"}}


def test_an_unknown_option_is_named_by_its_subcommand(capsys):
    import pytest

    from twolink.cli import main
    with pytest.raises(SystemExit) as exc:
        main(["mjcf", "--nosuch"])
    assert exc.value.code == 2
    assert capsys.readouterr().err == ("twolink mjcf: error: unknown option --nosuch "
                                       "(see twolink mjcf --help)\n")


def test_licence_and_citation_agree_with_the_package_metadata():
    import tomllib

    import yaml

    from twolink.artifacts import VERSION
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    licence = (ROOT / "LICENSE").read_text()
    assert project["license"] == "MIT" and licence.startswith("MIT License")
    assert project["license-files"] == ["LICENSE"]
    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    assert cff["cff-version"] == "1.2.0" and cff["version"] == VERSION
    assert cff["license"] == project["license"]
    paper = cff["references"][0]
    assert paper["year"] == 2006 and (paper["start"], paper["end"]) == (1347, 1352)
    # The README's BibTeX cites the same pages.
    assert "pages     = {1347--1352}" in (ROOT / "README.md").read_text()
