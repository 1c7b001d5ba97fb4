"""Independent, slow, obviously-correct references for the test-suite.

These functions are the ground truth the kernels are checked against, written
for clarity, not speed. The LP (``prismbatch.lab.exact``) shares no code with the
kernels; the 2-D brute-force references below are written for the tests only.

Geometry (binding for the whole project)
----------------------------------------
A prism is a convex polygon ``xy`` (n, 2) in its local frame at z = 0
(CCW or CW, normalised to CCW here) and a pose ``(p, R)`` where the COLUMNS
of ``R`` are the local axes in world coordinates.  The body is

    { p + R @ [x, y, t] : (x, y) in polygon, t >= 0 },

semi-infinite along the local +z axis ``d = R[:, 2]``.

Contents
--------
* ``margin_lp`` / ``margin_lp_batch``: exact signed margin via an LP (HiGHS).
* ``point_in_prism_residual``: constraint violation of a world point.
* ``ref_point_in_polygon``, ``ref_polygon_distance``,
  ``ref_halfline_distance``, ``ref_strip_distance``: brute-force 2D
  references for the planar sub-problems.
* ``StreamReference``: the random draws of one sample of the compiled sampling loops.
"""

from __future__ import annotations

import math

import numpy as np

# The LP lives in the package (prismbatch.lab.exact) so that `prismbatch validate`
# can use it too; it shares no code with the kernels.
from prismbatch.lab.exact import (  # noqa: F401
    margin_lp,
    margin_lp_batch,
    point_in_prism_residual,
    polygon_ccw,
    polygon_halfplanes,
)

__all__ = [
    "polygon_ccw",
    "polygon_halfplanes",
    "margin_lp",
    "margin_lp_batch",
    "point_in_prism_residual",
    "ref_point_in_polygon",
    "ref_polygon_distance",
    "ref_halfline_distance",
    "ref_strip_distance",
]

# ---------------------------------------------------------------------------
# 2D brute-force references
# ---------------------------------------------------------------------------


def _cross(o, a, b) -> float:
    return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))


def _hull(points) -> np.ndarray:
    """Convex hull (Andrew's monotone chain), CCW, collinear points dropped.

    Returns 1 vertex for a point set that is a single point, 2 for a
    segment, >= 3 otherwise.
    """
    pts = np.unique(np.asarray(points, dtype=float).reshape(-1, 2), axis=0)
    if len(pts) <= 2:
        return pts
    pts = [tuple(p) for p in pts]  # np.unique sorted them lexicographically
    lower, upper = [], []
    for p in pts:
        while len(lower) >= 2 and _cross(lower[-2], lower[-1], p) <= 0.0:
            lower.pop()
        lower.append(p)
    for p in reversed(pts):
        while len(upper) >= 2 and _cross(upper[-2], upper[-1], p) <= 0.0:
            upper.pop()
        upper.append(p)
    hull = lower[:-1] + upper[:-1]
    return np.array(hull, dtype=float)


def _edges(vertices: np.ndarray):
    """Edges of a convex point/segment/polygon given by its hull vertices."""
    k = len(vertices)
    if k == 1:
        return [(vertices[0], vertices[0])]
    if k == 2:
        return [(vertices[0], vertices[1])]
    return [(vertices[i], vertices[(i + 1) % k]) for i in range(k)]


def _point_segment_distance(x, a, b) -> float:
    x, a, b = (np.asarray(v, dtype=float) for v in (x, a, b))
    ab = b - a
    L2 = float(ab @ ab)
    if L2 == 0.0:
        return float(np.hypot(*(x - a)))
    t = min(1.0, max(0.0, float((x - a) @ ab) / L2))
    return float(np.hypot(*(x - (a + t * ab))))


def _on_segment(a, b, x) -> bool:
    """x (known collinear with a-b) lies within the bounding box of a-b."""
    return min(a[0], b[0]) <= x[0] <= max(a[0], b[0]) and min(a[1], b[1]) <= x[1] <= max(a[1], b[1])


def _segments_intersect(a, b, c, d) -> bool:
    """Closed segments [a, b] and [c, d] share a point (exact orientation tests)."""
    o1 = np.sign(_cross(a, b, c))
    o2 = np.sign(_cross(a, b, d))
    o3 = np.sign(_cross(c, d, a))
    o4 = np.sign(_cross(c, d, b))
    if o1 * o2 < 0 and o3 * o4 < 0:
        return True
    if o1 == 0 and _on_segment(a, b, c):
        return True
    if o2 == 0 and _on_segment(a, b, d):
        return True
    if o3 == 0 and _on_segment(c, d, a):
        return True
    if o4 == 0 and _on_segment(c, d, b):
        return True
    return False


def _inside_convex_ccw(poly_ccw: np.ndarray, x) -> bool:
    """Exact closed containment test in a CCW convex polygon (>= 3 vertices)."""
    k = len(poly_ccw)
    return all(_cross(poly_ccw[i], poly_ccw[(i + 1) % k], x) >= 0.0 for i in range(k))


def ref_point_in_polygon(poly, x, tol=0.0) -> bool:
    """Is point ``x`` in convex polygon ``poly`` (either orientation)?

    Computes the signed distance of ``x`` to every edge LINE (positive
    outside, CCW-normalised) and returns ``max <= tol``.  Note this is the
    half-plane slack test: near a sharp corner a point up to
    ``tol / sin(half corner angle)`` from the polygon is accepted.
    """
    n, h = polygon_halfplanes(poly)
    x = np.asarray(x, dtype=float).reshape(2)
    return bool(np.max(n @ x - h) <= tol)


