"""Writing artifacts atomically, with their provenance.

Every file the package writes (policies, trajectories, figures, reports, videos) goes
through :func:`atomic_path`: the content is written to a temporary file beside the
target and renamed over it only when complete, so an error, Ctrl-C or SIGTERM never
leaves a half-written file behind. Commands check all their outputs up front with
:func:`check_outputs`, before any work.
"""
from __future__ import annotations

import contextlib
import json
import os
import platform
import signal
import tempfile
import threading
from pathlib import Path
from typing import Mapping

from twolink.resources import protected_target

#: The package version (pyproject.toml reads it from here).
VERSION = "0.1.0"


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised like Ctrl-C so that cleanup (``finally``) runs."""


#: Signals delivered inside :func:`sigterm_raises` (their names), for :func:`signal_received`.
_received: list[str] = []


def _raise_terminated(signum, frame):
    _received.append("SIGTERM")
    raise Terminated("terminated by SIGTERM")


def _raise_interrupt(signum, frame):
    _received.append("SIGINT")
    raise KeyboardInterrupt


def signal_received() -> str | None:
    """``"SIGTERM"`` or ``"SIGINT"`` if one arrived inside the latest outermost
    :func:`sigterm_raises` block, else None.

    The exception a signal handler raises can surface as another one: raised while
    ctypes converts a foreign call's arguments (as PyOpenGL's EGL calls do during a
    render) it becomes ``ctypes.ArgumentError: argument 1: Terminated: ...``. A command
    that catches an unexpected exception asks this to report the signal instead."""
    return _received[-1] if _received else None


@contextlib.contextmanager
def sigterm_raises():
    """Within the block, SIGTERM raises :class:`Terminated` (a KeyboardInterrupt) instead
    of killing the process, so temporary files are removed as on Ctrl-C; both signals
    are recorded for :func:`signal_received`. Only the main thread can take signals;
    elsewhere, and when nested, this does nothing."""
    if threading.current_thread() is not threading.main_thread() or \
            signal.getsignal(signal.SIGTERM) is _raise_terminated:
        yield
        return
    _received.clear()
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    interrupt = signal.getsignal(signal.SIGINT) is signal.default_int_handler
    if interrupt:
        signal.signal(signal.SIGINT, _raise_interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
        if interrupt:
            signal.signal(signal.SIGINT, signal.default_int_handler)


def check_writable(path: os.PathLike) -> Path:
    """``path`` if a file can be written there (an existing, writable directory; not a
    directory itself), else a one-line OSError."""
    path = Path(path)
    parent = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise OSError(f"cannot write {path}: it is a directory")
    if not parent.is_dir():
        what = "is not a directory" if parent.exists() else "does not exist"
        raise OSError(f"cannot write {path}: directory {parent} {what}")
    if not os.access(parent, os.W_OK):
        raise OSError(f"cannot write {path}: directory {parent} is not writable")
    return path


def output_file(given, default_name: str) -> tuple[Path, list]:
    """(file, folders to make) of an ``-o`` value naming a file: ``given`` itself, or
    ``default_name`` in the current directory when None, or ``DIR/<default_name>`` when it
    is written with a trailing ``/`` (``DIR`` then among the folders :func:`check_outputs`
    may find missing and :func:`make_folders` makes, once every check has passed)."""
    if given is None:
        return Path(default_name), []
    text = os.fspath(given)
    if text.endswith(tuple(sep for sep in (os.sep, os.altsep) if sep)):
        folder = Path(text)
        return folder / default_name, [folder]
    return Path(text), []


def make_folders(folders) -> None:
    """Make each of ``folders`` (one level, after :func:`check_outputs` passed them)."""
    for folder in folders:
        Path(folder).mkdir(exist_ok=True)


def check_outputs(outputs: Mapping[str, os.PathLike | None], *, creatable=(),
                  ship: bool = False) -> dict:
    """Check every output of a command before any work: each can be written
    (:func:`check_writable`), none resolves (through symlinks too) into the installed
    package or a checkout's shipped ``policies/`` and ``models/`` unless ``ship``
    (:func:`twolink.resources.protected_target`), and no two are the same file. ``outputs`` maps a name (the
    option, e.g. ``--csv``) to a path or None (not written); returns the given paths.

    A directory in ``creatable`` (the default output folder) may be missing if it can be
    made; the caller makes it after the check, so a refused command leaves nothing.
    """
    creatable = {Path(d) for d in creatable}
    seen: dict = {}
    out = {}
    for name, path in outputs.items():
        if path is None:
            continue
        path = Path(path)
        folder = None if ship else protected_target(path)
        if folder is not None:
            raise OSError(f"cannot write {path}: it resolves into twolink's shipped files "
                          f"({folder}); write elsewhere (only --ship writes there)")
        if path.parent in creatable and not path.parent.exists():
            check_writable(path.parent)
        else:
            check_writable(path)
        key = os.path.realpath(path)
        if key in seen:
            raise ValueError(f"{seen[key]} and {name} both write {path}; give them "
                             f"different paths")
        seen[key] = name
        out[name] = path
    return out


@contextlib.contextmanager
def atomic_path(path: os.PathLike):
    """Yield a temporary path beside ``path``; rename it onto ``path`` on success.

    The temporary file is removed on any error, on Ctrl-C and (in the main thread) on
    SIGTERM.
    """
    path = check_writable(path)
    tmp = None
    with sigterm_raises():
        try:
            fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix,
                                       dir=path.parent)
            os.close(fd)
            yield Path(tmp)
            os.chmod(tmp, 0o666 & ~_umask())     # mkstemp makes 0600; give the usual mode
            os.replace(tmp, path)
        finally:
            if tmp is not None and os.path.exists(tmp):
                os.unlink(tmp)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_text(path: os.PathLike, text: str) -> Path:
    with atomic_path(path) as tmp:
        Path(tmp).write_text(text)
    return Path(path)


def write_json(path: os.PathLike, data) -> Path:
    return write_text(path, json.dumps(data, indent=2, sort_keys=True) + "\n")


def read_runs(path: os.PathLike, schema: str, version: int) -> dict:
    """The data of a study file that merges its runs (``{"schema": schema, "version":
    version, "runs": [...], ...}``): ``{"runs": []}`` when ``path`` does not exist, else
    the file's JSON; a ValueError in one line when it is not JSON or of another schema
    or version."""
    if not Path(path).is_file():
        return {"runs": []}
    try:
        data = json.loads(Path(path).read_text())
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path} is not JSON ({exc})") from None
    if not isinstance(data, dict) or (data.get("schema"), data.get("version")) != (schema, version):
        raise ValueError(f"{path} is not a {schema} version {version} file; "
                         "give another --json PATH")
    return data


def provenance() -> dict:
    """Package version and machine description stamped on reports."""
    from importlib.metadata import version

    import numpy

    return {"twolink_version": VERSION, "mujoco_version": version("mujoco"),
            "numpy_version": numpy.__version__, "python": platform.python_version(),
            "machine": platform.machine(), "processor": platform.processor() or None,
            "cpu_count": os.cpu_count(), "system": platform.platform()}
