"""Batch drivers: one plain loop over pairs, compiled serial and parallel.

The collide loop is written once (:func:`collide_serial`, over a range of
pairs) and :func:`collide_parallel` runs it on blocks of the batch over the
threads; the other loops (distance, margin, time of impact, detach, sampling)
are written once and compiled twice, as umap does (:func:`~.jit.twins`: with
``parallel=False`` ``prange`` is an ordinary range). Every iteration reads its
pair's shapes and poses (a batch of one broadcasts by index, no copies) and
writes only its own output slots.
"""

import math
import os
import sys

import numba
import numpy as np
from numba import prange

from ..config import ROUNDING_ALLOWANCE
from .jit import first_call, jit
from .planar import extreme_vertex
from .projection import CASE_ABOVE, T_P, T_R, T_TOL, pair_test, surely_above, surely_above_by_radius
from .vec3 import two_product, two_sum


@jit(inline="always")
def centres_world(acx, acy, bcx, bcy, Pa, Ra, Pb, Rb):
    """a's end-face centre o in world coordinates and b's centre relative to it, d = c_b - c_a.

    The end-face centres (acx, acy) and (bcx, bcy) are in each prism's local frame (the
    user's origin need not lie inside the polygon). d is formed differences first: (Pb - Pa)
    is exact for nearby positions, so small objects far from the origin keep every bit of
    their separation (summing world coordinates first rounds it to eps |P|, which for 1e-6
    objects at 1e6 reached tol and missed gaps just below it).
    """
    ox = Pa[0] + Ra[0, 0] * acx + Ra[0, 1] * acy
    oy = Pa[1] + Ra[1, 0] * acx + Ra[1, 1] * acy
    oz = Pa[2] + Ra[2, 0] * acx + Ra[2, 1] * acy
    dx = (Pb[0] - Pa[0]) + ((Rb[0, 0] * bcx + Rb[0, 1] * bcy) - (Ra[0, 0] * acx + Ra[0, 1] * acy))
    dy = (Pb[1] - Pa[1]) + ((Rb[1, 0] * bcx + Rb[1, 1] * bcy) - (Ra[1, 0] * acx + Ra[1, 1] * acy))
    dz = (Pb[2] - Pa[2]) + ((Rb[2, 0] * bcx + Rb[2, 1] * bcy) - (Ra[2, 0] * acx + Ra[2, 1] * acy))
    return ox, oy, oz, dx, dy, dz


@jit(inline="always")
def pair_tolerance(ra, rb, centre_distance, ox, oy, oz, dx, dy, dz, acx, acy, bcx, bcy, rtol, atol, eps):
    """The pair's tolerance ``atol + rtol S + 4 eps (|c_a| + |c_b|) + 8 eps (|k_a|_1 + |k_b|_1)``,
    S = ra + rb + |c_b - c_a|, as its two parts ``(atol + rtol S, the rest)``.

    Scale-aware: rounding grows with the sizes involved. The world centres are only known to
    eps |c| (o = c_a and d = c_b - c_a from :func:`centres_world`), and forming them from the
    end-face centres k = (kx, ky) in the prisms' local frames rounds at the size of k, as does
    storing the vertices about k: a polygon far from its own origin (|k| of 1e7 and more, placed
    near the world origin) was misplaced by hundreds of tol under the first two terms alone.
    """
    far = math.sqrt(ox * ox + oy * oy + oz * oz) + math.sqrt((dx + ox) ** 2 + (dy + oy) ** 2 + (dz + oz) ** 2)
    local = abs(acx) + abs(acy) + abs(bcx) + abs(bcy)
    return atol + rtol * (ra + rb + centre_distance), eps * (4.0 * far + 8.0 * local)


