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
