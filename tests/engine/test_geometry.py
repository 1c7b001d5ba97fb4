"""prismbatch.geometry against plain references written here (loops, closed forms)."""

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from prismbatch.geometry import (
    AXIS_DOWN,
    ccw,
    centroid_radius,
    convex_hull,
    halfplanes,
    max_radius,
    point_in_prism_residual,
    rotation_with_axis,
    signed_area,
)

angles = st.floats(0.0, 2 * math.pi)
offsets = st.floats(-1e6, 1e6)


def regular(n, r, phase=0.0, centre=(0.0, 0.0)):
    t = phase + 2 * math.pi * np.arange(n) / n
    return np.column_stack([r * np.cos(t) + centre[0], r * np.sin(t) + centre[1]])


@settings(max_examples=50, deadline=None)
@given(n=st.integers(3, 50), r=st.floats(1e-3, 1e3), phase=angles, cx=offsets, cy=offsets)
def test_area_centroid_radius_of_regular_polygons(n, r, phase, cx, cy):
    xy = regular(n, r, phase, (cx, cy))
    area = 0.5 * n * r * r * math.sin(2 * math.pi / n)
    assert math.isclose(signed_area(xy), area, rel_tol=1e-9, abs_tol=1e-9 * (abs(cx) + abs(cy)) ** 2)
    assert math.isclose(signed_area(xy[::-1]), -area, rel_tol=1e-9, abs_tol=1e-9 * (abs(cx) + abs(cy)) ** 2)
    c, rad = centroid_radius(xy)
    np.testing.assert_allclose(c, [cx, cy], atol=1e-9 * (r + abs(cx) + abs(cy)))
    assert math.isclose(rad, r, rel_tol=1e-9, abs_tol=1e-9 * (abs(cx) + abs(cy)))
    assert math.isclose(max_radius(xy, (cx, cy)), r, rel_tol=1e-9, abs_tol=1e-9 * (abs(cx) + abs(cy)))
    np.testing.assert_array_equal(ccw(xy[::-1]), xy)


@settings(max_examples=50, deadline=None)
@given(x=st.floats(-1, 1), y=st.floats(-1, 1), z=st.floats(-1, 1), spin=angles)
def test_rotation_with_axis(x, y, z, spin):
    d = np.array([x, y, z])
    if np.linalg.norm(d) < 1e-3:
        return
    R = rotation_with_axis(d, spin)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-14)
    assert math.isclose(np.linalg.det(R), 1.0, abs_tol=1e-14)
    np.testing.assert_allclose(R[:, 2], d / np.linalg.norm(d), atol=1e-15)
    # spin turns the first column about the axis by the angle
    R0 = rotation_with_axis(d)
    assert math.isclose(R0[:, 0] @ R[:, 0], math.cos(spin), abs_tol=1e-12)
    batch = rotation_with_axis(np.stack([d, -d]), [spin, 0.0])
    np.testing.assert_array_equal(batch[0], R)


def test_axis_down_is_the_papers_frame():
    np.testing.assert_array_equal(AXIS_DOWN[:, 2], [0.0, 0.0, -1.0])
    assert np.linalg.det(AXIS_DOWN) == 1.0


def residual_by_loop(xy, pos, rot, x):
    """max(-t, distance beyond each edge line), one edge at a time."""
    q = np.linalg.solve(rot, np.asarray(x, float) - pos)
    p = xy if sum(xy[i - 1][0] * xy[i][1] - xy[i][0] * xy[i - 1][1] for i in range(len(xy))) > 0 else xy[::-1]
    worst = -q[2]
    for i in range(len(p)):
        a, b = p[i], p[(i + 1) % len(p)]
        e = b - a
        out = (e[1] * (q[0] - a[0]) - e[0] * (q[1] - a[1])) / math.hypot(*e)
        worst = max(worst, out)
    return worst


@settings(max_examples=100, deadline=None)
@given(n=st.integers(3, 12), phase=angles, seed=st.integers(0, 2**32 - 1))
def test_point_in_prism_residual_and_halfplanes(n, phase, seed):
    rng = np.random.default_rng(seed)
    xy = regular(n, 1.5, phase, rng.uniform(-2, 2, 2))[:: rng.choice([1, -1])]
    pos = rng.uniform(-3, 3, 3)
    rot = rotation_with_axis(rng.normal(size=3), rng.uniform(0, 6))
    for _ in range(5):
        x = pos + rng.uniform(-3, 3, 3)
        assert math.isclose(point_in_prism_residual(xy, pos, rot, x), residual_by_loop(xy, pos, rot, x), abs_tol=1e-12)
    nrm, h = halfplanes(xy)
    assert len(h) == n
    np.testing.assert_allclose(nrm @ np.mean(xy, axis=0) - h, -1.5 * math.cos(math.pi / n) * np.ones(n), atol=1e-12)


