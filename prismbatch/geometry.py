"""Plain-NumPy geometry of polygons, prisms and frames: the one home of each formula.

The kernels have compiled versions of their own; these serve the Python side
(sampling, reports, references, the lab). Polygons are ``(n, 2)`` vertex
arrays; a prism's body is ``{p + R [x, y, t] : (x, y) in polygon, t >= 0}``.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "AXIS_DOWN",
    "signed_area",
    "ccw",
    "max_radius",
    "centroid_radius",
    "rotation_with_axis",
    "halfplanes",
    "point_in_prism_residual",
]

#: a's orientation in the paper's scene: local axes x, -y, -z (axis d_a = [0, 0, -1], body below).
AXIS_DOWN = np.diag([1.0, -1.0, -1.0])
AXIS_DOWN.flags.writeable = False


def signed_area(xy) -> float:
    """Signed area of a polygon (> 0 counter-clockwise), by the shoelace formula about its mean."""
    p = np.asarray(xy, dtype=float).reshape(-1, 2)
    v = p - p.mean(axis=0)  # well conditioned far from the origin
    return 0.5 * float(np.sum(v[:, 0] * np.roll(v[:, 1], -1) - np.roll(v[:, 0], -1) * v[:, 1]))


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


def rotation_with_axis(d, spin=0.0):
    """Rotations whose third column is the unit vector along ``d``, spun by ``spin`` about it.

    Parameters
    ----------
    d : array_like, shape (3,) or (N, 3)
        Axis directions (normalised here).
    spin : float or array_like of shape (N,), optional
        Angle about the axis, in radians, from the reference first column
        (x̂, or ŷ where d is close to x̂, made orthogonal to d).

    Returns
    -------
    numpy.ndarray, shape (3, 3) or (N, 3, 3)
    """
    d = np.asarray(d, dtype=float)
    single = d.ndim == 1
    d = np.atleast_2d(d)
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    ref = np.where(np.abs(d[:, :1]) < 0.9, np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]))
    x = ref - np.sum(ref * d, axis=1, keepdims=True) * d
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    y = np.cross(d, x)
    spin = np.broadcast_to(np.asarray(spin, dtype=float), (len(d),))
    c, s = np.cos(spin)[:, None], np.sin(spin)[:, None]
    R = np.stack([c * x + s * y, -s * x + c * y, d], axis=2)
    return R[0] if single else R


def halfplanes(xy):
    """Unit outward edge normals ``n`` (m, 2) and offsets ``h`` (m,) of a convex polygon.

    The polygon is ``{q : n_i . q <= h_i for all i}``. Edges shorter than
    1e-14 of the polygon's scale (repeated vertices) are skipped.
    """
    p = ccw(xy)
    e = np.roll(p, -1, axis=0) - p
    length = np.hypot(e[:, 0], e[:, 1])
    ok = length > 1e-14 * max(float(np.max(np.abs(p))), 1e-300)
    n = np.stack([e[ok, 1], -e[ok, 0]], axis=1) / length[ok, None]
    return n, np.einsum("ij,ij->i", n, p[ok])


def point_in_prism_residual(xy, pos, rot, x) -> float:
    """Largest violated half-space of world point ``x`` against one semi-infinite prism.

    ``max(-t, max_i(n_i . q - h_i))`` with ``[q, t] = R^T (x - p)`` and the
    unit outward edge normals n_i: <= 0 inside or on the body, > 0 outside,
    in length units (a lower bound of the Euclidean distance to the body,
    exact when a single face is violated).
    """
    local = np.asarray(rot, dtype=float).reshape(3, 3).T @ (
        np.asarray(x, dtype=float).reshape(3) - np.asarray(pos, dtype=float).reshape(3)
    )
    n, h = halfplanes(xy)
    return float(max(-local[2], np.max(n @ local[:2] - h)))
