"""Time of impact of a moving semi-infinite prism b against a fixed one a: conservative advancement.

b moves rigidly with constant world velocity v and angular velocity w about
its position: p_b(t) = p_b + v t, R_b(t) = exp(t [w]x) R_b. At each time the
signed distance d and its normal n (from a towards b) come from
:func:`~prismbatch._kernels.distance.pair_distance`; the time then advances by
the longest step that one of three bounds proves free of contact, and the
loop stops when d <= tol (the pair's touching tolerance) or once a step
passes the horizon.

b is semi-infinite: points far along its axis move arbitrarily fast when w
turns the axis. A contact at t' has a witness f_b + beta d_b on b with
f_b in b's end face, and 0 = k + alpha d_a - beta d_b with |k| <= S(t')
(S = R_a + R_b + |c_b - c_a|); so beta <= S(t') / sigma(t'), with sigma = 1
when d_a.d_b <= 0 and |d_a x d_b| otherwise; and while the axes face each
other, beta (-d_a.d_b) <= (c_b - c_a).d_a + R_b, since the witness lies in
a's half-space; alpha <= S(t') + beta. :func:`reach` takes the bound on beta
at its worst over a step (S grows at most at c_b's speed, the angle between
the axes changes at most at |w x d_b|).

The bounds (proofs in ``docs/methods/time-of-impact.md``):

- :func:`isotropic_step`: the gap d - m (m the distance's error) along the
  exact normal n*, within the angle phi of n, closes no faster than
  |v| cos(psi - phi) + |w| rho_b + |w x d_b| beta (any point of b's part
  that can touch).
- :func:`directional_step` in the world frame: along u = -n itself (no
  error cone) the gap is the separation of the support planes of a's and
  b's parts that can touch; it closes at the rate at which b's support
  along u grows, v.u + r*.(u x w), r* a support point of b. u turns in b's
  frame by at most |u x w| per unit time, so r* is one of the polygon's
  points within a cap of its support (:func:`face_rate`) or on the axis.
- the same in b's frame: a's support along u turning with b, its points'
  lever from p_b in place of r*; it is tight when a's support is a vertex
  and b's a face, the world frame when b's support is a vertex.

Near a contact the directional rates tend to the distance's own rate of
change, so the steps converge as Newton's method does rather than by a
constant factor.
"""

import math

import numpy as np
from numba import prange

from .batch import centres_world, unpack
from .distance import (
    ACC_EPS,
    BOX,
    EPA_ROOM,
    EPA_STOPPED,
    EPS64,
    LOOSE_FRACTION,
    block_of,
    pair_distance,
    pair_index,
    workspace,
)
from .jit import jit, twins
from .planar import extreme_vertex, slab_support
from .vec3 import rotate_by

#: Status codes of a pair: touching at ``time``; no contact up to the horizon; iteration cap reached
#: (or a step too small to advance the time), ``time`` then being how far the motion is proven free.
CONTACT, CLEAR, UNDECIDED = 1, 0, -1
#: Internal status of the batch loop: EPA ran out of the block's room; the pair is computed again with more.
RERUN = -2
#: :func:`face_rate` cuts at least this many radii (times |h|) below the top: over 100 times the band
#: of 8e-12 r within which an accepted outline's sides are straight only up to rounding.
FACE_BAND = 2.0**-30


