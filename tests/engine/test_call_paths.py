"""Every way of calling the kernel gives the same answer on the same pairs.

One pair alone (``collide_pair``, ``collide`` on plain arrays, ``explain``)
equals that pair inside a batch; the serial kernel equals the parallel one;
contiguous inputs equal strided views of the same numbers; on every
user-like pose family (identical rotations, quaternions, dense polygons, far
origins, tiny objects, mixed scales) drawn by hypothesis.
"""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import prismbatch as pb
from prismbatch.lab.families import FAMILIES, make_family

SETTINGS = settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _shared_shape_pairs(name, seed, n=64):
    """A family's poses with the first pair's polygons shared by every pair (so collide_pair applies)."""
    ps = make_family(name, n, seed)
    return pb.Prism(ps.xy_a[0]), pb.Prism(ps.xy_b[0]), ps


@pytest.mark.slow
@SETTINGS
@given(name=st.sampled_from(sorted(FAMILIES)), seed=st.integers(0, 2**31 - 1))
def test_one_pair_paths_equal_the_batch(name, seed):
    A, B, ps = _shared_shape_pairs(name, seed)
    col = pb.Collider(A, B)
    batch = col.collide(ps.pos_a, ps.rot_a, ps.pos_b, ps.rot_b, contact=True, parallel=False)
    for k in range(0, len(ps.pos_a), 7):
        one = col.collide_pair(ps.pos_a[k], ps.rot_a[k], ps.pos_b[k], ps.rot_b[k])
        assert one.hit == batch.hit[k] and one.case == batch.case[k]
        np.testing.assert_array_equal(one.contact, batch.contact[k])
        plain = col.collide(ps.pos_a[k], ps.rot_a[k], ps.pos_b[k], ps.rot_b[k], contact=True)
        assert plain.hit[0] == batch.hit[k]
        assert col.explain(ps.pos_a[k], ps.rot_a[k], ps.pos_b[k], ps.rot_b[k])["hit"] == batch.hit[k]


def test_explain_takes_every_pose_form_collide_pair_takes():
    """explain on two 4x4 transforms, on quaternions and on float32 arrays records the same decision
    as on the matrices (each form converted as collide_pair converts it)."""
    from scipy.spatial.transform import Rotation

    ps = make_family("facing", 24, 5)
    col = pb.Collider(pb.Prism(ps.xy_a[0]), pb.Prism(ps.xy_b[0]))
    for k in range(0, 24, 3):
        pa, ra, pb_, rb = ps.pos_a[k], ps.rot_a[k], ps.pos_b[k], ps.rot_b[k]
        want = col.explain(pa, ra, pb_, rb)
        Ta, Tb = np.eye(4), np.eye(4)
        Ta[:3, :3], Ta[:3, 3], Tb[:3, :3], Tb[:3, 3] = ra, pa, rb, pb_
        same = col.explain(Ta, Tb)
        assert same.keys() == want.keys()
        for f in want:  # every traced field, NaN where the test never got there
            np.testing.assert_array_equal(same[f], want[f], err_msg=f)
        quat = col.explain(
            pa, Rotation.from_matrix(ra).as_quat(), pb_, Rotation.from_matrix(rb).as_quat(), quat_order="xyzw"
        )
        pair = col.collide_pair(
            pa, Rotation.from_matrix(ra).as_quat(), pb_, Rotation.from_matrix(rb).as_quat(), quat_order="xyzw"
        )
        assert (quat["hit"], quat["case"]) == (pair.hit, pair.case)
        np.testing.assert_array_equal(quat["contact"], pair.contact)
        f32 = tuple(x.astype(np.float32) for x in (pa, ra, pb_, rb))
        pair32 = col.collide_pair(*f32)
        e32 = col.explain(*f32)
        assert (e32["hit"], e32["case"]) == (pair32.hit, pair32.case)
        np.testing.assert_array_equal(e32["contact"], pair32.contact)


