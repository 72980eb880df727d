"""Parameter files: an arm's parameters (e.g. identified ones) as a checked JSON file.

A parameter file holds a complete :class:`~twolink.arm.parameters.ArmParameters`, the
quantities the horizontal arm's dynamics (6)-(10) depend on (P1, P2, P3 of (10), b1, b2),
the provenance the writer supplies (for ``twolink identify``: the fitted values with
their standard errors, what the data cannot determine, data length, noise, seed,
excitation) and a sha256 of the content. It is written atomically.

:func:`load` refuses, with one line naming the file, anything that is not such a file:
missing, too large, not JSON, another format or version, edited or corrupted (the sha256),
not a regular file (a FIFO, a device), non-numeric, NaN, infinite (an integer beyond the
floats), non-positive or absurd parameters (more than :data:`PLAUSIBLE_FACTOR` times
Table I's value, or less than its 1/:data:`PLAUSIBLE_FACTOR`: a torque limit of 1e300 Nm
is a typo, not an arm; :func:`check_plausible`), an arm no plant can simulate (an all but massless link,
or a link so light for its damping that RK4 diverges:
:func:`twolink.arm.integrate.check_sampling`), derived values or recorded fitted values that
the parameters do not reproduce. The hash detects edits and corruption; it is not a
signature.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import stat
from pathlib import Path

from twolink.arm.integrate import check_sampling
from twolink.arm.parameters import TABLE_I, ArmParameters
from twolink.artifacts import VERSION as __version__
from twolink.artifacts import write_text
from twolink.validate import is_real

FORMAT = "twolink-parameters"
FORMAT_VERSION = 1
#: What the dynamics of the horizontal arm (6)-(10) depend on, besides the limits.
DYNAMIC = ("P1", "P2", "P3", "b1", "b2")
#: The largest parameter file :func:`load` reads (bytes).
MAX_BYTES = 1 << 20
#: How far a parameter of a file may lie from Table I's value: at most this many times it,
#: at least its 1/this (g: any value of magnitude at most this many times 9.81).
PLAUSIBLE_FACTOR = 1e4
#: Relative tolerance for recorded values the parameters must reproduce (round-off only).
_RTOL = 1e-9


class ParameterFileError(ValueError):
    """A file that is not a valid twolink parameter file."""


@dataclasses.dataclass(frozen=True)
class ParameterFile:
    """The content of a parameter file: the parameters, the writer's provenance and the
    file's content sha256."""

    params: ArmParameters
    provenance: dict
    sha256: str = ""


def dynamic_values(p: ArmParameters) -> dict:
    """P1, P2, P3 of (10) and b1, b2: all the horizontal arm's dynamics (6)-(8) depend on
    (with the torque and speed limits)."""
    return {name: float(getattr(p, name)) for name in DYNAMIC}


def _content_hash(record: dict) -> str:
    body = {k: v for k, v in record.items() if k != "sha256"}
    text = json.dumps(body, sort_keys=True, allow_nan=False, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def _record(params: ArmParameters, provenance: dict) -> dict:
    if not isinstance(params, ArmParameters):
        raise ValueError(f"params must be ArmParameters, got {type(params).__name__}")
    if not isinstance(provenance, dict):
        raise ValueError(f"provenance must be a dict, got {type(provenance).__name__}")
    record = {"format": FORMAT, "format_version": FORMAT_VERSION,
              "twolink_version": __version__, "parameters": params.as_dict(),
              "dynamic": dynamic_values(params), "provenance": provenance}
    try:
        record["sha256"] = _content_hash(record)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"provenance must hold finite JSON values only ({exc})") from None
    return record


def save(path: os.PathLike, params: ArmParameters, *, provenance: dict) -> Path:
    """Write ``params`` and ``provenance`` (a JSON-ready dict) atomically to ``path``.

    A provenance entry ``"identified"`` mapping names of :data:`DYNAMIC` to
    ``{"value": v, "std_error": s}`` is checked against the parameters, here and on load.
    """
    record = _record(params, provenance)
    check_sampling(params)
    _check_identified(record, Path(path))
    text = json.dumps(record, indent=2, sort_keys=True, allow_nan=False) + "\n"
    return write_text(path, text)


def _reject_constant(name: str):
    raise ValueError(f"{name} is not a number JSON allows")


