"""``prismbatch.distance``: the signed distance of two semi-infinite prisms, against independent references.

The references (``prismbatch/lab/distance_ref.py``) share no code with the kernels: the separating-axis
value over every candidate axis (exactly minus the depth when the bodies overlap), the gap by brute
force over feature pairs, and a QP by HiGHS with its optimality certificate. Every comparison is in
units of the pair tolerance ``tol`` (the one ``collide`` uses); the contract checked is

* ``|distance - reference| <= 10 tol``;
* witnesses: ``normal`` unit, ``point_b - point_a = distance * normal``, both points on their
  body's boundary to within tol (the half-space residual);
* the sign agrees with ``collide(...).hit`` outside the touching band ``|reference| <= 2 tol``;
* status: 1 beyond tol, 0 within it, -1 below -tol.

Recorded pairs (regressions found by review and mutation testing) are in ``test_distance_recorded.py``,
the API (pose forms, threads, dtypes, the result object, errors) in ``test_distance_api.py``.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

import prismbatch as pb
from prismbatch.distance import (
    PENETRATING,
    PLANAR_GAP,
    SEPARATED,
    TOUCHING,
    distance,
)
from prismbatch.geometry import pair_scale_tolerance
from prismbatch.lab.distance_ref import Body, residual, sat_separation, signed_distance_of
from prismbatch.sampling import free_poses

from helpers import (
    R_DOWN,
    bisect_to_contact,
    distance_with_witnesses,
    family_polygon,
    make_pairs,
    overlapping_pairs,
    pairs_from_rows,
    perpendicular_pairs,
    polygon_centre,
    polygon_radius,
    random_polygon,
    random_rotations,
    rot_z,
    sample_vertex_count,
    separating_directions,
    vertical_pairs,
)

EPS = np.finfo(np.float64).eps


def reference(d, pos_b=None):
    """Reference signed distances and the two reference bodies of every pair."""
    pos_b = d.pos_b if pos_b is None else pos_b
    out, bodies = [], []
    for k in range(len(d)):
        A, B = Body(d.polys_a[k], d.pos_a[k], d.rot_a[k]), Body(d.polys_b[k], pos_b[k], d.rot_b[k])
        out.append(signed_distance_of(A, B)[0])
        bodies.append((A, B))
    return np.array(out), bodies


def check(label, d, pos_b=None, *, coordinate_rounding=False):
    """Run ``distance`` and assert the whole contract against the reference; return (result, ref)."""
    r = distance_with_witnesses(d, pos_b)
    ref, bodies = reference(d, pos_b)
    tol = r.tol
    err = np.abs(r.distance - ref) / tol
    assert err.max() <= 10, f"{label}: |distance - reference| up to {err.max():.3g} tol (pair {err.argmax()})"
    status = np.where(r.distance > tol, SEPARATED, np.where(r.distance < -tol, PENETRATING, TOUCHING))
    np.testing.assert_array_equal(r.status, status)
    np.testing.assert_allclose(np.linalg.norm(r.normal, axis=1), 1.0, rtol=0, atol=1e-12)
    scale = np.abs(r.point_a).max(axis=1) + np.abs(r.distance)
    gap_vec = r.point_b - r.point_a - r.distance[:, None] * r.normal
    assert (np.abs(gap_vec).max(axis=1) <= 4 * EPS * scale).all(), f"{label}: point_b - point_a != distance n"
    # On the boundary: the largest violated half-space is ~0 (negative inside, positive outside).
    res = np.array(
        [[residual(A, r.point_a[k][None])[0], residual(B, r.point_b[k][None])[0]] for k, (A, B) in enumerate(bodies)]
    )
    allowed = tol + (64 * EPS * np.abs(r.point_a).max(axis=1) if coordinate_rounding else 0.0)
    bad = np.abs(res).max(axis=1) > allowed
    assert not bad.any(), f"{label}: witnesses off their bodies, pairs {np.flatnonzero(bad)[:5]}: {res[bad][:5]}"
    hit = pb.collide(pb.PrismSet(d.polys_a), pb.PrismSet(d.polys_b), d.pos_a, d.rot_a,
                     d.pos_b if pos_b is None else pos_b, d.rot_b).hit  # fmt: skip
    clear = np.abs(ref) > 2 * tol
    wrong = clear & ((ref < 0) != hit)
    assert not wrong.any(), f"{label}: sign disagrees with collide on pairs {np.flatnonzero(wrong)[:5]}"
    return r, ref


# ---------------------------------------------------------------------------
# random poses
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("pose_set", ["facing", "free"])
@pytest.mark.parametrize("family", ["small", pytest.param("medium", marks=pytest.mark.slow)])
def test_random_poses_match_the_reference(pose_set, family):
    rng = np.random.default_rng({"facing": 1, "free": 2}[pose_set] * 10 + len(family))
    d = make_pairs(rng, 150, pose_set, family)
    r, ref = check(f"{pose_set}/{family}", d)
    assert 0.1 < np.mean(ref < 0) < 0.9  # both signs are exercised
    assert (r.solver <= 1).all()  # every pair converged (GJK gap or EPA depth)


@pytest.mark.parametrize("family", ["skinny", pytest.param("collinear", marks=pytest.mark.slow)])
@pytest.mark.parametrize("pose_set", ["facing", "free"])
def test_skinny_and_collinear_polygons_match_the_reference(pose_set, family):
    """Polygons squashed to an aspect ratio of 1e-5 to 0.1, and dense collinear ones (3- to 7-gons with up
    to 59 more vertices on every edge: the reference takes about 10 s for 40 such pairs)."""
    rng = np.random.default_rng({"facing": 7, "free": 6}[pose_set] * 10 + len(family))  # (seed 59: a refused polygon)
    d = make_pairs(rng, 80 if family == "skinny" else 40, pose_set, family)
    r, ref = check(f"{pose_set}/{family}", d)
    assert (ref < 0).any() and (ref > 0).any()
    assert (r.solver <= 1).all()


@pytest.mark.slow
def test_large_polygons_match_the_reference():
    """A few hundred vertices on both sides, regular and irregular."""
    rng = np.random.default_rng(3)
    rows = []
    for k in range(24):
        A = random_polygon(rng, int(rng.integers(200, 400)), regular=bool(k % 2))
        B = random_polygon(rng, int(rng.integers(200, 400)), regular=not k % 2)
        Ra, Rb = random_rotations(rng, 2) if k % 3 else (R_DOWN, rot_z(rng.uniform(0, 6.3)))
        pa = rng.uniform(-1, 1, 3)
        cb = pa + Ra[:, :2] @ polygon_centre(A) + rng.uniform(-1, 1, 3) * 1.5 * (polygon_radius(A) + polygon_radius(B))
        rows.append((A, B, pa, Ra, cb - Rb[:, :2] @ polygon_centre(B), Rb))
    check("large", pairs_from_rows(rows))


def test_3600_gons_are_consistent():
    """The paper's 3600-vertex end faces: no reference at this size, but touching after the move,
    agreement with collide, and the distance of the 360-gon's prisms to within their difference."""
    rng = np.random.default_rng(4)
    n = 200
    a, b = pb.Prism.regular(3600, 2.0), pb.Prism.regular(3600, 2.5)
    ra, rb = random_rotations(rng, n), random_rotations(rng, n)
    pa, pb_ = rng.uniform(-1, 1, (n, 3)), rng.uniform(-1, 1, (n, 3)) * 5
    r = distance(a, b, pa, ra, pb_, rb, witness=True)
    assert (r.solver <= 1).all()
    hit = pb.collide(a, b, pa, ra, pb_, rb).hit
    clear = np.abs(r.distance) > 2 * r.tol
    assert np.array_equal(hit[clear], r.distance[clear] < 0)
    moved = distance(a, b, pa, ra, pb_ - r.distance[:, None] * r.normal, rb)
    assert (np.abs(moved.distance) <= moved.tol).all()
    # Inscribed 3600-gon vs circumscribed: the polygons differ by at most R (1 - cos(pi / 3600)).
    a2, b2 = pb.Prism.regular(360, 2.0), pb.Prism.regular(360, 2.5)
    r2 = distance(a2, b2, pa, ra, pb_, rb)
    assert (np.abs(r2.distance - r.distance) <= 4.5 * (1 - np.cos(np.pi / 360)) + 10 * r.tol).all()


