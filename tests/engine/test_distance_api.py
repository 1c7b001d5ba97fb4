"""``prismbatch.distance``'s API: pose forms and broadcasting, per-pair shapes, serial and parallel
kernels and threads, the batch's EPA room and its rerun, the tolerance, float32, the result object and
refused input (the accuracy contract itself: ``test_distance.py``).
"""

from __future__ import annotations

import importlib

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import prismbatch as pb
from prismbatch.distance import (
    AXES_DEPTH,
    PENETRATING,
    SEPARATED,
    DistanceResult,
    distance,
)
from prismbatch.geometry import pair_scale_tolerance
from prismbatch.sampling import free_poses

from helpers import (
    R_DOWN,
    count_pairs_sent,
    distance_with_witnesses,
    make_pairs,
    random_polygon,
    random_rotations,
)


def test_pose_forms_and_broadcasting_match_matrices():
    rng = np.random.default_rng(23)
    a, b = pb.Prism.regular(7, 1.0), pb.Prism(random_polygon(rng, 9))
    n = 50
    Ra, Rb = random_rotations(rng, n), random_rotations(rng, n)
    pa, pbb = rng.uniform(-1, 1, (n, 3)), rng.uniform(-2, 2, (n, 3))
    base = distance(a, b, pa, Ra, pbb, Rb, witness=True)
    T_a, T_b = np.tile(np.eye(4), (n, 1, 1)), np.tile(np.eye(4), (n, 1, 1))
    T_a[:, :3, :3], T_a[:, :3, 3], T_b[:, :3, :3], T_b[:, :3, 3] = Ra, pa, Rb, pbb
    q_a, q_b = Rotation.from_matrix(Ra), Rotation.from_matrix(Rb)
    for other in (
        distance(a, b, T_a, T_b, witness=True),
        distance(a, b, pa, q_a, pbb, q_b, witness=True),
        distance(a, b, pa, q_a.as_quat(), pbb, q_b.as_quat(), quat_order="xyzw", witness=True),
        distance(a, b, pa, q_a.as_quat(scalar_first=True), pbb, q_b.as_quat(scalar_first=True), quat_order="wxyz",
                 witness=True),
    ):  # fmt: skip
        np.testing.assert_allclose(other.distance, base.distance, rtol=0, atol=10 * base.tol.max())
        np.testing.assert_allclose(other.normal, base.normal, rtol=0, atol=1e-6)
    one = distance(a, b, pa[0], Ra[0], pbb, Rb)  # a single pose for a broadcasts
    ref = distance(a, b, np.repeat(pa[:1], n, 0), np.repeat(Ra[:1], n, 0), pbb, Rb)
    np.testing.assert_array_equal(one.distance, ref.distance)
    assert len(distance(a, b, pa[0], Ra[0], pbb[0], Rb[0])) == 1


def test_per_pair_shapes_match_single_prisms():
    rng = np.random.default_rng(29)
    d = make_pairs(rng, 30, "free", "smallmed")
    r = distance_with_witnesses(d)
    for k in range(len(d)):
        one = distance(pb.Prism(d.polys_a[k]), pb.Prism(d.polys_b[k]), d.pos_a[k], d.rot_a[k], d.pos_b[k], d.rot_b[k])
        assert one.distance[0] == r.distance[k]


def test_serial_and_parallel_agree_exactly():
    rng = np.random.default_rng(31)
    d = make_pairs(rng, 300, "facing", "smallmed")
    s, p = distance_with_witnesses(d, parallel=False), distance_with_witnesses(d, parallel=True)
    for name in ("distance", "status", "tol", "solver", "normal", "point_a", "point_b"):
        np.testing.assert_array_equal(getattr(s, name), getattr(p, name))


