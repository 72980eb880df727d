"""The per-joint saturated PD of an N-link arm (twolink.control.links_pd)."""
import math

import numpy as np
import pytest

from twolink.arm.parameters import TABLE_I, links_parameters
from twolink.control.links_pd import (
    TUNED,
    TUNING_SEED,
    LinksPD,
    joint_inertias,
    make_links_pd,
    tuned,
)
from twolink.sim.metrics import random_poses, success
from twolink.sim.plants import make_plant
from twolink.sim.rollout import rollout
from twolink.studies.scaling.measure import EVAL_SEED


def test_gains_follow_the_rule_and_two_links_match_the_two_link_inertias():
    t = TABLE_I                                       # det M0 / M0_jj of (7)
    m0 = np.array([[t.P1 + t.P2 + 2 * t.P3, t.P2 + t.P3], [t.P2 + t.P3, t.P2]])
    np.testing.assert_allclose(joint_inertias(links_parameters(2)), 1 / np.diag(np.linalg.inv(m0)))
    p = links_parameters(4, "copied")
    pd = make_links_pd(p, 20.0, 0.7)
    kp = p.tau_max / math.radians(20.0)
    np.testing.assert_allclose(pd.kp, kp)
    np.testing.assert_allclose(pd.kd, 1.4 * np.sqrt(kp * joint_inertias(p)))
    x = np.zeros((3, 8))
    x[1, 0] = math.radians(10.0)                      # half the saturation angle
    x[2, 0], x[2, 7] = 3.0, -50.0                     # far out: saturated
    u = pd(x)
    np.testing.assert_array_equal(u[0], 0.0)
    assert u[1, 0] == pytest.approx(-0.5 * p.tau_max[0]) and np.all(u[1, 1:] == 0)
    assert u[2, 0] == -p.tau_max[0] and u[2, 3] == p.tau_max[3]


def test_tuned_pd_settles_the_three_link_arm():
    p = links_parameters(3)
    pd = tuned(p)
    assert pd.links == 3 and TUNED[(3, "tapered")]["successes"] == 64
    x0 = random_poses(3, 4, 11)
    with make_plant("mujoco", p) as plant:
        ok = success(rollout(pd, plant, x0, duration=8.0))
    assert ok.all()


def test_the_tuning_seeds_are_not_the_evaluation_seeds():
    evaluation = {EVAL_SEED + n for n in range(2, 7)}
    assert not evaluation & {TUNING_SEED + n for n in range(2, 7)}
    assert set(TUNED) == {(n, r) for n in range(3, 7) for r in ("tapered", "copied")}


def test_bad_gains_and_states_are_refused():
    with pytest.raises(ValueError, match="sat_deg must be a positive number, got 0"):
        make_links_pd(links_parameters(3), 0, 1.0)
    with pytest.raises(ValueError, match="zeta must be a positive number, got nan"):
        make_links_pd(links_parameters(3), 10, float("nan"))
    with pytest.raises(ValueError, match=r"kd must be 3 finite numbers >= 0"):
        LinksPD([1, 1, 1], [1, -1, 1], [1, 1, 1])
    with pytest.raises(ValueError, match=r"states must have shape \(\.\.\., 6\) for 3 links"):
        make_links_pd(links_parameters(3), 10, 1.0)(np.zeros(4))
    with pytest.raises(ValueError, match="no tuned PD gains for 2 tapered links"):
        tuned(links_parameters(2))
