"""The axis cuts of the time-of-impact gap, kernel level, against the truncated bodies' exact supports.

:func:`~prismbatch._kernels.motion.directional_bounds` bounds the gap along a direction u (the computed
normal turned round) between the parts of a and b that can touch within a step: the end faces' support planes
less ``beta cut_b + alpha cut_a``, the reach of the axes where they lean along u. Along the exact normal the
cuts vanish and the computed normal is too close to it for any whole motion to show them, so these tests call
the kernel on directions that are not the normal and compare its g with a plain reference: the least
separation along u between the vertices of a's and b's prisms truncated where (2) and (3) of
``docs/methods/time-of-impact.md``, evaluated at b's actual poses over the step, say a contact can reach.
"""

import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

import prismbatch as pb
from prismbatch._kernels.motion import directional_bounds, face_rate, reach
from prismbatch._kernels.planar import extreme_vertex

from reference import rodrigues

DOWN = np.diag([1.0, -1.0, -1.0])  # a's axis points down: its body is z <= 0 below its end face at z = 0
ALONG_X = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # a body's axis along +x
SQUARE = pb.Prism.regular(4, math.sqrt(2.0), phase=math.pi / 4)  # the square [-1, 1]^2


def face(prism, pos, rot):
    """World vertices (n, 3) of a prism's end face and its world centre."""
    return pos + prism.xy @ rot[:, :2].T, pos + rot[:, :2] @ prism.centre


def reach_reference(a, b, pos_a, rot_a, pos_b, rot_b, v, w, step, samples=201):
    """(beta, alpha): the largest axial coordinates of b's and a's points in a contact at some t' in
    [0, step], by (2) and (3) of the docs evaluated at b's actual pose at t' (sampled)."""
    _, ca = face(a, pos_a, rot_a)
    da = rot_a[:, 2]
    beta = alpha = 0.0
    for t in np.linspace(0.0, step, samples if step > 0.0 else 1):
        R = rodrigues(w, t) @ rot_b
        _, cb = face(b, pos_b + v * t, R)
        db = R[:, 2]
        S = a.radius + b.radius + np.linalg.norm(cb - ca)
        gamma = da @ db
        sigma = 1.0 if gamma <= 0.0 else np.linalg.norm(np.cross(da, db))
        bt = S / sigma if sigma > 0.0 else math.inf  # (2)
        if gamma < 0.0:  # the axes face each other: the contact lies in a's half-space, (3)
            bt = min(bt, max(0.0, (cb - ca) @ da + b.radius) / -gamma)
        beta = max(beta, bt)
        alpha = max(alpha, S + bt * max(0.0, gamma))
    return beta, alpha


def truncated_gap(a, b, pos_a, rot_a, pos_b, rot_b, u, beta, alpha):
    """min (x_a - x_b).u over a's prism cut at alpha along its axis and b's cut at beta: from their vertices."""
    fa, _ = face(a, pos_a, rot_a)
    fb, _ = face(b, pos_b, rot_b)
    xa = np.concatenate([fa, fa + alpha * rot_a[:, 2]]) @ u
    xb = np.concatenate([fb, fb + beta * rot_b[:, 2]]) @ u
    return xa.min() - xb.max()


def pair_terms(a, b, pos_a, rot_a, pos_b, rot_b, v, w):
    """(S, theta, rise, c_b's speed bound, ``|w x d_b|``): the pair's quantities at t that :func:`reach` takes."""
    _, ca = face(a, pos_a, rot_a)
    _, cb = face(b, pos_b, rot_b)
    da, db = rot_a[:, 2], rot_b[:, 2]
    S = a.radius + b.radius + np.linalg.norm(cb - ca)
    centre_speed = np.linalg.norm(v) + np.linalg.norm(w) * np.linalg.norm(b.centre)
    theta = math.atan2(np.linalg.norm(np.cross(da, db)), da @ db)
    return S, theta, (cb - ca) @ da + b.radius, centre_speed, np.linalg.norm(np.cross(w, db))


