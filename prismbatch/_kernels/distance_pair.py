"""One pair's signed distance with its input checks compiled in: the low-latency path of ``Collider.distance``.

A batch call spends some 20 µs in Python on pose checks and array set-up
before its kernel runs; a controller that asks for one pair at a time gets
that work done here, in one compiled call (checks as ``collide_pair``'s).
"""

import math

import numba
import numpy as np

from .batch import unpack
from .distance import EPA_ROOM, block_of, pair_distance_any_room, signed_status, workspace
from .jit import per_dtype
from .one_pair import pair_problem, pair_scalars, unbundle


def _distance_pair(bundle, Pa, Ra, Pb, Rb, witness):
    """(problem, value, distance, tol, status, solver, normal, point_a, point_b) of one pair.

    ``bundle``: :func:`~.one_pair.pair_bundle`. ``problem`` 0: valid inputs; otherwise the first bad
    one, as ``collide_pair``'s, with ``value`` the offending number. The 3-tuples are NaN unless
    ``witness``.
    """
    a_floats, a_ints, b_floats, b_ints, scalars = unbundle(bundle, Pa)
    rtol, atol, eps, ortho_tol_a, ortho_tol_b, max_magnitude = pair_scalars(scalars)
    nan = math.nan
    none = (nan, nan, nan)
    problem, val = pair_problem(Pa, Ra, Pb, Rb, ortho_tol_a, ortho_tol_b, max_magnitude)
    if problem:
        return problem, val, nan, nan, 0, 0, none, none, none
    avx, avy, aeang, aetab, _, _, aoff, arad, acen = unpack(a_floats, a_ints)
    bvx, bvy, beang, betab, _, _, boff, brad, bcen = unpack(b_floats, b_ints)
    P = (avx, avy, aeang, aetab, bvx, bvy, beang, betab)
    ix = (aoff[0], aoff[1] - aoff[0], boff[0], boff[1] - boff[0])
    work = block_of(workspace(1, EPA_ROOM[0]), 0)
    # The poses copied into C-contiguous, writeable arrays, as the batch passes them: with this kernel's
    # read-only 'A' arrays pair_distance would compile once more for them (20-30 s of a cold start).
    pa, pb, ra, rb = (
        np.empty(3, Pa.dtype),
        np.empty(3, Pb.dtype),
        np.empty((3, 3), Ra.dtype),
        np.empty((3, 3), Rb.dtype),
    )
    for i in range(3):
        pa[i], pb[i] = Pa[i], Pb[i]
        for j in range(3):
            ra[i, j], rb[i, j] = Ra[i, j], Rb[i, j]
    d, t, code, n, p = pair_distance_any_room(
        P, ix, acen[0], bcen[0], arad[0], brad[0], pa, ra, pb, rb, rtol, atol, eps, witness, work
    )
    q = (p[0] + d * n[0], p[1] + d * n[1], p[2] + d * n[2])
    return 0, 0.0, d, t, signed_status(d, t), code, n, p, q


#: The one-pair kernel, one compiled copy per dtype, closed to other signatures as ``collide_pair`` is
#: (its last argument: ``witness``).
distance_pair = per_dtype(
    _distance_pair, "distance_pair", (np.float64, np.float32), error_model="numpy", refcounts=True
)
WITNESS_TYPE = numba.types.boolean
