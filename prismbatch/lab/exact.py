"""Exact reference for collision status: the signed margin of two semi-infinite
prisms by linear programming (scipy's HiGHS), plus a point-in-prism residual.

This shares no code with the kernels: it writes both bodies as half-spaces and
asks an LP solver for the largest common slack. It is slow (milliseconds per
pair) and is used on subsamples by :func:`prismbatch.lab.validate` and by the test
suite as ground truth. Needs scipy (``pip install 'prismbatch[exact]'``).

Geometry: a prism is a convex polygon ``xy`` (n, 2) in its local frame at
z = 0 and a pose ``(p, R)`` whose columns are the local axes in world
coordinates; the body is ``{p + R [x, y, t] : (x, y) in polygon, t >= 0}``.

Known limit: HiGHS works to about 1e-10 relative feasibility, so margins are
trusted to about 1e-7 of the scene size, and poses whose intersection lies
very far along nearly parallel axes (tilt below about 1e-8) are beyond it.
"""

from __future__ import annotations

import numpy as np

from ..config import LP_TRUST_RTOL
from ..geometry import halfplanes, max_radius, signed_area
from ..geometry import point_in_prism_residual as residual

__all__ = [
    "polygon_ccw",
    "polygon_halfplanes",
    "margin_lp",
    "margin_lp_batch",
    "point_in_prism_residual",
    "lp_trust_band",
]


def import_linprog():
    """scipy's ``linprog``; ImportError naming the ``[exact]`` extra when scipy is missing."""
    try:
        from scipy.optimize import linprog
    except ImportError as exc:
        raise ImportError("the exact LP reference needs scipy: pip install 'prismbatch[exact]'") from exc
    return linprog


# HiGHS rejects feasibility tolerances below 1e-10 ("Invalid option value").
_HIGHS_OPTIONS = {
    "primal_feasibility_tolerance": 1e-10,
    "dual_feasibility_tolerance": 1e-10,
}


def polygon_ccw(xy) -> np.ndarray:
    """Return the polygon as a float (n, 2) array in CCW order.

    Consecutive duplicate vertices (including last == first) are dropped.
    Raises ValueError for fewer than 3 distinct vertices or zero area.
    """
    poly = np.asarray(xy, dtype=float).reshape(-1, 2)
    keep = [0]
    for i in range(1, len(poly)):
        if np.any(poly[i] != poly[keep[-1]]):
            keep.append(i)
    poly = poly[keep]
    if len(poly) > 1 and np.all(poly[0] == poly[-1]):
        poly = poly[:-1]
    if len(poly) < 3:
        raise ValueError("polygon needs at least 3 distinct vertices")
    area = signed_area(poly)
    if area == 0.0:
        raise ValueError("polygon has zero area")
    if area < 0.0:
        poly = poly[::-1].copy()
    return poly


def lp_trust_band(tol, S):
    """Half-width of the touching band in which the LP margin decides nothing: ``max(tol, LP_TRUST_RTOL * S)``.

    ``tol`` is prismbatch's pair tolerance and ``S`` the scene scale
    (:func:`prismbatch.geometry.pair_scale_tolerance`); outside the band the
    LP's sign is the exact answer.
    """
    return np.maximum(tol, LP_TRUST_RTOL * np.asarray(S))


def polygon_halfplanes(xy):
    """Unit outward edge normals ``n`` (m, 2) and offsets ``h`` (m,) of a polygon given as the user gave it.

    :func:`prismbatch.geometry.halfplanes` of :func:`polygon_ccw` (repeated
    vertices dropped, fewer than 3 or zero area refused).
    """
    return halfplanes(polygon_ccw(xy))


def _body_rows(xy, p, R, length=None):
    """Rows (A, b) of  A @ [x, delta] <= b  for one body, unit normals.

    ``p``/``R`` are already expressed in the LP's working frame and scaled.
    """
    n2, h = polygon_halfplanes(xy)
    R = np.asarray(R, dtype=float)
    p = np.asarray(p, dtype=float)
    rows, rhs = [], []
    # side faces: n_w . (x - p) <= h - delta
    n_w = n2 @ R[:, :2].T  # (m, 3) = R @ [n, 0]
    n_w /= np.linalg.norm(n_w, axis=1, keepdims=True)
    for ni, hi in zip(n_w, h):
        rows.append([ni[0], ni[1], ni[2], 1.0])
        rhs.append(hi + ni @ p)
    # end face: d . (x - p) >= delta   <=>   -d . x + delta <= -d . p
    d = R[:, 2] / np.linalg.norm(R[:, 2])
    rows.append([-d[0], -d[1], -d[2], 1.0])
    rhs.append(-(d @ p))
    if length is not None:
        # optional far cap (finite prism of the given length):
        # d . (x - p) <= length - delta
        rows.append([d[0], d[1], d[2], 1.0])
        rhs.append(length + d @ p)
    return rows, rhs


