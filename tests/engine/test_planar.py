"""The five planar tests of ``prismbatch.planar`` against brute force.

Each of point/segment/half-line/strip/polygon vs convex polygon is checked on
>= 1000 random cases (random convex polygons of 3..200 vertices, regular and
irregular) against the plain references of tests/reference.py.  The cases
mix random queries with exact and near-exact contacts: queries on vertices
and edges, segments/rays/strips lying on a supporting line through a vertex
or along an edge line, polygons sharing a vertex or an edge, and all of
those pushed 1e-6 apart or together.

Decision rule (tol = 1e-9, polygons of radius 0.5..2):

* reference distance <= 1e-3 tol (touching up to rounding, or overlapping)
  => hit must be True;
* reference distance >  1e-7 => hit must be False;
* in between: no assertion (touching band).

On a hit the returned contact point must lie within 1e-7 of both shapes
(distances computed here by plain formulas / the reference), and without a
hit it must be NaN.  A second group of tests uses a large tol (0.05) and
checks the tolerance semantics themselves: "hit iff the 2-D distance <= tol"
and a contact within tol of both shapes.
"""

from __future__ import annotations

import numpy as np
import pytest

from prismbatch import planar

from helpers import hash_str, polygon_centre, random_polygon, sample_vertex_count
from reference import (
    polygon_halfplanes,
    ref_halfline_distance,
    ref_point_in_polygon,
    ref_polygon_distance,
    ref_strip_distance,
)

TOL = 1e-9
HIT_MAX = 1e-3 * TOL  # reference distance up to which a hit is required
MISS_MIN = 1e-7  # reference distance beyond which a miss is required
CONTACT_TOL = 1e-7
N_CASES = 1000

BIG_TOL = 0.05
N_TOL_CASES = 300


def seeded(name):
    return np.random.default_rng(hash_str("planar/" + name) % 2**32)


# ---------------------------------------------------------------------------
# plain geometry helpers (distances of a point to the query shapes)
# ---------------------------------------------------------------------------


def dist_point_segment(x, a, b):
    x, a, b = (np.asarray(v, float) for v in (x, a, b))
    ab = b - a
    L2 = ab @ ab
    t = 0.0 if L2 == 0 else min(1.0, max(0.0, (x - a) @ ab / L2))
    return float(np.hypot(*(x - a - t * ab)))


def dist_point_ray(x, p, d):
    x, p, d = (np.asarray(v, float) for v in (x, p, d))
    t = max(0.0, (x - p) @ d / (d @ d))
    return float(np.hypot(*(x - p - t * d)))


def dist_point_strip(x, p1, p2, d):
    """Distance from x to {p1 + s (p2 - p1) + t d : s in [0, 1], t >= 0}."""
    x, p1, p2, d = (np.asarray(v, float) for v in (x, p1, p2, d))
    e = p2 - p1
    det = e[0] * d[1] - e[1] * d[0]
    if abs(det) > 1e-14 * np.hypot(*e) * np.hypot(*d):
        r = x - p1
        s = (r[0] * d[1] - r[1] * d[0]) / det
        t = (e[0] * r[1] - e[1] * r[0]) / det
        if 0.0 <= s <= 1.0 and t >= 0.0:
            return 0.0
    # outside (or degenerate): the set is the union of its boundary pieces'
    # hull, and its distance is attained on the segment or one of the rays
    return min(dist_point_segment(x, p1, p2), dist_point_ray(x, p1, d), dist_point_ray(x, p2, d))


def dist_point_polygon(x, poly):
    return ref_polygon_distance(poly, np.asarray(x, float)[None, :])


class PolyGeom:
    """Vertices, edges, outward normals and vertex normals of a CCW polygon."""

    def __init__(self, P):
        self.P = P
        self.n = len(P)
        self.e = np.roll(P, -1, axis=0) - P
        L = np.hypot(*self.e.T)
        self.en = np.column_stack([self.e[:, 1], -self.e[:, 0]]) / L[:, None]  # outward normals
        nv = np.roll(self.en, 1, axis=0) + self.en
        self.vn = nv / np.hypot(*nv.T)[:, None]  # outward vertex normals
        self.vt = np.column_stack([-self.vn[:, 1], self.vn[:, 0]])  # supporting-line directions
        self.c = polygon_centre(P)
        self.r = float(np.max(np.hypot(*(P - self.c).T)))

    def box_point(self, rng, grow=1.0):
        return self.c + rng.uniform(-1, 1, 2) * self.r * (1.0 + grow)

    def edge_point(self, rng, i):
        return self.P[i] + rng.uniform(0.05, 0.95) * self.e[i]


