"""3-D GJK on the support function of D_L (:mod:`.minkowski`): the closest point of D_L to a point.

The signed distance (:mod:`.distance`) takes the gap from it, hands a simplex around the origin
to EPA, and runs it once more from the foot point for the witnesses; the margin query
(:mod:`.margin`) stops it as soon as its bounds decide. The closest point of a simplex to the
origin uses Ericson's Voronoi-region tests.
"""

import math

import numpy as np

from .jit import jit
from .minkowski import support
from .vec3 import cross, cross_accurate, cross_and_sizes, diff, dot, normal, plain_cross_too_tilted, row, sub

#: Iteration cap of :func:`gjk` (it then reports the distance unresolved and EPA decides).
GJK_MAX_ITER = 128


@jit(inline="always")
def _foot(a, e):
    """Foot of the perpendicular from the origin on the line a + t e, as e x (a x e) / |e|^2:
    exact to rounding of the result, where a + t e loses eps |a| when the foot is near the origin."""
    f = cross(e, cross(a, e))
    ee = dot(e, e)
    return f[0] / ee, f[1] / ee, f[2] / ee


#: A triangle whose edges ab, ac meet at a squared sine below this is a sliver: the Voronoi-region
#: tests of :func:`_triangle` (differences of products of dot products) are then rounding noise, and it
#: takes the nearest of its plane's foot and its three edges' closest points instead (:func:`_sliver`).
SLIVER_SIN2 = 1e-8


@jit(inline="always")
def _segment(a, b):
    """Closest point of segment ab to the origin, and the weight of b."""
    e = sub(b, a)
    ee = dot(e, e)
    t = min(max(-dot(a, e) / ee, 0.0), 1.0) if ee > 0.0 else 0.0
    return (b if t == 1.0 else (a if t == 0.0 else _foot(a, e))), t


@jit(inline="always")
def _plane_foot(a, b, c, n, nn, accurate):
    """``(p, wa, wb, wc)``: the foot p of the origin on the plane of triangle (a, b, c), n = (b - a) x
    (c - a) and nn = |n|^2 > 0 given, and the areas (times |n|) it cuts with the edges opposite a, b,
    c: the foot's weights, all >= 0 where it lies inside. Differences taken at the foot, and products
    exact to rounding: on a sliver (one far vertex) dot products lose them, and the weights must
    reproduce the foot for the witnesses. ``accurate``: with :func:`~.vec3.cross_accurate` (slivers)."""
    h = dot(n, a) / nn  # along the normal: exact to rounding of the result
    p = (h * n[0], h * n[1], h * n[2])
    pa, pb, pc = sub(a, p), sub(b, p), sub(c, p)
    if accurate:
        return p, dot(n, cross_accurate(pb, pc)), dot(n, cross_accurate(pc, pa)), dot(n, cross_accurate(pa, pb))
    return p, dot(n, cross(pb, pc)), dot(n, cross(pc, pa)), dot(n, cross(pa, pb))


@jit
def _sliver(a, b, c, n, nn):
    """Closest point of triangle (a, b, c) to the origin and its weights, with n = (b - a) x (c - a) from
    :func:`~.vec3.cross_accurate` and nn = |n|^2: the nearest of the three edges' closest points and the
    foot on the plane, the foot only where its area weights (:func:`_plane_foot`) put it inside. No region
    test: each candidate is a point of the triangle to within rounding of its own size, whatever the
    triangle's shape."""
    p, t = _segment(a, b)
    best = dot(p, p)
    res = p + (1.0 - t, t, 0.0)
    p, t = _segment(b, c)
    if dot(p, p) < best:
        best = dot(p, p)
        res = p + (0.0, 1.0 - t, t)
    p, t = _segment(a, c)
    if dot(p, p) < best:
        best = dot(p, p)
        res = p + (1.0 - t, 0.0, t)
    if nn > 0.0:
        p, wa, wb, wc = _plane_foot(a, b, c, n, nn, True)
        ws = wa + wb + wc
        if wa >= 0.0 and wb >= 0.0 and wc >= 0.0 and ws > 0.0 and dot(p, p) < best:
            res = p + (wa / ws, wb / ws, wc / ws)
    return res