@jit(inline="always")
def _offset_twice_precise(i, acx, acy, bcx, bcy, Pa, Ra, Pb, Rb):
    """Component i of d = c_b - c_a summed in twice the working precision (Ogita, Rump and Oishi's
    Dot2), then rounded: within eps |d_i| plus a term of order eps^2 (|P| + |k|)."""
    f = np.float64  # (a and b may differ in dtype: time_of_impact moves b in float64)
    s, c = two_sum(f(Pb[i]), -f(Pa[i]))
    for x, y in ((f(Rb[i, 0]), f(bcx)), (f(Rb[i, 1]), f(bcy)), (-f(Ra[i, 0]), f(acx)), (-f(Ra[i, 1]), f(acy))):
        h, r = two_product(x, y)
        s, q = two_sum(s, h)
        c += q + r
    return s + c


# Below this fraction of the rest of tol, the plain sum's rounding (at most about half the rounding
# part of tol) leaves d where it is to within tol / 4096; above it, d is formed again more precisely.
PLAIN_SUM_SHARE = 1.0 / 2048.0


@jit(inline="always")
def centres_and_tolerance(acx, acy, bcx, bcy, Pa, Ra, Pb, Rb, ra, rb, rtol, atol, eps):
    """:func:`centres_world` and the pair's tolerance (:func:`pair_tolerance`): ``(ox, oy, oz, dx,
    dy, dz, tol)``.

    Where the positions or the polygons' own offsets are so large against the pair that the plain
    sum's rounding is a noticeable part of tol (objects far from the world origin, polygons far from
    their own origin), d is formed again in twice the precision: a gap of 0.997 tol between
    polygons 5.5e7 from their own origins was moved above tol by that rounding, and missed.
    """
    ox, oy, oz, dx, dy, dz = centres_world(acx, acy, bcx, bcy, Pa, Ra, Pb, Rb)
    centre_distance = math.sqrt(dx * dx + dy * dy + dz * dz)
    base, rounding = pair_tolerance(
        ra, rb, centre_distance, ox, oy, oz, dx, dy, dz, acx, acy, bcx, bcy, rtol, atol, eps
    )
    if rounding > PLAIN_SUM_SHARE * base:
        dx = _offset_twice_precise(0, acx, acy, bcx, bcy, Pa, Ra, Pb, Rb)
        dy = _offset_twice_precise(1, acx, acy, bcx, bcy, Pa, Ra, Pb, Rb)
        dz = _offset_twice_precise(2, acx, acy, bcx, bcy, Pa, Ra, Pb, Rb)
    return ox, oy, oz, dx, dy, dz, base + rounding


@jit(error_model="numpy", inline="always")
def frame_inverse(Ra):
    """The exact inverse of a's rotation matrix, row by row ``(i00, i01, ..., i22)``: rows
    a1 x a2, a2 x a0, a0 x a1 over det. The body is the affine image of the matrix as given,
    whose rounding from orthonormal would misplace b by ``|Ra^T Ra - I| |d|`` under Ra^T.
    Apart from :func:`pair_world` so that a loop whose a stays put forms it once."""
    i00 = Ra[1, 1] * Ra[2, 2] - Ra[2, 1] * Ra[1, 2]
    i01 = Ra[2, 1] * Ra[0, 2] - Ra[0, 1] * Ra[2, 2]
    i02 = Ra[0, 1] * Ra[1, 2] - Ra[1, 1] * Ra[0, 2]
    i10 = Ra[1, 2] * Ra[2, 0] - Ra[2, 2] * Ra[1, 0]
    i11 = Ra[2, 2] * Ra[0, 0] - Ra[0, 2] * Ra[2, 0]
    i12 = Ra[0, 2] * Ra[1, 0] - Ra[1, 2] * Ra[0, 0]
    i20 = Ra[1, 0] * Ra[2, 1] - Ra[2, 0] * Ra[1, 1]
    i21 = Ra[2, 0] * Ra[0, 1] - Ra[0, 0] * Ra[2, 1]
    i22 = Ra[0, 0] * Ra[1, 1] - Ra[1, 0] * Ra[0, 1]
    inv_det = 1.0 / (Ra[0, 0] * i00 + Ra[1, 0] * i01 + Ra[2, 0] * i02)
    i00 *= inv_det
    i01 *= inv_det
    i02 *= inv_det
    i10 *= inv_det
    i11 *= inv_det
    i12 *= inv_det
    i20 *= inv_det
    i21 *= inv_det
    i22 *= inv_det
    return i00, i01, i02, i10, i11, i12, i20, i21, i22


