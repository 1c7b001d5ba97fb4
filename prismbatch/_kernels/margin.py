"""Do two semi-infinite convex prisms come within a margin m of each other? GJK that stops early.

The signed distance d of a pair is that of the origin to the Minkowski
difference D_L = K + C_L of :mod:`prismbatch._kernels.distance` (the same
frame, cut of the cone and supports). GJK keeps two bounds on it: the upper
bound |v| (v: the simplex's point nearest the origin, a point of D_L) and the
lower bound max v.w / |v| over its supports w (a plane with all of D_L beyond
it; for an overlapping pair it bounds minus the depth from below too, as the
depth is at most that plane's support value). The query needs only the side
of m that d lies on, so GJK stops as soon as

* |v| <= m + tol / 2, or the simplex holds the origin: a hit (d <= m + tol / 2);
* the lower bound exceeds m - tol / 2: a miss (d > m - tol / 2);

one of which holds once the bounds are tol apart: GJK runs to tol, not to the
1e-3 tol of the distance. A pair whose axes point apart stops before GJK where its
end planes, or the end faces' radii seen along GJK's first direction, keep the bodies
apart by more than the margin; a pair far from the
margin stops after one or two supports (the first one, towards b's centre turned
into a direction where D's support is finite, is already a plane); where it is not, b's centre inside a
settles a deep overlap without GJK. A pair whose GJK stops without settling
it (rounding on the slivers of very fine polygons, or the iteration cap; not
seen on 3600- and 100,000-gons placed within 0.1 to 1e3 tol of the margin) is
left undecided for :func:`margin_fallback_serial`, which takes the full signed
distance.

The pair loop allocates nothing (GJK's workspace comes per block of
:data:`BLOCK` pairs from the caller), so it is compiled without reference
counting, as collide's loop is. :func:`pair_margin` is not inlined into it:
the parallel twin then compiles in seconds instead of tens of seconds, at no
measured cost per pair.
"""

import math

import numpy as np
from numba import prange

from .batch import centres_and_tolerance, unpack, use_parallel
from .distance import BOX, EPA_ROOM, block_of, pair_distance_any_room, pair_index, workspace
from .gjk3d import GJK_MAX_ITER, closest
from .jit import first_call, jit, twins
from .minkowski import cut_difference, support
from .parallel import frames_rigid, parallel_gap
from .planar import point_polygon_distance

#: The decision thresholds sit this fraction of the pair tolerance either side of the margin.
SLACK = 0.5
#: A miss by the end planes alone (:func:`pair_margin`) must clear the margin by this fraction of the pair's size.
FAR_SLACK = 1e-4
#: Codes of :func:`pair_margin`: settled by GJK's bounds, or left to the full signed distance.
DECIDED, UNDECIDED = 0, 1
#: Pairs per block of the batch loop; each block has its own GJK workspace.
BLOCK = 64


@jit(inline="always")
def _first_direction(dx, dy, dz, ax, ay, az, bx, by, bz):
    """GJK's first direction: b's centre seen from a's (c_b - c_a), turned into the directions where
    D's support is finite (u.d_a <= 0 <= u.d_b), so that the first support already gives a plane."""
    t = dx * ax + dy * ay + dz * az
    ux, uy, uz = (dx - t * ax, dy - t * ay, dz - t * az) if t > 0.0 else (dx, dy, dz)
    t = ux * bx + uy * by + uz * bz
    if t < 0.0:
        ux, uy, uz = ux - t * bx, uy - t * by, uz - t * bz
        if ux * ax + uy * ay + uz * az > 0.0:  # both bind: along d_a x d_b, to b's side
            nx, ny, nz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
            t = (nx * dx + ny * dy + nz * dz) / max(nx * nx + ny * ny + nz * nz, 1e-300)
            ux, uy, uz = t * nx, t * ny, t * nz
    if ux == 0.0 and uy == 0.0 and uz == 0.0:
        return (dx, dy, dz) if dx != 0.0 or dy != 0.0 or dz != 0.0 else (1.0, 0.0, 0.0)
    return ux, uy, uz


