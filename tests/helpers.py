"""Seeded generators of polygons, poses and pose pairs for the tests (plain NumPy/scipy).

Everything is a plain function of a ``numpy.random.Generator``; the fixtures that use them are in
``conftest.py``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial import ConvexHull
from scipy.spatial.transform import Rotation

from reference import margin_lp, ref_polygon_distance  # noqa: E402

#: a's rotation in the ``facing`` pose set: local axes x, -y, -z (axis down).
R_DOWN = np.diag([1.0, -1.0, -1.0])

#: Vertex counts that must always be represented among large polygons.
LARGE_COUNTS = (360, 1000, 3600)


# ---------------------------------------------------------------------------
# polygons
# ---------------------------------------------------------------------------


def from_hex(x):
    """A float array of hex-float strings (``float.hex``), nested as ``x`` is: recorded inputs, exact to the bit."""
    return np.vectorize(float.fromhex, otypes=[float])(np.array(x))


def recorded(name):
    """The parsed JSON of ``tests/data/<name>.json`` (recorded cases)."""
    return json.loads((Path(__file__).resolve().parent / "data" / f"{name}.json").read_text())


def recorded_pair(rec):
    """``(xy_a, pos_a, rot_a, xy_b, pos_b, rot_b)`` of a recorded case's hex floats, shaped for the API."""
    shapes = {"xy_a": (-1, 2), "pos_a": (3,), "rot_a": (3, 3), "xy_b": (-1, 2), "pos_b": (3,), "rot_b": (3, 3)}
    return tuple(from_hex(rec[k]).reshape(s) for k, s in shapes.items())


def sliver_far_from_origin():
    """A counter-clockwise 4-vertex sliver about 1.5e5 from its local origin whose plain float
    shoelace sum of the raw coordinates rounds negative (found by an adversarial review)."""
    rows = [
        ["-0x1.c1b2cb0f4338fp+16", "-0x1.2ca8cee6749a1p+17"],
        ["-0x1.c1b1ced7fb55fp+16", "-0x1.2ca8c54e2fd41p+17"],
        ["-0x1.c1b1ced7fb6d3p+16", "-0x1.2ca8c54e2f3b2p+17"],
        ["-0x1.c1b2cb0f43503p+16", "-0x1.2ca8cee674012p+17"],
    ]
    return from_hex(rows)


def _ccw(xy):
    """Counter-clockwise by the signed area about the mean: the shoelace sum of coordinates far from
    the origin can round to the wrong sign on slivers."""
    v = xy - xy.mean(axis=0)
    area2 = np.sum(v[:, 0] * np.roll(v[:, 1], -1) - np.roll(v[:, 0], -1) * v[:, 1])
    return xy if area2 > 0 else xy[::-1].copy()


def regular_polygon(n, radius=1.0, phase=0.0, centre=(0.0, 0.0)):
    """Regular n-gon, CCW, circumradius ``radius``."""
    t = phase + 2.0 * np.pi * np.arange(n) / n
    return np.column_stack([radius * np.cos(t), radius * np.sin(t)]) + np.asarray(centre, float)


