"""Sampled poses for :mod:`prismbatch.probability`: ``p = p0 + dp``, ``R = exp([dtheta]x) R0``.

Two loops, each compiled serial and parallel (:func:`~prismbatch._kernels.jit.twins`):

- :data:`sample_serial` / :data:`sample_parallel`: sample s forms the noise ``x = L[q] z[s]``
  of its query ``q = query[s]`` (b's six components first, then a's when there are twelve),
  perturbs the query's nominal poses and writes only row s of the outputs (the search for
  design points, which needs the poses);
- :data:`count_serial` / :data:`count_parallel`: the estimate's samples, drawn, posed and
  tested for contact in one pass with nothing stored per sample (it runs at about the rate
  of ``collide`` on ready-made poses, not at that of NumPy's generator and batches of
  arrays). Task t draws samples ``start[t] .. start[t] + count[t] - 1`` of query
  ``query[t]`` from the query's stream (:mod:`~prismbatch._kernels.streams`), so the result
  does not depend on how the samples are cut into tasks or spread over threads; it writes
  only its own slots.
"""

import math

import numpy as np
from numba import prange

from .batch import frame_inverse, pair_of_sets, unpack
from .jit import jit, twins
from .streams import normal, sample_state, uniform
from .vec3 import rotate_by


@jit(inline="always", error_model="numpy")
def _perturb(L, z, q, s, row, pos0, rot0, pos, rot):
    """Row s of ``pos``/``rot``: the nominal pose of query q moved by ``x = L[q, row:row + 6] z[s]``."""
    k = z.shape[1]
    x0 = x1 = x2 = tx = ty = tz = 0.0
    for c in range(k):
        zc = z[s, c]
        x0 += L[q, row, c] * zc
        x1 += L[q, row + 1, c] * zc
        x2 += L[q, row + 2, c] * zc
        tx += L[q, row + 3, c] * zc
        ty += L[q, row + 4, c] * zc
        tz += L[q, row + 5, c] * zc
    rotate_by(tx, ty, tz, rot0[q], rot[s])
    pos[s, 0] = pos0[q, 0] + x0
    pos[s, 1] = pos0[q, 1] + x1
    pos[s, 2] = pos0[q, 2] + x2


@jit(inline="always")
def pose_usable(P, R, max_magnitude):
    """A sampled pose that collide may take: every coordinate of P within ``max_magnitude`` and
    every entry of R finite (a NaN fails both; R turns NaN when its rotation vector's length
    overflows). Free of branches, whose mispredictions cost the sampling loop some 10 ns a sample."""
    ok = (abs(P[0]) <= max_magnitude) & (abs(P[1]) <= max_magnitude) & (abs(P[2]) <= max_magnitude)
    nan_if_not_finite = 0.0
    for i in range(3):
        for j in range(3):
            nan_if_not_finite += R[i, j] - R[i, j]
    return ok & (nan_if_not_finite == 0.0)


@jit
def poses_usable(pos, rot, max_magnitude, out):
    """``out[s]``: :func:`pose_usable` of row s."""
    for s in range(pos.shape[0]):
        out[s] = pose_usable(pos[s], rot[s], max_magnitude)


def _sample_loop(query, L, z, pos_a0, rot_a0, pos_b0, rot_b0, pos_a, rot_a, pos_b, rot_b):
    """Poses of the noise ``L[query[s]] z[s]`` of every sample s (a's nominal pose when ``z`` has 6 columns)."""
    for s in prange(query.shape[0]):
        q = query[s]
        _perturb(L, z, q, s, 0, pos_b0, rot_b0, pos_b, rot_b)
        if z.shape[1] == 12:
            _perturb(L, z, q, s, 6, pos_a0, rot_a0, pos_a, rot_a)
        else:
            for j in range(3):
                pos_a[s, j] = pos_a0[q, j]
                for i in range(3):
                    rot_a[s, i, j] = rot_a0[q, i, j]


sample_serial, sample_parallel = twins(_sample_loop, "sample_poses", error_model="numpy")