# ---------------------------------------------------------------------------
# special relative poses
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("mode", ["generic", "vertex", "edge"])
@pytest.mark.parametrize("depression", [0.0, 1e-3])
def test_perpendicular_axes(mode, depression):
    rng = np.random.default_rng(7 + len(mode) + int(depression > 0))
    check(f"perpendicular/{mode}", perpendicular_pairs(rng, 80, mode, depression=depression))


@pytest.mark.parametrize("relation", ["parallel", "antiparallel"])
@pytest.mark.parametrize("height", ["coplanar", "random"])
def test_exactly_parallel_and_antiparallel_axes(relation, height):
    """Identical axes (rotations about z only) and exactly opposite ones, with the analytic gap."""
    rng = np.random.default_rng(11 + len(relation) + len(height))
    d, gap = vertical_pairs(rng, 120, relation, height)
    r, ref = check(f"{relation}/{height}", d)
    sep = ref > 2 * r.tol
    np.testing.assert_allclose(r.distance[sep], gap[sep], rtol=0, atol=10 * r.tol.max())


def test_identical_rotation_matrices():
    """One rotation matrix for both bodies (the axes are exactly parallel), side by side and overlapping."""
    rng = np.random.default_rng(13)
    rows = []
    for _ in range(120):
        A = random_polygon(rng, sample_vertex_count(rng, "smallmed"))
        B = random_polygon(rng, sample_vertex_count(rng, "smallmed"))
        R = Rotation.random(random_state=rng).as_matrix()
        pa = rng.uniform(-2, 2, 3)
        ca = pa + R[:, :2] @ polygon_centre(A)
        off = R @ np.array([*rng.uniform(-1.2, 1.2, 2) * (polygon_radius(A) + polygon_radius(B)), rng.uniform(-2, 2)])
        rows.append((A, B, pa, R, ca + off - R[:, :2] @ polygon_centre(B), R))
    r, ref = check("identical rotations", pairs_from_rows(rows))
    assert 0.2 < np.mean(ref < 0) < 0.8


