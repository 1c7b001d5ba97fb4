"""Projection of prism b onto prism a's end plane, case classification, test.

Everything here works in a's *centred frame*: origin at the centre of a's end
face, z along d_a (into a's body). b's pose in that frame is (p, R), so a
point of b is p + R [u, v, t] with (u, v) in b's polygon (about b's centre)
and t >= 0. Since a = P_a x [0, inf), the prisms meet iff the projection Q of
b ∩ {z >= 0} along z meets P_a (exact: a lies in that half-space). With

    h = (R20, R21), c = R22 = d_a.d_b (the paper's Δ1), w = (R02, R12),
    z(q, t) = p_z + h.q + c t,   Δ3 = max_q z(q, 0),

Q is the spec shape of :mod:`prismbatch._kernels.planar` with M = R[:2, :2]. Only the
part of Q within reach of P_a matters, so t is capped at
T = (|p_xy| + R_a + R_b + 2 tol) / |w|, which keeps every coordinate bounded
whatever the angle between the axes (no tan α or sec²α anywhere).

Why bodies within tol always hit and a hit lies within 2 tol (cases 7-9
included): ``docs/methods/projection.md``.
"""

import math

from .jit import jit
from .planar import extreme_vertex, gjk, point_polygon_distance
from .vec3 import length2

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

# --- step-by-step trace (used by `prismbatch replay`; the batch kernels pass
# None, which compiles every trace write away) ---
TRACE_FIELDS = (
    "tol",
    "p_x",
    "p_y",
    "p_z",
    "R00",
    "R01",
    "R02",
    "R10",
    "R11",
    "R12",
    "R20",
    "R21",
    "R22",
    "exit",
    "i_top",
    "delta3",
    "lateral_offset",
    "axis_xy_length",
    "reach_T",
    "height_drift",
    "perpendicular",
    "c_used",
    "height_tol",
    "near_top_vertices",
    "coarse_across",
    "coarse_along",
    "coarse_margin",
    "coarse_facing_lhs",
    "coarse_facing_rhs",
    "top_vertex_depth_in_Pa",
    "centre_depth_in_Pa",
    "i_bottom",
    "gjk_hit",
    "gjk_iterations",
    "case",
    "hit",
)
TRACE_SIZE = len(TRACE_FIELDS)
_T = {name: k for k, name in enumerate(TRACE_FIELDS)}
T_TOL, T_P, T_R, T_EXIT = _T["tol"], _T["p_x"], _T["R00"], _T["exit"]
T_ITOP, T_D3, T_PR, T_WN, T_REACH, T_DRIFT = (
    _T[k] for k in ("i_top", "delta3", "lateral_offset", "axis_xy_length", "reach_T", "height_drift")
)
T_PERP, T_CEFF, T_TZ, T_NTOP = _T["perpendicular"], _T["c_used"], _T["height_tol"], _T["near_top_vertices"]
T_ACROSS, T_ALONG, T_MARGIN = _T["coarse_across"], _T["coarse_along"], _T["coarse_margin"]
T_FACE_L, T_FACE_R, T_EARLY, T_EARLY_C, T_IBOT = (
    _T["coarse_facing_lhs"],
    _T["coarse_facing_rhs"],
    _T["top_vertex_depth_in_Pa"],
    _T["centre_depth_in_Pa"],
    _T["i_bottom"],
)
T_GJK_HIT, T_GJK_IT, T_CASE, T_HIT = _T["gjk_hit"], _T["gjk_iterations"], _T["case"], _T["hit"]

#: Where pair_test decided (trace field "exit").
EXITS = {
    1: "Δ3 < -tol and d_a.d_b <= 0: b's end face beyond a's plane and its body leaves it (no collision)",
    2: "Δ3 < -tol (-tol - drift when perpendicular) and d_a.d_b <= 0 after the perpendicular snap (no collision)",
    3: "the projection of b within reach of P_a is empty (no collision)",
    4: "coarse test: b's projected axis passes P_a at more than R_a + R_b + tol (no collision)",
    5: "coarse test: b's projection lies beyond P_a along the projected axis (no collision)",
    6: "coarse test: facing axes, b's cross-section ends before reaching P_a (no collision)",
    7: "coarse test: parallel axes, centres more than R_a + R_b + tol apart (no collision)",
    8: "early accept: b's deepest end-face vertex projects inside P_a (collision)",
    9: "2-D GJK: P_a and the projection of b are within tol (collision)",
    10: "2-D GJK: P_a and the projection of b are more than tol apart (no collision)",
    11: "early accept: b's end-face centre reaches a's plane and projects inside P_a (collision)",
}


