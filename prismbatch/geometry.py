"""Plain-NumPy geometry of polygons, prisms and frames: the one home of each formula.

The kernels have compiled versions of their own; these serve the Python side
(sampling, reports, references, the lab). Polygons are ``(n, 2)`` vertex
arrays; a prism's body is ``{p + R [x, y, t] : (x, y) in polygon, t >= 0}``.
"""

from __future__ import annotations

import numpy as np

from .config import DEFAULT_RTOL

__all__ = [
    "AXIS_DOWN",
    "signed_area",
    "exact_area2",
    "ccw",
    "max_radius",
    "centroid_radius",
    "rotation_with_axis",
    "row_norms",
    "convex_hull",
    "halfplanes",
    "point_in_prism_residual",
    "pair_scale_tolerance",
]

#: a's orientation in the paper's scene: local axes x, -y, -z (axis d_a = [0, 0, -1], body below).
AXIS_DOWN = np.diag([1.0, -1.0, -1.0])
AXIS_DOWN.flags.writeable = False


def signed_area(xy) -> float:
    """Signed area of a polygon (> 0 counter-clockwise), by the shoelace formula about its mean."""
    p = np.asarray(xy, dtype=float).reshape(-1, 2)
    v = p - p.mean(axis=0)  # well conditioned far from the origin
    return 0.5 * float(np.sum(v[:, 0] * np.roll(v[:, 1], -1) - np.roll(v[:, 0], -1) * v[:, 1]))


def exact_area2(xy):
    """Twice the signed area as an exact ``Fraction`` (floats are exact rationals; entries may be
    floats or Fractions already)."""
    from fractions import Fraction

    q = [tuple(v if isinstance(v, Fraction) else Fraction(float(v)) for v in p) for p in xy]
    return sum(x0 * y1 - x1 * y0 for (x0, y0), (x1, y1) in zip(q, q[1:] + q[:1]))


def ccw(xy) -> np.ndarray:
    """The polygon as a float ``(n, 2)`` array in counter-clockwise order."""
    p = np.asarray(xy, dtype=float).reshape(-1, 2)
    return p[::-1].copy() if signed_area(p) < 0 else p


def max_radius(xy, centre=(0.0, 0.0)) -> float:
    """Largest distance from ``centre`` to a vertex."""
    p = np.asarray(xy, dtype=float).reshape(-1, 2) - np.asarray(centre, dtype=float)
    return float(np.max(np.hypot(p[:, 0], p[:, 1])))


def centroid_radius(xy):
    """Area centroid ``(2,)`` of a convex polygon and the largest vertex distance from it.

    Raises ValueError for a polygon of zero area.
    """
    p = np.asarray(xy, dtype=float).reshape(-1, 2)
    x0 = p.mean(axis=0)
    v = p - x0
    vn = np.roll(v, -1, axis=0)
    cr = v[:, 0] * vn[:, 1] - vn[:, 0] * v[:, 1]
    area2 = cr.sum()
    if area2 == 0.0:
        raise ValueError("polygon has zero area")
    c = np.array([((v[:, 0] + vn[:, 0]) * cr).sum(), ((v[:, 1] + vn[:, 1]) * cr).sum()]) / (3.0 * area2) + x0
    return c, max_radius(p, c)


def rotation_with_axis(d, spin=0.0, *, exact_axis=False):
    """Rotations whose third column is the unit vector along ``d``, spun by ``spin`` about it.

    Parameters
    ----------
    d : array_like, shape (3,) or (N, 3)
        Axis directions (normalised here).
    spin : float or array_like of shape (N,), optional
        Angle about the axis, in radians, from the reference first column
        (x̂, or ŷ where d is close to x̂, made orthogonal to d).
    exact_axis : bool, optional
        Take ``d`` as unit vectors as given: the third column is ``d`` bit for
        bit (constructions that place a face exactly rely on it); by default
        ``d`` is normalised first.

    Returns
    -------
    numpy.ndarray, shape (3, 3) or (N, 3, 3)
    """
    d = np.asarray(d, dtype=float)
    single = d.ndim == 1
    d = np.atleast_2d(d)
    if not exact_axis:
        norm = row_norms(d)
        bad = ~(np.isfinite(norm) & (norm > 0))
        if bad.any():
            i = int(np.argmax(bad))
            raise ValueError(f"rotation_with_axis: axis {d[i].tolist()} is not a direction (zero or not finite)")
        d = d / norm[:, None]
    ref = np.where(np.abs(d[:, :1]) < 0.9, np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]))
    x = ref - np.sum(ref * d, axis=1, keepdims=True) * d
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    y = np.cross(d, x)
    spin = np.broadcast_to(np.asarray(spin, dtype=float), (len(d),))
    c, s = np.cos(spin)[:, None], np.sin(spin)[:, None]
    R = np.stack([c * x + s * y, -s * x + c * y, d], axis=2)
    return R[0] if single else R


def row_norms(x):
    """Euclidean norms of the rows of ``x`` (k, m), with no overflow or underflow in their squares.

    Each row is scaled by the power of two of its largest component first: exact, so rows whose
    squares are representable get the plain formula's bits, and rows of 1e200 or 1e-200 their norm
    (inf only where the norm itself is beyond float64).
    """
    x = np.asarray(x, dtype=float)
    big = np.abs(x).max(axis=1, initial=0.0)
    e = np.frexp(np.where(np.isfinite(big) & (big > 0.0), big, 1.0))[1]
    with np.errstate(over="ignore"):
        return np.ldexp(np.sqrt(np.square(np.ldexp(x, -e[:, None])).sum(axis=1)), e)


