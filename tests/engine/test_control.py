"""Detach controller: each row of eq. (42) on a constructed contact, and the
check that a small step of b along the detach direction reduces the
penetration, measured with the exact LP margin (tests/reference.py)."""

import numpy as np
import pytest

import prismbatch as pb
from prismbatch.control import CONTACT_CLASSES, detach
from prismbatch.sampling import random_rotations

from reference import margin_lp

A = pb.Prism([[-1, -1], [1, -1], [1, 1], [-1, 1]])  # square, side 2
B = pb.Prism([[-0.4, -0.4], [0.4, -0.4], [0.4, 0.4], [-0.4, 0.4]])
DOWN = np.diag([1.0, -1.0, -1.0])  # a's axis points down: a's body is z <= 0, its end face z = 0
S2 = np.sqrt(0.5)


def rot_from_axis(d, spin=0.0):
    """A rotation whose third column is d (unit), spun about d."""
    d = np.asarray(d, float) / np.linalg.norm(d)
    helper = np.array([1.0, 0, 0]) if abs(d[0]) < 0.9 else np.array([0, 1.0, 0])
    x = np.cross(helper, d)
    x /= np.linalg.norm(x)
    y = np.cross(d, x)
    c, s = np.cos(spin), np.sin(spin)
    return np.column_stack([c * x + s * y, -s * x + c * y, d])


def test_every_class_is_described():
    assert set(CONTACT_CLASSES) == set(range(7))


@pytest.mark.parametrize(
    "point, cls, direction",
    [
        ([1, 1, 0], 1, [0, 0, 1]),  # vertex of the end face, d_b = +z: leave along b's axis
        ([0, 1, 0], 2, [0, 0, 1]),  # end-face edge
        ([1, 1, -0.5], 3, [S2, S2, 0]),  # lateral edge: outward bisector
        ([1, 0.2, -0.5], 4, [1, 0, 0]),  # side face: outward normal
        ([-0.3, 0.1, 0], 5, [0, 0, 1]),  # end face: -d_a
        ([0.2, 0.1, -0.3], 6, [0, 0, 1]),  # inside, end face nearest
        ([0.95, 0.1, -0.7], 6, [1, 0, 0]),  # inside, side face nearest
    ],
)
def test_rows_of_eq42_on_given_points(point, cls, direction):
    r = detach(A, np.array([point], float), np.zeros(3), DOWN, np.eye(3), [[3.0, 4.0, 0.0]], eps=10.0)
    assert r.contact_class[0] == cls
    np.testing.assert_allclose(r.direction[0], direction, atol=1e-12)
    np.testing.assert_allclose(r.force[0], 10.0 * 5.0 * np.asarray(direction), atol=1e-9)


def test_vertex_and_edge_rows_follow_b_axis_unless_it_points_into_a():
    # eqs. (43)-(46): d_b projected normal to the edge; if that points into a
    # the direction turns to the normal of the edge and d_v, out of a.
    tilted_out = rot_from_axis([0.3, 0.0, 1.0])
    r = detach(A, [[1, 0, 0]], np.zeros(3), DOWN, tilted_out, [1.0])
    assert r.contact_class[0] == 2
    d = r.direction[0]
    np.testing.assert_allclose(d, np.array([0.3, 0, 1]) / np.hypot(0.3, 1), atol=1e-12)
    tilted_in = rot_from_axis([-0.3, 0.0, 1.0])  # projected axis points over a's end face
    r = detach(A, [[1, 0, 0]], np.zeros(3), DOWN, tilted_in, [1.0])
    d = r.direction[0]
    assert abs(d @ [0, 1, 0]) < 1e-12  # normal to the edge (along y)
    assert d @ np.array([1.0, 0, 1.0]) > 0  # out of a: between its side normal and -d_a
    assert abs(d @ (np.array([-0.3, 0, 1]) / np.hypot(0.3, 1))) < 1e-12


def test_no_contact_rows_are_nan():
    r = detach(A, [[np.nan] * 3, [0, 0, 0]], np.zeros(3), DOWN, np.eye(3), [1.0, 1.0])
    assert r.contact_class.tolist() == [0, 5]
    assert np.isnan(r.direction[0]).all() and np.isnan(r.force[0]).all()


