"""One orthonormality rule for rotation matrices, whatever the path.

The tolerance on max |R^T R - I| is ``ortho_tolerance(input dtype, compute
dtype)`` = max(ORTHO_TOL[compute], 64 eps(input)); a rejected rotation's
message says how to fix the input.
"""

import math
import sys

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import prismbatch as pb
from prismbatch._kernels.checks import first_bad_rotation, poses_ok
from prismbatch.config import SUPPORTED_RANGE
from prismbatch.poses import ORTHO_TOL_F32, ORTHO_TOL_F64, as_pose, as_rotations, ortho_tolerance

A = pb.Prism.regular(5, 2.0)
B = pb.Prism.regular(6, 1.0)
R = Rotation.from_rotvec([0.3, -0.2, 0.5]).as_matrix()
R6 = np.round(R, 6)  # what a text file with 6 decimals holds: |R^T R - I| ~ 1e-6
HINT = r"re-orthonormalise.*Rotation\.from_matrix\(R\)\.as_matrix\(\).*dtype=np\.float32"


def ortho_error(M):
    M = np.asarray(M, dtype=np.float64)
    return np.abs(M.T @ M - np.eye(3)).max()


def scaled(M, err):
    """M scaled so that max |M^T M - I| is about ``err``."""
    return M * np.sqrt(1.0 + err)


def test_ortho_tolerance_rule():
    eps32 = float(np.finfo(np.float32).eps)
    assert ortho_tolerance(np.float64, np.float64) == ORTHO_TOL_F64 == 1e-9
    assert ortho_tolerance(np.float32, np.float64) == pytest.approx(64 * eps32)  # ~7.6e-6
    assert ortho_tolerance(np.float32, np.float32) == ORTHO_TOL_F32 == 1e-5
    assert ortho_tolerance(np.float64, np.float32) == 1e-5
    assert ortho_tolerance(np.int64, np.float64) == 1e-9  # integers are exact: float64 input
    assert ortho_tolerance(np.dtype("int8"), "float32") == 1e-5
    with pytest.raises(TypeError, match="dtype"):
        ortho_tolerance(np.float64, np.float16)
    with pytest.raises(TypeError, match="input_dtype"):
        ortho_tolerance(np.complex128, np.float64)


def test_six_decimal_rotations_pass_under_float32_compute_only():
    assert 1e-7 < ortho_error(R6) < 5e-6
    out = as_rotations(R6, dtype=np.float32)
    assert out.dtype == np.float32
    np.testing.assert_array_equal(out, R6.astype(np.float32))
    with pytest.raises(ValueError, match=r"^rot is not orthonormal: .* > 1e-09; " + HINT):
        as_rotations(R6)
    with pytest.raises(ValueError, match=r"rot_a\[1\] is not orthonormal.*" + HINT):
        as_rotations(np.stack([R, R6]), name="rot_a")


def test_transforms_follow_the_same_rule():
    T = np.eye(4)
    T[:3, :3] = R6
    T[:3, 3] = [1.0, 2.0, 3.0]
    p, Rt = as_pose(T, dtype=np.float32)
    assert Rt.dtype == np.float32
    with pytest.raises(ValueError, match=r"pose_a rotation block is not orthonormal.*" + HINT):
        as_pose(T)


def test_float32_input_under_float64_compute_uses_its_own_precision():
    # Rounding to float32 is far inside 64 eps; an error of 9e-6 is not.
    as_rotations(R.astype(np.float32))
    bad = scaled(R, 9e-6).astype(np.float32)
    assert 8e-6 < ortho_error(bad) < 1e-5
    with pytest.raises(ValueError, match=r"not orthonormal: .* > 7\.63e-06"):
        as_rotations(bad)
    as_rotations(bad, dtype=np.float32)  # float32 compute: 1e-5
    with pytest.raises(ValueError, match=r"not orthonormal: .* > 1e-05; "):
        as_rotations(scaled(R, 3e-5).astype(np.float32), dtype=np.float32)


def test_the_check_still_rejects_non_rotations():
    for dtype in (np.float64, np.float32):
        with pytest.raises(ValueError, match="not orthonormal"):
            as_rotations(R * 1.001, dtype=dtype)
        with pytest.raises(ValueError, match="reflection"):
            as_rotations(-R, dtype=dtype)


def test_batch_collide_message_carries_the_hint():
    with pytest.raises(ValueError, match=r"rot_a\[0\] is not orthonormal.*" + HINT):
        pb.collide(A, B, np.zeros((1, 3)), R6[None], np.ones((1, 3)), np.eye(3)[None])