def _turn_exact(o, a, b):
    from fractions import Fraction as F

    v = (F(a[0]) - F(o[0])) * (F(b[1]) - F(o[1])) - (F(a[1]) - F(o[1])) * (F(b[0]) - F(o[0]))
    return (v > 0) - (v < 0)


def _is_strict_hull_of(hull, points):
    """Plain reference: hull vertices are input points, every turn is strictly left (exact), and
    no input point lies strictly outside an edge (exact)."""
    pts = {tuple(p) for p in np.asarray(points, float).tolist()}
    h = [tuple(p) for p in hull.tolist()]
    if not all(p in pts for p in h):
        return False
    m = len(h)
    if any(_turn_exact(h[i], h[(i + 1) % m], h[(i + 2) % m]) <= 0 for i in range(m)):
        return False
    return all(_turn_exact(h[i], h[(i + 1) % m], q) >= 0 for i in range(m) for q in pts)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(3, 60), scale=st.sampled_from([1e-9, 1.0, 1e9]))
def test_convex_hull_is_the_strict_hull(seed, n, scale):
    pts = np.random.default_rng(seed).normal(size=(n, 2)) * scale
    assert _is_strict_hull_of(convex_hull(pts), pts)


def test_convex_hull_of_nearly_collinear_points_decides_turns_exactly():
    # Points a few ulps off a long line: float cross products cannot tell the turns apart.
    x = np.linspace(0.0, 1.0, 41)
    y = 1e-17 * np.random.default_rng(3).integers(-2, 3, size=41)
    pts = np.column_stack([x, 0.1 + x * 0.3 + y])
    pts = np.vstack([pts, [[0.5, -1.0]]])
    assert _is_strict_hull_of(convex_hull(pts), pts)
    assert len(convex_hull([[0.0, 0.0], [1.0, 1.0]])) == 2  # fewer than 3 points: as given


def test_halfplanes_keep_the_edges_of_a_small_polygon_far_from_the_origin():
    """Edges are skipped relative to the polygon's extent, not to its distance from the origin: a 0.006
    chamfer at 1e12 was dropped, and a point 1.6e-3 outside it was called inside."""
    from prismbatch.geometry import halfplanes, point_in_prism_residual

    off = 1e12
    cham = np.array([[0.005, 0], [0.05, 0], [0.05, 0.05], [0, 0.05], [0, 0.003]]) + off
    assert len(halfplanes(cham)[0]) == 5
    outside = np.array([off + 0.001, off + 0.0005, 1.0])  # below the chamfer's line
    assert point_in_prism_residual(cham, np.zeros(3), np.eye(3), outside) > 1e-3
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]]) * 1e-3 + off
    assert point_in_prism_residual(square, np.zeros(3), np.eye(3), [off, off, 1.0]) <= 1e-3 * 1e-3


def test_rotation_with_axis_takes_any_finite_nonzero_axis():
    """Axes of 1e200 or 1e-200 components give the same rotation as unit ones (their norm overflowed to a
    singular matrix, or underflowed to NaN); zero or non-finite axes are refused by name."""
    import pytest

    from prismbatch.geometry import rotation_with_axis

    want = rotation_with_axis([1.0, 1.0, 0.0], 0.3)
    for s in (1e200, 1e-200):
        np.testing.assert_allclose(rotation_with_axis([s, s, 0.0], 0.3), want, rtol=0, atol=1e-15)
    for d in ([0.0, 0.0, 0.0], [np.inf, 0.0, 0.0], [[0.0, 0.0, 1.0], [np.nan, 0.0, 0.0]]):
        with pytest.raises(ValueError, match="is not a direction"):
            rotation_with_axis(d)


def test_row_norms_match_the_plain_formula_and_reach_the_ends_of_the_range():
    """Bit for bit the plain sqrt of the sum of squares where those squares are representable (the rows are
    scaled by a power of two, exactly); hypot's answer where they overflow or underflow."""
    from prismbatch.geometry import row_norms

    rng = np.random.default_rng(5)
    x = rng.normal(size=(2000, 3)) * 10.0 ** rng.uniform(-100, 100, (2000, 1))
    np.testing.assert_array_equal(row_norms(x), np.sqrt(np.square(x).sum(axis=1)))
    far = np.array([[3e200, 4e200], [3e-200, 4e-200], [0.0, 0.0], [1e308, 1e307]])
    np.testing.assert_allclose(row_norms(far), np.hypot(far[:, 0], far[:, 1]), rtol=1e-15)
    assert row_norms([[1.7e308, 1.7e308]])[0] == np.inf  # the norm itself is beyond float64
