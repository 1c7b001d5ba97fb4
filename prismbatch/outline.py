"""Convex polygon outlines: reading them and checking that they are convex.

One home for what makes a polygon acceptable (:func:`validate_polygon`; :class:`~prismbatch.shapes.PrismSet`
runs the same checks on stacks of polygons at once) and for the row shifts and binary exponents the checks
and :mod:`prismbatch.shapes` share.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .checks import refuse_masked
from .config import MIN_RELATIVE_AREA, MIN_RELATIVE_EDGE
from .geometry import exact_area2

__all__ = [
    "validate_polygon",
    "read_polygon",
    "check_polygons",
    "raise_first_failure",
    "PolygonChecks",
    "next_rows",
    "prev_rows",
    "binary_exponent",
]

_TWO_PI = 2.0 * np.pi
# A turn between consecutive edges may be negative by this much (relative to
# the product of the edge lengths) and still count as straight: nearly
# collinear consecutive vertices are legal, dents are not. Not more: the
# extreme-vertex search takes the edge angles as they are, so along a straight
# side whose edge angles rounding scatters by t, a support point can land
# anywhere on the side, off by up to t times its length (accepting turns up to
# 1e-6 gave missed contacts 2.6 tol deep on sides sampled at 1e4 from the origin).
_CONVEX_RTOL = 1e-12
# For the same reason the outline may not turn back by more than this in all
# (radians) over a run of vertices, each within _CONVEX_RTOL: 100,000 such steps
# would make a side concave by 9e-8 rad, its middle 1e-8 of its length inside.
_MAX_BACKTRACK = 4e-12


def next_rows(a):
    """Each polygon's rows shifted so that row k holds row k + 1 (cyclic along axis 1 of a stack)."""
    return np.concatenate((a[:, 1:], a[:, :1]), axis=1)


def prev_rows(a):
    """Each polygon's rows shifted so that row k holds row k - 1 (cyclic along axis 1)."""
    return np.concatenate((a[:, -1:], a[:, :-1]), axis=1)


def _absmax(x):
    """Largest magnitude of each polygon's entries (axis 0 indexes the polygons)."""
    return np.abs(x).reshape(len(x), -1).max(axis=1)


def binary_exponent(x):
    """Binary exponent ``e`` per polygon with ``max |x| < 2**e`` (0 where x is all zero)."""
    return np.frexp(_absmax(x))[1]


def validate_polygon(xy, *, name="polygon"):
    """Check a convex polygon and return it counter-clockwise as float64.

    Parameters
    ----------
    xy : array_like, shape (n, 2)
        Vertices in order (clockwise or counter-clockwise). A closed ring,
        whose last vertex repeats the first (as shapely and GeoJSON write
        polygons), is accepted: the repeat is dropped.
    name : str
        Used in error messages, e.g. ``"shape_b[3]"``.

    Returns
    -------
    numpy.ndarray, shape (n, 2)
        The same vertices, counter-clockwise, C-contiguous float64. The only
        changes made are reversing clockwise order and dropping a closing
        repeat of the first vertex.

    Raises
    ------
    TypeError
        Non-numeric data.
    ValueError
        Wrong shape, NaN/inf, fewer than 3 vertices, repeated vertices, zero
        area, a non-convex or self-intersecting outline. The message names the
        polygon and the offending vertex.
    """
    arr = read_polygon(xy, name)
    checks = check_polygons(arr[None])
    if not checks.ok[0]:
        raise_first_failure(checks, 0, arr, name)
    return np.ascontiguousarray(checks.ccw[0])


def read_polygon(xy, name):
    """``xy`` as an (n, 2) float64 array of finite vertices, n >= 3, a closing repeat dropped."""
    refuse_masked(xy, name)
    try:
        arr = np.asarray(xy)
    except ValueError as exc:  # ragged nested lists
        raise ValueError(f"{name}: vertices could not be read as an (n, 2) array: {exc}") from None
    if arr.dtype.kind not in "iuf":
        raise TypeError(f"{name}: vertices must be real numbers, got dtype {arr.dtype}")
    arr = np.array(arr, dtype=np.float64, order="C")
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ValueError(f"{name}: vertices must have shape (n, 2), got {arr.shape}")
    if arr.shape[0] >= 4 and (arr[0] == arr[-1]).all() and not (arr == arr[0]).all():
        arr = np.ascontiguousarray(arr[:-1])  # a closed ring: the last vertex closes it, it is not another
    n = arr.shape[0]
    if n < 3:
        raise ValueError(f"{name}: a polygon needs at least 3 vertices, got {n}")
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        raise ValueError(f"{name}: vertex {int(np.argmax(bad))} is not finite: {arr[np.argmax(bad)]}")
    return arr


