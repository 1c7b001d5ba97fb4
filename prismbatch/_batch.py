"""Batch drivers: one plain loop over pairs, compiled serial and parallel.

The loop body is written once (:func:`_collide_loop`) and compiled twice, as
umap does: with ``parallel=False`` ``prange`` is an ordinary range. Every
iteration reads its pair's shapes and poses (a batch of one broadcasts by
index, no copies) and writes only its own output slots.
"""

import math
import types

import numpy as np
from numba import njit, prange

from ._projection import T_P, T_R, T_TOL, pair_test
from .poses import first_bad_rotation


@njit(cache=True)
def pair_world(avx, avy, aeang, aetab, avang, ainv, aoff, arad, acen, ka,
               bvx, bvy, beang, betab, boff, brad, bcen, kb,
               Pa, Ra, Pb, Rb, rtol, atol, eps, trace):
    """One pair from world poses: (hit, case, contact x, y, z in world).

    Shapes ka of set a and kb of set b; Pa (3,), Ra (3, 3) etc. ``trace``:
    None, or TRACE_SIZE floats to fill (see _projection.TRACE_FIELDS).
    """
    # End-face centres in world coordinates (the user's origin need not
    # lie inside the polygon).
    cax = acen[ka, 0]
    cay = acen[ka, 1]
    cbx = bcen[kb, 0]
    cby = bcen[kb, 1]
    ox = Pa[0] + Ra[0, 0] * cax + Ra[0, 1] * cay
    oy = Pa[1] + Ra[1, 0] * cax + Ra[1, 1] * cay
    oz = Pa[2] + Ra[2, 0] * cax + Ra[2, 1] * cay
    dx = Pb[0] + Rb[0, 0] * cbx + Rb[0, 1] * cby - ox
    dy = Pb[1] + Rb[1, 0] * cbx + Rb[1, 1] * cby - oy
    dz = Pb[2] + Rb[2, 0] * cbx + Rb[2, 1] * cby - oz
    # b's pose in a's centred frame: p = Ra^T d, R = Ra^T Rb.
    px = Ra[0, 0] * dx + Ra[1, 0] * dy + Ra[2, 0] * dz
    py = Ra[0, 1] * dx + Ra[1, 1] * dy + Ra[2, 1] * dz
    pz = Ra[0, 2] * dx + Ra[1, 2] * dy + Ra[2, 2] * dz
    r00 = Ra[0, 0] * Rb[0, 0] + Ra[1, 0] * Rb[1, 0] + Ra[2, 0] * Rb[2, 0]
    r01 = Ra[0, 0] * Rb[0, 1] + Ra[1, 0] * Rb[1, 1] + Ra[2, 0] * Rb[2, 1]
    r02 = Ra[0, 0] * Rb[0, 2] + Ra[1, 0] * Rb[1, 2] + Ra[2, 0] * Rb[2, 2]
    r10 = Ra[0, 1] * Rb[0, 0] + Ra[1, 1] * Rb[1, 0] + Ra[2, 1] * Rb[2, 0]
    r11 = Ra[0, 1] * Rb[0, 1] + Ra[1, 1] * Rb[1, 1] + Ra[2, 1] * Rb[2, 1]
    r12 = Ra[0, 1] * Rb[0, 2] + Ra[1, 1] * Rb[1, 2] + Ra[2, 1] * Rb[2, 2]
    r20 = Ra[0, 2] * Rb[0, 0] + Ra[1, 2] * Rb[1, 0] + Ra[2, 2] * Rb[2, 0]
    r21 = Ra[0, 2] * Rb[0, 1] + Ra[1, 2] * Rb[1, 1] + Ra[2, 2] * Rb[2, 1]
    r22 = Ra[0, 2] * Rb[0, 2] + Ra[1, 2] * Rb[1, 2] + Ra[2, 2] * Rb[2, 2]
    ra = arad[ka]
    rb = brad[kb]
    # Scale-aware tolerance: rounding grows with the sizes involved, and
    # the world positions themselves are only known to eps |c|.
    tol = (atol + rtol * (ra + rb + math.sqrt(px * px + py * py + pz * pz))
           + 4.0 * eps * (math.sqrt(ox * ox + oy * oy + oz * oz)
                          + math.sqrt((dx + ox) ** 2 + (dy + oy) ** 2 + (dz + oz) ** 2)))
    sa = aoff[ka]
    na = aoff[ka + 1] - sa
    sb = boff[kb]
    nb = boff[kb + 1] - sb
    if trace is not None:
        trace[T_TOL] = tol
        for j, v in enumerate((px, py, pz)):
            trace[T_P + j] = v
        for j, v in enumerate((r00, r01, r02, r10, r11, r12, r20, r21, r22)):
            trace[T_R + j] = v
    hit, case, cx, cy, cz = pair_test(
        avx, avy, aeang, aetab, avang, ainv, sa, na, ra,
        bvx, bvy, beang, betab, sb, nb, rb,
        px, py, pz, r00, r01, r02, r10, r11, r12, r20, r21, r22, tol, trace)
    if not hit:
        return False, case, math.nan, math.nan, math.nan
    return (True, case,
            ox + Ra[0, 0] * cx + Ra[0, 1] * cy + Ra[0, 2] * cz,
            oy + Ra[1, 0] * cx + Ra[1, 1] * cy + Ra[1, 2] * cz,
            oz + Ra[2, 0] * cx + Ra[2, 1] * cy + Ra[2, 2] * cz)