def irregular_polygon(rng, n, radius=1.0):
    """Random convex polygon with at most ``n`` vertices (usually close to n).

    ``n`` random polar angles on a random ellipse (aspect 0.25..1, random
    orientation) with random radial shrink, then the convex hull.  The radial
    noise is large for small ``n`` (very irregular, possibly skinny shapes)
    and tiny for large ``n`` so that most of the points survive the hull.
    """
    for _ in range(100):
        m = max(int(n), 3)
        ang = np.sort(rng.uniform(0.0, 2.0 * np.pi, m))
        aspect = rng.uniform(0.25, 1.0)
        noise = 0.35 if m <= 12 else min(0.35, 3.0 / m**2)
        rad = 1.0 - noise * rng.uniform(0.0, 1.0, m)
        pts = np.column_stack([rad * np.cos(ang), aspect * rad * np.sin(ang)])
        th = rng.uniform(0.0, 2.0 * np.pi)
        c, s = np.cos(th), np.sin(th)
        pts = pts @ np.array([[c, s], [-s, c]])
        try:
            hull = ConvexHull(pts)
        except Exception:  # degenerate draw (qhull error): try again
            continue
        poly = pts[hull.vertices]  # CCW for 2-D input
        # Reject degenerate slivers: the package validates areas and edges.
        e = np.roll(poly, -1, axis=0) - poly
        if len(poly) < 3 or hull.volume < 1e-3 or np.min(np.hypot(*e.T)) < 1e-9:
            continue
        poly = _ccw(poly)
        r = np.max(np.hypot(*(poly - poly.mean(axis=0)).T))
        return poly * (radius / r)
    raise RuntimeError("could not draw a random convex polygon")


def random_polygon(rng, n, *, regular=None, radius=None, offset=0.3):
    """Random convex polygon, regular or irregular, CCW.

    ``radius`` defaults to a random value in [0.5, 2]; the polygon is shifted
    from the local origin by up to ``offset * radius``.
    """
    if regular is None:
        regular = bool(rng.random() < 0.35)
    if radius is None:
        radius = float(rng.uniform(0.5, 2.0))
    shift = rng.uniform(-offset, offset, 2) * radius
    if regular:
        return regular_polygon(n, radius, rng.uniform(0, 2 * np.pi), shift)
    return irregular_polygon(rng, n, radius) + shift


def sample_vertex_count(rng, family):
    """Vertex count for a polygon family.

    ``small``: 3..12 uniform; ``medium``: log-uniform 13..200; ``large``:
    one of 360/1000/3600 half of the time, otherwise log-uniform 201..3600;
    ``mixed``: skewed toward small (60% small, 35% medium, 5% large);
    ``smallmed``: 65% small, 35% medium.
    """
    if family == "mixed":
        u = rng.random()
        family = "small" if u < 0.6 else ("medium" if u < 0.95 else "large")
    elif family == "smallmed":
        family = "small" if rng.random() < 0.65 else "medium"
    if family == "small":
        return int(rng.integers(3, 13))
    if family == "medium":
        return int(np.exp(rng.uniform(np.log(13), np.log(200.999))))
    if family == "large":
        if rng.random() < 0.5:
            return int(rng.choice(LARGE_COUNTS))
        return int(np.exp(rng.uniform(np.log(201), np.log(3600.999))))
    raise ValueError(family)


def subdivided(base, k):
    """``base``'s vertices with k - 1 more on every edge (np.linspace, as a tessellation writes them):
    collinear up to the rounding of their coordinates."""
    t = np.linspace(0.0, 1.0, k, endpoint=False)[:, None]
    return np.concatenate([a + t * (b - a) for a, b in zip(base, np.roll(base, -1, axis=0))])


def collinear_polygon(rng, *, radius=None):
    """Irregular/regular 3..7-gon with 1..59 extra vertices on every edge
    (exactly collinear up to rounding: straight angles are legal input)."""
    base = random_polygon(rng, int(rng.integers(3, 8)), radius=radius)
    return subdivided(base, int(rng.integers(2, 61)))


def skinny_polygon(rng, *, radius=None):
    """Random convex 3..39-gon squashed to an aspect ratio of 1e-5..1e-1."""
    p = random_polygon(rng, int(rng.integers(3, 40)), radius=radius, offset=0.0)
    th = rng.uniform(0, 2 * np.pi)
    c, s = np.cos(th), np.sin(th)
    rot = np.array([[c, -s], [s, c]])
    squash = np.diag([1.0, 10 ** rng.uniform(-5, -1)])
    return p @ (rot @ squash @ rot.T).T + rng.uniform(-0.3, 0.3, 2)


SPECIAL_FAMILIES = {"collinear": collinear_polygon, "skinny": skinny_polygon}


