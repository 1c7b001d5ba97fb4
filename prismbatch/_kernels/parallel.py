"""Penetration depth of two prisms whose axes are parallel or nearly so and point the same way.

Exactly parallel (:func:`parallel_overlap`): B = (p_xy + M P_b) x [p_z, inf) in a's centred frame (M the
in-plane part of b's relative rotation), A = P_a x [0, inf), and the two overlap along the axis from
max(0, p_z) on whatever their cross-sections do: no translation along the axis separates them, and the
signed distance is that of the two convex polygons. Its depth is exact by the separating-axis theorem in
the plane: the smallest overlap ``h_A(n) + h_B(-n)`` over the outward edge normals n of both polygons,
each support an extreme-vertex search (O(1) to O(log n)).

Nearly parallel (:func:`tilted_overlap`): the separating-axis theorem in 3-D over the candidate facet
normals of D = A - B that have finite supports, which lie in a thin slab about a's end-face plane.

GJK and EPA in 3-D see D as a prism cut by the box of C_L (see :mod:`.distance`); on deep overlaps of
fine polygons EPA's polytope can run out of room or stop on rounding, giving only an upper bound (up
to 1e8 tol too deep on 3600-gons). :func:`~prismbatch._kernels.distance.pair_distance` comes here
for those pairs. O(n_a + n_b) supports: about 120 microseconds a pair for two 3600-gons, 2 for 36-gons,
exactly parallel; nearly parallel, the whole query takes about 1 ms for two 3600-gons.
"""

import math

from .batch import frame_inverse, relative_pose
from .checks import orthonormality_error
from .jit import jit
from .planar import extreme_vertex, segment_closest

#: The planar and separating-axis answers here are lengths in a's frame: they are taken only where both
#: rotations are orthonormal to within this fraction of tol / S (:func:`frames_rigid`).
RIGID_SHARE = 0.1


@jit(inline="always")
def frames_rigid(Ra, Rb, S, tol):
    """Whether lengths in a's frame are world lengths to within ``RIGID_SHARE * tol`` over the scale S:
    the largest entry of R^T R - I of either rotation times S is at most that. A rotation is used as the
    exact affine map it is; a float32 matrix given to the float64 path is orthonormal only to about 1e-7,
    and the planar gap of identical such rotations was then up to 13 tol off (GJK and EPA, in world
    coordinates, take those pairs). (Two calls, not a loop over (Ra, Rb): time_of_impact passes a's
    pose in the input's dtype and b's in float64.)"""
    return max(orthonormality_error(Ra), orthonormality_error(Rb)) * S <= RIGID_SHARE * tol


@jit(inline="always")
def normal_to_world(inv, ux, uy, uz):
    """A normal (ux, uy, uz) of a's frame in world axes: through the transpose of ``inv``, a's exact
    inverse (:func:`~.batch.frame_inverse`), as a normal must go (points go through Ra = inv^-1). The
    two differ by Ra's departure from orthonormality, which the input checks allow up to 1e-9."""
    return (
        inv[0] * ux + inv[3] * uy + inv[6] * uz,
        inv[1] * ux + inv[4] * uy + inv[7] * uz,
        inv[2] * ux + inv[5] * uy + inv[8] * uz,
    )