@jit(inline="always")
def relative_pose(inv, dx, dy, dz, Rb):
    """b's centre ``p = Ra^-1 d`` and the first two columns of ``Ra^-1 Rb`` in a's centred frame, from
    the rows of :func:`frame_inverse` ``inv``: ``(px, py, pz, r00, r01, r10, r11, r20, r21)``."""
    i00, i01, i02, i10, i11, i12, i20, i21, i22 = inv
    return (
        i00 * dx + i01 * dy + i02 * dz,
        i10 * dx + i11 * dy + i12 * dz,
        i20 * dx + i21 * dy + i22 * dz,
        i00 * Rb[0, 0] + i01 * Rb[1, 0] + i02 * Rb[2, 0],
        i00 * Rb[0, 1] + i01 * Rb[1, 1] + i02 * Rb[2, 1],
        i10 * Rb[0, 0] + i11 * Rb[1, 0] + i12 * Rb[2, 0],
        i10 * Rb[0, 1] + i11 * Rb[1, 1] + i12 * Rb[2, 1],
        i20 * Rb[0, 0] + i21 * Rb[1, 0] + i22 * Rb[2, 0],
        i20 * Rb[0, 1] + i21 * Rb[1, 1] + i22 * Rb[2, 1],
    )


# error_model="numpy": with Python's ZeroDivisionError check on 1 / det the
# facing-pose benchmark measured ~20% slower per pair; det ~ 1 here.
@jit(error_model="numpy", inline="always")
def pair_world(
    avx,
    avy,
    aeang,
    aetab,
    avang,
    ainv,
    aoff,
    arad,
    acen,
    ka,
    bvx,
    bvy,
    beang,
    betab,
    boff,
    brad,
    bcen,
    kb,
    Pa,
    Ra,
    inv,
    Pb,
    Rb,
    rtol,
    atol,
    eps,
    witness,
    trace,
):
    """One pair from world poses: (hit, case, contact x, y, z in world).

    Shapes ka of set a and kb of set b; Pa (3,), Ra (3, 3) etc.; ``inv``: :func:`frame_inverse`
    of Ra, or None to form it here. ``witness``: False when the caller does not want the contact
    (it may then be NaN). ``trace``:
    None, or TRACE_SIZE floats to fill (see _projection.TRACE_FIELDS).
    """
    acx, acy, bcx, bcy = acen[ka, 0], acen[ka, 1], bcen[kb, 0], bcen[kb, 1]
    ra = arad[ka]
    rb = brad[kb]
    ox, oy, oz, dx, dy, dz, tol = centres_and_tolerance(acx, acy, bcx, bcy, Pa, Ra, Pb, Rb, ra, rb, rtol, atol, eps)
    # b's pose in a's centred frame, p = Ra^-1 d and R = Ra^-1 Rb. Callers whose a changes with every
    # pair pass None and the inverse is formed here (the None branch is pruned when compiling).
    if inv is None:
        i00, i01, i02, i10, i11, i12, i20, i21, i22 = frame_inverse(Ra)
    else:
        i00, i01, i02, i10, i11, i12, i20, i21, i22 = inv
    px, py, pz, r00, r01, r10, r11, r20, r21 = relative_pose(
        (i00, i01, i02, i10, i11, i12, i20, i21, i22), dx, dy, dz, Rb
    )
    # b's axis relative to a's, well conditioned for every tilt: Ra^-1 d_a
    # is exactly e3, so R e3 = s e3 + Ra^-1 (d_b - s d_a) with s = sign of
    # d_a.d_b; the difference is exact (Sterbenz) for nearly (anti)parallel
    # axes, so a tilt of 1e-16 keeps its direction and identical axes give
    # exactly zero (forming Ra^-1 d_b directly leaves eps-level noise that
    # the reach T ~ 1/tilt turns into a sweep in a random direction).
    s = 1.0 if Ra[0, 2] * Rb[0, 2] + Ra[1, 2] * Rb[1, 2] + Ra[2, 2] * Rb[2, 2] >= 0.0 else -1.0
    ex = Rb[0, 2] - s * Ra[0, 2]
    ey = Rb[1, 2] - s * Ra[1, 2]
    ez = Rb[2, 2] - s * Ra[2, 2]
    r02 = i00 * ex + i01 * ey + i02 * ez
    r12 = i10 * ex + i11 * ey + i12 * ez
    r22 = s + (i20 * ex + i21 * ey + i22 * ez)
    sa = aoff[ka]
    na = aoff[ka + 1] - sa
    sb = boff[kb]
    nb = boff[kb + 1] - sb
    if trace is not None:
        trace[T_TOL] = tol  # the pair's tolerance, as geometry.pair_scale_tolerance gives it
        for j, v in enumerate((px, py, pz)):
            trace[T_P + j] = v
        for j, v in enumerate((r00, r01, r02, r10, r11, r12, r20, r21, r22)):
            trace[T_R + j] = v
    # Decided at tol plus the rounding of what follows (config.ROUNDING_ALLOWANCE; |d|_1 >= |d|, no root),
    # and of the end-face centres k as stored (in float32 they are rounded at the size of k).
    tol += (
        ROUNDING_ALLOWANCE * eps * (ra + rb + abs(dx) + abs(dy) + abs(dz) + abs(acx) + abs(acy) + abs(bcx) + abs(bcy))
    )
    if trace is None and surely_above_by_radius(pz, r20, r21, r22, rb, tol):  # the exit below, sooner
        return False, CASE_ABOVE, math.nan, math.nan, math.nan
    imax = extreme_vertex(bvx, bvy, beang, betab, sb, nb, r20, r21)  # b's vertex deepest into a
    if trace is None and surely_above(bvx, bvy, sb, imax, pz, r20, r21, r22, tol):
        # Most pairs of a scene leave here, without the call into pair_test (its arguments
        # cost more than this test); pair_test takes the same exit when tracing.
        return False, CASE_ABOVE, math.nan, math.nan, math.nan
    hit, case, cx, cy, cz = pair_test(
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
    )
    if not hit:
        return False, case, math.nan, math.nan, math.nan
    return (
        True,
        case,
        ox + Ra[0, 0] * cx + Ra[0, 1] * cy + Ra[0, 2] * cz,
        oy + Ra[1, 0] * cx + Ra[1, 1] * cy + Ra[1, 2] * cz,
        oz + Ra[2, 0] * cx + Ra[2, 1] * cy + Ra[2, 2] * cz,
    )


