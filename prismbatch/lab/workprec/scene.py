"""The work-precision scene: a cylinder as an inscribed n-gon, and near-contact poses with exact labels.

The construction and why its labels are exact: ``docs/methods/work-precision.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...geometry import rotation_with_axis
from ...sampling import AXIS_DOWN
from ...shapes import Prism
from ..checks import check_int, check_positive

#: Near-contact construction: |gap| / r range (log-uniform), angle of u from a's end-face normal and of
#: b's axis from u (degrees).
GAP_RANGE = (1e-8, 1e-1)
BETA_RANGE_DEG = (10.0, 80.0)
TILT_RANGE_DEG = (5.0, 60.0)

#: b's circumradius relative to the cylinder's radius (the paper's Fig. 6 hexagon : pentagon, 2.5 : 2).
B_SCALE = 1.25
B_VERTICES = 6


# ---------------------------------------------------------------------------
# argument checks (shared with run.py)
# ---------------------------------------------------------------------------


def geometric_error(n, radius=1.0):
    """Largest radial deficit ``radius (1 - cos(pi / n))`` of the inscribed regular n-gon.

    Computed as ``2 radius sin^2(pi / (2 n))`` (no cancellation for large n).

    Parameters
    ----------
    n : int or array_like
        Vertex count(s), each >= 3.
    radius : float, optional
        Circle radius.

    Returns
    -------
    numpy.ndarray
        The deficit, same shape as ``n`` (0-d for a scalar).
    """
    n = np.asarray(n, dtype=float)
    if np.any(n < 3):
        raise ValueError(f"n must be >= 3, got {n}")
    return radius * 2.0 * np.sin(np.pi / (2.0 * n)) ** 2


def vertices_needed(rel_error):
    """Smallest n whose inscribed n-gon has ``1 - cos(pi / n) <= rel_error``.

    Parameters
    ----------
    rel_error : float
        Relative geometric error, in (0, 1).

    Returns
    -------
    int
    """
    e = float(rel_error)
    if not (0.0 < e < 1.0):
        raise ValueError(f"rel_error must be in (0, 1), got {rel_error}")
    n = max(3, math.ceil(math.pi / (2.0 * math.asin(math.sqrt(e / 2.0)))))
    while n > 3 and geometric_error(n - 1) <= e:  # guard the ceil against rounding
        n -= 1
    while geometric_error(n) > e:
        n += 1
    return int(n)


# ---------------------------------------------------------------------------
# poses with exact labels
# ---------------------------------------------------------------------------


@dataclass
class NearContactPoses:
    """Near-contact pose pairs of the cylinder (a) and b with exact labels.

    Attributes
    ----------
    pos_a, rot_a, pos_b, rot_b : numpy.ndarray
        (N, 3) and (N, 3, 3) float64 poses (a's are the same for every pair).
    gap : numpy.ndarray, shape (N,)
        Signed gap g (length units): > 0 the bodies are exactly g apart,
        < 0 b's vertex ``v`` is inside the cylinder.
    beta : numpy.ndarray, shape (N,)
        Angle (rad) between u and the end face's outward normal ``-d_a``.
    u : numpy.ndarray, shape (N, 3)
        World direction of the construction.
    vertex : numpy.ndarray of int, shape (N,)
        Index of b's vertex ``v`` in ``shape_b.xy``.
    hit : numpy.ndarray of bool, shape (N,)
        Exact label: True iff the cylinder and b intersect (``g < 0``).
    radius : float
        Cylinder radius r.
    """

    pos_a: np.ndarray
    rot_a: np.ndarray
    pos_b: np.ndarray
    rot_b: np.ndarray
    gap: np.ndarray
    beta: np.ndarray
    u: np.ndarray
    vertex: np.ndarray
    hit: np.ndarray
    radius: float

    def __len__(self):
        return self.gap.shape[0]

    def vertex_local(self, shape_b):
        """b's vertex ``v`` of every pair in a's local frame, (N, 3)."""
        xy = np.asarray(shape_b.xy)[self.vertex]
        vw = self.pos_b + np.einsum("nij,nj->ni", self.rot_b[:, :, :2], xy)
        return np.einsum("nji,nj->ni", self.rot_a, vw - self.pos_a)

    def depth_in_cylinder(self, shape_b):
        """Depth of ``v`` inside the exact cylinder: ``min(t, r - |q|)`` (< 0 outside)."""
        loc = self.vertex_local(shape_b)
        return np.minimum(loc[:, 2], self.radius - np.hypot(loc[:, 0], loc[:, 1]))

    def depth_in_ngon(self, shape_b, n):
        """Depth of ``v`` inside a's inscribed regular n-gon prism (vertex 0 on local +x); < 0 outside."""
        loc = self.vertex_local(shape_b)
        step = 2.0 * np.pi / n
        th = np.mod(np.arctan2(loc[:, 1], loc[:, 0]), 2.0 * np.pi)
        mid = (np.floor(th / step) + 0.5) * step  # the edge whose sector holds v
        side = self.radius * math.cos(math.pi / n) - (loc[:, 0] * np.cos(mid) + loc[:, 1] * np.sin(mid))
        return np.minimum(loc[:, 2], side)


def _unit_rows(x):
    return x / np.linalg.norm(x, axis=1, keepdims=True)


def _check_pose_arguments(n, rng, radius, shape_b, gap_range, beta_range, tilt_range, hit_fraction):
    """Validated ``(n, radius, shape_b, (lo, hi), (b0, b1), (t0, t1))`` of :func:`near_contact_poses`."""
    n = check_int(n, "n", 1)
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    radius = check_positive(radius, "radius")
    if shape_b is None:
        shape_b = Prism.regular(B_VERTICES, B_SCALE * radius)
    if not isinstance(shape_b, Prism):
        raise TypeError(f"shape_b must be a prismbatch.Prism, got {type(shape_b).__name__}")
    lo, hi = (float(v) for v in gap_range)
    if not (0.0 < lo <= hi and np.isfinite(hi)):
        raise ValueError(f"gap_range must satisfy 0 < low <= high < inf, got {gap_range}")
    b0, b1 = (float(v) for v in beta_range)
    if not (0.0 < b0 <= b1 < np.pi / 2):
        raise ValueError(f"beta_range must lie inside (0, pi/2) with low <= high, got {beta_range}")
    t0, t1 = (float(v) for v in tilt_range)
    if not (0.0 <= t0 <= t1 < np.pi / 2):
        raise ValueError(f"tilt_range must lie inside [0, pi/2) with low <= high, got {tilt_range}")
    if not (0.0 <= float(hit_fraction) <= 1.0):
        raise ValueError(f"hit_fraction must be in [0, 1], got {hit_fraction}")
    return n, radius, shape_b, (lo, hi), (b0, b1), (t0, t1)


def near_contact_poses(
    n,
    rng,
    *,
    radius=1.0,
    shape_b=None,
    gap_range=GAP_RANGE,
    beta_range=tuple(np.radians(BETA_RANGE_DEG)),
    tilt_range=tuple(np.radians(TILT_RANGE_DEG)),
    hit_fraction=0.5,
):
    """Near-contact poses of a semi-infinite cylinder (a) and a polygonal prism (b), exact labels.

    See ``docs/methods/work-precision.md`` for the construction and why its labels are exact.

    Parameters
    ----------
    n : int
        Number of pose pairs (>= 1).
    rng : numpy.random.Generator
        Source of randomness.
    radius : float, optional
        Cylinder radius r (> 0).
    shape_b : Prism, optional
        b's prism (default: regular hexagon of circumradius ``1.25 radius``).
    gap_range : (float, float), optional
        Range of ``|g| / r``, sampled log-uniformly (0 < low <= high).
    beta_range : (float, float), optional
        Range (rad) of the angle between u and a's outward end-face normal,
        inside (0, pi/2).
    tilt_range : (float, float), optional
        Range (rad) of the angle between b's axis and u, inside [0, pi/2).
    hit_fraction : float, optional
        Probability of ``g < 0`` (a hit).

    Returns
    -------
    NearContactPoses
    """
    n, radius, shape_b, (lo, hi), (b0, b1), (t0, t1) = _check_pose_arguments(
        n, rng, radius, shape_b, gap_range, beta_range, tilt_range, hit_fraction
    )

    rot_a1 = AXIS_DOWN.astype(float)
    pos_a1 = np.zeros(3)
    beta = rng.uniform(b0, b1, n)
    phi = rng.uniform(0.0, 2.0 * np.pi, n)
    mag = radius * np.exp(rng.uniform(math.log(lo), math.log(hi), n))
    hit = rng.uniform(size=n) < float(hit_fraction)
    gap = np.where(hit, -mag, mag)
    # a's local frame: z = d_a (into the body); u has u . d_a = -cos(beta) < 0
    u_loc = np.column_stack([np.sin(beta) * np.cos(phi), np.sin(beta) * np.sin(phi), -np.cos(beta)])
    s_loc = np.column_stack([radius * np.cos(phi), radius * np.sin(phi), np.zeros(n)])
    u = u_loc @ rot_a1.T
    s = pos_a1 + s_loc @ rot_a1.T
    # b's axis at angle tilt from u (so u . d_b > 0: b's lowest point in u is on its end face)
    tilt = rng.uniform(t0, t1, n)
    psi = rng.uniform(0.0, 2.0 * np.pi, n)
    e1 = rotation_with_axis(u, np.zeros(n), exact_axis=True)
    d_b = np.cos(tilt)[:, None] * u + np.sin(tilt)[:, None] * (
        np.cos(psi)[:, None] * e1[:, :, 0] + np.sin(psi)[:, None] * e1[:, :, 1]
    )
    rot_b = rotation_with_axis(_unit_rows(d_b), rng.uniform(0.0, 2.0 * np.pi, n), exact_axis=True)
    xy_b = np.asarray(shape_b.xy)
    heights = np.einsum("nk,nkj->nj", u, rot_b[:, :, :2]) @ xy_b.T  # (N, n_b): u . (R_b [x, y, 0])
    vertex = np.argmin(heights, axis=1)
    v_rel = np.einsum("nij,nj->ni", rot_b[:, :, :2], xy_b[vertex])
    pos_b = s + gap[:, None] * u - v_rel
    pos_a = np.broadcast_to(pos_a1, (n, 3)).copy()
    rot_a = np.broadcast_to(rot_a1, (n, 3, 3)).copy()
    return NearContactPoses(pos_a, rot_a, pos_b, rot_b, gap, beta, u, vertex, hit, radius)