@jit
def pair_margin(P, ix, ca, cb, ra, rb, Pa, Ra, Pb, Rb, margin, rtol, atol, eps, W, I, lam, avang, ainv):
    """One pair: (hit, code). ``hit``: the signed distance is at most ``margin``, to within half the
    pair's tolerance; ``code``: :data:`DECIDED`, or :data:`UNDECIDED` (``hit`` is then False and
    meaningless). Arguments as :func:`~prismbatch._kernels.distance.pair_distance`, and a's vertex
    angles and inverse edge lengths (for the inside test of b's centre)."""
    ox, oy, oz, dx, dy, dz, tol = centres_and_tolerance(
        ca[0], ca[1], cb[0], cb[1], Pa, Ra, Pb, Rb, ra, rb, rtol, atol, eps
    )
    S = ra + rb + math.sqrt(dx * dx + dy * dy + dz * dz)  # the pair's scale
    hi = margin + SLACK * tol
    lo = margin - SLACK * tol
    dax, day, daz = np.float64(Ra[0, 2]), np.float64(Ra[1, 2]), np.float64(Ra[2, 2])
    dbx, dby, dbz = np.float64(Rb[0, 2]), np.float64(Rb[1, 2]), np.float64(Rb[2, 2])
    pz = dax * dx + day * dy + daz * dz  # b's centre along a's axis (a lies at pz >= 0)
    apart = dax * dbx + day * dby + daz * dbz <= 0.0
    far = lo + FAR_SLACK * S
    if apart:
        # Neither body reaches over the other's end plane along its axis, so each end plane bounds the
        # gap: b lies below pz + rb along d_a, a below ra - d_b.(c_b - c_a) along d_b. Far pairs (the
        # paper's facing scene) stop here, before the difference is built. These bounds take the axes
        # as unit and across the end faces, true only to the rotations' orthonormality (1e-5 in
        # float32), so they must clear the margin by FAR_SLACK of the pair's size.
        if -(pz + rb) > far or (dbx * dx + dby * dy + dbz * dz) - ra > far:
            return False, DECIDED
    ux, uy, uz = _first_direction(dx, dy, dz, dax, day, daz, dbx, dby, dbz)
    un = math.sqrt(ux * ux + uy * uy + uz * uz)
    if apart:
        # The same for the first direction u, by the end faces' radii: D's support there is at most
        # -u.d + (ra + rb) |u| (the cone's part is 0 where u.d_a <= 0 <= u.d_b; with the axes apart, each
        # point of the cut cone is s d_a - t d_b with s, t <= 2 L, which bounds what rounding leaves of it).
        cone_part = 2.0 * BOX * S
        cone_part *= max(ux * dax + uy * day + uz * daz, 0.0) + max(-(ux * dbx + uy * dby + uz * dbz), 0.0)
        if (ux * dx + uy * dy + uz * dz - cone_part) / un - (ra + rb) > far:
            return False, DECIDED
    # D_L as pair_distance builds it, in units of 1 / k (see cut_difference), as are hi_k and lo_k.
    fr, cone, s, (ex, ey, ez), k = cut_difference(Ra, Rb, dx, dy, dz, BOX * S)
    hi_k, lo_k = k * hi, k * lo
    if ex == 0.0 and ey == 0.0 and ez == 0.0 and frames_rigid(Ra, Rb, S, tol):
        # exactly parallel axes: apart in the plane, the gap as pair_distance takes it (parallel_gap)
        lower, gap, _, _ = parallel_gap(P, ix, Ra, Rb, ox, oy, oz, dx, dy, dz, SLACK * tol, s)
        if lower > 0.0 and gap <= hi:
            return True, DECIDED
        if lower > lo:
            return False, DECIDED
    x, y, z, ia, ib, kc = support(P, ix, fr, cone, ux, uy, uz)
    lower = -(ux * x + uy * y + uz * z) / un  # D_L lies beyond -u
    if lower > lo_k:
        return False, DECIDED
    if pz >= 0.0:  # b's centre inside a is an overlap
        px = Ra[0, 0] * dx + Ra[1, 0] * dy + Ra[2, 0] * dz
        py = Ra[0, 1] * dx + Ra[1, 1] * dy + Ra[2, 1] * dz
        if point_polygon_distance(P[0], P[1], avang, ainv, ix[0], ix[1], px, py) >= 0.0:
            return True, DECIDED
    W[0, 0], W[0, 1], W[0, 2] = x, y, z
    I[0, 0], I[0, 1], I[0, 2] = ia, ib, kc
    m = 1
    vx, vy, vz = x, y, z
    for _ in range(GJK_MAX_ITER):
        vv = vx * vx + vy * vy + vz * vz
        if vv <= hi_k * hi_k:
            return True, DECIDED
        vn = math.sqrt(vv)
        x, y, z, ia, ib, kc = support(P, ix, fr, cone, -vx, -vy, -vz)
        lower = max(lower, (vx * x + vy * y + vz * z) / vn)
        if lower > lo_k:
            return False, DECIDED
        for j in range(m):
            if I[j, 0] == ia and I[j, 1] == ib and I[j, 2] == kc:  # no new point: rounding stopped GJK
                return False, UNDECIDED
        W[m, 0], W[m, 1], W[m, 2] = x, y, z
        I[m, 0], I[m, 1], I[m, 2] = ia, ib, kc
        # Both bounds hold for any simplex, so a step that rounding makes lose ground is harmless.
        m, vx, vy, vz, inside, _ = closest(W, I, lam, m + 1)
        if inside:  # o in a tetrahedron of D_L: a hit, unless a support plane already put o outside D_L
            # (rounding on a sliver, see gjk3d.gjk); the full signed distance then decides
            return (True, DECIDED) if lower <= 0.0 else (False, UNDECIDED)
    return False, UNDECIDED