def test_a_thread_reuses_its_workspace_and_threads_keep_their_own():
    """Serial calls reuse the calling thread's GJK and EPA workspace: a batch gives the same outputs to
    the bit after other batches (deep, shallow, apart) in the same thread and while four threads run
    other batches at the same time (the kernels hold the GIL today: that part guards a move to nogil)."""
    import threading

    rng = np.random.default_rng(47)
    col = pb.Collider(pb.Prism.regular(36, 2.0), pb.Prism.regular(37, 2.5))
    pa, ra, pbb, rb = free_poses(240, rng, radius=2.5)
    batches = [(pa, ra, pa + t * (pbb - pa), rb) for t in (0.2, 0.9, 1.0, 3.0)]
    alone = [col.distance(*P, witness=True, parallel=False) for P in batches]
    again, errors = {}, []

    def worker(k):
        try:
            for _ in range(3):
                again[k] = col.distance(*batches[k], witness=True, parallel=False)
        except Exception as exc:  # (reported below: an exception in a thread is otherwise lost)
            errors.append(exc)

    threads = [threading.Thread(target=worker, args=(k,)) for k in range(len(batches))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    for k in range(len(batches)):
        for res in (again[k], col.distance(*batches[k], witness=True, parallel=False)):
            for name in ("distance", "status", "tol", "solver", "normal", "point_a", "point_b"):
                np.testing.assert_array_equal(getattr(res, name), getattr(alone[k], name))
    assert (alone[0].status == PENETRATING).sum() > 100 and (alone[3].status == SEPARATED).sum() > 100


@pytest.mark.parametrize("parallel", [False, True])
def test_pairs_out_of_the_batch_room_are_rerun(monkeypatch, parallel):
    """The batch loop runs EPA in a fixed room and reruns the pairs that run out of it with more:
    with the batch's room cut to 6 vertices, most penetrating pairs take the rerun, and every
    output is the same to the bit; except that pairs whose axes point the same way take the
    separating-axis depth where EPA stops, which agrees with EPA's depth (both exact) within tol."""
    dist_mod = importlib.import_module("prismbatch.distance")  # the module: the package's name is the function

    rng = np.random.default_rng(43)
    col = pb.Collider(pb.Prism.regular(36, 2.0), pb.Prism.regular(37, 2.5))
    pa, ra, pbb, rb = free_poses(400, rng, radius=2.5)
    poses = (pa, ra, pa + 0.2 * (pbb - pa), rb)  # mostly deep overlaps
    want = col.distance(*poses, witness=True, parallel=parallel)
    monkeypatch.setattr(dist_mod, "EPA_ROOM", (6,))
    rerun = count_pairs_sent(monkeypatch, dist_mod, "rerun_parallel" if parallel else "rerun_serial", 9)
    got = col.distance(*poses, witness=True, parallel=parallel)
    axes = got.solver == AXES_DEPTH
    assert rerun and rerun[0] > 100 and (want.solver == 1).sum() > 200 and axes.sum() > 50
    assert (np.einsum("ij,ij->i", ra[:, :, 2], rb[:, :, 2]) > 0)[axes].all()
    for name in ("distance", "status", "tol", "solver", "normal", "point_a", "point_b"):
        np.testing.assert_array_equal(getattr(got, name)[~axes], getattr(want, name)[~axes])
    assert (np.abs(got.distance - want.distance) <= got.tol)[axes].all()
    np.testing.assert_allclose(got.point_b - got.point_a, got.distance[:, None] * got.normal, rtol=0, atol=1e-12)


def test_tolerance_is_collides():
    rng = np.random.default_rng(37)
    a, b = pb.Prism(random_polygon(rng, 6)), pb.Prism(random_polygon(rng, 11))
    Ra, Rb = random_rotations(rng, 40), random_rotations(rng, 40)
    pa, pbb = rng.uniform(-5, 5, (40, 3)), rng.uniform(-5, 5, (40, 3))
    for rtol, atol in ((None, 0.0), (1e-6, 1e-3)):
        r = distance(a, b, pa, Ra, pbb, Rb, rtol=rtol, atol=atol)
        _, tol = pair_scale_tolerance(a, b, pa, Ra, pbb, Rb, rtol=rtol, atol=atol)
        np.testing.assert_allclose(r.tol, tol, rtol=1e-12)


def test_float32_agrees_within_its_tolerance():
    rng = np.random.default_rng(41)
    d = make_pairs(rng, 100, "free", "smallmed")
    r64 = distance_with_witnesses(d)
    r32 = distance_with_witnesses(d, dtype=np.float32)
    assert (r32.tol > 1e-6 * d.scale).all()
    assert (np.abs(r32.distance - r64.distance) <= 10 * r32.tol).all()


def test_result_object():
    a = pb.Prism.regular(4, 1.0)
    r = distance(a, a, [0, 0, 0], R_DOWN, [[0, 0, 0.5], [0, 0, -0.25], [3.0, 0, 0]], np.eye(3))
    np.testing.assert_allclose(r.distance, [0.5, -0.25, 1.0], rtol=0, atol=1e-12)
    assert r.status.tolist() == [SEPARATED, PENETRATING, SEPARATED]
    with pytest.raises(AttributeError, match="witness=True"):
        r.normal
    one = r[1]
    assert isinstance(one, DistanceResult) and len(one) == 1 and one.distance[0] == r.distance[1]
    assert len(r[r.distance > 0]) == 2
    with pytest.raises(IndexError):
        r[3]
    for k in (True, np.True_, None, (0, 1)):  # (True read as pair 1, None added an axis to every field)
        with pytest.raises(TypeError, match="pairs are selected"):
            r[k]
    w = distance(a, a, [0, 0, 0], R_DOWN, [[0, 0, 0.5]], np.eye(3), witness=True)
    cols = w.columns()
    assert set(cols) >= {"distance", "status", "tol", "solver", "normal_z", "point_a_x", "point_b_y"}
    np.testing.assert_allclose(w.normal[0], [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(w.point_b[0, 2] - w.point_a[0, 2], 0.5, atol=1e-12)
    assert "1 pair" in repr(w) and "witnesses" in repr(w)


def test_bad_input_is_refused():
    a = pb.Prism.regular(5, 1.0)
    with pytest.raises(ValueError, match="batch sizes do not match"):
        distance(a, a, np.zeros((3, 3)), np.eye(3), np.zeros((4, 3)), np.eye(3))
    with pytest.raises((TypeError, ValueError), match="witness"):
        distance(a, a, np.zeros(3), np.eye(3), np.zeros(3), np.eye(3), witness="yes")
    with pytest.raises(ValueError, match="pos_b"):
        distance(a, a, np.zeros(3), np.eye(3), [np.nan, 0, 0], np.eye(3))
    with pytest.raises(ValueError, match="rot_a"):
        distance(a, a, np.zeros(3), 2 * np.eye(3), np.zeros(3), np.eye(3))
    with pytest.raises(TypeError, match="pose for b"):
        distance(a, a, np.zeros(3), np.eye(3))
    with pytest.raises(TypeError):
        distance(a, a, np.zeros(3), np.eye(3), np.zeros(3), np.eye(3), dtype=np.int32)
    with pytest.raises(ValueError, match="rtol"):
        distance(a, a, np.zeros(3), np.eye(3), np.zeros(3), np.eye(3), rtol=-1.0)
