"""The one evaluation result (twolink.sim.metrics.Score): its numbers, its one JSON spelling,
the old spellings it still reads, and the three evaluations that all report it."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from twolink.arm.parameters import HORIZON, TABLE_I
from twolink.sim.metrics import (
    OLD_SCORE_KEYS,
    SCORE_KEYS,
    Score,
    random_poses,
    score,
    score_keys,
    wilson_interval,
)


def test_median_is_inf_when_more_than_half_fail():
    ok = np.array([True, True, False, False, False])
    assert score(ok, [1.0, 2.0, np.inf, np.inf, np.inf]).median_settle == math.inf
    # a failure counts as never settled even when it settled (too late to succeed)
    assert score(ok, [1.0, 2.0, 4.5, 4.6, 4.7]).median_settle == math.inf
    assert score(ok, [1.0, 2.0, 4.5, 4.6, 4.7]).as_dict()["median_settle"] is None
    assert score(~ok, [np.inf, np.inf, 1.0, 2.0, 3.0]).median_settle == 3.0   # 2 of 5 fail
    assert score([True, False], [1.0, 1.0]).median_settle == math.inf        # half of an even n


def test_score_counts_interval_and_worst_plant():
    ok = np.array([[True, True, False, True], [True, False, False, True]])
    st = np.where(ok, [[1.0, 2.0, 0, 0.5], [1.5, 0, 0, 3.0]], np.inf)
    s = score(ok, st, np.repeat([0, 1], 4))
    assert (s.successes, s.n, s.rate) == (5, 8, 5 / 8)
    assert s.wilson_95 == wilson_interval(5, 8)
    assert (s.worst_plant, s.worst_plant_successes) == (1, 2)
    assert s.median_settle == 2.5                             # (2.0 + 3.0) / 2
    one = score(ok, st, np.zeros(8, dtype=int))               # one plant: no worst plant
    assert (one.worst_plant, one.worst_plant_successes) == (None, None)
    assert score(ok, st).worst_plant is None
    d = json.loads(json.dumps(s.as_dict()))
    assert tuple(d) == SCORE_KEYS and d["wilson_95"] == list(wilson_interval(5, 8))
    assert Score.from_dict(d) == s
    with pytest.raises(ValueError, match="at least one run"):
        score([], [])
    with pytest.raises(ValueError, match="plant index"):
        score(ok, st, np.repeat([0.0, 1.0], 4))


def test_old_spellings_still_read():
    """Committed files hold ``runs``/``wilson95`` (the mismatch report), ``interval`` (the
    N-link section) and learning curves with only successes and n."""
    for old in ({"successes": 3, "runs": 4, "rate": 0.75, "wilson95": [0.3, 0.95],
                 "median_settle": 1.5, "plant_successes": [3]},
                {"successes": 3, "runs": 4, "interval": [0.3, 0.95], "median_settle": 1.5},
                {"steps": 10, "successes": 3, "n": 4, "median_settle": 1.5}):
        new = score_keys(old)
        assert new["n"] == 4 and not set(OLD_SCORE_KEYS) & set(new)
        assert all(new[k] == v for k, v in old.items() if k not in OLD_SCORE_KEYS)
        s = Score.from_dict(old)
        assert (s.successes, s.n, s.median_settle) == (3, 4, 1.5)
        assert s.wilson_95 == wilson_interval(3, 4) and s.worst_plant is None
    assert Score.from_dict({"successes": 0, "n": 2, "median_settle": None}).median_settle \
        == math.inf
    assert score_keys({"n": 5, "runs": 9})["n"] == 5                  # the new key wins


def test_the_three_evaluations_report_the_same_score():
    """sim.evaluation.evaluate, control.learning.evaluate and the scaling study's
    evaluate of the same policy from the same states on the same MuJoCo arm: one score,
    with the same keys in their JSON."""
    from twolink.synthesis.learning import evaluate as learning_evaluate
    from twolink.policy.fuzzy_policy import load_policy
    from twolink.sim.evaluation import evaluate
    from twolink.sim.plants import MujocoPlant
    from twolink.studies.scaling import measure as scaling

    policy = load_policy("decentralized_full")
    poses, seed = 6, 5
    x0 = random_poses(2, poses, seed + 2)                   # the scaling study's poses
    sim = evaluate(policy, x0=x0, horizon=HORIZON)
    with MujocoPlant(TABLE_I) as plant:
        learned = learning_evaluate(policy, plant, x0, steps=3)
    scaled = scaling.evaluate(policy, 2, "tapered", poses=poses, seed=seed)
    dicts = {"sim": sim.as_dict(rows=False), "learning": learned.as_dict(),
             "scaling": scaled.horizons[f"{HORIZON:g}"]}
    for name, d in dicts.items():
        d = json.loads(json.dumps(d))
        assert set(SCORE_KEYS) <= set(d) and not set(OLD_SCORE_KEYS) & set(d), name
        assert {k: d[k] for k in SCORE_KEYS} == sim.score.as_dict(), name
    assert learned.score == sim.score == scaled.scores()[f"{HORIZON:g}"]
    # several plants: the worst one is named, in the same keys
    many = evaluate(policy, params=[TABLE_I, TABLE_I.scaled(m1=1.3)], x0=x0[:2], horizon=2.0)
    d = many.as_dict(rows=False)
    assert set(SCORE_KEYS) <= set(d) and d["worst_plant"] in (0, 1)
    assert d["worst_plant_successes"] == min(d["plant_successes"])