def halfplanes(xy):
    """Unit outward edge normals ``n`` (m, 2) and offsets ``h`` (m,) of a convex polygon.

    The polygon is ``{q : n_i . q <= h_i for all i}``. Edges shorter than
    1e-14 of the polygon's extent (repeated vertices) are skipped: its extent,
    not its distance from the origin, which dropped real edges of small
    polygons far from it (a 0.006 chamfer at 1e12).
    """
    p = ccw(xy)
    e = np.roll(p, -1, axis=0) - p
    length = np.hypot(e[:, 0], e[:, 1])
    ok = length > 1e-14 * max(float(np.max(np.ptp(p, axis=0))), 1e-300)
    n = np.stack([e[ok, 1], -e[ok, 0]], axis=1) / length[ok, None]
    return n, np.einsum("ij,ij->i", n, p[ok])


def point_in_prism_residual(xy, pos, rot, x, planes=None) -> float:
    """Largest violated half-space of world point ``x`` against one semi-infinite prism.

    ``max(-t, max_i(n_i . q - h_i))`` with ``[q, t] = R^-1 (x - p)`` and the
    unit outward edge normals n_i: <= 0 inside or on the body, > 0 outside,
    in length units (a lower bound of the Euclidean distance to the body,
    exact when a single face is violated). ``planes``: ``halfplanes(xy)``
    when the caller keeps them (a suite asking many points of one polygon).
    R's inverse, not its transpose: a rotation is the exact affine map it is
    given as (a float32 matrix is orthonormal only to about 1e-7, and its
    transpose put points on the body 80 tol off it in float64 units).
    """
    local = np.linalg.solve(
        np.asarray(rot, dtype=float).reshape(3, 3),
        np.asarray(x, dtype=float).reshape(3) - np.asarray(pos, dtype=float).reshape(3),
    )
    n, h = halfplanes(xy) if planes is None else planes
    return float(max(-local[2], np.max(n @ local[:2] - h)))


def _orientation_exact(o, a, b):
    """Sign of the turn o -> a -> b in rational arithmetic on the float coordinates."""
    from fractions import Fraction

    ox, oy = Fraction(o[0]), Fraction(o[1])
    v = (Fraction(a[0]) - ox) * (Fraction(b[1]) - oy) - (Fraction(a[1]) - oy) * (Fraction(b[0]) - ox)
    return (v > 0) - (v < 0)


def convex_hull(points) -> np.ndarray:
    """Strictly convex hull (counter-clockwise, no repeated end point) of (n, 2) points.

    Andrew's monotone chain; a turn too close to zero for its floating-point
    value to be trusted is decided in rational arithmetic, so nearly collinear
    points are kept or dropped correctly. Fewer than 3 distinct points are
    returned as they are.
    """
    pts = sorted(tuple(map(float, p)) for p in np.unique(np.asarray(points, dtype=float), axis=0))
    if len(pts) < 3:
        return np.array(pts, dtype=float).reshape(-1, 2)

    def turn(o, a, b):
        v = (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
        size = abs(a[0] - o[0]) * abs(b[1] - o[1]) + abs(a[1] - o[1]) * abs(b[0] - o[0])
        return (v > 0) - (v < 0) if abs(v) > 1e-12 * size else _orientation_exact(o, a, b)

    def chain(seq):
        out = []
        for p in seq:
            while len(out) >= 2 and turn(out[-2], out[-1], p) <= 0:
                out.pop()
            out.append(p)
        return out

    lower, upper = chain(pts), chain(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


def pair_scale_tolerance(shape_a, shape_b, pos_a, rot_a, pos_b, rot_b, *, rtol=None, atol=0.0, dtype=np.float64):
    """Scene scale and touching tolerance of each pair, as the kernels compute them (NumPy).

    ``S = R_a + R_b + |c_b - c_a|`` and
    ``tol = atol + rtol S + 4 eps (|c_a| + |c_b|) + 8 eps (|k_a|_1 + |k_b|_1)``
    (end-face radii about the area centroids, centroids c in world coordinates and k in
    the prisms' local frames, eps of ``dtype``); for reports and references that need the
    kernels' tolerance outside them.

    Parameters
    ----------
    shape_a, shape_b : Prism
    pos_a, pos_b : numpy.ndarray, shape (N, 3)
    rot_a, rot_b : numpy.ndarray, shape (N, 3, 3)
    rtol : float, optional
        Default :data:`~prismbatch.config.DEFAULT_RTOL` of ``dtype``.
    atol : float, optional
    dtype : numpy dtype, optional

    Returns
    -------
    S, tol : numpy.ndarray, shape (N,)
    """
    dt = np.dtype(dtype)
    rtol = DEFAULT_RTOL[dt] if rtol is None else rtol
    eps = float(np.finfo(dt).eps)
    ca = pos_a + rot_a[:, :, :2] @ shape_a.centre
    cb = pos_b + rot_b[:, :, :2] @ shape_b.centre
    S = shape_a.radius + shape_b.radius + np.linalg.norm(cb - ca, axis=1)
    local = np.abs(shape_a.centre).sum() + np.abs(shape_b.centre).sum()
    tol = atol + rtol * S + eps * (4 * (np.linalg.norm(ca, axis=1) + np.linalg.norm(cb, axis=1)) + 8 * local)
    return S, tol
