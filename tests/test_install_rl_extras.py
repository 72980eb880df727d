"""scripts/install-rl-extras.sh: torch's CPU wheel first, then stable-baselines3, for a
Python 3.11 venv only; any other version installs nothing and exits 0. Checked with a
fake interpreter that logs what it is asked to do (nothing is installed)."""
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "scripts" / "install-rl-extras.sh"

_FAKE = """#!/bin/sh
# Reports Python {version}; logs every other call (pip installs) to {log}.
case "$*" in
  *"sys.version_info[:2]"*) echo {version}; exit 0 ;;
  *"importlib.metadata"*) exit 1 ;;
esac
echo "$*" >> {log}
"""


def _venv(tmp_path, version):
    log = tmp_path / "calls.log"
    bin_dir = tmp_path / "venv" / "bin"
    bin_dir.mkdir(parents=True)
    python = bin_dir / "python"
    python.write_text(_FAKE.format(version=version, log=log))
    python.chmod(0o755)
    return tmp_path / "venv", log


@pytest.mark.parametrize("version", ["3.12", "3.13"])
def test_other_pythons_install_nothing(tmp_path, version):
    venv, log = _venv(tmp_path, version)
    out = subprocess.run(["bash", str(SCRIPT), str(venv)], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert "nothing installed" in out.stdout and not log.exists()


def test_python_311_installs_torch_first(tmp_path):
    venv, log = _venv(tmp_path, "3.11")
    out = subprocess.run(["bash", str(SCRIPT), str(venv)], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert log.read_text().splitlines() == ["-m pip install -q torch==2.13.0",
                                            "-m pip install -q stable-baselines3==2.9.2"]


def test_the_pins_are_the_rl_extra():
    import tomllib

    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"][
        "optional-dependencies"]
    assert extras["rl"] == ["stable-baselines3==2.9.2"]
    assert "stable-baselines3==2.9.2" in SCRIPT.read_text()
    assert "bash scripts/install-rl-extras.sh .venv" in (ROOT / ".ci" / "run").read_text()


def test_a_missing_venv_is_one_line(tmp_path):
    out = subprocess.run(["bash", str(SCRIPT), str(tmp_path / "nope")], capture_output=True,
                         text=True)
    assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1
