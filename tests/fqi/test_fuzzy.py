"""Triangular memberships (13), circular angle bins and product grids (12)."""
import math

import numpy as np
import pytest

from twolink.fqi.fuzzy import (
    ANGLE_BINS_DEG,
    SPEED_BINS_DEG,
    Axis,
    Grid,
    angle_axis,
    speed_axis,
    torque_axis,
)


def _eq13(c, v, n):
    """Membership (13) of v in bin n (0-based) of a clamped axis, as printed."""
    N = len(c)
    if n == 0:
        return max(0.0, (c[1] - v) / (c[1] - c[0]))
    if n == N - 1:
        return max(0.0, (v - c[N - 2]) / (c[N - 1] - c[N - 2]))
    return max(0.0, min((v - c[n - 1]) / (c[n] - c[n - 1]), (c[n + 1] - v) / (c[n + 1] - c[n])))


def test_speed_memberships_follow_eq_13(rng):
    ax = speed_axis("dtheta2")
    c = ax.centers
    for v in rng.uniform(c[0], c[-1], 300):
        expected = [_eq13(c, v, n) for n in range(len(c))]
        np.testing.assert_allclose(ax.dense(v), expected, atol=1e-12)


def test_bins_of_the_paper():
    assert angle_axis("t").size == 12 and speed_axis("s").size == 7
    np.testing.assert_allclose(np.rad2deg(angle_axis("t").centers), ANGLE_BINS_DEG)
    np.testing.assert_allclose(np.rad2deg(speed_axis("s").centers), SPEED_BINS_DEG)
    np.testing.assert_allclose(torque_axis("tau2", 0.1).centers, [-0.1, 0.0, 0.1])


def test_memberships_are_a_partition_of_unity(rng):
    for ax in (angle_axis("t"), speed_axis("s")):
        v = rng.uniform(-10, 10, 1000)
        idx, w = ax.memberships(v)
        np.testing.assert_allclose(w.sum(-1), 1.0)
        assert np.all(w >= 0) and np.all(idx >= 0) and np.all(idx < ax.size)
        # one-hot at the centres
        np.testing.assert_allclose(ax.dense(np.asarray(ax.centers)), np.eye(ax.size), atol=1e-12)


def test_angle_axis_is_circular():
    ax = angle_axis("t")
    # 155 deg lies halfway between the last centre (130) and 180 == -180 (the first).
    d = ax.dense(math.radians(155.0))
    assert d[-1] == pytest.approx(0.5) and d[0] == pytest.approx(0.5)
    np.testing.assert_allclose(ax.dense(math.pi), ax.dense(-math.pi), atol=1e-12)
    np.testing.assert_allclose(ax.dense(0.3 + 2 * math.pi), ax.dense(0.3), atol=1e-12)


def test_speed_axis_is_clamped():
    ax = speed_axis("s")
    np.testing.assert_allclose(ax.dense(-100.0), np.eye(7)[0])
    np.testing.assert_allclose(ax.dense(100.0), np.eye(7)[-1])


def test_grid_memberships_are_sparse_products(rng):
    g = Grid((angle_axis("a"), angle_axis("b"), speed_axis("c"), speed_axis("d")))
    pts = rng.uniform(-4, 4, (100, 4))
    idx, w = g.memberships(pts)
    assert idx.shape == (100, 16) and w.shape == (100, 16)
    np.testing.assert_allclose(w.sum(-1), 1.0)
    for p, i_row, w_row in zip(pts[:10], idx[:10], w[:10]):
        dense = np.einsum("i,j,k,l->ijkl", *[ax.dense(v) for ax, v in zip(g.axes, p)]).ravel()
        sparse = np.zeros(g.size)
        np.add.at(sparse, i_row, w_row)
        np.testing.assert_allclose(sparse, dense, atol=1e-12)
    # bin centres in flat-index order
    np.testing.assert_allclose(g.memberships(g.centers()[123])[1].max(), 1.0)
    assert g.memberships(g.centers()[123])[0][np.argmax(g.memberships(g.centers()[123])[1])] == 123


def test_axis_and_grid_refuse_bad_input():
    with pytest.raises(ValueError, match="increase"):
        Axis("x", (0.0, 0.0, 1.0))
    with pytest.raises(ValueError, match="shape"):
        Grid((speed_axis("s"),)).memberships(np.zeros((3, 2)))


def test_refined_axis_keeps_centres_and_subdivides():
    a, s = angle_axis("theta1"), speed_axis("dtheta1")
    assert a.refined(1) == a and s.refined(1) == s
    a2, s3 = a.refined(2), s.refined(3)
    assert a2.size == 24 and a2.circular and s3.size == 19
    assert set(a.centers) <= set(a2.centers)
    np.testing.assert_allclose(s3.centers[::3], s.centers, rtol=0, atol=1e-12)
    assert a2.centers[-1] == pytest.approx((a.centers[-1] + a.centers[0] + 2 * np.pi) / 2)
    with pytest.raises(ValueError, match="positive integer"):
        a.refined(0)