def read(path: os.PathLike) -> ParameterFile:
    """The parameters and provenance of a parameter file, every check of :func:`load` done."""
    path = Path(path)

    def bad(why: str) -> ParameterFileError:
        return ParameterFileError(f"{path}: {why}")

    try:
        info = path.stat()
    except FileNotFoundError:
        raise bad("no such file") from None
    except OSError as exc:
        raise bad(f"cannot read it ({exc.strerror or exc})") from None
    if stat.S_ISDIR(info.st_mode):
        raise bad("is a directory, not a parameter file")
    if not stat.S_ISREG(info.st_mode):      # a FIFO would block the read, a device not end
        raise bad(f"is not a regular file (a {_kind(info.st_mode)}), not a parameter file")
    size = info.st_size
    if size > MAX_BYTES:
        raise bad(f"{size} bytes, more than a parameter file may hold ({MAX_BYTES} bytes)")
    try:
        with open(path, "rb") as fh:
            raw = fh.read(MAX_BYTES + 1)
    except OSError as exc:
        raise bad(f"cannot read it ({exc.strerror or exc})") from None
    try:
        record = json.loads(raw.decode("utf-8"), parse_constant=_reject_constant)
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise bad(f"not a parameter file (not valid JSON: {str(exc).splitlines()[0]})") from None
    if not isinstance(record, dict) or record.get("format") != FORMAT:
        found = record.get("format") if isinstance(record, dict) else None
        raise bad(f"not a parameter file (format {found!r}, expected {FORMAT!r})")
    version = record.get("format_version")
    if version != FORMAT_VERSION or isinstance(version, bool):
        raise bad(f"format version {version!r}; this twolink reads version {FORMAT_VERSION}")
    try:
        digest = _content_hash(record)
    except (TypeError, ValueError):
        raise bad("content cannot be hashed") from None
    if digest != record.get("sha256"):
        raise bad("content does not match the file's sha256 (the file was edited or is "
                  "corrupted)")
    values = record.get("parameters")
    names = [f.name for f in dataclasses.fields(ArmParameters)]
    if not isinstance(values, dict) or sorted(values) != sorted(names):
        raise bad(f"'parameters' must name exactly {', '.join(names)}")
    for name, value in values.items():
        if not is_real(value, numpy=False):
            raise bad(f"parameter {name} must be a number, got {value!r}")
        if not math.isfinite(_as_float(value)):
            raise bad(f"parameter {name} must be a finite number, got {_short(value)}")
    try:
        params = ArmParameters(**{k: float(v) for k, v in values.items()})
        check_sampling(params)
        check_plausible(params)
    except ValueError as exc:
        raise bad(str(exc)) from None
    dynamic = record.get("dynamic")
    if not isinstance(dynamic, dict) or sorted(dynamic) != sorted(DYNAMIC):
        raise bad(f"'dynamic' must name exactly {', '.join(DYNAMIC)}")
    for name, value in dynamic_values(params).items():
        if not _close(dynamic[name], value):
            raise bad(f"{name} = {_short(dynamic[name])} recorded, but the parameters give "
                      f"{value!r}")
    if not isinstance(record.get("provenance"), dict):
        raise bad("'provenance' must be an object")
    _check_identified(record, path)
    return ParameterFile(params, record["provenance"], record["sha256"])


def check_plausible(params: ArmParameters) -> ArmParameters:
    """``params`` unless a parameter lies more than :data:`PLAUSIBLE_FACTOR` times above
    Table I's value or below its 1/:data:`PLAUSIBLE_FACTOR` (for g: a magnitude above
    :data:`PLAUSIBLE_FACTOR` times 9.81); else a one-line ValueError naming it and the
    range accepted."""
    for field in dataclasses.fields(ArmParameters):
        value, ref = getattr(params, field.name), getattr(TABLE_I, field.name)
        low = 0.0 if field.name == "g" else ref / PLAUSIBLE_FACTOR
        high = abs(ref) * PLAUSIBLE_FACTOR
        if not low <= abs(value) <= high:
            raise ValueError(f"parameter {field.name} = {value:g} is implausible: accepted "
                             + (f"|{field.name}| <= {high:g}" if field.name == "g" else
                                f"{low:g} to {high:g} (Table I's {ref:g} times "
                                f"1/{PLAUSIBLE_FACTOR:g} to {PLAUSIBLE_FACTOR:g})"))
    return params


def load(path: os.PathLike) -> ArmParameters:
    """The :class:`ArmParameters` of a parameter file; a :class:`ParameterFileError`
    (a ValueError, one line naming the file) for anything else."""
    return read(path).params


def _as_float(value) -> float:
    """A JSON number as a float; infinity for an integer beyond the floats."""
    try:
        return float(value)
    except OverflowError:
        return math.inf


def _short(value) -> str:
    """The repr of a recorded value, an integer of hundreds of digits by its length."""
    text = repr(value)
    return text if len(text) <= 40 else f"an integer of {len(text.lstrip('-'))} digits"


def _kind(mode: int) -> str:
    for test, name in ((stat.S_ISFIFO, "FIFO"), (stat.S_ISCHR, "character device"),
                       (stat.S_ISBLK, "block device"), (stat.S_ISSOCK, "socket")):
        if test(mode):
            return name
    return "special file"


def _close(recorded, value: float) -> bool:
    return (is_real(recorded, numpy=False) and math.isfinite(_as_float(recorded))
            and abs(_as_float(recorded) - value) <= _RTOL * abs(value))


def _check_identified(record: dict, path: Path) -> None:
    """Fitted values recorded in the provenance must be those the parameters realise."""
    fitted = record["provenance"].get("identified")
    if fitted is None:
        return
    if not isinstance(fitted, dict) or not set(fitted) <= set(DYNAMIC):
        raise ParameterFileError(f"{path}: provenance 'identified' must map some of "
                                 f"{', '.join(DYNAMIC)} to their fitted value and std_error")
    for name, entry in fitted.items():
        if not isinstance(entry, dict) or not _close(entry.get("value"), record["dynamic"][name]):
            raise ParameterFileError(
                f"{path}: identified {name} does not match the parameters' {name} = "
                f"{record['dynamic'][name]!r}")
        err = entry.get("std_error")
        if not is_real(err, numpy=False) or not math.isfinite(_as_float(err)) or err < 0:
            raise ParameterFileError(f"{path}: identified {name}: std_error must be a finite "
                                     f"non-negative number, got {_short(err)}")