def rot2(v, ang):
    c, s = np.cos(ang), np.sin(ang)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def pick_shift(rng, big_tol=None):
    """Offset along an outward normal: 0 (touch), +-1e-6 or a random amount.

    With ``big_tol`` the offset is U(0, 2) * big_tol (around the tolerance).
    """
    if big_tol is not None:
        return rng.uniform(0.0, 2.0) * big_tol
    return float(rng.choice([0.0, 0.0, 1e-6, -1e-6, rng.uniform(-0.3, 0.3)]))


def random_test_polygon(rng, max_n=200):
    fam = "small" if rng.random() < 0.5 else "medium"
    n = min(sample_vertex_count(rng, fam), max_n)
    return random_polygon(rng, n)


# ---------------------------------------------------------------------------
# query generators: each returns (polygon, args) with a mixture of kinds
# ---------------------------------------------------------------------------


def gen_point(rng, g, big_tol=None):
    k = rng.integers(6)
    i = int(rng.integers(g.n))
    if k == 0:
        return g.box_point(rng)
    if k == 1:
        return g.P[i].copy()  # exactly a vertex
    if k == 2:
        return g.edge_point(rng, i)  # on an edge (up to rounding)
    if k == 3:
        return g.edge_point(rng, i) + pick_shift(rng, big_tol) * g.en[i]
    if k == 4:
        return g.P[i] + pick_shift(rng, big_tol) * g.vn[i]
    return g.c + rng.uniform(-0.3, 0.3, 2) * g.r


def gen_segment(rng, g, big_tol=None):
    k = rng.integers(7)
    i = int(rng.integers(g.n))
    s = pick_shift(rng, big_tol)
    if k == 0:
        return g.box_point(rng), g.box_point(rng)
    if k == 1:
        return g.box_point(rng), g.P[i].copy()  # ends on a vertex
    if k == 2:  # on the supporting line through vertex i (tangent)
        a, b = rng.uniform(0, 1, 2) * g.r * rng.choice([0.0, 1.0], 2, p=[0.2, 0.8])
        return g.P[i] - a * g.vt[i] + s * g.vn[i], g.P[i] + b * g.vt[i] + s * g.vn[i]
    if k == 3:  # collinear with edge i, beyond its end vertex
        a = float(rng.choice([0.0, 1e-6, rng.uniform(0, 1)]))
        b = a + rng.uniform(0.01, 1)
        j = (i + 1) % g.n
        return g.P[j] + a * g.e[i] + s * g.en[i], g.P[j] + b * g.e[i] + s * g.en[i]
    if k == 4:  # from inside to far outside
        return g.c + rng.uniform(-0.2, 0.2, 2) * g.r, g.box_point(rng, grow=3.0)
    if k == 5:  # degenerate: a point
        p = g.P[i] + s * g.vn[i] if rng.random() < 0.5 else g.box_point(rng)
        return p, p.copy()
    # inside entirely
    return g.c + rng.uniform(-0.2, 0.2, 2) * g.r, g.c + rng.uniform(-0.2, 0.2, 2) * g.r


def _draw(rng, g, big_tol):
    """Shared draws of the ray generators: variant k, vertex i, shift s, a random direction."""
    k = rng.integers(7)
    i = int(rng.integers(g.n))
    s = pick_shift(rng, big_tol)
    ang = rng.uniform(0, 2 * np.pi)
    return k, i, s, np.array([np.cos(ang), np.sin(ang)]) * rng.uniform(0.1, 3.0)


