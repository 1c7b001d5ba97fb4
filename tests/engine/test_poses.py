"""Tests for prismbatch.poses: parsing, validation, broadcasting, relative poses."""

import re

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from prismbatch.poses import (
    as_pose,
    as_positions,
    as_rotations,
    broadcast_poses,
    relative_poses,
)

RNG_SEED = 1234


@pytest.fixture
def rng():
    return np.random.default_rng(RNG_SEED)


def random_unit_quats_xyzw(rng, n):
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def random_rotations(rng, n):
    return Rotation.from_quat(random_unit_quats_xyzw(rng, n)).as_matrix()


def re_shape(shape):
    return re.escape(str(tuple(shape)))


def xyzw_to_wxyz(q):
    return np.concatenate([q[..., 3:], q[..., :3]], axis=-1)


# ---------------------------------------------------------------------------
# quaternions
# ---------------------------------------------------------------------------
def test_quat_xyzw_matches_scipy(rng):
    q = random_unit_quats_xyzw(rng, 200)
    R = as_rotations(q, quat_order="xyzw")
    assert R.shape == (200, 3, 3)
    np.testing.assert_allclose(R, Rotation.from_quat(q).as_matrix(), atol=1e-12)


def test_quat_wxyz_matches_scipy(rng):
    q_xyzw = random_unit_quats_xyzw(rng, 200)
    q_wxyz = xyzw_to_wxyz(q_xyzw)
    R = as_rotations(q_wxyz, quat_order="wxyz")
    expected = Rotation.from_quat(q_wxyz, scalar_first=True).as_matrix()
    np.testing.assert_allclose(R, expected, atol=1e-12)
    # Same rotation as the scalar-last form of the same quaternion.
    np.testing.assert_allclose(R, as_rotations(q_xyzw, quat_order="xyzw"), atol=1e-15)


def test_quat_orders_differ(rng):
    # Guards against one order silently being treated as the other.
    q = random_unit_quats_xyzw(rng, 1)[0]
    assert not np.allclose(as_rotations(q, quat_order="wxyz"), as_rotations(q, quat_order="xyzw"))


@pytest.mark.parametrize("order", ["wxyz", "xyzw"])
def test_quat_sign_invariance(rng, order):
    q = random_unit_quats_xyzw(rng, 50)
    np.testing.assert_allclose(
        as_rotations(q, quat_order=order),
        as_rotations(-q, quat_order=order),
        atol=1e-15,
    )


@pytest.mark.parametrize("order", ["wxyz", "xyzw"])
def test_quat_single_vs_batched(rng, order):
    q = random_unit_quats_xyzw(rng, 10)
    R_batch = as_rotations(q, quat_order=order)
    for i in range(10):
        R_single = as_rotations(q[i], quat_order=order)
        assert R_single.shape == (3, 3)
        np.testing.assert_array_equal(R_single, R_batch[i])


def test_quat_identity_and_result_is_rotation(rng):
    np.testing.assert_array_equal(as_rotations([1, 0, 0, 0], quat_order="wxyz"), np.eye(3))
    np.testing.assert_array_equal(as_rotations([0, 0, 0, 1], quat_order="xyzw"), np.eye(3))
    R = as_rotations(random_unit_quats_xyzw(rng, 100), quat_order="wxyz")
    eye = np.broadcast_to(np.eye(3), R.shape)
    np.testing.assert_allclose(R @ R.transpose(0, 2, 1), eye, atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-14)


def test_quat_float32_within_tolerance_accepted(rng):
    q = random_unit_quats_xyzw(rng, 100).astype(np.float32)
    R = as_rotations(q, quat_order="xyzw")
    assert R.dtype == np.float64
    np.testing.assert_allclose(R, Rotation.from_quat(q.astype(np.float64)).as_matrix(), atol=1e-6)


def test_as_pose_with_quaternions(rng):
    q = random_unit_quats_xyzw(rng, 5)
    p_in = rng.normal(size=(5, 3))
    p, R = as_pose(p_in, xyzw_to_wxyz(q), quat_order="wxyz", name="b", dtype=np.float32)
    assert p.dtype == np.float32 and R.dtype == np.float32 and R.shape == (5, 3, 3)
    np.testing.assert_allclose(R, Rotation.from_quat(q).as_matrix(), atol=1e-6)
    np.testing.assert_allclose(p, p_in, rtol=1e-6)
    q[3] *= 1.01
    with pytest.raises(ValueError, match=r"rot_b\[3\] is a quaternion of norm 1\.01"):
        as_pose(p_in, q, quat_order="xyzw", name="b")


