"""Penetration depth of two prisms whose axes are exactly parallel and point the same way.

Then B = (p_xy + M P_b) x [p_z, inf) in a's centred frame (M the in-plane part of b's relative
rotation), A = P_a x [0, inf), and the two overlap along the axis from max(0, p_z) on whatever
their cross-sections do: no translation along the axis separates them, and the signed distance is
that of the two convex polygons. Its depth is exact by the separating-axis theorem in the plane:
the smallest overlap ``h_A(n) + h_B(-n)`` over the outward edge normals n of both polygons, each
support an extreme-vertex search (O(1) to O(log n)).

GJK and EPA in 3-D see D as a prism cut by the box of C_L (see :mod:`.distance`); on deep overlaps of
fine polygons EPA's polytope can run out of room or stop on rounding, giving only an upper bound (up
to 1e8 tol too deep on 3600-gons). :func:`~prismbatch._kernels.distance.pair_distance` comes here
for those pairs. O(n_a + n_b) supports: about 120 microseconds a pair for two 3600-gons, 2 for 36-gons.
"""

import math

from .batch import frame_inverse, relative_pose
from .jit import jit
from .planar import extreme_vertex


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
    px, py, pz, m00, m01, m10, m11, _, _ = relative_pose(frame_inverse(Ra), dx, dy, dz, Rb)
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
    gx = Ra[0, 0] * nx + Ra[0, 1] * ny
    gy = Ra[1, 0] * nx + Ra[1, 1] * ny
    gz = Ra[2, 0] * nx + Ra[2, 1] * ny
    gn = math.sqrt(gx * gx + gy * gy + gz * gz)
    point = (
        ox + Ra[0, 0] * qx + Ra[0, 1] * qy + Ra[0, 2] * z,
        oy + Ra[1, 0] * qx + Ra[1, 1] * qy + Ra[1, 2] * z,
        oz + Ra[2, 0] * qx + Ra[2, 1] * qy + Ra[2, 2] * z,
    )
    return best, (gx / gn, gy / gn, gz / gn), point
