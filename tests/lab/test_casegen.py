"""Case-targeted pose generators (prismbatch.lab.casegen).

Every generated pose must have the requested case, the requested mix of hits
and misses, and hits that agree with the exact LP reference outside the
touching band (the touching-by-construction cases have margin 0 on a hit).
"""

import zlib

import numpy as np
import pytest

import prismbatch as pb
from prismbatch.lab.casegen import CASE_NUMBERS, EXACT_CASES, HIT_AND_MISS_CASES, case_poses

from helpers import collinear_polygon, irregular_polygon
from reference import margin_lp

pytestmark = [pytest.mark.slow]


def _irregular_off_centre():
    rng = np.random.default_rng(1234)
    a = irregular_polygon(rng, 9, 1.7) + np.array([2.5, -1.0])  # local origin outside the polygon
    b = irregular_polygon(rng, 14, 1.2) + np.array([-0.4, 0.9])
    return pb.Prism(a), pb.Prism(b)


SHAPES = {
    "paper": (pb.Prism.regular(5, 2.0), pb.Prism.regular(6, 2.5)),
    "36gons": (pb.Prism.regular(36, 1.5, phase=0.1), pb.Prism.regular(36, 2.0, phase=0.3, centre=(0.2, -0.1))),
    "irregular": _irregular_off_centre(),
    "3600gons": (pb.Prism.regular(3600, 2.5), pb.Prism.regular(3600, 1.5, phase=0.01, centre=(0.3, 0.0))),
}
N = 200
TOUCHING = (2, 3, 4, 7, 8)
# LP reference on 3600-gons is slow: check only these cases, and few poses.
LP_3600_CASES = (2, 4, 6, 8)


def _seed(*parts):
    return zlib.crc32("|".join(map(str, parts)).encode())


def _poses(case, shape, world):
    a, b = SHAPES[shape]
    return case_poses(case, N, a, b, np.random.default_rng(_seed(case, shape, world)), world_transform=world)


@pytest.mark.parametrize("world", [False, True], ids=["paper_frame", "world"])
@pytest.mark.parametrize("shape", sorted(SHAPES))
@pytest.mark.parametrize("case", CASE_NUMBERS)
def test_case_hits_and_lp(case, shape, world):
    a, b = SHAPES[shape]
    P = _poses(case, shape, world)
    for arr, shp in zip(P, [(N, 3), (N, 3, 3), (N, 3), (N, 3, 3)]):
        assert arr.shape == shp and arr.dtype == np.float64 and np.isfinite(arr).all()
    r = pb.collide(a, b, *P)
    assert (r.case == case).all(), r.case_counts()
    nhit = int(r.hit.sum())
    if case in HIT_AND_MISS_CASES:
        assert nhit == N // 2
    else:
        assert nhit == 0
    if not world:
        assert (P[0] == 0).all() and (P[1] == np.diag([1.0, -1.0, -1.0])).all()
    else:
        assert np.ptp(P[0], axis=0).min() > 0  # a's pose varies

    # Exact LP reference on a subsample (both hits and misses).
    if shape == "3600gons":
        if case not in LP_3600_CASES or world:
            return
        idx = np.concatenate([np.flatnonzero(r.hit)[:2], np.flatnonzero(~r.hit)[:2]])
    else:
        idx = np.concatenate([np.flatnonzero(r.hit)[:4], np.flatnonzero(~r.hit)[:4]])
    for i in idx:
        m = margin_lp(a.xy, P[0][i], P[1][i], b.xy, P[2][i], P[3][i])
        S = (
            a.radius
            + b.radius
            + np.linalg.norm(P[2][i] + P[3][i][:, :2] @ b.centre - P[0][i] - P[1][i][:, :2] @ a.centre)
        )
        band = 1e-7 * S
        if case in TOUCHING and r.hit[i]:
            assert abs(m) <= band, (i, m)  # touching by construction
        if abs(m) > band:
            assert bool(r.hit[i]) == (m > 0), (i, m, bool(r.hit[i]))


