"""Case-targeted pose generators: poses that prismbatch classifies as a given case.

Random poses almost never produce the degenerate cases (a vertex, an edge or
the whole end face exactly on a's plane, exactly perpendicular axes), yet a
timing study per case and the Monte Carlo ``degenerate`` distribution need
plenty of them. :func:`case_poses` builds them directly.

How the poses are built (orientation, height, lateral placement by bisection, world pose,
verification): ``docs/methods/case-poses.md``.
"""

from __future__ import annotations

import numpy as np

from ..collide import Collider
from ..sampling import AXIS_DOWN, random_rotations, spins_about_z
from ..shapes import Prism

__all__ = ["case_poses", "CASE_NUMBERS", "EXACT_CASES", "HIT_AND_MISS_CASES"]

#: Every case number prismbatch reports (see :data:`prismbatch.CASES`).
CASE_NUMBERS = tuple(range(1, 12))

#: Cases whose definition needs an exact zero (Δ3 = 0 or d_a . d_b = 0).
EXACT_CASES = (2, 3, 4, 7, 8)

#: Cases that admit both hits and misses (1 and 5 never collide).
HIT_AND_MISS_CASES = (2, 3, 4, 6, 7, 8, 9, 10, 11)

# Relative tolerance the generator designs for (prismbatch's float64 default):
# the touching cases must keep b's other vertices clearly below a's plane.
_RTOL = 1e-9
_BISECT_STEPS = 34


