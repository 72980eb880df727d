"""Importing what a user names: a module or a ``path/to/file.py`` (:func:`import_module`)
and the object ``module:callable`` names (:func:`import_entry_point`). The user's code
runs here: what it prints goes to stderr (stdout is the commands' output), and an
exception or ``sys.exit`` while it imports is one ControllerError line."""
from __future__ import annotations

import contextlib
import hashlib
import importlib
import importlib.util
import sys
from pathlib import Path

from twolink.sim.controller import ControllerError


def is_file_spec(where: str) -> bool:
    """Whether the part of a spec before the colon names a file (not a module)."""
    return where.endswith(".py") or "/" in where or where.startswith(".")


def import_module(where: str):
    if is_file_spec(where):
        path = Path(where)
        if not path.is_file():
            raise ControllerError(f"controller file {where} does not exist"
                                  if not path.exists() else f"controller file {where} is not "
                                  f"a file")
        digest = hashlib.sha256(str(path.resolve()).encode()).hexdigest()[:12]
        module_name = f"twolink_user_controller_{digest}"
        spec = importlib.util.spec_from_file_location(module_name, path)
        if spec is None or spec.loader is None:
            raise ControllerError(f"cannot import controller file {where}")
        module = importlib.util.module_from_spec(spec)
        sys.modules[module_name] = module
        try:
            with contextlib.redirect_stdout(sys.stderr):    # its prints: not our output
                spec.loader.exec_module(module)
        except (Exception, SystemExit) as exc:
            del sys.modules[module_name]
            raise ControllerError(f"cannot import controller file {where}: "
                                  f"{type(exc).__name__}: {exc}") from None
        return module
    try:
        with contextlib.redirect_stdout(sys.stderr):
            return importlib.import_module(where)
    except (Exception, SystemExit) as exc:
        raise ControllerError(f"cannot import controller module {where!r}: "
                              f"{type(exc).__name__}: {exc}") from None


def import_entry_point(spec: str, what: str = "entry point"):
    """The object ``module:callable`` or ``path/file.py:callable`` names (imported, not
    called); a one-line ControllerError, its spec called ``what``, when it does not import
    or is not callable."""
    where, _, attr = spec.rpartition(":")
    if not where or not attr:
        raise ControllerError(f"{what} {spec!r}: give module:callable or "
                              f"path/to/file.py:callable")
    obj = import_module(where)
    for part in attr.split("."):
        try:
            obj = getattr(obj, part)
        except AttributeError:
            raise ControllerError(f"{what} {spec!r}: {where} has no attribute "
                                  f"{attr!r}") from None
    if not callable(obj):
        raise ControllerError(f"{what} {spec!r} is not callable ({type(obj).__name__})")
    return obj