@jit(inline="always")
def reach(step, S, theta, rise, centre_speed, w_perp):
    """Bound on the axial coordinate beta of b's point in a first contact within ``step``.

    ``S``: the pair scale now; ``theta``: the angle between the axes now; ``rise``:
    (c_b - c_a).d_a + R_b now. Over the step S grows by at most ``centre_speed`` step, and
    theta and the angle from antiparallel change by at most ``w_perp`` step. Every contact
    witness f_b + beta d_b has beta <= S' / sigma (sigma = 1 when d_a.d_b <= 0, else
    |d_a x d_b|), and, while the axes face each other, beta (-d_a.d_b) <= rise' (it lies in
    a's half-space). inf when neither bound holds over the whole step.
    """
    grow = centre_speed * step
    turn = w_perp * step
    low = theta - turn  # the least angle between the axes over the step
    sigma = 1.0 if low >= 0.5 * math.pi else (math.sin(low) if low > 0.0 else 0.0)
    beta = (S + grow) / sigma if sigma > 0.0 else math.inf
    away = math.pi - theta + turn  # the largest angle from antiparallel over the step
    if away < 0.5 * math.pi:
        beta = min(beta, max(0.0, rise + grow) / math.cos(away))
    return beta


@jit(inline="always")
def face_rate(vx, vy, eang, etab, s, n, r, hx, hy, imax, imin, drop, zx, zy):
    """An upper bound on the largest z.g over the points g of a polygon with h.g >= h.g_imax - drop.

    The polygon is a slice ``[s, s + n)`` of vertex arrays (about its centre), of radius ``r``; ``imax``
    and ``imin`` its vertices of largest and least h.g. The set is the polygon cut by a line, and the
    largest z.g over it is the unconstrained maximiser or an end of the chord on that line
    (:func:`~prismbatch._kernels.planar.slab_support`), O(log n).

    The cut goes at least FACE_BAND r |h| below the top, and a maximiser within that of it counts as
    inside: a side straight only up to rounding (within 8e-12 r of its line) is not monotone in h.g
    when h is normal to it, and a cut within that band (drop 0 or tiny, on a slow turn) found the
    chord's ends anywhere along it, short by up to the side's length. Enlarging the set only raises
    the bound.
    """
    hh = hx * hx + hy * hy
    band = FACE_BAND * r * math.sqrt(hh)
    level = hx * vx[s + imax] + hy * vy[s + imax] - max(drop, band)
    k = (zx * hx + zy * hy) / hh if hh > 0.0 else 0.0
    ex, ey = zx - k * hx, zy - k * hy  # orders the chord's points as z does, well conditioned
    gx, gy, _ = slab_support(vx, vy, eang, etab, s, n, zx, zy, hx, hy, imin, imax, level, math.inf, ex, ey, band)
    return zx * gx + zy * gy


@jit(inline="always")
def directional_bounds(step, q, side):
    """(g, V) over [t, t + step]: g a lower bound on the gap along u = -n between the parts of a and b
    that can touch within the step, V a bound on the rate at which it closes, in one frame.

    ``q``: the pair's quantities at t, ``side`` the frame's (see :func:`pair_time_of_impact`):
    the world frame follows b's support along u, b's frame a's support along u turning with b.
    See ``docs/methods/time-of-impact.md``.
    """
    sep, cut_a, cut_b, vu, uw, wn, speed, S, centre_speed, theta, rise, w_perp = q
    b_frame, lev_rate, lev_abs, lev_len, r, hx, hy, imax, imin, zx, zy, poly, lean, axis_rate, axis_perp = side
    drift = speed if b_frame else 0.0  # in b's frame u turns in the world and a's lever shifts by v
    delta = min(2.0, uw * step)  # how far u turns against the body whose support moves
    rate = vu + drift * delta + 16.0 * EPS64 * (speed + wn * (lev_len + r))  # (rounding)
    if wn > 0.0:  # the end face: its centre, then the polygon's points that can be the support along u~
        vx, vy, eang, etab, s, n = poly
        face = lev_rate + delta * lev_abs + drift * uw * step + r * wn * delta
        face += face_rate(vx, vy, eang, etab, s, n, r, hx, hy, imax, imin, 2.0 * r * delta, zx, zy)
        rate += min(face, uw * (lev_len + drift * step + r))
    axis = 0.0
    if axis_perp > 0.0 and lean + delta >= 0.0:  # the axis may lean along u: its far points can lead
        axis = min(axis_perp, max(0.0, axis_rate + delta * axis_perp)) + 16.0 * EPS64 * axis_perp
    if axis > 0.0 or cut_a > 0.0 or cut_b > 0.0:
        beta = reach(step, S, theta, rise, centre_speed, w_perp)
        if not beta < math.inf:
            return -math.inf, math.inf
        alpha = S + centre_speed * step + beta  # a's part that can touch (docs)
        rate += axis * (alpha if b_frame else beta)
        return sep - beta * cut_b - alpha * cut_a, rate
    return sep, rate


