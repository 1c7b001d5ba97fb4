"""The pose and polygon forms users write: two 4x4 transforms, scipy Rotations and quaternions on the
one-pair path, closed rings; and the result as users handle it (repr, indexing, columns)."""

import dataclasses

import numpy as np
import pytest

import prismbatch as pb

Rotation = pytest.importorskip("scipy.spatial.transform").Rotation

A, B = pb.Prism.regular(5, 2.0), pb.Prism.regular(6, 2.5)
DOWN = np.diag([1.0, -1.0, -1.0])


def _transform(R, p):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T


def _poses(n, seed):
    rng = np.random.default_rng(seed)
    return (
        rng.uniform(-3, 3, (n, 3)),
        Rotation.random(n, random_state=seed).as_matrix(),
        rng.uniform(-3, 3, (n, 3)),
        Rotation.random(n, random_state=seed + 1).as_matrix(),
    )


@pytest.mark.parametrize("seed", [0, 1])
def test_two_transforms_as_written_equal_positions_and_rotations(seed):
    pa, ra, pb_, rb = _poses(64, seed)
    Ta = np.stack([_transform(r, p) for r, p in zip(ra, pa)])
    Tb = np.stack([_transform(r, p) for r, p in zip(rb, pb_)])
    ref = pb.collide(A, B, pa, ra, pb_, rb, contact=True)
    for got in (
        pb.collide(A, B, Ta, Tb, contact=True),
        pb.Collider(A, B).collide(Ta, Tb, contact=True),
        pb.collide(A, B, Ta, None, Tb, contact=True),
    ):
        assert np.array_equal(got.hit, ref.hit) and np.array_equal(got.case, ref.case)
        assert np.allclose(got.contact, ref.contact, equal_nan=True, rtol=0, atol=1e-12)
    col = pb.Collider(A, B)
    for k in range(8):
        one = col.collide_pair(Ta[k], Tb[k])
        assert (one.hit, one.case) == (bool(ref.hit[k]), int(ref.case[k]))


def test_collide_pair_takes_every_rotation_form_collide_takes():
    pa, ra, pb_, rb = _poses(32, 5)
    col = pb.Collider(A, B)
    ref = col.collide(pa, ra, pb_, rb)
    qa = Rotation.from_matrix(ra).as_quat()  # scipy: xyzw
    qb = Rotation.from_matrix(rb).as_quat()
    for k in range(32):
        want = (bool(ref.hit[k]), int(ref.case[k]))
        r1 = col.collide_pair(pa[k], Rotation.from_matrix(ra[k]), pb_[k], Rotation.from_matrix(rb[k]))
        r2 = col.collide_pair(pa[k], qa[k], pb_[k], qb[k], quat_order="xyzw")
        r3 = col.collide_pair(list(pa[k]), ra[k].tolist(), tuple(pb_[k]), rb[k].astype(np.float32))
        assert (r1.hit, r1.case) == want and (r2.hit, r2.case) == want and (r3.hit, r3.case) == want


def test_collide_pair_refuses_batches_and_missing_poses():
    col = pb.Collider(A, B)
    T = _transform(DOWN, [0, 0, 0])
    with pytest.raises(ValueError, match="one pose per body"):
        col.collide_pair(np.stack([T, T]), T)
    with pytest.raises(TypeError, match="needs a pose for b"):
        col.collide_pair([0, 0, 0], DOWN)
    with pytest.raises(ValueError, match="quaternion|unit"):
        col.collide_pair([0, 0, 0], [1, 1, 0, 0], [0, 0, 1], [1, 0, 0, 0], quat_order="wxyz")


def test_a_closed_ring_is_the_open_polygon():
    ring = [[0, 0], [2, 0], [2, 1], [0, 1], [0, 0]]
    assert np.array_equal(pb.Prism(ring).xy, pb.Prism(ring[:-1]).xy)
    assert pb.Prism(ring).n_vertices == 4
    with pytest.raises(ValueError, match="vertex 0 repeats vertex 2"):
        pb.Prism([[0, 0], [1, 0], [0, 0]])  # a "ring" of two points is not a polygon


def test_result_repr_indexing_and_columns():
    z = np.array([-1.0, -0.1, 0.0, 0.1, 1.0])
    pos_b = np.column_stack([np.zeros(5), np.zeros(5), z])
    r = pb.collide(A, B, np.zeros(3), DOWN, pos_b, np.eye(3), contact=True)
    hits = int(r.hit.sum())
    assert repr(r).startswith(f"CollisionResult(5 pairs, {hits} hits, with contacts; cases {{")
    one = r[1]
    assert len(one) == 1 and one.hit[0] == r.hit[1] and np.array_equal(one.contact, r.contact[1:2], equal_nan=True)
    assert len(r[-1]) == 1 and r[-1].case[0] == r.case[-1]
    assert np.array_equal(r[1:4].case, r.case[1:4]) and np.array_equal(r[r.hit].case, r.case[r.hit])
    with pytest.raises(IndexError):
        r[5]
    cols = r.columns()
    assert list(cols) == ["hit", "case", "contact_x", "contact_y", "contact_z"]
    assert all(np.asarray(c).shape == (5,) for c in cols.values())
    assert np.array_equal(cols["contact_z"], r.contact[:, 2], equal_nan=True)
    assert list(pb.collide(A, B, np.zeros(3), DOWN, pos_b, np.eye(3)).columns()) == ["hit", "case"]
    assert "1 pair, " in repr(r[0])


def test_every_result_is_indexed_the_same_way():
    """Collision, distance, time-of-impact and probability results cut every per-pair array alike
    and keep their scalars (prismbatch.results.BatchResult)."""
    z = np.array([-1.0, -0.1, 0.3, 1.0])
    pos_b = np.column_stack([np.zeros(4), np.zeros(4), z])
    cov = np.diag([0.0, 0.0, 0.1**2, 0.0, 0.0, 0.0])
    results = [
        pb.collide(A, B, np.zeros(3), DOWN, pos_b, np.eye(3), contact=True),
        pb.distance(A, B, np.zeros(3), DOWN, pos_b, np.eye(3), witness=True),
        pb.time_of_impact(A, B, np.zeros(3), DOWN, pos_b, np.eye(3), [0, 0, -1.0], horizon=1.0, pose=True),
        pb.collision_probability(A, B, np.zeros(3), DOWN, pos_b, np.eye(3), cov, seed=2, max_samples=4096),
    ]
    mask = np.array([True, False, True, True])
    for r in results:
        assert len(r) == 4
        for k, rows in ((2, [2]), (-1, [3]), (slice(1, 3), [1, 2]), (mask, [0, 2, 3]), (np.array([3, 0]), [3, 0])):
            part = r[k]
            assert type(part) is type(r) and len(part) == len(rows)
            for f in dataclasses.fields(r):
                v, w = getattr(r, f.name), getattr(part, f.name)
                if isinstance(v, np.ndarray):
                    np.testing.assert_array_equal(w, v[rows], err_msg=f.name)
                else:
                    assert w is v or w == v, f.name  # scalars (seed, confidence) and None kept
        with pytest.raises(IndexError):
            r[4]