@pytest.mark.slow  # the full suite; the fast set keeps a lighter test of the same path
def test_planar_depth_of_parallel_axes_against_the_reference():
    """The planar depth that takes over where EPA stops on exactly parallel, same-way axes, called
    directly on overlapping identical-rotation pairs of random polygons (3 to 3600 vertices): the
    depth against the separating-axis reference, the normal unit, both witnesses on their bodies."""
    from prismbatch._kernels.batch import centres_world
    from prismbatch._kernels.parallel import parallel_overlap

    rng = np.random.default_rng(17)
    checked = 0
    for _ in range(150):
        A = random_polygon(rng, sample_vertex_count(rng, "smallmed" if checked % 6 else "large"))
        B = random_polygon(rng, sample_vertex_count(rng, "smallmed"))
        R = Rotation.random(random_state=rng).as_matrix()
        pa = rng.uniform(-2, 2, 3)
        pa_c, pb_c = polygon_centre(A), polygon_centre(B)
        off = R @ np.array([*rng.uniform(-0.6, 0.6, 2) * (polygon_radius(A) + polygon_radius(B)), rng.uniform(-2, 2)])
        pb_ = pa + R[:, :2] @ pa_c + off - R[:, :2] @ pb_c
        Pa_, Pb_ = Body(A, pa, R), Body(B, pb_, R)
        sep, _ = sat_separation(Pa_, Pb_)
        if sep >= 0:
            continue
        sa, sb = (pb.PrismSet([X]).kernel_arrays(np.float64) for X in (A, B))
        P = (sa.vx, sa.vy, sa.edge_angle, sa.edge_table, sb.vx, sb.vy, sb.edge_angle, sb.edge_table)
        o_d = centres_world(sa.centre[0, 0], sa.centre[0, 1], sb.centre[0, 0], sb.centre[0, 1], pa, R, pb_, R)
        depth, n, x = parallel_overlap(P, (0, len(sa.vx), 0, len(sb.vx)), R, R, *o_d)
        n, x = np.array(n), np.array(x)
        tol = pair_scale_tolerance(pb.Prism(A), pb.Prism(B), pa[None], R[None], pb_[None], R[None])[1][0]
        assert abs(-depth - sep) <= 10 * tol, (checked, -depth, sep)
        assert abs(np.linalg.norm(n) - 1) < 1e-12 and abs(n @ R[:, 2]) < 1e-12
        res_a, res_b = residual(Pa_, x[None])[0], residual(Pb_, (x - depth * n)[None])[0]
        assert abs(res_a) <= tol and abs(res_b) <= tol, (checked, res_a / tol, res_b / tol)
        checked += 1
    assert checked > 60


