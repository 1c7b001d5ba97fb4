"""Every bad input raises a clear error that names what is wrong and where."""

import re

import numpy as np
import pytest

import prismbatch as pb

SQ = [[0, 0], [1, 0], [1, 1], [0, 1]]
A = pb.Prism.regular(5, 2.0)
B = pb.Prism.regular(6, 2.5)
I3 = np.eye(3)


@pytest.mark.parametrize(
    "xy, exc, match",
    [
        ([[0, 0], [2, 0], [1, 0.2], [2, 2], [0, 2]], ValueError, r"not convex at vertex 2"),
        # Pentagram: every turn is left, but the outline winds twice.
        ([[np.cos(a), np.sin(a)] for a in np.arange(5) * 4 * np.pi / 5], ValueError, "self-intersecting"),
        ([[0, 0], [1, 0]], ValueError, "at least 3 vertices"),
        ([[0, 0], [1, 1], [2, 2]], ValueError, "zero area"),
        ([[0, 0], [1, 0], [1, 0], [1, 1]], ValueError, r"vertex 2 repeats vertex 1"),
        ([[0, 0], [1, 0], [np.nan, 1]], ValueError, r"vertex 2 is not finite"),
        ([[0, 0], [1, 0], [np.inf, 1]], ValueError, r"vertex 2 is not finite"),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0]], ValueError, r"shape \(n, 2\)"),
        ([["a", "b"], ["c", "d"], ["e", "f"]], TypeError, "real numbers"),
        ([[0, 0], [0, 0], [0, 0]], ValueError, "coincide"),
    ],
)
def test_bad_polygon(xy, exc, match):
    with pytest.raises(exc, match=match):
        pb.Prism(xy)


def test_bad_polygon_in_set_names_its_index():
    with pytest.raises(ValueError, match=r"polygon 2: .*not convex"):
        pb.PrismSet([SQ, SQ, [[0, 0], [2, 0], [1, 0.2], [2, 2], [0, 2]]])


def test_clockwise_is_the_only_repair():
    cw = np.array(SQ[::-1], float)
    p = pb.Prism(cw)
    np.testing.assert_array_equal(p.xy, cw[::-1])


def test_a_clockwise_polygon_is_told_by_its_own_vertex_numbers():
    """The convexity checks run on the counter-clockwise order; a message names the vertex as given."""
    ccw = [[2, 0], [1, 1.9], [2, 2], [0, 2], [0, 0]]  # dent at vertex 1
    with pytest.raises(ValueError, match="not convex at vertex 1 "):
        pb.Prism(ccw)
    with pytest.raises(ValueError, match="not convex at vertex 3 "):
        pb.Prism(ccw[::-1])  # the same dent, now vertex 3
    with pytest.raises(ValueError, match=r"polygon 1: polygon is not convex at vertex 3 "):
        pb.PrismSet([SQ, ccw[::-1]])


def test_regular_arguments():
    with pytest.raises(ValueError, match=r"n must be in \[3, "):
        pb.Prism.regular(2, 1.0)
    with pytest.raises(ValueError, match=r"n must be in \[3, 10,000,000\], got 1000000000000"):
        pb.Prism.regular(10**12, 1.0)  # a clear limit, not a MemoryError
    for n in (3.7, "5", True):
        with pytest.raises(TypeError, match="n must be an integer"):
            pb.Prism.regular(n, 1.0)
    with pytest.raises(ValueError, match="radius"):
        pb.Prism.regular(5, -1.0)
    with pytest.raises(TypeError, match="radius must be a real number"):
        pb.Prism.regular(5, "1")
    with pytest.raises(ValueError, match="radius must be a scalar"):
        pb.Prism.regular(5, np.array([1.0, 2.0]))
    with pytest.raises(ValueError, match="centre must be 2 finite numbers"):
        pb.Prism.regular(5, 1.0, centre=(0, 0, 0))
    assert pb.Prism.regular(np.int64(5), np.float32(2)).n_vertices == 5
    assert pb.Prism.regular(np.int8(5), 1.0).n_vertices == 5  # (its memory estimate overflowed int8)
    with pytest.raises(ValueError, match=r"n must be in \[3, 10,000,000\], got 2000000000"):
        pb.Prism.regular(np.int32(2 * 10**9), 1.0)
    # Polygons whose extent overflows float64: their edges (and the kernels' tables) would be inf, with
    # overflow warnings; refused by name at construction, not first by collide.
    huge = [[-1.7e308, 0.0], [1.7e308, 0.0], [0.0, 1.7e308]]
    with pytest.raises(ValueError, match="prism: its extent overflows float64"):
        pb.Prism(huge)
    with pytest.raises(ValueError, match="polygon 1: its extent overflows float64"):
        pb.PrismSet([[[0, 0], [1, 0], [0, 1]], huge])
    with pytest.raises(ValueError, match="its extent overflows float64"):
        pb.Prism.regular(5, 1.7e308)
    assert np.isfinite(pb.Prism.regular(5, 1e307).radius)


