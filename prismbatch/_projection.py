"""Projection of prism b onto prism a's end plane, case classification, test.

Everything here works in a's *centred frame*: origin at the centre of a's end
face, z along d_a (into a's body). b's pose in that frame is (p, R), so a
point of b is p + R [u, v, t] with (u, v) in b's polygon (about b's centre)
and t >= 0. Since a = P_a x [0, inf), the prisms meet iff the projection Q of
b ∩ {z >= 0} along z meets P_a (NOTES.md). With

    h = (R20, R21), c = R22 = d_a.d_b (the paper's Δ1), w = (R02, R12),
    z(q, t) = p_z + h.q + c t,   Δ3 = max_q z(q, 0),

Q is the spec shape of :mod:`prismbatch._planar` with M = R[:2, :2]. Only the
part of Q within reach of P_a matters, so t is capped at
T = (|p_xy| + R_a + R_b + 2 tol) / |w|, which keeps every coordinate bounded
whatever the angle between the axes (no tan α or sec²α anywhere).

Tolerance: b's half-space test is relaxed to z >= -tol and GJK accepts a 2-D
gap <= tol. Hence bodies within tol (touching) always report a hit, and a
reported hit means the Euclidean distance between the bodies is <= sqrt(2) tol.
When the axes are perpendicular to within the reach (|c| T <= tol / 4), c is
set to 0 and the relaxation widened by |c| T: still every pair within tol
hits, and a hit is within sqrt(1 + 1.5^2) tol < 2 tol (cases 7-9).
"""

import math

from numba import njit

from ._planar import extreme_vertex, gjk, point_polygon_distance

# Case numbers. 1-9 are the paper's; 10 and 11 extend it to d_a.d_b > 0.
CASE_ABOVE = 1
CASE_VERTEX = 2
CASE_EDGE = 3
CASE_FACE = 4
CASE_COARSE = 5
CASE_POLYGON = 6
CASE_PERP_VERTEX = 7
CASE_PERP_EDGE = 8
CASE_PERP_STRIP = 9
CASE_RETURN = 10
CASE_UNBOUNDED = 11

CASES = {
    1: "b's end face beyond a's plane (Δ3 < 0) and b's body leaves it (d_a.d_b <= 0): no collision",
    2: "one vertex of b on a's plane (Δ3 = 0), axes not perpendicular: point vs polygon",
    3: "an edge of b on a's plane (two vertices, Δ3 = 0): segment vs polygon",
    4: "end faces coplanar (three or more vertices, Δ3 = 0): polygon vs polygon",
    5: "b crosses a's plane (Δ3 > 0), rejected by the coarse test Δ4: no collision",
    6: "b crosses a's plane (Δ3 > 0), facing axes: projected polygon vs polygon",
    7: "perpendicular axes, one vertex on a's plane: half-line vs polygon",
    8: "perpendicular axes, an edge on a's plane: unbounded strip vs polygon",
    9: "perpendicular axes, b reaches below a's plane (Δ3 > 0; the paper's text says Δ3 < 0): strip vs polygon",
    10: "added: d_a.d_b > 0 and b's end face does not enter a's half-space (Δ3 <= 0), but b's body "
        "comes back through a's plane: cross-section swept along the projected axis vs polygon",
    11: "added: d_a.d_b > 0 and b's end face enters a's half-space (Δ3 > 0): unbounded projection "
        "(end-face part, cross-section and sweep) vs polygon",
}


@njit(cache=True, inline="always")
def _near_top_count(bvx, bvy, sb, nb, hx, hy, imax, zmax_h, tol):
    """Number of b's vertices within tol of the top height (capped at 3)."""
    cnt = 1
    for step in (1, -1):
        j = imax
        for _ in range(2):
            j = (j + step) % nb
            if j == imax or hx * bvx[sb + j] + hy * bvy[sb + j] < zmax_h - tol:
                break
            cnt += 1
    return min(cnt, 3)


