"""scripts/install-rl-extras.sh: torch's CPU build first (PyTorch's CPU index, else the
default index), then stable-baselines3, then skrl (the marl extra), for Python 3.11-3.13; one line and exit 2 for
another Python, a missing venv or no torch wheel, never exit 0 having installed nothing.
Checked with a fake interpreter that logs what it is asked to do and answers pip as told
(nothing is installed)."""
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "scripts" / "install-rl-extras.sh"
SKRL = "-m pip install -q skrl==2.1.1"
CPU = "--retries 1 --timeout 15 --index-url https://download.pytorch.org/whl/cpu"

# Reports Python VERSION; "import importlib.metadata" checks succeed for the packages
# whose marker file exists; pip installs are logged, fail when their argument string
# matches FAIL (a shell pattern), and on success create the package's marker.
_FAKE = """#!/bin/sh
here=$(dirname "$0")
case "$*" in
  *"sys.version_info[:2]"*) echo {version}; exit 0 ;;
  *"m.version('torch')"*) [ -e "$here/has-torch" ]; exit $? ;;
  *"m.version('stable-baselines3')"*) [ -e "$here/has-sb3" ]; exit $? ;;
  *"m.version('skrl')"*) [ -e "$here/has-skrl" ]; exit $? ;;
  *"importlib.metadata"*) [ -e "$here/has-sb3" ] && [ -e "$here/has-torch" ] && [ -e "$here/has-skrl" ]; exit $? ;;
esac
echo "$*" >> {log}
case "$*" in
  {fail}) exit 1 ;;
  *torch==*) touch "$here/has-torch" ;;
  *stable-baselines3==*) touch "$here/has-sb3" ;;
  *skrl==*) touch "$here/has-skrl" ;;
esac
"""


def _run(tmp_path, version="3.11", fail="__never__", torch=False, have=()):
    log = tmp_path / "calls.log"
    bin_dir = tmp_path / "venv" / "bin"
    bin_dir.mkdir(parents=True)
    python = bin_dir / "python"
    python.write_text(_FAKE.format(version=version, log=log, fail=fail))
    python.chmod(0o755)
    if torch:
        (bin_dir / "has-torch").touch()
    for name in have:
        (bin_dir / f"has-{name}").touch()
    out = subprocess.run(["bash", str(SCRIPT), str(tmp_path / "venv")], capture_output=True,
                         text=True)
    calls = log.read_text().splitlines() if log.exists() else []
    return out, calls


@pytest.mark.parametrize("version", ["3.11", "3.12", "3.13"])
def test_torch_cpu_first_then_sb3_on_every_supported_python(tmp_path, version):
    out, calls = _run(tmp_path, version)
    assert out.returncode == 0, out.stderr
    assert calls == [f"-m pip install -q {CPU} torch==2.13.0",
                     "-m pip install -q stable-baselines3==2.9.2", SKRL]
    assert "torch 2.13.0 (CPU) from https://download.pytorch.org/whl/cpu" in out.stdout


def test_an_unreachable_cpu_index_falls_back_to_the_default_index(tmp_path):
    out, calls = _run(tmp_path, fail="*download.pytorch.org*")
    assert out.returncode == 0, out.stderr
    assert calls == [f"-m pip install -q {CPU} torch==2.13.0",
                     "-m pip install -q torch==2.13.0",
                     "-m pip install -q stable-baselines3==2.9.2", SKRL]
    assert "from the default index" in out.stdout


def test_no_torch_wheel_is_one_line_and_exit_2(tmp_path):
    out, calls = _run(tmp_path, fail="*torch==*")
    assert out.returncode == 2
    assert out.stderr.strip().splitlines() == [
        "twolink: no torch 2.13.0 wheel installs for Python 3.11 on this machine (tried "
        "https://download.pytorch.org/whl/cpu and the default index); install torch "
        "yourself, then rerun"]
    assert not any("stable-baselines3" in c for c in calls)


def test_a_preinstalled_torch_is_kept(tmp_path):
    out, calls = _run(tmp_path, "3.12", torch=True)
    assert out.returncode == 0, out.stderr
    assert calls == ["-m pip install -q stable-baselines3==2.9.2", SKRL]


def test_a_failed_sb3_install_is_exit_2(tmp_path):
    out, _ = _run(tmp_path, fail="*stable-baselines3==*")
    assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1
    assert "stable-baselines3 2.9.2 did not install" in out.stderr


@pytest.mark.parametrize("version", ["3.10", "3.14"])
def test_other_pythons_are_one_line_and_exit_2(tmp_path, version):
    out, calls = _run(tmp_path, version)
    assert out.returncode == 2 and calls == []
    assert out.stderr.strip() == (f"twolink: the rl extras need Python 3.11-3.13; "
                                  f"{tmp_path / 'venv'} is Python {version}")


def test_the_pins_are_the_rl_extra():
    import tomllib

    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"][
        "optional-dependencies"]
    assert extras["rl"] == ["stable-baselines3==2.9.2"]
    assert extras["marl"] == ["skrl==2.1.1"]
    text = SCRIPT.read_text()
    assert "SB3=2.9.2" in text and "TORCH=2.13.0" in text and "SKRL=2.1.1" in text
    from twolink.training.marl import SKRL_VERSION

    assert SKRL_VERSION == "2.1.1"
    assert "torch==2.13.0" in (ROOT / "pyproject.toml").read_text()     # the comment
    assert "bash scripts/install-rl-extras.sh .venv" in (ROOT / ".ci" / "run").read_text()


def test_a_missing_venv_is_one_line(tmp_path):
    out = subprocess.run(["bash", str(SCRIPT), str(tmp_path / "nope")], capture_output=True,
                         text=True)
    assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1


def test_skrl_comes_last_and_its_failure_is_one_line(tmp_path):
    out, calls = _run(tmp_path, fail="*skrl==*")
    assert out.returncode == 2, out.stdout
    assert out.stderr.strip().splitlines() == [
        f"twolink: skrl 2.1.1 did not install into {tmp_path / 'venv'}"]
    assert calls[-2:] == ["-m pip install -q stable-baselines3==2.9.2", SKRL]


def test_a_venv_with_everything_installs_nothing(tmp_path):
    out, calls = _run(tmp_path, torch=True, have=("sb3", "skrl"))
    assert out.returncode == 0 and calls == []
    assert "skrl 2.1.1 are already in" in out.stdout


def test_a_venv_without_skrl_gets_skrl(tmp_path):
    out, calls = _run(tmp_path, torch=True, have=("sb3",))
    assert out.returncode == 0, out.stderr
    assert calls[-1] == SKRL and "skrl 2.1.1 installed" in out.stdout