def _planar_polygon_distance(P, Q):
    """Plain reference: the distance of two disjoint convex polygons (k, 2), the least distance of a
    vertex of one to an edge of the other."""

    def vertex_to_edges(V, W):
        a, b = W, np.roll(W, -1, axis=0)
        e = b - a
        t = np.clip(np.einsum("vej,ej->ve", V[:, None, :] - a[None], e) / np.einsum("ej,ej->e", e, e), 0, 1)
        return np.linalg.norm(a[None] + t[..., None] * e[None] - V[:, None, :], axis=2).min()

    return min(vertex_to_edges(P, Q), vertex_to_edges(Q, P))


def _solve_exactly(R, d):
    """x with R x = d in rational arithmetic (Cramer's rule on the float matrix as given)."""
    M = [[Fraction(v) for v in row] for row in R]

    def det(m):
        return (
            m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
        )

    D = det(M)
    return [det([[d[i] if j == c else M[i][j] for j in range(3)] for i in range(3)]) / D for c in range(3)]


def test_gap_of_exactly_parallel_axes_against_the_reference():
    """Separated pairs with exactly parallel axes, pointing the same way (the same rotation) or opposite
    ways (b's rotation a's with its y and z columns negated), the end faces apart in the plane by 1e-6 to
    1 of their size: the gap (solver PLANAR_GAP) is the end faces' planar distance, and opposite ways also
    their distance along the axes in quadrature, against a plain vertex-to-edge reference in a's plane;
    witnesses on their bodies and point_b - point_a = distance * normal. Sizes 1 to 1e5 apart, the larger
    polygon up to 1e8 from its own origin (where GJK on the box-cut difference stalled 3.2 tol off)."""
    rng = np.random.default_rng(29)
    checked = [0, 0]
    for k in range(160):
        A = random_polygon(rng, sample_vertex_count(rng, "smallmed" if k % 5 else "large"))
        B = random_polygon(rng, sample_vertex_count(rng, "smallmed")) * 10.0 ** rng.uniform(0, 5 if k % 2 else 0)
        B = B + (10.0 ** rng.uniform(0, 8) if k % 3 == 0 else 0.0) * rng.normal(size=2)  # far from its origin
        R = Rotation.random(random_state=rng).as_matrix()
        facing = k % 4 >= 2
        flip = np.array([1.0, -1.0]) if facing else np.ones(2)  # b's in-plane axes seen from a
        Rb = R * np.array([1.0, -1.0, -1.0]) if facing else R
        ca, cb = polygon_centre(A), polygon_centre(B)
        ra, rb = polygon_radius(A), polygon_radius(B)
        u = rng.normal(size=2)
        u /= np.linalg.norm(u)
        # b's centre in a's plane beyond the sum of the radii along u, then moved back to a gap of
        # about 10^-6..1 of the size along u (planar distance known only to the reference)
        shift = ((A - ca) @ u).max() - (((B - cb) * flip) @ u).min() + 10.0 ** rng.uniform(-6, 0) * (ra + rb)
        off = shift * u + rng.uniform(-0.3, 0.3) * (ra + rb) * np.array([-u[1], u[0]])
        pa = rng.uniform(-2, 2, 3)
        pb_ = pa + R[:, :2] @ ca + R @ np.array([*off, rng.uniform(-2, 2) * (ra + rb)]) - Rb[:, :2] @ cb
        # the reference in a's frame, about a's centre; b's origin there, R^-1 (pb_ - pa), solved exactly
        # (pb_ holds R cb, up to 1e8, whose rounding would move the reference by eps |R cb|)
        x, y, z = _solve_exactly(R, [Fraction(v) - Fraction(w) for v, w in zip(pb_, pa)])
        ka = (Fraction(ca[0]), Fraction(ca[1]))
        Bpl = np.array([[float(Fraction(u) + x - ka[0]), float(Fraction(v) + y - ka[1])] for u, v in B * flip])
        rise = max(0.0, -float(z)) if facing else 0.0  # facing end faces apart along the axes (a's at 0)
        ref = math.hypot(_planar_polygon_distance(A - ca, Bpl), rise)
        r = pb.distance(pb.Prism(A), pb.Prism(B), pa, R, pb_, Rb, witness=True)
        tol = r.tol[0]
        if ref <= 2 * tol:  # touching or nearly: the reference's own rounding is then too close
            continue
        assert r.solver[0] == PLANAR_GAP and r.status[0] == 1, (k, r.solver[0])
        assert abs(r.distance[0] - ref) <= 0.01 * tol + 1e-12 * (ra + rb), (k, r.distance[0], ref, tol)
        np.testing.assert_allclose(r.point_b[0] - r.point_a[0], r.distance[0] * r.normal[0], atol=tol)
        assert abs(residual(Body(A, pa, R), r.point_a[:1])[0]) <= tol, k
        assert abs(residual(Body(B, pb_, Rb), r.point_b[:1])[0]) <= tol, k
        checked[facing] += 1
    assert min(checked) > 50, checked


