"""Planar kernels: convex-polygon queries in O(log n) and a 2-D GJK.

Every polygon is a slice ``[s, s + n)`` of flat structure-of-arrays storage
(see :class:`prismbatch.shapes.PrismSet`): vertices about an interior centre,
counter-clockwise, with unwrapped edge angles and polar angles.

The shape "B" that GJK tests against polygon A is always described by one
*spec* tuple (see :func:`support_spec`): the affine image

    B = { P + M q + t w : q in polygon_B, 0 <= t <= T, z(q, t) >= -tolz },
    z(q, t) = pz + h.q + c t,

which covers every planar shape the paper uses (point, segment, half-line,
unbounded strip, polygon, with ``M = I`` and no height constraint) and the
projection of prism b onto prism a's end plane (section IV of the paper).
"""

import math

from .jit import jit

TWO_PI = 2.0 * math.pi

# Spec tuple layout (all float64). Indices are named for readability.
SP_PX, SP_PY = 0, 1
SP_M00, SP_M01, SP_M10, SP_M11 = 2, 3, 4, 5
SP_WX, SP_WY = 6, 7
SP_HX, SP_HY = 8, 9
SP_PZ, SP_C, SP_T, SP_TOLZ = 10, 11, 12, 13
SP_IMIN, SP_IMAX = 14, 15

GJK_MAX_ITER = 160


@jit(inline="always")
def wrap(x, period):
    """``x % period`` for a float x in [-period, period] (a difference of two angles), bit for
    bit, without the remainder's libm call. (Integer indices keep ``%``: the same branches in
    place of the integer division measured slower.)"""
    if x < 0.0:
        return x + period
    if x >= period:
        return x - period
    return x


@jit(inline="always")
def pseudo_angle(x, y):
    """A strictly increasing stand-in for atan2(y, x), in [0, 4): cheaper than atan2.

    1 per quarter turn (the "diamond angle"); (0, 0) maps to 0.
    """
    if y >= 0.0:
        if x >= 0.0:
            s = x + y
            return y / s if s > 0.0 else 0.0
        return 1.0 - x / (y - x)
    if x < 0.0:
        return 2.0 - y / (-x - y)
    return 3.0 + x / (x - y)


@jit
def edge_search_tables(ex, ey, out_ang, out_tab):
    """Unwrapped edge pseudo-angles and bucket table of one CCW polygon.

    ``ex, ey``: the edge vectors v_{k+1} - v_k, taken from the polygon as
    given (differences of neighbouring floats are exact), not from vertices
    shifted to the centre: on short, nearly collinear edges that rounding
    exceeds the turns and misorders the angles (the extreme-vertex search
    then stops vertices short of the maximiser).
    out_ang[k]: pseudo-angle of edge k, unwrapped to increase by whole turns
    (no running sum, so no drift over thousands of edges); a rounding-level
    backward turn counts as no turn.
    out_tab[b]: number of edges whose angle offset from edge 0 is below
    4 b / n (n buckets of equal pseudo-angle width), so the extreme-vertex
    search only scans one bucket (O(1) for evenly spread edges).
    """
    n = ex.shape[0]
    if n == 1:
        out_ang[0] = 0.0
        out_tab[0] = 0
        return
    prev = pseudo_angle(ex[0], ey[0])
    out_ang[0] = prev
    if n == 2:  # a segment: its two edges are exactly a half turn apart
        out_ang[1] = prev + 2.0
    turns = 0.0
    for k in range(1, n if n > 2 else 0):
        a = pseudo_angle(ex[k], ey[k])
        # A convex turn is below a half turn (2): a larger jump is the seam
        # at 4 -> 0 (forward), or a tiny backward turn across it.
        if a < prev - 2.0:
            turns += 4.0
        elif a > prev + 2.0:
            turns -= 4.0
        out_ang[k] = max(a + turns, out_ang[k - 1])
        prev = a
    j = 0
    for b in range(n):
        edge = 4.0 * b / n
        while j < n and out_ang[j] - out_ang[0] < edge:
            j += 1
        out_tab[b] = j


@jit
def edge_search_tables_each(ex, ey, out_ang, out_tab):
    """:func:`edge_search_tables` of each row of ``(m, n)`` arrays (m polygons of n vertices)."""
    for k in range(ex.shape[0]):
        edge_search_tables(ex[k], ey[k], out_ang[k], out_tab[k])