def family_polygon(rng, family, *, regular=None):
    """One random polygon of a family (see sample_vertex_count and SPECIAL_FAMILIES)."""
    if family in SPECIAL_FAMILIES:
        return SPECIAL_FAMILIES[family](rng)
    return random_polygon(rng, sample_vertex_count(rng, family), regular=regular)


def polygon_pairs(rng, n_pairs, family, *, regular=None):
    """Lists (polys_a, polys_b) of per-pair polygons for a family.

    For ``large`` only one of the two polygons of a pair is large (the other
    is ``smallmed``), which keeps the LP reference affordable while exercising
    the large-polygon code paths on both sides.
    """
    pa, pb = [], []
    for k in range(n_pairs):
        fa = fb = family
        if family == "large":
            if k % 2 == 0:
                fb = "smallmed"
            else:
                fa = "smallmed"
        pa.append(family_polygon(rng, fa, regular=regular))
        pb.append(family_polygon(rng, fb, regular=regular))
    return pa, pb


# ---------------------------------------------------------------------------
# rotations and poses
# ---------------------------------------------------------------------------


def random_rotations(rng, n):
    """(n, 3, 3) uniformly random rotation matrices (seeded)."""
    return Rotation.random(n, random_state=rng).as_matrix().reshape(n, 3, 3)


def rot_z(theta):
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def polygon_centre(xy):
    """Area centroid of a convex polygon (independent of the package)."""
    xy = _ccw(np.asarray(xy, float))
    x0 = xy.mean(axis=0)
    v = xy - x0
    vn = np.roll(v, -1, axis=0)
    cr = v[:, 0] * vn[:, 1] - vn[:, 0] * v[:, 1]
    a = cr.sum() / 2.0
    return np.array([((v[:, 0] + vn[:, 0]) * cr).sum(), ((v[:, 1] + vn[:, 1]) * cr).sum()]) / (6 * a) + x0


def polygon_radius(xy, centre=None):
    xy = np.asarray(xy, float)
    c = polygon_centre(xy) if centre is None else centre
    return float(np.max(np.hypot(*(xy - c).T)))


def _world_centres(polys, pos, rot):
    c = np.array([polygon_centre(p) for p in polys])
    return pos + np.einsum("nij,nj->ni", rot[:, :, :2], c)


def _place(polys, pos, rot, target):
    """Shift ``pos`` so that the end-face centroids land on ``target``."""
    return pos + (target - _world_centres(polys, pos, rot))


def facing_poses(rng, polys_a, polys_b, *, max_tilt_deg=60.0):
    """Facing pose set.

    a: axis down (``rot_a = diag(1, -1, -1)``) at a random world position.
    b: random spin about its axis, then its axis (+z) tilted by up to
    ``max_tilt_deg`` about a random horizontal axis; its end-face centroid is
    within ~1.5 (R_a + R_b) of a's horizontally and at a height in
    [-1.5 R, 1 R] relative to a's end face (R = max(R_a, R_b)).
    Returns pos_a, rot_a, pos_b, rot_b with shapes (N, 3) and (N, 3, 3).
    """
    n = len(polys_a)
    ra = np.array([polygon_radius(p) for p in polys_a])
    rb = np.array([polygon_radius(p) for p in polys_b])
    rot_a = np.repeat(R_DOWN[None], n, axis=0)
    base = rng.uniform(-5, 5, (n, 3))
    pos_a = _place(polys_a, np.zeros((n, 3)), rot_a, base)
    spin = Rotation.from_euler("z", rng.uniform(0, 2 * np.pi, (n, 1)))
    ax = rng.uniform(0, 2 * np.pi, n)
    tilt = np.deg2rad(max_tilt_deg) * np.sqrt(rng.uniform(0, 1, n))
    axis = np.column_stack([np.cos(ax), np.sin(ax), np.zeros(n)])
    rot_b = (Rotation.from_rotvec(axis * tilt[:, None]) * spin).as_matrix()
    R = np.maximum(ra, rb)
    rho = 1.5 * (ra + rb) * np.sqrt(rng.uniform(0, 1, n))
    phi = rng.uniform(0, 2 * np.pi, n)
    dz = rng.uniform(-1.5, 1.0, n) * R
    target = base + np.column_stack([rho * np.cos(phi), rho * np.sin(phi), dz])
    pos_b = _place(polys_b, np.zeros((n, 3)), rot_b, target)
    return pos_a, rot_a, pos_b, rot_b


