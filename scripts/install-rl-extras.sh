#!/usr/bin/env bash
# Usage: scripts/install-rl-extras.sh VENV
# Installs the 'rl' and 'marl' extras of pyproject.toml (Stable-Baselines3, skrl and the
# torch they need)
# into the virtual environment VENV (Python 3.11, 3.12 or 3.13):
#   1. torch==$TORCH's CPU build, from PyTorch's documented CPU index
#      (pip install --index-url https://download.pytorch.org/whl/cpu), so that pip does
#      not pull a multi-GB CUDA build as a dependency of stable-baselines3; where that
#      index cannot be reached, plain torch==$TORCH from the default index (PyPI, or the
#      index pip is configured with);
#   2. stable-baselines3==$SB3 (torch is then already there);
#   3. skrl==$SKRL (IPPO/MAPPO for `twolink train --algo ippo|mappo`).
# A torch that is already installed (any version, e.g. a GPU machine's) is kept.
# Exits 2 with one line when VENV is no interpreter, its Python is not 3.11-3.13, or no
# torch wheel installs; never 0 having installed nothing.
set -euo pipefail
TORCH=2.13.0
SB3=2.9.2
SKRL=2.1.1
CPU_INDEX=https://download.pytorch.org/whl/cpu
venv=${1:?usage: scripts/install-rl-extras.sh VENV}
py="$venv/bin/python"
fail() { echo "twolink: $*" >&2; exit 2; }
[ -x "$py" ] || fail "$py is not a Python interpreter (make the venv first)"
ver=$("$py" -c 'import sys; print("%d.%d" % sys.version_info[:2])')
case "$ver" in
  3.11|3.12|3.13) ;;
  *) fail "the rl extras need Python 3.11-3.13; $venv is Python $ver" ;;
esac
have() { "$py" -c "import importlib.metadata as m; m.version('$1')" >/dev/null 2>&1; }
if have torch && "$py" -c 'import importlib.metadata as m, sys; sys.exit(m.version("stable-baselines3") != sys.argv[1] or m.version("skrl") != sys.argv[2])' "$SB3" "$SKRL" 2>/dev/null; then
  echo "twolink: torch, stable-baselines3 $SB3 and skrl $SKRL are already in $venv"
  exit 0
fi
if ! have torch; then
  if "$py" -m pip install -q --retries 1 --timeout 15 --index-url "$CPU_INDEX" "torch==$TORCH"; then
    echo "twolink: torch $TORCH (CPU) from $CPU_INDEX"
  elif "$py" -m pip install -q "torch==$TORCH"; then
    echo "twolink: torch $TORCH from the default index ($CPU_INDEX could not serve it)"
  else
    fail "no torch $TORCH wheel installs for Python $ver on this machine (tried $CPU_INDEX and the default index); install torch yourself, then rerun"
  fi
fi
"$py" -m pip install -q "stable-baselines3==$SB3" || fail "stable-baselines3 $SB3 did not install into $venv"
have stable-baselines3 || fail "stable-baselines3 is not in $venv after installing it"
echo "twolink: stable-baselines3 $SB3 installed into $venv"
"$py" -m pip install -q "skrl==$SKRL" || fail "skrl $SKRL did not install into $venv"
have skrl || fail "skrl is not in $venv after installing it"
echo "twolink: skrl $SKRL installed into $venv"
