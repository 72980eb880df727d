"""Table I, (10), the models (6)-(11) and their sampling over Ts."""
import math

import numpy as np
import pytest

from twolink.arm import dynamics
from twolink.arm.integrate import SUBSTEPS, integration_error, sample_step, wrap_angle
from twolink.arm.parameters import TABLE_I, ArmParameters


def test_derived_parameters_of_eq_10():
    p = TABLE_I
    assert p.P1 == pytest.approx(1.25 * 0.05**2 + 1.0 * 0.1**2 + 0.004)   # 0.017125
    assert p.P2 == pytest.approx(1.0 * 0.05**2 + 0.003)                   # 0.0055
    assert p.P3 == pytest.approx(1.0 * 0.1 * 0.05)                        # 0.005
    assert p.g1 == pytest.approx((1.25 * 0.05 + 1.0 * 0.1) * 9.81)
    assert p.g2 == pytest.approx(1.0 * 0.05 * 9.81)


def test_parameters_refuse_bad_values():
    with pytest.raises(ValueError, match="m1 must be positive"):
        ArmParameters(m1=-1.0)
    with pytest.raises(ValueError, match="finite"):
        ArmParameters(b2=float("nan"))
    with pytest.raises(ValueError, match="unknown parameter"):
        TABLE_I.scaled(mass=2.0)
    assert TABLE_I.scaled(m2=1.5).m2 == pytest.approx(1.5)


def test_simplified_model_as_printed():
    p = TABLE_I
    x = np.array([0.3, -1.1, 0.7, -2.0])
    tau = np.array([0.15, -0.05])
    c = math.cos(x[1])
    a1 = (p.P2 * (tau[0] - p.b1 * x[2]) - (p.P2 + p.P3 * c) * tau[1]) / (
        p.P2 * (p.P1 + p.P2 + 2 * p.P3 * c))
    a2 = tau[1] / p.P2 - p.b2 * x[3]
    np.testing.assert_allclose(dynamics.simplified_acceleration(p, x, tau), [a1, a2], rtol=1e-14)


def test_full_model_solves_eq_6(rng):
    p = TABLE_I
    x = rng.uniform(-3, 3, (50, 4))
    tau = rng.uniform(-0.2, 0.2, (50, 2))
    acc = dynamics.full_acceleration(p, x, tau)
    m = dynamics.mass_matrix(p, x[:, 1])
    lhs = np.einsum("bij,bj->bi", m, acc) + dynamics.coriolis_forces(p, x) \
        + np.stack([p.b1 * x[:, 2], p.b2 * x[:, 3]], -1)
    np.testing.assert_allclose(lhs, tau, atol=1e-14)


def test_coriolis_matrix_is_passive(rng):
    """dM/dt - 2C is skew-symmetric, i.e. dtheta' (dM/dt) dtheta = 2 dtheta' C dtheta."""
    p = TABLE_I
    for x in rng.uniform(-3, 3, (20, 4)):
        dm = p.P3 * -math.sin(x[1]) * x[3] * np.array([[2, 1], [1, 0]])
        lhs = x[2:] @ dm @ x[2:]
        rhs = 2 * x[2:] @ dynamics.coriolis_forces(p, x)
        assert lhs == pytest.approx(rhs, abs=1e-12)


def test_gravity_is_optional():
    p = TABLE_I
    x = np.array([0.5, 0.2, 0.0, 0.0])
    assert np.allclose(dynamics.full_acceleration(p, x, np.zeros(2)), 0.0)
    assert not np.allclose(dynamics.full_acceleration(p, x, np.zeros(2), gravity=True), 0.0)


def test_sampling_wraps_angles_and_saturates_speeds():
    p = TABLE_I
    # Link 2 of (11) gains about 0.9 rad/s over Ts under tau2 = 0.1 Nm and crosses pi.
    x = np.array([[0.0, math.pi - 0.01, 0.0, 6.0]])
    nxt = sample_step(dynamics.simplified_acceleration, p, x, np.array([[0.0, 0.1]]))
    assert -math.pi <= nxt[0, 1] < 0                                 # crossed pi, wrapped
    assert nxt[0, 3] == 2 * math.pi                                  # saturated
    assert wrap_angle(math.pi) == pytest.approx(-math.pi)
    # Torques beyond tau_max are clipped: 1 Nm acts like 0.2 Nm.
    a = sample_step(dynamics.simplified_acceleration, p, np.zeros(4), [1.0, 0.0])
    b = sample_step(dynamics.simplified_acceleration, p, np.zeros(4), [0.2, 0.0])
    np.testing.assert_array_equal(a, b)


def test_integration_error_is_small_and_shrinks_with_substeps(rng):
    x = rng.uniform(-3, 3, (200, 4))
    tau = rng.uniform(-0.2, 0.2, (200, 2))
    coarse = integration_error(dynamics.full_acceleration, TABLE_I, x, tau, substeps=2,
                               reference_substeps=200)
    chosen = integration_error(dynamics.full_acceleration, TABLE_I, x, tau, substeps=SUBSTEPS,
                               reference_substeps=200)
    assert max(chosen["max"]) < 1e-5
    assert max(chosen["max"]) < max(coarse["max"]) / 100
