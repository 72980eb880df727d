"""Writing artifacts atomically, with their provenance.

Every file the package writes (policies, trajectories, figures, reports, videos) goes
through :func:`atomic_path`: the content is written to a temporary file beside the
target and renamed over it only when complete, so an error, Ctrl-C or SIGTERM never
leaves a half-written file behind. A command that writes a set of files (a report with
its JSON and figures) writes them through :func:`staged_set`: all of them or none.
Commands check all their outputs up front with :func:`check_outputs`, before any work.
"""
from __future__ import annotations

import contextlib
import json
import os
import platform
import shutil
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


def signal_count() -> int:
    """How many signals :func:`signal_received` has recorded so far: a count taken before
    a foreign call and compared after it tells whether a signal arrived during the call,
    also where the call swallowed the exception the signal raised."""
    return len(_received)


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


#: Prefix of the staging folders of :func:`staged_set` (``.gitignore`` names it too).
STAGING_PREFIX = ".staging-"


@contextlib.contextmanager
def _signals_deferred():
    """Within the block (main thread only), SIGINT and SIGTERM are held back: they are
    recorded and delivered again, to the handlers in force before, when the block ends."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held: list = []
    previous = {s: signal.signal(s, lambda signum, frame: held.append(signum))
                for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
        for s in dict.fromkeys(held):
            signal.raise_signal(s)


def _move_all(pairs) -> None:
    """Rename each ``(source, target)`` of ``pairs`` onto its target (same filesystem).
    On any error the targets moved in are removed and the files they replaced put
    back (best effort), and the error is raised; the replaced files are deleted once
    every rename succeeded."""
    done: list = []              # (source, target, the replaced file set aside or None)
    try:
        for source, target in pairs:
            backup = None
            if os.path.lexists(target):
                fd, backup = tempfile.mkstemp(prefix=f".{Path(target).name}.old-",
                                              dir=Path(target).parent)
                os.close(fd)
                os.replace(target, backup)
            done.append((source, target, backup))
            os.replace(source, target)
    except BaseException:
        for source, target, backup in reversed(done):
            with contextlib.suppress(OSError):
                if not os.path.lexists(source):          # the new file went in: out again
                    os.unlink(target)
                if backup is not None:
                    os.replace(backup, target)
        raise
    for _, _, backup in done:
        if backup is not None:
            with contextlib.suppress(OSError):
                os.unlink(backup)


@contextlib.contextmanager
def staged_set(dest: os.PathLike):
    """Yield an empty staging folder for a set of files bound for the folder ``dest``:
    the caller writes every file of the set into it; when the block ends without an
    error the files are moved into ``dest`` together (all or none), else none is.

    The staging folder is made on the same filesystem as ``dest`` (inside it when it
    exists, else beside it), so that the moves are renames: a new ``dest`` is the
    staging folder renamed, an existing one gets each file renamed over its namesake,
    with SIGINT and SIGTERM held back until the renames are done and the replaced files
    put back if one fails. Files of ``dest`` that the set does not name are kept. On an
    error, Ctrl-C or (in the main thread) SIGTERM inside the block the staging folder
    is removed and ``dest`` is left as it was; the exception propagates."""
    dest = Path(dest)
    if dest.exists() and not dest.is_dir():
        raise OSError(f"cannot write into {dest}: it is a file; give a folder")
    parent = dest if dest.is_dir() else (dest.parent if str(dest.parent) else Path("."))
    if not parent.is_dir():
        raise OSError(f"cannot write {dest}: directory {parent} does not exist")
    staging = None
    with sigterm_raises():
        try:
            staging = Path(tempfile.mkdtemp(prefix=STAGING_PREFIX, dir=parent))
            os.chmod(staging, 0o777 & ~_umask())
            yield staging
            with _signals_deferred():
                if dest.is_dir():
                    _move_all([(staging / name, dest / name)
                               for name in sorted(os.listdir(staging))])
                else:
                    os.rename(staging, dest)
                    staging = None
        finally:
            if staging is not None:
                shutil.rmtree(staging, ignore_errors=True)


@contextlib.contextmanager
def staged_files(paths):
    """Yield one temporary path beside each of ``paths`` (files anywhere, same suffix):
    the caller writes the set into them; when the block ends without an error they are
    renamed onto ``paths`` together (SIGINT and SIGTERM held back meanwhile, the replaced
    files put back if a rename fails), else every temporary file is removed and
    ``paths`` are left as they were: all of the set or none of it."""
    paths = [check_writable(p) for p in paths]
    temps: list = []
    with sigterm_raises():
        try:
            for path in paths:
                fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix,
                                           dir=path.parent)
                os.close(fd)
                temps.append(Path(tmp))
            yield list(temps)
            for tmp in temps:
                os.chmod(tmp, 0o666 & ~_umask())
            with _signals_deferred():
                _move_all(list(zip(temps, paths)))
        finally:
            for tmp in temps:
                with contextlib.suppress(OSError):
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
    except (ValueError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(data, dict) or (data.get("schema"), data.get("version")) != (schema, version):
        raise ValueError(f"{path} is not a {schema} version {version} file; "
                         "give another --json PATH")
    return data


@contextlib.contextmanager
def folder_lock(path: os.PathLike):
    """Hold an exclusive lock on the folder of ``path`` (``flock`` of the folder itself, no
    lock file), so processes that read, change and rewrite a file there take turns."""
    import fcntl

    fd = os.open(Path(path).resolve().parent, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)                        # closing the descriptor releases the lock


def merge_run(path: os.PathLike, schema: str, version: int, record: dict, **fields) -> dict:
    """Add ``record`` (replacing one of the same ``id``) to the study file at ``path``
    (:func:`read_runs`), with the top-level ``fields``, reading the file afresh under
    :func:`folder_lock`: two processes writing the same study keep each other's runs.
    The merged data."""
    with folder_lock(path):
        data = read_runs(path, schema, version)
        runs = [r for r in data.get("runs", []) if r.get("id") != record["id"]] + [record]
        data.update(fields, schema=schema, version=version,
                    runs=sorted(runs, key=lambda r: r["id"]))
        write_json(path, data)
    return data


def provenance() -> dict:
    """Package version and machine description stamped on reports."""
    from importlib.metadata import version

    import numpy

    return {"twolink_version": VERSION, "mujoco_version": version("mujoco"),
            "numpy_version": numpy.__version__, "python": platform.python_version(),
            "machine": platform.machine(), "processor": platform.processor() or None,
            "cpu_count": os.cpu_count(), "system": platform.platform()}
