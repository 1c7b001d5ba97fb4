"""Invariances of ``prismbatch.collide``.

Required invariances: one rigid transform applied to both poses; cyclic
shift of vertex order; uniform scaling from 1e-6 to 1e3; swapping a and b
gives the same hit.  Added: clockwise vertex order, moving/rotating a polygon in its
own local frame with the pose compensating, and float32 vs float64.

All comparisons are made on pairs clearly away from the touching band of
the LP reference: |delta*| > 1e-6 S (S = R_a + R_b + |c_b - c_a|), or
|delta*| > 1e-4 S for float32 (its default rtol is 1e-5).  The data is the
session fixture ``pairs_with_margins`` (800 facing + 800 free pairs, 3..200
vertices, regular and irregular).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import prismbatch as pb

from helpers import PairData, random_rotations, rot_z
from reference import point_in_prism_residual

pytestmark = [pytest.mark.slow]

CLEAR_REL = 1e-6


def run(d: PairData, polys_a=None, polys_b=None, **kw):
    sa = pb.PrismSet(d.polys_a if polys_a is None else polys_a)
    sb = pb.PrismSet(d.polys_b if polys_b is None else polys_b)
    return pb.collide(sa, sb, d.pos_a, d.rot_a, d.pos_b, d.rot_b, **kw)


@pytest.fixture(scope="module")
def data(pairs_with_margins):
    d = pairs_with_margins
    clear = np.abs(d.delta) > CLEAR_REL * d.scale
    assert clear.mean() > 0.99, f"only {clear.sum()} of {len(d)} pairs are clear of the band"
    base = run(d, contact=True)
    # sanity: the baseline itself agrees with the reference on clear pairs
    assert np.array_equal(base.hit[clear], d.delta[clear] > 0)
    assert 0.1 < base.hit.mean() < 0.9
    return d, clear, base


def assert_same(label, clear, hit0, hit1, case0=None, case1=None):
    diff = np.flatnonzero(clear & (hit0 != hit1))
    assert diff.size == 0, f"{label}: hit differs for {diff.size} clear pairs, e.g. {diff[:10]}"
    if case0 is not None:
        cd = np.flatnonzero(clear & (case0 != case1))
        assert cd.size == 0, (
            f"{label}: case differs for {cd.size} clear pairs, e.g. "
            f"{[(int(k), int(case0[k]), int(case1[k])) for k in cd[:10]]}"
        )


# ---------------------------------------------------------------------------
# rigid transform of both poses
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("translation", [0.0, 10.0, 1e3])
def test_rigid_transform_of_both_poses(data, translation):
    d, clear, base = data
    rng = np.random.default_rng(int(translation) + 5)
    n = len(d)
    Q = random_rotations(rng, n)
    t = rng.uniform(-1, 1, (n, 3)) * translation
    moved = PairData(
        d.polys_a,
        d.polys_b,
        np.einsum("nij,nj->ni", Q, d.pos_a) + t,
        Q @ d.rot_a,
        np.einsum("nij,nj->ni", Q, d.pos_b) + t,
        Q @ d.rot_b,
    )
    r = run(moved, contact=True)
    assert_same(f"rigid transform (|t| ~ {translation:g})", clear, base.hit, r.hit, base.case, r.case)

    # contacts transform with the bodies: each moved contact lies in both
    # moved prisms, and almost always it is the transformed contact itself
    hits = np.flatnonzero(r.hit & base.hit)
    expect = np.einsum("nij,nj->ni", Q, base.contact) + t
    err = np.linalg.norm(r.contact - expect, axis=1)[hits] / d.scale[hits]
    close = err <= 1e-6
    assert close.mean() >= 0.99, f"only {close.sum()} of {hits.size} contacts move with the bodies"
    for k in hits:
        tol = 1e-9 * d.scale[k] + 1e-15 * translation
        for poly, pos, rot in (
            (d.polys_a[k], moved.pos_a[k], moved.rot_a[k]),
            (d.polys_b[k], moved.pos_b[k], moved.rot_b[k]),
        ):
            res = point_in_prism_residual(poly, pos, rot, r.contact[k])
            assert res <= 2 * tol + 1e-12 * d.scale[k], (k, res, tol)


def test_rotation_given_as_scipy_rotation_or_quaternion(data):
    """The same rotations as scipy Rotation objects / wxyz and xyzw quaternions."""
    d, clear, base = data
    sa, sb = pb.PrismSet(d.polys_a), pb.PrismSet(d.polys_b)
    ra, rb = Rotation.from_matrix(d.rot_a), Rotation.from_matrix(d.rot_b)
    r1 = pb.collide(sa, sb, d.pos_a, ra, d.pos_b, rb)
    qa, qb = ra.as_quat(), rb.as_quat()  # xyzw
    r2 = pb.collide(sa, sb, d.pos_a, qa, d.pos_b, qb, quat_order="xyzw")
    r3 = pb.collide(sa, sb, d.pos_a, np.roll(qa, 1, axis=1), d.pos_b, np.roll(qb, 1, axis=1), quat_order="wxyz")
    for lab, r in (("Rotation", r1), ("xyzw", r2), ("wxyz", r3)):
        assert_same(lab, clear, base.hit, r.hit, base.case, r.case)


# ---------------------------------------------------------------------------
# vertex order, local frame of the polygon
# ---------------------------------------------------------------------------


def test_cyclic_shift_and_clockwise_order(data):
    d, clear, base = data
    rng = np.random.default_rng(11)

    def shifted(polys):
        return [np.roll(p, int(rng.integers(1, len(p))), axis=0) for p in polys]

    def reversed_(polys):
        return [p[::-1].copy() for p in polys]

    variants = {
        "cyclic shift": (shifted(d.polys_a), shifted(d.polys_b)),
        "clockwise": (reversed_(d.polys_a), reversed_(d.polys_b)),
        "clockwise + shift": (shifted(reversed_(d.polys_a)), shifted(reversed_(d.polys_b))),
    }
    for label, (pa, pb_) in variants.items():
        r = run(d, pa, pb_)
        assert_same(label, clear, base.hit, r.hit)
        # the case number is a property of the geometry, not of the listing
        same_case = np.mean(r.case[clear] == base.case[clear])
        assert same_case >= 0.999, f"{label}: case numbers agree for only {same_case:.4f} of clear pairs"


def test_polygon_moved_in_its_local_frame(data):
    """Shift and spin each polygon in its local frame and compensate in the
    pose: the bodies are unchanged, so the hits are too (the local origin
    need not lie inside the polygon)."""
    d, clear, base = data
    rng = np.random.default_rng(12)
    n = len(d)

    def move(polys, pos, rot):
        out_p, out_pos, out_rot = [], pos.copy(), rot.copy()
        for k, p in enumerate(polys):
            phi = rng.uniform(0, 2 * np.pi)
            off = rng.uniform(-3, 3, 2) * np.max(np.abs(p))
            Z = rot_z(phi)
            out_p.append(p @ Z[:2, :2].T + off)  # x' = Z x + off
            # body point p + R [x, t] = p' + R' [x', t] with R' = R Z^T
            out_rot[k] = rot[k] @ Z.T
            out_pos[k] = pos[k] - out_rot[k][:, :2] @ off
        return out_p, out_pos, out_rot

    pa, pos_a, rot_a = move(d.polys_a, d.pos_a, d.rot_a)
    pb_, pos_b, rot_b = move(d.polys_b, d.pos_b, d.rot_b)
    r = pb.collide(pb.PrismSet(pa), pb.PrismSet(pb_), pos_a, rot_a, pos_b, rot_b)
    assert len(r.hit) == n
    assert_same("local frame", clear, base.hit, r.hit, base.case, r.case)


def test_shared_prism_equals_per_pair_copies(data):
    """One Prism shared by all pairs gives the same results as a PrismSet
    holding a copy of it for every pair (and as a batch of one)."""
    d, _, _ = data
    n = 300
    A = pb.Prism(d.polys_a[0])
    B = pb.Prism(d.polys_b[1])
    args = (d.pos_a[:n], d.rot_a[:n], d.pos_b[:n], d.rot_b[:n])
    shared = pb.collide(A, B, *args, contact=True)
    copies = pb.collide(pb.PrismSet([d.polys_a[0]] * n), pb.PrismSet([d.polys_b[1]] * n), *args, contact=True)
    np.testing.assert_array_equal(shared.hit, copies.hit)
    np.testing.assert_array_equal(shared.case, copies.case)
    np.testing.assert_array_equal(shared.contact, copies.contact)
    for k in (0, 7, n - 1):
        one = pb.collide(A, B, d.pos_a[k], d.rot_a[k], d.pos_b[k], d.rot_b[k])
        assert one.hit.shape == (1,)
        assert one.hit[0] == shared.hit[k] and one.case[0] == shared.case[k]
    assert 0 < shared.hit.sum() < n


# ---------------------------------------------------------------------------
# uniform scaling
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("scale", [1e-6, 1e-3, 1.0, 1e3])
def test_uniform_scaling(data, scale):
    d, clear, base = data
    scaled = PairData(
        [p * scale for p in d.polys_a],
        [p * scale for p in d.polys_b],
        d.pos_a * scale,
        d.rot_a,
        d.pos_b * scale,
        d.rot_b,
    )
    r = run(scaled, contact=True)
    assert_same(f"scale {scale:g}", clear, base.hit, r.hit, base.case, r.case)
    # contacts scale too (same relative pose up to rounding)
    hits = np.flatnonzero(r.hit & base.hit)
    err = np.linalg.norm(r.contact[hits] / scale - base.contact[hits], axis=1) / d.scale[hits]
    assert np.mean(err <= 1e-6) >= 0.99
    assert np.all(np.isnan(r.contact[~r.hit]))


# ---------------------------------------------------------------------------
# swapping a and b; float32
# ---------------------------------------------------------------------------


def test_swap_a_and_b(data):
    d, clear, base = data
    r = pb.collide(pb.PrismSet(d.polys_b), pb.PrismSet(d.polys_a), d.pos_b, d.rot_b, d.pos_a, d.rot_a)
    # case numbers describe b relative to a, so they may differ
    assert_same("swap", clear, base.hit, r.hit)


def test_float32_matches_float64(data):
    d, _, base = data
    clear32 = np.abs(d.delta) > 1e-4 * d.scale
    assert clear32.mean() > 0.95
    r = run(d, dtype=np.float32)
    assert r.hit.dtype == np.bool_ and r.hit.shape == base.hit.shape
    assert_same("float32", clear32, base.hit, r.hit)
    # float32 also agrees with the reference there
    assert np.array_equal(r.hit[clear32], d.delta[clear32] > 0)