@pytest.mark.slow  # the full suite; the fast set keeps a lighter test of the same path
def test_depth_of_nearly_parallel_axes_against_the_reference():
    """The separating-axis depth that takes over where EPA stops on nearly parallel, same-way axes,
    called directly on tilted pairs (tilts 1e-12 to 0.3 rad, and none) of random, dense nearly
    collinear and skinny polygons, and at any angle below 90 degrees: its value against the reference's
    separating-axis value where they overlap (minus the depth), no larger where they are apart, and its
    normal unit."""
    from prismbatch._kernels.batch import centres_world
    from prismbatch._kernels.parallel import tilted_overlap

    rng = np.random.default_rng(23)
    overlaps = 0
    for k in range(300):
        family = ("smallmed", "collinear", "skinny")[k % 3]
        A, B = family_polygon(rng, family), family_polygon(rng, "smallmed")
        Ra = Rotation.random(random_state=rng).as_matrix()
        tilt = 10 ** rng.uniform(-12, -0.5) if k % 8 else 0.0
        if k % 5 == 4:  # any angle below 90 degrees (every pair of end edges a candidate)
            tilt = rng.uniform(0.3, 1.5)
        ax = rng.normal(size=3)
        ax -= (ax @ Ra[:, 2]) * Ra[:, 2]
        Rb = Rotation.from_rotvec(ax / np.linalg.norm(ax) * tilt).as_matrix() @ Ra @ rot_z(rng.uniform(0, 6.3))
        pa = rng.uniform(-2, 2, 3)
        off = Ra @ np.array([*rng.uniform(-0.7, 0.7, 2) * (polygon_radius(A) + polygon_radius(B)), rng.uniform(-2, 2)])
        pb_ = pa + Ra[:, :2] @ polygon_centre(A) + off - Rb[:, :2] @ polygon_centre(B)
        sep, _ = sat_separation(Body(A, pa, Ra), Body(B, pb_, Rb))
        sa, sb = (pb.PrismSet([X]).kernel_arrays(np.float64) for X in (A, B))
        P = (sa.vx, sa.vy, sa.edge_angle, sa.edge_table, sb.vx, sb.vy, sb.edge_angle, sb.edge_table)
        o_d = centres_world(sa.centre[0, 0], sa.centre[0, 1], sb.centre[0, 0], sb.centre[0, 1], pa, Ra, pb_, Rb)
        e = Rb[:, 2] - Ra[:, 2]
        value, n = tilted_overlap(P, (0, len(sa.vx), 0, len(sb.vx)), Ra, Rb, *o_d[3:], *e)
        n = np.array(n)
        tol = pair_scale_tolerance(pb.Prism(A), pb.Prism(B), pa[None], Ra[None], pb_[None], Rb[None])[1][0]
        # the reference's axes hold these; apart, the largest separation need not be along a facet
        # normal of D (the gap may be attained at an edge or vertex of D): then only a lower bound
        assert (abs(value - sep) if sep < 0 else value - sep) <= 10 * tol, (k, family, tilt, value, sep)
        assert abs(np.linalg.norm(n) - 1) < 1e-12
        overlaps += sep < 0
    assert overlaps > 180


