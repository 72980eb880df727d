#!/usr/bin/env bash
# Usage: scripts/find-python.sh 3.12 -- prints a Python 3.12 interpreter: pythonX.Y on
# PATH when it runs, else one installed by pyenv (its shims only run the active versions).
set -euo pipefail
v=$1
if command -v "python$v" >/dev/null 2>&1 && "python$v" -c '' 2>/dev/null; then
  command -v "python$v"
  exit 0
fi
root=$(pyenv root 2>/dev/null || echo "${PYENV_ROOT:-$HOME/.pyenv}")
for p in $(ls -d "$root"/versions/"$v".*/bin/"python$v" 2>/dev/null | sort -V -r); do
  "$p" -c '' 2>/dev/null && { echo "$p"; exit 0; }
done
echo "twolink: no Python $v found (on PATH or under $root/versions)" >&2
exit 1