def _accepts(f):
    try:
        f()
    except ValueError as exc:
        assert "orthonormal" in str(exc)
        return False
    return True


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize(
    "rot",
    [R.astype(np.float32), R6.astype(np.float32), scaled(R, 9e-6).astype(np.float32)],
    ids=["rounded", "6-decimals", "9e-6"],
)
def test_collide_and_collide_pair_agree_on_float32_rotations(dtype, rot):
    col = pb.Collider(A, B, dtype=dtype)
    pa, pbp, I3 = np.zeros(3), np.array([0.0, 0.0, 1.0]), np.eye(3)
    via_pair = _accepts(lambda: col.collide_pair(pa, rot, pbp, I3))
    via_batch = _accepts(lambda: pb.collide(A, B, pa[None], rot[None], pbp[None], I3[None], dtype=dtype))
    via_collide = _accepts(lambda: pb.collide(A, B, pa, rot, pbp, I3, dtype=dtype))
    assert via_pair == via_batch == via_collide
    assert via_pair == (ortho_error(rot) <= ortho_tolerance(np.float32, dtype))


def test_collide_with_float32_accepts_six_decimal_rotations():
    for pa, ra in ((np.zeros(3), R6), (np.zeros((2, 3)), np.stack([R6, R6]))):
        r = pb.collide(A, B, pa, ra, pa + [0.0, 0.0, 1.0], np.eye(3), dtype=np.float32)
        assert r.hit.all()
    col = pb.Collider(A, B, dtype=np.float32)
    assert col.collide_pair(np.zeros(3), R6, [0.0, 0.0, 1.0], np.eye(3)).hit


def test_one_pair_message_carries_the_hint():
    with pytest.raises(ValueError, match=r"rot_a is not orthonormal.*" + HINT):
        pb.Collider(A, B).collide_pair(np.zeros(3), R6, np.ones(3), np.eye(3))


@pytest.mark.parametrize("kind", ["not orthonormal", "reflection", "non-finite"])
def test_parallel_rotation_check_names_the_first_bad_matrix(kind):
    # The check runs in chunks on the threads for large batches: the first bad matrix is the one named.
    n = 20_000
    rng = np.random.default_rng(len(kind))
    rot = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    bad = np.sort(rng.choice(n, 5, replace=False))
    for i in bad:
        if kind == "not orthonormal":
            rot[i, 0, 0] = 1.001
        elif kind == "reflection":
            rot[i, 2, 2] = -1.0
        else:
            rot[i, 1, 2] = np.nan
    col = pb.Collider(pb.Prism.regular(4, 1.0), pb.Prism.regular(4, 1.0))
    pos = np.zeros((n, 3))
    messages = []
    for parallel in (False, True):
        with pytest.raises(ValueError) as err:
            col.collide(pos, rot, pos, np.eye(3), parallel=parallel)
        messages.append(str(err.value))
    assert messages[0] == messages[1]
    assert f"rot_a[{bad[0]}]" in messages[1]


def _first_bad_reference(Rs, tol):
    """(index, kind, value) of the first bad matrix, in plain Python (the kernel's summation order)."""
    for i, M in enumerate(Rs):
        if not all(math.isfinite(v) for v in M.flat):
            return i, 1, 0.0
        err = max(abs(sum(M[m, j] * M[m, k] for m in range(3)) - (j == k)) for j in range(3) for k in range(3))
        if err > tol:
            return i, 2, err
        det = np.linalg.det(M)
        if det <= 0.0:
            return i, 3, None  # (the kernel's det: its own formula)
    return -1, 0, 0.0


def _edge_rotations(rng, n, tol):
    """n rotations, most at the tolerance's edge (one entry moved by 0.3 to 3 tol, the whole scaled, two
    columns sheared), non-finite entries in every place, reflections, and good ones."""
    cases = []
    for _ in range(n):
        M = Rotation.random(random_state=rng).as_matrix()
        kind = rng.integers(0, 6)
        if kind == 1:
            M[rng.integers(3), rng.integers(3)] += rng.choice([-1, 1]) * rng.uniform(0.3, 3.0) * tol
        elif kind == 2:
            M[rng.integers(3), rng.integers(3)] = rng.choice([np.nan, np.inf, -np.inf])
        elif kind == 3:
            M[:, rng.integers(3)] *= -1.0  # a reflection
        elif kind == 4:
            M = M * (1.0 + rng.choice([-1, 1]) * rng.uniform(0.1, 1.0) * tol)  # scaled to the edge
        elif kind == 5:  # two columns sheared together: their dot product moves, the norms hardly
            j, k = rng.choice(3, 2, replace=False)
            M[:, j] += rng.choice([-1, 1]) * rng.uniform(0.3, 3.0) * tol * M[:, k]
        cases.append(M)
    return cases


