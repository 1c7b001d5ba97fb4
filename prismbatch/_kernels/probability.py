"""Sampled poses for :mod:`prismbatch.probability`: ``p = p0 + dp``, ``R = exp([dtheta]x) R0``.

One loop over samples, compiled serial and parallel (:func:`~prismbatch._kernels.jit.twins`);
sample s forms the noise ``x = L[q] z[s]`` of its query ``q = query[s]`` (b's six components
first, then a's when there are twelve), perturbs the query's nominal poses and writes only
row s of the outputs.
"""

import math

from numba import prange

from .jit import jit, twins


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
    t = math.sqrt(tx * tx + ty * ty + tz * tz)
    # Rodrigues: E = I + a K + b K^2, K = [theta]x; b = (1 - cos t) / t^2 written with
    # sin(t / 2) so that small angles lose no digits.
    if t > 0.0:
        a = math.sin(t) / t
        h = math.sin(0.5 * t) / (0.5 * t)
        b = 0.5 * h * h
    else:
        a, b = 1.0, 0.5
    xx, yy, zz = tx * tx, ty * ty, tz * tz
    e00, e11, e22 = 1.0 - b * (yy + zz), 1.0 - b * (xx + zz), 1.0 - b * (xx + yy)
    e01, e10 = b * tx * ty - a * tz, b * tx * ty + a * tz
    e02, e20 = b * tx * tz + a * ty, b * tx * tz - a * ty
    e12, e21 = b * ty * tz - a * tx, b * ty * tz + a * tx
    for j in range(3):
        r0, r1, r2 = rot0[q, 0, j], rot0[q, 1, j], rot0[q, 2, j]
        rot[s, 0, j] = e00 * r0 + e01 * r1 + e02 * r2
        rot[s, 1, j] = e10 * r0 + e11 * r1 + e12 * r2
        rot[s, 2, j] = e20 * r0 + e21 * r1 + e22 * r2
    pos[s, 0] = pos0[q, 0] + x0
    pos[s, 1] = pos0[q, 1] + x1
    pos[s, 2] = pos0[q, 2] + x2


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


# No reference counting: the loop allocates nothing, and with it every array passed to the inlined
# helper costs atomic increments per sample (see jit.jit).
sample_serial, sample_parallel = twins(_sample_loop, "sample_poses", error_model="numpy", refcounts=False)