@SETTINGS
@given(name=st.sampled_from(sorted(FAMILIES)), seed=st.integers(0, 2**31 - 1))
def test_serial_equals_parallel_and_strided_equals_contiguous(name, seed):
    ps = make_family(name, 48, seed)
    A, B = pb.PrismSet(ps.xy_a), pb.PrismSet(ps.xy_b)
    col = pb.Collider(A, B)
    serial = col.collide(ps.pos_a, ps.rot_a, ps.pos_b, ps.rot_b, contact=True, parallel=False)
    par = col.collide(ps.pos_a, ps.rot_a, ps.pos_b, ps.rot_b, contact=True, parallel=True)
    np.testing.assert_array_equal(serial.hit, par.hit)
    np.testing.assert_array_equal(serial.case, par.case)
    np.testing.assert_array_equal(serial.contact, par.contact)
    # Strided views of the same numbers: every other row of a doubled array, Fortran order.
    pa2 = np.repeat(ps.pos_a, 2, axis=0)[::2]
    rb2 = np.asfortranarray(ps.rot_b)
    assert not pa2.flags.c_contiguous and not rb2.flags.c_contiguous
    strided = col.collide(pa2, ps.rot_a, ps.pos_b, rb2, contact=True)
    np.testing.assert_array_equal(serial.hit, strided.hit)
    np.testing.assert_array_equal(serial.contact, strided.contact)


@SETTINGS
@given(name=st.sampled_from(["quaternion", "transform_4x4", "scipy_rotation"]), seed=st.integers(0, 2**31 - 1))
def test_rotation_forms_equal_matrices(name, seed):
    from prismbatch.lab.families import collide_family

    ps = make_family(name, 48, seed)
    as_given = collide_family(ps)
    A, B = pb.PrismSet(ps.xy_a), pb.PrismSet(ps.xy_b)
    from prismbatch.poses import as_rotations

    if ps.form == "quat":
        ra = as_rotations(ps.call_a, quat_order=ps.quat_order)
        rb = as_rotations(ps.call_b, quat_order=ps.quat_order)
    else:
        ra, rb = ps.rot_a, ps.rot_b
    as_matrices = pb.collide(A, B, ps.pos_a, ra, ps.pos_b, rb)
    np.testing.assert_array_equal(as_given.hit, as_matrices.hit)


