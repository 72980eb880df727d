#!/usr/bin/env bash
# Usage: scripts/venv.sh PYTHON VENV [EXTRAS]
# Makes VENV a virtual environment of the interpreter PYTHON with twolink installed
# editable ('.' or '.[EXTRAS]'). A VENV of another Python version is rebuilt, so
# `make demo` after `make demo PYTHON=python3.12` goes back to python3.
set -euo pipefail
python=$1 venv=$2 extras=${3:-}
cd "$(dirname "$0")/.."
version() { "$1" -c 'import platform; print(platform.python_version())' 2>/dev/null; }

want=$(version "$python") || { echo "twolink: $python is not a working Python interpreter" >&2; exit 2; }
have=$(version "$venv/bin/python" || true)
if [ "$have" != "$want" ]; then
  [ -z "$have" ] || echo "$venv is Python $have, $python is $want: rebuilding it" >&2
  rm -rf "$venv"
  if ! "$python" -c 'import ensurepip' 2>/dev/null; then
    # Debian ships venv's ensurepip separately (python3.11-venv).
    pkg="python$("$python" -c 'import sys; print("%d.%d" % sys.version_info[:2])')-venv"
    if [ "$(id -u)" -eq 0 ] && command -v apt-get >/dev/null 2>&1; then
      echo "Installing $pkg" >&2
      DEBIAN_FRONTEND=noninteractive apt-get update -qq >/dev/null
      DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "$pkg" >/dev/null
    else
      echo "twolink: $python cannot create a virtual environment (run as root: apt-get install $pkg)" >&2
      exit 2
    fi
  fi
  "$python" -m venv "$venv"
  "$venv/bin/python" -m pip install -q --upgrade pip
fi
"$venv/bin/python" -m pip install -q -e ".${extras:+[$extras]}"
# dm-control's labmaze requirement has no wheel for Python >= 3.13 (pyproject.toml says
# why that is harmless here): dm-control itself comes without its dependencies there.
"$venv/bin/python" - <<'EOF'
import subprocess, sys, tomllib
if sys.version_info >= (3, 13):
    with open("pyproject.toml", "rb") as f:
        deps = tomllib.load(f)["project"]["dependencies"]
    pin = next(d.split(";")[0].strip() for d in deps if d.startswith("dm-control"))
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", pin], check=True)
EOF