def test_ragged_polygon_names_the_argument():
    with pytest.raises(ValueError, match=r"^prism: vertices could not be read"):
        pb.Prism([[0, 0], [1, 0, 3], [0, 1]])


def test_thin_polygons_get_the_right_message():
    # A true repeat and true collinearity (exact) keep their messages ...
    with pytest.raises(ValueError, match="vertex 2 repeats vertex 1"):
        pb.Prism([[0, 0], [1, 0], [1, 0], [0, 1]])
    with pytest.raises(ValueError, match="zero area"):
        pb.Prism([[0, 0], [1e10, 1e-3], [2e10, 2e-3]])
    # ... a sliver beyond the supported aspect is named as such, not as "zero area".
    with pytest.raises(ValueError, match="too thin"):
        pb.Prism([[0, 0], [1e10, 0], [1e10, 1e-3], [0, 1e-3]])
    with pytest.raises(ValueError, match="edge 1 is .* below the supported 1e-14: merge vertices 1 and 2"):
        pb.Prism([[0, 0], [1e10, 0], [1e10, 1e-5], [0, 1e-5]])
    assert pb.Prism([[0, 0], [1e10, 0], [1e10, 1e-2], [0, 1e-2]]).n_vertices == 4


def _call(**kw):
    args = dict(pos_a=np.zeros(3), rot_a=I3, pos_b=np.zeros(3), rot_b=I3)
    args.update(kw)
    return pb.collide(A, B, args["pos_a"], args["rot_a"], args["pos_b"], args["rot_b"])


@pytest.mark.parametrize(
    "kw, match",
    [
        ({"pos_a": np.array([[0, 0, 0], [0, np.nan, 0]])}, r"pos_a\[1\].*non-finite"),
        ({"pos_b": np.array([np.inf, 0, 0])}, r"pos_b.*non-finite"),
        ({"rot_b": np.stack([I3, I3 * np.nan])}, r"rot_b\[1\].*non-finite"),
        ({"rot_a": I3 * 1.001}, r"rot_a.*not orthonormal"),
        ({"rot_b": np.stack([I3, I3, np.diag([1.0, 1.0, -1.0])])}, r"rot_b\[2\].*reflection"),
        ({"pos_a": np.zeros((5, 3)), "pos_b": np.zeros((7, 3))}, r"batch sizes do not match: pos_a has 5.*pos_b has 7"),
        ({"pos_a": np.zeros((3, 4))}, r"pos_a has shape \(3, 4\)"),
        ({"rot_a": np.zeros((3, 5))}, r"rot_a has shape \(3, 5\)"),
        ({"rot_a": np.array([1.0, 0, 0, 0])}, r"quat_order"),
    ],
)
def test_bad_pose(kw, match):
    with pytest.raises(ValueError, match=match):
        _call(**kw)


def test_bad_dtype_pose():
    with pytest.raises(TypeError, match="dtype"):
        _call(pos_a=np.array(["0", "0", "0"]))