def test_quat_without_order_raises(rng):
    q = random_unit_quats_xyzw(rng, 3)
    with pytest.raises(ValueError, match=r"rot_a.*quat_order \('wxyz' or 'xyzw'\)"):
        as_rotations(q, name="rot_a")
    with pytest.raises(ValueError, match=r"explicit quat_order"):
        as_rotations(q[0])
    with pytest.raises(ValueError, match=r"explicit quat_order"):
        as_pose(np.zeros(3), q[0])


def test_bad_quat_order_raises():
    with pytest.raises(ValueError, match=r"quat_order must be 'wxyz'.*'xyzw'.*'wxzy'"):
        as_rotations([1, 0, 0, 0], quat_order="wxzy")


def test_unnormalised_quat_raises(rng):
    q = random_unit_quats_xyzw(rng, 10)
    q[6] *= 1.001
    with pytest.raises(ValueError, match=r"rot_b\[6\] is a quaternion of norm 1\.001"):
        as_rotations(q, quat_order="xyzw", name="rot_b")
    with pytest.raises(ValueError, match=r"^rot is a quaternion of norm 2\b"):
        as_rotations([2.0, 0, 0, 0], quat_order="wxyz")
    with pytest.raises(ValueError, match=r"norm 0\b"):
        as_rotations([0.0, 0, 0, 0], quat_order="wxyz")
    # Just inside the tolerance is accepted (and yields an exact rotation).
    R = as_rotations([1.0 + 5e-7, 0, 0, 0], quat_order="wxyz")
    np.testing.assert_allclose(R, np.eye(3), atol=1e-15)


def test_nan_quat_raises():
    q = np.tile([0.0, 0, 0, 1], (4, 1))
    q[2, 1] = np.nan
    with pytest.raises(ValueError, match=r"rot\[2\] contains non-finite"):
        as_rotations(q, quat_order="xyzw")


# ---------------------------------------------------------------------------
# rotation matrices and scipy Rotation
# ---------------------------------------------------------------------------
def test_matrices_pass_through(rng):
    R = random_rotations(rng, 20)
    out = as_rotations(R)
    assert out.dtype == np.float64 and out.flags.c_contiguous
    np.testing.assert_array_equal(out, R)
    single = as_rotations(R[3])
    assert single.shape == (3, 3)
    np.testing.assert_array_equal(single, R[3])


def test_matrices_non_contiguous_and_int(rng):
    R = random_rotations(rng, 5)
    Rf = np.asfortranarray(R.transpose(0, 2, 1)).transpose(0, 2, 1)  # strided view
    out = as_rotations(R[::-1])
    assert out.flags.c_contiguous
    np.testing.assert_array_equal(out, R[::-1])
    np.testing.assert_array_equal(as_rotations(Rf), R)
    perm = np.array([[0, 1, 0], [0, 0, 1], [1, 0, 0]], dtype=np.int64)
    out = as_rotations(perm)
    assert out.dtype == np.float64
    np.testing.assert_array_equal(out, perm)
    np.testing.assert_array_equal(as_rotations(np.eye(3).tolist()), np.eye(3))


def test_scipy_rotation_single_and_batched(rng):
    q = random_unit_quats_xyzw(rng, 8)
    rb = Rotation.from_quat(q)
    out = as_rotations(rb)
    assert out.shape == (8, 3, 3) and out.flags.c_contiguous
    np.testing.assert_array_equal(out, rb.as_matrix())

    rs = Rotation.from_quat(q[0])
    out = as_rotations(rs)
    assert out.shape == (3, 3)
    np.testing.assert_array_equal(out, rs.as_matrix())

    # A batch of one stays a batch.
    r1 = Rotation.from_quat(q[:1])
    assert as_rotations(r1).shape == (1, 3, 3)

    # Through as_pose as well.
    p, R = as_pose(np.zeros((8, 3)), rb)
    np.testing.assert_array_equal(R, rb.as_matrix())