def gen_halfline(rng, g, big_tol=None):
    k, i, s, rnd_dir = _draw(rng, g, big_tol)
    if k == 0:
        return g.box_point(rng, grow=2.0), rnd_dir
    if k == 1:  # pointing at the polygon
        p = g.box_point(rng, grow=2.0)
        return p, (g.c - p) * rng.uniform(0.1, 2.0)
    if k == 2:  # along the supporting line through vertex i
        sign = rng.choice([-1.0, 1.0])
        p = g.P[i] - sign * rng.uniform(0, 1) * g.r * g.vt[i] + s * g.vn[i]
        return p, sign * g.vt[i] * rng.uniform(0.1, 3.0)
    if k == 3:  # along edge i's line, from before its start vertex
        p = g.P[i] - rng.uniform(0, 1) * g.e[i] + s * g.en[i]
        return p, g.e[i] * rng.uniform(0.1, 3.0)
    if k == 4:  # from a vertex, pointing away from the polygon
        return g.P[i] + s * g.vn[i], rot2(g.vn[i], rng.uniform(-1.4, 1.4)) * rng.uniform(0.1, 3.0)
    if k == 5:  # collinear with edge i, beyond its end, pointing away
        j = (i + 1) % g.n
        a = float(rng.choice([0.0, 1e-6, rng.uniform(0, 1)]))
        return g.P[j] + a * g.e[i] + s * g.en[i], g.e[i] * rng.uniform(0.1, 3.0)
    return g.c + rng.uniform(-0.2, 0.2, 2) * g.r, rnd_dir  # from inside


def gen_strip(rng, g, big_tol=None):
    k, i, s, rnd_dir = _draw(rng, g, big_tol)
    if k == 0:
        return g.box_point(rng, grow=2.0), g.box_point(rng, grow=2.0), rnd_dir
    if k == 1:  # base segment on the supporting line at vertex i, strip outward
        a, b = rng.uniform(0, 1, 2) * g.r
        p1 = g.P[i] - a * g.vt[i] + s * g.vn[i]
        p2 = g.P[i] + b * g.vt[i] + s * g.vn[i]
        return p1, p2, rot2(g.vn[i], rng.uniform(-1.4, 1.4)) * rng.uniform(0.1, 3.0)
    if k == 2:  # one boundary ray on the supporting line at vertex i
        sign = rng.choice([-1.0, 1.0])
        p2 = g.P[i] - sign * rng.uniform(0, 1) * g.r * g.vt[i] + s * g.vn[i]
        p1 = p2 + rng.uniform(0.05, 1) * g.r * g.vn[i] + rng.uniform(-1, 1) * g.r * g.vt[i]
        return p1, p2, sign * g.vt[i] * rng.uniform(0.1, 3.0)
    if k == 3:  # degenerate: direction parallel to the base segment
        p1 = g.box_point(rng, grow=2.0)
        return p1, p1 + rnd_dir * rng.uniform(0.1, 1.0), rnd_dir * rng.choice([-1.0, 1.0])
    if k == 4:  # base segment crosses the polygon's whole width
        t = rnd_dir / np.linalg.norm(rnd_dir)  # (cos ang, sin ang) of the draw
        q = g.c - 0.5 * g.r * rot2(t, np.pi / 2) * rng.uniform(-3, 3)
        return q - 3 * g.r * t, q + 3 * g.r * t, rot2(t, rng.uniform(0.2, 2.9))
    if k == 5:  # boundary ray along edge i's line, strip outside
        p2 = g.P[i] - rng.uniform(0, 1) * g.e[i] + s * g.en[i]
        p1 = p2 + rng.uniform(0.05, 1) * g.r * g.en[i]
        return p1, p2, g.e[i] * rng.uniform(0.1, 3.0)
    # base segment is a single point (strip degenerates to a ray)
    p = g.box_point(rng, grow=1.0)
    return p, p.copy(), rnd_dir


def gen_polygon(rng, g, big_tol=None):
    """Second polygon: random, touching at a vertex or along an edge, or nested."""
    k = rng.integers(6)
    i = int(rng.integers(g.n))
    s = pick_shift(rng, big_tol)
    Q = random_polygon(rng, sample_vertex_count(rng, "small"), radius=g.r * rng.uniform(0.2, 1.5))
    if k == 0:  # random placement
        return Q + g.box_point(rng, grow=1.5) - polygon_centre(Q)
    if k == 1:  # Q's extreme vertex against -vn_i placed on vertex i
        j = int(np.argmin(Q @ g.vn[i]))
        return Q + (g.P[i] - Q[j]) + s * g.vn[i]
    if k == 2:  # sharing edge i exactly (Q built on the outer side of it)
        a, b = g.P[i], g.P[(i + 1) % g.n]
        L = np.hypot(*g.e[i])
        m = rng.integers(1, 6)
        out = (
            a
            + rng.uniform(0, 1, (m, 1)) * g.e[i]
            + rng.uniform(0.05, 1.0, (m, 1)) * L * g.en[i][None, :]
            + rng.uniform(-0.5, 0.5, (m, 1)) * g.e[i]
        )
        pts = np.vstack([a, b, out])
        from scipy.spatial import ConvexHull

        hull = ConvexHull(pts)
        Q = pts[hull.vertices]
        return Q + s * g.en[i]
    if k == 3:  # nested: a shrunken copy of P inside P
        f = rng.uniform(0.05, 0.9)
        return g.c + f * (g.P - g.c)
    if k == 4:  # P inside a large polygon
        return Q * (3.0 * g.r / polygon_radius_of(Q)) + g.c - polygon_centre(Q)
    # point reflection of P through one of its vertices (touch at that vertex)
    if g.n <= 16:
        return 2.0 * g.P[i] - g.P + s * g.vn[i]
    return Q + g.box_point(rng, grow=0.5) - polygon_centre(Q)