def _tilted(rng, n, tilt, facing):
    """b's axis parallel (or antiparallel) to a's, tilted by ``tilt`` about a random axis across it."""
    rows = []
    for _ in range(n):
        A = random_polygon(rng, sample_vertex_count(rng, "smallmed"))
        B = random_polygon(rng, sample_vertex_count(rng, "smallmed"))
        Ra = Rotation.random(random_state=rng).as_matrix()
        ax = rng.normal(size=3)
        ax -= (ax @ Ra[:, 2]) * Ra[:, 2]
        Rt = Rotation.from_rotvec(ax / np.linalg.norm(ax) * tilt).as_matrix()
        Rb = Rt @ Ra @ (R_DOWN if facing else np.eye(3)) @ rot_z(rng.uniform(0, 2 * np.pi))
        pa = rng.uniform(-1, 1, 3)
        ra, rb = polygon_radius(A), polygon_radius(B)
        cb = (
            pa
            + Ra[:, :2] @ polygon_centre(A)
            + Ra @ np.array([*rng.uniform(-1.2, 1.2, 2), rng.uniform(-1, 1)]) * (ra + rb)
        )
        rows.append((A, B, pa, Ra, cb - Rb[:, :2] @ polygon_centre(B), Rb))
    return pairs_from_rows(rows)


@pytest.mark.parametrize(
    "tilt", [pytest.param(1e-2, marks=pytest.mark.slow), pytest.param(1e-5, marks=pytest.mark.slow), 1e-8, 1e-13, 1e-16]
)
@pytest.mark.parametrize("facing", [False, True])
def test_nearly_parallel_axes(tilt, facing):
    """Axes that (nearly) point the same way meet or pass at about gap / tilt from the end faces: the
    distance and normal stay exact, the witness points lie out there and carry the rounding of their
    own coordinates."""
    rng = np.random.default_rng(int(-np.log10(tilt)) + 40 * facing)
    r, ref = check(f"tilt {tilt:g}, facing={facing}", _tilted(rng, 80, tilt, facing), coordinate_rounding=True)
    assert 0.1 < np.mean(ref < 0) < 0.9


# ---------------------------------------------------------------------------
# near contact, and scale
# ---------------------------------------------------------------------------


@pytest.mark.slow  # the fast set: the small random families and the recorded cases
@pytest.mark.parametrize("pose_set", ["facing", "free"])
def test_near_contact(pose_set):
    """Pairs bisected to touching (by collide), then moved in or out by 0.1 to 1e4 tol."""
    rng = np.random.default_rng(17 + len(pose_set))
    d = overlapping_pairs(rng, 150, pose_set)
    sa, sb = pb.PrismSet(d.polys_a), pb.PrismSet(d.polys_b)
    far = 3 * d.scale
    u, ok = separating_directions(rng, sa, sb, d, far)
    lo, hi = bisect_to_contact(sa, sb, d, u, far)
    tol = distance(sa, sb, *d.args()).tol
    step = rng.choice([-1.0, 1.0], len(d)) * 10 ** rng.uniform(-1, 4, len(d)) * tol
    pos_b = d.pos_b + (0.5 * (lo + hi) + step)[:, None] * u
    keep = np.flatnonzero(ok)
    r, ref = check(f"near contact/{pose_set}", d.subset(keep), pos_b[keep])
    assert (r.status == TOUCHING).sum() >= 5 and (r.status == SEPARATED).sum() >= 20
    assert (r.status == PENETRATING).sum() >= 20


@pytest.mark.parametrize("size, offset", [(1e-6, 1e6), (1e-3, 1e3), (1e3, 1e-3)])
def test_tiny_and_huge_objects_far_from_the_origin(size, offset):
    rng = np.random.default_rng(int(np.log10(size)) + 50)
    d = make_pairs(rng, 80, "free", "small")
    d.polys_a = [p * size for p in d.polys_a]
    d.polys_b = [p * size for p in d.polys_b]
    d.pos_a, d.pos_b = d.pos_a * size + offset, d.pos_b * size + offset
    r, _ = check(f"size {size:g} at {offset:g}", d)
    base = distance_with_witnesses(make_pairs(np.random.default_rng(int(np.log10(size)) + 50), 80, "free", "small"))
    np.testing.assert_allclose(r.distance, size * base.distance, rtol=0, atol=10 * r.tol.max())