@pytest.mark.slow
@SETTINGS
@given(name=st.sampled_from(sorted(FAMILIES)), seed=st.integers(0, 2**31 - 1))
def test_near_touching_pairs_with_a_known_gap(name, seed):
    """Pairs placed at g tol along a separating plane: g <= 1 must hit, g > 2 must miss.

    The placement rounds positions by about eps |p|; pairs whose gap lies within
    that (times 16) of tol or 2 tol are left out.
    """
    from prismbatch.geometry import pair_scale_tolerance
    from prismbatch.lab.families import collide_family

    ps = make_family(name, 64, seed)
    r = collide_family(ps)
    known = np.flatnonzero(np.isfinite(ps.target))
    for k in known:
        A, B = pb.Prism(ps.xy_a[k]), pb.Prism(ps.xy_b[k])
        _, tol = pair_scale_tolerance(
            A, B, ps.pos_a[k : k + 1], ps.rot_a[k : k + 1], ps.pos_b[k : k + 1], ps.rot_b[k : k + 1]
        )
        slack = (
            16
            * np.finfo(float).eps
            * (
                np.abs(ps.pos_a[k]).max()
                + np.abs(ps.pos_b[k]).max()
                + A.radius
                + B.radius
                + np.abs(ps.xy_a[k]).max()
                + np.abs(ps.xy_b[k]).max()
            )
        )
        gap = ps.target[k] * tol[0]
        if gap <= tol[0] - slack:
            assert r.hit[k], (name, k, ps.target[k])
        elif gap > 2 * tol[0] + slack:
            assert not r.hit[k], (name, k, ps.target[k])


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_one_pair_distance_equals_the_batch(dtype):
    """Collider.distance on one plain pair (the compiled one-pair path, checks in the kernel) gives
    the batch path's answer to the bit, and the batch path's error messages."""
    from prismbatch.sampling import facing_poses, free_poses

    rng = np.random.default_rng(11)
    col = pb.Collider(pb.Prism.regular(36, 1.0), pb.Prism.regular(7, 0.6), dtype=dtype)
    for poses in (facing_poses(60, rng, radius=1.0), free_poses(60, rng, radius=1.0)):
        P = [np.asarray(x, dtype=dtype) for x in poses]
        for i in range(60):
            for witness in (False, True):
                one = col.distance(*(np.ascontiguousarray(x[i]) for x in P), witness=witness)
                batch = col.distance(*(x[i : i + 1] for x in P), witness=witness)
                for name, v in batch.columns().items():
                    np.testing.assert_array_equal(one.columns()[name], v, err_msg=name)
    pa, ra, pb_, rb = (np.asarray(x, dtype=dtype) for x in (np.zeros(3), np.eye(3), [0, 0, 1.0], np.eye(3)))
    for bad, k, name, what in (
        (np.array([np.nan, 0, 0], dtype=dtype), 2, "pos_b", "non-finite"),
        (2 * ra, 1, "rot_a", "orthonormal"),
    ):
        args = [pa, ra, pb_, rb]
        args[k] = bad
        for call in (lambda: col.distance(*args), lambda: col.distance(*(x[None] for x in args))):
            with pytest.raises(ValueError, match=what) as err:
                call()
            assert str(err.value).startswith(name)  # the batch adds the index: pos_b[0]
    strided = np.zeros((3, 2), dtype=dtype)[:, 0]  # not contiguous: copied, same answer
    assert col.distance(strided, ra, pb_, rb).distance[0] == col.distance(pa, ra, pb_, rb).distance[0]


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_one_pair_forms_reach_the_kernel_as_they_should(dtype, monkeypatch):
    # Views of a 4x4 transform go to the compiled kernel as they are (its signature takes any layout);
    # forms it cannot take (a list, another dtype, two transforms) are converted without being offered
    # to it: a call Numba's dispatcher refuses costs some 0.1 ms in its TypeError.
    ps = make_family("free", 40, 3)
    A, B = pb.Prism(ps.xy_a[0]), pb.Prism(ps.xy_b[0])
    col = pb.Collider(A, B, dtype=dtype)
    other = np.float32 if dtype == np.float64 else np.float64
    rows = range(40)
    T = np.zeros((40, 2, 4, 4), dtype=dtype)
    T[:, 0, :3, :3], T[:, 0, :3, 3], T[:, 1, :3, :3], T[:, 1, :3, 3] = ps.rot_a, ps.pos_a, ps.rot_b, ps.pos_b
    T[:, :, 3, 3] = 1.0
    batch = col.collide(T[:, 0], T[:, 1], contact=True)  # the same numbers as stored in dtype
    col.collide_pair(*(np.ascontiguousarray(x[0], dtype=dtype) for x in (ps.pos_a, ps.rot_a, ps.pos_b, ps.rot_b)))

    kernel = col._pair_kernel
    offered = []

    def recording(bundle, pa, ra, pb_, rb, contact):
        offered.append((pa.dtype, ra.dtype, pb_.dtype, rb.dtype))
        return kernel(bundle, pa, ra, pb_, rb, contact)

    monkeypatch.setattr(col, "_pair_kernel", recording)
    converted = []
    real_converted = col._converted_pair
    monkeypatch.setattr(col, "_converted_pair", lambda *a: converted.append(1) or real_converted(*a))
    for k in rows:
        Ta, Tb = T[k, 0], T[k, 1]
        views = col.collide_pair(Ta[:3, 3], Ta[:3, :3], Tb[:3, 3], Tb[:3, :3])
        assert views.hit == batch.hit[k] and views.case == batch.case[k]
        np.testing.assert_array_equal(views.contact.astype(dtype), batch.contact[k])  # (a pair's is float64)
    assert not converted and len(offered) == len(rows)  # every view pair went straight to the kernel
    offered.clear()
    Ta, Tb = T[5, 0], T[5, 1]
    for args in (
        (Ta[:3, 3].tolist(), Ta[:3, :3].tolist(), Tb[:3, 3].tolist(), Tb[:3, :3].tolist()),
        (Ta[:3, 3].astype(other), Ta[:3, :3].astype(other), Tb[:3, 3].astype(other), Tb[:3, :3].astype(other)),
        (Ta, Tb),
    ):
        r = col.collide_pair(*args)
        assert r.hit == batch.hit[5] and r.case == batch.case[5]
    assert len(converted) == 3
    # what reached the kernel was converted to the compute dtype first, never refused by it
    assert all(d == np.dtype(dtype) for row in offered for d in row)


