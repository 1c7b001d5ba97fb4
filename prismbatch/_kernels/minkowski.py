"""The support function of D_L = K + C_L, the cut Minkowski difference of two semi-infinite prisms.

See :mod:`prismbatch._kernels.distance` for D = A - B = K + C and the cut C_L = C ∩ box. A support
point of K costs two extreme-vertex searches (O(1) to O(log n),
:func:`~prismbatch._kernels.planar.extreme_vertex`); C_L has at most five corners.
"""

import math

import numpy as np

from .jit import jit
from .planar import extreme_vertex


@jit
def cone_box(dax, day, daz, ex, ey, ez, s, L):
    """C_L = cone(d_a, -d_b) ∩ box, as a 22-tuple: ŝ (3), ẑ (3), vertex count, then (s, z, a) per vertex.

    ``d_b = e + s d_a`` with ``s = +-1`` the sign of d_a.d_b; the caller forms
    ``e`` as an exact difference, so nearly (anti)parallel axes keep the
    direction of their tilt and identical ones give e = 0. A vertex is the
    point s ŝ + z ẑ; ``a`` is its part along a's axis (the rest is along -d_b).
    """
    n = math.sqrt(dax * dax + day * day + daz * daz)
    zx, zy, zz = dax / n, day / n, daz / n
    ep = ex * zx + ey * zy + ez * zz
    # -d_b across d_a is -(e across d_a): no cancellation between the nearly equal axes.
    sx, sy, sz = -(ex - ep * zx), -(ey - ep * zy), -(ez - ep * zz)
    rho = math.sqrt(sx * sx + sy * sy + sz * sz)
    kap = -ep - s * n  # -d_b along d_a
    if rho > 0.0:
        sx, sy, sz = sx / rho, sy / rho, sz / rho
    o = 0.0
    if rho == 0.0 and kap > 0.0:  # antiparallel: a ray
        return sx, sy, sz, zx, zy, zz, 2.0, o, o, o, o, L, L, o, o, o, o, o, o, o, o, o
    if rho == 0.0:  # parallel: a line
        return sx, sy, sz, zx, zy, zz, 2.0, o, -L, o, o, L, L, o, o, o, o, o, o, o, o, o
    r = kap / rho
    if kap >= rho:  # -d_b climbs steeply: it leaves the box through z = L
        return sx, sy, sz, zx, zy, zz, 3.0, o, o, o, o, L, L, L / r, L, o, o, o, o, o, o, o
    if kap >= -rho:  # it leaves through s = L
        return sx, sy, sz, zx, zy, zz, 4.0, o, o, o, o, L, L, L, L, L - L * r, L, L * r, o, o, o, o
    return sx, sy, sz, zx, zy, zz, 5.0, o, o, o, o, L, L, L, L, L - L * r, L, -L, -L - L * r, -L / r, -L, o