@jit(inline="always")  # inlined: compiled apart, each call's literal arguments cost a copy (~0.15 s cold)
def _done(trace, exit_code, case, hit):
    if trace is not None:
        trace[T_EXIT] = exit_code
        trace[T_CASE] = case
        trace[T_HIT] = 1.0 if hit else 0.0


@jit(inline="always")
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


@jit(inline="always")
def _projects_inside(avx, avy, avang, ainv, sa, na, x, y, trace, field):
    """Does (x, y) lie in P_a? (Its signed depth goes to ``trace[field]``.)"""
    depth = point_polygon_distance(avx, avy, avang, ainv, sa, na, x, y)
    if trace is not None:
        trace[field] = depth
    return depth >= 0.0


@jit(inline="always")
def surely_above(bvx, bvy, sb, imax, pz, r20, r21, r22, tol):
    """The common case-1 exit, Δ3 < -tol and d_a.d_b <= 0 (b's end face beyond a's plane and its body
    leaving it): :func:`pair_test`'s first test, cheap enough for the caller to take ahead of the call."""
    return pz + (r20 * bvx[sb + imax] + r21 * bvy[sb + imax]) < -tol and r22 <= 0.0


@jit(inline="always")
def surely_above_by_radius(pz, r20, r21, r22, rb, tol):
    """:func:`surely_above` proven without b's deepest vertex: no vertex of b reaches further into
    a than its circumradius ``rb`` times the tilt ``|(r20, r21)|``. Most pairs that leave early
    leave here, before the vertex search, which costs more than everything else they do."""
    return r22 <= 0.0 and pz + math.sqrt(r20 * r20 + r21 * r21) * rb < -tol


@jit(inline="always")
def _plane_stretch(r00, r01, r10, r11):
    """How far b's end face can reach in a's plane per unit of its radius: the largest singular value of
    the block [[r00, r01], [r10, r11]] of R = Ra^-1 Rb, where it exceeds 1 (by more than rounding), else 1.

    For orthonormal rotations it is at most 1, but a rotation is used as given (an exact affine map), and
    a float32 matrix taken in float64 is orthonormal only to about 1e-7: its b reaches up to 1e-7 of its
    radius further than rb, which is thousands of float64 tolerances (the coarse tests below missed
    bodies 24 tol deep in each other on such rotations).
    """
    a = r00 * r00 + r10 * r10
    c = r01 * r01 + r11 * r11
    b = r00 * r01 + r10 * r11
    h = 0.5 * (a - c)
    s2 = 0.5 * (a + c) + math.sqrt(h * h + b * b)
    return math.sqrt(s2) if s2 > 1.0 + 1e-15 else 1.0


