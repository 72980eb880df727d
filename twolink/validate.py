"""Checks of single values (and of plain numeric arrays) shared by the whole package.

Each check returns the value it accepts, converted (``int``, ``float``, the string, an
array), or raises a ``ValueError`` whose one-line message names the value: ``what``
(the option's name) and the value given; :func:`seed`, :func:`numbers`, :func:`count_of`
and :func:`pixels`, the checks of API arguments, raise a ``TypeError`` for a value of
the wrong type and a ``ValueError`` for a wrong value. A bool is never a number here, although
Python counts ``True`` as the int 1.

``message``, where a check takes one, is a :meth:`str.format` template for that text in
place of the default; it may use the fields ``{what}``, ``{value}`` (``{value!r}`` for its
repr), ``{low}`` and ``{high}`` (``{high:,}``, ``{low:g}`` and other format specs apply),
and for :func:`choice` ``{choices}`` (the choices joined by ", ") and ``{quoted}`` (their
reprs joined by ", ").

This module imports only the standard library and numpy, so every layer may use it.
"""
from __future__ import annotations

import math

import numpy as np

#: The types :func:`is_whole` accepts (bool excepted).
WHOLE_TYPES = (int, np.integer)
#: The types :func:`is_real` accepts (bool excepted); ``numpy=False``: the first two only.
REAL_TYPES = (int, float, np.integer, np.floating)


def is_whole(value) -> bool:
    """True for a Python int or a numpy integer, False for anything else, bools included."""
    return isinstance(value, WHOLE_TYPES) and not isinstance(value, bool)


def is_real(value, *, numpy: bool = True) -> bool:
    """True for one real number: a Python int or float or (``numpy``) a numpy integer or
    floating scalar; False for bools, complex numbers, arrays and anything else. NaN and
    infinities count (see :func:`real` for a finite one). ``numpy=False`` still takes
    ``np.float64``, which is a Python float."""
    return (isinstance(value, REAL_TYPES if numpy else REAL_TYPES[:2])
            and not isinstance(value, bool))


def whole(value, what: str, low: int | None = None, high: int | None = None, *,
          message: str | None = None) -> int:
    """``value`` as an int if it is a whole number (:func:`is_whole`) in [``low``,
    ``high``] (either bound may be None: none), else a ValueError.

    Default messages, e.g. for ``what="seed"``: "seed must be a whole number" (no bounds),
    "... a non-negative whole number" (low 0), "... a positive whole number" (low 1),
    "... a whole number from 1 to 10" (both), then ", got <repr>".
    """
    if is_whole(value) and (low is None or value >= low) and (high is None or value <= high):
        return int(value)
    if message is None:
        message = "{what} must be " + _whole_range(low, high) + ", got {value!r}"
    raise ValueError(message.format(what=what, value=value, low=low, high=high))


def real(value, what: str, low: float | None = None, high: float | None = None, *,
         open_low: bool = False, open_high: bool = False, numpy: bool = True,
         message: str | None = None) -> float:
    """``value`` as a float if it is one finite real number (:func:`is_real`, with
    ``numpy``) within the bounds, else a ValueError. The bounds are inclusive unless
    ``open_low``/``open_high``; either may be None (none). An int too large for a float
    is not finite.

    Default messages, e.g. for ``what="gamma"``: "gamma must be a finite number" (no
    bounds), "... a number in [0, 1)" (both; brackets as the bounds), "... a finite
    non-negative number" (low 0), "... a finite positive number" (low 0, open), then
    ", got <repr>".
    """
    if is_real(value, numpy=numpy) and math.isfinite(_as_float(value)) \
            and (low is None or (value > low if open_low else value >= low)) \
            and (high is None or (value < high if open_high else value <= high)):
        return float(value)
    if message is None:
        message = "{what} must be " + _real_range(low, high, open_low, open_high) \
            + ", got {value!r}"
    raise ValueError(message.format(what=what, value=value, low=low, high=high))


def in_range(value, what: str, bounds: tuple, meaning: str) -> float:
    """``value`` as a float if it is a finite number within the inclusive ``bounds`` (low,
    high), else a ValueError "<what> must be a number from <low> to <high> (<meaning>),
    got <repr>": the check of an option whose range a module states once."""
    low, high = bounds
    return real(value, what, low, high,
                message=f"{{what}} must be a number from {low:g} to {high:g} ({meaning}), "
                        f"got {{value!r}}")


def choice(value, what: str, choices, *, message: str | None = None) -> str:
    """``value`` if it is a string among ``choices`` (any iterable of strings), else a
    ValueError; by default "<what> must be one of 'a', 'b', got <repr>"."""
    if isinstance(value, str) and value in choices:
        return value
    if message is None:
        message = "{what} must be one of {quoted}, got {value!r}"
    raise ValueError(message.format(what=what, value=value,
                                    choices=", ".join(map(str, choices)),
                                    quoted=", ".join(map(repr, choices))))


def real_array(value, what: str, *, dtype=float, finite: bool = True) -> np.ndarray:
    """``value`` as an array of ``dtype`` (None: the dtype numpy gives it) if it holds
    real numbers (integers or floats; not bools, complex numbers, strings or objects),
    else a ValueError "<what> must hold real numbers, got dtype <dtype>"; with ``finite``
    also "<what> contains NaN or infinite values" for any NaN or infinity."""
    arr = np.asarray(value)
    if arr.dtype.kind not in "iuf":
        raise ValueError(f"{what} must hold real numbers, got dtype {arr.dtype}")
    if dtype is not None:
        arr = arr.astype(dtype)
    if finite and not np.all(np.isfinite(arr)):
        raise ValueError(f"{what} contains NaN or infinite values")
    return arr