def test_two_transforms_take_the_kernel_and_bad_ones_keep_their_messages(monkeypatch):
    # collide_pair(T_a, T_b), and collide on one such pair, pass the transforms' blocks to the kernel as
    # views (a few µs, not the pose parser's tens); a transform the kernel rejects is parsed again for
    # the message naming it.
    ps = make_family("facing", 30, 5)
    col = pb.Collider(pb.Prism(ps.xy_a[0]), pb.Prism(ps.xy_b[0]))
    T = np.zeros((30, 2, 4, 4))
    T[:, 0, :3, :3], T[:, 0, :3, 3], T[:, 1, :3, :3], T[:, 1, :3, 3] = ps.rot_a, ps.pos_a, ps.rot_b, ps.pos_b
    T[:, :, 3, 3] = 1.0
    batch = col.collide(T[:, 0], T[:, 1], contact=True)
    col.collide_pair(T[0, 0], T[0, 1])  # the first query compiles or closes the kernel
    parsed = []
    real_one_pose = col._one_pose
    monkeypatch.setattr(col, "_one_pose", lambda *a: parsed.append(a[-1]) or real_one_pose(*a))
    for k in range(30):
        r = col.collide_pair(T[k, 0], T[k, 1])
        assert r.hit == batch.hit[k] and r.case == batch.case[k]
        np.testing.assert_array_equal(r.contact, batch.contact[k])
        one = col.collide(T[k, 0], T[k, 1], contact=True)  # collide on one pair takes the same route
        assert one.hit[0] == batch.hit[k] and one.case[0] == batch.case[k]
        np.testing.assert_array_equal(one.contact[0], batch.contact[k])
    assert not parsed
    bad = T[3].copy()
    bad[1, :3, :3] = bad[1, :3, :3] @ np.diag([1.0, 1.0, -1.0])  # a reflection
    with pytest.raises(ValueError, match=r"^pose_b rotation block is a reflection"):
        col.collide_pair(bad[0], bad[1])
    bad = T[3].copy()
    bad[0, 0, 3] = np.nan
    with pytest.raises(ValueError, match=r"^pose_a"):
        col.collide_pair(bad[0], bad[1])
    parsed.clear()
    tilted = T[3].copy()
    tilted[0, 3, 0] = 1e-13  # within the last row's tolerance: parsed, and the same answer
    r = col.collide_pair(tilted[0], tilted[1])
    assert r.hit == batch.hit[3] and parsed == ["a", "b"]


def _unaligned(x):
    """A copy of ``x`` one byte into a buffer: same numbers, not aligned."""
    buf = np.zeros(x.nbytes + 1, np.uint8)
    out = np.ndarray(x.shape, x.dtype, buffer=buf, offset=1)
    out[...] = x
    return out


def test_byte_order_and_alignment_never_fool_the_one_pair_kernel():
    # Numba's dispatcher keys arrays by a fingerprint without byte order and alignment: once it had met
    # an unaligned array, a big-endian one of the same kind reached the kernel as native and was read
    # byte-swapped (a hit 5 apart). Each form must give the answer of the same numbers in native arrays.
    import numba

    col = pb.Collider(pb.Prism.regular(4, 1.0), pb.Prism.regular(4, 1.0))
    I, z = np.eye(3), np.zeros(3)
    col.collide_pair(z, I, z, I)
    col.distance(z, I, z, I)  # (both one-pair kernels closed: the later calls take the fast paths)
    users_own = numba.njit(lambda x: x[0])  # the caller's Numba code meets such arrays first
    for big in (np.zeros(3).astype(">f8"), np.eye(3).astype(">f8")):
        with pytest.raises(numba.core.errors.TypingError):  # (Numba has no type for them)
            users_own(big)
    T = np.eye(4)
    for x, want in ((5.0, False), (1.5, True)):
        far = np.array([x, 0.0, 0.0])
        T[:3, 3] = far
        Tu, Tbig = _unaligned(T), T.astype(">f8")
        forms = [
            (_unaligned(far), I, z, I),
            (far.astype(">f8"), I, z, I),
            (far, I.astype(">f8"), z, I),
            (Tu[:3, 3], Tu[:3, :3], z, I),
            (Tbig[:3, 3], Tbig[:3, :3], z, I),
            (_unaligned(far), _unaligned(I), _unaligned(z), _unaligned(I)),
        ]
        for k, args in enumerate(forms):
            assert col.collide_pair(*args).hit == want, k
            assert col.collide(*args).hit.tolist() == [want], k
            assert (col.distance(*args).distance[0] <= col.distance(*args).tol[0]) == want, k