def test_prismset_size_must_match_batch():
    s = pb.PrismSet([SQ, SQ, SQ])
    with pytest.raises(ValueError, match=r"shape set has 3"):
        pb.collide(s, B, np.zeros((4, 3)), I3, np.zeros(3), I3)
    with pytest.raises(ValueError, match="different sizes"):
        pb.collide(s, pb.PrismSet([SQ, SQ]), np.zeros(3), I3, np.zeros(3), I3)


def test_bad_shape_argument_type():
    with pytest.raises(TypeError, match="shape_a must be a prismbatch.Prism or PrismSet"):
        pb.collide(SQ, B, np.zeros(3), I3, np.zeros(3), I3)


def test_bad_tolerance_and_dtype():
    call = lambda **kw: pb.collide(A, B, np.zeros(3), I3, np.zeros(3), I3, **kw)  # noqa: E731
    with pytest.raises(ValueError, match=r"rtol must be in \[0, 1\], got -1"):
        call(rtol=-1.0)
    with pytest.raises(ValueError, match=r"rtol must be in \[0, 1\], got 1e\+308"):
        call(rtol=1e308)  # the tolerance would overflow to inf: every pair a hit
    for bad in ("1e-9", True):
        with pytest.raises(TypeError, match="rtol must be a real number"):
            call(rtol=bad)
    with pytest.raises(TypeError, match="atol must be a real number"):
        call(atol=None)
    with pytest.raises(ValueError, match="atol must be a scalar"):
        call(atol=np.array([1.0, 2.0]))
    with pytest.raises(ValueError, match="atol must be in"):
        call(atol=np.nan)
    assert call(rtol=np.float32(1e-6), atol=np.array(0.0)).hit.tolist() == [True]
    for flag in ("parallel", "contact"):
        with pytest.raises(TypeError, match=f"{flag} must be True or False, got str 'no'"):
            call(**{flag: "no"})
    with pytest.raises(TypeError, match="float64 or numpy.float32"):
        pb.collide(A, B, np.zeros(3), I3, np.zeros(3), I3, dtype=np.int32)


def test_missing_pose_b():
    with pytest.raises(TypeError, match="pose for b"):
        pb.collide(A, B, np.zeros(3), I3)


def test_contact_not_requested_is_an_error_not_nan():
    r = _call()
    with pytest.raises(AttributeError, match="contact=True"):
        r.contact  # noqa: B018


def test_accepted_pose_forms_agree():
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(3)
    rot = Rotation.random(20, random_state=rng)
    pos = rng.uniform(-3, 3, (20, 3))
    ref = pb.collide(A, B, np.zeros(3), I3, pos, rot.as_matrix())
    q_xyzw = rot.as_quat()
    q_wxyz = np.roll(q_xyzw, 1, axis=1)
    T = np.tile(np.eye(4), (20, 1, 1))
    T[:, :3, :3] = rot.as_matrix()
    T[:, :3, 3] = pos
    forms = [
        pb.collide(A, B, np.zeros(3), I3, pos, rot),
        pb.collide(A, B, np.zeros(3), I3, pos, q_xyzw, quat_order="xyzw"),
        pb.collide(A, B, np.zeros(3), I3, pos, q_wxyz, quat_order="wxyz"),
        pb.collide(A, B, np.eye(4), None, T, None),
    ]
    assert ref.hit.any() and not ref.hit.all()
    for r in forms:
        np.testing.assert_array_equal(r.hit, ref.hit)
        np.testing.assert_array_equal(r.case, ref.case)


def _masked(x, k):
    """``x`` as a numpy masked array whose flat entry ``k`` is masked (its value is kept under the mask)."""
    m = np.zeros(np.shape(x), dtype=bool)
    m.flat[k] = True
    return np.ma.array(x, mask=m)


_A, _B = pb.Prism.regular(6, 2.0), pb.Prism.regular(6, 2.5)
_COL = pb.Collider(_A, _B)
_P, _R = np.zeros(3), np.eye(3)
_FAR = np.array([0.0, 0.0, 5.0])  # the value under a mask (a miss if read, as np.asarray would)