def whole_array(value, what: str, *, message: str | None = None) -> np.ndarray:
    """``value`` (a number or an array of them; integral floats and bools count) as an
    int array if it holds non-negative whole numbers only, else a ValueError; by default
    "<what> must hold non-negative whole numbers, got <value>". Something that does not
    convert to floats raises numpy's own error."""
    d = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(d)) or np.any(d < 0) or np.any(d != np.round(d)):
        if message is None:
            message = "{what} must hold non-negative whole numbers, got {value}"
        raise ValueError(message.format(what=what, value=value, low=0, high=None))
    return d.astype(int)


#: The largest seed :func:`seed` takes by default (numpy's generators take any; JSON and
#: numpy's int64 hold this one).
MAX_SEED = 2**63 - 1


def seed(value, what: str = "seed", *, high: int = MAX_SEED, none: bool = True,
         generator: bool = False):
    """``value`` as an int if it is a whole number from 0 to ``high``; None when ``none``
    allows it; a ``np.random.Generator`` as it is when ``generator`` allows it. A value
    of another type (a string, a float, a bool) raises a TypeError, a negative or too
    large one a ValueError, both naming ``what``: "seed must be an int, got 'abc'",
    "seed must be a non-negative whole number (at most 2**63 - 1), got -1"."""
    if value is None and none:
        return None
    if generator and isinstance(value, np.random.Generator):
        return value
    if not is_whole(value):
        kinds = "an int" + (" or a numpy Generator" if generator else "") \
            + (" or None" if none else "")
        raise TypeError(f"{what} must be {kinds}, got {value!r}")
    if not 0 <= value <= high:
        bound = "2**63 - 1" if high == MAX_SEED else f"{high}"
        raise ValueError(f"{what} must be a non-negative whole number (at most {bound}), "
                         f"got {value!r}")
    return int(value)


def numbers(value, what: str) -> np.ndarray:
    """``value`` as a float array if it is a number or a (nested) sequence or array of
    real numbers, else a TypeError naming ``what``: for a string, a dict, a set, None, or
    anything numpy does not read as real numbers ("x0 must be real numbers, got a
    dict: {...}"). Shapes, NaN and bounds are left to the caller."""
    kind = None
    if value is None or isinstance(value, (str, bytes, dict, set, frozenset)):
        kind = "None" if value is None else f"a {type(value).__name__}"
    else:
        try:
            arr = np.asarray(value)
        except (TypeError, ValueError):       # ragged, or not array-like at all
            arr = None
        if arr is None or arr.dtype.kind not in "iuf":
            kind = (f"a {type(value).__name__}" if arr is None or arr.dtype.kind == "O"
                    else f"values of dtype {arr.dtype}")
    if kind is not None:
        raise TypeError(f"{what} must be real numbers, got {kind}: {_short(value)}")
    return arr.astype(float)


def count_of(value, what: str, count: int) -> np.ndarray:
    """``value`` (one real number or a sequence of them) as a float array of ``count``
    values, one number repeated; a TypeError naming ``what`` when it is not numbers, a
    ValueError naming ``what`` and ``count`` for another number of values or a NaN or
    infinity ("speed_max must have 1 or 2 values (one per link), got 3")."""
    arr = numbers(value, what)
    arr = arr[None] if arr.ndim == 0 else arr
    if arr.ndim != 1 or arr.size not in (1, count):
        raise ValueError(f"{what} must have 1 or {count} values (one per link), got "
                         f"{arr.size if arr.ndim == 1 else 'shape ' + str(arr.shape)}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{what} contains NaN or infinite values")
    return np.broadcast_to(arr, (count,)).copy()


def pixels(value, what: str, high: int) -> int:
    """``value`` as an int if it is a whole number of pixels from 1 to ``high``: a
    TypeError naming ``what`` for another type, a ValueError for another value
    ("width must be from 1 to 4096 pixels, got 100000")."""
    if not is_whole(value):
        raise TypeError(f"{what} must be an int (pixels), got {value!r}")
    if not 1 <= value <= high:
        raise ValueError(f"{what} must be from 1 to {high} pixels, got {value!r}")
    return int(value)


def _short(value, limit: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _as_float(value) -> float:
    try:
        return float(value)
    except OverflowError:           # an int beyond the floats
        return math.inf


def _whole_range(low, high) -> str:
    if low is None and high is None:
        return "a whole number"
    if high is None:
        return {0: "a non-negative whole number", 1: "a positive whole number"}.get(
            low, "a whole number of at least {low}")
    if low is None:
        return "a whole number of at most {high}"
    return "a whole number from {low} to {high}"


def _real_range(low, high, open_low: bool, open_high: bool) -> str:
    if low is None and high is None:
        return "a finite number"
    if high is None:
        if low == 0:
            return "a finite positive number" if open_low else "a finite non-negative number"
        return "a finite number " + (">" if open_low else ">=") + " {low:g}"
    if low is None:
        return "a finite number " + ("<" if open_high else "<=") + " {high:g}"
    return ("a number in " + ("(" if open_low else "[") + "{low:g}, {high:g}"
            + (")" if open_high else "]"))
