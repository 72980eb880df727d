"""Whether an N-link pose can reach the goal band by a deadline
(twolink.limits.links): the CasADi dynamics against the numpy ones, answers
on three links that must and must not be reachable, the defect check, bad input."""
import math

import numpy as np
import pytest

from twolink.arm.dynamics import links_acceleration
from twolink.arm.integrate import SUBSTEPS, rk4, sample_step
from twolink.arm.parameters import TS, links_parameters
from twolink.limits import links as L

def _step(p, x, tau):
    """One sample of the package's RK4, unwrapped (as the answers are checked)."""
    return rk4(links_acceleration, p, x, tau, TS, SUBSTEPS)


casadi = pytest.importorskip("casadi", reason="CasADi is not installed "
                             "(pip install 'twolink[limits]')")


@pytest.mark.parametrize("links, rule", [(3, "tapered"), (6, "tapered"), (4, "copied")])
def test_the_symbolic_dynamics_and_step_are_the_package_s(links, rule):
    p = links_parameters(links, rule)
    rng = np.random.default_rng(links)
    x = np.concatenate([rng.uniform(-3, 3, links), rng.uniform(-2, 2, links)])
    tau = rng.uniform(-1, 1, links) * p.tau_max
    sym = casadi.SX.sym("x", 2 * links)
    accel = casadi.Function("a", [sym], [L.acceleration_expression(casadi, p, sym, tau)])
    np.testing.assert_allclose(np.asarray(accel(x)).ravel(), links_acceleration(p, x, tau),
                               rtol=1e-13, atol=1e-12)
    stepped = np.asarray(L.step_function(p)(x, tau)).ravel()
    ours = sample_step(links_acceleration, p, x, tau)
    wrapped = np.mod(stepped[:links] - ours[:links] + math.pi, 2 * math.pi) - math.pi
    assert np.abs(wrapped).max() < 1e-11 and np.abs(stepped[links:] - ours[links:]).max() < 1e-11


def test_a_near_pose_is_reachable_and_its_answer_is_a_trajectory_of_the_model():
    p = links_parameters(3)
    x0 = np.array([0.4, -0.3, 0.2, 0, 0, 0])
    r = L.reach(p, x0, 20)                              # 1 s
    assert r.reachable and r.targets == (0.0, 0.0, 0.0)
    assert r.torques.shape == (20, 3) and np.all(np.abs(r.torques) <= p.tau_max + 1e-9)
    assert r.defect < 1e-6 and r.slack <= 0                # IPOPT's constraint tolerance
    assert np.array_equal(r.torques[0], r.torques[1])   # held for HOLD = 2 samples
    # The torques replayed for a few samples follow the answer (no feedback needed there).
    x = x0
    for tau in r.torques[:4]:
        x = sample_step(links_acceleration, p, x, tau)
    assert np.abs(x[3:]).max() > 0.05                  # it moves


def test_a_far_pose_is_not_reachable_in_two_samples():
    r = L.reach(links_parameters(3), np.array([3.0, 0, 0, 0, 0, 0]), 2)
    assert not r.reachable and r.torques is None and r.slack > 0
    assert r.as_dict()["reachable"] is False and len(r.targets) == 3


def test_the_candidate_bands_go_the_other_way_round_for_far_joints():
    first, second = L.candidate_targets(np.array([3.0, 0.5, -2.0, 0, 0, 0]), 3)
    assert first.tolist() == [0, 0, 0]
    assert second.tolist() == [2 * math.pi, 0, -2 * math.pi]
    assert len(L.candidate_targets(np.zeros(6), 3)) == 1


def test_the_defect_sees_a_state_off_the_model():
    p = links_parameters(3)
    x0 = np.array([0.1, 0.0, 0.0, 0, 0, 0])
    tau = np.tile(0.5 * p.tau_max, (2, 1))
    states = [x0]
    for t in tau:
        states.append(_step(p, _step(p, states[-1], t), t))
    states = np.array(states)
    assert L.defect(p, states, tau, 2) < 1e-14
    states[2, 4] += 1e-3
    assert L.defect(p, states, tau, 2) == pytest.approx(1e-3, rel=1e-9)


@pytest.mark.parametrize("x0, deadline, kwargs, match", [
    (np.zeros(5), 20, {}, "x0 of a 3-link arm must be 6 finite numbers"),
    (np.array([np.nan, 0, 0, 0, 0, 0]), 20, {}, "must be 6 finite numbers"),
    (np.array([0, 0, 0, 100.0, 0, 0]), 20, {}, "speed limits"),
    (np.zeros(6), 21, {}, "deadline 21 must be a whole multiple of hold 2"),
    (np.zeros(6), 10 ** 6, {}, "deadline must be a whole number from 2 to 300"),
    (np.zeros(6), 20, {"hold": 0}, "hold must be a whole number from 1 to 20"),
    (np.zeros(6), 20, {"substeps": 10 ** 9}, "substeps must be a whole number from 1 to 50"),
])
def test_bad_input_is_one_line_before_any_solve(x0, deadline, kwargs, match):
    with pytest.raises(ValueError, match=match):
        L.reach(links_parameters(3), x0, deadline, **kwargs)


def test_the_deadline_is_in_samples_of_ts():
    assert L.HOLD * TS == pytest.approx(0.1) and L.NLP_SUBSTEPS == 20


def test_speeds_inside_a_held_period_are_checked():
    """The NLP bounds the speeds at the ends of the held periods only; the answer's check
    sees the samples in between: link 3 coasting down from 3 rad/s is fastest at the
    period's first sample, not at its end."""
    p = links_parameters(3)
    x0 = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 3.0])
    tau = np.zeros((1, 3))
    mid = _step(p, x0, tau[0])
    end = _step(p, mid, tau[0])
    states = np.array([x0, end])
    assert L.defect(p, states, tau, 2) < 1e-14
    assert abs(mid[5]) > abs(end[5])
    assert L.peak_speed(p, states, tau, 2) == pytest.approx(
        np.abs(np.r_[mid[3:], end[3:]]).max() / p.speed_max[0], rel=1e-12)