@jit(error_model="numpy")
def parallel_overlap(P, ix, Ra, Rb, ox, oy, oz, dx, dy, dz):
    """``(depth, normal, point_a)`` in world coordinates for exactly parallel, same-way axes.

    ``P``, ``ix``: the polygon arrays and ranges of :func:`~prismbatch._kernels.minkowski.support`;
    (ox, oy, oz): a's end-face centre, (dx, dy, dz) = c_b - c_a (:func:`~.batch.centres_world`).
    ``normal`` (unit) points from a to b; ``point_a`` lies on a's boundary and
    ``point_a - depth * normal`` on b's.
    """
    avx, avy, aeang, aetab, bvx, bvy, beang, betab = P
    sa, na, sb, nb = ix
    # b's centre and the in-plane rotation M in a's centred frame
    inv = frame_inverse(Ra)
    px, py, pz, m00, m01, m10, m11, _, _ = relative_pose(inv, dx, dy, dz, Rb)
    # The minimum's axis n (from a to b), the touching point r on the line of the edge it comes from (b's
    # deepest vertex projected onto a's edge, or a's deepest onto b's) and that edge (start s, vector e).
    best, nx, ny, rx, ry, sx, sy, ex, ey, on_b = math.inf, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, False
    for k in range(na):  # a's outward edge normals u: b's deepest vertex against the edge's line
        k1 = k + 1 if k + 1 < na else 0
        fx, fy = avx[sa + k1] - avx[sa + k], avy[sa + k1] - avy[sa + k]
        ln = math.sqrt(fx * fx + fy * fy)
        if ln == 0.0:
            continue
        ux, uy = fy / ln, -fx / ln
        j = sb + extreme_vertex(bvx, bvy, beang, betab, sb, nb, -(m00 * ux + m10 * uy), -(m01 * ux + m11 * uy))
        bx = px + m00 * bvx[j] + m01 * bvy[j]
        by = py + m10 * bvx[j] + m11 * bvy[j]
        ov = ux * (avx[sa + k] - bx) + uy * (avy[sa + k] - by)
        if ov < best:
            best, nx, ny, rx, ry = ov, ux, uy, bx + ov * ux, by + ov * uy
            sx, sy, ex, ey, on_b = avx[sa + k], avy[sa + k], fx, fy, False
    for k in range(nb):  # b's outward edge normals w (n = -w): a's deepest vertex against the edge's line
        k1 = k + 1 if k + 1 < nb else 0
        fx, fy = bvx[sb + k1] - bvx[sb + k], bvy[sb + k1] - bvy[sb + k]
        gx, gy = m00 * fx + m01 * fy, m10 * fx + m11 * fy
        ln = math.sqrt(gx * gx + gy * gy)
        if ln == 0.0:
            continue
        wx, wy = gy / ln, -gx / ln
        i = sa + extreme_vertex(avx, avy, aeang, aetab, sa, na, -wx, -wy)
        vx = px + m00 * bvx[sb + k] + m01 * bvy[sb + k]
        vy = py + m10 * bvx[sb + k] + m11 * bvy[sb + k]
        ov = wx * (vx - avx[i]) + wy * (vy - avy[i])
        if ov < best:
            best, nx, ny, rx, ry = ov, -wx, -wy, avx[i] + ov * wx, avy[i] + ov * wy
            sx, sy, ex, ey, on_b = vx, vy, gx, gy, True
    # Where the deepest feature is an edge parallel to the line, r may lie past the end of the line's
    # edge; the bodies, once moved apart by the depth, touch on that edge: the nearest point of it.
    ee = ex * ex + ey * ey
    t = min(max(((rx - sx) * ex + (ry - sy) * ey) / ee, 0.0), 1.0) if ee > 0.0 else 0.0
    qx, qy = sx + t * ex, sy + t * ey
    if on_b:  # the point of b's edge; a's point lies the depth behind it
        qx, qy = qx + best * nx, qy + best * ny
    z = max(0.0, pz)  # both bodies hold every height from here on
    gx, gy, gz = normal_to_world(inv, nx, ny, 0.0)
    gn = math.sqrt(gx * gx + gy * gy + gz * gz)
    point = (
        ox + Ra[0, 0] * qx + Ra[0, 1] * qy + Ra[0, 2] * z,
        oy + Ra[1, 0] * qx + Ra[1, 1] * qy + Ra[1, 2] * z,
        oz + Ra[2, 0] * qx + Ra[2, 1] * qy + Ra[2, 2] * z,
    )
    return best, (gx / gn, gy / gn, gz / gn), point


#: Most iterations of :func:`parallel_gap` (each adds a support of the end faces' difference).
PLANAR_GAP_MAX_ITER = 256


@jit(inline="always")
def _planar_support(P, ix, rel, ux, uy):
    """The end faces' difference A - B' (B' = b's end face in a's plane) in the direction u: ``(wx, wy,
    ax, ay, i, j)``, w = a - b' from a's vertex i furthest along u and b's vertex j furthest along -u."""
    avx, avy, aeang, aetab, bvx, bvy, beang, betab = P
    sa, na, sb, nb = ix
    px, py, _, m00, m01, m10, m11, _, _ = rel
    i = sa + extreme_vertex(avx, avy, aeang, aetab, sa, na, ux, uy)
    j = sb + extreme_vertex(bvx, bvy, beang, betab, sb, nb, -(m00 * ux + m10 * uy), -(m01 * ux + m11 * uy))
    bx = px + m00 * bvx[j] + m01 * bvy[j]
    by = py + m10 * bvx[j] + m11 * bvy[j]
    return avx[i] - bx, avy[i] - by, avx[i], avy[i], i, j