def _collide_loop(avx, avy, aeang, aetab, avang, ainv, aoff, arad, acen,
                  bvx, bvy, beang, betab, bvang, binv, boff, brad, bcen,
                  pos_a, rot_a, pos_b, rot_b, rtol, atol, eps, want_contact,
                  hit_out, case_out, contact_out):
    n = hit_out.shape[0]
    npa = pos_a.shape[0]
    nra = rot_a.shape[0]
    npb = pos_b.shape[0]
    nrb = rot_b.shape[0]
    nsa = arad.shape[0]
    nsb = brad.shape[0]
    for ip in prange(n):
        # prange's index is unsigned; mixing it with int64 would give floats.
        i = np.int64(ip)
        # A batch of one broadcasts: min() picks row 0 (sizes are 1 or n).
        hit, case, cx, cy, cz = pair_world(
            avx, avy, aeang, aetab, avang, ainv, aoff, arad, acen, min(i, nsa - 1),
            bvx, bvy, beang, betab, boff, brad, bcen, min(i, nsb - 1),
            pos_a[min(i, npa - 1)], rot_a[min(i, nra - 1)], pos_b[min(i, npb - 1)], rot_b[min(i, nrb - 1)],
            rtol, atol, eps, None)
        hit_out[i] = hit
        case_out[i] = case
        if want_contact:
            contact_out[i, 0] = cx
            contact_out[i, 1] = cy
            contact_out[i, 2] = cz


def _variant(func, name):
    """A copy of ``func`` under another name.

    Numba's on-disk cache is keyed by the function's name and source line,
    not by the ``parallel`` flag: compiled twice under one name, the serial
    and parallel kernels would overwrite each other's cache entry and one
    would silently run as the other.
    """
    code = func.__code__.replace(co_name=name, co_qualname=name)
    g = types.FunctionType(code, func.__globals__, name, func.__defaults__, func.__closure__)
    g.__qualname__ = name
    g.__doc__ = func.__doc__
    return g


collide_serial = njit(cache=True, parallel=False)(_variant(_collide_loop, "collide_serial"))
collide_parallel = njit(cache=True, parallel=True)(_variant(_collide_loop, "collide_parallel"))


#: Batches smaller than this run on the serial kernel when ``parallel`` is
#: left to choose: starting the threads (OpenMP here) can cost milliseconds.
PARALLEL_MIN_PAIRS = 4096


def run(a_arrays, b_arrays, pos_a, rot_a, pos_b, rot_b, n, rtol, atol,
        want_contact, parallel):
    """Allocate outputs and call the serial or parallel kernel (None: by batch size)."""
    if parallel is None:
        parallel = n >= PARALLEL_MIN_PAIRS
    hit = np.empty(n, dtype=np.bool_)
    case = np.empty(n, dtype=np.int8)
    # A status-only call gets a (0, 3) placeholder: no memory, no writes.
    contact = np.empty((n if want_contact else 0, 3), dtype=pos_a.dtype)
    kern = collide_parallel if parallel else collide_serial
    kern(*a_arrays, *b_arrays, pos_a, rot_a, pos_b, rot_b,
         rtol, atol, float(np.finfo(pos_a.dtype).eps), want_contact, hit, case, contact)
    return hit, case, contact


@njit(cache=True)
def collide_pair(avx, avy, aeang, aetab, avang, ainv, aoff, arad, acen,
                 bvx, bvy, beang, betab, bvang, binv, boff, brad, bcen,
                 Pa, Ra, Pb, Rb, rtol, atol, eps, ortho_tol):
    """One pair, with its input checks compiled in (the low-latency path).

    Returns (problem, value, hit, case, cx, cy, cz). ``problem`` 0 means the
    inputs are valid; otherwise it names the first bad input (see
    collide.PAIR_PROBLEMS) and ``value`` gives the offending number.
    """
    nan = math.nan
    for k, P in enumerate((Pa, Pb)):
        for j in range(3):
            if not math.isfinite(P[j]):
                return 1 + 4 * k, nan, False, 0, nan, nan, nan
    for k, R in enumerate((Ra, Rb)):
        _, kind, val = first_bad_rotation(R.reshape((1, 3, 3)), ortho_tol)
        if kind != 0:
            return 1 + kind + 4 * k, val, False, 0, nan, nan, nan
    hit, case, cx, cy, cz = pair_world(avx, avy, aeang, aetab, avang, ainv, aoff, arad, acen, 0,
                                       bvx, bvy, beang, betab, boff, brad, bcen, 0,
                                       Pa, Ra, Pb, Rb, rtol, atol, eps, None)
    return 0, 0.0, hit, case, cx, cy, cz