def test_first_one_pair_calls_from_several_threads(tmp_path):
    # The first one-pair query compiles (or loads) the kernel and closes it to other signatures; threads
    # making their first queries at once must wait for it, not find it closed half-way ("compilation
    # disabled"). A fresh process, sharing this one's Numba cache.
    import subprocess
    import sys

    script = tmp_path / "threads.py"
    script.write_text(
        "import threading, numpy as np, prismbatch as pb\n"
        "A, B = pb.Prism.regular(5, 1.0), pb.Prism.regular(6, 1.0)\n"
        "for dt in (np.float64, np.float32):\n"
        "    cols = [pb.Collider(A, B, dtype=dt) for _ in range(4)]\n"
        "    I, z = np.eye(3, dtype=dt), np.zeros(3, dtype=dt)\n"
        "    barrier, errors, hits = threading.Barrier(4), [], []\n"
        "    def work(c):\n"
        "        barrier.wait()\n"
        "        try:\n"
        "            hits.append(bool(c.collide_pair(z, I, z, I).hit))\n"
        "            hits.append(bool(c.distance(z, I, z, I).status[0] <= 0))\n"
        "        except Exception as e:\n"
        "            errors.append(repr(e))\n"
        "    ts = [threading.Thread(target=work, args=(c,)) for c in cols]\n"
        "    [t.start() for t in ts]\n"
        "    [t.join() for t in ts]\n"
        "    assert not errors and hits == [True] * 8, (errors, hits)\n"
        "print('ok')\n"
    )
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr[-2000:]


def test_read_only_and_unpickled_poses_go_straight_to_the_one_pair_kernels(monkeypatch):
    """Frozen, np.broadcast_to and unpickled arrays (an equal dtype object, not the same one), and
    ``witness=np.True_``, take the fast paths (the kernels' signatures take read-only poses): a refused
    call cost some 0.1 ms."""
    import pickle

    ps = make_family("facing", 12, 2)
    col = pb.Collider(pb.Prism(ps.xy_a[0]), pb.Prism(ps.xy_b[0]))
    col.collide_pair(ps.pos_a[0], ps.rot_a[0], ps.pos_b[0], ps.rot_b[0])
    col.distance(ps.pos_a[0], ps.rot_a[0], ps.pos_b[0], ps.rot_b[0])
    batch = col.collide(ps.pos_a, ps.rot_a, ps.pos_b, ps.rot_b, contact=True)
    dist = col.distance(ps.pos_a, ps.rot_a, ps.pos_b, ps.rot_b, witness=True)
    slow = []
    monkeypatch.setattr(col, "_converted_pair", lambda *a: slow.append("collide_pair"))
    monkeypatch.setattr(col, "_pair_distance", lambda *a: slow.append("distance"))

    def frozen(x):
        y = x.copy()
        y.flags.writeable = False
        return y

    for k in range(12):
        pose = (ps.pos_a[k], ps.rot_a[k], ps.pos_b[k], ps.rot_b[k])
        for form in (
            tuple(frozen(x) for x in pose),
            tuple(np.broadcast_to(x, x.shape) for x in pose),
            tuple(pickle.loads(pickle.dumps(x)) for x in pose),
        ):
            one = col.collide_pair(*form)
            assert (one.hit, one.case) == (batch.hit[k], batch.case[k])
            np.testing.assert_array_equal(one.contact, batch.contact[k])
            d = col.distance(*form, witness=True)
            np.testing.assert_array_equal(d.distance, dist.distance[k : k + 1])
            np.testing.assert_array_equal(d.point_b, dist.point_b[k : k + 1])
        d = col.distance(*pose, witness=np.True_)  # a flag read from a NumPy array: the same fast query
        np.testing.assert_array_equal(d.point_a, dist.point_a[k : k + 1])
    assert not slow