@jit(inline="always", error_model="numpy")
def _draw_proposal(state, z, t, q, j0, j1, mu, cum, active, spread, defensive):
    """Move the standard normals ``z[t]`` to a draw of query q's defensive mixture; returns the state.

    The mixture is ``d N(0, I) + (1 - d) sum_j pi_j N(mu_j, S)`` over centres ``j0 .. j1 - 1``
    (``cum[j] = d + (1 - d) (pi_j0 + ... + pi_j)``), ``S`` ``spread^2`` on the query's active
    noise components and 1 on the others (which then cancel from the weight).
    """
    k = z.shape[1]
    w, state = uniform(state)
    if w >= defensive:  # centre j by its weight; the nominal N(0, I) below ``defensive``
        j = j0
        while j < j1 - 1 and w >= cum[j]:
            j += 1
        for c in range(k):
            if active[q, c]:
                z[t, c] = mu[j, c] + spread * z[t, c]
    return state


@jit(inline="always")
def _rescaled(s1, s2, s3, scale):
    """The power sums of the weights (s1, s2, s3) after every weight is multiplied by ``scale``."""
    return s1 * scale, s2 * scale * scale, s3 * scale * scale * scale


@jit(inline="always")
def _active_norm2(z, t, q, active):
    """``|z[t]|^2`` over query q's active noise components."""
    zz = 0.0
    for c in range(z.shape[1]):
        if active[q, c]:
            zz += z[t, c] * z[t, c]
    return zz


@jit(inline="always", error_model="numpy")
def _centre_exponent(z, t, q, j, mu, lpi, active, consts, zz):
    """``log(pi_j N(z; mu_j, S) / N(z; 0, I))`` of the draw ``z[t]`` (``zz = |z|^2`` over the active
    components), the mixture's centre j against the nominal distribution."""
    half_inv_s2, log_spread_n = consts[2], consts[3]
    d2 = 0.0
    for c in range(z.shape[1]):
        if active[q, c]:
            e = z[t, c] - mu[j, c]
            d2 += e * e
    return lpi[j] - half_inv_s2 * d2 + 0.5 * zz - log_spread_n


@jit(inline="always", error_model="numpy")
def _weight(z, t, q, j0, j1, mu, lpi, active, consts):
    """``phi(z) / q(z)`` of the draw ``z[t]`` of :func:`_draw_proposal` (``log pi_j = lpi[j]``),
    at most ``1 / d``; 0.0 where it may be below ``exp(-600)``, whose logarithm
    :func:`_log_weight` then gives. Only hits need it, so the loop forms it after the test.
    ``consts``: ``(log d, log(1 - d), 0.5 / spread^2, n_active log spread, d)``. One exponential
    a centre: the logarithm's form costs three transcendentals a hit, some 10 % of the loop."""
    zz = _active_norm2(z, t, q, active)
    ratio = 0.0  # q(z) / phi(z) over the centres' part
    for j in range(j0, j1):
        e = _centre_exponent(z, t, q, j, mu, lpi, active, consts, zz)
        if e > 600.0:  # the weight may leave the normal floats (and exp(e) overflow at 709)
            return 0.0
        ratio += math.exp(e)
    d = consts[4]
    return 1.0 / (d + (1.0 - d) * ratio)


@jit(inline="always", error_model="numpy")
def _log_weight(z, t, q, j0, j1, mu, lpi, active, consts):
    """``log(phi(z) / q(z))`` of the draw ``z[t]``, for weights of any size (see :func:`_weight`).
    The tests compare both with a NumPy form of the same formulas."""
    log_d, log_1md = consts[0], consts[1]
    zz = _active_norm2(z, t, q, active)
    # log sum_j exp(e_j) in one pass (running maximum m, sum acc of exp(e_j - m)). A term below
    # exp(-60) of the largest is not added: it could not change acc >= 1 in double precision,
    # and skipping it saves its exponential.
    m, acc = -math.inf, 0.0
    for j in range(j0, j1):
        e = _centre_exponent(z, t, q, j, mu, lpi, active, consts, zz)
        if e > m:
            acc = (acc * math.exp(m - e) if m - e > -60.0 else 0.0) + 1.0
            m = e
        elif e - m > -60.0:
            acc += math.exp(e - m)
    lr = m + math.log(acc) if acc != 1.0 else m  # one term: no log needed
    # -log(d + (1 - d) exp(lr)), as a log-sum-exp
    x, y = log_d, log_1md + lr
    top = max(x, y)
    return -(top + math.log1p(math.exp(-abs(x - y))))