@jit(inline="always")
def pair_of_sets(a, b, ka, kb, Pa, Ra, inv, Pb, Rb, rtol, atol, eps, witness, trace):
    """:func:`pair_world` for prism ka of set a and prism kb of set b, each set the tuple of :func:`unpack`
    (``inv``: :func:`frame_inverse` of Ra, or None)."""
    # (unpacked by name: Numba's inliner takes no star arguments)
    ax, ay, aea, aet, ava, ainv, aoff, arad, acen = a
    bx, by, bea, bet, _, _, boff, brad, bcen = b
    return pair_world(
        ax,
        ay,
        aea,
        aet,
        ava,
        ainv,
        aoff,
        arad,
        acen,
        ka,
        bx,
        by,
        bea,
        bet,
        boff,
        brad,
        bcen,
        kb,
        Pa,
        Ra,
        inv,
        Pb,
        Rb,
        rtol,
        atol,
        eps,
        witness,
        trace,
    )


@jit(parallel=False, error_model="numpy")
def collide_serial(
    lo,
    hi,
    a_floats,
    a_ints,
    b_floats,
    b_ints,
    pos_a,
    rot_a,
    pos_b,
    rot_b,
    rtol,
    atol,
    eps,
    want_contact,
    hit_out,
    case_out,
    contact_out,
):
    """Pairs ``lo .. hi - 1`` of a batch: the serial kernel, and each block of :func:`collide_parallel`.

    Every iteration reads its pair's shapes and poses (a batch of one broadcasts by index, no copies)
    and writes only its own output slots.
    """
    a = unpack(a_floats, a_ints)
    b = unpack(b_floats, b_ints)
    npa = pos_a.shape[0]
    nra = rot_a.shape[0]
    npb = pos_b.shape[0]
    nrb = rot_b.shape[0]
    nsa = a_ints[0]  # the number of prisms (see pack)
    nsb = b_ints[0]
    for i in range(lo, hi):
        # A batch of one broadcasts: min() picks row 0 (sizes are 1 or n).
        hit, case, cx, cy, cz = pair_of_sets(
            a,
            b,
            min(i, nsa - 1),
            min(i, nsb - 1),
            pos_a[min(i, npa - 1)],
            rot_a[min(i, nra - 1)],
            None,
            pos_b[min(i, npb - 1)],
            rot_b[min(i, nrb - 1)],
            rtol,
            atol,
            eps,
            want_contact,
            None,
        )
        hit_out[i] = hit
        case_out[i] = case
        if want_contact:
            contact_out[i, 0] = cx
            contact_out[i, 1] = cy
            contact_out[i, 2] = cz


