#!/usr/bin/env bash
# Usage: scripts/build-docs.sh VENV
# Installs the 'docs' extra of pyproject.toml (MkDocs, Material, mkdocstrings: pinned
# there) into the virtual environment VENV, which already has twolink (make venv), and
# builds the documentation site into build/site with `mkdocs build --strict`: any
# warning, any internal link or anchor that does not resolve, any page left out of the
# nav fails it. The pages it builds are committed; tests/test_docs.py checks that the
# generated ones (python docs/generate.py) are current.
set -euo pipefail
venv=${1:?usage: scripts/build-docs.sh VENV}
cd "$(dirname "$0")/.."
py="$venv/bin/python"
[ -x "$py" ] || { echo "twolink: $py is not a Python interpreter (make the venv first)" >&2; exit 2; }
# Only the extra's own requirements: reinstalling twolink itself is not needed.
mapfile -t reqs < <("$py" - <<'PY'
import tomllib
with open("pyproject.toml", "rb") as f:
    print("\n".join(tomllib.load(f)["project"]["optional-dependencies"]["docs"]))
PY
)
"$py" -m pip install -q "${reqs[@]}"
export NO_MKDOCS_2_WARNING=1          # Material's banner about MkDocs 2.0, not a build problem
"$py" -m mkdocs build --strict --clean --site-dir build/site