@jit
def _triangle(W, i, j, k):
    """Closest point of triangle (W[i], W[j], W[k]) to the origin and its three weights (Ericson; on a
    sliver, :func:`_sliver`)."""
    a, b, c = row(W, i), row(W, j), row(W, k)
    ab, ac = sub(b, a), sub(c, a)
    # The vertex regions first: each is two dot products, sound on any shape (a sliver's noise is in the
    # differences of their products below), and they need no normal.
    d1, d2 = -dot(ab, a), -dot(ac, a)
    if d1 <= 0.0 and d2 <= 0.0:
        return a + (1.0, 0.0, 0.0)
    d3, d4 = -dot(ab, b), -dot(ac, b)
    if d3 >= 0.0 and d4 <= d3:
        return b + (0.0, 1.0, 0.0)
    d5, d6 = -dot(ab, c), -dot(ac, c)
    if d6 >= 0.0 and d5 <= d6:
        return c + (0.0, 0.0, 1.0)
    n, nn, lim = cross_and_sizes(ab, ac)  # (nn to within eps |ab| |ac|: enough to tell a sliver)
    if nn < SLIVER_SIN2 * lim:
        n = cross_accurate(ab, ac)
        return _sliver(a, b, c, n, dot(n, n))
    accurate = plain_cross_too_tilted(nn, lim)
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        t = d1 / (d1 - d3)
        return _foot(a, ab) + (1.0 - t, t, 0.0)
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        t = d2 / (d2 - d6)
        return _foot(a, ac) + (1.0 - t, 0.0, t)
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and d4 - d3 >= 0.0 and d5 - d6 >= 0.0:
        t = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return _foot(b, sub(c, b)) + (0.0, 1.0 - t, t)
    # Nearly a sliver, the normal with its components exact to rounding: the plain cross product tilts
    # it by about eps / sin(ab, ac) (a sliver of sin 1.6e-8, 2.5e5 long, moved the plane by 2.2 tol).
    if accurate:
        n = cross_accurate(ab, ac)
        nn = dot(n, n)
    if not (va + vb + vc > 0.0 and nn > 0.0):  # degenerate (collinear): its nearest vertex
        da, db, dc = dot(a, a), dot(b, b), dot(c, c)
        if da <= min(db, dc):
            return a + (1.0, 0.0, 0.0)
        return b + (0.0, 1.0, 0.0) if db <= dc else c + (0.0, 0.0, 1.0)
    p, wa, wb, wc = _plane_foot(a, b, c, n, nn, accurate)
    ws = wa + wb + wc
    if not ws > 0.0:
        den = va + vb + vc
        return p + (va / den, vb / den, vc / den)
    return p + (max(wa, 0.0) / ws, max(wb, 0.0) / ws, max(wc, 0.0) / ws)


_FACES = ((0, 1, 2, 3), (0, 3, 1, 2), (0, 2, 3, 1), (1, 3, 2, 0))  # three vertices of a face, then the fourth


@jit(inline="always")
def _compact(W, I, lam, m):
    """Keep the rows of W, I, lam with positive weight (in place, in order); their number."""
    k = 0
    for j in range(m):
        if lam[j] > 0.0:
            for c in range(3):  # element by element: a row copy may allocate (no NRT in margin's loop)
                W[k, c], I[k, c] = W[j, c], I[j, c]
            lam[k] = lam[j]
            k += 1
    return k


@jit(inline="always")
def closest(W, I, lam, m):
    """Closest point of conv(W[:m]) to the origin; keeps only the vertices that carry it.

    Returns (m', vx, vy, vz, inside, face): ``lam[:m']`` are the weights, W and I
    are compacted in place. ``inside``: the origin lies in the tetrahedron
    (m = 4); W, I are then left whole, v and ``lam`` describe the nearest point
    of its boundary (stable weights for a point on the boundary, which Cramer's
    rule on a sliver is not), and ``face`` is its distance (else 0).
    """
    for j in range(4):
        lam[j] = 0.0
    if m == 1:
        p = row(W, 0)
        lam[0] = 1.0
    elif m == 2:
        p, t = _segment(row(W, 0), row(W, 1))
        lam[0], lam[1] = 1.0 - t, t
    elif m == 3:
        i0 = np.int64(0)  # (not literal indices: they would compile _triangle once more)
        px, py, pz, lam[0], lam[1], lam[2] = _triangle(W, i0, i0 + 1, i0 + 2)
        p = (px, py, pz)
    else:
        best = math.inf
        inside = True
        p = (0.0, 0.0, 0.0)
        for sweep in range(2):  # the faces the origin is beyond; if none, it is inside: all faces
            for f in range(4):
                i, j, k, l = _FACES[f]
                n = normal(diff(W, j, i), diff(W, k, i))  # (accurate on slivers, as in _triangle)
                if sweep == 1 or -dot(n, row(W, i)) * dot(n, diff(W, l, i)) <= 0.0:
                    inside = sweep == 1
                    qx, qy, qz, li, lj, lk = _triangle(W, i, j, k)
                    if qx * qx + qy * qy + qz * qz < best:
                        best = qx * qx + qy * qy + qz * qz
                        p = (qx, qy, qz)
                        for c in range(4):
                            lam[c] = 0.0
                        lam[i], lam[j], lam[k] = li, lj, lk
            if best < math.inf:
                break
        if inside:
            return 4, p[0], p[1], p[2], True, math.sqrt(best)
    return _compact(W, I, lam, m), p[0], p[1], p[2], False, 0.0


