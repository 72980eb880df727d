"""Where the package's files live, found the way an installed wheel finds them.

* Shipped data (the committed policies under ``policies/`` and the MJCF model under
  ``models/``) are installed as the packages ``twolink._policies`` and ``twolink._models``
  (``pyproject.toml`` maps the top-level folders onto them), and found through
  :mod:`importlib.resources`, in an editable checkout and in a wheel alike.
* Outputs (figures, videos, reports) go under :func:`output_dir`: ``$TWOLINK_OUTPUT`` if
  set, else ``twolink-results/`` in the current working directory, a folder git ignores
  in a checkout, so that no documented command rewrites a tracked file. The committed
  results under the checkout's ``renders/`` are regenerated on purpose only
  (``make results``: the studies with ``TWOLINK_OUTPUT=renders``).
"""
from __future__ import annotations

import importlib.resources
import os
from pathlib import Path

#: Environment variable naming the default output folder.
OUTPUT_ENV = "TWOLINK_OUTPUT"
#: Default output folder, relative to the working directory (ignored by git).
DEFAULT_OUTPUT = "twolink-results"
MODEL_FILE = "twolink.xml"


def _package_dir(package: str) -> Path:
    return Path(str(importlib.resources.files(package)))


def shipped_policy_dir() -> Path:
    """The folder holding the shipped policy files (``policies/`` of the checkout)."""
    return _package_dir("twolink._policies")


def model_file() -> Path:
    """The committed MJCF model (``models/twolink.xml`` of the checkout)."""
    return _package_dir("twolink._models") / MODEL_FILE


def source_checkout() -> Path | None:
    """The repository root when the package runs from a source checkout, else None."""
    root = shipped_policy_dir().parent
    return root if (root / "pyproject.toml").is_file() and (root / "twolink").is_dir() else None


def output_dir(*, create: bool = True) -> Path:
    """The default output folder: ``$TWOLINK_OUTPUT`` or ``./twolink-results``; created on
    demand."""
    path = Path(os.environ.get(OUTPUT_ENV) or DEFAULT_OUTPUT)
    if create and not path.is_dir():
        path.mkdir(parents=True, exist_ok=True)
    return path


def protected_dirs() -> tuple[Path, ...]:
    """Folders no ordinary output may resolve into: the installed package itself and its
    shipped data (``policies/``, ``models/`` and ``data/`` of a source checkout); only the
    ``--ship`` options write there."""
    package = Path(__file__).resolve().parent
    return tuple(dict.fromkeys(p.resolve() for p in (package, shipped_policy_dir(),
                                                     model_file().parent,
                                                     _package_dir("twolink._data"))))


def protected_target(path: os.PathLike) -> Path | None:
    """The protected folder ``path`` resolves into (symlinks followed), else None."""
    real = Path(os.path.realpath(path))
    for folder in protected_dirs():
        if real == folder or folder in real.parents:
            return folder
    return None


#: The shipped table of the time-optimal limits (``data/`` of the checkout).
LIMITS_FILE = "limits.json"


def limits_file() -> Path:
    """The shipped limits table (``data/limits.json`` of the checkout), installed as the
    package ``twolink._data``."""
    return _package_dir("twolink._data") / LIMITS_FILE
