"""The results file of robustness cells (the mismatch report's ``sweep.jsonl``): JSON
lines, appended to, held under an exclusive lock.

Line 1 is a header (``{"format": "twolink-sweep", "format_version": 1}``); every later
line is one finished cell's record (:func:`twolink.sim.cells.run_cells`). Records are only
ever appended, one task's records in one write, so the file never shrinks while a sweep
runs; a later line for the same cell supersedes an earlier one. A run that is killed
mid-write leaves at most a torn last line: it is dropped (and reported) when the file is
opened again, and its cells run again. A bad line anywhere else is an error.

Files of another kind are refused in one line: one whose header is not this format's
("not a twolink sweep results file"), or of a newer or unknown version ("unsupported
sweep results version"). A file of an older version is started over when a sweep opens
it (its records are dropped, one line says so, and every cell runs again);
:func:`load_results` refuses it in one line. Within a file of this version a record is
reused only for a cell of the same key (:attr:`twolink.sim.cells.Cell.key`); records of
other keys are kept in the file and ignored.

While a :class:`CellFile` is open it holds ``fcntl.flock`` on the file, so a second run
on the same file refuses at once instead of computing every cell twice.
"""
from __future__ import annotations

import fcntl
import json
import os
from pathlib import Path
from typing import Optional

FORMAT = "twolink-sweep"
#: 2: per-row noise generators (twolink.sim.perturbations.ObservationNoise); version 1 files
#: hold noise cells drawn otherwise, so a sweep starts them over.
#: 3: records hold per-row returns (the worst-case return of a joint size needs them);
#: older files are started over.
#: 4: a cell is a policy under a twolink.sim.challenges.Challenge, its plants and noise
#: drawn by the challenge's seeding rule; version 3 files hold cells of perturbation
#: families drawn otherwise, so a sweep starts them over.
FORMAT_VERSION = 4
_HEADER = json.dumps({"format": FORMAT, "format_version": FORMAT_VERSION}) + "\n"


class CellFileLocked(RuntimeError):
    """Another open :class:`CellFile` (in this or another process) holds the file."""


class _OlderFormat(ValueError):
    """A results file of an earlier format version: its records are not reused."""


def _lock_holder(path: Path) -> Optional[int]:
    """The pid holding a flock on ``path``, from /proc/locks (Linux); None if unknown."""
    try:
        inode = os.stat(path).st_ino
        with open("/proc/locks") as f:
            for line in f:
                fields = line.split()
                if len(fields) > 5 and fields[1] == "FLOCK" and \
                        fields[5].rsplit(":", 1)[-1] == str(inode):
                    return int(fields[4])
    except (OSError, ValueError):
        pass
    return None


def _parse(path: Path, data: bytes) -> tuple[dict, int, Optional[str]]:
    """Records by key, the length of the good prefix, and a note on a torn last line."""
    lines = data.split(b"\n")
    complete = data.endswith(b"\n")
    if complete:
        lines.pop()                                # the empty piece after the last newline
    try:
        header = json.loads(lines[0]) if lines else None
    except ValueError:
        header = None
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise ValueError(f"{path} is not a twolink sweep results file")
    version = header.get("format_version")
    if version != FORMAT_VERSION:
        if isinstance(version, int) and 0 < version < FORMAT_VERSION:
            raise _OlderFormat(f"{path}: dropped results of the older format version "
                               f"{version}; every cell runs again")
        raise ValueError(f"{path}: unsupported sweep results version {version!r}")
    if not complete and len(lines) == 1:
        raise ValueError(f"{path}: torn header line")
    records, good = {}, len(lines[0]) + 1
    for n, line in enumerate(lines[1:], start=2):
        try:
            rec = json.loads(line)
            key = rec["key"]
            if not isinstance(rec["cell"], dict) or not isinstance(key, str):
                raise TypeError
        except (ValueError, KeyError, TypeError):
            if n == len(lines):
                return records, good, (f"{path}: dropped a torn last line (line {n}, "
                                       f"{len(line)} bytes); its cell runs again")
            raise ValueError(f"{path}: line {n} is not a sweep result") from None
        if n == len(lines) and not complete:       # valid JSON but no newline: keep, finish it
            return dict(records, **{key: rec}), good + len(line), "newline"
        records[key] = rec
        good += len(line) + 1
    return records, good, None


def load_results(path: os.PathLike) -> dict:
    """Finished cells of a results file by key, without locking it ({} when it does not
    exist). A torn last line is skipped; a bad line elsewhere is a ValueError."""
    path = Path(path)
    if not path.exists():
        return {}
    records, _, _ = _parse(path, path.read_bytes())
    return records


class CellFile:
    """A results file opened for a sweep: locked, read, and appended to.

    ``with CellFile(path) as store:`` creates the file (header only) if needed, takes an
    exclusive lock (:class:`CellFileLocked` if another run holds it), drops a torn last line
    (``store.note`` says so) and exposes the stored records as ``store.records``.
    """

    def __init__(self, path: os.PathLike):
        self.path = Path(path)
        self.records: dict = {}
        self.note: Optional[str] = None
        self._fd: Optional[int] = None

    def __enter__(self) -> "CellFile":
        self.open()
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def open(self) -> None:
        if not self.path.parent.is_dir():
            raise OSError(f"cannot write {self.path}: directory {self.path.parent} "
                          "does not exist")
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_APPEND, 0o666)
        try:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                pid = _lock_holder(self.path)
                who = f"another run (pid {pid})" if pid else "another run"
                raise CellFileLocked(f"{self.path} is in use by {who}; wait for it to finish "
                                  "or choose another output folder") from None
            data = b""
            while chunk := os.read(fd, 1 << 20):
                data += chunk
            try:
                records, good, note = _parse(self.path, data) if data else ({}, 0, None)
            except _OlderFormat as exc:
                records, good, note = {}, 0, str(exc)
                os.ftruncate(fd, 0)
                data = b""
            if not data:
                os.write(fd, _HEADER.encode())
                os.fsync(fd)
            else:
                if note == "newline":              # a whole record missing its newline
                    os.write(fd, b"\n")
                    note = None
                elif note is not None:
                    os.ftruncate(fd, good)
                    os.fsync(fd)
        except BaseException:
            os.close(fd)
            raise
        self._fd, self.records, self.note = fd, records, note

    def append(self, records) -> None:
        """Add finished records (one write, then fsync) and keep them in ``records``."""
        if self._fd is None:
            raise RuntimeError(f"{self.path} is not open")
        text = "".join(json.dumps(r, sort_keys=True) + "\n" for r in records)
        os.write(self._fd, text.encode())
        os.fsync(self._fd)
        for r in records:
            self.records[r["key"]] = r

    def close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)                     # releases the lock
            self._fd = None
