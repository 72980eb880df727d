"""Start-up time: ``python -c "import twolink"`` and ``twolink --help`` in fresh processes,
best of ``repeats`` wall times, beside the interpreter's own start (``python -c pass``),
and which heavy libraries ``import twolink`` loads (it should load none)."""
from __future__ import annotations

import subprocess
import sys
import time

from benchmarks.common import Row

#: Targets of the start-up rows (seconds, best of 5, on the 2-core CI machine).
TARGETS = {"import twolink": 0.3, "twolink --help": 0.5}
HEAVY = ("numpy", "scipy", "matplotlib", "numba", "mujoco", "gymnasium", "dm_control")


def _best(argv, repeats: int) -> float:
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        subprocess.run(argv, check=True, stdout=subprocess.DEVNULL)
        best = min(best, time.perf_counter() - t0)
    return best


def bench_startup(repeats: int = 5) -> tuple[list[Row], dict]:
    py = sys.executable
    cli = [py, "-c", "import sys; from twolink.cli import main; sys.exit(main(['--help']))"]
    figures = {"python -c pass": _best([py, "-c", "pass"], repeats),
               "import twolink": _best([py, "-c", "import twolink"], repeats),
               "twolink --help": _best(cli, repeats)}
    loaded = subprocess.run([py, "-c", "import sys, twolink; print(' '.join(m for m in "
                             f"{HEAVY!r} if m in sys.modules))"],
                            check=True, capture_output=True, text=True).stdout.split()
    rows = [Row("startup", name, seconds, "s",
                f"best of {repeats}" + (f"; target <= {TARGETS[name]:g} s "
                                        f"{'met' if seconds <= TARGETS[name] else 'MISSED'}"
                                        if name in TARGETS else ""))
            for name, seconds in figures.items()]
    rows.append(Row("startup", "heavy modules import twolink loads", len(loaded), "",
                    " ".join(loaded) or "none"))
    return rows, {"seconds": figures, "targets": TARGETS, "heavy_loaded": loaded}