def polygon_radius_of(Q):
    return float(np.max(np.hypot(*(Q - polygon_centre(Q)).T)))


# ---------------------------------------------------------------------------
# driver
# ---------------------------------------------------------------------------

KINDS = {
    # name: (generator, package call, reference distance, distance of x to the query shape)
    "segment": (
        gen_segment,
        lambda P, q, tol: planar.segment_polygon(P, q[0], q[1], tol),
        lambda P, q: ref_polygon_distance(P, np.array([q[0], q[1]])),
        lambda x, q: dist_point_segment(x, q[0], q[1]),
    ),
    "halfline": (
        gen_halfline,
        lambda P, q, tol: planar.halfline_polygon(P, q[0], q[1], tol),
        lambda P, q: ref_halfline_distance(P, q[0], q[1]),
        lambda x, q: dist_point_ray(x, q[0], q[1]),
    ),
    "strip": (
        gen_strip,
        lambda P, q, tol: planar.strip_polygon(P, q[0], q[1], q[2], tol),
        lambda P, q: ref_strip_distance(P, q[0], q[1], q[2]),
        lambda x, q: dist_point_strip(x, q[0], q[1], q[2]),
    ),
    "polygon": (
        gen_polygon,
        lambda P, q, tol: planar.polygon_polygon(P, q, tol),
        lambda P, q: ref_polygon_distance(P, q),
        lambda x, q: dist_point_polygon(x, q),
    ),
}


def _as_tuple(q):
    return q if isinstance(q, tuple) else q


def run_cases(kind, n_cases, tol, big_tol=None, seed_name=None):
    gen, call, ref, dist_query = KINDS[kind]
    rng = seeded(seed_name or kind)
    failures = []
    stats = {"must_hit": 0, "must_miss": 0, "band": 0, "hits": 0}
    for case in range(n_cases):
        P = random_test_polygon(rng, max_n=200 if kind != "polygon" else 120)
        g = PolyGeom(P)
        q = gen(rng, g, big_tol)
        # the package accepts either orientation: pass it clockwise half the time
        P_in = P[::-1].copy() if rng.random() < 0.5 else P
        hit, contact = call(P_in, q, tol)
        dist = ref(P, q)
        if big_tol is None:
            must_hit, must_miss = dist <= HIT_MAX, dist > MISS_MIN
            ctol = CONTACT_TOL
        else:
            # "hit iff the 2-D Euclidean distance <= tol" (relative slack 1e-9)
            must_hit, must_miss = dist <= tol * (1 - 1e-9), dist > tol * (1 + 1e-9)
            ctol = tol * (1 + 1e-9) + 1e-12
        stats["must_hit"] += must_hit
        stats["must_miss"] += must_miss
        stats["band"] += not (must_hit or must_miss)
        stats["hits"] += bool(hit)
        msg = None
        if must_hit and not hit:
            msg = f"missed: ref distance {dist:.3e}"
        elif must_miss and hit:
            msg = f"false hit: ref distance {dist:.3e}"
        contact = np.asarray(contact, float)
        if msg is None and contact.shape != (2,):
            msg = f"contact has shape {contact.shape}"
        elif msg is None and hit:
            if not np.all(np.isfinite(contact)):
                msg = f"hit without a finite contact: {contact}"
            else:
                d_poly = dist_point_polygon(contact, P)
                d_query = dist_query(contact, q)
                if d_poly > ctol or d_query > ctol:
                    msg = (
                        f"contact {contact} is {d_poly:.3e} from the polygon and {d_query:.3e} "
                        f"from the {kind} (ref distance {dist:.3e})"
                    )
        elif msg is None and not np.all(np.isnan(contact)):
            msg = f"no hit but contact {contact} is not NaN"
        if msg:
            failures.append(f"case {case} (n={len(P)}): {msg}\n    P={P.tolist()}\n    q={_fmt(q)}")
    return failures, stats