def test_one_pair_distance_fast_path_checks_what_the_batch_checks():
    """Once the one-pair distance kernel is closed, a plain pair goes straight to it: views answer as
    contiguous copies to the bit, and flags, bad poses and batches are judged as before."""
    ps = make_family("free", 40, 3)
    col = pb.Collider(pb.Prism(ps.xy_a[0]), pb.Prism(ps.xy_b[0]))
    batch = col.distance(ps.pos_a, ps.rot_a, ps.pos_b, ps.rot_b, witness=True, parallel=False)
    T = np.zeros((40, 2, 4, 4))
    T[:, 0, :3, :3], T[:, 0, :3, 3], T[:, 1, :3, :3], T[:, 1, :3, 3] = ps.rot_a, ps.pos_a, ps.rot_b, ps.pos_b
    for k in range(40):
        Ta, Tb = T[k, 0], T[k, 1]
        for args in (
            (ps.pos_a[k], ps.rot_a[k], ps.pos_b[k], ps.rot_b[k]),
            (Ta[:3, 3], Ta[:3, :3], Tb[:3, 3], Tb[:3, :3]),
        ):
            one = col.distance(*args, witness=True)
            for f in ("distance", "status", "tol", "solver", "normal", "point_a", "point_b"):
                got, want = getattr(one, f), getattr(batch, f)[k : k + 1]
                assert got.dtype == want.dtype and got.shape == want.shape, f
                np.testing.assert_array_equal(got, want, err_msg=f)
            plain = col.distance(*args)
            with pytest.raises(AttributeError, match="normal was not computed"):
                plain.normal
            assert vars(plain).keys() == vars(batch[k]).keys()  # (the same fields, None ones too)
            assert all(x.flags.owndata for x in (one.normal, one.point_a, one.point_b))
    z, I = np.zeros(3), np.eye(3)
    with pytest.raises(TypeError, match="witness must be"):
        col.distance(z, I, z, I, witness="yes")
    with pytest.raises(TypeError, match="parallel must be"):
        col.distance(z, I, z, I, parallel="no")
    with pytest.raises(ValueError, match=r"^pos_b contains non-finite"):
        col.distance(z, I, np.array([0.0, np.nan, 0.0]), I)
    with pytest.raises(ValueError, match=r"^rot_a is not orthonormal"):
        col.distance(z, 2 * I, z, I)
    with pytest.raises(ValueError, match=r"pos_b has shape \(2,\)"):
        col.distance(z, I, np.zeros(2), I)
    assert len(col.distance(np.zeros((3, 3)), I, z, I)) == 3  # a batch takes the batch path
    assert col.distance(z, I, z, I, witness=np.True_, parallel=np.False_).normal.shape == (1, 3)


def test_a_batch_given_to_collide_pair_is_named():
    col = pb.Collider(pb.Prism.regular(4, 1.0), pb.Prism.regular(4, 1.0))
    I, z = np.eye(3), np.zeros(3)
    with pytest.raises(
        ValueError, match=r"collide_pair takes one pose per body; rot_a is a batch of 2 \(use collide\)"
    ):
        col.collide_pair(z, np.stack([I, I]), z, I)
    with pytest.raises(ValueError, match=r"rot_b is a batch of 5"):
        col.collide_pair(z, I, z, np.tile([1.0, 0, 0, 0], (5, 1)), quat_order="wxyz")
    with pytest.raises(ValueError, match=r"pos_b is a batch of 3"):
        col.collide_pair(z, I, np.zeros((3, 3)), I, quat_order="wxyz")