def _touching_scenes():
    """b poses whose collide contact lies on each feature class of a."""
    return {
        # b facing a, end faces coplanar, b's face inside a's: contact on a's end face
        5: (np.array([0.2, -0.1, 0.0]), np.eye(3)),
        # b's end face against a's side face x = 1 (b's axis along +x), below a's top
        4: (np.array([1.0, 0.1, -1.0]), rot_from_axis([1, 0, 0])),
        # b's end face against a's lateral edge at (1, 1): the plane x + y = 2 touches only the edge
        3: (np.array([1.0, 1.0, -1.0]), rot_from_axis([S2, S2, 0])),
        # b tilted so its lowest vertex sits on a's vertex (1, 1, 0)
        1: None,
        # b tilted about y: its lowest edge (along y) lies on a's end-face edge x = 1
        2: (np.array([1.0 - 0.4 * np.cos(0.3), 0.2, 0.4 * np.sin(0.3)]), rot_from_axis([np.sin(0.3), 0, np.cos(0.3)])),
        # b deep inside a
        6: (np.array([0.0, 0.0, -0.5]), np.eye(3)),
    }


def _vertex_scene():
    Rb = rot_from_axis([0.3, 0.2, 1.0], spin=0.4)
    lowest = B.xy[np.argmin((Rb[:, :2] @ B.xy.T)[2])]
    pos_b = np.array([1.0, 1.0, 0.0]) - Rb[:, :2] @ lowest
    return pos_b, Rb


@pytest.mark.parametrize("cls", [1, 2, 3, 4, 5, 6])
def test_small_step_along_detach_direction_reduces_penetration(cls):
    scene = _touching_scenes()[cls] or _vertex_scene()
    pos_b, Rb = scene
    r = pb.collide(A, B, np.zeros(3), DOWN, pos_b, Rb, contact=True)
    assert r.hit[0]
    d = detach(A, r.contact, np.zeros(3), DOWN, Rb, [1.0], tol=1e-7)
    assert d.contact_class[0] == cls, CONTACT_CLASSES[int(d.contact_class[0])]
    h = 1e-3
    before = margin_lp(A.xy, np.zeros(3), DOWN, B.xy, pos_b, Rb)
    after = margin_lp(A.xy, np.zeros(3), DOWN, B.xy, pos_b + h * d.direction[0], Rb)
    assert after < before - 0.1 * h


@pytest.mark.slow  # the full suite; the fast set keeps a lighter test of the same path
def test_fraction_of_random_colliding_pairs_where_a_step_reduces_penetration():
    rng = np.random.default_rng(2)
    n = 400
    a = pb.Prism.regular(6, 1.0)
    b = pb.Prism.regular(5, 0.6)
    pos_b = rng.uniform(-1.2, 1.2, (n, 3))
    Rb = random_rotations(n, rng)
    r = pb.collide(a, b, np.zeros(3), DOWN, pos_b, Rb, contact=True)
    idx = np.flatnonzero(r.hit)
    d = detach(a, r.contact[idx], np.zeros(3), DOWN, Rb[idx], np.ones(len(idx)))
    h = 1e-3
    ok = 0
    for j, i in enumerate(idx):
        before = margin_lp(a.xy, np.zeros(3), DOWN, b.xy, pos_b[i], Rb[i])
        after = margin_lp(a.xy, np.zeros(3), DOWN, b.xy, pos_b[i] + h * d.direction[j], Rb[i])
        ok += after < before - 1e-9
    frac = ok / len(idx)
    print(
        f"\nstep of 1e-3 along the detach direction reduced the LP margin in {ok}/{len(idx)} "
        f"random colliding pairs ({100 * frac:.1f} %); classes {np.bincount(d.contact_class, minlength=7)}"
    )
    assert len(idx) > 100
    assert frac > 0.5


def test_batch_size_mismatch_is_named():
    with pytest.raises(ValueError, match="contact has 3 rows, state_error 2"):
        detach(A, np.zeros((3, 3)), np.zeros(3), DOWN, np.eye(3), np.ones((2, 3)))
    with pytest.raises(ValueError, match="contact has 3 rows"):
        detach(A, np.zeros((3, 3)), np.zeros((4, 3)), DOWN, np.eye(3), np.ones(4))


def test_single_pair_error_vector_and_broadcast_contacts():
    r = detach(A, [0.2, 0.1, -0.3], np.zeros(3), DOWN, np.eye(3), [3.0, 4.0, 0.0])
    np.testing.assert_allclose(r.force[0], [0, 0, 50.0], atol=1e-12)
    r = detach(A, np.array([[1, 0.2, -0.5], [0, 0, 0]]), np.zeros(3), DOWN, np.eye(3), [1.0, 2.0])
    assert r.contact_class.tolist() == [4, 5]
    np.testing.assert_allclose(np.linalg.norm(r.force, axis=1), [10.0, 20.0])