def _fmt(q):
    if isinstance(q, tuple):
        return "(" + ", ".join(repr(np.asarray(v).tolist()) for v in q) + ")"
    return repr(np.asarray(q).tolist())


@pytest.mark.slow
@pytest.mark.parametrize("kind", list(KINDS))
def test_planar_against_reference(kind):
    failures, stats = run_cases(kind, N_CASES, TOL)
    assert not failures, f"{len(failures)} of {N_CASES} {kind} cases failed:\n" + "\n".join(failures[:8])
    # the mixture must really contain contacts, near misses and clear misses
    assert stats["must_hit"] >= 0.25 * N_CASES, stats
    assert stats["must_miss"] >= 0.15 * N_CASES, stats


@pytest.mark.parametrize("kind", list(KINDS))
def test_planar_tolerance_semantics(kind):
    """tol = 0.05: hit iff the 2-D distance <= tol, contact within tol of both."""
    failures, stats = run_cases(kind, N_TOL_CASES, BIG_TOL, big_tol=BIG_TOL, seed_name=kind + "/tol")
    assert not failures, f"{len(failures)} of {N_TOL_CASES} {kind} cases failed (tol={BIG_TOL}):\n" + "\n".join(
        failures[:8]
    )
    # enough queries within (0, tol] and (tol, 2 tol]
    assert stats["must_hit"] >= 0.2 * N_TOL_CASES and stats["must_miss"] >= 0.2 * N_TOL_CASES, stats


# ---------------------------------------------------------------------------
# point vs polygon (eq. 1: signed distance to the edge line of the polar wedge)
# ---------------------------------------------------------------------------


def wedge_distances(P, c, x, slack=1e-9):
    """Signed distances (positive inside) of x to the edge lines of every
    polar wedge about c that holds x (more than one only on a wedge border)."""
    n = len(P)
    out = []
    v = P - c
    w = x - c
    scale = np.max(np.hypot(*v.T)) * max(np.hypot(*w), 1e-300)
    for i in range(n):
        a, b = v[i], v[(i + 1) % n]
        c1 = a[0] * w[1] - a[1] * w[0]
        c2 = w[0] * b[1] - w[1] * b[0]
        if c1 >= -slack * scale and c2 >= -slack * scale and (a @ w > 0 or b @ w > 0):
            e = b - a
            L = np.hypot(*e)
            out.append(float((e[0] * (w[1] - a[1]) - e[1] * (w[0] - a[0])) / L))
    return out


@pytest.mark.slow
def test_point_polygon_against_reference():
    rng = seeded("point")
    failures = []
    n_inside = n_outside = n_hit = 0
    for case in range(N_CASES):
        P = random_test_polygon(rng)
        g = PolyGeom(P)
        x = gen_point(rng, g)
        hit, sd = planar.point_polygon(P[::-1].copy() if case % 2 else P, x, TOL)
        msgs = []
        if hit != (sd >= -TOL):
            msgs.append(f"hit={hit} but signed distance {sd:.3e} (tol {TOL})")
        dist = dist_point_polygon(x, P)
        if dist <= HIT_MAX and not hit:
            msgs.append(f"missed: ref distance {dist:.3e}, signed distance {sd:.3e}")
        if dist > MISS_MIN and hit:
            msgs.append(f"false hit: ref distance {dist:.3e}, signed distance {sd:.3e}")
        n_hit += hit
        # sign against the reference containment test (half-plane slacks)
        if ref_point_in_polygon(P, x, tol=-1e-12):
            n_inside += 1
            if not sd > 0:
                msgs.append(f"strictly inside but signed distance {sd:.3e}")
        elif not ref_point_in_polygon(P, x, tol=1e-12):
            n_outside += 1
            if not sd < 0:
                msgs.append(f"strictly outside but signed distance {sd:.3e}")
        n2, h = polygon_halfplanes(P)
        slack = n2 @ x - h
        if sd >= 0:
            # inside: the wedge edge is one of the edges, so its distance is
            # at least the distance to the boundary
            if sd < -slack.max() - 1e-12:
                msgs.append(f"inside distance {sd:.3e} below the boundary distance {-slack.max():.3e}")
        else:
            # outside: a lower bound of the Euclidean distance
            if -sd > dist + 1e-12:
                msgs.append(f"outside |signed distance| {-sd:.3e} exceeds the Euclidean distance {dist:.3e}")
        # eq. 1 exactly: the distance to the edge line of x's polar wedge about
        # the area centroid (either wedge when x is on a wedge border)
        if np.hypot(*(x - g.c)) > 1e-6 * g.r:
            cands = wedge_distances(P, g.c, x)
            if cands and min(abs(sd - cd) for cd in cands) > 1e-10 * (1 + g.r):
                msgs.append(f"signed distance {sd:.6e} is not a wedge edge-line distance {cands}")
        if msgs:
            failures.append(
                f"case {case} (n={len(P)}): " + "; ".join(msgs) + f"\n    P={P.tolist()}\n    x={x.tolist()}"
            )
    assert not failures, f"{len(failures)} of {N_CASES} point cases failed:\n" + "\n".join(failures[:8])
    assert n_inside >= 0.2 * N_CASES and n_outside >= 0.2 * N_CASES, (n_inside, n_outside)
    assert 0.2 * N_CASES <= n_hit <= 0.9 * N_CASES