def test_identical_float32_rotations_in_float64_against_the_exact_gap():
    """Float32 rotation matrices (orthonormal to ~1e-7) given to the float64 path, the same matrix for a and b:
    exactly parallel axes, whose planar answers (.parallel) measure lengths in a's frame. Those lengths were up
    to 13 tol off the world's here; such pairs go to GJK and EPA, which work in world coordinates. Checked
    against the exact gap (rational arithmetic) and the margin query against it."""
    from prismbatch.lab.exact_gap import gap_bounds

    rng = np.random.default_rng(44)
    a, b = pb.Prism.regular(5, 1.0), pb.Prism.regular(6, 1.3, phase=0.2)
    rot = Rotation.random(12, random_state=3).as_matrix().astype(np.float32)
    pos_a = rng.uniform(-3, 3, (12, 3)).astype(np.float32)
    pos_b = (pos_a + rng.uniform(-4, 4, (12, 3))).astype(np.float32)
    r = pb.distance(a, b, pos_a, rot, pos_b, rot, witness=True)
    apart = np.flatnonzero(r.status == SEPARATED)
    assert len(apart) >= 6
    for i in apart:
        args = (a.xy, pos_a[i].astype(float), rot[i].astype(float), b.xy, pos_b[i].astype(float), rot[i].astype(float))
        g = gap_bounds(*args)
        lo, hi = math.sqrt(g.lo), math.sqrt(g.hi)
        assert lo - 10 * r.tol[i] <= r.distance[i] <= hi + 10 * r.tol[i], i
        for pt, xy, p in ((r.point_a[i], a.xy, pos_a[i]), (r.point_b[i], b.xy, pos_b[i])):
            assert pb.geometry.point_in_prism_residual(xy, p.astype(float), rot[i].astype(float), pt) <= r.tol[i]
        for m, want in ((lo + 3 * r.tol[i], True), (hi - 3 * r.tol[i], False)):
            assert pb.collide(a, b, pos_a[i], rot[i], pos_b[i], rot[i], margin=m).hit[0] == want, i


@pytest.mark.parametrize("scale", [2.0**-330, 1e-99, 1e-80, 1e80, 1e99, 2.0**328])
def test_scales_at_the_ends_of_the_accepted_range(scale):
    """Shapes and positions scaled towards 1e-100 and 1e100 (sizes the API accepts): the distance, its
    witnesses, the margin query and the time of impact scale with them. GJK's and EPA's cross products
    reach the size^4, which overflowed beyond about 1e76 and underflowed below 1e-76 (distances of -0
    and 1e9 tol off, margins the wrong way) before they ran in the pair's own unit. A power of two
    scales every float exactly, and then the answers do too, to the bit."""
    a, b = pb.Prism.regular(5, 2.0), pb.Prism.regular(6, 2.5, phase=0.3)
    pos_a, rot_a, pos_b, rot_b = free_poses(400, np.random.default_rng(71), radius=2.5)
    base = pb.distance(a, b, pos_a, rot_a, pos_b, rot_b, witness=True)
    base_margin = pb.collide(a, b, pos_a, rot_a, pos_b, rot_b, margin=0.5).hit
    sa, sb = pb.Prism(a.xy * scale), pb.Prism(b.xy * scale)
    r = pb.distance(sa, sb, pos_a * scale, rot_a, pos_b * scale, rot_b, witness=True)
    margin = pb.collide(sa, sb, pos_a * scale, rot_a, pos_b * scale, rot_b, margin=0.5 * scale).hit
    assert (r.status == SEPARATED).sum() >= 50 and (r.status == PENETRATING).sum() >= 50
    if math.frexp(scale)[0] == 0.5:
        np.testing.assert_array_equal(r.distance / scale, base.distance)
        np.testing.assert_array_equal(r.point_b / scale, base.point_b)
        np.testing.assert_array_equal(margin, base_margin)
    else:  # the polygons and poses are rounded at the new scale
        np.testing.assert_allclose(r.distance / scale, base.distance, rtol=0, atol=0.01 * base.tol.max())
        np.testing.assert_allclose(r.point_b / scale, base.point_b, rtol=0, atol=0.01 * base.tol.max())
        far = np.abs(base.distance - 0.5) > base.tol
        np.testing.assert_array_equal(margin[far], base_margin[far])
    np.testing.assert_array_equal(r.status, base.status)
    sq = pb.Prism.regular(4, scale)
    down = np.diag([1.0, -1.0, -1.0])
    toi = pb.time_of_impact(
        sq, sq, [0, 0, 0], down, [0, 0, 2.0 * scale], np.eye(3), velocity=[0, 0, -4.0 * scale], horizon=1.0
    )
    assert toi.status[0] == 1 and abs(toi.time[0] - 0.5) <= 1e-9 and 0.0 < toi.distance[0] <= 1e-8 * scale