# Not inline="always": Numba's IR inlining of its many call sites cost about 1 s of the cold compile
# (CPU time 7.0-7.4 -> 5.9-6.4 s); facing and free pairs ran at the same ns per pair without it.
@jit
def extreme_vertex(vx, vy, eang, etab, s, n, dx, dy):
    """Local index of a vertex maximising ``(dx, dy) . v``.

    Vertex k lies between edge k-1 and edge k; it is extreme for directions
    whose angle + pi/2 lies between the angles of those edges. A bucket
    lookup then a binary search inside the bucket (see edge_search_tables).
    """
    if n == 1:
        return 0
    p0 = eang[s]
    off = wrap(pseudo_angle(-dy, dx) - p0, 4.0)  # angle + pi/2, relative to edge 0
    target = p0 + off
    if not off >= 0.0:  # NaN direction (never from valid input): any vertex, but no wild index
        off = 0.0
    b = int(off * n * 0.25)
    if b >= n:
        b = n - 1
    lo = etab[s + b]
    hi = etab[s + b + 1] if b + 1 < n else n
    while lo < hi:
        mid = (lo + hi) >> 1
        if eang[s + mid] < target:
            lo = mid + 1
        else:
            hi = mid
    return lo % n


@jit(inline="always")
def wedge_edge(vang, s, n, px, py):
    """Edge k whose wedge (polar angles about the centre) holds point p (eq. 1)."""
    th0 = vang[s]
    target = th0 + wrap(math.atan2(py, px) - th0, TWO_PI)
    lo = 0
    hi = n
    while lo < hi:  # count of vertices with polar angle <= target
        mid = (lo + hi) >> 1
        if vang[s + mid] <= target:
            lo = mid + 1
        else:
            hi = mid
    return lo - 1 if lo > 0 else 0


@jit
def point_polygon_distance(vx, vy, vang, inv_len, s, n, px, py):
    """Signed distance from p to the edge line of its wedge (paper eq. 1).

    Positive inside the polygon. For a point outside it is a lower bound of
    the Euclidean distance to the polygon (the polygon lies on one side of
    every edge line), so ``>= 0`` is an exact inside test.
    """
    k = wedge_edge(vang, s, n, px, py)
    k1 = k + 1 if k + 1 < n else 0
    x0 = vx[s + k]
    y0 = vy[s + k]
    ex = vx[s + k1] - x0
    ey = vy[s + k1] - y0
    return (ex * (py - y0) - ey * (px - x0)) * inv_len[s + k]


@jit(inline="always")
def _chain_cross(vx, vy, s, n, hx, hy, start, m, level, rising):
    """Point where h.v crosses `level` on the monotone chain start..start+m."""
    lo = 0
    hi = m
    while hi - lo > 1:
        mid = (lo + hi) >> 1
        j = (start + mid) % n
        hv = hx * vx[s + j] + hy * vy[s + j]
        if (hv <= level) == rising:
            lo = mid
        else:
            hi = mid
    i0 = (start + lo) % n
    i1 = (start + hi) % n
    h0 = hx * vx[s + i0] + hy * vy[s + i0]
    h1 = hx * vx[s + i1] + hy * vy[s + i1]
    den = h1 - h0
    f = (level - h0) / den if den != 0.0 else 0.0
    if f < 0.0:
        f = 0.0
    elif f > 1.0:
        f = 1.0
    return (vx[s + i0] + f * (vx[s + i1] - vx[s + i0]), vy[s + i0] + f * (vy[s + i1] - vy[s + i0]))


@jit
def chord(vx, vy, s, n, hx, hy, imin, imax, level):
    """End points of the chord {q in polygon : h.q = level} in O(log n).

    ``imin``/``imax`` are the vertices of least/greatest h.q. A level outside
    that range (by rounding) is clamped to the extreme vertex.
    """
    hmin = hx * vx[s + imin] + hy * vy[s + imin]
    hmax = hx * vx[s + imax] + hy * vy[s + imax]
    if level <= hmin:
        return vx[s + imin], vy[s + imin], vx[s + imin], vy[s + imin]
    if level >= hmax:
        return vx[s + imax], vy[s + imax], vx[s + imax], vy[s + imax]
    m_up = (imax - imin) % n
    m_dn = (imin - imax) % n
    ux, uy = _chain_cross(vx, vy, s, n, hx, hy, imin, m_up, level, True)
    dx, dy = _chain_cross(vx, vy, s, n, hx, hy, imax, m_dn, level, False)
    return ux, uy, dx, dy


SLAB_INSIDE, SLAB_LO, SLAB_HI = 0, 1, 2