def ref_polygon_distance(poly, other_points) -> float:
    """Euclidean distance between convex polygon ``poly`` and conv(other_points).

    ``other_points`` is (k, 2); k = 1 is a point, k = 2 a segment, more a
    convex hull (computed here).  Exact brute force: 0 if any vertex of one
    lies in the other or any edge pair intersects, otherwise the minimum of
    all vertex-to-edge distances in both directions.  O(n k).
    """
    A = polygon_ccw(poly)
    B = _hull(other_points)
    if len(B) == 0:
        raise ValueError("other_points is empty")
    for v in B:
        if _inside_convex_ccw(A, v):
            return 0.0
    if len(B) >= 3:
        for v in A:
            if _inside_convex_ccw(B, v):
                return 0.0
    edges_a, edges_b = _edges(A), _edges(B)
    for a0, a1 in edges_a:
        for b0, b1 in edges_b:
            if _segments_intersect(a0, a1, b0, b1):
                return 0.0
    best = np.inf
    for v in A:
        for b0, b1 in edges_b:
            best = min(best, _point_segment_distance(v, b0, b1))
    for v in B:
        for a0, a1 in edges_a:
            best = min(best, _point_segment_distance(v, a0, a1))
    return float(best)


def _truncation_length(poly, base_points, d) -> float:
    """Ray parameter T beyond which no distance minimiser need lie.

    Let c be the vertex mean of the polygon (inside it, convexity) and
    R = max |v - c|.  For a shape S = {b + t d : b in B, t >= 0} with B
    convex, a minimising pair (x* = b* + t* d, q*) either has t* = 0 or,
    by optimality in t, (x* - q*) . d = 0, i.e. t* |d| = (q* - b*) . d/|d|
    <= |q* - b*| <= R + max_b |b - c|.  Truncating at
    T = (max_b |b - c| + R + 1) / |d| therefore keeps a minimiser.
    """
    P = np.asarray(poly, dtype=float).reshape(-1, 2)
    c = P.mean(axis=0)
    R = float(np.max(np.hypot(*(P - c).T)))
    reach = max(float(np.hypot(*(np.asarray(b, float) - c))) for b in base_points)
    nd = float(np.hypot(*np.asarray(d, dtype=float)))
    if nd == 0.0:
        raise ValueError("direction d must be non-zero")
    return (reach + R + 1.0) / nd


def ref_halfline_distance(poly, p, d) -> float:
    """Distance between convex polygon ``poly`` and the ray {p + t d, t >= 0}."""
    p = np.asarray(p, dtype=float).reshape(2)
    d = np.asarray(d, dtype=float).reshape(2)
    T = _truncation_length(poly, [p], d)
    return ref_polygon_distance(poly, np.array([p, p + T * d]))


def ref_strip_distance(poly, p1, p2, d) -> float:
    """Distance between ``poly`` and {p1 + s (p2 - p1) + t d : s in [0,1], t >= 0}."""
    p1 = np.asarray(p1, dtype=float).reshape(2)
    p2 = np.asarray(p2, dtype=float).reshape(2)
    d = np.asarray(d, dtype=float).reshape(2)
    T = _truncation_length(poly, [p1, p2], d)
    return ref_polygon_distance(poly, np.array([p1, p2, p1 + T * d, p2 + T * d]))


class StreamReference:
    """Plain-Python SplitMix64 and ziggurat draws of one sample (``prismbatch._kernels.streams``),
    on Python integers masked to 64 bits, written from the papers' descriptions for the tests.

    ``StreamReference(key, u)`` is the generator of sample ``u`` of stream ``key``; the
    ziggurat's tables come from the package (the tests check them on their own).
    """

    MASK = (1 << 64) - 1
    GOLDEN = 0x9E3779B97F4A7C15

    @classmethod
    def mix(cls, x):
        x = ((x ^ (x >> 30)) * 0xBF58476D1CE4E5B9) & cls.MASK
        x = ((x ^ (x >> 27)) * 0x94D049BB133111EB) & cls.MASK
        return x ^ (x >> 31)

    def __init__(self, key, u):
        self.state = self.mix((int(key) + (int(u) + 1) * self.GOLDEN) & self.MASK)

    def bits(self):
        self.state = (self.state + self.GOLDEN) & self.MASK
        return self.mix(self.state)

    def uniform(self):
        return ((self.bits() >> 12) + 0.5) / 2.0**52

    def normal(self, tables):
        k, w, f, r = tables
        while True:
            bits = self.bits()
            i, negative, a = bits & 0xFF, (bits >> 8) & 1, (bits >> 9) & ((1 << 52) - 1)
            x = -(a * float(w[i])) if negative else a * float(w[i])
            if a < int(k[i]):
                return x
            if i == 0:
                while True:
                    xx = -math.log(self.uniform()) / r
                    if -2.0 * math.log(self.uniform()) > xx * xx:
                        return -(r + xx) if negative else r + xx
            elif (f[i - 1] - f[i]) * self.uniform() + f[i] < math.exp(-0.5 * x * x):
                return x


def rodrigues(w, t):
    """exp(t [w]x), written independently of the kernels (matrix exponential of the skew matrix)."""
    th = np.linalg.norm(w) * t
    if th == 0.0:
        return np.eye(3)
    k = np.asarray(w, float) / np.linalg.norm(w)
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(th) * K + (1.0 - math.cos(th)) * K @ K