# Kept as one long function: the per-pair hot path (not split into calls, which would add call and
# tuple overhead per pair; a measured split is future work).
@jit
def pair_test(
    avx,
    avy,
    aeang,
    aetab,
    avang,
    ainv,
    sa,
    na,
    ra,
    bvx,
    bvy,
    beang,
    betab,
    sb,
    nb,
    rb,
    px,
    py,
    pz,
    r00,
    r01,
    r02,
    r10,
    r11,
    r12,
    r20,
    r21,
    r22,
    tol,
    imax,
    witness,
    trace,
):
    """Collision test for one pair in a's centred frame.

    Returns (hit, case, cx, cy, cz): the case number and, on a hit, a contact
    point (a's centred frame) lying within tol of both bodies; with ``witness``
    false the contact may be NaN (the planar GJK then skips it). ``trace`` is
    None (no tracing) or a float array of TRACE_SIZE that receives the
    intermediate quantities (fields TRACE_FIELDS, exit codes EXITS). ``imax``
    is b's end-face vertex deepest into a (``extreme_vertex`` in direction
    (r20, r21)), found by the caller for its own early exit. With
    None, Numba compiles a specialisation with every trace branch removed,
    so the batch kernels pay nothing for it (an array argument would cost
    reference counting on every call).
    """
    nan = math.nan
    hx = r20
    hy = r21
    c = r22
    top_u = bvx[sb + imax]
    top_v = bvy[sb + imax]
    top_h = hx * top_u + hy * top_v
    d3 = pz + top_h  # the paper's Δ3
    if trace is not None:
        trace[T_ITOP] = imax
        trace[T_D3] = d3
    if surely_above(bvx, bvy, sb, imax, pz, hx, hy, c, tol):  # d3 < -tol and c <= 0
        _done(trace, 1, CASE_ABOVE, False)
        return False, CASE_ABOVE, nan, nan, nan  # the common case: leave at once
    pr = length2(px, py)
    wn = length2(r02, r12)
    rb = rb * _plane_stretch(r00, r01, r10, r11)
    T = (pr + ra + rb + 2.0 * tol) / max(wn, 1e-150)
    # Perpendicular within reach: b's axis changes height by at most tol/4
    # over T. Then c is taken as 0 and the height relaxation widened by
    # that change, so bodies within tol still hit (and a hit is within 2 tol).
    drift = abs(c) * T
    perp = drift <= 0.25 * tol
    ceff = 0.0 if perp else c
    tz = tol + drift if perp else tol
    if trace is not None:
        trace[T_PR] = pr
        trace[T_WN] = wn
        trace[T_REACH] = T
        trace[T_DRIFT] = drift
        trace[T_PERP] = 1.0 if perp else 0.0
        trace[T_CEFF] = ceff
        trace[T_TZ] = tz

    # --- classification (labels; the decision below is one exact path) ---
    # Below -tz, not -tol: where the snap took c as 0, b's body may still rise by up to the drift within
    # reach, so a Δ3 between -tz and -tol can leave a gap under tol (0.906 tol was missed here).
    if d3 < -tz:
        if ceff <= 0.0:
            _done(trace, 2, CASE_ABOVE, False)
            return False, CASE_ABOVE, nan, nan, nan
        case = CASE_RETURN
    elif d3 <= tol:
        if ceff > 0.0:
            case = CASE_RETURN
        else:
            k = _near_top_count(bvx, bvy, sb, nb, hx, hy, imax, top_h, tol)
            if trace is not None:
                trace[T_NTOP] = k
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
        _done(trace, 3, case, False)
        return False, case, nan, nan, nan

    # --- coarse rejection (the paper's Δ4, rewritten without sec²α) ---
    margin = ra + rb + tol
    coarse = CASE_COARSE if case == CASE_POLYGON else case
    if wn > 0.0:
        ux = r02 / wn
        uy = r12 / wn
        along = ux * px + uy * py
        across = abs(ux * py - uy * px)
        if trace is not None:
            trace[T_ACROSS] = across
            trace[T_ALONG] = along
            trace[T_MARGIN] = margin
        if across > margin or along > margin:
            _done(trace, 4 if across > margin else 5, coarse, False)
            return False, coarse, nan, nan, nan
        # Facing axes: the cross-section ends at t <= (Δ3 + tol) / |c|.
        if ceff < 0.0:
            lhs = abs(c) * (-along - margin)
            rhs = wn * (d3 + tz)
            if trace is not None:
                trace[T_FACE_L] = lhs
                trace[T_FACE_R] = rhs
            if lhs > rhs:
                _done(trace, 6, coarse, False)
                return False, coarse, nan, nan, nan
    elif pr > margin:
        if trace is not None:
            trace[T_MARGIN] = margin
        _done(trace, 7, coarse, False)
        return False, coarse, nan, nan, nan

    # --- early accept: b's deepest end-face vertex, or its centre, projects inside P_a ---
    if d3 >= -tz:
        ex = px + r00 * top_u + r01 * top_v
        ey = py + r10 * top_u + r11 * top_v
        if _projects_inside(avx, avy, avang, ainv, sa, na, ex, ey, trace, T_EARLY):
            _done(trace, 8, case, True)
            return True, case, ex, ey, 0.5 * (d3 + max(d3, 0.0))
        # b's end-face centre, when it reaches a's plane too: for end faces nearly parallel to a's,
        # the deepest vertex is any corner and often outside P_a where the centre is inside (on
        # facing squares 86 % of the hits went on to GJK, which costs several times this test).
        if pz >= -tz and _projects_inside(avx, avy, avang, ainv, sa, na, px, py, trace, T_EARLY_C):
            _done(trace, 11, case, True)
            return True, case, px, py, 0.5 * (pz + max(pz, 0.0))

    # --- exact planar test: GJK of P_a against the projection of b ---
    imin = extreme_vertex(bvx, bvy, beang, betab, sb, nb, -hx, -hy)
    sp = (px, py, r00, r01, r10, r11, r02, r12, hx, hy, pz, ceff, T, tz, float(imin), float(imax))
    hit, iters, ax, ay, u, v, t = gjk(avx, avy, aeang, aetab, sa, na, bvx, bvy, beang, betab, sb, nb, sp, tol, witness)
    if trace is not None:
        trace[T_IBOT] = imin
        trace[T_GJK_HIT] = 1.0 if hit else 0.0
        trace[T_GJK_IT] = iters
    _done(trace, 9 if hit else 10, case, hit)
    if not hit:
        return False, case, nan, nan, nan
    if not witness:
        return True, case, nan, nan, nan
    bx = px + r00 * u + r01 * v + r02 * t
    by = py + r10 * u + r11 * v + r12 * t
    bz = pz + r20 * u + r21 * v + r22 * t
    return True, case, 0.5 * (ax + bx), 0.5 * (ay + by), 0.5 * (bz + max(bz, 0.0))
