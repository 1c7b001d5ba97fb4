"""Polygons, rotations and pair scales for the stiff suite's constructions.

Random convex end faces (ellipse polygons, slivers, nearly collinear
edges), rotations with a prescribed axis, and ``S = R_a + R_b + |c_b - c_a|``,
the scale every separation and tolerance of the suite is measured in.
See docs/methods/stiff-suite.md.
"""

from __future__ import annotations

import math

import numpy as np

from ...geometry import centroid_radius, halfplanes, rotation_with_axis
from ...outline import validate_polygon

#: a's orientation in every constructed family: axis down, d_a = -z, end plane z = p_a[2].
R_DOWN = np.diag([1.0, -1.0, -1.0])


def rot_z(phi):
    """Rotation by ``phi`` about z (3, 3)."""
    c, s = math.cos(phi), math.sin(phi)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def down_rotation(rng):
    """a's rotation: axis down (third column exactly (0, 0, -1)), random spin about it."""
    return rot_z(rng.uniform(0, 2 * np.pi)) @ R_DOWN


def axis_rotation(axis, angle):
    """Rotation (3, 3) by ``angle`` about ``axis`` (Rodrigues); exactly I for angle 0."""
    k = np.asarray(axis, float)
    k = k / np.linalg.norm(k)
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * (K @ K)


def with_axis(d, spin):
    """A rotation whose third column is exactly ``d`` (unit, given), spun by ``spin`` about it."""
    return rotation_with_axis(d, spin, exact_axis=True)


def random_polygon(rng, n=None, radius=1.0, *, aspect=None, regular=None, offset=0.3):
    """A random convex polygon (k, 2): vertices on an ellipse (so in convex position).

    Parameters
    ----------
    rng : numpy.random.Generator
    n : int, optional
        Vertex count (default: uniform in 3..12).
    radius : float
        Largest distance of a vertex from the ellipse's centre.
    aspect : float, optional
        Minor/major axis ratio (default: uniform in 0.3..1; 1 for regular polygons).
    regular : bool, optional
        Equally spaced angles (default: 35 % of draws).
    offset : float
        The polygon is shifted from the local origin by up to ``offset * radius``.
    """
    return _retry(_random_polygon, rng, n, radius, aspect, regular, offset)


def _random_polygon(rng, n, radius, aspect, regular, offset):
    if n is None:
        n = int(rng.integers(3, 13))
    if regular is None:
        regular = bool(rng.random() < 0.35)
    if aspect is None:
        aspect = 1.0 if regular else float(rng.uniform(0.3, 1.0))
    if regular:
        ang = rng.uniform(0, 2 * np.pi) + 2 * np.pi * np.arange(n) / n
    else:
        for _ in range(100):
            ang = np.sort(rng.uniform(0, 2 * np.pi, n))
            gaps = np.diff(np.concatenate([ang, [ang[0] + 2 * np.pi]]))
            if gaps.min() > 0.2 / n and gaps.max() < np.pi:  # no near-duplicates, centre inside
                break
    pts = np.column_stack([np.cos(ang), aspect * np.sin(ang)])
    th = rng.uniform(0, 2 * np.pi)
    c, s = math.cos(th), math.sin(th)
    pts = pts @ np.array([[c, s], [-s, c]])
    pts *= radius / np.max(np.hypot(*pts.T))
    return pts + rng.uniform(-offset, offset, 2) * radius


def sliver_polygon(rng, aspect, radius=1.0):
    """A convex 3..12-gon of the given aspect ratio (a random ellipse polygon squashed)."""
    return _retry(_sliver_polygon, rng, aspect, radius)


def _sliver_polygon(rng, aspect, radius):
    return random_polygon(rng, int(rng.integers(3, 13)), radius, aspect=aspect, regular=False)


def collinear_polygon(rng, bulge, radius=1.0):
    """A 3..6-gon with 4..20 extra vertices on every edge, pushed out by ``bulge * radius``
    (a parabola through the corners; capped where a corner turns too little for it to stay
    convex): nearly collinear consecutive vertices; exactly collinear (to rounding) for
    ``bulge = 0``."""
    return _retry(_collinear_polygon, rng, bulge, radius)