def test_float32_output_and_input(rng):
    R = random_rotations(rng, 6)
    out = as_rotations(R, dtype=np.float32)
    assert out.dtype == np.float32 and out.flags.c_contiguous
    np.testing.assert_allclose(out, R, atol=1e-7)
    # float32 input passes with the relaxed 1e-5 tolerance ...
    R32 = R.astype(np.float32)
    np.testing.assert_allclose(as_rotations(R32), R32.astype(np.float64))
    # ... but errors well above 1e-5 are still caught, and float64 input
    # with a 1e-7 error fails the tight 1e-9 tolerance.
    with pytest.raises(ValueError, match=r"rot\[0\] is not orthonormal"):
        as_rotations((R[:1] * 1.001).astype(np.float32))
    with pytest.raises(ValueError, match=r"rot\[2\] is not orthonormal"):
        bad = R.copy()
        bad[2] *= 1 + 1e-7
        as_rotations(bad)
    p = as_positions(np.ones((4, 3)), dtype=np.float32)
    assert p.dtype == np.float32
    p, R = as_pose(np.eye(4), dtype=np.float32)
    assert p.dtype == np.float32 and R.dtype == np.float32


@pytest.mark.parametrize("parallel", [False, True])
def test_float32_rotations_are_judged_in_float64(rng, parallel):
    # float32 matrices are checked as they are (no float64 copy of the batch) but in float64 arithmetic:
    # each accepted or rejected as the plain NumPy reference judges its exact float64 value
    from prismbatch.poses import ortho_tolerance

    tol = ortho_tolerance(np.float32, np.float32)
    R = random_rotations(rng, 3000) * (1 + rng.uniform(-2, 2, (3000, 1, 1)) * tol)  # about half too far off
    R32 = R.astype(np.float32)
    R64 = R32.astype(np.float64)
    err = np.abs(np.einsum("nji,njk->nik", R64, R64) - np.eye(3)).max(axis=(1, 2))
    want = err <= tol
    assert 0.2 < want.mean() < 0.8
    assert np.array_equal(want[: want.argmin()], np.ones(want.argmin(), bool))
    k = int(np.argmin(want))  # the first matrix the reference rejects: the batch's message names it
    with pytest.raises(ValueError, match=rf"rot\[{k}\] is not orthonormal"):
        as_rotations(R32, dtype=np.float32, parallel=parallel)
    ok = as_rotations(R32[want], dtype=np.float32, parallel=parallel)
    assert ok.dtype == np.float32 and np.array_equal(ok, R32[want])
    for i in np.flatnonzero(~want)[:50]:  # each rejected alone too
        with pytest.raises(ValueError, match="not orthonormal"):
            as_rotations(R32[i], dtype=np.float32)


def test_float32_poses_are_not_copied_to_float64():
    import tracemalloc

    import prismbatch as pb
    from prismbatch.sampling import facing_poses

    poses = tuple(np.ascontiguousarray(x, dtype=np.float32) for x in facing_poses(100_000, np.random.default_rng(2)))
    col = pb.Collider(pb.Prism.regular(6, 1.0), pb.Prism.regular(6, 1.0), dtype=np.float32)
    col.collide(*poses[:4])  # compile outside the measurement
    tracemalloc.start()
    try:
        hit = col.collide(*poses).hit
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    # the outputs and the range test's temporaries (about 16 bytes a pair), not float64 copies of the poses
    # (96 bytes a pose: a peak of 168 bytes a pair before)
    assert len(hit) == 100_000 and peak < 40 * 100_000, peak


def test_bad_output_dtype_raises():
    with pytest.raises(TypeError, match=r"dtype must be np.float64 or np.float32"):
        as_rotations(np.eye(3), dtype=np.int32)
    with pytest.raises(TypeError, match=r"dtype must be np.float64 or np.float32"):
        as_positions(np.zeros(3), dtype=np.float16)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_nonfinite_rotation_raises(rng, bad):
    R = random_rotations(rng, 20)
    R[17, 1, 2] = bad
    with pytest.raises(ValueError, match=r"rot_a\[17\] contains non-finite values"):
        as_rotations(R, name="rot_a")
    with pytest.raises(ValueError, match=r"^rot contains non-finite values"):
        as_rotations(R[17])


def test_non_orthonormal_raises(rng):
    R = random_rotations(rng, 10)
    R[4] *= 1.001
    with pytest.raises(ValueError, match=r"rot_a\[4\] is not orthonormal: max \|R\^T R - I\| = 2\.00\de-03"):
        as_rotations(R, name="rot_a")
    with pytest.raises(ValueError, match=r"^rot is not orthonormal"):
        as_rotations(R[4])
    with pytest.raises(ValueError, match=r"rot_a\[4\] is not orthonormal"):
        as_pose(np.zeros(3), R, name="a")