def _margin_loop(a_floats, a_ints, b_floats, b_ints, poses, margin, rtol, atol, eps, work, hit_out, code_out):
    """Every pair of a batch; ``poses``: (pos_a, rot_a, pos_b, rot_b), each of N or 1 rows; ``work``:
    GJK's workspace (W, I, lam) per block of :data:`BLOCK` pairs, ceil(N / BLOCK) x 8 (x 3) each."""
    avx, avy, aeang, aetab, avang, ainv, aoff, arad, acen = unpack(a_floats, a_ints)
    bvx, bvy, beang, betab, _, _, boff, brad, bcen = unpack(b_floats, b_ints)
    P = (avx, avy, aeang, aetab, bvx, bvy, beang, betab)
    pos_a, rot_a, pos_b, rot_b = poses
    W_all, I_all, lam_all = work
    n = hit_out.shape[0]
    for bp in prange(W_all.shape[0]):
        blk = np.int64(bp)  # prange's index is unsigned
        W, I, lam = W_all[blk], I_all[blk], lam_all[blk]
        for i in range(blk * BLOCK, min(blk * BLOCK + BLOCK, n)):
            ka, kb, ix, r = pair_index(i, arad, aoff, brad, boff, pos_a.shape[0], rot_a.shape[0], pos_b.shape[0],
                                        rot_b.shape[0])  # fmt: skip
            hit, code = pair_margin(P, ix, acen[ka], bcen[kb], arad[ka], brad[kb], pos_a[r[0]], rot_a[r[1]],
                                    pos_b[r[2]], rot_b[r[3]], margin, rtol, atol, eps, W, I, lam, avang,
                                    ainv)  # fmt: skip
            hit_out[i] = hit
            code_out[i] = code


margin_serial, margin_parallel = twins(_margin_loop, "margin", error_model="numpy")


def _fallback_loop(a_floats, a_ints, b_floats, b_ints, poses, margin, rtol, atol, eps, pairs, hit_out):
    """The pairs ``pairs`` (indices) that :func:`pair_margin` left undecided, by the full signed distance."""
    avx, avy, aeang, aetab, _, _, aoff, arad, acen = unpack(a_floats, a_ints)
    bvx, bvy, beang, betab, _, _, boff, brad, bcen = unpack(b_floats, b_ints)
    P = (avx, avy, aeang, aetab, bvx, bvy, beang, betab)
    pos_a, rot_a, pos_b, rot_b = poses
    for k in prange(pairs.shape[0]):
        i = pairs[k]
        ka, kb, ix, r = pair_index(i, arad, aoff, brad, boff, pos_a.shape[0], rot_a.shape[0], pos_b.shape[0],
                                    rot_b.shape[0])  # fmt: skip
        work = block_of(workspace(1, EPA_ROOM[0]), 0)
        d = pair_distance_any_room(P, ix, acen[ka], bcen[kb], arad[ka], brad[kb], pos_a[r[0]], rot_a[r[1]],
                                   pos_b[r[2]], rot_b[r[3]], rtol, atol, eps, np.bool_(False), work)[0]  # fmt: skip
        hit_out[i] = d <= margin


margin_fallback_serial, margin_fallback_parallel = twins(
    _fallback_loop, "margin_fallback", error_model="numpy", refcounts=True
)


def run(a_arrays, b_arrays, pos_a, rot_a, pos_b, rot_b, n, margin, rtol, atol, parallel):
    """``hit`` (n,) bool: the margin query of a batch, shapes and poses checked and converted
    (as :func:`prismbatch._kernels.batch.run` takes them); ``parallel`` None: by batch size."""
    shapes = (a_arrays.floats, a_arrays.ints, b_arrays.floats, b_arrays.ints)
    poses = (pos_a, rot_a, pos_b, rot_b)
    dt = pos_a.dtype
    eps = float(np.finfo(dt).eps)
    hit = np.empty(n, dtype=np.bool_)
    code = np.empty(n, dtype=np.int8)
    nb = -(-n // BLOCK)
    work = (np.empty((nb, 8, 3)), np.empty((nb, 8, 3), dtype=np.int64), np.empty((nb, 8)))
    kern = margin_parallel if use_parallel(parallel, n) else margin_serial
    first_call((kern, dt), kern, *shapes, poses, margin, rtol, atol, eps, work, hit, code)
    pairs = np.flatnonzero(code == UNDECIDED)
    if pairs.size:
        kern = margin_fallback_parallel if use_parallel(parallel, pairs.size) else margin_fallback_serial
        first_call((kern, dt), kern, *shapes, poses, margin, rtol, atol, eps, pairs, hit)
    return hit
