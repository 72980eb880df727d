"""One row of the tuning table: a variant synthesised and evaluated on MuJoCo
(:func:`twolink.sim.evaluation.evaluate`) on the tuning set (:mod:`.tuning_set`):
nominal, the settle / T* over the tuning grid, and ``medium`` and ``hard`` plain and
compensated. Each cell is k/n with the 95 % Wilson interval and the median settle time
(failures never settle).
"""
from __future__ import annotations

import time

import numpy as np

from twolink.sim.evaluation import evaluate

from .tuning_set import CHALLENGE_PLANTS, CHALLENGE_POSES, PLANT_SEED, POSES, ratio_grid
from .variants import VARIANTS


def _cell(e) -> dict:
    """The JSON cell of an evaluation: successes, n, the Wilson interval, the median
    settle time (None when nothing settled)."""
    s = e.score
    return {"successes": s.successes, "n": s.n, "wilson_95": list(s.wilson_95),
            "median_settle": s.median_settle if np.isfinite(s.median_settle) else None}


def measure(label: str) -> dict:
    """The row of the variant ``label`` of :data:`.variants.VARIANTS`: its synthesis
    seconds and every cell of the table."""
    t0 = time.perf_counter()
    controller = VARIANTS[label]()
    row = {"variant": label, "synthesis_seconds": time.perf_counter() - t0}
    row["none"] = _cell(evaluate(controller, x0=POSES))
    states, limit = ratio_grid()
    grid = evaluate(controller, x0=states)
    ratio = grid.settle.ravel() / limit
    row["ratio"] = {"successes": int(grid.success.sum()), "n": int(grid.success.size),
                    "median": float(np.median(ratio)) if np.isfinite(np.median(ratio))
                    else None,
                    "worst": float(np.max(ratio)) if np.isfinite(np.max(ratio)) else None}
    for level in ("medium", "hard"):
        for compensate in (False, True):
            e = evaluate(controller, x0=POSES[:CHALLENGE_POSES], challenge=level,
                         seed=PLANT_SEED, count=CHALLENGE_PLANTS, compensate=compensate)
            row[level + (" compensated" if compensate else "")] = _cell(e)
    return row