@pytest.mark.slow  # the full suite; the fast set keeps a lighter test of the same path
def test_point_polygon_vertices_and_edges_exact():
    """Every vertex and edge midpoint of a few polygons is a hit at tol = 0
    up to rounding (signed distance >= -1e-12 r), the signed distance of a
    point pushed out by h along an edge normal is in [-h, 0), and the area
    centroid is inside with at least its distance to the boundary."""
    rng = seeded("point-exact")
    for _ in range(40):
        P = random_test_polygon(rng)
        g = PolyGeom(P)
        for i in range(g.n):
            for x in (P[i], 0.5 * (P[i] + P[(i + 1) % g.n])):
                hit, sd = planar.point_polygon(P, x, 1e-12 * g.r)
                assert hit and abs(sd) <= 1e-12 * g.r, (P.tolist(), x.tolist(), sd)
            h = 1e-4 * g.r
            x = g.edge_point(rng, i) + h * g.en[i]
            hit, sd = planar.point_polygon(P, x, 0.0)
            assert not hit and -h * (1 + 1e-6) <= sd < 0, (P.tolist(), x.tolist(), sd)
        # the area centroid itself (polar angle undefined): inside, positive
        hit, sd = planar.point_polygon(P, g.c, 0.0)
        n2, h2 = polygon_halfplanes(P)
        assert hit and sd >= np.min(h2 - n2 @ g.c) * (1 - 1e-9), (P.tolist(), sd)


@pytest.mark.parametrize("period", [4.0, 2 * np.pi])
def test_wrap_is_the_remainder_bit_for_bit(period):
    """The kernels' ``wrap`` (a compare and an add, for differences of two angles) against Python's
    ``%`` over its whole range [-period, period], ends and values that round to the period included."""
    from prismbatch._kernels.planar import wrap

    rng = np.random.default_rng(11)
    edges = [-period, period, 0.0, -0.0, -1e-300, -1e-17, 1e-17, np.nextafter(period, 0.0), -np.nextafter(period, 0.0)]
    xs = np.concatenate([rng.uniform(-period, period, 20000), 10.0 ** rng.uniform(-20, 0, 2000) * -1, edges])
    got = np.array([wrap(float(x), period) for x in xs])
    want = np.array([float(x) % period for x in xs])
    assert np.array_equal(got, want)
    assert 0.0 <= got.min() and got.max() <= period
    assert np.isnan(wrap(np.nan, period))


# ---------------------------------------------------------------------------
# the planar GJK without its witness (collide's status-only path)
# ---------------------------------------------------------------------------