@jit(error_model="numpy")
def parallel_gap(P, ix, Ra, Rb, ox, oy, oz, dx, dy, dz, acc, s):
    """``(lower, gap, normal, point_a)`` in world coordinates for exactly parallel axes, pointing the same
    way (``s`` = 1) or opposite ways (``s`` = -1).

    In a's centred frame A = P_a x [0, inf) and B = B' x [p_z, inf) (s = 1) or B' x (-inf, p_z] (s = -1),
    B' = b's end face in a's plane; sets that are products so are apart by the planar distance of P_a and
    B' and the distance of the two intervals (0, or -p_z when the end faces face each other apart) in
    quadrature. The planar distance: 2-D GJK on the end faces' difference, O(log n) supports a step,
    until within ``acc`` of its lower bound ``lower`` (> 0 proves the end faces apart in the plane; <= 0:
    they touch or overlap there and ``gap`` means nothing). In 3-D, GJK on the difference cut by a box
    (:mod:`.distance`) stalled on such pairs, 1 to 3 tol off (a polygon 3e5 times the other's size; two
    1e-5 polygons 12 apart along facing axes, a thin needle of a difference). ``normal`` (unit) points
    from a to b, ``point_a`` lies on a's boundary, point_a + gap normal on b's.
    """
    inv = frame_inverse(Ra)
    rel = relative_pose(inv, dx, dy, dz, Rb)
    px, py, pz = rel[0], rel[1], rel[2]
    ux, uy = (-px, -py) if px != 0.0 or py != 0.0 else (1.0, 0.0)
    # the simplex: one point (k = 1) or a segment (k = 2) of the difference, with a's points behind them
    w0x, w0y, a0x, a0y, i0, j0 = _planar_support(P, ix, rel, ux, uy)
    w1x, w1y, a1x, a1y, i1, j1 = w0x, w0y, a0x, a0y, i0, j0
    k, t = 1, 0.0
    vx, vy = w0x, w0y
    lower = -math.inf
    for _ in range(PLANAR_GAP_MAX_ITER):
        vn = math.sqrt(vx * vx + vy * vy)
        if vn == 0.0:
            break
        wx, wy, ax, ay, i, j = _planar_support(P, ix, rel, -vx, -vy)
        lower = max(lower, (vx * wx + vy * wy) / vn)
        if vn - lower <= acc or (i == i0 and j == j0) or (k == 2 and i == i1 and j == j1):
            break  # converged, or no new point (rounding): |v| is then within vn - lower of the gap
        if k == 1:
            w1x, w1y, a1x, a1y, i1, j1 = wx, wy, ax, ay, i, j
            k = 2
        else:
            c0 = w0x * w1y - w0y * w1x  # o inside the triangle w0 w1 w: the end faces overlap (lower <= 0)
            c1 = w1x * wy - w1y * wx
            c2 = wx * w0y - wy * w0x
            if (c0 >= 0.0 and c1 >= 0.0 and c2 >= 0.0) or (c0 <= 0.0 and c1 <= 0.0 and c2 <= 0.0):
                lower = min(lower, 0.0)
                break
            # o outside: its nearest point lies on an edge through w, from whichever old point is nearer
            d0x, d0y, _ = segment_closest(w0x, w0y, wx, wy)
            d1x, d1y, _ = segment_closest(w1x, w1y, wx, wy)
            if d1x * d1x + d1y * d1y < d0x * d0x + d0y * d0y:
                w0x, w0y, a0x, a0y, i0, j0 = w1x, w1y, a1x, a1y, i1, j1
            w1x, w1y, a1x, a1y, i1, j1 = wx, wy, ax, ay, i, j
        vx, vy, t = segment_closest(w0x, w0y, w1x, w1y) if k == 2 else (w0x, w0y, 0.0)
    # heights: both hold every z >= max(0, p_z) (s = 1), or [0, p_z]; facing end faces apart: a's at 0, b's at p_z
    z, rise = (max(0.0, pz), 0.0) if s > 0.0 else (0.0, min(0.0, pz))
    gap = math.sqrt(vx * vx + vy * vy + rise * rise)
    if rise < 0.0 and lower > 0.0:
        lower = math.sqrt(lower * lower + rise * rise)
    qx, qy = a0x + t * (a1x - a0x), a0y + t * (a1y - a0y)  # a's point of the closest pair
    nx, ny, nz = (-vx / gap, -vy / gap, rise / gap) if gap > 0.0 else (1.0, 0.0, 0.0)  # v = a - b': a to b is -v
    gx, gy, gz = normal_to_world(inv, nx, ny, nz)
    gn = math.sqrt(gx * gx + gy * gy + gz * gz)
    point = (
        ox + Ra[0, 0] * qx + Ra[0, 1] * qy + Ra[0, 2] * z,
        oy + Ra[1, 0] * qx + Ra[1, 1] * qy + Ra[1, 2] * z,
        oz + Ra[2, 0] * qx + Ra[2, 1] * qy + Ra[2, 2] * z,
    )
    return lower, gap, (gx / gn, gy / gn, gz / gn), point