def kernel_gap(a, b, pos_a, rot_a, pos_b, rot_b, u, v, w, step):
    """g of ``directional_bounds`` in the world frame, its inputs formed from the geometry as
    ``pair_time_of_impact`` documents them, the end faces' separation along u taken exact."""
    fa, _ = face(a, pos_a, rot_a)
    fb, _ = face(b, pos_b, rot_b)
    da, db = rot_a[:, 2], rot_b[:, 2]
    sep = (fa @ u).min() - (fb @ u).max()
    S, theta, rise, centre_speed, w_perp = pair_terms(a, b, pos_a, rot_a, pos_b, rot_b, v, w)
    speed, wn = np.linalg.norm(v), np.linalg.norm(w)
    uxw = np.cross(u, w)
    q = (sep, max(0.0, -(da @ u)), max(0.0, db @ u), v @ u, np.linalg.norm(uxw), wn, speed, S)
    q = q + (centre_speed, theta, rise, w_perp)
    arr = pb.PrismSet([b]).kernel_arrays()
    c = rot_b[:, :2] @ b.centre  # b's end-face centre from p_b
    hx, hy = rot_b[:, 0] @ u, rot_b[:, 1] @ u
    along = hx * arr.vx + hy * arr.vy
    poly = (arr.vx, arr.vy, arr.edge_angle, arr.edge_table, 0, len(arr.vx))
    side = (False, u @ np.cross(w, c), np.linalg.norm(np.cross(w, c)), np.linalg.norm(b.centre), b.radius, hx, hy)
    side = side + (int(along.argmax()), int(along.argmin()), rot_b[:, 0] @ uxw, rot_b[:, 1] @ uxw, poly)
    side = side + (db @ u, u @ np.cross(w, db), w_perp)
    g, _ = directional_bounds(float(step), tuple(float(x) for x in q), side)
    return g, sep


def check(a, b, pos_a, rot_a, pos_b, rot_b, u, v, w, step):
    """Assert g <= the reference gap; return (g, the reference, the gap without the cuts, a slack)."""
    pos_a, pos_b, u, v, w = (np.asarray(x, float) for x in (pos_a, pos_b, u, v, w))
    u = u / np.linalg.norm(u)
    g, sep = kernel_gap(a, b, pos_a, rot_a, pos_b, rot_b, u, v, w, step)
    beta, alpha = reach_reference(a, b, pos_a, rot_a, pos_b, rot_b, v, w, step)
    if g == -math.inf:  # the kernel says nothing can be bounded over the step: trivially right
        return g, None, sep, None
    ref = truncated_gap(a, b, pos_a, rot_a, pos_b, rot_b, u, beta, alpha)
    slack = 1e-12 * (1.0 + np.abs(pos_a).max() + np.abs(pos_b).max() + alpha + beta + a.radius + b.radius)
    assert g <= ref + slack, (g, ref)
    return g, ref, sep, slack


def check_cut_matters(*args):
    """:func:`check`, on a case where g without the cuts would exceed the reference (so the test can fail)."""
    g, ref, sep, slack = check(*args)
    assert ref is not None  # reach is finite over the step
    assert sep > ref + slack and g < sep


@pytest.mark.parametrize("step", [0.0, 0.05])
@pytest.mark.parametrize("tilt", [1e-6, 1e-3, 0.1])
def test_b_across_a_face_leans_along_a_turned_normal(tilt, step):
    # b lies across above a's face z = 0, its axis along +x, its lowest edge at z = 0.25: the exact normal is
    # +z. u, -z turned by `tilt` towards +x, sees b's axis lean along it: d_b.u = sin(tilt) > 0, and b's far
    # points (beta up to S) lie lower along u than its end face by beta sin(tilt).
    b = pb.Prism.regular(4, 0.5 * math.sqrt(2.0), phase=math.pi / 4)  # the square [-0.5, 0.5]^2
    u = [math.sin(tilt), 0.0, -math.cos(tilt)]
    v, w = [0.3, 0.0, -1.0], [0.0, 2.0, 0.5]
    check_cut_matters(SQUARE, b, [0, 0, 0], DOWN, [-1.5, 0.0, 0.75], ALONG_X, u, v, w, step)


@pytest.mark.parametrize("step", [0.0, 0.05])
@pytest.mark.parametrize("tilt", [1e-6, 1e-3, 0.1])
def test_a_across_below_b_leans_along_a_turned_normal(tilt, step):
    # a lies across below b's end face z = 0.25 (b's body is z >= 0.25), a's axis along +x and its top edge at
    # z = 0: the exact normal is +z. n, turned by `tilt` towards +x, sees a's axis lean along it: d_a.n > 0.
    a = pb.Prism.regular(4, 0.5 * math.sqrt(2.0), phase=math.pi / 4)
    u = [-math.sin(tilt), 0.0, -math.cos(tilt)]
    v, w = [0.0, 0.3, -1.0], [1.0, 0.0, 0.5]
    check_cut_matters(a, SQUARE, [-1.5, 0.0, -0.5], ALONG_X, [0.0, 0.0, 0.25], np.eye(3), u, v, w, step)