def free_poses(rng, polys_a, polys_b, *, half_width=1.25):
    """Free pose set: uniform random rotations, centroid offsets uniform in a
    box of half-width ``half_width * (R_a + R_b)`` (about 2.5 radii wide)."""
    n = len(polys_a)
    ra = np.array([polygon_radius(p) for p in polys_a])
    rb = np.array([polygon_radius(p) for p in polys_b])
    rot_a = random_rotations(rng, n)
    rot_b = random_rotations(rng, n)
    base = rng.uniform(-5, 5, (n, 3))
    pos_a = _place(polys_a, np.zeros((n, 3)), rot_a, base)
    off = rng.uniform(-1, 1, (n, 3)) * (half_width * (ra + rb))[:, None]
    pos_b = _place(polys_b, np.zeros((n, 3)), rot_b, base + off)
    return pos_a, rot_a, pos_b, rot_b


POSE_SETS = {"facing": facing_poses, "free": free_poses}


# ---------------------------------------------------------------------------
# tolerances and reference margins
# ---------------------------------------------------------------------------


def pair_scale(polys_a, pos_a, rot_a, polys_b, pos_b, rot_b):
    """S = R_a + R_b + |c_b - c_a| per pair (world end-face centroids)."""
    ra = np.array([polygon_radius(p) for p in polys_a])
    rb = np.array([polygon_radius(p) for p in polys_b])
    ca = _world_centres(polys_a, np.asarray(pos_a, float).reshape(-1, 3), np.asarray(rot_a, float).reshape(-1, 3, 3))
    cb = _world_centres(polys_b, np.asarray(pos_b, float).reshape(-1, 3), np.asarray(rot_b, float).reshape(-1, 3, 3))
    return ra + rb + np.linalg.norm(cb - ca, axis=1)


def pair_tolerance(polys_a, pos_a, rot_a, polys_b, pos_b, rot_b, *, rtol=1e-9, atol=0.0):
    """The binding pair tolerance ``atol + rtol * S``.

    The package adds rounding floors ``4 eps (|c_a| + |c_b|) + 8 eps (|k_a|_1 + |k_b|_1)`` for the
    world and local positions of the centres; with the unit-size positions used here they are below 1e-14.
    """
    return atol + rtol * pair_scale(polys_a, pos_a, rot_a, polys_b, pos_b, rot_b)


def margins(polys_a, pos_a, rot_a, polys_b, pos_b, rot_b):
    """LP margins delta* (N,) for per-pair polygons."""
    return np.array(
        [margin_lp(polys_a[k], pos_a[k], rot_a[k], polys_b[k], pos_b[k], rot_b[k]) for k in range(len(polys_a))]
    )


@dataclass
class PairData:
    """A batch of pose pairs with per-pair polygons and (optionally) margins."""

    polys_a: list
    polys_b: list
    pos_a: np.ndarray
    rot_a: np.ndarray
    pos_b: np.ndarray
    rot_b: np.ndarray
    kind: np.ndarray = field(default=None)  # "facing"/"free" per pair
    delta: np.ndarray = field(default=None)  # LP margins
    scale: np.ndarray = field(default=None)  # S per pair

    def __len__(self):
        return len(self.polys_a)

    def subset(self, idx):
        idx = np.asarray(idx)
        if idx.dtype == bool:
            idx = np.flatnonzero(idx)
        pick = lambda v: None if v is None else v[idx]  # noqa: E731
        return PairData(
            [self.polys_a[i] for i in idx],
            [self.polys_b[i] for i in idx],
            self.pos_a[idx],
            self.rot_a[idx],
            self.pos_b[idx],
            self.rot_b[idx],
            pick(self.kind),
            pick(self.delta),
            pick(self.scale),
        )

    def args(self):
        return self.pos_a, self.rot_a, self.pos_b, self.rot_b