def _detach_one(**kw):
    """One contact on a's end face (class 5), |state error| = 5."""
    return detach(A, [[-0.3, 0.1, 0.0]], np.zeros(3), DOWN, np.eye(3), [3.0, 4.0, 0.0], **kw)


def _detach_three(**kw):
    pts = [[-0.3, 0.1, 0.0], [1, 0.2, -0.5], [0.2, 0.1, -0.3]]
    return detach(A, pts, np.zeros(3), DOWN, np.eye(3), [1.0, 2.0, 3.0], **kw)


@pytest.mark.parametrize("tol", [1e-7, [1e-7], np.float32(1e-7), 0, np.array(1e-7)])
def test_tol_scalar_or_one_value(tol):
    assert _detach_one(tol=tol).contact_class.tolist() == [5]


def test_tol_one_per_pair():
    assert _detach_three(tol=[1e-7, 1e-7, 1e-7]).contact_class.tolist() == [5, 4, 6]
    # per pair: a tolerance of 0.6 puts the third contact (0.3 below the end face) on the end face
    assert _detach_three(tol=np.array([1e-7, 1e-7, 0.6])).contact_class[2] == 5


@pytest.mark.parametrize(
    "tol, match",
    [
        ([], r"tol must be a scalar or have shape \(3,\) \(one per pair\), got shape \(0,\)"),
        ([1e-7, 1e-7], r"tol must be .* got shape \(2,\)"),
        ([1e-7] * 4, r"tol must be .* got shape \(4,\)"),
        ([[1e-7], [1e-7], [1e-7]], r"tol must be .* got shape \(3, 1\)"),
        (np.full((1, 1), 1e-7), r"tol must be .* got shape \(1, 1\)"),
        (-1e-7, r"^tol must be finite and >= 0, got -1e-07"),
        (np.nan, r"^tol must be finite and >= 0, got nan"),
        ([1e-7, np.inf, -1.0], r"^tol\[1\] must be finite and >= 0, got inf"),
        ([1e-7, 1e-7, -1.0], r"^tol\[2\] must be finite and >= 0, got -1"),
        ([[1e-7, 1e-7, 1e-7]], r"got shape \(1, 3\)"),
    ],
)
def test_bad_tol_raises_value_error(tol, match):
    with pytest.raises(ValueError, match=match):
        _detach_three(tol=tol)


@pytest.mark.parametrize("tol", ["abc", "1e-7", ["1e-7"], [None], object(), True, [True, False, True], 1e-7 + 0j])
def test_non_numeric_tol_raises_type_error(tol):
    with pytest.raises(TypeError, match=r"^tol must have a real numeric dtype"):
        _detach_three(tol=tol)


def test_empty_tol_no_longer_reads_out_of_bounds():
    # Before: tol=[] read tol[-1] out of bounds and the class changed run to run.
    for _ in range(3):
        with pytest.raises(ValueError, match="got shape \\(0,\\)"):
            _detach_one(tol=[])


@pytest.mark.parametrize(
    "eps, exc, match",
    [
        (-1.0, ValueError, r"^eps must be finite and >= 0, got -1"),
        (np.nan, ValueError, r"^eps must be finite and >= 0, got nan"),
        (np.inf, ValueError, r"^eps must be finite and >= 0, got inf"),
        ([10.0], ValueError, r"^eps must be a scalar, got shape \(1,\)"),
        (np.ones(3), ValueError, r"^eps must be a scalar, got shape \(3,\)"),
        ("10", TypeError, r"^eps must be a real number, got str"),
        (None, TypeError, r"^eps must be a real number, got NoneType"),
        (True, TypeError, r"^eps must be a real number, got bool"),
    ],
)
def test_bad_eps(eps, exc, match):
    with pytest.raises(exc, match=match):
        _detach_one(eps=eps)


def test_eps_that_overflows_the_force_raises():
    with pytest.raises(ValueError, match=r"^eps = 1e\+308 gives pair 0 a non-finite force"):
        _detach_one(eps=1e308)
    # The first pair whose force overflows is named; pairs without contact do not count.
    with pytest.raises(ValueError, match=r"gives pair 2 a non-finite force"):
        detach(A, [[np.nan] * 3, [0, 0, 0], [0, 0, 0]], np.zeros(3), DOWN, np.eye(3), [1e150, 1.0, 1e150], eps=1e200)
    # A large finite product is fine, and eps = 0 gives zero force.
    r = _detach_one(eps=1e300)
    np.testing.assert_allclose(r.force[0], 5e300 * r.direction[0], rtol=1e-15)
    assert (_detach_one(eps=0).force == 0).all()
    assert _detach_one(eps=np.int64(2)).force[0] @ r.direction[0] == pytest.approx(10.0)