@jit
def slab_support(vx, vy, eang, etab, s, n, dx, dy, hx, hy, imin, imax, lo, hi, ex, ey, slack):
    """Maximise d.q over {q in polygon : lo - slack <= h.q <= hi + slack} (assumed non-empty).

    If the unconstrained maximiser violates one side of the slab by more than
    ``slack``, the constrained maximum lies on that side's chord (an LP fact),
    found by binary search. The chord's two ends are told apart by ``e``: any
    direction that orders points on the chord like ``d`` does (d differs from
    e by a multiple of h, constant on the chord), chosen well conditioned.
    Returns (u, v, flag) with flag SLAB_INSIDE/LO/HI.

    Why ``slack``: a side that is straight up to rounding (accepted outlines
    may turn back by up to 4e-12 rad in all) is not monotone in h.q when h is
    normal to it, so ``imin``/``imax`` may lie anywhere along it and a chord
    at a level within that side's rounding band could end anywhere along it
    (supports short by up to the side's length: missed contacts). A violation
    within ``slack`` counts as inside; a larger one puts the level above that
    band, where the chains from ``imin``/``imax`` are monotone.
    """
    k = extreme_vertex(vx, vy, eang, etab, s, n, dx, dy)
    u = vx[s + k]
    v = vy[s + k]
    hq = hx * u + hy * v
    if hq > hi + slack:
        level = hi
        flag = SLAB_HI
    elif hq < lo - slack:
        level = lo
        flag = SLAB_LO
    else:
        return u, v, SLAB_INSIDE
    u1, v1, u2, v2 = chord(vx, vy, s, n, hx, hy, imin, imax, level)
    if ex * u1 + ey * v1 >= ex * u2 + ey * v2:
        return u1, v1, flag
    return u2, v2, flag


@jit
def support_spec(vx, vy, eang, etab, s, n, sp, dx, dy):
    """Support point of the spec shape B in direction d.

    Returns (x, y, u, v, t): the 2-D point and its pre-image (q = (u, v), t).
    The maximisation is a 3-variable LP over (polygon x [0, T]) cut by the
    half-space z(q, t) >= -tolz; it never divides by c unless the answer lies
    strictly inside the slab, where the quotient is bounded by T.
    """
    au = sp[SP_M00] * dx + sp[SP_M10] * dy  # M^T d
    av = sp[SP_M01] * dx + sp[SP_M11] * dy
    g = sp[SP_WX] * dx + sp[SP_WY] * dy
    T = sp[SP_T]
    c = sp[SP_C]
    pz = sp[SP_PZ]
    tz = sp[SP_TOLZ]
    hx = sp[SP_HX]
    hy = sp[SP_HY]
    imin = int(sp[SP_IMIN])
    imax = int(sp[SP_IMAX])
    # The slab's sides may be missed by this much in height (see slab_support): points of B up to
    # tolz + slack below a's end plane then count, still within the 2 tol a hit may be off.
    slack = 0.0625 * tz
    tf = T if g > 0.0 else 0.0
    if c == 0.0:
        u, v, _ = slab_support(vx, vy, eang, etab, s, n, au, av, hx, hy, imin, imax, -tz - pz, math.inf, au, av, slack)
        t = tf
    else:
        k = extreme_vertex(vx, vy, eang, etab, s, n, au, av)
        u = vx[s + k]
        v = vy[s + k]
        if pz + hx * u + hy * v + c * tf >= -tz:
            t = tf
        else:
            # Optimum lies on the plane z = -tolz: substitute t(q) and scale
            # the objective by |c| so nothing blows up as c -> 0.
            ac = abs(c)
            sg = 1.0 if c > 0.0 else -1.0
            du = ac * au - sg * g * hx
            dv = ac * av - sg * g * hy
            h0 = -tz - pz  # h.q on the plane at t = 0
            ht = h0 - c * T  # ... and at t = T
            if h0 <= ht:
                lo, hi, t_lo, t_hi = h0, ht, 0.0, T
            else:
                lo, hi, t_lo, t_hi = ht, h0, T, 0.0
            # On a chord (t fixed) the objective is a.q + const: compare ends by a.
            u, v, flag = slab_support(vx, vy, eang, etab, s, n, du, dv, hx, hy, imin, imax, lo, hi, au, av, slack)
            if flag == SLAB_LO:
                t = t_lo
            elif flag == SLAB_HI:
                t = t_hi
            else:
                t = (h0 - (hx * u + hy * v)) / c
                if t < 0.0:
                    t = 0.0
                elif t > T:
                    t = T
    x = sp[SP_PX] + sp[SP_M00] * u + sp[SP_M01] * v + sp[SP_WX] * t
    y = sp[SP_PY] + sp[SP_M10] * u + sp[SP_M11] * v + sp[SP_WY] * t
    return x, y, u, v, t


