"""The N-link arm's rigid-body model (dynamics.links_*) and its sampling (integrate)
against MuJoCo, against an independent per-state reference written here, and against
the two-link model (6)-(9)."""
import cmath

import mujoco
import numpy as np
import pytest

from twolink.arm import dynamics, mjcf, task
from twolink.arm.integrate import (
    SUBSTEPS,
    finish_sample,
    integration_error,
    sample_step,
    sample_step_compiled,
    wrap_angle,
)
from twolink.arm.parameters import (
    LINK_RULES,
    MAX_LINKS,
    MIN_LINKS,
    TABLE_I,
    TS,
    as_links,
    links_parameters,
)

ARMS = [(n, rule) for n in range(MIN_LINKS, MAX_LINKS + 1) for rule in LINK_RULES]


def _states(rng, n, count):
    """Random states: angles in [-pi, pi), speeds in [-2 pi, 2 pi)."""
    return rng.uniform(-np.pi, np.pi, (count, 2 * n)) * np.r_[np.ones(n), 2 * np.ones(n)]


# --------------------------------------------------------------------------- reference
def _ref_mass(c, theta):
    """M(theta) of one state from the geometric Jacobians, a loop over links; works for
    complex theta (complex-step derivatives)."""
    n = c.links
    phi = [sum(theta[:k + 1]) for k in range(n)]          # absolute link angles
    jx, jy = [0.0] * n, [0.0] * n                         # joint positions
    for k in range(1, n):
        jx[k] = jx[k - 1] + c.lengths[k - 1] * cmath.cos(phi[k - 1])
        jy[k] = jy[k - 1] + c.lengths[k - 1] * cmath.sin(phi[k - 1])
    m = [[0.0] * n for _ in range(n)]
    for k in range(n):
        px = jx[k] + c.coms[k] * cmath.cos(phi[k])        # centre of mass of link k
        py = jy[k] + c.coms[k] * cmath.sin(phi[k])
        # Column i of J_v: z x (p - o_i) for the joints i <= k; J_w = 1 there.
        jvx = [-(py - jy[i]) if i <= k else 0.0 for i in range(n)]
        jvy = [(px - jx[i]) if i <= k else 0.0 for i in range(n)]
        jw = [1.0 if i <= k else 0.0 for i in range(n)]
        for i in range(n):
            for j in range(n):
                m[i][j] += c.masses[k] * (jvx[i] * jvx[j] + jvy[i] * jvy[j]) \
                    + c.inertias[k] * jw[i] * jw[j]
    return m


def _ref_dmass(c, theta, h=1e-30):
    """dM/dtheta_k for every k by complex-step differentiation (exact to rounding)."""
    n = c.links
    out = []
    for k in range(n):
        t = [complex(v) for v in theta]
        t[k] += 1j * h
        mk = _ref_mass(c, t)
        out.append([[mk[i][j].imag / h for j in range(n)] for i in range(n)])
    return out                                            # out[k][i][j] = dM_ij/dtheta_k


def _ref_bias(c, x):
    """C(theta, dtheta) dtheta from the Christoffel symbols of M."""
    n = c.links
    dq = x[n:]
    dm = _ref_dmass(c, list(x[:n]))
    return [sum((dm[k][i][j] - 0.5 * dm[i][j][k]) * dq[j] * dq[k]
                for j in range(n) for k in range(n)) for i in range(n)]


def _ref_acceleration(c, x, tau, locked=None):
    n = c.links
    m = np.array([[v.real for v in row] for row in _ref_mass(c, list(x[:n]))])
    rhs = np.asarray(tau) - np.array(_ref_bias(c, x)) - np.array(c.dampings) * x[n:]
    free = [k for k in range(n) if not (locked and locked[k])]
    out = np.zeros(n)
    out[free] = np.linalg.solve(m[np.ix_(free, free)], rhs[free])
    return out


# --------------------------------------------------------------------------- MuJoCo
@pytest.mark.parametrize("n,rule", ARMS)
def test_mass_matrix_and_bias_match_mujoco(n, rule, rng):
    c = links_parameters(n, rule)
    model = mjcf.build_model(c)
    data = mujoco.MjData(model)
    full = np.zeros((n, n))
    xs = _states(rng, n, 8)
    mass = dynamics.links_mass_matrix(c, xs[:, :n])
    bias = dynamics.links_bias(c, xs)
    assert mass.shape == (8, n, n) and bias.shape == (8, n)
    for x, m, b in zip(xs, mass, bias):
        data.qpos[:], data.qvel[:] = x[:n], x[n:]
        mujoco.mj_forward(model, data)
        mujoco.mj_fullM(model, data, full)
        np.testing.assert_allclose(m, full, rtol=0, atol=1e-10)
        np.testing.assert_allclose(b, data.qfrc_bias, rtol=0, atol=1e-10)