def _collinear_polygon(rng, bulge, radius):
    base = ccw(random_polygon(rng, int(rng.integers(3, 7)), radius, regular=False))
    k = int(rng.integers(5, 21))
    t = np.arange(k) / k
    nxt = np.roll(base, -1, axis=0)
    e_all = nxt - base
    ln = np.hypot(*e_all.T)
    prev = np.roll(e_all, 1, axis=0)
    turn = np.abs(np.arctan2(prev[:, 0] * e_all[:, 1] - prev[:, 1] * e_all[:, 0], np.einsum("ij,ij->i", prev, e_all)))
    # the parabola leaves a corner 4 amp / L off the edge: keep that well inside the corner's turn
    amp = min(bulge * radius, float(np.min(ln) * np.min(turn)) / 16.0)
    out = []
    for a, e, L in zip(base, e_all, ln):
        nrm = np.array([e[1], -e[0]]) / L  # outward for CCW
        out.append(a + t[:, None] * e + (amp * 4 * t * (1 - t))[:, None] * nrm)
    return np.concatenate(out)


def _retry(gen, rng, *args):
    """Draw until the polygon passes the package's validation (rounding can dent a draw)."""
    for _ in range(50):
        xy = gen(rng, *args)
        try:
            validate_polygon(xy)
        except ValueError:
            continue
        return xy
    raise RuntimeError(f"{gen.__name__}: no valid polygon in 50 draws")


def _is_ccw(xy):
    """Counter-clockwise vertex order (positive shoelace sum)."""
    x, y = xy[:, 0], xy[:, 1]
    return np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) > 0


def ccw(xy):
    """``xy`` in counter-clockwise order (a reversed copy if it is clockwise)."""
    return xy if _is_ccw(xy) else xy[::-1].copy()


def outward_normals(w):
    """Unit outward normals (n, 2) of the edges w[i] -> w[i+1] of a convex polygon (any orientation)."""
    e = np.roll(w, -1, axis=0) - w
    sgn = 1.0 if _is_ccw(w) else -1.0
    nrm = sgn * np.column_stack([e[:, 1], -e[:, 0]])
    return nrm / np.hypot(*nrm.T)[:, None]


def push(shift, W, v, n2):
    """``shift`` (a signed move of b's touching point v along n2), with overlaps limited to half
    of a's chord from v along -n2: the moved point must stay inside a's polygon (slivers!)."""
    if shift >= 0:
        return shift
    nrm = outward_normals(W)
    h = np.einsum("ij,ij->i", nrm, W)
    dn = nrm @ -n2
    pos = dn > 1e-12
    chord = float(np.min((h[pos] - nrm[pos] @ v) / dn[pos])) if pos.any() else math.inf
    return -min(-shift, 0.5 * chord)


def by_identity(fn):
    """``fn(xy)`` remembered per polygon object: the suite asks the same large polygons
    thousands of times (kept while the object lives; the cache is cleared past 4096)."""
    cache = {}

    def cached(xy):
        hit = cache.get(id(xy))
        if hit is not None and hit[0] is xy:
            return hit[1]
        out = fn(xy)
        if len(cache) > 4096:
            cache.clear()
        cache[id(xy)] = (xy, out)
        return out

    cached.__doc__ = fn.__doc__
    return cached


#: Area centroid (2,) and radius about it of a convex polygon (:func:`prismbatch.geometry.centroid_radius`).
centre_radius = by_identity(centroid_radius)
#: Unit outward edge normals and offsets of a convex polygon (:func:`prismbatch.geometry.halfplanes`).
polygon_planes = by_identity(halfplanes)


def world_centres(xy_a, pos_a, rot_a, xy_b, pos_b, rot_b):
    """World area centroids and radii of both end faces: ``(w_a, r_a, w_b, r_b)``."""
    (ca, ra), (cb, rb) = centre_radius(xy_a), centre_radius(xy_b)
    wa = np.asarray(pos_a, float) + np.asarray(rot_a, float)[:, :2] @ ca
    wb = np.asarray(pos_b, float) + np.asarray(rot_b, float)[:, :2] @ cb
    return wa, ra, wb, rb


def pair_scale(xy_a, pos_a, rot_a, xy_b, pos_b, rot_b):
    """S = R_a + R_b + |c_b - c_a| of one pair (radii about the area centroids, c in world)."""
    wa, ra, wb, rb = world_centres(xy_a, pos_a, rot_a, xy_b, pos_b, rot_b)
    return ra + rb + float(np.linalg.norm(wb - wa))