@pytest.mark.parametrize("point", [[50.0, 0.0, -5.0], [0.0, 0.0, 1e200], [0.0, 0.0, 0.3], [1.5, 0.0, -0.5]])
def test_points_that_are_not_contacts_of_a_are_refused(point):
    # Outside a (above its end face, beside its side faces) by far more than tol:
    # no class would be true of them.
    with pytest.raises(ValueError, match=r"contact\[0\] = .* lies outside a .*not a contact point of a"):
        detach(A, [point], np.zeros(3), DOWN, np.eye(3), [1.0, 0.0, 0.0])


def test_contacts_from_collide_are_never_refused():
    rng = np.random.default_rng(11)
    pos_b = rng.uniform(-1.5, 1.5, (3000, 3))
    Rb = random_rotations(3000, rng)
    r = pb.collide(A, B, np.zeros(3), DOWN, pos_b, Rb, contact=True)
    d = detach(A, r.contact, np.zeros(3), DOWN, Rb, np.ones(3000))
    assert r.hit.sum() > 300
    np.testing.assert_array_equal(d.contact_class == 0, ~r.hit)


def test_contact_rows_are_finite_or_all_nan():
    with pytest.raises(ValueError, match=r"contact\[1\] = \[0\.5, 0\.0, nan\]: a contact is finite, or all NaN"):
        detach(A, [[0.0, 0.0, 0.0], [0.5, 0.0, np.nan]], np.zeros(3), DOWN, np.eye(3), np.ones(2))
    for bad in (np.zeros((1, 3), complex), np.array([["a", "b", "c"]]), np.zeros((1, 3), bool)):
        with pytest.raises(TypeError, match="contact must have a real numeric dtype"):
            detach(A, bad, np.zeros(3), DOWN, np.eye(3), np.ones(1))
    with pytest.raises(TypeError, match="state_error must have a real numeric dtype"):
        detach(A, np.zeros((1, 3)), np.zeros(3), DOWN, np.eye(3), np.ones(3, complex))


def test_empty_batch_gives_empty_results():
    d = detach(A, np.zeros((0, 3)), np.zeros(3), DOWN, np.eye(3), np.zeros((0, 3)))
    assert d.contact_class.shape == (0,) and d.force.shape == (0, 3)


def test_parallel_flag_is_a_bool():
    with pytest.raises(TypeError, match="parallel must be True, False or None"):
        _detach_one(parallel="no")


def test_detach_from_a_distance_uses_where_the_bodies_really_touch():
    """With a distance result, the contact is on a's boundary (never class 6), the direction is the
    penetration normal, and pushing b out along it by the depth leaves the bodies touching."""
    from prismbatch.distance import distance
    from prismbatch.sampling import free_poses

    rng = np.random.default_rng(7)
    a, b = pb.Prism.regular(12, 2.0), pb.Prism.regular(9, 2.5)
    P = free_poses(400, rng, radius=2.5)
    d = distance(a, b, *P, witness=True)
    res = detach(a, d, P[0], P[1], P[3], np.ones((400, 3)), tol=d.tol)
    contact = d.status <= 0
    assert contact.sum() > 50 and (~contact).sum() > 50
    assert np.all(res.contact_class[~contact] == 0) and np.all(np.isnan(res.direction[~contact]))
    assert np.all((res.contact_class[contact] >= 1) & (res.contact_class[contact] <= 5))
    np.testing.assert_array_equal(res.direction[contact], d.normal[contact])
    np.testing.assert_allclose(res.depth[contact], np.maximum(-d.distance[contact], 0.0))
    pushed = P[2][contact] + res.depth[contact, None] * res.direction[contact]
    after = distance(a, b, P[0][contact], P[1][contact], pushed, P[3][contact])
    assert np.all(np.abs(after.distance) <= 10 * after.tol)
    with pytest.raises(ValueError, match="witness=True"):
        detach(a, distance(a, b, *P), P[0], P[1], P[3], np.ones((400, 3)))