def pairs_from_rows(rows):
    """PairData from rows (polygon_a, polygon_b, pos_a, rot_a, pos_b, rot_b)."""
    A, B, pa, Ra, pb_, Rb = zip(*rows)
    d = PairData(list(A), list(B), np.array(pa), np.array(Ra), np.array(pb_), np.array(Rb))
    d.scale = pair_scale(d.polys_a, d.pos_a, d.rot_a, d.polys_b, d.pos_b, d.rot_b)
    return d


def make_pairs(rng, n_pairs, pose_set, family="mixed", *, regular=None, with_margin=False):
    """Random PairData for one pose set (``facing``/``free``) and family."""
    pa, pb = polygon_pairs(rng, n_pairs, family, regular=regular)
    poses = POSE_SETS[pose_set](rng, pa, pb)
    d = PairData(pa, pb, *poses, kind=np.array([pose_set] * n_pairs))
    d.scale = pair_scale(pa, *poses[:2], pb, *poses[2:])
    if with_margin:
        d.delta = margins(pa, *poses[:2], pb, *poses[2:])
    return d


def distance_with_witnesses(d, pos_b=None, **kw):
    """``prismbatch.distance`` with witnesses on PairData ``d`` (b moved to ``pos_b`` if given)."""
    import prismbatch as pb

    sa, sb = pb.PrismSet(d.polys_a), pb.PrismSet(d.polys_b)
    return pb.distance(sa, sb, d.pos_a, d.rot_a, d.pos_b if pos_b is None else pos_b, d.rot_b, witness=True, **kw)


def concat_pairs(*parts):
    cat = lambda name: np.concatenate([getattr(p, name) for p in parts])  # noqa: E731
    out = PairData(
        sum((p.polys_a for p in parts), []),
        sum((p.polys_b for p in parts), []),
        cat("pos_a"),
        cat("rot_a"),
        cat("pos_b"),
        cat("rot_b"),
        cat("kind"),
        None,
        cat("scale"),
    )
    if all(p.delta is not None for p in parts):
        out.delta = cat("delta")
    return out


# ---------------------------------------------------------------------------
# targeted configurations (shared by the agreement and contact tests)
# ---------------------------------------------------------------------------


def overlapping_pairs(rng, n, pose_set):
    """Pairs whose b end-face centroid lies strictly inside a (so they overlap)."""
    d = make_pairs(rng, n, pose_set, "smallmed")
    ra = np.array([polygon_radius(p) for p in d.polys_a])
    ca = d.pos_a + np.einsum("nij,nj->ni", d.rot_a[:, :, :2], np.array([polygon_centre(p) for p in d.polys_a]))
    cb_local = np.array([polygon_centre(p) for p in d.polys_b])
    depth = rng.uniform(0.05, 1.0, n) * ra
    target = ca + depth[:, None] * d.rot_a[:, :, 2]
    d.pos_b = target - np.einsum("nij,nj->ni", d.rot_b[:, :, :2], cb_local)
    d.scale = pair_scale(d.polys_a, d.pos_a, d.rot_a, d.polys_b, d.pos_b, d.rot_b)
    return d


