"""The paper's five planar tests (section III), one query at a time.

Each tests a convex polygon against a point (eq. 1), a segment (eqs. 3-5), a
half-line (eqs. 6-8), an unbounded strip (eqs. 9-14) or another convex
polygon (eqs. 15-19), and returns ``(hit, contact)`` with ``contact`` a 2-D
point within ``tol`` of both shapes (NaN when there is no hit).

The point test is the paper's polar wedge search (binary search, O(log n)).
The other four run the same 2-D GJK the prism kernels use, over O(log n)
support queries, instead of the paper's vertex-set scans and edge walk: one
exact piece of code for every shape (see :mod:`prismbatch._kernels.planar`).

Arguments are checked as :func:`prismbatch.collide` checks its own: ``tol`` a real number in
[0, 1e100], points and directions two real numbers of magnitude at most 1e100, polygons in the
supported range (:data:`~prismbatch.config.SUPPORTED_RANGE`); TypeError or ValueError naming the
argument otherwise.
"""

from __future__ import annotations

import math

import numpy as np

from ._kernels.planar import edge_search_tables, gjk_generators, point_polygon_distance
from .checks import as_real_array, real_scalar
from .config import MAX_MAGNITUDE
from .shapes import Prism, as_prism_set

__all__ = ["point_polygon", "segment_polygon", "halfline_polygon", "strip_polygon", "polygon_polygon"]


def _poly_arrays(poly, name="poly"):
    """The polygon as a Prism and its one-polygon PrismSet, in the range the kernels support (as collide's)."""
    prism = poly if isinstance(poly, Prism) else Prism(poly, name=name)
    return prism, as_prism_set(prism, name)[0]


def _vec2(x, name):
    """A point or direction: two real numbers of magnitude at most MAX_MAGNITUDE (as collide's positions)."""
    a = as_real_array(x, name).astype(np.float64).reshape(-1)
    if a.shape != (2,) or not np.all(np.abs(a) <= MAX_MAGNITUDE):
        raise ValueError(f"{name} must be 2 finite numbers of magnitude <= {MAX_MAGNITUDE:g}, got {x!r}")
    return a


def _tol(tol):
    return real_scalar(tol, "tol", 0.0, MAX_MAGNITUDE)


def _run(prism, pset, pts, w, tol, poly_b=None):
    """Shared driver: pts are generator points (k = 1 or 2) in poly's frame."""
    c = prism.centre
    if poly_b is not None:
        bset = poly_b
        gx = np.ascontiguousarray(bset.vx + (bset.centre[0, 0] - c[0]))
        gy = np.ascontiguousarray(bset.vy + (bset.centre[0, 1] - c[1]))
        geang, getab = bset.edge_angle, bset.edge_table
        reach_pts = np.c_[gx, gy]
    else:
        g = np.atleast_2d(pts) - c
        gx = np.ascontiguousarray(g[:, 0])
        gy = np.ascontiguousarray(g[:, 1])
        geang = np.empty(len(g))
        getab = np.empty(len(g), dtype=np.int64)
        ge = np.roll(g, -1, axis=0) - g
        edge_search_tables(
            np.ascontiguousarray(ge[:, 0]), np.ascontiguousarray(ge[:, 1]), geang, getab
        )  # 1 or 2 points
        reach_pts = g
    wx, wy, T = 0.0, 0.0, 0.0
    if w is not None:
        big = max(abs(w[0]), abs(w[1]))
        if big == 0.0:
            raise ValueError("direction d must be non-zero")
        wn = math.hypot(w[0] / big, w[1] / big)  # (scaled first: a subnormal or huge d keeps its direction)
        wx, wy = w[0] / big / wn, w[1] / big / wn
        # Beyond this length the shape is farther than the polygon's reach.
        T = float(np.max(np.hypot(reach_pts[:, 0], reach_pts[:, 1]))) + pset.radius[0] + 2 * tol + 1.0
    hit, _, ax, ay, u, v, t = gjk_generators(
        pset.vx,
        pset.vy,
        pset.edge_angle,
        pset.edge_table,
        len(pset.vx),
        gx,
        gy,
        geang,
        getab,
        len(gx),
        wx,
        wy,
        T,
        float(tol),
    )
    if not hit:
        return False, np.full(2, np.nan)
    bx, by = u + wx * t, v + wy * t
    return True, np.array([0.5 * (ax + bx) + c[0], 0.5 * (ay + by) + c[1]])


def point_polygon(poly, p, tol=0.0):
    """Point vs convex polygon by the paper's polar wedge search (eq. 1).

    Returns ``(hit, signed_distance)``: the signed distance of ``p`` to the
    edge line of its polar wedge (positive inside; outside, a lower bound of
    the Euclidean distance). ``hit`` is ``signed_distance >= -tol``.
    """
    prism, s = _poly_arrays(poly)
    tol = _tol(tol)
    p = _vec2(p, "p") - prism.centre
    d = point_polygon_distance(s.vx, s.vy, s.vertex_angle, s.inv_edge_len, 0, len(s.vx), p[0], p[1])
    return bool(d >= -tol), float(d)


def segment_polygon(poly, p1, p2, tol=0.0):
    """Segment [p1, p2] vs convex polygon: ``(hit, contact)``; hit iff distance <= tol."""
    prism, s = _poly_arrays(poly)
    pts = np.array([_vec2(p1, "p1"), _vec2(p2, "p2")])
    if np.array_equal(pts[0], pts[1]):
        pts = pts[:1]
    return _run(prism, s, pts, None, _tol(tol))


def halfline_polygon(poly, p, d, tol=0.0):
    """Half-line {p + t d : t >= 0} vs convex polygon: ``(hit, contact)``."""
    prism, s = _poly_arrays(poly)
    return _run(prism, s, _vec2(p, "p")[None, :], _vec2(d, "d"), _tol(tol))


def strip_polygon(poly, p1, p2, d, tol=0.0):
    """Unbounded strip {p1 + s (p2 - p1) + t d : s in [0, 1], t >= 0} vs polygon."""
    prism, s = _poly_arrays(poly)
    pts = np.array([_vec2(p1, "p1"), _vec2(p2, "p2")])
    if np.array_equal(pts[0], pts[1]):
        pts = pts[:1]
    return _run(prism, s, pts, _vec2(d, "d"), _tol(tol))


def polygon_polygon(poly, other, tol=0.0):
    """Convex polygon vs convex polygon (both in the same plane frame)."""
    prism, s = _poly_arrays(poly)
    _, so = _poly_arrays(other, name="other")
    return _run(prism, s, None, None, _tol(tol), poly_b=so)