@jit(inline="always")
def directional_step(rest, q, side):
    """A step in [0, rest] free of contact by :func:`directional_bounds`; ``rest`` proves the rest free."""
    g0, v0 = directional_bounds(0.0, q, side)
    if not (g0 > 0.0 and v0 < math.inf):
        return 0.0
    step = rest if v0 <= 0.0 else min(rest, g0 / v0)
    for _ in range(8):  # a bound over a step holds for any shorter one
        g1, v1 = directional_bounds(step, q, side)
        if g1 > 0.0 and v1 < math.inf:
            break
        step *= 0.25
    else:
        return 0.0
    if step * v1 < g1:
        return step
    safe = g1 / v1  # shorter than step: V and g there are no worse than at step
    # V grows about linearly with the step: solve step (v0 + k step) = g1 for a longer candidate
    k = (v1 - v0) / step
    if k > 0.0:
        guess = 2.0 * g1 / (v0 + math.sqrt(v0 * v0 + 4.0 * k * g1))
        if guess > safe:
            g2, v2 = directional_bounds(guess, q, side)
            if guess * v2 < g2:
                return guess
            if g2 > 0.0 and v2 < math.inf:
                safe = max(safe, g2 / v2)
    return safe


@jit(inline="always")
def isotropic_step(rest, gap, approach, base, w_perp, S, theta, rise, centre_speed):
    """A step in [0, rest] free of contact by the whole-body bound ``approach + |w| rho_b + w_perp beta``
    on the speed along the exact normal, from the gap ``gap``; ``rest`` proves the rest free."""
    step = rest
    bound = approach + base
    if w_perp > 0.0:  # b's far points add |w x d_b| beta: bound beta over the step
        step = min(step, gap / (bound + w_perp * reach(0.0, S, theta, rise, centre_speed, w_perp)))
        far = math.inf
        for _ in range(8):  # the bound over a step holds for any shorter one: keep it if finite
            beta = reach(step, S, theta, rise, centre_speed, w_perp)
            if beta < math.inf:
                far = w_perp * beta
                break
            step *= 0.25
        bound += far
    if bound * step < gap:
        return step
    return gap / bound if bound < math.inf else 0.0