def test_compiled_check_matches_a_plain_reference():
    """The branch-free pass of first_bad_rotation against the plain rule, on matrices at the
    tolerance's edge, non-finite entries in every place and reflections, one matrix at a time and
    as batches."""
    tol = ORTHO_TOL_F64
    cases = _edge_rotations(np.random.default_rng(11), 300, tol)
    kinds = []
    for M in cases:
        want = _first_bad_reference([M], tol)
        got = first_bad_rotation(M[None].copy(), tol)
        assert got[:2] == want[:2], (M, got, want)
        if want[1] == 2:
            assert got[2] == want[2]
        kinds.append(want[1])
    assert set(kinds) == {0, 1, 2, 3}  # every outcome was tried
    batch = np.array(cases)
    for start in range(0, 300, 37):
        want = _first_bad_reference(batch[start:], tol)
        got = first_bad_rotation(batch[start:].copy(), tol)
        assert got[:2] == want[:2]


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_the_small_batch_check_matches_the_plain_rule(dtype):
    """poses_ok, the one compiled pass that clears a small batch of plain arrays, against the plain
    rule: every coordinate within the dtype's range (NaN and inf outside), every matrix as
    _first_bad_reference judges it in float64, on batches of 1 to 9 poses with one or no bad entry:
    coordinates at the limit, one ulp past it, non-finite; rotations at the tolerance's edge."""
    rng = np.random.default_rng(12)
    dt = np.dtype(dtype)
    limit = SUPPORTED_RANGE[dt.name][1]
    tol = ortho_tolerance(dt, dt)
    over = float(np.nextafter(dt.type(limit), dt.type(np.inf)))
    edge_coords = [limit, -limit, over, -over, np.nan, np.inf, -np.inf, 0.0]
    outcomes = set()
    for _ in range(400):
        n = [int(rng.integers(1, 10)) for _ in range(4)]
        pos = [rng.uniform(-1e3, 1e3, (k, 3)).astype(dt) for k in n[::2]]
        rot = [
            np.array(
                _edge_rotations(rng, k, tol)
                if rng.random() < 0.3
                else Rotation.random(k, random_state=rng).as_matrix(),
                dtype=dt,
            )
            for k in n[1::2]
        ]
        if rng.random() < 0.5:
            p = pos[rng.integers(2)]
            p[rng.integers(p.shape[0]), rng.integers(3)] = edge_coords[rng.integers(len(edge_coords))]
        want = all(abs(float(v)) <= limit for p in pos for v in p.flat)
        want &= all(_first_bad_reference(r.astype(np.float64), tol)[1] == 0 for r in rot)
        assert poses_ok(pos[0], rot[0], pos[1], rot[1], limit, tol) == want
        outcomes.add(want)
    assert outcomes == {True, False}


def test_a_plain_batch_is_cleared_in_one_pass_and_a_bad_one_named_as_before(monkeypatch):
    """Collider's batch path clears plain arrays without the NumPy pose parser, to the same answer; a
    batch with a bad pose goes to the parser, which names it as it did (and the same for arrays the
    pass does not take: lists, another dtype)."""
    collide_module = sys.modules["prismbatch.collide"]  # (the package's name collide is the function)

    col = pb.Collider(pb.Prism.regular(6, 1.0), pb.Prism.regular(5, 1.5))
    rng = np.random.default_rng(3)
    pos_a, pos_b = rng.normal(size=(7, 3)), rng.normal(size=(7, 3))
    rot_a, rot_b = Rotation.random(7, random_state=rng).as_matrix(), Rotation.random(1, random_state=rng).as_matrix()
    via_parser = col.collide(pos_a.tolist(), rot_a.tolist(), pos_b.tolist(), rot_b[0].tolist(), contact=True)
    parsed = []
    real_as_pose = collide_module.as_pose
    monkeypatch.setattr(collide_module, "as_pose", lambda *a, **k: parsed.append(1) or real_as_pose(*a, **k))
    for rb in (rot_b, rot_b[0]):
        got = col.collide(pos_a, rot_a, pos_b, rb, contact=True)
        np.testing.assert_array_equal(got.hit, via_parser.hit)
        np.testing.assert_array_equal(got.case, via_parser.case)
        np.testing.assert_array_equal(got.contact, via_parser.contact)
        assert col.distance(pos_a, rot_a, pos_b, rb).distance.shape == (7,)
    assert parsed == []
    bad_rot = rot_a.copy()
    bad_rot[4, 0, 0] = 1.001
    for args, where in (
        ((pos_a, bad_rot, pos_b, rot_b), "rot_a[4]"),
        ((pos_a, rot_a, pos_b[:, ::-1] * 1e300, rot_b), "pos_b[0]"),
    ):
        with pytest.raises(ValueError) as err:
            col.collide(*args)
        assert where in str(err.value)
        assert parsed
        with pytest.raises(ValueError) as err_list:
            col.collide(*(x.tolist() for x in args))
        assert str(err.value) == str(err_list.value)
    with pytest.raises(ValueError, match="batch sizes do not match"):
        col.collide(pos_a, rot_a, pos_b[:3], rot_b)
