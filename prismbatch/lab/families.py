"""Pose families that look like users' poses, for checking prismbatch against an exact reference.

Each family draws ``n`` pose pairs of two prisms (one polygon pair per pair) as
a :class:`PairSet`: identical and nearly identical rotations, rotations given
as quaternions, 4x4 transforms or scipy ``Rotation`` objects, dense nearly
collinear polygons, local origins far outside the polygon (with the bodies far from the world
origin, or near it), small objects far
from the world origin, magnitudes from 1e-12 to 1e12 in one scene, and random
facing and free poses. In every family a share of the pairs is placed at a
chosen gap of a fraction of the touching tolerance on both sides of it (from
-0.5 tol, overlapping, to 10 tol), where errors of a collision test live.

The generators only place pairs; the verdict comes from the exact reference
(:mod:`prismbatch.lab.exact_gap`). Needs numpy; the ``scipy`` family needs scipy.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..geometry import convex_hull, pair_scale_tolerance
from ..sampling import random_rotations
from ..shapes import Prism
from .exact_gap import exact_dot

__all__ = ["PairSet", "FAMILIES", "make_family", "collide_family"]

#: Gaps, in units of the pair's tolerance, at which near-touching pairs are placed.
TARGET_GAPS = (-0.5, -0.01, 0.0, 0.25, 0.5, 0.9, 0.99, 1.01, 1.1, 1.5, 1.9, 1.99, 2.01, 2.1, 3.0, 10.0)


class PairSet(NamedTuple):
    """Pose pairs of one family, with the form in which they are passed to :func:`prismbatch.collide`.

    ``rot_a``/``rot_b`` are the float matrices that define the bodies (for
    ``form == "quat"`` the exact reference uses the quaternions instead);
    ``call_a``/``call_b`` are the rotation arguments as the user passes them
    (matrices, quaternions, (N, 4, 4) transforms with ``pos`` unused, or a
    scipy ``Rotation``); ``target`` the gap / tol of a near-touching pair
    placed with a separating plane (up to the rounding of the placement),
    inf where placed without one, NaN for a free pose.
    """

    family: str
    xy_a: list
    xy_b: list
    pos_a: np.ndarray
    rot_a: np.ndarray
    pos_b: np.ndarray
    rot_b: np.ndarray
    form: str
    call_a: object
    call_b: object
    quat_order: str | None
    target: np.ndarray


# --- polygons ---------------------------------------------------------------


def _regular(rng, radius):
    n = int(rng.choice([3, 4, 5, 6, 8, 12, 36, 100, 360]))
    ang = rng.uniform(0, 2 * np.pi) + 2 * np.pi * np.arange(n) / n
    return radius * np.column_stack([np.cos(ang), np.sin(ang)])


def _random_convex(rng, radius):
    k = int(rng.integers(3, 40))
    pts = rng.normal(size=(k + 3, 2)) * radius
    return convex_hull(pts)


def _dense_collinear(rng, radius):
    """Thousands of vertices on a slightly wobbled ellipse, most turns far below 1e-6 rad."""
    m = int(rng.integers(800, 2500))
    # clustered angles: a few wide gaps and many tiny steps (edges down to ~1e-10)
    runs = rng.uniform(0, 2 * np.pi, 40)[:, None] + np.cumsum(10.0 ** rng.uniform(-10, -5, (40, m // 40)), axis=1)
    t = np.sort(np.concatenate([rng.uniform(0, 2 * np.pi, 12), runs.ravel()]))
    t = np.mod(t, 2 * np.pi)
    ab = radius * rng.uniform(0.6, 1.0, 2)
    pts = np.column_stack([ab[0] * np.cos(t), ab[1] * np.sin(t)])
    return convex_hull(pts)


def _polygon(rng, kind, radius):
    return {"regular": _regular, "random": _random_convex, "dense": _dense_collinear}[kind](rng, radius)


def _valid_polygon(rng, kind, radius, offset=(0.0, 0.0)):
    for _ in range(20):
        xy = _polygon(rng, kind, radius) + np.asarray(offset)
        try:
            return Prism(xy).xy
        except ValueError:  # a hull can keep rounding-level dents: draw again
            continue
    raise RuntimeError(f"could not draw a valid {kind} polygon")


# --- rotations --------------------------------------------------------------


def _small_rotations(rng, n, angles):
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    K = np.zeros((n, 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -axis[:, 2], axis[:, 1], -axis[:, 0]
    K -= np.transpose(K, (0, 2, 1))
    s, c = np.sin(angles)[:, None, None], np.cos(angles)[:, None, None]
    return np.eye(3) + s * K + (1 - c) * (K @ K)


def _quat_to_matrix(q):
    """Float rotation matrices of unit quaternions (w, x, y, z)."""
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.stack(
        [
            1 - 2 * (y * y + z * z),
            2 * (x * y - w * z),
            2 * (x * z + w * y),
            2 * (x * y + w * z),
            1 - 2 * (x * x + z * z),
            2 * (y * z - w * x),
            2 * (x * z - w * y),
            2 * (y * z + w * x),
            1 - 2 * (x * x + y * y),
        ],
        axis=1,
    ).reshape(-1, 3, 3)


# --- placement --------------------------------------------------------------


def _place_near_touching(xy_a, pos_a, rot_a, xy_b, pos_b, rot_b, gap_over_tol, rng):
    """Move b so that the bodies are ``gap_over_tol * tol`` apart along a separating direction.

    A random direction n with n.d_a <= 0 and n.d_b >= 0 (so neither body runs
    off along n), then b's lowest vertex along n is put at a's highest vertex
    plus the gap along n: both bodies then lie on opposite sides of two planes
    ``gap`` apart that share the two points, so the Euclidean gap is that gap
    (up to rounding; negative values overlap by that depth).
    """
    da, db = rot_a[:, 2], rot_b[:, 2]
    for _ in range(64):
        nrm = rng.normal(size=3)
        para = abs(da @ db) > 1 - 1e-6
        if para:  # (nearly) parallel axes: only directions across the axis separate
            nrm -= (nrm @ da) * da
        nrm /= np.linalg.norm(nrm)
        if nrm @ da <= 0 and (nrm @ db >= 0 or para):
            break
        if nrm @ da > 0 and -nrm @ db >= 0:
            nrm = -nrm
            break
    wa = pos_a + (xy_a @ rot_a[:, :2].T)
    wb = pos_b + (xy_b @ rot_b[:, :2].T)
    sa = wa[np.argmax(wa @ nrm)]
    sb = wb[np.argmin(wb @ nrm)]
    new_b = pos_b + (sa - sb)
    A, B = Prism(xy_a), Prism(xy_b)
    _, tol = pair_scale_tolerance(A, B, pos_a[None], rot_a[None], new_b[None], rot_b[None])
    # The gap is known by construction only where neither body runs off along
    # -n / +n, judged exactly: an axis off by 1e-16 still crosses the plane
    # (about 1e16 away), and semi-infinite bodies then meet there. Bitwise
    # equal axes keep their distance whatever n.d is.
    known = bool((da == db).all()) or (exact_dot(nrm, da) <= 0 and exact_dot(nrm, db) >= 0)
    return new_b + gap_over_tol * tol[0] * nrm, known


# --- families ---------------------------------------------------------------


def _scene(
    rng,
    n,
    *,
    kinds=("regular", "random"),
    radius=(0.5, 3.0),
    spread=3.0,
    offset=0.0,
    rot=None,
    near_share=0.6,
    scale=lambda rng: 1.0,
    where=lambda rng: np.zeros(3),
    centres_at_where=False,
):
    """Common body of the families: polygons, poses and near-touching placement. ``offset``: how far
    the polygons lie from their local origins (a number, or a function of the generator);
    ``centres_at_where``: place the end-face centres, not the local origins, about ``where``."""
    xa, xb, pa, pb_, target = [], [], [], [], []
    rots = rot(n) if rot is not None else (random_rotations(n, rng), random_rotations(n, rng))
    for k in range(n):
        s = scale(rng)
        off = (offset(rng) if callable(offset) else offset) * s * rng.normal(size=2)
        A = _valid_polygon(rng, rng.choice(kinds), s * rng.uniform(*radius), off)
        B = _valid_polygon(rng, rng.choice(kinds), s * rng.uniform(*radius), -off)
        centre = where(rng)
        p_a = centre + s * spread * rng.uniform(-1, 1, 3) * 0.3
        p_b = centre + s * spread * rng.uniform(-1, 1, 3)
        if centres_at_where:  # the world centres near ``where``, however far the polygons are from their origins
            p_a = p_a - rots[0][k][:, :2] @ Prism(A).centre
            p_b = p_b - rots[1][k][:, :2] @ Prism(B).centre
        g = np.nan
        if rng.uniform() < near_share:
            g = float(rng.choice(TARGET_GAPS))
            p_b, known = _place_near_touching(A, p_a, rots[0][k], B, p_b, rots[1][k], g, rng)
            g = g if known else np.inf
        xa.append(A)
        xb.append(B)
        pa.append(p_a)
        pb_.append(p_b)
        target.append(g)
    return xa, xb, np.array(pa), rots[0], np.array(pb_), rots[1], np.array(target)


def _matrix_family(name, rng, n, **kw):
    xa, xb, pa, ra, pb_, rb, tg = _scene(rng, n, **kw)
    return PairSet(name, xa, xb, pa, ra, pb_, rb, "matrix", ra, rb, None, tg)


def _identical(rng, n):
    return _matrix_family(
        "identical_rotation", rng, n, rot=lambda m: (lambda R: (R, R.copy()))(random_rotations(m, rng))
    )


def _near_identical(rng, n):
    def rot(m):
        R = random_rotations(m, rng)
        return R, R @ _small_rotations(rng, m, 10.0 ** rng.uniform(-16, -6, m))

    return _matrix_family("near_identical_rotation", rng, n, rot=rot)


def _quaternions(rng, n):
    qa, qb = rng.normal(size=(n, 4)), rng.normal(size=(n, 4))
    same = rng.uniform(size=n) < 0.3  # some identical quaternions too
    qb[same] = qa[same]
    qa /= np.linalg.norm(qa, axis=1, keepdims=True)
    qb /= np.linalg.norm(qb, axis=1, keepdims=True)
    order = "wxyz" if rng.uniform() < 0.5 else "xyzw"
    xa, xb, pa, ra, pb_, rb, tg = _scene(rng, n, rot=lambda m: (_quat_to_matrix(qa), _quat_to_matrix(qb)))
    perm = [0, 1, 2, 3] if order == "wxyz" else [1, 2, 3, 0]
    return PairSet("quaternion", xa, xb, pa, ra, pb_, rb, "quat", qa[:, perm], qb[:, perm], order, tg)


def _transforms(rng, n):
    ps = _matrix_family("transform_4x4", rng, n)
    T = np.zeros((2, n, 4, 4))
    for j, (p, R) in enumerate(((ps.pos_a, ps.rot_a), (ps.pos_b, ps.rot_b))):
        T[j, :, :3, :3], T[j, :, :3, 3], T[j, :, 3, 3] = R, p, 1.0
    return ps._replace(form="transform", call_a=T[0], call_b=T[1])


def _scipy(rng, n):
    from scipy.spatial.transform import Rotation

    ra = Rotation.random(n, random_state=int(rng.integers(2**31)))
    rb = Rotation.random(n, random_state=int(rng.integers(2**31)))
    Ma, Mb = ra.as_matrix(), rb.as_matrix()
    ps = _matrix_family("scipy_rotation", rng, n, rot=lambda m: (Ma, Mb))
    return ps._replace(form="scipy", call_a=ra, call_b=rb)


FAMILIES = {
    "facing": lambda rng, n: _matrix_family(
        "facing",
        rng,
        n,
        rot=lambda m: (
            np.broadcast_to(np.diag([1.0, -1.0, -1.0]), (m, 3, 3)).copy(),
            _small_rotations(rng, m, rng.uniform(0, 0.3, m)),
        ),
    ),
    "free": lambda rng, n: _matrix_family("free", rng, n),
    "identical_rotation": _identical,
    "near_identical_rotation": _near_identical,
    "quaternion": _quaternions,
    "transform_4x4": _transforms,
    "scipy_rotation": _scipy,
    "dense_collinear": lambda rng, n: _matrix_family("dense_collinear", rng, n, kinds=("dense",)),
    "far_origin": lambda rng, n: _matrix_family("far_origin", rng, n, offset=1e6),
    # end faces 1e5-1e10 from their own origins but near the world origin: the rounding of the vertices
    # about their centre and of the world centres is then far above the world positions' own
    "far_local_origin": lambda rng, n: _matrix_family(
        "far_local_origin", rng, n, offset=lambda r: 10.0 ** r.uniform(5, 10), centres_at_where=True
    ),
    "tiny_far": lambda rng, n: _matrix_family(
        "tiny_far", rng, n, scale=lambda r: 1e-6, where=lambda r: r.uniform(-1e6, 1e6, 3)
    ),
    "mixed_scales": lambda rng, n: _matrix_family("mixed_scales", rng, n, scale=lambda r: 10.0 ** r.uniform(-12, 12)),
}


def make_family(name, n, seed):
    """Draw ``n`` pairs of family ``name`` (a key of :data:`FAMILIES`) from ``seed``."""
    if name not in FAMILIES:
        raise ValueError(f"unknown family {name!r}; choose from {', '.join(FAMILIES)}")
    rng = np.random.default_rng([seed, sum(map(ord, name))])
    return FAMILIES[name](rng, n)


def collide_family(ps, **kwargs):
    """Call :func:`prismbatch.collide` on a :class:`PairSet` in the form a user would."""
    from ..collide import collide
    from ..shapes import PrismSet

    A, B = PrismSet(ps.xy_a), PrismSet(ps.xy_b)
    if ps.form == "transform":
        return collide(A, B, ps.call_a, None, ps.call_b, None, **kwargs)
    if ps.form == "quat":
        return collide(A, B, ps.pos_a, ps.call_a, ps.pos_b, ps.call_b, quat_order=ps.quat_order, **kwargs)
    return collide(A, B, ps.pos_a, ps.call_a, ps.pos_b, ps.call_b, **kwargs)