@jit
def pair_time_of_impact(P, ix, ca, cb, ra, rb, Pa, Ra, Pb0, Rb0, v, w, horizon, rtol, atol, eps, max_iter, ws, rerun):
    """One pair: (time, status, iterations, signed distance at time, contact point 3-tuple).

    ``P``, ``ix``, ``ca``, ``cb``, ``ra``, ``rb``: as :func:`pair_distance`;
    ``Pb0``, ``Rb0``: b's pose at t = 0; ``v``, ``w``: its velocity and angular
    velocity (world); ``ws``: (Pb, Rb, work) workspace (``work`` a block of
    :func:`~prismbatch._kernels.distance.workspace`), Pb and Rb left at
    b's pose at the returned time. The contact point (the midpoint of the
    witness points) is NaN unless the status is CONTACT. ``rerun``: return the status
    RERUN where EPA runs out of the room of ``work`` (the batch loop, which cannot allocate
    more); else go on with its bound, as :func:`~prismbatch._kernels.distance.pair_distance_any_room`
    does at its largest room.

    Each step is the longest of :func:`isotropic_step` and :func:`directional_step`
    in the world frame and in b's frame. Their ``q``: (the gap along u = -n less
    rounding, max(0, d_a.n), max(0, d_b.u), v.u, ``|u x w|``, ``|w|``, ``|v|``, S,
    c_b's speed, theta, rise, ``|w x d_b|``); a frame's ``side``: (b's frame or not,
    u.(w x l), ``|w x l|``, ``|l|`` with l the lever from p_b to the end-face centre
    whose support moves, that face's radius, the support direction in its plane,
    its vertices extreme along and against it, u x w in its plane, the polygon,
    its axis's lean along the support direction, u.(w x d), ``|w x d|``).
    """
    Pb, Rb, work = ws
    avx, avy, aeang, aetab, bvx, bvy, beang, betab = P
    poly_a = (avx, avy, aeang, aetab, ix[0], ix[1])
    poly_b = (bvx, bvy, beang, betab, ix[2], ix[3])
    vx, vy, vz = np.float64(v[0]), np.float64(v[1]), np.float64(v[2])
    wx, wy, wz = np.float64(w[0]), np.float64(w[1]), np.float64(w[2])
    speed = math.sqrt(vx * vx + vy * vy + vz * vz)
    wn = math.sqrt(wx * wx + wy * wy + wz * wz)
    # |w x d_b| is the same at every time: the rotation is about w.
    bx, by, bz = np.float64(Rb0[0, 2]), np.float64(Rb0[1, 2]), np.float64(Rb0[2, 2])
    bn = math.sqrt(bx * bx + by * by + bz * bz)
    qx, qy, qz = wy * bz - wz * by, wz * bx - wx * bz, wx * by - wy * bx
    w_perp = math.sqrt(qx * qx + qy * qy + qz * qz) / bn
    cbx, cby = np.float64(cb[0]), np.float64(cb[1])
    cen_b = math.sqrt(cbx * cbx + cby * cby)
    rho_b = cen_b + rb  # b's end face lies within this of p_b
    centre_speed = speed + wn * cen_b  # c_b's speed bound
    dax, day, daz = np.float64(Ra[0, 2]), np.float64(Ra[1, 2]), np.float64(Ra[2, 2])
    dan = math.sqrt(dax * dax + day * day + daz * daz)
    dax, day, daz = dax / dan, day / dan, daz / dan
    adx, ady, adz = wy * daz - wz * day, wz * dax - wx * daz, wx * day - wy * dax  # w x d_a
    w_perp_a = math.sqrt(adx * adx + ady * ady + adz * adz)  # how fast a's axis turns as b sees it
    pos0 = math.sqrt(np.float64(Pb0[0]) ** 2 + np.float64(Pb0[1]) ** 2 + np.float64(Pb0[2]) ** 2)
    nan = math.nan
    t = 0.0
    it = 0
    while True:
        for c in range(3):
            Pb[c] = Pb0[c] + v[c] * t
        rotate_by(t * wx, t * wy, t * wz, Rb0, Rb)
        # (np.bool_: with a literal True pair_distance would compile once more, for that constant)
        d, tol, code, n, pa = pair_distance(
            P, ix, ca, cb, ra, rb, Pa, Ra, Pb, Rb, rtol, atol, eps, np.bool_(True), work
        )
        if rerun and code == EPA_STOPPED:
            return t, RERUN, it, d, (nan, nan, nan)
        if d <= tol:
            h = 0.5 * d
            return t, CONTACT, it, d, (pa[0] + h * n[0], pa[1] + h * n[1], pa[2] + h * n[2])
        if it >= max_iter:
            return t, UNDECIDED, it, d, (nan, nan, nan)
        it += 1
        _, _, _, dx, dy, dz = centres_world(ca[0], ca[1], cb[0], cb[1], Pa, Ra, Pb, Rb)
        S = ra + rb + math.sqrt(dx * dx + dy * dy + dz * dz)
        rest = horizon - t  # no need to look further
        ex, ey, ez = Rb[0, 2], Rb[1, 2], Rb[2, 2]  # d_b now
        cx, cy, cz = day * ez - daz * ey, daz * ex - dax * ez, dax * ey - day * ex
        theta = math.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), dax * ex + day * ey + daz * ez)
        rise = dx * dax + dy * day + dz * daz + rb  # bounds (f_b - c_a).d_a over b's end face
        # 1. Along the exact normal n*: the gap is at least d - margin (the distance's error), n* is
        # within the angle phi of n (closest point of a convex set), and no point of b that can make
        # a contact approaches a faster than the whole-body bound.
        margin = max(LOOSE_FRACTION * tol, ACC_EPS * EPS64 * BOX * S)
        phi = 2.0 * math.asin(min(1.0, math.sqrt(2.0 * margin / d)))
        kx, ky, kz = vy * n[2] - vz * n[1], vz * n[0] - vx * n[2], vx * n[1] - vy * n[0]
        psi = math.atan2(math.sqrt(kx * kx + ky * ky + kz * kz), -(vx * n[0] + vy * n[1] + vz * n[2]))
        approach = speed * max(0.0, math.cos(max(0.0, psi - phi)))
        step = isotropic_step(rest, d - margin, approach, wn * rho_b, w_perp, S, theta, rise, centre_speed)
        # 2. Along the computed normal itself (u = -n, no error cone): the gap is the separation of the
        # end faces' support planes; it closes at the rate of b's support along u (world frame), or
        # of a's support along u turning with b (b's frame), each bounded directionally (see the docs).
        ux, uy, uz = -n[0], -n[1], -n[2]
        nax = Ra[0, 0] * n[0] + Ra[1, 0] * n[1] + Ra[2, 0] * n[2]  # n in a's end-face plane
        nay = Ra[0, 1] * n[0] + Ra[1, 1] * n[1] + Ra[2, 1] * n[2]
        ia = extreme_vertex(avx, avy, aeang, aetab, ix[0], ix[1], nax, nay)
        hx = Rb[0, 0] * ux + Rb[1, 0] * uy + Rb[2, 0] * uz  # u in b's end-face plane
        hy = Rb[0, 1] * ux + Rb[1, 1] * uy + Rb[2, 1] * uz
        ib = extreme_vertex(bvx, bvy, beang, betab, ix[2], ix[3], hx, hy)
        sep = -(dx * ux + dy * uy + dz * uz) - (nax * avx[ix[0] + ia] + nay * avy[ix[0] + ia])
        sep -= hx * bvx[ix[2] + ib] + hy * bvy[ix[2] + ib]
        # rounding of the pose along the motion, and of the supports (as the distance's own floor)
        sep -= ACC_EPS * EPS64 * BOX * S + 2.0 * EPS64 * (pos0 + speed * t)
        da_u = dax * ux + day * uy + daz * uz
        db_u = ex * ux + ey * uy + ez * uz
        zwx, zwy, zwz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx  # u x w
        uw = math.sqrt(zwx * zwx + zwy * zwy + zwz * zwz)
        q = (sep, max(0.0, -da_u), max(0.0, db_u), vx * ux + vy * uy + vz * uz, uw, wn, speed)
        q = q + (S, centre_speed, theta, rise, w_perp)
        # world frame: b's end-face centre c from p_b, its polygon, its axis
        cwx = Rb[0, 0] * cbx + Rb[0, 1] * cby
        cwy = Rb[1, 0] * cbx + Rb[1, 1] * cby
        cwz = Rb[2, 0] * cbx + Rb[2, 1] * cby
        ox, oy, oz = wy * cwz - wz * cwy, wz * cwx - wx * cwz, wx * cwy - wy * cwx  # w x c
        jb = extreme_vertex(bvx, bvy, beang, betab, ix[2], ix[3], -hx, -hy) if wn > 0.0 else ib
        zx = Rb[0, 0] * zwx + Rb[1, 0] * zwy + Rb[2, 0] * zwz
        zy = Rb[0, 1] * zwx + Rb[1, 1] * zwy + Rb[2, 1] * zwz
        lean_rate = ux * (wy * ez - wz * ey) + uy * (wz * ex - wx * ez) + uz * (wx * ey - wy * ex)  # u.(w x d_b)
        side = (False, ox * ux + oy * uy + oz * uz, math.sqrt(ox * ox + oy * oy + oz * oz), cen_b, rb, hx, hy)
        side = side + (ib, jb, zx, zy, poly_b, db_u, lean_rate, w_perp)
        step = max(step, directional_step(rest, q, side))
        if wn > 0.0 and step < rest:
            # b's frame: a's end-face centre from p_b, a's polygon, a's axis
            lx, ly, lz = cwx - dx, cwy - dy, cwz - dz  # c_a - p_b = (c_b - p_b) - (c_b - c_a)
            ox, oy, oz = wy * lz - wz * ly, wz * lx - wx * lz, wx * ly - wy * lx  # w x l
            ja = extreme_vertex(avx, avy, aeang, aetab, ix[0], ix[1], -nax, -nay)
            zx = Ra[0, 0] * zwx + Ra[1, 0] * zwy + Ra[2, 0] * zwz
            zy = Ra[0, 1] * zwx + Ra[1, 1] * zwy + Ra[2, 1] * zwz
            lever = math.sqrt(lx * lx + ly * ly + lz * lz)
            side = (True, ox * ux + oy * uy + oz * uz, math.sqrt(ox * ox + oy * oy + oz * oz), lever, ra, nax, nay)
            side = side + (ia, ja, zx, zy, poly_a, -da_u, adx * ux + ady * uy + adz * uz, w_perp_a)
            step = max(step, directional_step(rest, q, side))
        if step >= rest:  # the whole rest of the horizon is free of contact
            return math.inf, CLEAR, it, nan, (nan, nan, nan)
        if not step > 0.0 or t + step == t:  # cannot advance: say so rather than guess
            return t, UNDECIDED, it, d, (nan, nan, nan)
        t += step