def test_gjk_without_witness_decides_as_with_it():
    """``gjk(..., witness=False)`` (collide without contacts) takes the same decision after the same
    iterations as with the witness, and leaves the witness at zero; with it, a hit's point of A lies
    in A and within tol of its point of B. Polygon A against polygon B moved by p and swept along w
    (the spec of a projected prism), placed to touch, overlap and miss."""
    from prismbatch._kernels.planar import gjk, point_polygon_distance
    from prismbatch.shapes import PrismSet

    rng = seeded("gjk/witness")
    hits = misses = 0
    for case in range(400):
        sa, sb = (PrismSet([random_polygon(rng, sample_vertex_count(rng, "small" if case % 2 else "medium"))])
                  for _ in range(2))  # fmt: skip
        direction = rng.normal(size=2)
        w = direction / np.hypot(*direction)
        # B's vertex furthest along -w put on A's vertex furthest along w, then moved along w by up to
        # +-0.5 or +-tol/10 (touching: the nearest pair is then these two vertices), or anywhere
        ka, kb = np.argmax(sa.vx * w[0] + sa.vy * w[1]), np.argmax(-(sb.vx * w[0] + sb.vy * w[1]))
        gap = rng.choice([-0.5, -0.1 * TOL, 0.0, 0.1 * TOL, 0.5]) * rng.random()
        vertex_to_vertex = np.array([sa.vx[ka] - sb.vx[kb], sa.vy[ka] - sb.vy[kb]])
        p = vertex_to_vertex + gap * w if case % 4 else rng.uniform(-4.0, 4.0, 2)
        sweep = rng.uniform(0.0, 3.0)
        sp = (p[0], p[1], 1.0, 0.0, 0.0, 1.0, w[0], w[1], 0.0, 0.0, 1.0, 0.0, sweep, 0.0, 0.0, 0.0)
        arrays = (sa.vx, sa.vy, sa.edge_angle, sa.edge_table, 0, len(sa.vx))
        arrays += (sb.vx, sb.vy, sb.edge_angle, sb.edge_table, 0, len(sb.vx))
        full = gjk(*arrays, sp, TOL, True)
        bare = gjk(*arrays, sp, TOL, False)
        assert bare[:2] == full[:2], (case, bare, full)
        assert bare[2:] == (0.0,) * 5, (case, bare)
        if full[0]:
            hits += 1
            depth = point_polygon_distance(
                sa.vx, sa.vy, sa.vertex_angle, sa.inv_edge_len, 0, len(sa.vx), full[2], full[3]
            )
            assert depth >= -1e-12, (case, full, depth)
            _, _, ax, ay, u, v, t = full
            apart = np.hypot(ax - (p[0] + u + w[0] * t), ay - (p[1] + v + w[1] * t))
            assert apart <= TOL + 1e-12, (case, full, apart)
        else:
            misses += 1
    assert hits >= 100 and misses >= 100, (hits, misses)


def test_planar_tests_check_their_arguments_as_collide_does():
    """tol is a real number in [0, 1e100] (a negative one made segment_polygon hit a segment 0.1 away, NaN made
    point_polygon miss the square's centre), points and directions are real numbers of magnitude <= 1e100
    (beyond about 1e154 their squares overflowed, and rays through the square missed it) and polygons lie in
    collide's supported range; a direction is scaled before it is normalised."""
    from prismbatch import planar as P

    sq = [[0, 0], [1, 0], [1, 1], [0, 1]]
    for tol, exc in (
        (-1.0, ValueError),
        (np.nan, ValueError),
        (np.inf, ValueError),
        (True, TypeError),
        ("0.1", TypeError),
    ):
        with pytest.raises(exc, match="tol"):
            P.segment_polygon(sq, [2.0, 0.0], [2.0, 1.0], tol=tol)
        with pytest.raises(exc, match="tol"):
            P.point_polygon(sq, [0.5, 0.5], tol=tol)
    with pytest.raises(ValueError, match=r"p must be 2 finite numbers of magnitude <= 1e\+100"):
        P.halfline_polygon(sq, [1e200, 0.5], [-1, 0])
    with pytest.raises(TypeError, match="p must have a real numeric dtype"):
        P.point_polygon(sq, ["0.5", "0.5"])
    with pytest.raises(ValueError, match="outside the supported range"):
        P.point_polygon(np.array(sq, float) * 1e-170, [0.0, 0.0])
    assert P.halfline_polygon(sq, [1e99, 0.5], [-1, 0])[0] and P.segment_polygon(sq, [1e99, 0.5], [-1e99, 0.5])[0]
    assert not P.halfline_polygon(sq, [1e99, 1.5], [-1, 0])[0]
    want = P.halfline_polygon(sq, [2, -0.5], [-1, 1])
    for d in ([-1.5e99, 1.5e99], [-1e-320, 1e-320]):
        got = P.halfline_polygon(sq, [2, -0.5], d)
        assert got[0] and np.allclose(got[1], want[1], rtol=0, atol=1e-12)