@jit(inline="always")
def segment_closest(px, py, qx, qy):
    """``(vx, vy, lam)``: the point v of segment [p, q] nearest the origin, v = p + lam (q - p).

    In the interior v is taken along the edge's normal: p + lam (q - p) loses the direction when |v|
    is tiny against |p| (relative error eps |p| / |v|), and GJK then stalls on long edges; the
    normal is exact to eps whatever |v|.
    """
    ex = qx - px
    ey = qy - py
    ee = ex * ex + ey * ey
    if ee <= 0.0:
        return px, py, 0.0
    lam = -(px * ex + py * ey) / ee
    if lam <= 0.0:
        return px, py, 0.0
    if lam >= 1.0:
        return qx, qy, 1.0
    inv = 1.0 / math.sqrt(ee)
    nx = -ey * inv
    ny = ex * inv
    d = px * nx + py * ny
    return d * nx, d * ny, lam


@jit(inline="always")
def _seg_closest(p, q):
    """:func:`segment_closest` of two simplex entries, tuples (wx, wy, dx, dy): the point w = a - b of
    the Minkowski difference and the direction d its support on B was taken in; lam is q's weight."""
    return segment_closest(p[0], p[1], q[0], q[1])


@jit
def _entry_witness(avx, avy, aeang, aetab, sa, na, bvx, bvy, beang, betab, sb, nb, sp, e):
    """(ax, ay, u, v, t) of simplex entry ``e``: a's support point and the pre-image of b's, found
    again from the entry's direction (both supports are pure functions of it, so this is the point
    the entry was made from, to the bit). GJK carries only w and d, and makes the witness from them
    on a hit when it is asked for: carrying the five witness numbers through every iteration cost
    the status-only query a quarter of its GJK time."""
    ka = extreme_vertex(avx, avy, aeang, aetab, sa, na, -e[2], -e[3])
    _, _, u, v, t = support_spec(bvx, bvy, beang, betab, sb, nb, sp, e[2], e[3])
    return avx[sa + ka], avy[sa + ka], u, v, t


@jit(inline="always")
def _mix(p, q, lam):
    """(1 - lam) p + lam q, entry-wise, of two :func:`_entry_witness` tuples."""
    m = 1.0 - lam
    return (
        m * p[0] + lam * q[0],
        m * p[1] + lam * q[1],
        m * p[2] + lam * q[2],
        m * p[3] + lam * q[3],
        m * p[4] + lam * q[4],
    )