def margin_lp(xy_a, pos_a, rot_a, xy_b, pos_b, rot_b, *, length_a=None, length_b=None) -> float:
    """Exact signed margin between two semi-infinite prisms.

    ``delta* = max_{x in R^3, delta} delta`` subject to every half-space of
    both bodies holding with slack >= delta, each written with a unit normal::

        end face   : (x - p) . d      >= delta
        side face i: n_i . (x - p)    <= h_i - delta

    so delta is in length units.  ``delta* >= 0`` iff the closed bodies
    intersect; if ``delta* < 0`` the Euclidean gap g satisfies ``g >= 2 |delta*|``
    (the midpoint of a closest pair violates no constraint by more than g/2).
    For two parallel slabs / half-spaces the bound is tight (``g = -2 delta*``).

    ``length_a`` / ``length_b`` (keyword-only, optional) add a far cap
    ``(x - p) . d <= length - delta``, i.e. the margin of FINITE prisms of
    that length; used to compare against finite stand-ins (python-fcl).

    The LP is solved in a frame centred at (p_a + p_b) / 2, rotated into
    a's frame, with lengths divided by the larger polygon radius; the
    result is returned in the input's length units.  delta is bounded above
    by 1e3 (scaled units; it is naturally bounded by the polygons' inradii).
    Raises RuntimeError if HiGHS does not report an optimal solution.
    """
    pos_a = np.asarray(pos_a, dtype=float).reshape(3)
    pos_b = np.asarray(pos_b, dtype=float).reshape(3)
    rot_a = np.asarray(rot_a, dtype=float).reshape(3, 3)
    rot_b = np.asarray(rot_b, dtype=float).reshape(3, 3)
    scale = max(max_radius(xy_a), max_radius(xy_b), 1e-300)

    origin = 0.5 * (pos_a + pos_b)
    Q = rot_a.T  # world -> a-frame rotation (exact for orthonormal rot_a)
    xa = np.asarray(xy_a, dtype=float) / scale
    xb = np.asarray(xy_b, dtype=float) / scale
    pa = Q @ (pos_a - origin) / scale
    pb = Q @ (pos_b - origin) / scale
    Ra = Q @ rot_a
    Rb = Q @ rot_b
    la = None if length_a is None else float(length_a) / scale
    lb = None if length_b is None else float(length_b) / scale

    rows_a, rhs_a = _body_rows(xa, pa, Ra, la)
    rows_b, rhs_b = _body_rows(xb, pb, Rb, lb)
    A = np.array(rows_a + rows_b, dtype=float)
    b = np.array(rhs_a + rhs_b, dtype=float)
    c = np.array([0.0, 0.0, 0.0, -1.0])
    bounds = [(None, None)] * 3 + [(None, 1e3)]
    # Tight tolerances first; HiGHS occasionally gives up on nearly degenerate
    # poses (status 4), so fall back to its other solvers before failing.
    attempts = (("highs", _HIGHS_OPTIONS), ("highs-ds", _HIGHS_OPTIONS), ("highs-ipm", {}), ("highs-ds", {}))
    linprog = import_linprog()
    for method, options in attempts:
        res = linprog(c, A_ub=A, b_ub=b, bounds=bounds, method=method, options=options)
        if res.status == 0:
            return float(res.x[3]) * scale
    raise RuntimeError(f"margin_lp: HiGHS status {res.status}: {res.message}")


def margin_lp_batch(xy_a, pos_a, rot_a, xy_b, pos_b, rot_b, *, length_a=None, length_b=None) -> np.ndarray:
    """``margin_lp`` over N pose pairs -> (N,) float array.

    ``xy_a`` / ``xy_b``: one (n, 2) polygon shared by all pairs, or a list
    (length N) of per-pair polygons.  ``pos_*``: (N, 3), ``rot_*``: (N, 3, 3).
    ``length_*``: None, a scalar, or an (N,) array.
    """
    pos_a = np.asarray(pos_a, dtype=float).reshape(-1, 3)
    pos_b = np.asarray(pos_b, dtype=float).reshape(-1, 3)
    rot_a = np.asarray(rot_a, dtype=float).reshape(-1, 3, 3)
    rot_b = np.asarray(rot_b, dtype=float).reshape(-1, 3, 3)
    N = len(pos_a)
    if not (len(pos_b) == len(rot_a) == len(rot_b) == N):
        raise ValueError("pos_a, rot_a, pos_b, rot_b must have the same length N")

    def per_pair_poly(xy):
        if isinstance(xy, (list, tuple)) and len(xy) == N and np.ndim(xy[0]) == 2:
            return list(xy)
        return [xy] * N

    def per_pair_len(L):
        if L is None or np.ndim(L) == 0:
            return [L] * N
        return list(np.asarray(L, dtype=float).reshape(N))

    pa_list, pb_list = per_pair_poly(xy_a), per_pair_poly(xy_b)
    la_list, lb_list = per_pair_len(length_a), per_pair_len(length_b)
    out = np.empty(N)
    for k in range(N):
        out[k] = margin_lp(
            pa_list[k], pos_a[k], rot_a[k], pb_list[k], pos_b[k], rot_b[k], length_a=la_list[k], length_b=lb_list[k]
        )
    return out


def point_in_prism_residual(xy, pos, rot, x) -> float:
    """:func:`prismbatch.geometry.point_in_prism_residual` of the polygon as given (see :func:`polygon_ccw`)."""
    return residual(polygon_ccw(xy), pos, rot, x)
