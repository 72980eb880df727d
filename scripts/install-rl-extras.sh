#!/usr/bin/env bash
# Usage: scripts/install-rl-extras.sh VENV
# Installs the 'rl' extras of pyproject.toml (Stable-Baselines3 and the torch it needs)
# into the Python 3.11 virtual environment VENV: torch==2.13.0 first, so that pip takes
# the CPU wheel this machine serves for Python 3.11 instead of pulling a multi-GB CUDA
# build as a dependency of stable-baselines3, then stable-baselines3 itself. For any
# other Python version it installs nothing and exits 0 (the SB3 tests then skip).
set -euo pipefail
venv=${1:?usage: scripts/install-rl-extras.sh VENV}
py="$venv/bin/python"
[ -x "$py" ] || { echo "twolink: $py is not a Python interpreter (make the venv first)" >&2; exit 2; }
ver=$("$py" -c 'import sys; print("%d.%d" % sys.version_info[:2])')
if [ "$ver" != "3.11" ]; then
  echo "twolink: the rl extras are installed for Python 3.11 only; $venv is Python $ver: nothing installed"
  exit 0
fi
if "$py" -c 'import importlib.metadata as m, sys; sys.exit(not (m.version("torch") == "2.13.0" and m.version("stable-baselines3") == "2.9.2"))' 2>/dev/null; then
  echo "twolink: torch 2.13.0 and stable-baselines3 2.9.2 are already in $venv"
  exit 0
fi
"$py" -m pip install -q torch==2.13.0
"$py" -m pip install -q stable-baselines3==2.9.2
