"""The worst case over a level's parameter box (twolink.sim.plant_grid)."""
import itertools

import numpy as np
import pytest

from twolink.arm.parameters import TABLE_I
from twolink.sim.challenges import challenge
from twolink.sim.metrics import evaluation_set
from twolink.sim.perturbations import PHYSICAL
from twolink.sim.plant_grid import (
    corner_signs,
    grid_plants,
    plackett_burman_12,
    worst_case,
)


def test_the_design_is_orthogonal_balanced_and_of_resolution_four():
    d = plackett_burman_12()
    assert d.shape == (12, 11) and set(np.unique(d)) == {-1, 1}
    assert np.array_equal(d.T @ d, 12 * np.eye(11, dtype=int))        # orthogonal columns
    s = corner_signs()
    assert s.shape == (24, len(PHYSICAL)) and np.all(s.sum(axis=0) == 0)   # balanced
    for i, j in itertools.combinations(range(len(PHYSICAL)), 2):       # every sign pair
        pairs = {(a, b) for a, b in zip(s[:, i], s[:, j])}
        assert pairs == {(1, 1), (1, -1), (-1, 1), (-1, -1)}
        for k in range(len(PHYSICAL)):                                 # main vs 2-factor
            assert s[:, k] @ (s[:, i] * s[:, j]) == 0
    assert len({tuple(r) for r in s}) == 24                            # 24 distinct corners


def test_the_grid_is_the_centre_and_corners_of_the_levels_box():
    hard = challenge("hard")
    plants = grid_plants("hard")
    assert len(plants) == 25 and plants[0].label == "centre"
    centre = plants[0].params
    assert centre.tau1_max == pytest.approx(TABLE_I.tau1_max * (1 + hard.torque_limit))
    corner = plants[1]
    for name, change in corner.changes.items():
        assert abs(change) == pytest.approx(hard.spread)
        assert getattr(corner.params, name) == pytest.approx(
            getattr(hard.offset(TABLE_I), name) * (1 + change))
    assert corner.label.split()[0] in ("+l1", "-l1")
    assert [g.label for g in grid_plants("none")] == ["centre"]


def test_worst_case_reports_every_plant_and_the_worst(monkeypatch):
    """A controller that does nothing fails everywhere but where it starts in the band."""
    x0 = evaluation_set()[[0, 5]]
    x0[1] = 0.0                                       # at rest at the goal: a success
    r = worst_case(lambda x: np.zeros((len(x), 2)), "easy", x0=x0, seed=3)
    d = r.as_dict()
    assert d["plants"] == 25 and d["states"] == 2 and d["n"] == 50
    assert set(d["per_plant"].values()) == {1} and d["successes"] == 25
    assert d["worst_plant"] == "centre" and d["worst_plant_successes"] == 1
