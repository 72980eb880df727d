"""The states and plants the tuning table is measured on: none of them is used by a
reported figure.

* nominal: 48 random poses at rest, ``random_poses(2, 48, seed=9301)``;
* ``medium`` and ``hard``: the first 32 of those poses on 8 plants of the level drawn from
  seed 9302 (its noise and faults too);
* the settle / T* column: the 64 states of a tuning grid at rest (:func:`ratio_grid`,
  built as the evaluation set's grid at other angles) with their time-optimal limits.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from twolink.policy.registry import TUNING_SEEDS
from twolink.resources import source_checkout
from twolink.sim.metrics import random_poses

POSE_SEED, PLANT_SEED = TUNING_SEEDS
POSES = random_poses(2, 48, seed=POSE_SEED)
CHALLENGE_POSES, CHALLENGE_PLANTS = 32, 8
#: Angles (deg) of the tuning grid of the settle / T* column (:func:`ratio_grid`).
RATIO_ANGLES_DEG = (-160.0, -100.0, -55.0, -12.0, 12.0, 55.0, 100.0, 160.0)
#: T* of that grid, relative to the source checkout:
#: ``twolink limits --model full --degrees --x0 A B 0 0 ... --write`` over the 64 pairs,
#: in the order of :func:`ratio_grid`.
RATIO_LIMITS_FILE = Path("renders") / "fuzzy_design" / "tuning_limits.json"


def ratio_limits_path() -> Path:
    """The committed T* of the tuning grid (:data:`RATIO_LIMITS_FILE` in the source
    checkout); a ValueError outside a checkout, where the file is not installed."""
    root = source_checkout()
    if root is None:
        raise ValueError(f"the tuning grid's limits ({RATIO_LIMITS_FILE}) are only in a "
                         "source checkout")
    return root / RATIO_LIMITS_FILE


def ratio_grid(limits: Path | None = None) -> tuple:
    """The states of the settle / T* column and their T* (s): the 8 x 8 angle pairs of
    :data:`RATIO_ANGLES_DEG` at rest, as the evaluation set's grid is made but at other
    angles, with T* of the full model (6) from ``limits`` (default
    :func:`ratio_limits_path`; ``upper`` x Ts, inf where the limit found none)."""
    from twolink.limits.table import tables_from_json

    limits = ratio_limits_path() if limits is None else Path(limits)
    table = tables_from_json(limits.read_text())["full"]
    a = np.deg2rad(RATIO_ANGLES_DEG)
    t1, t2 = np.meshgrid(a, a, indexing="ij")
    want = np.zeros((t1.size, 4))
    want[:, 0], want[:, 1] = t1.ravel(), t2.ravel()
    if not np.allclose(table.states, want):
        raise ValueError(f"{limits} does not hold the tuning grid of RATIO_ANGLES_DEG")
    seconds = np.array([np.inf if r.upper is None else r.seconds for r in table.rows])
    return want, seconds
