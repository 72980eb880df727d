"""Shared pieces of the benchmark suite: timing, peak memory, result rows, the table."""
from __future__ import annotations

import dataclasses
import math
import time
import tracemalloc
from typing import Callable, Optional

import numpy as np


@dataclasses.dataclass
class Row:
    """One measured figure: ``section / name = value unit``, with a free-form note."""

    section: str
    name: str
    value: float
    unit: str
    note: str = ""

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


def best_time(fn: Callable[[], object], repeats: int) -> tuple[float, object]:
    """Smallest wall time of ``repeats`` calls of ``fn`` (the least noisy estimate on a
    shared machine) and the last call's result."""
    best, out = math.inf, None
    for _ in range(max(1, repeats)):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def interleaved_best(fns: dict, repeats: int) -> tuple[dict, dict]:
    """Best wall time of each callable in ``fns``, taking turns ``repeats`` times so every
    one sees the same background load on a shared machine; and each one's last result."""
    best, out = dict.fromkeys(fns, math.inf), {}
    for _ in range(max(1, repeats)):
        for key, fn in fns.items():
            t, out[key] = best_time(fn, 1)
            best[key] = min(best[key], t)
    return best, out


def peak_bytes(fn: Callable[[], object]) -> tuple[int, object]:
    """Peak bytes allocated through Python's allocators (numpy and scipy arrays included)
    while ``fn`` runs, above what was allocated before it; and its result."""
    was_tracing = tracemalloc.is_tracing()
    if not was_tracing:
        tracemalloc.start()
    tracemalloc.reset_peak()
    base, _ = tracemalloc.get_traced_memory()
    try:
        out = fn()
        _, peak = tracemalloc.get_traced_memory()
    finally:
        if not was_tracing:
            tracemalloc.stop()
    return peak - base, out


def total_ram_bytes() -> Optional[int]:
    """Physical memory of the machine (Linux and macOS), or None when unknown."""
    import os

    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return None


def available_ram_bytes() -> Optional[int]:
    """Memory available to a new process now (Linux /proc/meminfo), or None."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return None


def _fmt(v: float) -> str:
    if isinstance(v, bool):
        return str(v)
    if isinstance(v, int) or (isinstance(v, float) and v.is_integer() and abs(v) < 1e15):
        return f"{int(v):,}"
    if not math.isfinite(v):
        return str(v)
    a = abs(v)
    if a >= 1e5 or (a < 1e-3 and a != 0):
        return f"{v:.3g}"
    return f"{v:.4g}"


def format_table(rows: list[Row]) -> str:
    """A plain-text table, one block per section."""
    w_name = max((len(r.name) for r in rows), default=4)
    w_val = max((len(_fmt(r.value)) for r in rows), default=5)
    w_unit = max((len(r.unit) for r in rows), default=4)
    out, section = [], None
    for r in rows:
        if r.section != section:
            section = r.section
            out.append(f"\n== {section} ==")
        out.append(f"  {r.name:<{w_name}}  {_fmt(r.value):>{w_val}}  {r.unit:<{w_unit}}  {r.note}"
                   .rstrip())
    return "\n".join(out).lstrip("\n")


def copy_bandwidth(nbytes: int) -> Callable[[], int]:
    """A callable copying a float64 array of ``nbytes`` into another (numpy ``copyto``);
    it returns the bytes it moves, 2 * nbytes (read and write). Timed beside a kernel
    that moves the same bytes, it gives the machine's attainable bandwidth in the same run."""
    src = np.random.default_rng(0).random(max(1, nbytes // 8))
    dst = np.empty_like(src)

    def copy() -> int:
        np.copyto(dst, src)
        return 2 * src.nbytes

    return copy
