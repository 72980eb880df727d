"""Progress of long runs, on a terminal and in logs alike: one helper for every bar.

:func:`progress_bar` is ``tqdm`` with two behaviours. On a terminal (stderr a tty) it is
the usual bar, redrawn in place. Anywhere else (stderr a file, a pipe, a CI log) the bar
is not dropped, as ``tqdm(disable=None)`` drops it: its status is printed as a plain line,
at most every :data:`LOG_INTERVAL` seconds, and once more when it ends, so a log shows the
run advancing. ``enabled=False`` shows nothing (``--json`` and library calls).
"""
from __future__ import annotations

import sys
import time

from tqdm import tqdm

#: Seconds between two progress lines when stderr is not a terminal.
LOG_INTERVAL = 10.0
_now = time.monotonic


class _Lines:
    """A stream for tqdm that turns the statuses it draws (``\r`` + text) into lines: the
    first, then at most one every :data:`LOG_INTERVAL` s (tqdm redraws on every
    ``set_postfix`` too), and the last one at :meth:`finish`; blank redraws are dropped."""

    def __init__(self, stream):
        self.stream = stream
        self.pending = None
        self.shown = None
        self.last = None

    def write(self, text: str) -> None:
        line = text.replace("\r", "").replace("\x1b[A", "").strip()
        if not line:
            return
        self.pending = line
        now = _now()
        if self.last is None or now - self.last >= LOG_INTERVAL:
            self._emit()
            self.last = now

    def _emit(self) -> None:
        if self.pending is not None and self.pending != self.shown:
            self.stream.write(self.pending + "\n")
            self.stream.flush()
            self.shown = self.pending
        self.pending = None

    def finish(self) -> None:
        """Print the latest status unless it was printed."""
        self._emit()

    def flush(self) -> None:
        self.stream.flush()


class _LogBar(tqdm):
    """A tqdm bar whose :class:`_Lines` prints the final status when it closes."""

    def close(self):
        lines = getattr(self, "_lines", None)
        super().close()
        if lines is not None:
            lines.finish()


def on_terminal(stream=None) -> bool:
    """Whether ``stream`` (default: stderr) is a terminal."""
    stream = sys.stderr if stream is None else stream
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):      # no isatty, or closed
        return False


def progress_bar(iterable=None, *, enabled: bool = True, **kwargs) -> tqdm:
    """A ``tqdm`` bar over ``iterable`` (tqdm's keywords: ``total``, ``desc``, ``unit``,
    ...): drawn in place on a terminal, printed as a line at most every
    :data:`LOG_INTERVAL` s (and at its end) elsewhere, hidden when not ``enabled``."""
    if not enabled:
        return tqdm(iterable, disable=True, **kwargs)
    if on_terminal():
        return tqdm(iterable, disable=False, **kwargs)
    lines = _Lines(sys.stderr)
    kwargs.update(file=lines, leave=True, dynamic_ncols=False, ncols=100, ascii=True)
    bar = _LogBar(iterable, disable=False, **kwargs)
    bar._lines = lines
    return bar