def _classes_by_plain_search(xy, pos, rot, points, tol):
    """The contact class of each point, by a plain search over every vertex and edge of a (the test's reference).

    a's frame by solving with the matrix as given; on the end face or above it (z <= tol); near a vertex or
    an edge within tol; a point beside the polygon that is near neither takes its nearest vertex or edge;
    inside otherwise. Returns (classes, margin): margin is how far each point's deciding distances lie from
    tol, in units of tol (points near a threshold are left out of the comparison).
    """
    v = np.asarray(xy, float)
    u, w = v[1] - v[0], v[2] - v[1]
    if u[0] * w[1] - u[1] * w[0] < 0:
        v = v[::-1]
    e = np.roll(v, -1, axis=0) - v
    n = np.column_stack([e[:, 1], -e[:, 0]]) / np.hypot(e[:, 0], e[:, 1])[:, None]
    classes, margins = [], []
    for p in points:
        x, y, z = np.linalg.solve(rot, p - pos)
        q = np.array([x, y])
        dv = np.hypot(*(q - v).T).min()
        f = np.clip(((q - v) * e).sum(axis=1) / (e * e).sum(axis=1), 0.0, 1.0)
        seg = np.hypot(*(q - v - f[:, None] * e).T)
        k = int(np.argmin(seg))
        de = seg[k]
        inside = ((q - v) * n).sum(axis=1).max()  # > 0: outside the polygon
        on_end, near_v, near_e = z <= tol, dv <= tol, de <= tol
        if inside > 0 and not (near_v or near_e):
            near_v, near_e = f[k] in (0.0, 1.0), f[k] not in (0.0, 1.0)
        c = (1 if near_v else 2 if near_e else 5) if on_end else (3 if near_v else 4 if near_e else 6)
        classes.append(c)
        # (and the side of the polygon's outline, exact by its sign, away from rounding)
        margins.append(min(abs(d - tol) / tol for d in (z, dv, de)) if abs(inside) > 1e-3 * tol else 0.0)
    return np.array(classes), np.array(margins)


@pytest.mark.parametrize("rotations", ["float64", "float32", "far", "thin"])
def test_classes_against_a_plain_search_over_every_feature(rotations):
    """Random convex polygons, points at each kind of feature (on it, just inside, just outside, above the end
    face, deep inside) against the plain search. ``float32``: float32 rotation matrices, orthonormal only to
    about 1e-7, which the kernel once inverted by their transpose and put 1,811 of 2,000 vertex contacts in
    class 6. ``far``: the polygon 1e6 from its own origin, which the default tol once left out of its
    rounding floor. ``thin``: flat 300-gons with a tol larger than their edges, where the nearest edge can
    lie beyond the contact's polar wedge's neighbours (309 of 7,119 points were misclassified)."""
    rng = np.random.default_rng({"float64": 1, "float32": 2, "far": 3, "thin": 4}[rotations])
    tol = 0.02 if rotations == "thin" else 1e-6
    checked = 0
    for trial in range(30):
        m = 300 if rotations == "thin" else int(rng.integers(3, 40))
        ang = np.sort(rng.uniform(0, 2 * np.pi, m))
        flat = rng.uniform(0.04, 0.1) if rotations == "thin" else rng.uniform(0.3, 1.0)
        xy = np.column_stack([np.cos(ang), flat * np.sin(ang)])
        if rotations == "far":
            xy = xy + rng.uniform(-1e6, 1e6, 2)
        try:
            a = pb.Prism(xy)
        except ValueError:  # a sliver the package refuses
            continue
        v = a.xy
        R = random_rotations(1, rng)[0]
        pos = rng.uniform(-100, 100, 3)
        if rotations == "float32":  # (exactly the float32 numbers, read in float64 by the reference)
            R, pos = R.astype(np.float32).astype(np.float64), pos.astype(np.float32).astype(np.float64)
        local = []
        for _ in range(40):
            kind = rng.integers(6)
            j = int(rng.integers(len(v)))
            e = v[(j + 1) % len(v)] - v[j]
            if kind == 0:  # at a vertex
                q = v[j]
            elif kind in (1, 5):  # on an edge; or (5) inside, within tol of it, deep in the body
                q = v[j] + rng.uniform(0.05, 0.95) * e
                if kind == 5:
                    q = q + np.array([-e[1], e[0]]) / np.hypot(*e) * rng.uniform(0.1, 0.9) * tol
            else:  # the end face's inside
                q = v.mean(axis=0) + rng.uniform(0.0, 0.98) * (v[j] - v.mean(axis=0))
            z = {
                0: 0.0,
                1: 0.0,
                2: 0.0,
                3: rng.uniform(0.01, 0.5),
                4: -rng.uniform(0, 3e-5),
                5: rng.uniform(0.05, 0.5),
            }[kind]
            if rotations == "thin":  # within tol of the point built: outside a by less than the refusal margin
                u = rng.normal(size=3)
                offset = u / np.linalg.norm(u) * rng.choice([0.1, 0.5, 0.9]) * tol
            else:
                offset = rng.normal(size=3) * rng.choice([0.1 * tol, 10 * tol, 1e-5])
            local.append(np.array([q[0], q[1], z]) + offset)
        points = pos + (R @ np.array(local).T).T
        want, margin = _classes_by_plain_search(v, pos, R, points, tol)
        rot32 = R.astype(np.float32) if rotations == "float32" else R
        got = detach(a, points, pos.astype(rot32.dtype), rot32, np.eye(3), np.ones(len(points)), tol=tol)
        clear = margin > 0.5
        np.testing.assert_array_equal(got.contact_class[clear], want[clear])
        checked += int(clear.sum())
    assert checked >= 500