@njit(cache=True)
def pair_test(avx, avy, aeang, aetab, avang, ainv, sa, na, ra,
              bvx, bvy, beang, betab, sb, nb, rb,
              px, py, pz, r00, r01, r02, r10, r11, r12, r20, r21, r22, tol):
    """Collision test for one pair in a's centred frame.

    Returns (hit, case, cx, cy, cz): the case number and, on a hit, a contact
    point (a's centred frame) lying within tol of both bodies.
    """
    nan = math.nan
    hx = r20
    hy = r21
    c = r22
    imax = extreme_vertex(bvx, bvy, beang, betab, sb, nb, hx, hy)
    top_u = bvx[sb + imax]
    top_v = bvy[sb + imax]
    top_h = hx * top_u + hy * top_v
    d3 = pz + top_h  # the paper's Δ3
    if d3 < -tol and c <= 0.0:
        return False, CASE_ABOVE, nan, nan, nan  # the common case: leave at once
    pr = math.hypot(px, py)
    wn = math.hypot(r02, r12)
    T = (pr + ra + rb + 2.0 * tol) / max(wn, 1e-150)
    # Perpendicular within reach: b's axis changes height by at most tol/4
    # over T. Then c is taken as 0 and the height relaxation widened by
    # that change, so bodies within tol still hit (and a hit is within 2 tol).
    drift = abs(c) * T
    perp = drift <= 0.25 * tol
    ceff = 0.0 if perp else c
    tz = tol + drift if perp else tol

    # --- classification (labels; the decision below is one exact path) ---
    if d3 < -tol:
        if ceff <= 0.0:
            return False, CASE_ABOVE, nan, nan, nan
        case = CASE_RETURN
    elif d3 <= tol:
        if ceff > 0.0:
            case = CASE_RETURN
        else:
            k = _near_top_count(bvx, bvy, sb, nb, hx, hy, imax, top_h, tol)
            if perp:
                case = CASE_PERP_VERTEX if k == 1 else CASE_PERP_EDGE
            else:
                case = CASE_VERTEX + k - 1
    else:
        if perp:
            case = CASE_PERP_STRIP
        elif c < 0.0:
            case = CASE_POLYGON
        else:
            case = CASE_UNBOUNDED

    # Empty projection within reach (e.g. b's body re-enters beyond a).
    if d3 + max(ceff, 0.0) * T < -tz:
        return False, case, nan, nan, nan

    # --- coarse rejection (the paper's Δ4, rewritten without sec²α) ---
    margin = ra + rb + tol
    if wn > 0.0:
        ux = r02 / wn
        uy = r12 / wn
        along = ux * px + uy * py
        if abs(ux * py - uy * px) > margin or along > margin:
            return False, (CASE_COARSE if case == CASE_POLYGON else case), nan, nan, nan
        # Facing axes: the cross-section ends at t <= (Δ3 + tol) / |c|.
        if ceff < 0.0 and abs(c) * (-along - margin) > wn * (d3 + tz):
            return False, (CASE_COARSE if case == CASE_POLYGON else case), nan, nan, nan
    elif pr > margin:
        return False, (CASE_COARSE if case == CASE_POLYGON else case), nan, nan, nan

    # --- early accept: b's deepest end-face vertex projects inside P_a ---
    if d3 >= -tz:
        ex = px + r00 * top_u + r01 * top_v
        ey = py + r10 * top_u + r11 * top_v
        if point_polygon_distance(avx, avy, avang, ainv, sa, na, ex, ey) >= 0.0:
            return True, case, ex, ey, 0.5 * (d3 + max(d3, 0.0))

    # --- exact planar test: GJK of P_a against the projection of b ---
    imin = extreme_vertex(bvx, bvy, beang, betab, sb, nb, -hx, -hy)
    sp = (px, py, r00, r01, r10, r11, r02, r12, hx, hy, pz, ceff, T, tz, float(imin), float(imax))
    hit, _, ax, ay, u, v, t = gjk(avx, avy, aeang, aetab, sa, na, bvx, bvy, beang, betab, sb, nb, sp, tol)
    if not hit:
        return False, case, nan, nan, nan
    bx = px + r00 * u + r01 * v + r02 * t
    by = py + r10 * u + r11 * v + r12 * t
    bz = pz + r20 * u + r21 * v + r22 * t
    return True, case, 0.5 * (ax + bx), 0.5 * (ay + by), 0.5 * (bz + max(bz, 0.0))