MASKED_CALLS = {
    "collide_pair pos_b": (lambda m: _COL.collide_pair(_P, _R, m(_FAR, 2), _R), "pos_b"),
    "collide_pair rot_a": (lambda m: _COL.collide_pair(_P, m(_R, 1), _FAR, _R), "rot_a"),
    "Collider.collide": (lambda m: _COL.collide(_P, _R, m(_FAR, 2), _R), "pos_b"),
    "pb.collide batch": (lambda m: pb.collide(_A, _B, m(np.zeros((2, 3)), 4), _R, _FAR, _R), "pos_a"),
    "4x4 transform": (lambda m: pb.collide(_A, _B, m(np.eye(4), 3), np.eye(4)), "pose_a"),
    "distance": (lambda m: pb.distance(_A, _B, _P, _R, m(_FAR, 0), _R), "pos_b"),
    "explain": (lambda m: _COL.explain(_P, _R, m(_FAR, 2), _R), "pos_b"),
    "time_of_impact velocity": (
        lambda m: pb.time_of_impact(_A, _B, _P, _R, _FAR, _R, m(np.array([0.0, 0.0, -1.0]), 2), horizon=10.0),
        "velocity",
    ),
    "Prism vertices": (lambda m: pb.Prism(m(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]), 3)), "prism"),
    "PrismSet polygon": (lambda m: pb.PrismSet([_A.xy, m(_B.xy, 0)]), "polygon 1"),
    "rtol": (lambda m: pb.Collider(_A, _B, rtol=np.ma.masked), "rtol"),
    "rows as a list": (lambda m: pb.distance(_A, _B, np.zeros((2, 3)), _R, [m(_FAR, 0), _FAR], _R), "pos_b"),
    "Prism.regular centre": (
        lambda m: pb.Prism.regular(6, 1.0, centre=m(np.array([0.0, 5.0]), 1)),
        "Prism.regular: centre",
    ),
}


@pytest.mark.parametrize("call", MASKED_CALLS.values(), ids=MASKED_CALLS.keys())
def test_masked_entries_are_refused_not_read(call):
    """Nothing is repaired silently: np.asarray keeps the values under a mask, so a masked entry is an
    error naming the argument; the same call on the unmasked data succeeds (a MaskedArray without
    masked entries is read as its data)."""
    f, name = call
    with pytest.raises(ValueError, match=f"^{name} has masked entries"):
        f(_masked)
    if name != "rtol":
        f(lambda x, k: np.ma.array(x))  # no entry masked: accepted


def test_unmasked_masked_array_answers_as_its_data():
    plain = _COL.collide_pair(_P, _R, np.array([0.0, 0.0, 0.5]), _R)
    as_ma = _COL.collide_pair(_P, _R, np.ma.array([0.0, 0.0, 0.5]), np.ma.array(_R))
    assert (plain.hit, plain.case) == (as_ma.hit, as_ma.case)
    np.testing.assert_array_equal(plain.contact, as_ma.contact)


def test_a_coordinate_just_past_the_limit_is_printed_past_it():
    """The message must not read "1e+100 outside |x| <= 1e+100": a value that rounds onto the limit in
    the short format is printed with all its digits (batch, one-pair kernel and single pose alike)."""
    from prismbatch.config import SUPPORTED_RANGE

    lim = SUPPORTED_RANGE["float64"][1]
    I, z = np.eye(3), np.zeros(3)
    for v in (np.nextafter(lim, np.inf), -lim * (1 + 1e-9)):
        want = rf"has a coordinate {re.escape(repr(float(v)))} outside the supported range"
        with pytest.raises(ValueError, match=r"^pos_a\[1\] " + want):
            _COL.collide(np.array([z, [v, 0.0, 0.0]]), I, z, I)
        with pytest.raises(ValueError, match=r"^pos_a " + want):
            _COL.collide_pair(np.array([v, 0.0, 0.0]), I, z, I)
    with pytest.raises(ValueError, match=r"^pos_b has a coordinate 3e\+100 outside"):  # the short form otherwise
        _COL.collide_pair(z, I, np.array([0.0, 3 * lim, 0.0]), I)