# --- nearly parallel axes: the separating-axis theorem in 3-D -------------------------------------


@jit(inline="always")
def _separation(P, ix, rel, ux, uy, uz):
    """``min_B u.y - max_A u.x`` along the unit u (a's centred frame), from the end faces alone: their
    supports carry the bodies' wherever u.d_a <= 0 <= u.d_b. ``rel``: :func:`~.batch.relative_pose`."""
    avx, avy, aeang, aetab, bvx, bvy, beang, betab = P
    sa, na, sb, nb = ix
    px, py, pz, m00, m01, m10, m11, r20, r21 = rel
    i = sa + extreme_vertex(avx, avy, aeang, aetab, sa, na, ux, uy)
    wx, wy = ux * m00 + uy * m10 + uz * r20, ux * m01 + uy * m11 + uz * r21  # u in b's end-face plane
    j = sb + extreme_vertex(bvx, bvy, beang, betab, sb, nb, -wx, -wy)
    return ux * px + uy * py + uz * pz + wx * bvx[j] + wy * bvy[j] - (ux * avx[i] + uy * avy[i])


#: How a candidate axis u must pass as having finite supports (u.d_a <= 0 <= u.d_b): in general; across
#: an axis by construction (u.d_a = 0 or u.d_b = 0), then by the sign of u.e alone; across both (always).
GENERAL, ACROSS, ACROSS_BOTH = 0, 1, 2
#: |d_b - d_a|^2 above which (tilts beyond about 13 degrees) every pair of end edges is a candidate.
WIDE = 0.05


@jit(inline="always")
def _better(P, ix, rel, ex, ey, ez, ux, uy, uz, test, best):
    """``best`` (value, ux, uy, uz) or the separation along u (normalised here) if that is larger and u
    has finite supports. With d_a = z and d_b = z + e (e formed exactly, so that a tilt of 1e-13
    decides a sign where u.d_b itself is rounding) the test is u_z <= 0 <= u_z + u.e; for u across
    one axis by construction (``test`` ACROSS) either condition reduces to u.e >= 0. A zero u changes
    nothing."""
    n = math.sqrt(ux * ux + uy * uy + uz * uz)
    if not n > 0.0:
        return best
    ux, uy, uz = ux / n, uy / n, uz / n
    ue = ux * ex + uy * ey + uz * ez
    if test == GENERAL and (uz > 0.0 or uz + ue < 0.0) or test == ACROSS and ue < 0.0:
        return best
    v = _separation(P, ix, rel, ux, uy, uz)
    return (v, ux, uy, uz) if v > best[0] else best