# --- GJK and EPA ---------------------------------------------------------------------------------


@jit(inline="always")
def _copy_simplex(W, I, lam, src, dst, m):
    """Rows ``src .. src + m - 1`` of the simplex to ``dst ..`` (element by element: a slice copy
    would need Numba's reference counting, which the batch loop runs without)."""
    for j in range(m):
        for c in range(3):
            W[dst + j, c] = W[src + j, c]
            I[dst + j, c] = I[src + j, c]
        lam[dst + j] = lam[src + j]


@jit
def gjk(P, ix, fr, cone, ox, oy, oz, acc, loose, W, I, lam):
    """Closest point of D_L to o: GJK on the support function.

    Returns (m, vx, vy, vz, inside, lower): v = closest point - o, ``lower`` the best lower
    bound on the distance (a support plane), the simplex in
    ``W[:m]`` (points minus o), ``I[:m]`` (pre-images ia, ib, kc) and
    ``lam[:m]`` (weights). ``inside``: o lies in D_L or within ``acc`` of it, or
    GJK stopped (rounding, or its iteration cap) without showing a gap to within
    ``loose``; the distance is then not resolved and EPA takes over; the simplex is then a
    tetrahedron around o, or, when o is within ``acc`` of the simplex's boundary,
    the simplex of the nearest boundary point (v is that point - o). Otherwise
    |v| is the distance, to within ``acc`` (or, where rounding stopped GJK, to
    within ``loose``: rounding on the slivers of 100,000-gons leaves about 1e-10 |v|).
    """
    ux, uy, uz = fr[12], fr[13], fr[14]
    if ux == 0.0 and uy == 0.0 and uz == 0.0:
        ux = 1.0
    x, y, z, ia, ib, kc = support(P, ix, fr, cone, ux, uy, uz)
    W[0, 0], W[0, 1], W[0, 2] = x - ox, y - oy, z - oz
    I[0, 0], I[0, 1], I[0, 2] = ia, ib, kc
    lam[0] = 1.0
    m = 1
    vx, vy, vz = W[0, 0], W[0, 1], W[0, 2]
    lower = 0.0
    for _ in range(GJK_MAX_ITER):
        vn = math.sqrt(vx * vx + vy * vy + vz * vz)
        if vn <= acc:
            return m, vx, vy, vz, True, lower
        x, y, z, ia, ib, kc = support(P, ix, fr, cone, -vx, -vy, -vz)
        wx, wy, wz = x - ox, y - oy, z - oz
        lower = max(lower, (vx * wx + vy * wy + vz * wz) / vn)
        if vn - lower <= acc:
            return m, vx, vy, vz, False, lower
        for j in range(m):
            if I[j, 0] == ia and I[j, 1] == ib and I[j, 2] == kc:  # no progress: converged to rounding
                return m, vx, vy, vz, lower <= acc or vn - lower > loose, lower
        _copy_simplex(W, I, lam, 0, 4, m)  # kept: on slivers rounding can misjudge the faces and lose much ground
        m0, vx0, vy0, vz0 = m, vx, vy, vz
        vv0 = vx * vx + vy * vy + vz * vz
        W[m, 0], W[m, 1], W[m, 2] = wx, wy, wz
        I[m, 0], I[m, 1], I[m, 2] = ia, ib, kc
        m, vx, vy, vz, inside, face = closest(W, I, lam, m + 1)
        # Lost ground, or "inside" a tetrahedron although a support plane puts o at least lower > acc
        # from D_L (rounding on a sliver: three nearly equal points and a far one, as on identical
        # rotations of 3600-gons, where taking it gave a distance of 0 and a NaN normal): back to the
        # last simplex, whose v is a point of D_L.
        if (inside and lower > acc) or (not inside and vx * vx + vy * vy + vz * vz > 2.0 * vv0):
            m = m0
            _copy_simplex(W, I, lam, 4, 0, m)
            return m, vx0, vy0, vz0, lower <= acc or vn - lower > loose, lower  # a gap if shown, else EPA decides
        if inside:
            if face > acc:
                return 4, 0.0, 0.0, 0.0, True, lower
            return _compact(W, I, lam, 4), vx, vy, vz, True, lower  # o on the boundary (the witness pass)
    return m, vx, vy, vz, lower <= acc or vn - lower > loose, lower