@pytest.mark.parametrize("case", EXACT_CASES)
@pytest.mark.parametrize("world", [False, True])
def test_exact_zeros(case, world):
    a, b = SHAPES["36gons"]
    pa, ra, pb_, rb = case_poses(case, 100, a, b, 7, world_transform=world)
    da, db = ra[:, :, 2], rb[:, :, 2]
    # a's axis is a signed coordinate axis exactly.
    assert ((np.abs(da) == 1.0).sum(axis=1) == 1).all() and ((da == 0.0).sum(axis=1) == 2).all()
    dot = np.einsum("ij,ij->i", da, db)
    if case in (7, 8):
        assert (dot == 0.0).all()
    if case == 4:
        assert (db == -da).all()
    # b's lowest end-face vertex on a's plane, to rounding.
    ca = pa + np.einsum("kij,j->ki", ra[:, :, :2], a.centre)
    verts = pb_[:, None, :] + np.einsum("kij,mj->kmi", rb[:, :, :2], b.xy)
    depth = np.einsum("kmi,ki->km", verts - ca[:, None, :], da).max(axis=1)
    assert np.abs(depth).max() < 1e-12 * (a.radius + b.radius + np.abs(ca).max())


def test_reproducible_and_hit_fraction():
    a, b = SHAPES["paper"]
    P1 = case_poses(6, 120, a, b, np.random.default_rng(3), hit_fraction=0.25, world_transform=True)
    P2 = case_poses(6, 120, a, b, np.random.default_rng(3), hit_fraction=0.25, world_transform=True)
    for x, y in zip(P1, P2):
        np.testing.assert_array_equal(x, y)
    assert int(pb.collide(a, b, *P1).hit.sum()) == 30
    for hf, expect in ((0.0, 0), (1.0, 50)):
        r = pb.collide(a, b, *case_poses(9, 50, a, b, 1, hit_fraction=hf))
        assert int(r.hit.sum()) == expect and (r.case == 9).all()
    # Cases that never collide ignore hit_fraction.
    r = pb.collide(a, b, *case_poses(5, 50, a, b, 1, hit_fraction=1.0))
    assert not r.hit.any() and (r.case == 5).all()


def test_large_polygons_fast_enough():
    import time

    a, b = SHAPES["3600gons"]
    case_poses(2, 10, a, b, 0)  # compile
    t = time.perf_counter()
    P = case_poses(6, 1000, a, b, 0)
    assert time.perf_counter() - t < 3.0  # typically ~0.2 s
    assert (pb.collide(a, b, *P).case == 6).all()


def test_empty_and_bad_arguments():
    a, b = SHAPES["paper"]
    out = case_poses(3, 0, a, b, 0)
    assert [x.shape for x in out] == [(0, 3), (0, 3, 3), (0, 3), (0, 3, 3)]
    for bad in (0, 12, 2.5, True):
        with pytest.raises(ValueError, match="case"):
            case_poses(bad, 5, a, b, 0)
    with pytest.raises(ValueError, match="hit_fraction"):
        case_poses(2, 5, a, b, 0, hit_fraction=1.5)
    with pytest.raises(ValueError, match="n must"):
        case_poses(2, -1, a, b, 0)
    with pytest.raises(TypeError, match="shape_b"):
        case_poses(2, 5, a, b.xy, 0)


def test_impossible_edge_case_raises_clearly():
    # Every side of this polygon carries collinear vertices: an "edge" on a's
    # plane always has three or more vertices there, which prismbatch calls case 4.
    a = SHAPES["paper"][0]
    b = pb.Prism(collinear_polygon(np.random.default_rng(0)))
    with pytest.raises(RuntimeError, match="case 3 cannot be constructed"):
        case_poses(3, 5, a, b, 0)
    # ...but its corners still give cases 2 and 7, and its sides case 8.
    for case in (2, 7, 8):
        assert (pb.collide(a, b, *case_poses(case, 40, a, b, 0)).case == case).all()