@jit(error_model="numpy")
def tilted_overlap(P, ix, Ra, Rb, dx, dy, dz, ex, ey, ez):
    """``(separation, normal)`` of nearly parallel axes pointing the same way (d_a . d_b > 0): the
    largest separation over every candidate facet normal of D = A - B with finite supports, so minus
    the penetration depth when the bodies overlap; ``normal`` (unit, world) points from a to b.

    ``(dx, dy, dz)`` = c_b - c_a and ``(ex, ey, ez)`` = d_b - d_a, formed exactly, in world axes.
    The candidates, in a's centred frame (d_a = z): a's side normals; minus b's; a's end edges
    across d_b; d_a across b's end edges; d_a across d_b; and a's end edges across b's where the
    two can meet on the Gauss sphere. Finite supports confine u to the slab u.d_a <= 0 <= u.d_b,
    within |e| of a's end-face plane; there an end edge of a and one of b (outward normals n_a,
    n_b in their planes) meet only if n_a and -n_b, seen in a's plane, are nearly opposite: the sine
    of the angle is at most about tan^2 of the tilt (about |e|^2: both arcs rise by at most |e| from
    their equators), so each of a's edges is paired with b's edges within a window of 8 |e|^2 + 1e-6,
    found by one extreme-vertex search and a scan: O((n_a + n_b) log n) supports. Beyond
    |e|^2 = WIDE every pair is tried (O(n_a n_b): 0.1-0.3 s for two 3600-gons): EPA's first room ran out
    there on deep overlaps of 3600-gons, so beyond :data:`~.distance.SAT_FIRST` EPA gets its larger
    rooms first (polygons with more than :data:`~.distance.SAT_SMALL` pairs of edges) and this scan
    comes only where the largest runs out.
    """
    avx, avy = P[0], P[1]
    bvx, bvy = P[4], P[5]
    sa, na, sb, nb = ix
    inv = frame_inverse(Ra)
    rel = relative_pose(inv, dx, dy, dz, Rb)
    _, _, _, m00, m01, m10, m11, r20, r21 = rel
    fx = inv[0] * ex + inv[1] * ey + inv[2] * ez
    fy = inv[3] * ex + inv[4] * ey + inv[5] * ez
    fz = inv[6] * ex + inv[7] * ey + inv[8] * ez
    bz = 1.0 + fz  # d_b = (fx, fy, bz)
    ee = fx * fx + fy * fy + fz * fz
    window = 8.0 * ee + 1e-6  # sine of the angle between n_a and -n_b: generous (extra axes only cost)
    wide = ee > WIDE  # the window's bound needs |e| small: beyond, every pair of end edges
    best = (-math.inf, 0.0, 0.0, 1.0)
    best = _better(P, ix, rel, fx, fy, fz, -fy, fx, 0.0, ACROSS_BOTH, best)  # d_a x d_b, both ways
    best = _better(P, ix, rel, fx, fy, fz, fy, -fx, 0.0, ACROSS_BOTH, best)
    for k in range(na):
        k1 = k + 1 if k + 1 < na else 0
        gx, gy = avx[sa + k1] - avx[sa + k], avy[sa + k1] - avy[sa + k]
        gn = math.sqrt(gx * gx + gy * gy)
        best = _better(P, ix, rel, fx, fy, fz, gy, -gx, 0.0, ACROSS, best)  # a's side normal
        cx, cy, cz = gy * bz, -gx * bz, gx * fy - gy * fx  # a's edge x d_b
        best = _better(P, ix, rel, fx, fy, fz, cx, cy, cz, ACROSS, best)
        best = _better(P, ix, rel, fx, fy, fz, -cx, -cy, -cz, ACROSS, best)
        # b's edges of nearly opposite direction, from b's local normal direction M^T (-n_a): an
        # edge h of b maps to q = M h, whose in-plane normal J M h is parallel to -n_a iff J h is to
        # M^T (-n_a) (J the quarter turn; J M^-1 J^-1 = M^T / det M)
        vx, vy = m10 * gx - m00 * gy, m11 * gx - m01 * gy
        j0 = extreme_vertex(P[4], P[5], P[6], P[7], sb, nb, vx, vy)
        for step in (-1, 1):
            j = j0 - 1 if step < 0 else j0
            for _ in range(nb if step > 0 or not wide else 0):
                j = j % nb
                j1 = j + 1 if j + 1 < nb else 0
                hx, hy = bvx[sb + j1] - bvx[sb + j], bvy[sb + j1] - bvy[sb + j]
                qx, qy, qz = m00 * hx + m01 * hy, m10 * hx + m11 * hy, r20 * hx + r21 * hy  # in a's frame
                # q's in-plane normal (qy, -qx) against -n_a = (-gy, gx): opposite within the window
                qn = math.sqrt(qx * qx + qy * qy)
                if not (qn > 0.0 and gn > 0.0):
                    j += step
                    continue
                if not wide and (-(qy * gy + qx * gx) <= 0.0 or abs(qy * gx - qx * gy) > window * qn * gn):
                    break
                cx, cy, cz = gy * qz, -gx * qz, gx * qy - gy * qx  # a's edge x b's edge
                best = _better(P, ix, rel, fx, fy, fz, cx, cy, cz, GENERAL, best)
                best = _better(P, ix, rel, fx, fy, fz, -cx, -cy, -cz, GENERAL, best)
                j += step
    for k in range(nb):
        k1 = k + 1 if k + 1 < nb else 0
        hx, hy = bvx[sb + k1] - bvx[sb + k], bvy[sb + k1] - bvy[sb + k]
        qx, qy, qz = m00 * hx + m01 * hy, m10 * hx + m11 * hy, r20 * hx + r21 * hy
        # minus b's side normal: -(q x d_b)
        best = _better(
            P, ix, rel, fx, fy, fz, -(qy * bz - qz * fy), -(qz * fx - qx * bz), -(qx * fy - qy * fx), ACROSS, best
        )
        best = _better(P, ix, rel, fx, fy, fz, -qy, qx, 0.0, ACROSS, best)  # d_a x b's edge, both ways
        best = _better(P, ix, rel, fx, fy, fz, qy, -qx, 0.0, ACROSS, best)
    v, ux, uy, uz = best
    nx, ny, nz = normal_to_world(inv, ux, uy, uz)
    nn = math.sqrt(nx * nx + ny * ny + nz * nz)
    return v, (nx / nn, ny / nn, nz / nn)