@pytest.mark.parametrize("n", [3, 6])
def test_one_sample_period_matches_mujoco_rk4(n, rng):
    """sample_step of links_acceleration and MuJoCo's RK4 with the same substep."""
    c = links_parameters(n)
    model = mjcf.build_model(c)
    data = mujoco.MjData(model)
    xs = _states(rng, n, 5) * np.r_[np.ones(n), 0.5 * np.ones(n)]
    taus = rng.uniform(-1, 1, (5, n)) * c.tau_max
    ours = sample_step(dynamics.links_acceleration, c, xs, taus)
    for x, tau, mine in zip(xs, taus, ours):
        mujoco.mj_resetData(model, data)
        data.qpos[:], data.qvel[:], data.ctrl[:] = x[:n], x[n:], tau
        for _ in range(SUBSTEPS):
            mujoco.mj_step(model, data)
        np.testing.assert_allclose(wrap_angle(mine[:n] - data.qpos), 0.0, atol=1e-10)
        np.testing.assert_allclose(mine[n:], data.qvel, rtol=0, atol=1e-9)


# --------------------------------------------------------------------------- reference
@pytest.mark.parametrize("n,rule", ARMS)
def test_against_independent_reference(n, rule, rng):
    c = links_parameters(n, rule)
    xs = _states(rng, n, 4)
    taus = rng.uniform(-1, 1, (4, n)) * c.tau_max
    mass = dynamics.links_mass_matrix(c, xs[:, :n])
    bias = dynamics.links_bias(c, xs)
    acc = dynamics.links_acceleration(c, xs, taus)
    for x, tau, m, b, a in zip(xs, taus, mass, bias, acc):
        ref = np.array([[v.real for v in row] for row in _ref_mass(c, list(x[:n]))])
        np.testing.assert_allclose(m, ref, rtol=0, atol=1e-10)
        np.testing.assert_allclose(b, _ref_bias(c, x), rtol=0, atol=1e-10)
        np.testing.assert_allclose(a, _ref_acceleration(c, x, tau), rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("locked", [(True, False, False), (False, True, False),
                                    (True, True, False), (False, False, True),
                                    (True, False, True)])
def test_locked_joints_leave_the_solve(locked, rng):
    c = links_parameters(3, "copied")
    xs = _states(rng, 3, 6)
    taus = rng.uniform(-1, 1, (6, 3)) * c.tau_max
    acc = dynamics.links_acceleration(c, xs, taus, locked=locked)
    held = np.array(locked)
    assert np.all(acc[:, held] == 0.0)
    assert np.all(acc[:, ~held] != 0.0)
    for x, tau, a in zip(xs, taus, acc):
        np.testing.assert_allclose(a, _ref_acceleration(c, x, tau, locked), rtol=1e-10,
                                   atol=1e-10)
    # Locking joints changes the free joints' motion (the inertia they see).
    free = dynamics.links_acceleration(c, xs, taus)
    assert np.abs(free[:, ~held] - acc[:, ~held]).max() > 1e-3


def test_locked_six_links_np_bools(rng):
    c = links_parameters(6)
    locked = np.array([True, False, True, False, False, True])
    x, tau = _states(rng, 6, 1)[0], rng.uniform(-1, 1, 6) * c.tau_max
    a = dynamics.links_acceleration(c, x, tau, locked=locked)
    assert a.shape == (6,) and np.all(a[locked] == 0.0)
    np.testing.assert_allclose(a, _ref_acceleration(c, x, tau, list(locked)), rtol=1e-10,
                               atol=1e-10)


# --------------------------------------------------------------------------- two links
@pytest.mark.parametrize("p", [TABLE_I, TABLE_I.scaled(m2=1.3, l1=0.8, I1=1.5, b2=2.0)])
def test_two_links_equal_full_acceleration(p, rng):
    x = _states(rng, 2, 2000)
    tau = rng.uniform(-1, 1, (2000, 2)) * p.tau_max
    want = dynamics.full_acceleration(p, x, tau)
    np.testing.assert_allclose(dynamics.links_acceleration(p, x, tau), want, rtol=0, atol=1e-12)
    np.testing.assert_allclose(dynamics.links_acceleration(as_links(p), x, tau), want,
                               rtol=0, atol=1e-12)
    np.testing.assert_allclose(dynamics.links_mass_matrix(p, x[:, :2]),
                               dynamics.mass_matrix(p, x[:, 1]), rtol=0, atol=1e-15)
    np.testing.assert_allclose(dynamics.links_bias(p, x), dynamics.coriolis_forces(p, x),
                               rtol=0, atol=1e-14)
    # Agent 1's frozen link 2 of the paper: ddtheta1 = (tau1 - b1 dtheta1) / M11 at rest.
    rest = x * [1, 1, 1, 0]
    a = dynamics.links_acceleration(p, rest, tau, locked=(False, True))
    m11 = p.P1 + p.P2 + 2 * p.P3 * np.cos(x[:, 1])
    np.testing.assert_allclose(a[:, 0], (tau[:, 0] - p.b1 * x[:, 2]) / m11, rtol=1e-13)


def _old_sample_step(accel, p, x, tau, substeps=SUBSTEPS):
    """integrate.sample_step as it was for two links only (hard-coded 4 and 2)."""
    tau = np.clip(tau, -p.tau_max, p.tau_max)
    h = TS / substeps

    def f(s):
        return np.concatenate([s[..., 2:], accel(p, s, tau)], -1)

    for _ in range(substeps):
        k1 = f(x)
        k2 = f(x + 0.5 * h * k1)
        k3 = f(x + 0.5 * h * k2)
        k4 = f(x + h * k3)
        x = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    out = np.empty_like(x)
    out[..., :2] = np.mod(x[..., :2] + np.pi, 2.0 * np.pi) - np.pi
    out[..., 2:] = np.clip(x[..., 2:], -p.speed_max, p.speed_max)
    return out


@pytest.mark.parametrize("name", sorted(dynamics.MODELS))
def test_two_link_sampling_is_bit_identical(name, rng):
    x = _states(rng, 2, 500)
    tau = rng.uniform(-0.3, 0.3, (500, 2))
    accel = dynamics.MODELS[name]
    np.testing.assert_array_equal(sample_step(accel, TABLE_I, x, tau),
                                  _old_sample_step(accel, TABLE_I, x, tau))


# --------------------------------------------------------------------------- sampling
def test_n_link_sampling_shapes_wrap_and_saturate(rng):
    c = links_parameters(3)
    x = _states(rng, 3, 35).reshape(5, 7, 6)
    tau = rng.uniform(-1, 1, (5, 7, 3)) * c.tau_max
    out = sample_step(dynamics.links_acceleration, c, x, tau)
    assert out.shape == (5, 7, 6)
    assert np.all((out[..., :3] >= -np.pi) & (out[..., :3] < np.pi))
    # Broadcasting one state against several torques.
    assert sample_step(dynamics.links_acceleration, c, x[0, 0], tau[0]).shape == (7, 6)
    # Torques beyond the limits are clipped to them.
    np.testing.assert_array_equal(
        sample_step(dynamics.links_acceleration, c, x, np.sign(tau) * c.tau_max * [3, 50, 1e6]),
        sample_step(dynamics.links_acceleration, c, x, np.sign(tau) * c.tau_max))
    # Angles wrap through +-pi.
    fast = np.r_[3.1, -3.1, 0.0, 6.2, -6.2, 0.0]
    end = sample_step(dynamics.links_acceleration, c, fast, c.tau_max * [1, -1, 1])
    assert end[0] < 0 < end[1]
    # At the end of a period speeds saturate at +-speed_max (per joint, or overridden).
    x = np.r_[4.0, -4.0, 1.0, 9.0, -9.0, 1.0]
    np.testing.assert_array_equal(finish_sample(c, x), np.r_[4.0 - 2 * np.pi, -4.0 + 2 * np.pi,
                                                            1.0, 2 * np.pi, -2 * np.pi, 1.0])
    np.testing.assert_array_equal(finish_sample(c, x, speed_max=np.array([1, 2, 0.5]))[3:], [1, -2, 0.5])


def test_n_link_integration_error_is_small(rng):
    c = links_parameters(4)
    x = _states(rng, 4, 50) * np.r_[np.ones(4), 0.5 * np.ones(4)]
    tau = rng.uniform(-1, 1, (50, 4)) * c.tau_max
    err = integration_error(dynamics.links_acceleration, c, x, tau, reference_substeps=100)
    assert len(err["max"]) == len(err["rms"]) == 8
    assert max(err["max"]) < 1e-4


# --------------------------------------------------------------------------- bad input
def test_bad_input_is_refused():
    c = links_parameters(3)
    x, tau = np.zeros(6), np.zeros(3)
    acc = dynamics.links_acceleration
    with pytest.raises(ValueError, match=r"x must have shape \(\.\.\., 6\) for a 3-link arm"):
        acc(c, np.zeros(4), tau)
    with pytest.raises(ValueError, match=r"tau must have shape \(\.\.\., 3\)"):
        acc(c, x, np.zeros(2))
    with pytest.raises(ValueError, match="do not broadcast"):
        acc(c, np.zeros((4, 6)), np.zeros((5, 3)))
    with pytest.raises(ValueError, match="locked must be a sequence of 3 booleans"):
        acc(c, x, tau, locked=(True, False))
    with pytest.raises(ValueError, match="locked must be a sequence of 3 booleans"):
        acc(c, x, tau, locked=(1, 0, 0))
    with pytest.raises(ValueError, match="locked must be a sequence of 3 booleans"):
        acc(c, x, tau, locked="yes")
    with pytest.raises(ValueError, match="locked holds every joint"):
        acc(c, x, tau, locked=(True, True, True))
    with pytest.raises(ValueError, match=r"theta must have shape \(\.\.\., 3\)"):
        dynamics.links_mass_matrix(c, np.zeros(6))
    with pytest.raises(ValueError, match=r"x must have shape \(\.\.\., 4\) for a 2-link"):
        dynamics.links_bias(TABLE_I, x)
    with pytest.raises(ValueError, match=r"states must have shape \(\.\.\., 6\)"):
        sample_step(acc, c, np.zeros(4), tau)
    with pytest.raises(ValueError, match=r"torques must have shape \(\.\.\., 3\)"):
        sample_step(acc, c, x, np.zeros(2))
    with pytest.raises(ValueError, match="the compiled step is for two links"):
        sample_step_compiled("full", c, x, tau)


# --------------------------------------------------------------------------- own motor
def test_own_motor_speed_is_torque_over_damping_within_the_speed_limit():
    c = links_parameters(6, "tapered")
    speed = task.own_motor_speed(c)
    assert speed.shape == (6,)
    np.testing.assert_allclose(speed, np.minimum(np.array(c.tau_max) / np.array(c.dampings),
                                                 c.speed_limits))
    assert speed[-1] == pytest.approx(0.00625 / 0.02)          # the tapered joint 6
    import dataclasses
    free = dataclasses.replace(c, dampings=(1e-4,) * 6)         # light: the speed limit
    np.testing.assert_allclose(task.own_motor_speed(free), c.speed_limits)


def test_a_joint_turned_by_its_own_motor_with_the_rest_held_stays_under_the_bound():
    """The bound on the model itself: joint 6 of the tapered six-link arm at full torque
    from rest, joints 1-5 locked, for 3 s: it approaches tau/b from below and has turned
    less than (tau/b) t."""
    c = links_parameters(6, "tapered")
    bound = task.own_motor_speed(c)[-1]
    locked = (True,) * 5 + (False,)
    tau = np.zeros(6)
    tau[-1] = c.tau_max[-1]
    x = np.zeros(12)
    x[:5] = [0.3, -1.0, 2.0, 0.5, -0.7]                          # any held pose

    def accel(p, s, t):
        return dynamics.links_acceleration(p, s, t, locked=locked)
    steps = int(round(3.0 / TS))
    for _ in range(steps):
        x = sample_step(accel, c, x, tau)
    assert 0.99 * bound < x[-1] < bound
    assert 0 < x[5] < bound * steps * TS
    np.testing.assert_allclose(x[:5], [0.3, -1.0, 2.0, 0.5, -0.7])


def test_own_motor_seconds_per_joint_and_bad_angles():
    c = links_parameters(5, "tapered")
    a = np.deg2rad([[10.0, -20.0, 30.0, 150.0, -150.0], [0, 0, 0, 0, 360.0 + 90.0]])
    t = task.own_motor_seconds(c, a)
    assert t.shape == (2, 5)
    np.testing.assert_allclose(t[0], np.abs(a[0]) / task.own_motor_speed(c))
    assert t[1, -1] == pytest.approx(np.pi / 2 / 0.625)          # wrapped: 450 deg is 90
    with pytest.raises(ValueError, match=r"shape \(\.\.\., 5\)"):
        task.own_motor_seconds(c, np.zeros(4))
    with pytest.raises(ValueError, match="finite"):
        task.own_motor_seconds(c, [0, 0, np.nan, 0, 0])
