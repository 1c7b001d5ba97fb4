"""The stiff and extreme suite: pose pairs where floating point is hardest, with known answers.

Families (each run for several parameter values, in float64 and float32):

* ``separation``: b's lowest end-face vertex above a's end face (or beside a's
  side edge) at a signed separation ``s * S`` for ``s`` from 1e-15 to 1e-3
  (``S = R_a + R_b + |c_b - c_a|``, the scale of the pair tolerance).
* ``perpendicular_gap`` / ``perpendicular_lp``: ``|d_a . d_b|`` from 1e-1
  down to 1e-16 and exactly 0.
* ``antiparallel_gap`` / ``antiparallel_lp`` (facing axes) and
  ``parallel_gap`` / ``parallel_lp`` (axes pointing the same way):
  ``1 - |d_a . d_b|`` from 1e-1 down to 1e-16 and 0 (the ``_lp`` families
  take the tilt angle itself, down to 1e-16 rad).
* ``coplanar``: end faces coplanar to within a few ulp either side, polygons
  touching at a vertex or along an edge, pushed apart or together.
* ``scale`` / ``scale_lp``: object sizes and positions scaled by 1e-6 .. 1e3.
* ``vertices``: regular end faces with 3 .. 100,000 vertices.
* ``sliver`` / ``sliver_lp``: end faces of aspect ratio down to 1e-6.
* ``collinear`` / ``collinear_lp``: many vertices along every edge, bulged
  outward by a relative 1e-3 .. 1e-12, or exactly collinear.

Ground truth. ``*_gap`` families and ``separation``, ``coplanar``,
``scale``, ``vertices``, ``sliver``, ``collinear`` are exact constructions:
a separating plane (a's end plane, or a vertical plane through a vertex of a
along its normal-cone bisector) and a pair of witness points at the
constructed distance, so the signed gap is known to the rounding of float64
coordinates (~1e-15 S, far below the tolerance 1e-9 S). Negative gaps are
overlaps by construction. The ``*_lp`` families use random poses and the exact
LP margin (:func:`prismbatch.lab.exact.margin_lp`), trusted outside
``max(tol, 1e-7 S)``; where prismbatch disagrees with the LP, certificates
decide: a hit is accepted when its contact point lies in both bodies within
``2 tol`` (:func:`prismbatch.lab.exact.point_in_prism_residual`), a miss when a
separating plane (face normals and cross products of edges and axes, the
finiteness conditions ``n . d_a <= 0 <= n . d_b`` checked in exact rational
arithmetic) shows a gap above ``tol``. The LP is not used at all for axes
pointing the same way within 1e-8 rad (its tolerances fail for intersections
at depth ~ gap / tilt): there only certificates count.

Band. For float64 a pair must hit when its gap is at most ``tol`` and must
miss when it exceeds ``2 tol`` (the guaranteed bound; sqrt(2) tol off the
perpendicular cases); in between it is *inside the band*. For the LP families
the band is ``|margin| <= max(tol, 1e-7 S)``.

float32. The float32 run gets the same poses and polygons rounded to float32
(rounding the pose itself moves the bodies by ~1e-7 S, which is part of what a
float32 user gets); its ground truth is still the float64 one. A row's
``departures`` counts pairs outside the *float64* band where the float32
answer differs from the float64-required one, with the largest ``|gap|/S``
(or ``|LP margin|/S``) among them; ``disagreements_outside_band`` for float32
uses float32's own band (``tol32 = 1e-5 S`` plus the pose rounding). float32
here means float32 *storage*: Numba promotes much of the arithmetic inside the
kernels to float64.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from fractions import Fraction

import numpy as np

from .report import run_metadata, write_csv, write_json
from ..collide import DEFAULT_RTOL, Collider
from .exact import margin_lp
from ..shapes import Prism, PrismSet, validate_polygon

__all__ = ["StiffReport", "run_stiff_suite", "write_stiff_report", "FAMILIES", "PairSet", "pair_scale",
           "face_pairs", "side_pairs", "coplanar_pairs", "random_polygon", "sliver_polygon",
           "collinear_polygon", "axis_rotation", "plane_certificate", "contact_certified"]

#: a's orientation in every constructed family: axis down, d_a = -z, end plane z = p_a[2].
R_DOWN = np.diag([1.0, -1.0, -1.0])

#: Relative separations cycled through by the constructed families other than ``separation``:
#: overlaps, clear hits, the float64 band (3e-9), float32's range (1e-7 .. 1e-5), clear misses.
_S_CYCLE = (-1e-3, -1e-9, 1e-15, 1e-12, 3e-9, 1e-7, 1e-5, 1e-3)

_EPS64 = float(np.finfo(np.float64).eps)
_EPS32 = float(np.finfo(np.float32).eps)


# ---------------------------------------------------------------------------
# polygons and rotations
# ---------------------------------------------------------------------------


def rot_z(phi):
    """Rotation by ``phi`` about z (3, 3)."""
    c, s = math.cos(phi), math.sin(phi)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def axis_rotation(axis, angle):
    """Rotation (3, 3) by ``angle`` about ``axis`` (Rodrigues); exactly I for angle 0."""
    k = np.asarray(axis, float)
    k = k / np.linalg.norm(k)
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * (K @ K)


def _with_axis(d, spin):
    """A rotation whose third column is exactly ``d`` (unit, given), spun by ``spin`` about it."""
    d = np.asarray(d, float)
    ref = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = ref - (ref @ d) * d
    x /= np.linalg.norm(x)
    y = np.cross(d, x)
    c, s = math.cos(spin), math.sin(spin)
    return np.column_stack([c * x + s * y, -s * x + c * y, d])


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
    base = _ccw(random_polygon(rng, int(rng.integers(3, 7)), radius, regular=False))
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


def _ccw(xy):
    x, y = xy[:, 0], xy[:, 1]
    return xy if np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) > 0 else xy[::-1].copy()


def _outward_normals(w):
    """Unit outward normals (n, 2) of the edges w[i] -> w[i+1] of a convex polygon (any orientation)."""
    e = np.roll(w, -1, axis=0) - w
    sgn = 1.0 if np.sum(w[:, 0] * np.roll(w[:, 1], -1) - np.roll(w[:, 0], -1) * w[:, 1]) > 0 else -1.0
    nrm = sgn * np.column_stack([e[:, 1], -e[:, 0]])
    return nrm / np.hypot(*nrm.T)[:, None]


# ---------------------------------------------------------------------------
# exact constructions
# ---------------------------------------------------------------------------


@dataclass
class PairSet:
    """Pose pairs of one (family, value) with their ground truth.

    ``gap`` is the signed ground-truth gap per pair (negative: overlap by
    construction) or NaN where the LP decides (``lp=True``).
    """

    polys_a: list
    polys_b: list
    pos_a: np.ndarray
    rot_a: np.ndarray
    pos_b: np.ndarray
    rot_b: np.ndarray
    gap: np.ndarray
    lp: bool = False

    def __len__(self):
        return len(self.polys_a)


def _stack(rows, lp=False):
    A, B, pa, Ra, pb_, Rb, g = zip(*rows)
    return PairSet(list(A), list(B), np.array(pa), np.array(Ra), np.array(pb_), np.array(Rb),
                   np.array(g, float), lp)


def _a_pose(rng, A, scale):
    Ra = rot_z(rng.uniform(0, 2 * np.pi)) @ R_DOWN  # third column exactly (0, 0, -1)
    pa = rng.uniform(-2, 2, 3) * scale
    Aw = pa[:2] + A @ Ra[:2, :2].T
    return pa, Ra, Aw


def face_pairs(rng, polys_a, polys_b, rots_b, seps, *, scale=1.0):
    """b's lowest end-face vertex above a point inside a's end face, at height ``sep * S``.

    a's axis is down (its body is ``z <= p_a[2]``); every ``rots_b[k]`` must have
    ``d_b[2] >= 0`` so b lies above its lowest end-face vertex. The plane
    ``z = p_a[2]`` then separates the bodies, and the vertex and the point of
    a's end face below it are witnesses: the gap is exactly that height
    (negative: the vertex is inside a). Returns a :class:`PairSet`.

    Parameters
    ----------
    rng : numpy.random.Generator
    polys_a, polys_b : list of (n, 2) arrays
        End faces, one per pair.
    rots_b : list of (3, 3) arrays
        b's rotations (``d_b[2] >= 0``).
    seps : (N,) array_like
        Signed separations relative to S = R_a + R_b + |c_b - c_a|.
    scale : float
        Positions are drawn in a box of half-width 2 * scale.
    """
    rows = []
    for A, B, Rb, s in zip(polys_a, polys_b, rots_b, seps):
        if Rb[2, 2] < 0:
            raise ValueError("face_pairs: rots_b must have d_b[2] >= 0")
        pa, Ra, Aw = _a_pose(rng, A, scale)
        ca = Aw.mean(axis=0)
        q = ca + rng.uniform(0.0, 0.6) * (Aw[rng.integers(len(Aw))] - ca)  # inside a's end face
        Wb = B @ Rb[:, :2].T
        k = int(np.argmin(Wb[:, 2]))
        pb0 = np.array([q[0] - Wb[k, 0], q[1] - Wb[k, 1], pa[2] - Wb[k, 2]])
        pb_ = pb0 + np.array([0.0, 0.0, s * pair_scale(A, pa, Ra, B, pb0, Rb)])
        gap = float(np.min(pb_[2] + Wb[:, 2]) - pa[2])
        rows.append((A, B, pa, Ra, pb_, Rb, gap))
    return _stack(rows)


def side_pairs(rng, polys_a, polys_b, tilts, seps, *, scale=1.0):
    """b beside a side edge of a, both axes pointing down, b's tilted by ``tilt`` away from a.

    n is the bisector of a's outward edge normals at a random vertex v (so -n
    points into a); b's axis is ``(sin(tilt) n, -cos(tilt))`` (``n . d_b >= 0``),
    its extreme end-face vertex along -n is put at ``v + sep * S * n`` at a depth
    in ``[0, R_a]`` below a's end plane (exactly on it for a quarter of the
    pairs). The vertical plane through v normal to n separates the bodies and
    the two points are witnesses, so the gap is ``sep * S`` (negative: b's
    vertex inside a, moved in by at most half of a's chord there). Returns a
    :class:`PairSet`.

    Parameters
    ----------
    rng : numpy.random.Generator
    polys_a, polys_b : list of (n, 2) arrays
        End faces, one per pair.
    tilts : (N,) array_like
        Angles (rad) between the axes.
    seps : (N,) array_like
        Signed separations relative to S = R_a + R_b + |c_b - c_a|.
    scale : float
        Positions are drawn in a box of half-width 2 * scale.
    """
    rows = []
    for j, (A, B, tilt, s) in enumerate(zip(polys_a, polys_b, tilts, seps)):
        pa, Ra, Aw = _a_pose(rng, A, scale)
        i = int(rng.integers(len(Aw)))
        nrm = _outward_normals(Aw)
        n2 = nrm[i - 1] + nrm[i]
        n2 /= np.hypot(*n2)
        n3 = np.array([n2[0], n2[1], 0.0])
        Rb = axis_rotation(np.cross(n3, [0.0, 0.0, 1.0]), tilt) @ rot_z(rng.uniform(0, 2 * np.pi)) @ R_DOWN
        Wb = B @ Rb[:, :2].T
        k = int(np.argmin(Wb[:, :2] @ n2))
        depth = 0.0 if j % 4 == 0 else rng.uniform(0, 1) * np.max(np.hypot(*(A - A.mean(0)).T))
        pb0 = np.array([Aw[i, 0], Aw[i, 1], pa[2] - depth]) - Wb[k]
        pb_ = pb0 + _push(s * pair_scale(A, pa, Ra, B, pb0, Rb), Aw, Aw[i], n2) * n3
        # plane value (lower bound on the gap; the witnesses make it exact)
        lo = float(np.min((pb_[:2] + Wb[:, :2]) @ n2) - np.max(Aw @ n2))
        rows.append((A, B, pa, Ra, pb_, Rb, lo if s >= 0 else min(lo, 0.0)))
    return _stack(rows)


def coplanar_pairs(rng, polys_a, ulps, seps, *, scale=1.0):
    """End faces coplanar to within ``ulps`` ulp, polygons touching then pushed by ``sep * S``.

    a's axis down with its end plane at ``z0`` (about 1); b faces it (axis up)
    with its end plane ``ulps`` floats above (+) or below (-) ``z0``. b's end
    face is a's point-reflected through a vertex or an edge midpoint m of a,
    then moved by ``sep * S`` along the outward bisector / edge normal n:
    the line through m normal to n separates the polygons and the gap in the
    plane is ``sep * S`` (negative: overlap); across the planes it is at most
    ``|ulps|`` ulp more. Returns a :class:`PairSet`.
    """
    rows = []
    for j, (A, s) in enumerate(zip(polys_a, seps)):
        Ra = rot_z(rng.uniform(0, 2 * np.pi)) @ R_DOWN
        z0 = rng.uniform(0.5, 2.0) * scale
        pa = np.array([*(rng.uniform(-2, 2, 2) * scale), z0])
        Aw = pa[:2] + A @ Ra[:2, :2].T
        nrm = _outward_normals(Aw)
        i = int(rng.integers(len(Aw)))
        if j % 2 == 0:  # vertex contact
            m = Aw[i]
            n2 = nrm[i - 1] + nrm[i]
        else:  # edge contact
            m = 0.5 * (Aw[i] + Aw[(i + 1) % len(Aw)])
            n2 = nrm[i].copy()
        n2 /= np.hypot(*n2)
        S = 2 * _centre_radius(A)[1] + 2 * float(np.hypot(*(m - Aw.mean(axis=0))))  # nominal; B mirrors A
        Bw = 2.0 * m - Aw + _push(s * S, Aw, m, n2) * n2
        zb = z0
        for _ in range(abs(int(ulps))):
            zb = np.nextafter(zb, np.inf if ulps > 0 else -np.inf)
        Rb = rot_z(rng.uniform(0, 2 * np.pi))
        pb_ = np.array([*Bw.mean(axis=0), zb])
        B = (Bw - pb_[:2]) @ Rb[:2, :2]  # local: R^T (w - p)
        Bw_exact = pb_[:2] + B @ Rb[:2, :2].T
        g2 = float(np.min(Bw_exact @ n2) - np.max(Aw @ n2))
        dz = max(float(zb - z0), 0.0)
        if s >= 0:
            gap = math.hypot(g2, dz) if g2 > 0 else dz
        else:  # overlapping polygons: the planes' offset (a few ulp) is all that separates
            gap = dz if dz > 0 else min(g2, 0.0)
        rows.append((A, _ccw(B), pa, Ra, pb_, Rb, gap))
    return _stack(rows)


def _push(shift, W, v, n2):
    """``shift`` (a signed move of b's touching point v along n2), with overlaps limited to half
    of a's chord from v along -n2: the moved point must stay inside a's polygon (slivers!)."""
    if shift >= 0:
        return shift
    nrm = _outward_normals(W)
    h = np.einsum("ij,ij->i", nrm, W)
    dn = nrm @ -n2
    pos = dn > 1e-12
    chord = float(np.min((h[pos] - nrm[pos] @ v) / dn[pos])) if pos.any() else math.inf
    return -min(-shift, 0.5 * chord)


_CR_CACHE = {}


def _centre_radius(xy):
    """Area centroid (2,) and radius about it of a convex polygon (cached for large ones)."""
    key = id(xy) if len(xy) > 1000 else None
    if key is not None and key in _CR_CACHE and _CR_CACHE[key][0] is xy:
        return _CR_CACHE[key][1]
    p = _ccw(np.asarray(xy, float))
    x0 = p.mean(axis=0)
    v = p - x0
    vn = np.roll(v, -1, axis=0)
    cr = v[:, 0] * vn[:, 1] - vn[:, 0] * v[:, 1]
    c = np.array([((v[:, 0] + vn[:, 0]) * cr).sum(), ((v[:, 1] + vn[:, 1]) * cr).sum()]) / (3 * cr.sum()) + x0
    out = (c, float(np.max(np.hypot(*(p - c).T))))
    if key is not None:
        _CR_CACHE[key] = (xy, out)
    return out


def pair_scale(xy_a, pos_a, rot_a, xy_b, pos_b, rot_b):
    """S = R_a + R_b + |c_b - c_a| of one pair (radii about the area centroids, c in world)."""
    (ca, ra), (cb, rb) = _centre_radius(xy_a), _centre_radius(xy_b)
    wa = np.asarray(pos_a, float) + np.asarray(rot_a, float)[:, :2] @ ca
    wb = np.asarray(pos_b, float) + np.asarray(rot_b, float)[:, :2] @ cb
    return ra + rb + float(np.linalg.norm(wb - wa))


# ---------------------------------------------------------------------------
# certificates
# ---------------------------------------------------------------------------


def _world(xy, p, R):
    return p + np.asarray(xy, float) @ R[:, :2].T


def plane_certificate(xy_a, pos_a, rot_a, xy_b, pos_b, rot_b, *, top=12):
    """Largest gap shown by a separating plane between two semi-infinite prisms (or -inf).

    Candidate normals n (pointing from a to b): a's end-face and side normals,
    b's (negated), and ``±`` cross products of the axes and edge directions.
    A plane is valid only if both bodies are bounded along it,
    ``n . d_a <= 0 <= n . d_b``: these signs are checked in exact rational
    arithmetic on the float inputs (a candidate that fails them is also tried
    projected exactly onto the planes normal to ``d_a``, to ``d_b`` and to both). The gap ``min_b n.x - max_a n.x`` is then
    evaluated in float64 over the end-face vertices (error ~1e-16 of the
    coordinates).

    Returns
    -------
    float
        A lower bound on the Euclidean distance between the bodies, or -inf.
    """
    pa, Ra, pb_, Rb = (np.asarray(v, float) for v in (pos_a, rot_a, pos_b, rot_b))
    Wa, Wb = _world(xy_a, pa, Ra), _world(xy_b, pb_, Rb)
    da, db = Ra[:, 2], Rb[:, 2]
    ea = np.roll(Wa, -1, axis=0) - Wa
    eb = np.roll(Wb, -1, axis=0) - Wb
    na = np.cross(ea, da)  # a's side normals up to sign (fixed below by validity)
    nb = np.cross(eb, db)
    # d_a x (d_b - d_a) = d_a x d_b without the cancellation for nearly parallel axes
    cand = [da[None], db[None], na, nb, np.cross(da, db - da)[None], np.cross(da, eb), np.cross(ea, db)]
    if len(ea) * len(eb) <= 4096:
        cand.append(np.cross(ea[:, None, :], eb[None, :, :]).reshape(-1, 3))
    C = np.concatenate(cand)
    C = np.concatenate([C, -C])
    nn = np.linalg.norm(C, axis=1)
    C = C[nn > 1e-300] / nn[nn > 1e-300, None]
    sa, sb = C @ da, C @ db
    ok = (sa <= 1e-12) & (sb >= -1e-12)
    if not ok.any():
        return -math.inf
    C = C[ok]
    val = (Wb @ C.T).min(axis=0) - (Wa @ C.T).max(axis=0)
    best = -math.inf
    fa = [Fraction(float(v)) for v in da]
    fb = [Fraction(float(v)) for v in db]
    # Best float value first; many near-valid candidates fail the exact signs for nearly
    # parallel axes, so go on until `top` of them pass.
    found = 0
    for idx in np.argsort(-val)[:50 * top]:
        if val[idx] <= best:
            break
        for n in _valid_variants(C[idx], fa, fb):
            g = (float(np.min(Wb @ n)) - float(np.max(Wa @ n))) / float(np.linalg.norm(n))
            best = max(best, g)
            found += 1
        if found >= top:
            break
    return best


def _fdot(u, v):
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


def _valid_variants(n, fa, fb):
    """``n`` itself and ``n`` projected exactly onto the plane normal to d_a, to d_b, or to both, each kept
    only when ``n . d_a <= 0 <= n . d_b`` holds exactly (rational arithmetic). Returned as float
    vectors; rounding them back moves the supports by ~1e-16 of the coordinates only."""
    fn = [Fraction(float(v)) for v in n]
    out = []
    for proj in (None, fa, fb, "both"):
        m = fn
        if proj == "both":  # normal to both axes (d_a x d_b for nearly parallel axes)
            aa, ab, bb = _fdot(fa, fa), _fdot(fa, fb), _fdot(fb, fb)
            det = aa * bb - ab * ab
            if det == 0:
                continue
            na_, nb_ = _fdot(fn, fa), _fdot(fn, fb)
            al, be = (na_ * bb - nb_ * ab) / det, (nb_ * aa - na_ * ab) / det
            m = [x - al * y - be * z for x, y, z in zip(fn, fa, fb)]
        elif proj is not None:
            c = _fdot(fn, proj) / _fdot(proj, proj)
            m = [x - c * y for x, y in zip(fn, proj)]
        if _fdot(m, fa) <= 0 <= _fdot(m, fb):
            v = np.array([float(x) for x in m])
            if np.any(v != 0):
                out.append(v)
                if proj is None:
                    break  # n is valid as it is
    return out


_HP_CACHE = {}


def _halfplanes(xy):
    """Unit outward edge normals (m, 2) and offsets (m,) of a convex polygon (cached by identity)."""
    key = id(xy)
    hit = _HP_CACHE.get(key)
    if hit is not None and hit[0] is xy:
        return hit[1]
    p = _ccw(np.asarray(xy, float))
    e = np.roll(p, -1, axis=0) - p
    ln = np.hypot(e[:, 0], e[:, 1])
    ok = ln > 0
    n = np.column_stack([e[ok, 1], -e[ok, 0]]) / ln[ok, None]
    out = (n, np.einsum("ij,ij->i", n, p[ok]))
    if len(_HP_CACHE) > 4096:
        _HP_CACHE.clear()
    _HP_CACHE[key] = (xy, out)
    return out


def _residual(xy, pos, rot, x):
    """Largest violation of a world point against one body's half-spaces (<= 0: inside); as
    :func:`prismbatch.lab.exact.point_in_prism_residual`, vectorised for large polygons."""
    local = np.asarray(rot, float).T @ (np.asarray(x, float) - np.asarray(pos, float))
    n, h = _halfplanes(xy)
    return float(max(-local[2], np.max(n @ local[:2] - h)))


def contact_certified(xy_a, pos_a, rot_a, xy_b, pos_b, rot_b, x, tol, eps=_EPS64):
    """Is ``x`` inside both bodies within ``2 tol`` (plus the rounding of its own coordinates)?"""
    x = np.asarray(x, float)
    if not np.all(np.isfinite(x)):
        return False
    slack = 2.0 * tol + 8.0 * eps * (np.linalg.norm(x) + np.linalg.norm(pos_a) + np.linalg.norm(pos_b))
    return _residual(xy_a, pos_a, rot_a, x) <= slack and _residual(xy_b, pos_b, rot_b, x) <= slack


# ---------------------------------------------------------------------------
# families
# ---------------------------------------------------------------------------


def _polys(rng, n):
    return [random_polygon(rng, radius=float(rng.uniform(0.5, 2.0))) for _ in range(n)]


def _cycle(n, rng):
    s = np.array([_S_CYCLE[k % len(_S_CYCLE)] for k in range(n)])
    return s[rng.permutation(n)]


def _tilted_up(rng, n, max_tilt):
    out = []
    for _ in range(n):
        az = rng.uniform(0, 2 * np.pi)
        t = max_tilt * math.sqrt(rng.uniform())
        d = np.array([math.sin(t) * math.cos(az), math.sin(t) * math.sin(az), math.cos(t)])
        out.append(_with_axis(d, rng.uniform(0, 2 * np.pi)))
    return out


def _mixed(rng, A, B, seps, scale=1.0):
    """Half face constructions (facing, tilt up to 60 deg), half side constructions (tilt 1e-12..1e-1)."""
    n = len(A)
    h = (n + 1) // 2
    f = face_pairs(rng, A[:h], B[:h], _tilted_up(rng, h, math.radians(60)), seps[:h], scale=scale)
    if n == h:
        return f
    tilts = 10.0 ** rng.uniform(-12, -1, n - h)
    s = side_pairs(rng, A[h:], B[h:], tilts, seps[h:], scale=scale)
    return _concat(f, s)


def _concat(*parts):
    c = lambda k: np.concatenate([getattr(p, k) for p in parts])  # noqa: E731
    return PairSet(sum((p.polys_a for p in parts), []), sum((p.polys_b for p in parts), []), c("pos_a"),
                   c("rot_a"), c("pos_b"), c("rot_b"), c("gap"), parts[0].lp)


def _fam_separation(rng, n, s):
    return _mixed(rng, _polys(rng, n), _polys(rng, n), np.full(n, s))


def _fam_perp_gap(rng, n, v):
    rots = []
    for _ in range(n):
        az = rng.uniform(0, 2 * np.pi)
        c = math.sqrt(1.0 - v * v)
        rots.append(_with_axis(np.array([c * math.cos(az), c * math.sin(az), v]), rng.uniform(0, 2 * np.pi)))
    return face_pairs(rng, _polys(rng, n), _polys(rng, n), rots, _cycle(n, rng))


def _tilt_of(v):
    """Angle whose 1 - cos is v (accurate for tiny v)."""
    return 2.0 * math.asin(math.sqrt(v / 2.0))


def _fam_antiparallel_gap(rng, n, v):
    t = _tilt_of(v)
    rots = []
    for _ in range(n):
        az = rng.uniform(0, 2 * np.pi)
        rots.append(axis_rotation([math.cos(az), math.sin(az), 0.0], t) @ rot_z(rng.uniform(0, 2 * np.pi)))
    return face_pairs(rng, _polys(rng, n), _polys(rng, n), rots, _cycle(n, rng))


def _fam_parallel_gap(rng, n, v):
    return side_pairs(rng, _polys(rng, n), _polys(rng, n), np.full(n, _tilt_of(v)), _cycle(n, rng))


def _fam_coplanar(rng, n, ulps):
    return coplanar_pairs(rng, _polys(rng, n), ulps, _cycle(n, rng))


def _fam_scale(rng, n, scale):
    A = [p * scale for p in _polys(rng, n)]
    B = [p * scale for p in _polys(rng, n)]
    return _mixed(rng, A, B, _cycle(n, rng), scale)


_REGULAR_CACHE = {}


def _fam_vertices(rng, n, nv):
    nv = int(nv)
    if nv not in _REGULAR_CACHE:
        ang = 2 * np.pi * np.arange(nv) / nv
        _REGULAR_CACHE[nv] = (np.column_stack([2.0 * np.cos(ang), 2.0 * np.sin(ang)]),
                              np.column_stack([1.5 * np.cos(ang + 0.3), 1.5 * np.sin(ang + 0.3)]))
    A, B = _REGULAR_CACHE[nv]
    return _mixed(rng, [A] * n, [B] * n, _cycle(n, rng))


def _special_pair_polys(rng, n, make, param):
    """Polygon pairs where a, b or both (cycling) are ``make(rng, param, size)``."""
    A, B = _polys(rng, n), _polys(rng, n)
    for k in range(n):  # a special, b special, both
        if k % 3 != 1:
            A[k] = make(rng, param, float(rng.uniform(0.5, 2.0)))
        if k % 3 != 0:
            B[k] = make(rng, param, float(rng.uniform(0.5, 2.0)))
    return A, B


def _sliver_pair_polys(rng, n, aspect):
    return _special_pair_polys(rng, n, sliver_polygon, aspect)


def _fam_sliver(rng, n, aspect):
    return _mixed(rng, *_sliver_pair_polys(rng, n, aspect), _cycle(n, rng))


def _collinear_pair_polys(rng, n, bulge):
    return _special_pair_polys(rng, n, collinear_polygon, bulge)


def _fam_collinear(rng, n, bulge):
    return _mixed(rng, *_collinear_pair_polys(rng, n, bulge), _cycle(n, rng))


# --- LP families: random poses near contact ---------------------------------


def _lp_set(A, B, pa, Ra, pb_, Rb):
    return PairSet(list(A), list(B), np.array(pa), np.array(Ra), np.array(pb_), np.array(Rb),
                   np.full(len(A), np.nan), True)


def _fam_perp_lp(rng, n, v):
    """a down; b's axis at |d_a . d_b| = v, tilted towards or away from a's body at random."""
    A, B = _polys(rng, n), _polys(rng, n)
    Ra = [rot_z(rng.uniform(0, 2 * np.pi)) @ R_DOWN for _ in range(n)]
    Rb = []
    for _ in range(n):
        az, sgn = rng.uniform(0, 2 * np.pi), rng.choice([-1.0, 1.0])
        c = math.sqrt(1.0 - v * v)
        Rb.append(_with_axis(np.array([c * math.cos(az), c * math.sin(az), sgn * v]), rng.uniform(0, 2 * np.pi)))
    pa = rng.uniform(-1, 1, (n, 3))
    pb_ = pa + np.column_stack([rng.uniform(-3.5, 3.5, (n, 2)), rng.uniform(-2.0, 2.0, n)])
    return _lp_set(A, B, pa, Ra, pb_, Rb)


def _near_parallel_lp(rng, n, tilt, facing):
    A, B = _polys(rng, n), _polys(rng, n)
    Ra = [rot_z(rng.uniform(0, 2 * np.pi)) @ R_DOWN for _ in range(n)]
    base = np.eye(3) if facing else R_DOWN
    Rb = [axis_rotation([math.cos(t), math.sin(t), 0.0], tilt) @ rot_z(s) @ base
          for t, s in rng.uniform(0, 2 * np.pi, (n, 2))]
    pa = rng.uniform(-1, 1, (n, 3))
    pb_ = pa + np.column_stack([rng.uniform(-3.0, 3.0, (n, 2)), rng.uniform(-1.0, 1.0, n)])
    return _lp_set(A, B, pa, Ra, pb_, Rb)


def _fam_antiparallel_lp(rng, n, tilt):
    return _near_parallel_lp(rng, n, tilt, True)


def _fam_parallel_lp(rng, n, tilt):
    return _near_parallel_lp(rng, n, tilt, False)


def _free_lp(rng, A, B, scale=1.0):
    from ..sampling import random_rotations

    n = len(A)
    pa = rng.uniform(-1.5, 1.5, (n, 3)) * scale
    pb_ = rng.uniform(-1.5, 1.5, (n, 3)) * scale
    return _lp_set(A, B, pa, random_rotations(n, rng), pb_, random_rotations(n, rng))


def _fam_scale_lp(rng, n, scale):
    return _free_lp(rng, [p * scale for p in _polys(rng, n)], [p * scale for p in _polys(rng, n)], scale)


def _fam_sliver_lp(rng, n, aspect):
    return _free_lp(rng, *_sliver_pair_polys(rng, n, aspect))


def _fam_collinear_lp(rng, n, bulge):
    return _free_lp(rng, *_collinear_pair_polys(rng, n, bulge))


_SEPARATIONS = (-1e-3, -1e-9, -1e-15, 0.0) + tuple(10.0 ** k for k in range(-15, -2)) + (3e-9,)
_PERP = (1e-1, 1e-3, 1e-6, 1e-9, 1e-12, 1e-16, 0.0)
_PAR = (1e-1, 1e-4, 1e-8, 1e-12, 1e-16, 0.0)
_TILTS = (1e-2, 1e-4, 1e-6, 1e-8, 1e-10, 1e-12, 1e-16, 0.0)

#: name -> (parameter name, values, generator(rng, n, value), truth)
FAMILIES = {
    "separation": ("gap/S", tuple(sorted(_SEPARATIONS)), _fam_separation, "construction"),
    "perpendicular_gap": ("|d_a.d_b|", _PERP, _fam_perp_gap, "construction"),
    "perpendicular_lp": ("|d_a.d_b|", _PERP, _fam_perp_lp, "LP + certificates"),
    "antiparallel_gap": ("1-|d_a.d_b|", _PAR, _fam_antiparallel_gap, "construction"),
    "antiparallel_lp": ("tilt (rad)", _TILTS, _fam_antiparallel_lp, "LP + certificates"),
    "parallel_gap": ("1-|d_a.d_b|", _PAR, _fam_parallel_gap, "construction"),
    "parallel_lp": ("tilt (rad)", _TILTS, _fam_parallel_lp, "LP + certificates"),
    "coplanar": ("ulps", (-4, -1, 0, 1, 4), _fam_coplanar, "construction"),
    "scale": ("scale", (1e-6, 1e-3, 1.0, 1e3), _fam_scale, "construction"),
    "scale_lp": ("scale", (1e-6, 1e-3, 1.0, 1e3), _fam_scale_lp, "LP + certificates"),
    "vertices": ("vertices", (3, 4, 10, 100, 1000, 10_000, 100_000), _fam_vertices, "construction"),
    "sliver": ("aspect", (1e-2, 1e-4, 1e-6), _fam_sliver, "construction"),
    "sliver_lp": ("aspect", (1e-2, 1e-4, 1e-6), _fam_sliver_lp, "LP + certificates"),
    "collinear": ("bulge", (1e-3, 1e-6, 1e-9, 1e-12, 0.0), _fam_collinear, "construction"),
    "collinear_lp": ("bulge", (1e-6, 1e-12, 0.0), _fam_collinear_lp, "LP + certificates"),
}

#: pairs per (family, value): (construction, LP) for quick and full runs
_SIZES = {True: (8, 4), False: (320, 96)}


# ---------------------------------------------------------------------------
# evaluation
# ---------------------------------------------------------------------------


def _shape(polys):
    first = polys[0]
    if all(p is first for p in polys):
        return Prism(first)
    return PrismSet(polys)


def _lp_untrusted(Ra, Rb):
    """Axes pointing the same way within 1e-8 rad, not exactly: the LP's blind spot."""
    da, db = Ra[:, 2], Rb[:, 2]
    sine = float(np.linalg.norm(np.cross(da, db)))
    return float(da @ db) > 0 and 0.0 < sine < 1e-8


def _margins(ps):
    m = np.full(len(ps), np.nan)
    trusted = np.zeros(len(ps), bool)
    for k in range(len(ps)):
        if _lp_untrusted(ps.rot_a[k], ps.rot_b[k]):
            continue
        try:
            m[k] = margin_lp(ps.polys_a[k], ps.pos_a[k], ps.rot_a[k], ps.polys_b[k], ps.pos_b[k], ps.rot_b[k])
            trusted[k] = True
        except RuntimeError:  # HiGHS gave up: certificates decide
            pass
    return m, trusted


def _geometry(ps):
    """Per pair: S, |c_a| + |c_b|, |p_a| + |p_b| + 2 (rho_a + rho_b) (rho: largest |vertex|)."""
    n = len(ps)
    S, csum, big = np.empty(n), np.empty(n), np.empty(n)
    for k in range(n):
        (ca, ra), (cb, rb) = _centre_radius(ps.polys_a[k]), _centre_radius(ps.polys_b[k])
        wa = ps.pos_a[k] + ps.rot_a[k][:, :2] @ ca
        wb = ps.pos_b[k] + ps.rot_b[k][:, :2] @ cb
        S[k] = ra + rb + np.linalg.norm(wb - wa)
        csum[k] = np.linalg.norm(wa) + np.linalg.norm(wb)
        rho = np.max(np.abs(ps.polys_a[k])) + np.max(np.abs(ps.polys_b[k]))
        big[k] = np.linalg.norm(ps.pos_a[k]) + np.linalg.norm(ps.pos_b[k]) + 2 * math.sqrt(2) * rho
    return S, csum, big


def _need(ps, m, trusted, tol, lo_slack, hi_slack, band_lp):
    """+1 must hit, -1 must miss, 0 inside the band, 2 unknown (certificates decide)."""
    need = np.zeros(len(ps), np.int8)
    if not ps.lp:
        g = ps.gap
        need[g <= tol * (1 - 1e-6) - lo_slack] = 1
        need[g > 2 * tol * (1 + 1e-6) + hi_slack] = -1
        return need
    need[trusted & (m > np.maximum(band_lp, lo_slack))] = 1
    need[trusted & (m < -np.maximum(band_lp, tol + hi_slack))] = -1
    need[~trusted] = 2
    return need


def _run_one(ps, shapes, m, trusted, dt):
    """Evaluate one PairSet in one dtype; returns the counts and per-pair verdicts."""
    dt = np.dtype(dt)
    rtol, eps = DEFAULT_RTOL[dt], float(np.finfo(dt).eps)
    S, csum, big = _geometry(ps)
    tol64 = DEFAULT_RTOL[np.dtype(np.float64)] * S + 4 * _EPS64 * csum
    tol = rtol * S + 4 * eps * csum
    band_lp = np.maximum(tol64, 1e-7 * S)
    slack = np.zeros(len(ps)) if dt == np.float64 else 2 * eps * big  # bodies moved by rounding to float32
    need64 = _need(ps, m, trusted, tol64, 0.0, 0.0, band_lp)
    need = need64 if dt == np.float64 else _need(ps, m, trusted, tol, slack, slack, band_lp)

    sa, sb = shapes
    P = [np.ascontiguousarray(x, dtype=dt) for x in (ps.pos_a, ps.rot_a, ps.pos_b, ps.rot_b)]
    r = Collider(sa, sb, dtype=dt).collide(*P, contact=True)
    # what the kernel saw: poses and polygons rounded to dt (certificates use these)
    pa, Ra, pb_, Rb = (x.astype(np.float64) for x in P)
    memo = {}

    def rnd(xy):  # one rounded copy per distinct polygon (keeps the half-plane cache warm)
        if dt == np.float64:
            return xy
        if id(xy) not in memo:
            memo[id(xy)] = (xy, np.asarray(xy, dt).astype(np.float64))
        return memo[id(xy)][1]

    c = dict(pairs=len(ps), hits=int(r.hit.sum()), non_finite=0, disagreements_outside_band=0, inside_band=0,
             unresolved=0, certified_over_lp=0, rounding_explained=0, contact_outside_2tol=0)
    c["non_finite"] = int((~np.isfinite(r.contact[r.hit])).any(axis=1).sum()
                          + (~np.isnan(r.contact[~r.hit])).any(axis=1).sum())
    truth64 = need64.copy()  # confirmed float64 truth for the departure count
    for k in range(len(ps)):
        h = bool(r.hit[k])
        xa, xb = rnd(ps.polys_a[k]), rnd(ps.polys_b[k])
        cert_c = lambda: contact_certified(xa, pa[k], Ra[k], xb, pb_[k], Rb[k], r.contact[k],  # noqa: E731
                                           tol[k] + slack[k], eps)
        cert_p = lambda: plane_certificate(xa, pa[k], Ra[k], xb, pb_[k], Rb[k])  # noqa: E731
        if h and np.all(np.isfinite(r.contact[k])) and not cert_c():
            c["contact_outside_2tol"] += 1
        nk = int(need[k])
        if nk == 0:
            c["inside_band"] += 1
            continue
        if nk == 2:
            if h:
                if cert_c():
                    truth64[k] = 0
                elif cert_p() > 2 * tol[k]:
                    c["disagreements_outside_band"] += 1
                else:
                    c["unresolved"] += 1
            else:
                g = cert_p()
                if g > tol[k]:
                    truth64[k] = -1 if g > 2 * tol64[k] else 0
                else:
                    c["unresolved"] += 1
            continue
        if (nk == 1) == h:
            continue
        if not ps.lp:
            # float32: the rounded bodies may really touch (or part): a tilt of 1e-12 rad changes by
            # ~1e-7 rad when rounded, and nearly parallel bodies then meet (or not) far away
            if dt != np.float64 and (cert_c() if h else cert_p() > tol[k]):
                c["rounding_explained"] += 1
            else:
                c["disagreements_outside_band"] += 1
        elif h and cert_c():  # the LP missed a real contact
            c["certified_over_lp"] += 1
            truth64[k] = 0
        elif not h and cert_p() > tol[k]:  # the LP saw an overlap that a plane refutes
            c["certified_over_lp"] += 1
            truth64[k] = 0
        else:
            c["disagreements_outside_band"] += 1
    measure = np.abs(ps.gap) if not ps.lp else np.abs(m)
    dep = ((truth64 == 1) & ~r.hit) | ((truth64 == -1) & r.hit)
    c["departures"] = int(dep.sum())
    c["departures_hit"] = int((dep & r.hit).sum())  # float64 says miss, this dtype says hit
    with np.errstate(invalid="ignore"):
        c["max_departure_rel"] = float(np.nanmax(measure[dep] / S[dep])) if dep.any() else 0.0
        c["max_departure_tol64"] = float(np.nanmax(measure[dep] / tol64[dep])) if dep.any() else 0.0
    vals, cnt = np.unique(r.case, return_counts=True)
    c["cases"] = " ".join(f"{int(v)}:{int(n)}" for v, n in zip(vals, cnt))
    return c


# ---------------------------------------------------------------------------
# report
# ---------------------------------------------------------------------------

_COLS = ("family", "param", "value", "dtype", "truth", "pairs", "hits", "non_finite", "disagreements_outside_band",
         "inside_band", "unresolved", "certified_over_lp", "rounding_explained", "contact_outside_2tol", "departures", "departures_hit",
         "max_departure_rel", "max_departure_tol64", "cases")


def _fmt(v):
    if isinstance(v, float):
        if v == int(v) and abs(v) < 1e7:
            return str(int(v))
        return f"{v:.3g}"
    return str(v)


@dataclass
class StiffReport:
    """Result of :func:`run_stiff_suite`.

    Attributes
    ----------
    rows : list of dict
        One per (family, parameter value, dtype), keys: ``family``, ``param``
        (what ``value`` measures), ``value``, ``dtype``, ``truth``
        ("construction" or "LP + certificates"), ``pairs``, ``hits``,
        ``non_finite`` (hits with a non-finite contact, misses with a non-NaN
        one), ``disagreements_outside_band`` (answers contradicting the ground
        truth outside this dtype's band), ``inside_band``, ``unresolved`` (no
        LP and no certificate could decide), ``certified_over_lp`` (the LP
        was overruled by a certificate), ``rounding_explained`` (float32 only: a
        constructed answer contradicted, but a certificate on the float32-rounded
        poses shows the rounded bodies do touch / part), ``contact_outside_2tol`` (hits whose
        contact is not within 2 tol of both bodies), ``departures`` (answers
        differing from the float64-required one, outside the float64 band),
        ``departures_hit`` (of those, hits where float64 must miss),
        ``max_departure_rel`` (largest ``|gap|/S`` or ``|LP margin|/S`` among
        departures), ``max_departure_tol64`` (the same in float64 tolerances),
        ``cases`` (case histogram "case:count").
    quick : bool
    seed : int
    seconds : float
        Wall time of the run (noisy: shared machine).
    meta : dict
        :func:`prismbatch.lab.report.run_metadata`.
    """

    rows: list
    quick: bool
    seed: int
    seconds: float
    meta: dict = field(default_factory=dict)

    def _f64(self):
        return [r for r in self.rows if r["dtype"] == "float64"]

    @property
    def ok(self) -> bool:
        """float64 has zero NaN/inf, zero disagreements outside the band and nothing unresolved."""
        f = self._f64()
        return bool(f) and all(r["non_finite"] == 0 and r["disagreements_outside_band"] == 0
                               and r["unresolved"] == 0 for r in f)

    def _tot(self, dtype, key):
        return sum(r[key] for r in self.rows if r["dtype"] == dtype)

    def summary_lines(self) -> list:
        """A few lines: totals per dtype and where float32 departs."""
        out = [f"stiff suite ({'quick' if self.quick else 'full'}, seed {self.seed}): "
               f"{len({(r['family'], r['value']) for r in self.rows})} family/value sets, "
               f"{self.seconds:.1f} s; float64 {'OK' if self.ok else 'FAILED'}"]
        for dt in sorted({r["dtype"] for r in self.rows}, reverse=True):
            t = lambda k: self._tot(dt, k)  # noqa: E731
            out.append(f"  {dt}: {t('pairs')} pairs, {t('hits')} hits, non-finite {t('non_finite')}, "
                       f"outside band {t('disagreements_outside_band')}, inside band {t('inside_band')}, "
                       f"unresolved {t('unresolved')}, LP overruled {t('certified_over_lp')}, "
                       f"rounding-explained {t('rounding_explained')}, "
                       f"contacts beyond 2 tol {t('contact_outside_2tol')}, departures from float64 "
                       f"{t('departures')}")
        dep = [r for r in self.rows if r["dtype"] == "float32" and r["departures"]]
        if dep:
            worst = max(dep, key=lambda r: r["max_departure_rel"])
            out.append(f"  float32 departs in {len(dep)} sets; largest |gap|/S {worst['max_departure_rel']:.3g} "
                       f"({worst['max_departure_tol64']:.3g} float64 tol) in {worst['family']} "
                       f"{worst['param']}={_fmt(worst['value'])}")
        return out

    def csv_tables(self) -> dict:
        """``{"stiff": (header, rows)}``: every row of :attr:`rows`."""
        return {"stiff": (list(_COLS), [[r[c] for c in _COLS] for r in self.rows])}

    def json(self) -> dict:
        """Everything as plain JSON-able data (metadata, settings, rows, ok)."""
        return {"meta": self.meta, "quick": self.quick, "seed": self.seed, "seconds": self.seconds,
                "ok": self.ok, "rows": self.rows}

    def markdown(self) -> str:
        """A report section: how the suite works, the float64 table, the float32 departure table."""
        L = ["## Stiff and extreme suite", "",
             f"{'Quick' if self.quick else 'Full'} run, seed {self.seed}, {self.seconds:.0f} s "
             "(wall time on a shared machine, noisy). "
             f"float64: **{'no NaN/inf and no disagreement outside the touching band' if self.ok else 'FAILED'}**.",
             "",
             "Ground truth: *construction* families have a known separating plane and two witness points "
             "at the constructed gap (exact to the rounding of float64 coordinates, ~1e-15 S); *LP* "
             "families use random poses and the exact LP margin (`prismbatch.lab.exact.margin_lp`, trusted "
             "outside max(tol, 1e-7 S)), overruled only by certificates (a contact inside both bodies "
             "within 2 tol; a separating plane, its finiteness signs checked in exact arithmetic), and not "
             "used at all for axes pointing the same way within 1e-8 rad. S = R_a + R_b + |c_b - c_a|; "
             "float64 tol ~ 1e-9 S. A pair is inside the band when its gap is in (tol, 2 tol] "
             "(LP: |margin| <= max(tol, 1e-7 S)).", "",
             "float32 runs receive the same poses and polygons rounded to float32 (rounding a pose moves "
             "the bodies by ~1e-7 S: part of what a float32 user gets) and are judged against the float64 "
             "ground truth. This measures float32 *storage*: Numba promotes much of the kernels' "
             "arithmetic to float64.", "",
             "### float64", "",
             "| family | parameter | value | truth | pairs | hits | NaN/inf | outside band | inside band | "
             "unresolved | LP overruled | contact > 2 tol | cases |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in self._f64():
            L.append(f"| {r['family']} | {r['param']} | {_fmt(r['value'])} | {r['truth']} | {r['pairs']} | "
                     f"{r['hits']} | {r['non_finite']} | {r['disagreements_outside_band']} | {r['inside_band']} | "
                     f"{r['unresolved']} | {r['certified_over_lp']} | {r['contact_outside_2tol']} | {r['cases']} |")
        f32 = [r for r in self.rows if r["dtype"] == "float32"]
        if f32:
            L += ["", "### Where float32 departs", "",
                  "*departs*: answer differs from the float64-required one (pairs outside the float64 band); "
                  "*as hits*: of those, hits where float64 must miss (float32's wider tolerance, 1e-5 S); "
                  "*largest |gap|/S*: the largest |gap| (or |LP margin|) relative to S among departing "
                  "pairs, also in float64 tolerances; *outside own band*: contradicts the ground truth "
                  "beyond float32's own band (2 tol32 plus the pose rounding near the end faces); "
                  "*rounding*: contradicts it, but the float32-rounded bodies are certified to touch "
                  "(or part) as answered (nearly parallel axes: rounding turns a 1e-12 rad tilt by "
                  "~1e-7 rad, and the bodies then meet far away).", "",
                  "| family | parameter | value | pairs | hits | NaN/inf | departs | as hits | largest gap/S | "
                  "in float64 tol | outside own band | rounding | unresolved | contact > 2 tol32 |",
                  "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
            for r in f32:
                L.append(f"| {r['family']} | {r['param']} | {_fmt(r['value'])} | {r['pairs']} | {r['hits']} | "
                         f"{r['non_finite']} | {r['departures']} | {r['departures_hit']} | "
                         f"{_fmt(r['max_departure_rel'])} | {_fmt(r['max_departure_tol64'])} | "
                         f"{r['disagreements_outside_band']} | {r['rounding_explained']} | {r['unresolved']} | "
                         f"{r['contact_outside_2tol']} |")
        return "\n".join(L) + "\n"


def run_stiff_suite(*, quick=False, seed=0, dtypes=("float64", "float32"), progress=False,
                    families=None) -> StiffReport:
    """Run every stiff/extreme family in each dtype against its known ground truth.

    Parameters
    ----------
    quick : bool
        A few pairs per (family, value) (about 20 s once compiled) instead of
        320 constructed / 96 LP pairs (a few minutes).
    seed : int
        Seed of all pose and polygon draws.
    dtypes : sequence of {"float64", "float32"}
        Precisions to run; the ground truth is always float64.
    progress : bool
        Show a progress bar (needs tqdm).
    families : sequence of str, optional
        Run only these families (keys of :data:`FAMILIES`); default all.

    Returns
    -------
    StiffReport

    Raises
    ------
    ValueError
        Unknown dtype, an empty ``dtypes`` or an unknown family.
    TypeError
        ``seed`` not an integer.
    """
    dts = []
    for d in dtypes if not isinstance(dtypes, str) else (dtypes,):
        dd = np.dtype(d)
        if dd not in DEFAULT_RTOL:
            raise ValueError(f"dtypes: {d!r} is not float64 or float32")
        dts.append(dd)
    if not dts:
        raise ValueError("dtypes is empty")
    if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool):
        raise TypeError(f"seed must be an int, got {type(seed).__name__}")
    names = list(FAMILIES) if families is None else [families] if isinstance(families, str) else list(families)
    unknown = [f for f in names if f not in FAMILIES]
    if unknown or not names:
        raise ValueError(f"families: unknown {unknown} (choose from {sorted(FAMILIES)})" if unknown
                         else "families is empty")
    from .report import progress as _progress

    n_con, n_lp = _SIZES[bool(quick)]
    t0 = time.perf_counter()
    rows = []
    jobs = [(f, v) for f in names for v in FAMILIES[f][1]]
    with _progress(len(jobs), enabled=progress, unit="set", desc="stiff") as bar:
        for fam, val in jobs:
            pname, _, gen, truth = FAMILIES[fam]
            rng = np.random.default_rng([int(seed), list(FAMILIES).index(fam), FAMILIES[fam][1].index(val)])
            ps = gen(rng, n_lp if truth.startswith("LP") else n_con, val)
            m, trusted = _margins(ps) if ps.lp else (None, None)
            shapes = (_shape(ps.polys_a), _shape(ps.polys_b))
            for dt in dts:
                c = _run_one(ps, shapes, m, trusted, dt)
                rows.append(dict(family=fam, param=pname, value=float(val), dtype=dt.name, truth=truth, **c))
            bar.update(1)
    return StiffReport(rows, bool(quick), int(seed), time.perf_counter() - t0,
                       run_metadata(suite="stiff", quick=bool(quick), seed=int(seed)))


def write_stiff_report(report, out_dir):
    """Write ``stiff.csv``, ``stiff.json`` and ``stiff.md`` into ``out_dir``; returns the paths."""
    from pathlib import Path

    out = Path(out_dir)
    files = []
    for name, (header, rows) in report.csv_tables().items():
        files.append(write_csv(out / f"{name}.csv", header, rows))
    files.append(write_json(out / "stiff.json", report.json()))
    md = out / "stiff.md"
    md.write_text(report.markdown(), encoding="utf-8")
    files.append(str(md))
    return files