class _Polygon:
    """Centred vertices of a prism's end face and what the constructions need."""

    def __init__(self, prism: Prism):
        q = np.asarray(prism.xy, float) - prism.centre  # CCW, about the area centroid
        self.centre = np.asarray(prism.centre, float)
        self.q = q
        self.m = len(q)
        self.radius = float(prism.radius)
        e = np.roll(q, -1, axis=0) - q  # edge i: q[i] -> q[i+1]
        elen = np.hypot(e[:, 0], e[:, 1])
        self.normal = np.column_stack([e[:, 1], -e[:, 0]]) / elen[:, None]  # outward (CCW)
        self.offset = np.einsum("ij,ij->i", self.normal, q)  # > 0: the centroid is interior
        # Vertex i is extreme for the directions between the normals of edges i-1 and i;
        # along their bisector it is the unique top, its neighbours lower by `vdrop`.
        bis = self.normal + np.roll(self.normal, 1, axis=0)
        bis /= np.hypot(bis[:, 0], bis[:, 1])[:, None]
        self.bisector = bis
        self.vdrop = np.minimum(
            np.einsum("ij,ij->i", bis, q - np.roll(q, 1, axis=0)),
            np.einsum("ij,ij->i", bis, q - np.roll(q, -1, axis=0)),
        )
        # Edge i along its normal: both ends on top, the next vertices lower by `edrop`.
        n = self.normal
        self.edrop = np.minimum(
            np.einsum("ij,ij->i", n, q - np.roll(q, 1, axis=0)),
            np.einsum("ij,ij->i", n, np.roll(q, -1, axis=0) - np.roll(q, -2, axis=0)),
        )

    def interior_points(self, k, rng, depth=0.95):
        """``k`` random points strictly inside the centred polygon (area-uniform in each ray)."""
        ang = rng.uniform(0.0, 2.0 * np.pi, k)
        d = np.column_stack([np.cos(ang), np.sin(ang)])
        # Ray from the centroid leaves the polygon at 1 / max_i (n_i . d / h_i).
        inv = np.empty(k)
        step = max(1, 2_000_000 // self.m)
        for s in range(0, k, step):
            inv[s : s + step] = np.max(d[s : s + step] @ (self.normal / self.offset[:, None]).T, axis=1)
        rho = depth * np.sqrt(rng.uniform(0.0, 1.0, k)) / inv
        return d * rho[:, None]

    def heights(self, h):
        """(k, m) heights ``h . q`` of every vertex, as the kernels form them."""
        return h[:, 0:1] * self.q[None, :, 0] + h[:, 1:2] * self.q[None, :, 1]

    def top(self, h):
        """Index and height of the highest vertex along each ``h`` (k, 2)."""
        k = len(h)
        idx = np.empty(k, dtype=np.int64)
        val = np.empty(k)
        step = max(1, 2_000_000 // self.m)
        for s in range(0, k, step):
            z = self.heights(h[s : s + step])
            idx[s : s + step] = np.argmax(z, axis=1)
            val[s : s + step] = z[np.arange(len(z)), idx[s : s + step]]
        return idx, val


def _unit2(k, rng):
    ang = rng.uniform(0.0, 2.0 * np.pi, k)
    return np.column_stack([np.cos(ang), np.sin(ang)])


def _rotation_from_last_row(hx, hy, cz, spin):
    """Rotations R (k, 3, 3) with last row exactly (hx, hy, cz), spun by ``spin`` about z.

    (hx, hy, cz) must be a unit vector. Row 0 is horizontal and perpendicular
    to it, row 1 completes a right-handed frame; the spin rotates rows 0 and 1
    and leaves row 2 untouched, so exact zeros in it survive.
    """
    k = len(hx)
    hn = np.hypot(hx, hy)
    flat = hn == 0.0
    safe = np.where(flat, 1.0, hn)
    r0 = np.column_stack([np.where(flat, 1.0, -hy / safe), np.where(flat, 0.0, hx / safe), np.zeros(k)])
    r2 = np.column_stack([hx, hy, cz])
    r1 = np.cross(r2, r0)
    cs, sn = np.cos(spin)[:, None], np.sin(spin)[:, None]
    R = np.empty((k, 3, 3))
    R[:, 0] = cs * r0 - sn * r1
    R[:, 1] = sn * r0 + cs * r1
    R[:, 2] = r2
    return R


def _axis_aligned_rotations(k, rng):
    """Random rotations that map local z to a signed world coordinate axis exactly.

    ``P @ Rz(phi)`` with P a proper signed permutation: the third column is
    exactly ±e_m and row m of the product with any R is exactly ±R[2].
    """
    perms = np.array([[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]])
    P = np.zeros((k, 3, 3))
    cols = perms[rng.integers(0, 6, k)]
    signs = rng.choice([-1.0, 1.0], size=(k, 3))
    rows = np.arange(k)[:, None]
    P[rows, cols, np.arange(3)[None, :]] = signs
    det = np.linalg.det(P)
    P[:, :, 0] *= np.sign(det)[:, None]  # make it proper; column 2 is untouched
    return P @ spins_about_z(rng.uniform(0.0, 2.0 * np.pi, k))


class _Builder:
    """Draws poses of one case for one pair of shapes (unverified)."""

    def __init__(self, shape_a, shape_b, world_transform):
        self.A = _Polygon(shape_a)
        self.B = _Polygon(shape_b)
        self.col = Collider(shape_a, shape_b)
        self.world_transform = bool(world_transform)
        self.ra, self.rb = self.A.radius, self.B.radius
        self.S = self.ra + self.rb
        # A bound on the pair tolerance over the placements used (|p| <= about 5 S).
        self.tol = _RTOL * 6.0 * self.S

    # --- frame F -> world --------------------------------------------------
    def world(self, G, O, p, R):
        ca = np.append(self.A.centre, 0.0)
        cb = np.append(self.B.centre, 0.0)
        rot_b = G @ R
        pos_a = O - G @ ca
        pos_b = O + np.einsum("kij,kj->ki", G, p - R @ cb)
        return pos_a, G, pos_b, rot_b

    def frame(self, k, rng, exact):
        if not self.world_transform:
            G = np.broadcast_to(AXIS_DOWN, (k, 3, 3)).copy()
            O = np.einsum("kij,j->ki", G, np.append(self.A.centre, 0.0))  # pos_a = 0
            return G, O, True
        G = _axis_aligned_rotations(k, rng) if exact else random_rotations(k, rng)
        O = rng.uniform(-2.0 * self.S, 2.0 * self.S, (k, 3))
        return G, O, False

    def hits(self, G, O, p, R, origin_a_zero):
        pa, ra, pb, rb = self.world(G, O, p, R)
        if origin_a_zero:
            pa = np.zeros_like(pa)
        return self.col.collide(pa, ra, pb, rb, parallel=False)

    # --- orientation ---------------------------------------------------------
    def orient(self, case, k, rng):
        """(R, hhat-choice index) for the case; index is the chosen vertex/edge or -1."""
        B = self.B
        choice = np.full(k, -1)
        spin = rng.uniform(0.0, 2.0 * np.pi, k)
        if case in (2, 3, 7, 8):
            perp = case in (7, 8)
            if perp:
                sin_t = np.ones(k)
                cz = np.zeros(k)
            else:
                th = rng.uniform(0.3, 1.2, k)
                sin_t, cz = np.sin(th), -np.cos(th)
            drop = B.vdrop if case in (2, 7) else B.edrop
            dirs = B.bisector if case in (2, 7) else B.normal
            if case == 8:
                ok = np.arange(B.m)  # two or more vertices on the plane: any edge will do
            else:
                # b's other vertices must stay clearly (4 x a bound on the pair
                # tolerance) below a's plane at the smallest tilt.
                need = 4.0 * self.tol / (1.0 if perp else np.sin(0.3))
                ok = np.flatnonzero(drop >= need)
                if ok.size == 0:
                    what = "vertex" if case in (2, 7) else "edge"
                    raise RuntimeError(
                        f"case_poses: case {case} cannot be constructed for shape_b: no {what} of its "
                        f"{B.m} vertices has its neighbours more than {need:.3g} off the supporting "
                        f"line (largest: {float(drop.max()):.3g}); prismbatch would count them on a's "
                        f"plane too (e.g. collinear vertices)"
                    )
            choice = ok[rng.integers(0, ok.size, k)]
            hh = dirs[choice]
            return _rotation_from_last_row(sin_t * hh[:, 0], sin_t * hh[:, 1], cz, spin), choice
        if case == 4:
            z = np.zeros(k)
            return _rotation_from_last_row(z, z, -np.ones(k), spin), choice
        hh = _unit2(k, rng)
        if case == 1:
            th = rng.uniform(0.0, 0.5 * np.pi, k)
            sin_t, cz = np.sin(th), -np.cos(th)
            perp = rng.random(k) < 0.2  # exactly perpendicular, Δ3 < 0: also case 1
            sin_t[perp], cz[perp] = 1.0, 0.0
        elif case in (5, 6):
            th = rng.uniform(0.0, 1.2, k)
            sin_t, cz = np.sin(th), -np.cos(th)
        elif case == 9:
            sin_t, cz = np.ones(k), np.zeros(k)
        else:  # 10, 11: d_a . d_b > 0
            th = rng.uniform(0.15, 1.4, k)
            sin_t, cz = np.sin(th), np.cos(th)
        return _rotation_from_last_row(sin_t * hh[:, 0], sin_t * hh[:, 1], cz, spin), choice

    # --- one draw ------------------------------------------------------------
    def draw(self, case, want_hit, rng):
        """Unverified poses (world) for the labels ``want_hit``; plus a construction-ok mask."""
        k = len(want_hit)
        A, B, S, rb = self.A, self.B, self.S, self.rb
        R, choice = self.orient(case, k, rng)
        h = R[:, 2, :2]
        top_idx, top_h = B.top(h)
        if case == 1:
            d3 = -rng.uniform(0.02, 1.0, k) * S
        elif case in EXACT_CASES:
            d3 = np.zeros(k)
        elif case == 10:
            d3 = -rng.uniform(0.01, 1.0, k) * rb
        elif case in (5, 6):
            d3 = rng.uniform(0.01, 0.5, k) * rb
        else:  # 9, 11
            d3 = rng.uniform(0.01, 1.0, k) * rb
        pz = d3 - top_h
        exact = case in EXACT_CASES
        G, O, a_at_origin = self.frame(k, rng, exact)
        ok = np.ones(k, dtype=bool)

        if case in (1, 5):
            if case == 1:
                pxy = _unit2(k, rng) * (1.5 * S * np.sqrt(rng.uniform(0.0, 1.0, k)))[:, None]
            else:
                pxy = self._beyond_coarse(R, k, rng)
            p = np.column_stack([pxy, pz])
            return self._out(G, O, p, R, a_at_origin), ok

        # Anchor (b-centred local coordinates u, v, t) inside a's half-space.
        t = np.zeros(k)
        if case in (2, 7):
            uv = B.q[choice]
            if case == 7:
                t = np.where(rng.random(k) < 0.5, 0.0, rng.uniform(0.0, 1.5 * rb, k))
        elif case in (3, 8):
            lam = rng.uniform(0.0, 1.0, k)[:, None]
            uv = B.q[choice] + lam * (B.q[(choice + 1) % B.m] - B.q[choice])
            if case == 8:
                t = np.where(rng.random(k) < 0.5, 0.0, rng.uniform(0.0, 1.5 * rb, k))
        elif case == 4:
            uv = B.interior_points(k, rng)
        else:  # 6, 9, 10, 11: the deepest end-face vertex (and down b's lateral edge)
            uv = B.q[top_idx]
            c = R[:, 2, 2]
            if case == 9:
                t = rng.uniform(0.0, 1.5 * rb, k)
            elif case == 11:
                t = rng.uniform(0.0, rb, k)
            elif case == 10:
                t = (rng.uniform(0.0, 0.2, k) * rb - d3) / c
        off = np.einsum("kij,kj->ki", R, np.column_stack([uv, t]))
        ok &= pz + off[:, 2] >= -1e-12 * S  # the anchor lies in a's half-space
        target = A.interior_points(k, rng, depth=0.9)
        base = np.column_stack([target - off[:, :2], pz])

        # Miss direction: lateral, not against b's projected axis.
        u = _unit2(k, rng)
        w = R[:, :2, 2]
        u *= np.where(np.einsum("ij,ij->i", u, w) < 0.0, -1.0, 1.0)[:, None]
        L = 2.0 * self.ra + rb + np.hypot(off[:, 0], off[:, 1]) + 0.2 * S
        step = np.column_stack([u * L[:, None], np.zeros(k)])

        lo, hi = np.zeros(k), np.ones(k)
        ok &= self.hits(G, O, base, R, a_at_origin).hit
        ok &= ~self.hits(G, O, base + step, R, a_at_origin).hit
        for _ in range(_BISECT_STEPS):
            mid = 0.5 * (lo + hi)
            hm = self.hits(G, O, base + mid[:, None] * step, R, a_at_origin).hit
            lo = np.where(hm, mid, lo)
            hi = np.where(hm, hi, mid)
        # Hits before the boundary, misses after it (mostly near misses).
        s_hit = lo * rng.uniform(0.0, 0.98, k)
        s_miss = hi + (1.0 - hi) * (0.01 + 0.99 * rng.uniform(0.0, 1.0, k) ** 2)
        s = np.where(want_hit, s_hit, s_miss)
        p = base + s[:, None] * step
        return self._out(G, O, p, R, a_at_origin), ok

    def _beyond_coarse(self, R, k, rng):
        """Centres of b beyond the coarse test Δ4 (case 5): along > S or |cross| > S.

        ``along`` and ``cross`` are the components of b's centre along b's
        projected axis and across it; the coarse test rejects either.
        """
        S = self.S
        w = R[:, :2, 2]
        wn = np.hypot(w[:, 0], w[:, 1])
        flat = wn == 0.0
        safe = np.where(flat, 1.0, wn)
        ux = np.where(flat, 1.0, w[:, 0] / safe)
        uy = np.where(flat, 0.0, w[:, 1] / safe)
        ahead = rng.random(k) < 0.5
        along = np.where(ahead, rng.uniform(1.1, 3.0, k), rng.uniform(-3.0, 3.0, k)) * S
        cross = np.where(ahead, rng.uniform(-2.0, 2.0, k), rng.choice([-1.0, 1.0], k) * rng.uniform(1.1, 3.0, k)) * S
        return np.column_stack([along * ux - cross * uy, along * uy + cross * ux])

    def _out(self, G, O, p, R, a_at_origin):
        pa, ra, pb, rb = self.world(G, O, p, R)
        if a_at_origin:
            pa = np.zeros_like(pa)
        return pa, ra, pb, rb


def case_poses(case, n, shape_a, shape_b, rng=None, *, hit_fraction=0.5, world_transform=False, max_rounds=40):
    """Pose pairs that prismbatch classifies as a given case.

    Parameters
    ----------
    case : int
        Case number, 1 to 11 (see :data:`prismbatch.CASES`).
    n : int
        Number of pose pairs.
    shape_a, shape_b : Prism
        The two prisms (any convex polygons; the local origin need not lie
        inside them).
    rng : numpy.random.Generator or int or None
        Random source (an int seeds a new generator); the output is
        reproducible for a given seed.
    hit_fraction : float, optional
        Fraction of the pairs that collide (``round(n * hit_fraction)`` of
        them exactly, in random order). Ignored for cases 1 and 5, which never
        collide. Misses are mostly near misses (just beyond contact).
    world_transform : bool, optional
        False (default): the paper's scene, a at the origin with its axis
        down (``pos_a = 0``, ``rot_a = diag(1, -1, -1)``). True: a random
        rigid transform of the whole scene, so a's pose varies too. For the
        cases that need exact zeros (2, 3, 4, 7, 8) a's axis is then still a
        signed world coordinate axis (a signed permutation after a spin about
        the axis), which keeps b's heights along a's axis, and d_a . d_b for 7
        and 8, exact in floating point; other cases get a uniform rotation.
    max_rounds : int, optional
        Poses that fail verification are drawn again up to this many times.

    Returns
    -------
    pos_a : numpy.ndarray, shape (n, 3)
    rot_a : numpy.ndarray, shape (n, 3, 3)
    pos_b : numpy.ndarray, shape (n, 3)
    rot_b : numpy.ndarray, shape (n, 3, 3)
        Float64 poses (rotation columns are the local axes in world
        coordinates), every one verified with :func:`prismbatch.collide`
        (default tolerance) to have the requested case and hit status.

    Raises
    ------
    ValueError
        Unknown case, negative ``n`` or ``hit_fraction`` outside [0, 1].
    TypeError
        Shapes that are not :class:`~prismbatch.Prism`.
    RuntimeError
        A construction kept failing verification after ``max_rounds`` draws.

    Notes
    -----
    Constructions, in a's frame (z along d_a, into a):

    * 1: b's end face beyond a's plane (Δ3 < 0), b's axis at 0-90 degrees
      from -d_a (20% exactly perpendicular).
    * 2 / 3: facing axes tilted 0.3-1.2 rad, about an axis making one vertex
      (the bisector of its normal cone) or one edge (tilt axis parallel to
      it) the lowest; it is put exactly on a's plane. Vertices whose
      neighbours would lie within the tolerance band are not chosen.
    * 4: d_b = -d_a exactly, end face on a's plane.
    * 5: facing, Δ3 > 0, centre beyond the coarse test's reach.
    * 6: facing (tilt 0-1.2 rad), Δ3 > 0, hits and near misses.
    * 7 / 8 / 9: d_a . d_b = 0 exactly; a vertex / an edge on a's plane, or
      Δ3 > 0.
    * 10: d_a . d_b > 0 (tilt 0.15-1.4 rad), Δ3 < 0, b's lateral edge coming
      back through a's plane; 11: d_a . d_b > 0, Δ3 > 0.

    Examples
    --------
    >>> import prismbatch as pb
    >>> from prismbatch.lab.casegen import case_poses
    >>> a, b = pb.Prism.regular(5, 2.0), pb.Prism.regular(6, 2.5)
    >>> poses = case_poses(7, 100, a, b, 0)
    >>> r = pb.collide(a, b, *poses)
    >>> sorted(set(r.case.tolist())), int(r.hit.sum())
    ([7], 50)
    """
    if isinstance(case, (bool, np.bool_)) or int(case) != case or int(case) not in CASE_NUMBERS:
        raise ValueError(f"case must be one of {CASE_NUMBERS}, got {case!r}")
    case = int(case)
    n = int(n)
    if n < 0:
        raise ValueError(f"n must be >= 0, got {n}")
    hit_fraction = float(hit_fraction)
    if not 0.0 <= hit_fraction <= 1.0:
        raise ValueError(f"hit_fraction must be in [0, 1], got {hit_fraction}")
    for nm, s in (("shape_a", shape_a), ("shape_b", shape_b)):
        if not isinstance(s, Prism):
            raise TypeError(f"{nm} must be a prismbatch.Prism, got {type(s).__name__}")
    rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)

    want = np.zeros(n, dtype=bool)
    if case in HIT_AND_MISS_CASES:
        want[: int(round(n * hit_fraction))] = True
        want = rng.permutation(want)
    out = (np.empty((n, 3)), np.empty((n, 3, 3)), np.empty((n, 3)), np.empty((n, 3, 3)))
    if n == 0:
        return out
    builder = _Builder(shape_a, shape_b, world_transform)
    todo = np.arange(n)
    got_case = got_hit = None
    for _ in range(max_rounds):
        poses, ok = builder.draw(case, want[todo], rng)
        r = builder.col.collide(*poses, parallel=False)
        good = ok & (r.case == case) & (r.hit == want[todo])
        for dst, src in zip(out, poses):
            dst[todo[good]] = src[good]
        got_case, got_hit = r.case[~good], r.hit[~good]
        todo = todo[~good]
        if todo.size == 0:
            return out
    vals, cnt = np.unique(got_case, return_counts=True)
    raise RuntimeError(
        f"case_poses: could not construct {todo.size} of {n} poses of case {case} "
        f"({'hit' if want[todo[0]] else 'miss'} requested for the first) after {max_rounds} rounds; "
        f"the last draw gave cases {dict(zip(vals.tolist(), cnt.tolist()))} and "
        f"{int(got_hit.sum())} hits (shapes with {builder.A.m} and {builder.B.m} vertices)"
    )