class PolygonChecks(NamedTuple):
    """The outline checks of a stack of ``m`` polygons of ``n`` vertices (see :func:`check_polygons`)."""

    ok: np.ndarray  # (m,) passed every check
    ccw: np.ndarray  # (m, n, 2) the vertices, counter-clockwise
    coincide: np.ndarray  # (m,) all vertices equal
    elen: np.ndarray  # (m, n) unit-scaled edge lengths (of the input order)
    short: np.ndarray  # (m, n) edge below MIN_RELATIVE_EDGE
    area2: np.ndarray  # (m,) unit-scaled twice signed area
    thin: np.ndarray  # (m,) area below MIN_RELATIVE_AREA
    dent: np.ndarray  # (m, n) reflex turn at the (counter-clockwise) vertex
    turns: np.ndarray  # (m, n) signed turn at the (counter-clockwise) vertex, radians
    backtrack: tuple  # ((m,), (m,)) the most the outline turns back over a run of vertices, and where
    total: np.ndarray  # (m,) total left turn, radians
    fold: np.ndarray  # (m, n) the outline folds back at the vertex


def check_polygons(arr):
    """Every outline check of ``m`` polygons at once, ``arr`` (m, n, 2) finite float64.

    Each polygon is judged relative to itself: shifted to its vertex 0 and scaled by
    powers of two (exact) to unit size, so a polygon far from its origin, or of any size,
    is judged like the same polygon at unit scale. Edges are differences of neighbouring
    vertices taken before any shift (exact for nearby floats), so short edges keep every
    bit. :func:`validate_polygon` is this with ``m = 1``; :class:`PrismSet` stacks the
    polygons of equal vertex count.
    """
    u = np.ldexp(arr, -binary_exponent(arr)[:, None, None])  # |u| < 1
    edges = next_rows(u) - u
    size = _absmax(edges)
    scale = np.frexp(size)[1]
    coincide = (_absmax(arr) == 0.0) | (size == 0.0)
    rel = np.ldexp(u - u[:, :1], -scale[:, None, None])
    edges = np.ldexp(edges, -scale[:, None, None])
    elen = np.hypot(edges[..., 0], edges[..., 1])
    # Repeated vertices: consecutive duplicates show as zero-length edges;
    # non-consecutive ones make the outline self-touching (caught below).
    # (Distinct floats never differ by exactly 0, so a zero edge is a repeat.)
    short = elen <= MIN_RELATIVE_EDGE
    area2 = np.sum(rel[..., 0] * next_rows(rel[..., 1]) - next_rows(rel[..., 0]) * rel[..., 1], axis=1)
    thin = np.abs(area2) <= MIN_RELATIVE_AREA
    cw = (area2 < 0.0)[:, None]
    ccw = np.where(cw[..., None], arr[:, ::-1], arr)
    ccw_edges = np.where(cw[..., None], -next_rows(edges[:, ::-1]), edges)
    ccw_elen = np.where(cw, next_rows(elen[:, ::-1]), elen)
    prev = prev_rows(ccw_edges)
    cross = prev[..., 0] * ccw_edges[..., 1] - prev[..., 1] * ccw_edges[..., 0]
    dot = prev[..., 0] * ccw_edges[..., 0] + prev[..., 1] * ccw_edges[..., 1]
    dent = cross < -_CONVEX_RTOL * ccw_elen * prev_rows(ccw_elen)
    turns = np.arctan2(cross, dot)
    backtrack = _backtrack(ccw_edges, turns)
    total = np.sum(np.maximum(turns, 0.0), axis=1)
    fold = np.abs(turns) >= np.pi - 1e-12
    bad = coincide | short.any(axis=1) | thin | dent.any(axis=1) | (backtrack[0] > _MAX_BACKTRACK)
    ok = ~(bad | (np.abs(total - _TWO_PI) > 1e-6) | fold.any(axis=1))
    return PolygonChecks(ok, ccw, coincide, elen, short, area2, thin, dent, turns, backtrack, total, fold)