@jit
def gjk(avx, avy, aeang, aetab, sa, na, bvx, bvy, beang, betab, sb, nb, sp, tol, witness):
    """Is dist(polygon A, spec shape B) <= tol?  2-D GJK on O(log n) supports.

    Returns (hit, iterations, ax, ay, u, v, t): on a hit with ``witness`` true, (ax, ay) is a point
    of A and (u, v, t) the pre-image of a point of B within tol of it (their weighted simplex
    combination); zeros otherwise. Replaces the walk of eqs. (15)-(18): it needs no starting edge
    pair and ends in a bounded number of steps.
    """
    tol2 = tol * tol
    dx = sp[SP_PX]
    dy = sp[SP_PY]
    if dx == 0.0 and dy == 0.0:
        dx = 1.0
    # Simplex entries: (wx, wy, bdx, bdy), w = a - b from the supports of A in -bd and of B in bd.
    # The witness is p0 while the simplex is one point (k = 1), (1 - lam) p0 + lam p1 on a segment.
    ka = extreme_vertex(avx, avy, aeang, aetab, sa, na, dx, dy)
    bx, by, _, _, _ = support_spec(bvx, bvy, beang, betab, sb, nb, sp, -dx, -dy)
    p0 = (avx[sa + ka] - bx, avy[sa + ka] - by, -dx, -dy)
    p1 = p0
    k = 1
    lam = 0.0
    vx_ = p0[0]
    vy_ = p0[1]
    last_vv = math.inf
    lower = -math.inf  # best lower bound of the distance so far
    hit_at = -1  # the iteration that found |v| <= tol
    for it in range(GJK_MAX_ITER):
        vv = vx_ * vx_ + vy_ * vy_
        if vv <= tol2:
            hit_at = it
            break
        ka = extreme_vertex(avx, avy, aeang, aetab, sa, na, -vx_, -vy_)
        bx, by, bu, bv, bt = support_spec(bvx, bvy, beang, betab, sb, nb, sp, vx_, vy_)
        ax = avx[sa + ka]
        ay = avy[sa + ka]
        pn = (ax - bx, ay - by, vx_, vy_)
        vw = vx_ * pn[0] + vy_ * pn[1]
        lower = max(lower, vw / math.sqrt(vv))
        if lower > tol:
            return False, it, 0.0, 0.0, 0.0, 0.0, 0.0  # separating line with gap > tol
        if vv - vw <= 1e-13 * vv:
            return False, it, 0.0, 0.0, 0.0, 0.0, 0.0  # converged at distance ~|v| > tol
        if vv >= last_vv:
            # |v| stopped shrinking at rounding level: |v| (> tol) is the
            # distance to within rounding. (Calling this "touching" because the
            # lower bound lags gave hits several tol apart.)
            return False, it, 0.0, 0.0, 0.0, 0.0, 0.0
        last_vv = vv
        if k == 1:
            vx_, vy_, lam = _seg_closest(p0, pn)
            if lam >= 1.0:
                p0 = pn
            elif lam > 0.0:
                p1 = pn
                k = 2
        else:
            # Triangle p0, p1, pn: origin inside -> overlap.
            s_ = (p1[0] - p0[0]) * (pn[1] - p0[1]) - (p1[1] - p0[1]) * (pn[0] - p0[0])
            c0 = p1[0] * pn[1] - p1[1] * pn[0]  # weight of p0 (times s_)
            c1 = pn[0] * p0[1] - pn[1] * p0[0]  # weight of p1
            c2 = p0[0] * p1[1] - p0[1] * p1[0]  # weight of pn
            if s_ != 0.0 and (
                (s_ > 0.0 and c0 >= 0.0 and c1 >= 0.0 and c2 >= 0.0)
                or (s_ < 0.0 and c0 <= 0.0 and c1 <= 0.0 and c2 <= 0.0)
            ):
                if not witness:
                    return True, it, 0.0, 0.0, 0.0, 0.0, 0.0
                l0 = c0 / s_
                l1 = c1 / s_
                l2 = 1.0 - l0 - l1
                w0 = _entry_witness(avx, avy, aeang, aetab, sa, na, bvx, bvy, beang, betab, sb, nb, sp, p0)
                w1 = _entry_witness(avx, avy, aeang, aetab, sa, na, bvx, bvy, beang, betab, sb, nb, sp, p1)
                return (
                    True,
                    it,
                    l0 * w0[0] + l1 * w1[0] + l2 * ax,
                    l0 * w0[1] + l1 * w1[1] + l2 * ay,
                    l0 * w0[2] + l1 * w1[2] + l2 * bu,
                    l0 * w0[3] + l1 * w1[3] + l2 * bv,
                    l0 * w0[4] + l1 * w1[4] + l2 * bt,
                )
            # Otherwise the closest point lies on an edge through the new point.
            ax0, ay0, la = _seg_closest(p0, pn)
            ax1, ay1, lb = _seg_closest(p1, pn)
            if ax0 * ax0 + ay0 * ay0 <= ax1 * ax1 + ay1 * ay1:
                vx_, vy_, lam, q = ax0, ay0, la, p0
            else:
                vx_, vy_, lam, q = ax1, ay1, lb, p1
            if lam >= 1.0:
                p0 = pn
                k = 1
            elif lam <= 0.0:
                p0 = q
                k = 1
            else:
                p0 = q
                p1 = pn
    if hit_at < 0:
        # Iteration cap (cycling at rounding level): touching counts, so a
        # distance not shown to exceed tol is a hit.
        if lower > tol:
            return False, GJK_MAX_ITER, 0.0, 0.0, 0.0, 0.0, 0.0
        hit_at = GJK_MAX_ITER
    # A hit on the point p0 (k = 1) or the segment p0 p1 at weight lam (one exit: each call of a
    # helper with other literal arguments would compile another copy of it).
    if not witness:
        return True, hit_at, 0.0, 0.0, 0.0, 0.0, 0.0
    w = _entry_witness(avx, avy, aeang, aetab, sa, na, bvx, bvy, beang, betab, sb, nb, sp, p0)
    if k == 2:
        w = _mix(w, _entry_witness(avx, avy, aeang, aetab, sa, na, bvx, bvy, beang, betab, sb, nb, sp, p1), lam)
    return True, hit_at, w[0], w[1], w[2], w[3], w[4]


@jit
def gjk_generators(avx, avy, aeang, aetab, an, gx, gy, geang, getab, gn, wx, wy, T, tol):
    """GJK of polygon A (centred) vs conv(generators) + [0, T] w."""
    sp = (0.0, 0.0, 1.0, 0.0, 0.0, 1.0, wx, wy, 0.0, 0.0, 1.0, 0.0, T, 0.0, 0.0, 0.0)
    return gjk(avx, avy, aeang, aetab, 0, an, gx, gy, geang, getab, 0, gn, sp, tol, True)
