"""Exact constructions of the stiff suite: pose pairs with a known signed gap.

Each construction places b against a so that a known plane separates them and
two witness points lie at the constructed distance (negative: an overlap by
construction). See docs/methods/stiff-suite.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .geometry import R_DOWN, axis_rotation, ccw, centre_radius, down_rotation, outward_normals, pair_scale, push, rot_z


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
    return PairSet(list(A), list(B), np.array(pa), np.array(Ra), np.array(pb_), np.array(Rb), np.array(g, float), lp)


def concat(*parts):
    """One :class:`PairSet` of all the pairs of ``parts``, in order."""
    c = lambda k: np.concatenate([getattr(p, k) for p in parts])  # noqa: E731
    return PairSet(
        sum((p.polys_a for p in parts), []),
        sum((p.polys_b for p in parts), []),
        c("pos_a"),
        c("rot_a"),
        c("pos_b"),
        c("rot_b"),
        c("gap"),
        parts[0].lp,
    )


def _a_pose(rng, A, scale):
    Ra = down_rotation(rng)
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
        nrm = outward_normals(Aw)
        n2 = nrm[i - 1] + nrm[i]
        n2 /= np.hypot(*n2)
        n3 = np.array([n2[0], n2[1], 0.0])
        Rb = axis_rotation(np.cross(n3, [0.0, 0.0, 1.0]), tilt) @ rot_z(rng.uniform(0, 2 * np.pi)) @ R_DOWN
        Wb = B @ Rb[:, :2].T
        k = int(np.argmin(Wb[:, :2] @ n2))
        depth = 0.0 if j % 4 == 0 else rng.uniform(0, 1) * np.max(np.hypot(*(A - A.mean(0)).T))
        pb0 = np.array([Aw[i, 0], Aw[i, 1], pa[2] - depth]) - Wb[k]
        pb_ = pb0 + push(s * pair_scale(A, pa, Ra, B, pb0, Rb), Aw, Aw[i], n2) * n3
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
        Ra = down_rotation(rng)
        z0 = rng.uniform(0.5, 2.0) * scale
        pa = np.array([*(rng.uniform(-2, 2, 2) * scale), z0])
        Aw = pa[:2] + A @ Ra[:2, :2].T
        nrm = outward_normals(Aw)
        i = int(rng.integers(len(Aw)))
        if j % 2 == 0:  # vertex contact
            m = Aw[i]
            n2 = nrm[i - 1] + nrm[i]
        else:  # edge contact
            m = 0.5 * (Aw[i] + Aw[(i + 1) % len(Aw)])
            n2 = nrm[i].copy()
        n2 /= np.hypot(*n2)
        S = 2 * centre_radius(A)[1] + 2 * float(np.hypot(*(m - Aw.mean(axis=0))))  # nominal; B mirrors A
        Bw = 2.0 * m - Aw + push(s * S, Aw, m, n2) * n2
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
        rows.append((A, ccw(B), pa, Ra, pb_, Rb, gap))
    return _stack(rows)