def _toi_loop(
    a_floats, a_ints, b_floats, b_ints, poses, motion, rtol, atol, eps, max_iter, work, out, pose_out, contact
):
    """Every pair of a batch, in as many contiguous blocks as ``work`` has: (Pb (blocks, 3), Rb
    (blocks, 3, 3), a :func:`~prismbatch._kernels.distance.workspace`); ``poses``: (pos_a, rot_a,
    pos_b, rot_b), ``motion``: (velocity, angular_velocity, horizon), each of N or 1 rows; ``out``:
    (time, status, iterations, distance), N each; ``pose_out``: (pos_b, rot_b) at that time, N or 0
    rows; ``contact``: N x 3 or 0 x 3. A pair whose EPA ran out of room has status RERUN (see
    :func:`_rerun_loop`)."""
    avx, avy, aeang, aetab, _, _, aoff, arad, acen = unpack(a_floats, a_ints)
    bvx, bvy, beang, betab, _, _, boff, brad, bcen = unpack(b_floats, b_ints)
    P = (avx, avy, aeang, aetab, bvx, bvy, beang, betab)
    pos_a, rot_a, pos_b, rot_b = poses
    vel, omg, horizon = motion
    time_out, status_out, iter_out, dist_out = out
    pos_out, rot_out = pose_out
    n = time_out.shape[0]
    blocks = work[0].shape[0]
    for bp in prange(blocks):
        blk = np.int64(bp)  # prange's index is unsigned
        ws = (work[0][blk], work[1][blk], block_of(work[2:], blk))
        for i in range(blk * n // blocks, (blk + 1) * n // blocks):
            _one(i, P, aoff, arad, acen, boff, brad, bcen, pos_a, rot_a, pos_b, rot_b, vel, omg, horizon, rtol,
                 atol, eps, max_iter, ws, np.bool_(True), time_out, status_out, iter_out, dist_out, pos_out, rot_out,
                 contact)  # fmt: skip


def _rerun_loop(a_floats, a_ints, b_floats, b_ints, poses, motion, rtol, atol, eps, max_iter, pairs, blocks, out,
                pose_out, contact):  # fmt: skip
    """The pairs ``pairs`` (indices) that :func:`_toi_loop` left with status RERUN, with EPA's largest room
    (the same answer as growing it step by step: a room only matters once it is full), in ``blocks``
    contiguous blocks that each allocate that room once."""
    avx, avy, aeang, aetab, _, _, aoff, arad, acen = unpack(a_floats, a_ints)
    bvx, bvy, beang, betab, _, _, boff, brad, bcen = unpack(b_floats, b_ints)
    P = (avx, avy, aeang, aetab, bvx, bvy, beang, betab)
    pos_a, rot_a, pos_b, rot_b = poses
    vel, omg, horizon = motion
    time_out, status_out, iter_out, dist_out = out
    pos_out, rot_out = pose_out
    m = pairs.shape[0]
    for bp in prange(blocks):
        blk = np.int64(bp)  # prange's index is unsigned
        ws = (np.empty(3), np.empty((3, 3)), block_of(workspace(1, EPA_ROOM[-1]), 0))
        for k in range(blk * m // blocks, (blk + 1) * m // blocks):
            _one(pairs[k], P, aoff, arad, acen, boff, brad, bcen, pos_a, rot_a, pos_b, rot_b, vel, omg, horizon, rtol,
                 atol, eps, max_iter, ws, np.bool_(False), time_out, status_out, iter_out, dist_out, pos_out, rot_out,
                 contact)  # fmt: skip


@jit(inline="always")
def _one(i, P, aoff, arad, acen, boff, brad, bcen, pos_a, rot_a, pos_b, rot_b, vel, omg, horizon, rtol, atol, eps,
         max_iter, ws, rerun, time_out, status_out, iter_out, dist_out, pos_out, rot_out, contact):  # fmt: skip
    """Pair i of the batch, into row i of the outputs (a batch of one broadcasts by index)."""
    ka, kb, ix, r = pair_index(i, arad, aoff, brad, boff, pos_a.shape[0], rot_a.shape[0], pos_b.shape[0],
                               rot_b.shape[0])  # fmt: skip
    Pa, Ra, Pb, Rb = pos_a[r[0]], rot_a[r[1]], pos_b[r[2]], rot_b[r[3]]
    v, w, h = vel[min(i, vel.shape[0] - 1)], omg[min(i, omg.shape[0] - 1)], horizon[min(i, horizon.shape[0] - 1)]
    t, st, it, d, p = pair_time_of_impact(
        P, ix, acen[ka], bcen[kb], arad[ka], brad[kb], Pa, Ra, Pb, Rb, v, w, h, rtol, atol, eps, max_iter, ws, rerun
    )
    time_out[i] = t
    status_out[i] = st
    iter_out[i] = it
    dist_out[i] = d
    if pos_out.shape[0] > 0:
        fin = st != CLEAR
        for c in range(3):
            pos_out[i, c] = ws[0][c] if fin else math.nan
            for j in range(3):
                rot_out[i, c, j] = ws[1][c, j] if fin else math.nan
    if contact.shape[0] > 0:
        for c in range(3):
            contact[i, c] = p[c]


# The batch loop allocates nothing (its workspace comes in), so it runs without reference counting (jit's
# default); the second pass allocates EPA's largest room and counts.
toi_serial, toi_parallel = twins(_toi_loop, "time_of_impact", error_model="numpy")
toi_rerun_serial, toi_rerun_parallel = twins(_rerun_loop, "time_of_impact_rerun", error_model="numpy", refcounts=True)