@jit(inline="always")
def cut_difference(Ra, Rb, dx, dy, dz, L):
    """D_L for :func:`support` from the poses, in the pair's own unit: ``(fr, cone, s, (ex, ey, ez), k)``.

    ``fr``: columns 0, 1 of R_a and R_b, then ``(dx, dy, dz)`` = c_b - c_a; ``cone``: :func:`cone_box`
    with box half-width L; ``s``: the sign of d_a.d_b; ``e = d_b - s d_a``, formed exactly. All in
    float64 whatever the pose arrays' dtype, so that the supports, and GJK and EPA on them, run in
    double: with float32 products, the witness GJK stalled short of the foot point on some float32
    pairs and left point_b 1.7 to 37 tol outside b.

    ``k``: the power of two that brings L into [0.5, 1). The columns, c_b - c_a and the cone's corners
    are multiplied by it, so every support point, and GJK and EPA, are k times the true ones: exactly
    so (a power of two only shifts exponents), but with no overflow or underflow where GJK's and
    EPA's cross products reach L^4 (at sizes beyond about 1e76 or below 1e-76 they had left gaps of
    -0 and depths 1e9 tol off). Lengths they return are divided by k.
    """
    f = np.float64
    k = math.ldexp(1.0, -math.frexp(L)[1])
    fr = (k * f(Ra[0, 0]), k * f(Ra[1, 0]), k * f(Ra[2, 0]), k * f(Ra[0, 1]), k * f(Ra[1, 1]), k * f(Ra[2, 1]))
    fr = fr + (k * f(Rb[0, 0]), k * f(Rb[1, 0]), k * f(Rb[2, 0]), k * f(Rb[0, 1]), k * f(Rb[1, 1]), k * f(Rb[2, 1]))
    fr = fr + (k * f(dx), k * f(dy), k * f(dz))
    dax, day, daz = f(Ra[0, 2]), f(Ra[1, 2]), f(Ra[2, 2])
    dbx, dby, dbz = f(Rb[0, 2]), f(Rb[1, 2]), f(Rb[2, 2])
    s = 1.0 if dax * dbx + day * dby + daz * dbz >= 0.0 else -1.0
    ex, ey, ez = dbx - s * dax, dby - s * day, dbz - s * daz  # exact (Sterbenz) for nearly (anti)parallel axes
    return fr, cone_box(dax, day, daz, ex, ey, ez, s, k * L), s, (ex, ey, ez), k


@jit(inline="always")
def point_a(avx, avy, sa, fr, ia):
    """Vertex ia of F_a (relative to a's centre)."""
    u = avx[sa + ia]
    v = avy[sa + ia]
    return fr[0] * u + fr[3] * v, fr[1] * u + fr[4] * v, fr[2] * u + fr[5] * v


@jit(inline="always")
def support(P, ix, fr, cone, ux, uy, uz):
    """Support point of D_L in direction u and its pre-image: (x, y, z, ia, ib, kc).

    ``P``: the polygon arrays (vx, vy, edge angles, edge tables of a, then of b); ``ix``:
    (start, count) of a's and b's polygons; ``fr``: columns 0, 1 of R_a and R_b, then
    c_b - c_a; ``cone``: :func:`cone_box`. The point is vertex ia of F_a minus
    vertex ib of F_b plus corner kc of C_L.
    """
    avx, avy, aeang, aetab, bvx, bvy, beang, betab = P
    sa, na, sb, nb = ix
    ia = extreme_vertex(
        avx, avy, aeang, aetab, sa, na, fr[0] * ux + fr[1] * uy + fr[2] * uz, fr[3] * ux + fr[4] * uy + fr[5] * uz
    )
    bu = fr[6] * ux + fr[7] * uy + fr[8] * uz
    ib = extreme_vertex(bvx, bvy, beang, betab, sb, nb, -bu, -(fr[9] * ux + fr[10] * uy + fr[11] * uz))
    us = cone[0] * ux + cone[1] * uy + cone[2] * uz
    uz_ = cone[3] * ux + cone[4] * uy + cone[5] * uz
    kc = 0
    best = -math.inf
    for k in range(int(cone[6])):
        val = us * cone[7 + 3 * k] + uz_ * cone[8 + 3 * k]
        if val > best:
            best = val
            kc = k
    ax, ay, az = point_a(avx, avy, sa, fr, ia)
    u = bvx[sb + ib]
    v = bvy[sb + ib]
    cs = cone[7 + 3 * kc]
    cz = cone[8 + 3 * kc]
    return (
        ax - (fr[12] + fr[6] * u + fr[9] * v) + cs * cone[0] + cz * cone[3],
        ay - (fr[13] + fr[7] * u + fr[10] * v) + cs * cone[1] + cz * cone[4],
        az - (fr[14] + fr[8] * u + fr[11] * v) + cs * cone[2] + cz * cone[5],
        ia,
        ib,
        kc,
    )