@pytest.mark.parametrize("step", [0.0, 0.05])
@pytest.mark.parametrize("theta", [0.05, 0.3])
def test_nearly_parallel_axes_reach_far_along_a(theta, step):
    # a's axis tilted by theta from b's (both pointing up), b beside it along +x: by (2) a contact can be
    # S / sin(theta) along b and up to S + beta cos(theta) along a, more than beta, and a's axis leans along
    # n = +x: the cut of a is the larger one (swapping alpha and beta, or alpha = S, fails here).
    c, s = math.cos(theta), math.sin(theta)
    rot_a = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    b = pb.Prism.regular(6, 0.5)
    v, w = [-1.0, 0.5, 0.2], [0.1, 0.3, 0.0]  # |w x d_b| step = 0.016 < theta: reach stays finite
    check_cut_matters(SQUARE, b, [0, 0, 0], rot_a, [3.0, 0.0, 0.0], np.eye(3), [-1.0, 0.0, 0.0], v, w, step)


def test_the_cuts_vanish_along_the_computed_normal():
    # Why no whole motion shows the cuts: along the normal that the distance computes for b across a's face
    # (as above), neither axis leans along it beyond rounding, so cut_a and cut_b are (about) 0.
    b = pb.Prism.regular(4, 0.5 * math.sqrt(2.0), phase=math.pi / 4)
    n = pb.distance(SQUARE, b, [0, 0, 0], DOWN, [-1.5, 0.0, 0.75], ALONG_X, witness=True).normal[0]
    assert DOWN[:, 2] @ n <= 1e-12 and ALONG_X[:, 2] @ -n <= 1e-12  # cut_a = max(0, d_a.n), cut_b = max(0, d_b.u)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), step=st.sampled_from([0.0, 0.01, 0.1]))
def test_gap_is_a_lower_bound_for_any_direction(seed, step):
    # Random prisms, poses, motions and directions u (any u: g is a lower bound along it, whatever its sign).
    rng = np.random.default_rng(seed)

    def prism():
        n = int(rng.integers(3, 9))
        centre = tuple(rng.uniform(-1.0, 1.0, 2))
        return pb.Prism.regular(n, rng.uniform(0.2, 2.0), phase=rng.uniform(0, 2 * math.pi), centre=centre)

    def rotation():
        q = rng.normal(size=4)
        a, b, c, d = q / np.linalg.norm(q)
        return np.array([[a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c)],
                         [2 * (b * c + a * d), a * a - b * b + c * c - d * d, 2 * (c * d - a * b)],
                         [2 * (b * d - a * c), 2 * (c * d + a * b), a * a - b * b - c * c + d * d]])  # fmt: skip

    a, b = prism(), prism()
    u = rng.normal(size=3)
    g, ref, sep, slack = check(a, b, rng.uniform(-3, 3, 3), rotation(), rng.uniform(-3, 3, 3), rotation(), u,
                               rng.uniform(-5, 5, 3), rng.uniform(-5, 5, 3), step)  # fmt: skip
    if ref is not None and sep - ref > 10.0 * slack:
        assert g < sep  # the cuts are what brings g under the reference


def test_reach_bounds_the_axial_coordinates():
    # reach itself, against (2) and (3) at b's actual poses over a step: b across, facing and parallel to a.
    b = pb.Prism.regular(5, 0.5, centre=(0.3, -0.2))
    rng = np.random.default_rng(7)
    pos_a, pos_b = np.zeros(3), np.array([-1.5, 0.0, 0.75])
    for _ in range(20):
        v, w = rng.uniform(-3, 3, 3), rng.uniform(-3, 3, 3)
        for rot_b in (ALONG_X, np.eye(3), DOWN):
            beta_ref, _ = reach_reference(SQUARE, b, pos_a, DOWN, pos_b, rot_b, v, w, 0.1)
            beta = reach(0.1, *pair_terms(SQUARE, b, pos_a, DOWN, pos_b, rot_b, v, w))
            assert beta >= beta_ref * (1.0 - 1e-12)