@pytest.mark.parametrize("shift", [1e2, pytest.param(1e5, marks=pytest.mark.slow), 1e8])
def test_polygons_far_from_their_own_origin(shift):
    """End faces given far from their prism's local origin (vertices about k, |k| = shift times the size),
    the poses moved so that the bodies stay where they were: the contract against the reference, which
    takes the floats as given, and the distances of the unshifted pairs to within the tolerance, which
    grows with |k| (the polygons' own rounding at the size of k)."""
    rng = np.random.default_rng(int(np.log10(shift)) + 60)
    d = make_pairs(rng, 80, "free", "smallmed")
    base = distance_with_witnesses(d)
    k = shift * d.scale[:, None, None] * rng.uniform(-1, 1, (len(d), 2, 2))
    d.polys_a = [p + k[i, 0] for i, p in enumerate(d.polys_a)]
    d.polys_b = [p + k[i, 1] for i, p in enumerate(d.polys_b)]
    d.pos_a = d.pos_a - np.einsum("nij,nj->ni", d.rot_a[:, :, :2], k[:, 0])
    d.pos_b = d.pos_b - np.einsum("nij,nj->ni", d.rot_b[:, :, :2], k[:, 1])
    r, _ = check(f"polygons shifted by {shift:g} of their size", d, coordinate_rounding=True)
    assert (r.tol > base.tol).all()
    np.testing.assert_allclose(r.distance, base.distance, rtol=0, atol=10 * r.tol.max())


# ---------------------------------------------------------------------------
# properties (hypothesis)
# ---------------------------------------------------------------------------


def _random_pair(seed, facing):
    rng = np.random.default_rng(seed)
    return make_pairs(rng, 1, "facing" if facing else "free", "smallmed")


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), facing=st.booleans())
def test_moving_b_by_minus_distance_normal_touches(seed, facing):
    d = _random_pair(seed, facing)
    r = distance_with_witnesses(d)
    moved = distance_with_witnesses(d, d.pos_b - r.distance[:, None] * r.normal)
    assert abs(moved.distance[0]) <= moved.tol[0]
    assert moved.status[0] == TOUCHING


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 2**32 - 1),
    quat=st.tuples(*[st.floats(-1, 1, allow_nan=False)] * 4).filter(lambda q: np.linalg.norm(q) > 0.1),
    shift=st.tuples(*[st.floats(-1e3, 1e3, allow_nan=False)] * 3),
)
def test_a_common_rigid_motion_changes_nothing(seed, quat, shift):
    d = _random_pair(seed, seed % 2 == 0)
    r = distance_with_witnesses(d)
    Q = Rotation.from_quat(np.array(quat) / np.linalg.norm(quat)).as_matrix()
    t = np.array(shift)
    moved = distance(
        pb.Prism(d.polys_a[0]), pb.Prism(d.polys_b[0]), Q @ d.pos_a[0] + t, Q @ d.rot_a[0], Q @ d.pos_b[0] + t,
        Q @ d.rot_b[0], witness=True,
    )  # fmt: skip
    tol = max(r.tol[0], moved.tol[0])
    assert abs(moved.distance[0] - r.distance[0]) <= 10 * tol
    # The moved pair's normal, turned back, is a normal of the original pair (ties may pick another one).
    back = distance_with_witnesses(d, d.pos_b - r.distance[:, None] * (Q.T @ moved.normal[0]))
    assert abs(back.distance[0]) <= back.tol[0]


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), facing=st.booleans())
def test_swapping_a_and_b(seed, facing):
    d = _random_pair(seed, facing)
    r = distance_with_witnesses(d)
    s = distance(pb.PrismSet(d.polys_b), pb.PrismSet(d.polys_a), d.pos_b, d.rot_b, d.pos_a, d.rot_a, witness=True)
    assert abs(s.distance[0] - r.distance[0]) <= 10 * r.tol[0]
    # moving a by -d n_ba is moving b by +d n_ba
    back = distance_with_witnesses(d, d.pos_b + s.distance[:, None] * s.normal)
    assert abs(back.distance[0]) <= back.tol[0]