def test_reflection_raises(rng):
    R = random_rotations(rng, 10)
    R[7, :, 0] *= -1.0
    with pytest.raises(ValueError, match=r"rot_b\[7\] is a reflection \(det = -1\)"):
        as_rotations(R, name="rot_b")
    with pytest.raises(ValueError, match=r"^rot is a reflection \(det = -1\)"):
        as_rotations(-np.eye(3))


@pytest.mark.parametrize(
    "shape",
    [(3,), (2, 3), (3, 5), (2, 3, 3, 3), (5, 3, 4), (3, 3, 3, 1), (), (9,)],
)
def test_rotation_wrong_shape_raises(shape):
    msg = rf"rot_a has shape {re_shape(shape)}; expected \(3, 3\) or \(N, 3, 3\)"
    with pytest.raises(ValueError, match=msg):
        as_rotations(np.zeros(shape), name="rot_a")


def test_rotation_last_dim_4_is_quaternion_only_with_order(rng):
    # (3, 4) is read as three quaternions: refused without quat_order, and
    # the message names the argument and the received shape.
    q = random_unit_quats_xyzw(rng, 3)
    with pytest.raises(ValueError, match=r"rot_a has shape \(3, 4\).*explicit quat_order"):
        as_rotations(q, name="rot_a")
    assert as_rotations(q, quat_order="xyzw").shape == (3, 3, 3)
    with pytest.raises(ValueError, match=r"rot\[0\] is a quaternion of norm 0"):
        as_rotations(np.zeros((3, 4)), quat_order="xyzw")


def test_rotation_4x4_hints_at_transform():
    with pytest.raises(ValueError, match=r"quat_order.*rot=None"):
        as_rotations(np.eye(4))
    with pytest.raises(ValueError, match=r"\(2, 4, 4\).*rot=None"):
        as_rotations(np.tile(np.eye(4), (2, 1, 1)))


def test_two_by_three_by_three_garbage_raises():
    # (2, 3, 3) is a valid shape; zeros are not rotations.
    with pytest.raises(ValueError, match=r"rot\[0\] is not orthonormal"):
        as_rotations(np.zeros((2, 3, 3)))


@pytest.mark.parametrize(
    "value, kind",
    [
        (np.eye(3, dtype=bool), "bool"),
        (np.eye(3, dtype=complex), "complex"),
        (np.array([["1", "0", "0"]] * 3), "<U1"),
        (np.eye(3).astype(object), "object"),
    ],
)
def test_rotation_bad_dtype_raises(value, kind):
    with pytest.raises(TypeError, match=rf"rot_a must have a real numeric dtype.*{kind}"):
        as_rotations(value, name="rot_a")


def test_ragged_input_raises():
    with pytest.raises(ValueError, match=r"rot_a could not be converted"):
        as_rotations([[1, 0, 0], [0, 1], [0, 0, 1]], name="rot_a")


# ---------------------------------------------------------------------------
# positions
# ---------------------------------------------------------------------------
def test_positions_ok(rng):
    p = rng.normal(size=(5, 3))
    out = as_positions(p)
    assert out.flags.c_contiguous and out.dtype == np.float64
    np.testing.assert_array_equal(out, p)
    assert as_positions([1, 2, 3]).shape == (3,)
    out = as_positions(p.T.copy().T[:, ::-1])
    assert out.flags.c_contiguous
    np.testing.assert_array_equal(out, p[:, ::-1])


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_nonfinite_position_raises(bad):
    p = np.zeros((20, 3))
    p[17, 0] = bad
    with pytest.raises(ValueError, match=r"pos_a\[17\] contains non-finite"):
        as_positions(p, name="pos_a")
    with pytest.raises(ValueError, match=r"pos_a\[17\] contains non-finite"):
        as_pose(p, np.eye(3), name="a")
    with pytest.raises(ValueError, match=r"^pos contains non-finite"):
        as_positions(p[17])


@pytest.mark.parametrize("shape", [(4,), (2,), (3, 4), (2, 3, 3), (), (3, 1)])
def test_position_wrong_shape_raises(shape):
    msg = rf"pos_b has shape {re_shape(shape)}; expected \(3,\) or \(N, 3\)"
    with pytest.raises(ValueError, match=msg):
        as_positions(np.zeros(shape), name="pos_b")