def test_one_pair_inputs_of_another_dtype_are_judged_as_the_batch_judges_them():
    # A float64 pose given to a float32 Collider: collide_pair checked the float32-rounded rotation,
    # the batch the float64 one, and they disagreed on half the rotations at the tolerance; a float64
    # position beyond float32's range was reported as non-finite (the inf it rounds to).
    col = pb.Collider(pb.Prism.regular(5, 2.0), pb.Prism.regular(6, 2.5), dtype=np.float32)
    P0, I = np.array([0.1, 0.2, 0.3]), np.eye(3)
    col.collide_pair(P0, I, P0, I)
    rng = np.random.default_rng(0)
    tol = 1e-5  # ortho_tolerance(float64, float32)
    for _ in range(100):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        q[:, 0] *= np.sign(np.linalg.det(q))
        E = rng.normal(size=(3, 3))
        lo, hi = 0.0, 1e-3  # (q + t E) is orthonormal to within tol for t <= lo, not for t >= hi
        for _ in range(60):
            mid = (lo + hi) / 2
            R = q + mid * E
            lo, hi = (mid, hi) if np.abs(R.T @ R - np.eye(3)).max() <= tol else (lo, mid)
        for t in (lo, hi):
            R = q + t * E
            verdicts = []
            for call in (
                lambda: col.collide_pair(P0, R, P0, I),
                lambda: col.collide(P0[None], R[None], P0[None], I[None]),
            ):
                try:
                    call()
                    verdicts.append("accepted")
                except ValueError as e:
                    verdicts.append(str(e).split(":")[0])
            assert verdicts[0] == verdicts[1].replace("rot_a[0]", "rot_a"), (t, verdicts)
    for pos in ([1e39, 0, 0], np.array([1e39, 0.0, 0.0])):
        with pytest.raises(ValueError, match=r"^pos_a has a coordinate 1e\+39 outside the supported range"):
            col.collide_pair(pos, I, P0, I)
    with pytest.raises(ValueError, match=r"^rot_a could not be converted to an array"):
        col.collide_pair(P0, [[1, 0, 0], [0, 1], [0, 0, 1]], P0, I)  # ragged
    for query in (col.collide_pair, col.collide):
        with pytest.raises(TypeError, match=r"needs a pose for a: pos_a"):
            query(None, None, None, None)


def test_one_pair_names_the_first_bad_input_as_the_batch_does():
    # a's position, a's rotation, then b's: with a bad rot_a and a bad pos_b the one-pair kernel named
    # pos_b (it checked both positions first), the batch rot_a[0].
    col = pb.Collider(pb.Prism.regular(4, 1.0), pb.Prism.regular(4, 1.0))
    I, z = np.eye(3), np.zeros(3)
    col.collide_pair(z, I, z, I)
    bad_rot, bad_pos = np.diag([1.0, 1.0, -1.0]), np.array([np.nan, 0.0, 0.0])
    for args, first in (
        ((z, bad_rot, bad_pos, I), "rot_a"),
        ((bad_pos, bad_rot, z, I), "pos_a"),
        ((z, I, bad_pos, bad_rot), "pos_b"),
        ((z, I, z, bad_rot), "rot_b"),
    ):
        batch = (args[0][None], args[1][None], args[2][None], args[3][None])
        for query, batched in ((col.collide_pair, False), (col.collide, False), (col.collide, True)):
            with pytest.raises(ValueError, match="^" + first + (r"\[0\]" if batched else " ")):
                query(*(batch if batched else args))


@pytest.mark.parametrize("dtype", [np.float64, np.float32, "list"])
def test_a_wrong_shape_gets_one_message_whatever_the_dtype(dtype):
    # The message depended on the dtype: "pos_a has shape (1, 3); collide_pair takes (3,)" for arrays of
    # the Collider's dtype, "pos_a is a batch of 1" for others.
    col = pb.Collider(pb.Prism.regular(4, 1.0), pb.Prism.regular(4, 1.0))
    I, z = np.eye(3), np.zeros(3)
    col.collide_pair(z, I, z, I)

    def as_given(x):
        return np.asarray(x).tolist() if dtype == "list" else np.asarray(x, dtype=dtype)

    with pytest.raises(
        ValueError, match=r"^collide_pair takes one pose per body; pos_a is a batch of 1 \(use collide\)"
    ):
        col.collide_pair(as_given(np.zeros((1, 3))), as_given(I), z, I)
    with pytest.raises(ValueError, match=r"^pos_b has shape \(2,\); expected \(3,\) or \(N, 3\)"):
        col.collide_pair(z, I, as_given(np.zeros(2)), as_given(I))