@jit(parallel=True, error_model="numpy")
def collide_parallel(blocks, *batch):
    """A batch in ``blocks`` contiguous blocks (:func:`work_blocks`) over the threads, each block by
    :func:`collide_serial` (``batch``: its arguments after ``lo, hi``). With the pair loop compiled into
    this loop's outlined body instead, a pair took 7 % longer than in the serial kernel (two threads
    1.78x one; 1.91x called), and this kernel's first compile now reuses the serial one's (from Numba's
    cache too)."""
    n = batch[-3].shape[0]  # (hit_out)
    for bp in prange(blocks):
        blk = np.int64(bp)  # prange's index is unsigned; mixing it with int64 would give floats
        collide_serial(blk * n // blocks, (blk + 1) * n // blocks, *batch)


#: Batches smaller than this run on the serial kernel when ``parallel`` is
#: left to choose: starting the threads (OpenMP here) can cost milliseconds.
PARALLEL_MIN_PAIRS = 4096

# GNU OpenMP cannot start threads in a child forked after it ran threads in
# the parent (Numba aborts the child). Such a child runs the serial kernels.
_threads = {"used": False, "forked_after_omp": False, "warned": False}


def _after_fork_in_child():
    if _threads["used"]:
        try:
            layer = numba.threading_layer()
        except ValueError:  # no threading layer started after all
            return
        _threads["forked_after_omp"] = layer == "omp"


os.register_at_fork(after_in_child=_after_fork_in_child)


def use_parallel(parallel, n):
    """Whether a batch of ``n`` runs on the parallel kernel.

    ``parallel`` None chooses by batch size. In a process forked after a
    parallel call under GNU OpenMP the answer is False, with a one-line
    warning the first time (threads there would abort the process).
    """
    if parallel is None:
        parallel = n >= PARALLEL_MIN_PAIRS
    if parallel and _threads["forked_after_omp"]:
        if not _threads["warned"]:
            _threads["warned"] = True
            print(
                "prismbatch: this process was forked after a parallel call under GNU OpenMP, which cannot "
                "start threads in a forked child; running serially (use the 'spawn' start method, or "
                "`pip install tbb` with NUMBA_THREADING_LAYER=tbb, for parallel children)",
                file=sys.stderr,
            )
        return False
    if parallel:
        _threads["used"] = True
    return bool(parallel)


#: Blocks of pairs per thread in a parallel batch (more blocks balance the threads better; where pairs need a
#: workspace, each block has its own and its pairs reuse it).
BLOCKS_PER_THREAD = 4


def work_blocks(n, parallel):
    """How many blocks (each with its own workspace) a batch of ``n`` pairs is cut into."""
    return max(1, min(n, BLOCKS_PER_THREAD * numba.get_num_threads())) if parallel else 1


def pack(vx, vy, edge_angle, edge_table, vertex_angle, inv_edge_len, offsets, radius, centre, dtype):
    """A prism set's nine arrays as one float array of ``dtype`` and one int64 array (see :func:`unpack`).

    ``floats``: ``vx, vy, edge_angle, vertex_angle, inv_edge_len`` (``t`` values
    each, ``t`` the total vertex count), ``radius`` (``m``), ``centre`` (``2 m``);
    ``ints``: ``m``, ``offsets`` (``m + 1``), ``edge_table`` (``t``).
    """
    floats = np.concatenate([vx, vy, edge_angle, vertex_angle, inv_edge_len, radius, np.ravel(centre)]).astype(dtype)
    ints = np.concatenate([[len(radius)], offsets, edge_table]).astype(np.int64)
    return floats, ints


@jit(inline="always", refcounts=True)  # returns arrays (when called from Python, not inlined)
def unpack(floats, ints):
    """The nine arrays of a :func:`pack`-ed prism set, as views, in the order :func:`pack` takes them.

    Two arrays cross the dispatcher instead of nine: each array argument costs
    a one-pair call a few hundred nanoseconds of type checks and unboxing.
    Python builds its views with ``unpack.py_func``; a test compares the two.
    """
    m = ints[0]
    offsets = ints[1 : m + 2]
    t = offsets[m]
    return (
        floats[0:t],
        floats[t : 2 * t],
        floats[2 * t : 3 * t],
        ints[m + 2 : m + 2 + t],
        floats[3 * t : 4 * t],
        floats[4 * t : 5 * t],
        offsets,
        floats[5 * t : 5 * t + m],
        floats[5 * t + m : 5 * t + 3 * m].reshape((m, 2)),
    )


def all_fields(s):
    """Every array of a PrismArrays ``s``, in the order the batch kernels take them."""
    return (s.vx, s.vy, s.edge_angle, s.edge_table, s.vertex_angle, s.inv_edge_len, s.offsets, s.radius, s.centre)


def pair_fields(s):
    """The arrays of a PrismArrays that :func:`pair_world` takes for prism b."""
    return s.vx, s.vy, s.edge_angle, s.edge_table, s.offsets, s.radius, s.centre


def run(a_arrays, b_arrays, pos_a, rot_a, pos_b, rot_b, n, rtol, atol, want_contact, parallel):
    """Allocate outputs and call the serial or parallel kernel (None: by batch size)."""
    parallel = use_parallel(parallel, n)
    hit = np.empty(n, dtype=np.bool_)
    case = np.empty(n, dtype=np.int8)
    # A status-only call gets a (0, 3) placeholder: no memory, no writes.
    contact = np.empty((n if want_contact else 0, 3), dtype=pos_a.dtype)
    kern = collide_parallel if parallel else collide_serial
    first_call(
        (kern, pos_a.dtype),
        kern,
        *((work_blocks(n, True),) if parallel else (0, n)),  # the blocks, or the whole batch as one
        a_arrays.floats,
        a_arrays.ints,
        b_arrays.floats,
        b_arrays.ints,
        pos_a,
        rot_a,
        pos_b,
        rot_b,
        rtol,
        atol,
        float(np.finfo(pos_a.dtype).eps),
        want_contact,
        hit,
        case,
        contact,
    )
    return hit, case, contact