def separating_directions(rng, sa, sb, d, far, rounds=30):
    """Unit directions u (N, 3) such that b moved by ``far * u`` misses a
    (according to prismbatch); rows that never separate are left zero and
    flagged False in the returned mask."""
    import prismbatch as pb  # local: conftest itself must not need the package

    n = len(d)
    u = np.zeros((n, 3))
    todo = np.ones(n, bool)
    for _ in range(rounds):
        if not todo.any():
            break
        cand = rng.normal(size=(n, 3))
        cand /= np.linalg.norm(cand, axis=1, keepdims=True)
        trial = np.where(todo[:, None], cand, u)
        rf = pb.collide(sa, sb, d.pos_a, d.rot_a, d.pos_b + far[:, None] * trial, d.rot_b)
        ok = todo & ~rf.hit
        u[ok] = cand[ok]
        todo &= ~ok
    return u, ~todo


def bisect_to_contact(sa, sb, d, u, far, steps=60):
    """Bisection on prismbatch's own decision along b's translation s u,
    from s = 0 (hit) to s = far (miss).  Returns (lo, hi): the last hit and
    first miss.  The set of s at which the bodies meet is an interval (a
    line through the convex Minkowski difference), so the boundary is unique."""
    import prismbatch as pb

    lo = np.zeros(len(d))
    hi = np.asarray(far, float).copy()
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        h = pb.collide(sa, sb, d.pos_a, d.rot_a, d.pos_b + mid[:, None] * u, d.rot_b).hit
        lo = np.where(h, mid, lo)
        hi = np.where(h, hi, mid)
    return lo, hi


# columns e_y, e_z, e_x: local +z (the axis) -> world +x, exactly
_M_PERP = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def perpendicular_pairs(rng, n, mode, depression=0.0):
    """a: axis exactly +z (rot_a = Rz(phi)); b: axis exactly horizontal, or
    with ``depression`` (radians) pointing that much below the horizontal,
    i.e. away from a's body.

    mode "generic": b's end-face centroid at a random height in [-R, R];
    mode "vertex": b's highest end-face vertex exactly on a's plane;
    mode "edge": one edge of b exactly horizontal and on a's plane.
    """
    cd, sd = np.cos(depression), np.sin(depression)
    # rotation about world y taking +x to (cos, 0, -sin): b's axis points down
    pitch = np.array([[cd, 0.0, sd], [0.0, 1.0, 0.0], [-sd, 0.0, cd]])
    rows = []
    for _ in range(n):
        A = random_polygon(rng, sample_vertex_count(rng, "smallmed"))
        B = random_polygon(rng, sample_vertex_count(rng, "smallmed"))
        Ra = rot_z(rng.uniform(0, 2 * np.pi))
        if mode == "edge":
            i = int(rng.integers(len(B)))
            e = B[(i + 1) % len(B)] - B[i]
            theta = np.pi - np.arctan2(e[1], e[0])  # edge i -> direction -x', normal +y'
        else:
            theta = rng.uniform(0, 2 * np.pi)
        Rb = rot_z(rng.uniform(0, 2 * np.pi)) @ pitch @ _M_PERP @ rot_z(theta)
        if depression == 0.0:
            Rb[2, 2] = 0.0  # b's axis exactly horizontal
        pa = np.array([*rng.uniform(-2, 2, 2), rng.uniform(-2, 2)])
        ra, rb = polygon_radius(A), polygon_radius(B)
        ca = pa + Ra[:, :2] @ polygon_centre(A)
        rho = 1.2 * (ra + rb) * np.sqrt(rng.uniform())
        phi = rng.uniform(0, 2 * np.pi)
        # horizontal placement of b's end-face centroid relative to a's
        cb = ca + np.array([rho * np.cos(phi), rho * np.sin(phi), 0.0])
        pb_ = cb - Rb[:, :2] @ polygon_centre(B)
        if mode == "generic":
            pb_[2] += rng.uniform(-1, 1) * max(ra, rb)
        else:
            zb = pb_[2] + (Rb[2, :2] @ B.T)
            top = int(np.argmax(zb)) if mode == "vertex" else i
            pb_[2] = pa[2] - Rb[2, :2] @ B[top]
            if depression != 0.0:
                # put the top vertex over a random point near a's polygon
                rho = 1.3 * ra * np.sqrt(rng.uniform())
                goal = ca[:2] + rho * np.array([np.cos(phi), np.sin(phi)])
                pb_[:2] += goal - (pb_[:2] + Rb[:2, :2] @ B[top])
        rows.append((A, B, pa, Ra, pb_, Rb))
    return pairs_from_rows(rows)