def test_default_tol_covers_a_polygon_far_from_its_origin():
    """Contacts at the vertices of a square placed 1e8 from a's own origin, turned (their world coordinates
    rounded, by about 1e-8): the same class (vertex) as with the offset in a's position. The default tol's
    rounding floor had left the polygon's offset out, and they came back as side faces and "inside"."""
    R = random_rotations(1, np.random.default_rng(1))[0]
    sq = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
    off = np.array([1e8, 1e8])
    for shape, pos in ((pb.Prism(sq), R[:, :2] @ off), (pb.Prism(sq + off), np.zeros(3))):
        xy = sq if pos.any() else sq + off
        world = pos + np.c_[xy, np.zeros(4)] @ R.T
        r = detach(shape, world, pos, R, R, np.ones(4))
        assert r.contact_class.tolist() == [1, 1, 1, 1]


def test_a_point_just_outside_a_touches_it_where_it_is_nearest():
    """Within the refusal margin but beyond tol outside a (collide's contact lies within collide's own
    tolerance, which can exceed detach's): classified by a's nearest feature, never "inside" (class 6)."""
    for point, cls in (([0.2, 0.1, 1e-6], 5), ([1.0 + 1e-6, 0.3, -0.5], 4), ([1 + 1e-6, 1 + 1e-6, 1e-6], 1)):
        r = detach(A, [point], np.zeros(3), DOWN, np.eye(3), [1.0])
        assert r.contact_class[0] == cls and r.depth[0] == 0.0, point


def test_state_error_norms_and_the_batch_they_belong_to():
    """(N,) state errors with one contact and N poses are N norms (the batch is N pairs); norms far from 1 are
    taken without squaring them (1e-200 underflowed to a force of 0, 1e200 overflowed and was refused)."""
    r = detach(A, [[0.2, 0.1, 0.0]], np.zeros((3, 3)), DOWN, np.eye(3), [1.0, 2.0, 3.0])
    np.testing.assert_allclose(np.linalg.norm(r.force, axis=1), [10.0, 20.0, 30.0])
    r = detach(A, [[0.2, 0.1, 0.0]] * 2, np.zeros(3), DOWN, np.eye(3), [[1e-200, 0.0], [3e-170, 4e-170]], eps=1e200)
    np.testing.assert_allclose(np.linalg.norm(r.force, axis=1), [1.0, 5e30], rtol=1e-14)
    r = detach(A, [[0.2, 0.1, 0.0]], np.zeros(3), DOWN, np.eye(3), [[3e200, 4e200]], eps=1e-100)
    assert np.linalg.norm(r.force[0]) == pytest.approx(5e100, rel=1e-14)


def test_a_collision_result_or_a_shared_contact_is_named_plainly():
    r = pb.collide(A, B, np.zeros(3), DOWN, [0.0, 0.0, -0.1], np.eye(3), contact=True)
    with pytest.raises(TypeError, match=r"got a CollisionResult; pass collide\(\.\.\., contact=True\)\.contact"):
        detach(A, r, np.zeros(3), DOWN, np.eye(3), [1.0])
    # one contact for three poses, not on a at the third: the pair is named, not a row the contact lacks
    with pytest.raises(ValueError, match=r"^contact \(of pair 2\) = "):
        detach(A, [[0.2, 0.1, 0.0]], [[0, 0, 0], [0, 0, 0], [50.0, 0, 0]], DOWN, np.eye(3), np.ones(3))