def _count_loop(
    a_floats,
    a_ints,
    b_floats,
    b_ints,
    task_query,
    task_start,
    task_count,
    keys,
    L,
    pos_a0,
    rot_a0,
    pos_b0,
    rot_b0,
    mix_start,
    mu,
    lpi,
    cum,
    active,
    defensive,
    spread,
    zk,
    zw,
    zf,
    zr,
    rtol,
    atol,
    eps,
    max_magnitude,
    z,
    pos_a,
    rot_a,
    pos_b,
    rot_b,
    hits,
    shift,
    sums,
    bad,
):
    """Task t: ``hits[t]`` of ``task_count[t]`` samples and the power sums ``sums[t, 0:3]`` of the
    hits' weights ``exp(lw - shift[t])`` (weights 1 for a query with no mixture, ``mix_start[q]
    == mix_start[q + 1]``). ``z`` and the pose arrays are scratch, one row per task; ``bad[t]``
    is the first sample that fails :func:`pose_usable` (-1 if none)."""
    a, b = unpack(a_floats, a_ints), unpack(b_floats, b_ints)
    k = z.shape[1]
    half_inv_s2 = 0.5 / (spread * spread)
    log_d, log_1md = math.log(defensive), math.log1p(-defensive)
    for tp in prange(task_query.shape[0]):
        t = np.int64(tp)
        q = task_query[t]
        j0, j1 = mix_start[q], mix_start[q + 1]
        n_active = 0
        for c in range(k):
            n_active += active[q, c]
        consts = (log_d, log_1md, half_inv_s2, n_active * math.log(spread), defensive)
        for j in range(3):  # a's nominal pose, for six-component noise
            pos_a[t, j] = pos_a0[q, j]
            for i in range(3):
                rot_a[t, i, j] = rot_a0[q, i, j]
        inv_a = frame_inverse(rot_a[t])  # a stays put under six-component noise
        count, top, s1, s2, s3 = 0, -math.inf, 0.0, 0.0, 0.0
        top_w, inv_top = 0.0, math.inf  # exp(top), exp(-top): finite wherever a linear weight w <= top_w uses them
        bad[t] = -1
        for s in range(task_count[t]):
            state = sample_state(keys[q], np.uint64(task_start[t] + s))
            for c in range(k):  # components that move nothing are not drawn (they change no pose or weight)
                if active[q, c]:
                    z[t, c], state = normal(state, zk, zw, zf, zr)
                else:
                    z[t, c] = 0.0
            if j1 > j0:
                state = _draw_proposal(state, z, t, q, j0, j1, mu, cum, active, spread, defensive)
            _perturb(L, z, q, t, 0, pos_b0, rot_b0, pos_b, rot_b)
            if k == 12:
                _perturb(L, z, q, t, 6, pos_a0, rot_a0, pos_a, rot_a)
                inv_a = frame_inverse(rot_a[t])
            # collide's input checks are not run here, so the loop makes its own
            usable = pose_usable(pos_b[t], rot_b[t], max_magnitude)
            if k == 12:
                usable &= pose_usable(pos_a[t], rot_a[t], max_magnitude)
            if not usable:
                bad[t] = s
                break
            # (a hit is all the estimate needs: no contact point, witness=False)
            Pa, Ra, Pb, Rb = pos_a[t], rot_a[t], pos_b[t], rot_b[t]
            # (np.bool_: a literal False would compile pair_test and its callees once more)
            hit = pair_of_sets(a, b, 0, 0, Pa, Ra, inv_a, Pb, Rb, rtol, atol, eps, np.bool_(False), None)[0]
            if hit:
                count += 1
                # a running shift (the largest log weight) keeps the sums' relative error for tiny weights
                w = _weight(z, t, q, j0, j1, mu, lpi, active, consts) if j1 > j0 else 1.0
                if w > 0.0:
                    if w > top_w:
                        scale = top_w / w
                        s1, s2, s3 = _rescaled(s1, s2, s3, scale)
                        top, top_w, inv_top = math.log(w), w, 1.0 / w
                    e = w * inv_top
                else:  # below exp(-600): in logarithms
                    lw = _log_weight(z, t, q, j0, j1, mu, lpi, active, consts)
                    if lw > top:
                        scale = math.exp(top - lw)
                        s1, s2, s3 = _rescaled(s1, s2, s3, scale)
                        top, top_w, inv_top = lw, math.exp(lw), math.exp(-lw)
                    e = math.exp(lw - top)
                s1 += e
                s2 += e * e
                s3 += e * e * e
        hits[t] = count
        shift[t] = top
        sums[t, 0] = s1
        sums[t, 1] = s2
        sums[t, 2] = s3


count_serial, count_parallel = twins(_count_loop, "count_hits", error_model="numpy")
