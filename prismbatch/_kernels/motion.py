"""Time of impact of a moving semi-infinite prism b against a fixed one a: conservative advancement.

b moves rigidly with constant world velocity v and angular velocity w about
its position: p_b(t) = p_b + v t, R_b(t) = exp(t [w]x) R_b. At each time the
signed distance d and its normal n (from a towards b) come from
:func:`~prismbatch._kernels.distance.pair_distance`; the time then advances by
(d - m) / V, where m covers the distance's error and V bounds how fast any
point of b that can take part in a contact approaches a along the exact
normal. The loop stops when d <= tol (the pair's touching tolerance) or once
the step passes the horizon.

b is semi-infinite: points far along its axis move arbitrarily fast when w
turns the axis. A contact at t' has a witness f_b + beta d_b on b with
f_b in b's end face, and 0 = k + alpha d_a - beta d_b with |k| <= S(t')
(S = R_a + R_b + |c_b - c_a|); so beta <= S(t') / sigma(t'), with sigma = 1
when d_a.d_b <= 0 and |d_a x d_b| otherwise; and while the axes face each
other, beta (-d_a.d_b) <= (c_b - c_a).d_a + R_b, since the witness lies in
a's half-space. Only b's points with axial coordinate up to that bound can
make the first contact; they move at most at |w| rho_b + |w x d_b| beta on
top of v (rho_b: the largest distance of b's end face from p_b).
:func:`reach` takes the bound at its worst over a step (S grows at most at
c_b's speed, the angle between the axes changes at most at |w x d_b|); a
step whose own bound allows it is kept. The proof is in
``docs/methods/time-of-impact.md``.
"""

import math

import numpy as np
from numba import prange

from .batch import centres_world, unpack
from .distance import ACC_EPS, BOX, EPS64, LOOSE_FRACTION, pair_distance
from .jit import jit, twins

#: Status codes of a pair: touching at ``time``; no contact up to the horizon; iteration cap reached
#: (or a step too small to advance the time), ``time`` then being how far the motion is proven free.
CONTACT, CLEAR, UNDECIDED = 1, 0, -1


@jit(inline="always")
def rotate(wx, wy, wz, t, R0, R):
    """R = exp(t [w]x) R0 (Rodrigues), written into R."""
    wn = math.sqrt(wx * wx + wy * wy + wz * wz)
    th = t * wn
    if th == 0.0:
        for i in range(3):
            for j in range(3):
                R[i, j] = R0[i, j]
        return
    kx, ky, kz = wx / wn, wy / wn, wz / wn
    s = math.sin(th)
    c1 = 2.0 * math.sin(0.5 * th) ** 2  # 1 - cos, without its cancellation at small angles
    m00, m01, m02 = 1.0 - c1 * (ky * ky + kz * kz), c1 * kx * ky - s * kz, c1 * kx * kz + s * ky
    m10, m11, m12 = c1 * kx * ky + s * kz, 1.0 - c1 * (kx * kx + kz * kz), c1 * ky * kz - s * kx
    m20, m21, m22 = c1 * kx * kz - s * ky, c1 * ky * kz + s * kx, 1.0 - c1 * (kx * kx + ky * ky)
    for j in range(3):
        r0, r1, r2 = R0[0, j], R0[1, j], R0[2, j]
        R[0, j] = m00 * r0 + m01 * r1 + m02 * r2
        R[1, j] = m10 * r0 + m11 * r1 + m12 * r2
        R[2, j] = m20 * r0 + m21 * r1 + m22 * r2


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