def _backtrack(edges, turns):
    """``(fall, vertex)`` per polygon: the most the edge direction falls back below the largest it had
    reached (radians, over a run of vertices) and the vertex where it does. From each edge's own angle,
    unwrapped by whole turns (a running sum of the turns would round by n eps), taken from the vertex
    of the largest turn, so that no run of backward turns straddles the start. Only polygons with a
    backward turn are measured: the others never fall back (measuring all of them added 6 % to the build
    of a PrismSet of 100,000 random polygons)."""
    m, n = turns.shape
    out_fall, out_vertex = np.zeros(m), np.zeros(m, dtype=np.int64)
    some = np.flatnonzero((turns < 0.0).any(axis=1))
    if len(some):
        order = (np.argmax(turns[some], axis=1)[:, None] + np.arange(n)) % n  # edge k: vertex k to k + 1
        e = np.take_along_axis(edges[some], order[..., None], axis=1)
        theta = np.arctan2(e[..., 1], e[..., 0])
        wraps = -np.round(np.diff(theta, axis=1) / _TWO_PI)
        unwrapped = theta + _TWO_PI * np.concatenate((np.zeros((len(some), 1)), np.cumsum(wraps, axis=1)), axis=1)
        fall = np.maximum.accumulate(unwrapped, axis=1) - unwrapped
        k = np.argmax(fall, axis=1)
        rows = np.arange(len(some))
        out_fall[some], out_vertex[some] = fall[rows, k], order[rows, k]
    return out_fall, out_vertex


def raise_first_failure(c, i, arr, name):
    """Raise the ValueError of polygon ``i`` of the checks ``c``: its first failed check, in order. Vertex
    numbers are the caller's: the checks after the edge lengths run on the counter-clockwise order."""
    n = c.ccw.shape[1]
    given = (lambda k: n - 1 - k) if c.area2[i] < 0.0 else (lambda k: k)  # noqa: E731
    if c.coincide[i]:
        raise ValueError(f"{name}: all {n} vertices coincide")
    if c.short[i].any():
        k = int(np.argmax(c.short[i]))
        if c.elen[i, k] == 0.0:
            raise ValueError(f"{name}: vertex {(k + 1) % n} repeats vertex {k} (zero-length edge)")
        raise ValueError(
            f"{name}: edge {k} is {c.elen[i, k]:.3g} of the polygon's size, below the supported "
            f"{MIN_RELATIVE_EDGE:g}: merge vertices {k} and {(k + 1) % n}"
        )
    if c.thin[i]:
        if exact_area2(arr) == 0:
            raise ValueError(f"{name}: polygon has zero area (collinear vertices)")
        raise ValueError(
            f"{name}: polygon is too thin: its area is about {abs(c.area2[i]) / 2:.3g} of its size "
            f"squared, below the supported {MIN_RELATIVE_AREA / 2:g}"
        )
    if c.dent[i].any():
        k = int(np.argmax(c.dent[i]))
        turn = c.turns[i, k]
        k = given(k)
        hint = (
            ": a turn this small is the rounding of vertices dense for their distance from the polygon's own "
            "origin (a straight side sampled densely, or a fine polygon given far away); drop the vertices "
            "inside straight sides (they change nothing), or give fewer"
            if turn > -1e-6
            else ""
        )
        raise ValueError(f"{name}: polygon is not convex at vertex {k} (reflex turn of {-turn:.2g} rad){hint}")
    fall, k = c.backtrack[0][i], given(int(c.backtrack[1][i]))
    if fall > _MAX_BACKTRACK:
        raise ValueError(
            f"{name}: polygon is not convex: its outline turns back by {fall:.2g} rad in all up to vertex {k}, "
            f"over vertices that each turn back by less than {_CONVEX_RTOL:g} (a side bent inwards)"
        )
    if abs(c.total[i] - _TWO_PI) > 1e-6:
        raise ValueError(
            f"{name}: polygon outline is self-intersecting (it turns {c.total[i] / _TWO_PI:.3f} times, not once)"
        )
    raise ValueError(f"{name}: polygon folds back on itself at vertex {given(int(np.argmax(c.fold[i])))}")