def test_position_bad_dtype_raises():
    with pytest.raises(TypeError, match=r"pos must have a real numeric dtype"):
        as_positions(np.array(["a", "b", "c"]))
    with pytest.raises(TypeError, match=r"pos_a must have a real numeric dtype.*bool"):
        as_pose(np.array([True, False, True]), np.eye(3))


# ---------------------------------------------------------------------------
# homogeneous transforms
# ---------------------------------------------------------------------------
def make_transforms(rng, n):
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = random_rotations(rng, n)
    T[:, :3, 3] = rng.normal(size=(n, 3))
    return T


def test_transform_round_trip(rng):
    T = make_transforms(rng, 12)
    p, R = as_pose(T)
    assert p.shape == (12, 3) and R.shape == (12, 3, 3)
    assert p.flags.c_contiguous and R.flags.c_contiguous
    T2 = np.tile(np.eye(4), (12, 1, 1))
    T2[:, :3, :3] = R
    T2[:, :3, 3] = p
    np.testing.assert_array_equal(T2, T)
    # Single transform stays single.
    p1, R1 = as_pose(T[5])
    assert p1.shape == (3,) and R1.shape == (3, 3)
    np.testing.assert_array_equal(p1, T[5, :3, 3])
    np.testing.assert_array_equal(R1, T[5, :3, :3])


def test_transform_bad_last_row_raises(rng):
    T = make_transforms(rng, 20)
    T[17, 3, 0] = 1e-9
    with pytest.raises(ValueError, match=r"pose_a\[17\] has last row \[1e-09, 0\.0, 0\.0, 1\.0\]"):
        as_pose(T, name="a")
    T = make_transforms(rng, 3)
    T[1, 3, 3] = 2.0
    with pytest.raises(ValueError, match=r"pose_b\[1\] has last row.*\[0, 0, 0, 1\]"):
        as_pose(T, name="b")
    with pytest.raises(ValueError, match=r"^pose_a has last row"):
        as_pose(T[1])


def test_transform_bad_rotation_block_raises(rng):
    T = make_transforms(rng, 4)
    T[2, :3, 1] *= -1
    with pytest.raises(ValueError, match=r"pose_a\[2\] rotation block is a reflection"):
        as_pose(T)
    T = make_transforms(rng, 4)
    T[3, :3, :3] *= 1.001
    with pytest.raises(ValueError, match=r"pose_a\[3\] rotation block is not orthonormal"):
        as_pose(T)
    T = make_transforms(rng, 4)
    T[0, 1, 3] = np.nan
    with pytest.raises(ValueError, match=r"pose_a\[0\] contains non-finite"):
        as_pose(T)


@pytest.mark.parametrize("shape", [(3,), (3, 3), (4, 3), (2, 3, 4)])
def test_transform_wrong_shape_raises(shape):
    msg = rf"pose_a has shape {re_shape(shape)}.*\(4, 4\) or \(N, 4, 4\)"
    with pytest.raises(ValueError, match=msg):
        as_pose(np.zeros(shape))


# ---------------------------------------------------------------------------
# broadcasting
# ---------------------------------------------------------------------------
def test_broadcast_all_single():
    N, (pa, Ra, pb, Rb) = broadcast_poses(np.zeros(3), np.eye(3), np.ones(3), np.eye(3))
    assert N == 1
    assert pa.shape == (1, 3) and Ra.shape == (1, 3, 3)
    assert pb.shape == (1, 3) and Rb.shape == (1, 3, 3)
    np.testing.assert_array_equal(pb, [[1, 1, 1]])


def test_broadcast_one_vs_n(rng):
    Rb_in = random_rotations(rng, 7)
    pa_in = rng.normal(size=(1, 3))
    N, arrs = broadcast_poses(pa_in, np.eye(3), np.zeros((7, 3)), Rb_in, n_shapes=1)
    assert N == 7
    for a, shape in zip(arrs, [(7, 3), (7, 3, 3), (7, 3), (7, 3, 3)]):
        assert a.shape == shape
        assert a.flags.c_contiguous and a.flags.writeable and a.dtype == np.float64
    np.testing.assert_array_equal(arrs[0], np.repeat(pa_in, 7, axis=0))
    np.testing.assert_array_equal(arrs[1], np.broadcast_to(np.eye(3), (7, 3, 3)))
    np.testing.assert_array_equal(arrs[3], Rb_in)
    # Inputs that need no broadcasting are still writeable (N=1 case too).
    N, arrs = broadcast_poses(np.zeros((1, 3)), np.eye(3)[None], np.zeros(3), np.eye(3))
    assert N == 1 and all(a.flags.writeable and a.flags.c_contiguous for a in arrs)
    # The shape set alone can set N.
    N, arrs = broadcast_poses(np.zeros(3), np.eye(3), np.zeros(3), np.eye(3), n_shapes=4)
    assert N == 4 and arrs[2].shape == (4, 3)