def vertical_pairs(rng, n, relation, height, *, with_gap=True):
    """a: axis exactly +z; b: axis exactly +z ("parallel") or -z ("antiparallel").

    ``height``: "coplanar" (b's end face in a's end plane) or "random".
    Polygon placements: random (about half overlap), touching at a vertex
    (b = a point-reflected through one of its vertices), touching along an
    edge (reflected through an edge midpoint), or such a touching placement
    pushed 1e-3 R apart / together.
    Returns the pairs and the analytic Euclidean gap of the bodies.
    """
    rows, gaps = [], []
    flip = np.diag([1.0, -1.0, -1.0])
    for k in range(n):
        A = random_polygon(rng, sample_vertex_count(rng, "small"), offset=0.0)
        phi = rng.uniform(0, 2 * np.pi)
        Ra = rot_z(phi)
        pa = np.array([0.0, 0.0, rng.uniform(-1, 1)])
        Aw = A @ Ra[:2, :2].T  # a's polygon in world xy (about pa)
        ra = polygon_radius(A)
        style = k % 4
        if style == 0:  # independent polygon, random placement
            Bw = random_polygon(rng, sample_vertex_count(rng, "small"), offset=0.0)
            Bw = Bw + rng.uniform(-1, 1, 2) * 1.1 * (ra + polygon_radius(Bw))
        else:
            i = int(rng.integers(len(Aw)))
            if style == 1:  # vertex contact
                m = Aw[i]
            else:  # edge contact
                m = 0.5 * (Aw[i] + Aw[(i + 1) % len(Aw)])
            Bw = 2.0 * m - Aw
            if style == 3:  # pushed apart or together along the outward direction
                out = m - polygon_centre(Aw)
                out /= np.linalg.norm(out)
                Bw = Bw + rng.choice([-1.0, 1.0]) * 1e-3 * ra * out
        if relation == "parallel":
            Rb = rot_z(rng.uniform(0, 2 * np.pi))
        else:
            Rb = rot_z(rng.uniform(0, 2 * np.pi)) @ flip
        # b's local polygon such that Rb maps it onto Bw exactly enough
        B = Bw @ Rb[:2, :2]  # rows: Rb2^T w (Rb2 orthonormal)
        Bw_exact = B @ Rb[:2, :2].T
        if height == "coplanar":
            zb = pa[2]
        else:
            zb = pa[2] + rng.uniform(-1, 1) * ra
        pb_ = np.array([0.0, 0.0, zb])
        dist2d = ref_polygon_distance(Aw, Bw_exact) if with_gap else np.nan
        if relation == "parallel" or zb >= pa[2]:
            gap = dist2d
        else:  # antiparallel, b's end face below a's: separated vertically too
            gap = np.hypot(dist2d, pa[2] - zb)
        rows.append((A, B, pa, Ra, pb_, Rb))
        gaps.append(gap)
    return pairs_from_rows(rows), np.array(gaps)


def hash_str(s):
    """Deterministic string hash (Python's ``hash`` is salted per process)."""
    h = 1469598103934665603
    for ch in s.encode():
        h = ((h ^ ch) * 1099511628211) % (1 << 64)
    return h


def count_pairs_sent(monkeypatch, module, kernel_name, arg):
    """Wrap ``module.kernel_name`` (a second-pass kernel) so that each call records how many pairs it got
    (``len`` of its positional argument ``arg``); returns the list of counts."""
    sent = []
    original = getattr(module, kernel_name)

    def counting(*args):
        sent.append(len(args[arg]))
        return original(*args)

    monkeypatch.setattr(module, kernel_name, counting)
    return sent