@jit
def pair_time_of_impact(P, ix, ca, cb, ra, rb, Pa, Ra, Pb0, Rb0, v, w, horizon, rtol, atol, eps, max_iter, ws):
    """One pair: (time, status, iterations, signed distance at time, contact point 3-tuple).

    ``P``, ``ix``, ``ca``, ``cb``, ``ra``, ``rb``: as :func:`pair_distance`;
    ``Pb0``, ``Rb0``: b's pose at t = 0; ``v``, ``w``: its velocity and angular
    velocity (world); ``ws``: (Pb, Rb, W, I, lam) workspace, Pb and Rb left at
    b's pose at the returned time. The contact point (the midpoint of the
    witness points) is NaN unless the status is CONTACT.
    """
    Pb, Rb, W, I, lam = ws
    vx, vy, vz = np.float64(v[0]), np.float64(v[1]), np.float64(v[2])
    wx, wy, wz = np.float64(w[0]), np.float64(w[1]), np.float64(w[2])
    speed = math.sqrt(vx * vx + vy * vy + vz * vz)
    wn = math.sqrt(wx * wx + wy * wy + wz * wz)
    # |w x d_b| is the same at every time: the rotation is about w.
    bx, by, bz = np.float64(Rb0[0, 2]), np.float64(Rb0[1, 2]), np.float64(Rb0[2, 2])
    bn = math.sqrt(bx * bx + by * by + bz * bz)
    qx, qy, qz = wy * bz - wz * by, wz * bx - wx * bz, wx * by - wy * bx
    w_perp = math.sqrt(qx * qx + qy * qy + qz * qz) / bn
    cen_b = math.sqrt(cb[0] * cb[0] + cb[1] * cb[1])
    rho_b = cen_b + rb  # b's end face lies within this of p_b
    centre_speed = speed + wn * cen_b  # c_b's speed bound
    dax, day, daz = np.float64(Ra[0, 2]), np.float64(Ra[1, 2]), np.float64(Ra[2, 2])
    dan = math.sqrt(dax * dax + day * day + daz * daz)
    dax, day, daz = dax / dan, day / dan, daz / dan
    nan = math.nan
    t = 0.0
    it = 0
    while True:
        for c in range(3):
            Pb[c] = Pb0[c] + v[c] * t
        rotate(wx, wy, wz, t, Rb0, Rb)
        d, tol, _, n, pa = pair_distance(P, ix, ca, cb, ra, rb, Pa, Ra, Pb, Rb, rtol, atol, eps, True, W, I, lam)
        if d <= tol:
            h = 0.5 * d
            return t, CONTACT, it, d, (pa[0] + h * n[0], pa[1] + h * n[1], pa[2] + h * n[2])
        if it >= max_iter:
            return t, UNDECIDED, it, d, (nan, nan, nan)
        it += 1
        _, _, _, dx, dy, dz = centres_world(ca[0], ca[1], cb[0], cb[1], Pa, Ra, Pb, Rb)
        S = ra + rb + math.sqrt(dx * dx + dy * dy + dz * dz)
        margin = max(LOOSE_FRACTION * tol, ACC_EPS * EPS64 * BOX * S)  # the distance's error
        gap = d - margin  # the exact gap is at least this
        # The exact normal n* is within the chord 2 sqrt(2 margin / d) of n (closest point of a convex
        # set), an angle phi; -v.n* is at most |v| cos(angle(-v, n) - phi).
        phi = 2.0 * math.asin(min(1.0, math.sqrt(2.0 * margin / d)))
        ux, uy, uz = vy * n[2] - vz * n[1], vz * n[0] - vx * n[2], vx * n[1] - vy * n[0]
        psi = math.atan2(math.sqrt(ux * ux + uy * uy + uz * uz), -(vx * n[0] + vy * n[1] + vz * n[2]))
        approach = speed * max(0.0, math.cos(max(0.0, psi - phi)))
        bound = approach + wn * rho_b  # the approach speed of b's end face (and any point near it)
        step = horizon - t  # no need to look further
        if w_perp > 0.0:  # b's far points add |w x d_b| beta: bound beta over the step
            ex, ey, ez = Rb[0, 2], Rb[1, 2], Rb[2, 2]
            cx, cy, cz = day * ez - daz * ey, daz * ex - dax * ez, dax * ey - day * ex
            theta = math.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), dax * ex + day * ey + daz * ez)
            rise = dx * dax + dy * day + dz * daz + rb  # bounds (f_b - c_a).d_a over b's end face
            base = bound
            step = min(step, gap / (base + w_perp * reach(0.0, S, theta, rise, centre_speed, w_perp)))
            bound = math.inf
            for _ in range(8):  # the bound over a step holds for any shorter one: keep it if finite
                beta = reach(step, S, theta, rise, centre_speed, w_perp)
                if beta < math.inf:
                    bound = base + w_perp * beta
                    break
                step *= 0.25
        if bound * step < gap:  # the whole step is free of contact
            if step == horizon - t:
                return math.inf, CLEAR, it, nan, (nan, nan, nan)
        else:
            step = gap / bound  # shorter than step: the bound holds over it
        if not step > 0.0 or t + step == t:  # cannot advance: say so rather than guess
            return t, UNDECIDED, it, d, (nan, nan, nan)
        t += step


def _toi_loop(a_floats, a_ints, b_floats, b_ints, poses, motion, rtol, atol, eps, max_iter, out, pose_out, contact):
    """Every pair of a batch; ``poses``: (pos_a, rot_a, pos_b, rot_b), ``motion``: (velocity,
    angular_velocity, horizon), each of N or 1 rows; ``out``: (time, status, iterations, distance),
    N each; ``pose_out``: (pos_b, rot_b) at that time, N or 0 rows; ``contact``: N x 3 or 0 x 3."""
    avx, avy, aeang, aetab, _, _, aoff, arad, acen = unpack(a_floats, a_ints)
    bvx, bvy, beang, betab, _, _, boff, brad, bcen = unpack(b_floats, b_ints)
    P = (avx, avy, aeang, aetab, bvx, bvy, beang, betab)
    pos_a, rot_a, pos_b, rot_b = poses
    vel, omg, horizon = motion
    time_out, status_out, iter_out, dist_out = out
    pos_out, rot_out = pose_out
    npa, nra, npb, nrb = pos_a.shape[0], rot_a.shape[0], pos_b.shape[0], rot_b.shape[0]
    nv, nw, nh = vel.shape[0], omg.shape[0], horizon.shape[0]
    nsa, nsb = arad.shape[0], brad.shape[0]
    for ip in prange(time_out.shape[0]):
        i = np.int64(ip)  # prange's index is unsigned
        ka, kb = min(i, nsa - 1), min(i, nsb - 1)  # a batch of one broadcasts
        ix = (aoff[ka], aoff[ka + 1] - aoff[ka], boff[kb], boff[kb + 1] - boff[kb])
        ws = (np.empty(3), np.empty((3, 3)), np.empty((8, 3)), np.empty((8, 3), dtype=np.int64), np.empty(8))
        Pa, Ra, Pb, Rb = pos_a[min(i, npa - 1)], rot_a[min(i, nra - 1)], pos_b[min(i, npb - 1)], rot_b[min(i, nrb - 1)]
        t, st, it, d, p = pair_time_of_impact(
            P,
            ix,
            acen[ka],
            bcen[kb],
            arad[ka],
            brad[kb],
            Pa,
            Ra,
            Pb,
            Rb,
            vel[min(i, nv - 1)],
            omg[min(i, nw - 1)],
            horizon[min(i, nh - 1)],
            rtol,
            atol,
            eps,
            max_iter,
            ws,
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


toi_serial, toi_parallel = twins(_toi_loop, "time_of_impact", error_model="numpy")