def test_broadcast_mismatch_message():
    msg = (
        r"batch sizes do not match: pos_a has 5, rot_a has 1 \(broadcast\), "
        r"pos_b has 7, rot_b has 1 \(single, broadcast\)"
    )
    with pytest.raises(ValueError, match=msg):
        broadcast_poses(np.zeros((5, 3)), np.eye(3)[None], np.zeros((7, 3)), np.eye(3))


def test_broadcast_mismatch_with_shape_set():
    with pytest.raises(
        ValueError,
        match=r"pos_a has 5, rot_a has 5, pos_b has 5, rot_b has 5, shape set has 7",
    ):
        broadcast_poses(
            np.zeros((5, 3)),
            np.tile(np.eye(3), (5, 1, 1)),
            np.zeros((5, 3)),
            np.tile(np.eye(3), (5, 1, 1)),
            n_shapes=7,
        )


def test_broadcast_wrong_shape_raises():
    msg = r"rot_b has shape \(5, 3\); expected \(3, 3\) or \(N, 3, 3\)"
    with pytest.raises(ValueError, match=msg):
        broadcast_poses(np.zeros(3), np.eye(3), np.zeros(3), np.zeros((5, 3)))
    with pytest.raises(ValueError, match=r"pos_a has shape \(4,\); expected \(3,\) or \(N, 3\)"):
        broadcast_poses(np.zeros(4), np.eye(3), np.zeros(3), np.eye(3))


# ---------------------------------------------------------------------------
# relative poses
# ---------------------------------------------------------------------------
def test_relative_poses_matches_loop(rng):
    n = 64
    pa, pb = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    Ra, Rb = random_rotations(rng, n), random_rotations(rng, n)
    p_rel, R_rel = relative_poses(pa, Ra, pb, Rb)
    assert p_rel.shape == (n, 3) and R_rel.shape == (n, 3, 3)
    assert p_rel.flags.c_contiguous and R_rel.flags.c_contiguous
    for i in range(n):
        np.testing.assert_allclose(R_rel[i], Ra[i].T @ Rb[i], atol=1e-14)
        np.testing.assert_allclose(p_rel[i], Ra[i].T @ (pb[i] - pa[i]), atol=1e-14)
        # Composition check: a's pose followed by the relative pose gives b.
        np.testing.assert_allclose(Ra[i] @ R_rel[i], Rb[i], atol=1e-14)
        np.testing.assert_allclose(pa[i] + Ra[i] @ p_rel[i], pb[i], atol=1e-14)


def test_relative_poses_broadcast_and_known_value(rng):
    # a at (1, 0, 0) rotated +90 deg about z; b at (1, 1, 0), unrotated.
    Rz = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])
    p_rel, R_rel = relative_poses(np.array([1.0, 0, 0]), Rz, np.array([1.0, 1, 0]), np.eye(3))
    np.testing.assert_allclose(p_rel, [[1.0, 0, 0]], atol=1e-15)  # b is along a's local +x
    np.testing.assert_allclose(R_rel, [Rz.T], atol=1e-15)
    # single a vs batch of b
    pb = rng.normal(size=(9, 3))
    Rb = random_rotations(rng, 9)
    p_rel, R_rel = relative_poses(np.zeros(3), np.eye(3), pb, Rb)
    np.testing.assert_allclose(p_rel, pb, atol=1e-15)
    np.testing.assert_allclose(R_rel, Rb, atol=1e-15)
    p32, R32 = relative_poses(np.zeros(3), np.eye(3), pb, Rb, dtype=np.float32)
    assert p32.dtype == np.float32 and R32.dtype == np.float32


def test_relative_poses_mismatch_raises():
    with pytest.raises(ValueError, match=r"batch sizes do not match: pos_a has 5.*pos_b has 7"):
        relative_poses(np.zeros((5, 3)), np.eye(3), np.zeros((7, 3)), np.eye(3))
