"""The time-optimal limit T*(x0) of initial states, from the shipped table
(:func:`twolink.limits.shipped_limits`, the 65 states of the evaluation set)."""
from __future__ import annotations

import numpy as np

from twolink.arm.parameters import TS
from twolink.limits import shipped_limits


def state_limits(x0, model: str = "full") -> tuple[np.ndarray | None, str]:
    """(T* in seconds per row of ``x0`` (n, 4), where the arm of ``model`` can first be
    held in the goal band; a description of the source). (None, why) when a state is not
    in the shipped table or has no upper bound there."""
    table = shipped_limits(model)
    states, samples = table.states, table.samples
    x0 = np.asarray(x0, dtype=float).reshape(-1, 4)
    out = np.empty(len(x0))
    for i, x in enumerate(x0):
        hit = np.flatnonzero(np.all(np.abs(states - x) < 1e-12, axis=1))
        if not hit.size or samples[hit[0]] < 0:
            return None, (f"state {i} ({', '.join(f'{v:g}' for v in x)}) has no shipped limit; "
                          f"twolink limits --x0 computes one")
        out[i] = samples[hit[0]] * TS
    what = {"full": "full model (6)", "simplified": "simplified model (11)"}.get(model, model)
    return out, f"T* of the shipped time-optimal table, {what}"