def _cap_max(vx, vy, h, z, drop):
    """Plain exact reference: the largest z.g over the convex hull of the vertices cut to
    h.g >= max h.g - drop (rational arithmetic on the float inputs)."""
    pts = sorted({(Fraction(x), Fraction(y)) for x, y in zip(vx, vy)})

    def turn(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    hull = []
    for chain in (pts, pts[::-1]):  # Andrew's monotone chain
        part = []
        for p in chain:
            while len(part) >= 2 and turn(part[-2], part[-1], p) <= 0:
                part.pop()
            part.append(p)
        hull += part[:-1]
    (hx, hy), (zx, zy) = (map(Fraction, h)), (map(Fraction, z))
    hv = [hx * x + hy * y for x, y in hull]
    level = max(hv) - Fraction(drop)
    best = None
    for i, p in enumerate(hull):
        q, hp, hq = hull[(i + 1) % len(hull)], hv[i], hv[(i + 1) % len(hull)]
        points = [p] if hp >= level else []
        if (hp - level) * (hq - level) < 0:  # the cut crosses this edge
            t = (level - hp) / (hq - hp)
            points.append((p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])))
        for x, y in points:
            best = zx * x + zy * y if best is None else max(best, zx * x + zy * y)
    return float(best)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), flat=st.booleans())
@example(seed=2, flat=True)  # seeds 2, 10 and 20: short by up to the top side's length before the band
@example(seed=10, flat=True)
@example(seed=20, flat=True)
def test_face_rate_bounds_the_cap_against_the_reference(seed, flat):
    # face_rate must be an upper bound of max z.g over the polygon's cap {h.g >= top - drop}, and a
    # tight one: at most the cap's cut FACE_BAND r |h| lower. flat: the top side sampled with np.linspace
    # (straight only up to rounding), turned and moved from its origin, with drop 0 or tiny (a slow turn);
    # else a random convex polygon and drops across its size.
    rng = np.random.default_rng(seed)
    if flat:
        size, k, height = 10.0 ** rng.uniform(-3, 3), int(rng.integers(3, 120)), rng.uniform(0.3, 1.5)
        th = rng.uniform(0, 2 * np.pi)
        turn = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
        top = np.column_stack([np.linspace(-1.0, 0.0, k)[::-1], np.zeros(k)])
        xy = np.vstack([[[-1.3, -height], [0.3, -height]], top]) * size @ turn.T
        xy = xy + rng.normal(size=2) * size * 10.0 ** rng.uniform(0, 4)
        h = turn @ [0.0, rng.uniform(0.5, 2.0)]  # normal to the top side
        z = turn @ [rng.choice([-1.0, 1.0]) * rng.uniform(0.2, 1.0), rng.uniform(-0.3, -0.05)]
        drops = [0.0, 1e-14 * size, 1e-12 * size]
    else:
        ang = np.sort(rng.uniform(0, 2 * np.pi, int(rng.integers(3, 40))))
        xy = np.column_stack([np.cos(ang), np.sin(ang)]) * rng.uniform(0.5, 2) + rng.normal(size=2)
        h, z, drops = rng.normal(size=2), rng.normal(size=2), [0.0, 1e-3, 0.1, 1.0, 5.0]
    try:
        arrays = pb.PrismSet([xy]).kernel_arrays(np.float64)
    except ValueError:  # (a refused outline: rarely drawn)
        return
    vx, vy, eang, etab, r = arrays.vx, arrays.vy, arrays.edge_angle, arrays.edge_table, arrays.radius[0]
    n = len(vx)
    imax = extreme_vertex(vx, vy, eang, etab, 0, n, h[0], h[1])
    imin = extreme_vertex(vx, vy, eang, etab, 0, n, -h[0], -h[1])
    band = 2.0**-30 * r * np.hypot(*h)
    for drop in drops:
        got = face_rate(vx, vy, eang, etab, 0, n, r, h[0], h[1], imax, imin, drop, z[0], z[1])
        small = 1e-12 * r * np.hypot(*z)
        assert got >= _cap_max(vx, vy, h, z, drop) - small, drop
        assert got <= _cap_max(vx, vy, h, z, max(drop, band) + 2 * band) + small, drop
