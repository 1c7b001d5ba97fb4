"""Signed distance between two semi-infinite convex prisms: 3-D GJK and EPA on O(log n) supports.

Each pair is computed in world axes with the origin at a's end-face centre
(positions differenced first, as in :func:`prismbatch._kernels.batch.pair_world`,
so small objects far from the world origin keep their separation). With
F_a, F_b the end faces and d_a, d_b the axes, A = F_a + ray(d_a) and
B = F_b + ray(d_b), so the Minkowski difference is

    D = A - B = K + C,   K = F_a - F_b,   C = cone(d_a, -d_b).

The signed distance is dist(0, D) when 0 is outside D and minus
dist(0, boundary of D) when inside. K is bounded and its support point
costs two extreme-vertex searches (O(1) to O(log n),
:func:`~prismbatch._kernels.planar.extreme_vertex`). C is cut to
C_L = C ∩ box: in C's plane, with ẑ along d_a and ŝ across it towards -d_b,
the box is 0 <= s <= L, |z| <= L, with L = 4 S (S = R_a + R_b + |c_b - c_a|).
Every point of D within 3 S of the origin is a point k + c with |c| <= L, so
the gap (at most S) and the depth (at most S) of D_L = K + C_L are those of D,
and the coordinates stay below about 5 S for every angle between the axes: the
tilt enters only as the s : z ratio of C_L's corners, never as a division.

GJK gives the gap; when the origin is inside D_L (or within the accuracy), EPA
expands a polytope inside D_L to the facet nearest the origin. The witness
points come from one more GJK: the closest point of D_L to the foot point,
whose simplex weights split it into a point of A and a point of B.
"""

import math

import numpy as np
from numba import prange

from .batch import centres_and_tolerance, unpack
from .gjk3d import gjk
from .jit import jit, twins
from .minkowski import cut_difference, point_a, support
from .parallel import frames_rigid, parallel_gap, parallel_overlap, tilted_overlap
from .vec3 import cross, diff, dot, normal, row, sub

SEPARATED, TOUCHING, PENETRATING = 1, 0, -1
#: C_L's box half-width in units of the pair scale S (see the module docstring).
BOX = 4.0
#: Target accuracy of the distance as a fraction of the pair tolerance, floored at ACC_EPS float64 eps L.
ACC_FRACTION = 1e-3
ACC_EPS = 64.0
#: Where rounding stops GJK short of that, a gap bracketed to within this fraction of the tolerance is kept.
LOOSE_FRACTION = 0.1
EPS64 = float(np.finfo(np.float64).eps)
#: EPA's room in vertices: tried in turn while it runs out (128 hold 99.99 % of 3600-gon pairs; 100,000-gons
#: need up to ~600); it has 8 faces per vertex. The batch loops hold one workspace of the first per block
#: and send the rare pair that runs out of it to a second pass with the last (pairs whose axes point the same
#: way take the separating-axis depth instead, at their first stop if nearly parallel or small: SAT_FIRST).
EPA_ROOM = (128, 1024, 8192)
#: Axes pointing the same way take the separating-axis depth at EPA's first stop when |d_b - d_a|^2 is at
#: most SAT_FIRST (tilts up to about 1.8 degrees: the scan then costs about 1 ms for two 3600-gons, and EPA
#: may stop on rounding there whatever its room) or the polygons have at most SAT_SMALL pairs of edges (the
#: scan over all of them is cheap). Otherwise EPA gets its larger rooms first (it finished in 0.1-0.2 ms on
#: 3600-gons whose first room ran out) and the separating axes come only where the largest runs out: their
#: scan grew to 7 ms at a tilt of 0.1 rad, 35 ms at 0.2 and 0.3 s over every pair of end edges (parallel.WIDE).
SAT_FIRST = 1e-3
SAT_SMALL = 4096
#: A face counts as seen from a new point up to this fraction of the accuracy below its plane: on nearly
#: coplanar faces (100,000-gons) rounding would otherwise leave an unseen face inside the seen region.
SEEN_SLACK = 1e-2
#: Solver codes of a pair (the ``solver`` output): the gap by GJK; the depth by EPA; EPA stopped early
#: (out of room at its largest, or a rounding-level step that would break its polytope: the depth
#: returned is then an upper bound, the last face offset a lower one); no volume around the origin (touching);
#: GJK stalled on rounding with a gap proven (the gap returned is an upper bound, attained by the witnesses);
#: the depth of exactly parallel axes pointing the same way, from their end faces in the plane (where EPA
#: stopped early on them: :mod:`.parallel`); the depth of other axes pointing the same way (nearly parallel:
#: EPA has only stopped on those) by the separating-axis theorem, where EPA stopped early; the gap of exactly
#: parallel axes, either way, from their end faces' distance in the plane and along the axes (:mod:`.parallel`).
GJK_GAP, EPA_DEPTH, EPA_STOPPED, FLAT, GJK_STALLED, PLANAR_DEPTH, AXES_DEPTH, PLANAR_GAP = 0, 1, 2, 3, 4, 5, 6, 7


# --- EPA ------------------------------------------------------------------------------------------


@jit
def _off_hull(V, cnt, p):
    """Distance of p from the affine hull of V[:cnt] (cnt = 1, 2, 3)."""
    d = sub(p, row(V, 0))
    if cnt == 1:
        return math.sqrt(dot(d, d))
    e = diff(V, 1, 0)
    if cnt == 2:
        c = cross(d, e)
        return math.sqrt(dot(c, c) / dot(e, e))
    n = cross(e, diff(V, 2, 0))
    return abs(dot(n, d)) / math.sqrt(dot(n, n))


@jit
def _tetrahedron(P, ix, fr, cone, W, I, m, V, VI, tiny):
    """GJK's simplex grown to a positively oriented tetrahedron in V, VI by support points off its
    affine hull (searched along the axes; across a segment; along a triangle's normal). Returns
    (ok, nx, ny, nz): when no point lies more than ``tiny`` off, the hull is flat and n is across it."""
    cnt = 0
    for j in range(m):
        if cnt == 0 or _off_hull(V, cnt, row(W, j)) > tiny:
            for c in range(3):
                V[cnt, c], VI[cnt, c] = W[j, c], I[j, c]
            cnt += 1
    g = (1.0, 0.0, 0.0)
    while cnt < 4:
        e, f = diff(V, 1, 0), diff(V, 2, 0)
        if cnt == 2:  # f: a vector across e
            ax = abs(e[0]) <= abs(e[1]) and abs(e[0]) <= abs(e[2])
            f = (0.0, e[2], -e[1]) if ax else ((-e[2], 0.0, e[0]) if abs(e[1]) <= abs(e[2]) else (e[1], -e[0], 0.0))
        if cnt > 1:
            g = cross(e, f)
        best = tiny
        for t in range(6 if cnt == 1 else (4 if cnt == 2 else 2)):
            sg = 1.0 if t % 2 == 0 else -1.0
            if cnt == 1:
                d = ((sg if t < 2 else 0.0), (sg if 2 <= t < 4 else 0.0), (sg if t >= 4 else 0.0))
            else:
                d = (sg * f[0], sg * f[1], sg * f[2]) if cnt == 2 and t < 2 else (sg * g[0], sg * g[1], sg * g[2])
            x, y, z, ia, ib, kc = support(P, ix, fr, cone, d[0], d[1], d[2])
            off = _off_hull(V, cnt, (x, y, z))
            if off > best:
                best = off
                V[cnt, 0], V[cnt, 1], V[cnt, 2] = x, y, z
                VI[cnt, 0], VI[cnt, 1], VI[cnt, 2] = ia, ib, kc
        if best <= tiny:
            gn = math.sqrt(dot(g, g))
            return False, g[0] / gn, g[1] / gn, g[2] / gn
        cnt += 1
    if dot(cross(diff(V, 1, 0), diff(V, 2, 0)), diff(V, 3, 0)) < 0.0:  # orient: (1 - 0) x (2 - 0) towards 3
        for c in range(3):
            V[1, c], V[2, c] = V[2, c], V[1, c]
            VI[1, c], VI[2, c] = VI[2, c], VI[1, c]
    return True, 0.0, 0.0, 0.0


@jit
def _set_face(V, FV, FN, FG, f, i, j, k):
    """Face f = (V[i], V[j], V[k]), counter-clockwise seen from outside: unit normal and offset."""
    FV[f, 0], FV[f, 1], FV[f, 2] = i, j, k
    u, v = diff(V, j, i), diff(V, k, i)
    n = normal(u, v)  # (on slivers exact to rounding: a plain normal is tilted by eps / sin)
    nn = math.sqrt(dot(n, n))
    FG[f] = nn > 1e-13 * math.sqrt(dot(u, u) * dot(v, v))  # slivers: no trustworthy normal, never expanded
    if nn > 0.0:
        n = (n[0] / nn, n[1] / nn, n[2] / nn)
    FN[f, 0], FN[f, 1], FN[f, 2] = n
    FN[f, 3] = (dot(n, row(V, i)) + dot(n, row(V, j)) + dot(n, row(V, k))) / 3.0
    FN[f, 4] = FN[f, 3] if FG[f] else math.inf  # its key in the search for the nearest face (inf: never)


@jit
def epa(P, ix, fr, cone, W, I, m, acc, work):
    """Penetration depth of D_L from GJK's final simplex: (depth, nx, ny, nz, code).

    The simplex (whose hull holds the origin, to within ``acc``) is grown to a
    tetrahedron, then expanded towards the face nearest the origin until the
    support in that face's normal n lies within ``acc`` of the face. The depth
    returned is h_D(n), the support value (within ``acc`` above the face offset,
    a lower bound); ``n`` points out of D. ``code``: EPA_DEPTH; EPA_STOPPED (out
    of room, the workspace's vertices, or a step that would break the polytope); FLAT (no tetrahedron:
    D_L lies within ``acc`` of a plane through the origin; depth 0, n across it). ``work``: a
    :func:`workspace` block (its contents on entry do not matter).
    """
    V, VI, FV, FA, FN, FG, alive, stack, hor, start = work[3:]
    MV, MF = V.shape[0], FV.shape[0]
    ok, nx, ny, nz = _tetrahedron(P, ix, fr, cone, W, I, m, V, VI, acc)
    if not ok:
        return 0.0, nx, ny, nz, FLAT
    # Only the faces and vertices made here are read, each set when made: nothing to clear (the largest
    # room's arrays would cost a rerun pair some microseconds).
    for f, (i, j, k) in enumerate(((0, 2, 1), (0, 1, 3), (1, 2, 3), (0, 3, 2))):
        start[f] = -1  # (vertex f) the new face whose horizon edge starts at the vertex
        _set_face(V, FV, FN, FG, f, i, j, k)
        alive[f] = True
    for f in range(4):  # neighbours: the face holding the reversed edge
        for e in range(3):
            for g in range(4):
                for e2 in range(3):
                    if FV[g, e2] == FV[f, (e + 1) % 3] and FV[g, (e2 + 1) % 3] == FV[f, e]:
                        FA[f, e] = g
    nf, nv = 4, 4
    bh, bx, by, bz = math.inf, 1.0, 0.0, 0.0  # the least support value of a face set aside (an upper bound)
    while True:
        f = -1
        dmin = math.inf
        for g in range(nf):  # (one compare a face: a dead or set-aside face's key is inf)
            if FN[g, 4] < dmin:
                dmin = FN[g, 4]
                f = g
        if f < 0:
            return (bh, bx, by, bz, EPA_DEPTH) if bh < math.inf else (0.0, 1.0, 0.0, 0.0, FLAT)
        nx, ny, nz = FN[f, 0], FN[f, 1], FN[f, 2]
        x, y, z, ia, ib, kc = support(P, ix, fr, cone, nx, ny, nz)
        hw = nx * x + ny * y + nz * z
        if hw > bh:
            hw, nx, ny, nz = bh, bx, by, bz
        if hw - dmin <= acc:
            return hw, nx, ny, nz, EPA_DEPTH
        if nv == MV:
            return hw, nx, ny, nz, EPA_STOPPED
        stuck = False
        for c in range(3):
            v = FV[f, c]
            stuck |= VI[v, 0] == ia and VI[v, 1] == ib and VI[v, 2] == kc
        if stuck:  # no new vertex, yet short of the support: a sliver's normal is off; set the face aside
            bh, bx, by, bz = hw, nx, ny, nz
            FG[f] = False
            FN[f, 4] = math.inf
            continue
        iv = nv
        V[iv, 0], V[iv, 1], V[iv, 2] = x, y, z
        VI[iv, 0], VI[iv, 1], VI[iv, 2] = ia, ib, kc
        start[iv] = -1
        nv += 1
        # Faces seen from the new point, by a walk from f; their rim is the horizon.
        alive[f] = False
        FN[f, 4] = math.inf
        for sp, e in enumerate((2, 1, 0)):
            stack[sp, 0], stack[sp, 1] = f, e
        sp = 3
        nh = 0
        while sp > 0:
            sp -= 1
            g, e = stack[sp, 0], stack[sp, 1]
            h = FA[g, e]
            if not alive[h]:
                continue
            k = 0
            while FA[h, k] != g:
                k += 1
            if FN[h, 0] * x + FN[h, 1] * y + FN[h, 2] * z > FN[h, 3] - SEEN_SLACK * acc:
                alive[h] = False
                FN[h, 4] = math.inf
                stack[sp, 0], stack[sp, 1] = h, (k + 2) % 3
                stack[sp + 1, 0], stack[sp + 1, 1] = h, (k + 1) % 3
                sp += 2
            else:
                hor[nh, 0], hor[nh, 1], hor[nh, 2], hor[nh, 3] = FV[g, e], FV[g, (e + 1) % 3], h, k
                nh += 1
        if nf + nh > MF:
            return hw, nx, ny, nz, EPA_STOPPED
        ok = True
        for t in range(nh):  # new faces (a, b, new point), linked to the faces beyond and to each other
            g = nf + t
            _set_face(V, FV, FN, FG, g, hor[t, 0], hor[t, 1], iv)
            alive[g] = True
            FA[g, 0] = hor[t, 2]
            FA[hor[t, 2], hor[t, 3]] = g
            ok &= start[hor[t, 0]] < 0  # else the seen region is no disc (rounding): stop here
            start[hor[t, 0]] = g
        for t in range(nh):
            g = nf + t
            j = start[hor[t, 1]]
            ok &= j >= 0
            j = j if j >= 0 else g
            FA[g, 1] = j
            FA[j, 2] = g
        for t in range(nh):
            start[hor[t, 0]] = -1
        nf += nh
        if not ok:
            return hw, nx, ny, nz, EPA_STOPPED


# --- one pair, and the batch loop -----------------------------------------------------------------


@jit(refcounts=True)
def workspace(blocks, room):
    """Scratch of ``blocks`` independent distance computations with EPA room for ``room`` vertices:
    GJK's simplex and a copy (W 8 x 3, I 8 x 3, lam 8), then EPA's polytope (vertices, faces with
    their neighbours, normals (with offset and search key) and flags, the walk's stack, the horizon
    and its links), each array with a leading axis of ``blocks`` (:func:`block_of` takes one)."""
    b, mv, mf = blocks, room, 8 * room
    return (
        np.empty((b, 8, 3)),
        np.empty((b, 8, 3), dtype=np.int64),
        np.empty((b, 8)),
        np.empty((b, mv, 3)),
        np.empty((b, mv, 3), dtype=np.int64),
        np.empty((b, mf, 3), dtype=np.int64),
        np.empty((b, mf, 3), dtype=np.int64),
        np.empty((b, mf, 5)),
        np.empty((b, mf), dtype=np.bool_),
        np.empty((b, mf), dtype=np.bool_),
        np.empty((b, 2 * mf + 3, 2), dtype=np.int64),
        np.empty((b, mf, 4), dtype=np.int64),
        np.empty((b, mv), dtype=np.int64),
    )


@jit(inline="always", refcounts=True)  # returns arrays (when called from Python, not inlined)
def block_of(work, k):
    """Block k of a :func:`workspace`."""
    return (
        work[0][k],
        work[1][k],
        work[2][k],
        work[3][k],
        work[4][k],
        work[5][k],
        work[6][k],
        work[7][k],
        work[8][k],
        work[9][k],
        work[10][k],
        work[11][k],
        work[12][k],
    )


@jit
def pair_distance(P, ix, ca, cb, ra, rb, Pa, Ra, Pb, Rb, rtol, atol, eps, witness, work):
    """One pair: (signed distance, tol, solver code, normal, point_a), world coordinates.

    ``P``, ``ix``: as :func:`support`; ``ca``, ``cb``: the polygons' centres in
    their local frames; ``ra``, ``rb``: their radii. ``work``: a block of
    :func:`workspace` (GJK's simplex, EPA's polytope); where EPA runs out of its room the
    code is EPA_STOPPED (:func:`pair_distance_any_room` then tries more). The normal
    (3-tuple) points from a to b, point_b = point_a + distance * normal; both NaN unless ``witness``.
    """
    W, I, lam = work[0], work[1], work[2]
    ox, oy, oz, dx, dy, dz, tol = centres_and_tolerance(
        ca[0], ca[1], cb[0], cb[1], Pa, Ra, Pb, Rb, ra, rb, rtol, atol, eps
    )
    S = ra + rb + math.sqrt(dx * dx + dy * dy + dz * dz)
    L = BOX * S
    acc = max(ACC_FRACTION * tol, ACC_EPS * EPS64 * L)
    loose = max(LOOSE_FRACTION * tol, acc)
    fr, cone, s, (ex, ey, ez), k = cut_difference(Ra, Rb, dx, dy, dz, L)
    # (.parallel's answers are lengths in a's frame: taken only where the frames are rigid, frames_rigid)
    if ex == 0.0 and ey == 0.0 and ez == 0.0 and frames_rigid(Ra, Rb, S, tol):
        # exactly parallel axes: apart in the plane, the gap is that of the end faces there and along the
        # axes (no cut box)
        lower, gap, nrm, pa = parallel_gap(P, ix, Ra, Rb, ox, oy, oz, dx, dy, dz, acc, s)
        if lower > 0.0:
            if not witness:
                nrm = pa = (math.nan, math.nan, math.nan)
            return gap, tol, PLANAR_GAP, nrm, pa
    # GJK and EPA work in units of 1 / k (see cut_difference), and so do their accuracies
    m, vx, vy, vz, inside, lower = gjk(P, ix, fr, cone, 0.0, 0.0, 0.0, k * acc, k * loose, W, I, lam)
    code = GJK_GAP
    if inside and lower > k * acc:
        # GJK stalled short of its accuracy (rounding on nearly coplanar faces of D_L: nearly parallel
        # axes) but a support plane proves a gap: EPA, which starts from the origin inside, would be
        # wrong; |v| is attained by the simplex's points, an upper bound within |v| - lower of the gap.
        inside = False
        code = GJK_STALLED
    if not inside:
        vn = math.sqrt(vx * vx + vy * vy + vz * vz)
        nx, ny, nz = -vx / vn, -vy / vn, -vz / vn
        dist = vn / k
    else:
        depth, nx, ny, nz, code = epa(P, ix, fr, cone, W, I, m, k * acc, work)
        dist = -depth / k
        if code == EPA_STOPPED and s > 0.0 and ex == 0.0 and ey == 0.0 and ez == 0.0 and frames_rigid(Ra, Rb, S, tol):
            # D is a prism along the axes: its depth is the end faces' planar overlap, exactly
            depth, nrm, pa = parallel_overlap(P, ix, Ra, Rb, ox, oy, oz, dx, dy, dz)
            if not witness:
                nrm = pa = (math.nan, math.nan, math.nan)
            return -depth, tol, PLANAR_DEPTH, nrm, pa
        if (
            code == EPA_STOPPED
            and s > 0.0
            and (
                ex * ex + ey * ey + ez * ez <= SAT_FIRST
                or ix[1] * ix[3] <= SAT_SMALL
                or work[3].shape[0] >= EPA_ROOM[-1]
            )
            and frames_rigid(Ra, Rb, S, tol)
        ):
            # nearly parallel (D's facets nearly coplanar in a thin slab), small polygons, or out of EPA's
            # largest room: the depth by the separating-axis theorem over D's candidate facet normals, exact
            # to rounding
            sep, n_sat = tilted_overlap(P, ix, Ra, Rb, dx, dy, dz, ex, ey, ez)
            if sep > -math.inf:  # (some candidate always has finite supports: a guard)
                dist, (nx, ny, nz), code = sep, n_sat, AXES_DEPTH
    nan = math.nan
    if not witness:
        return dist, tol, code, (nan, nan, nan), (nan, nan, nan)
    if inside:  # split the foot point -dist n (on D's boundary, to within acc) into A and B
        f = -k * dist
        m, vx, vy, vz, _, _ = gjk(P, ix, fr, cone, f * nx, f * ny, f * nz, k * acc, k * loose, W, I, lam)
    px = py = pz = 0.0
    for j in range(m):
        qx, qy, qz = point_a(P[0], P[1], ix[0], fr, I[j, 0])
        al = cone[9 + 3 * I[j, 2]]  # the part of C_L's corner along a's axis
        px += lam[j] * (qx + al * cone[3])
        py += lam[j] * (qy + al * cone[4])
        pz += lam[j] * (qz + al * cone[5])
    return dist, tol, code, (nx, ny, nz), (ox + px / k, oy + py / k, oz + pz / k)


@jit(refcounts=True)
def pair_distance_any_room(P, ix, ca, cb, ra, rb, Pa, Ra, Pb, Rb, rtol, atol, eps, witness, work):
    """:func:`pair_distance` in ``work`` (a block of :func:`workspace` with room ``EPA_ROOM[0]``), then,
    while EPA runs out of room, again with the larger rooms of :data:`EPA_ROOM` (allocated here, for the
    rare pair: the one-pair path and the margin's fallback call this). Axes that point the same way never
    come back stopped from the largest room (nor from any, nearly parallel or small: :data:`SAT_FIRST`):
    :func:`pair_distance` takes the depth of :mod:`.parallel` there."""
    args = (P, ix, ca, cb, ra, rb, Pa, Ra, Pb, Rb, rtol, atol, eps, witness)
    res = pair_distance(*args, work)
    for room in EPA_ROOM[1:]:
        if res[2] != EPA_STOPPED:
            break
        res = pair_distance(*args, block_of(workspace(1, room), 0))  # the same GJK, then EPA with more room
    return res


@jit(inline="always")
def signed_status(d, tol):
    """SEPARATED, TOUCHING (``|d| <= tol``) or PENETRATING."""
    return TOUCHING if abs(d) <= tol else (SEPARATED if d > tol else PENETRATING)


@jit  # not inlined: Numba's array analysis of the parallel margin loop fails on it inlined
def pair_index(i, arad, aoff, brad, boff, npos_a, nrot_a, npos_b, nrot_b):
    """Pair i's shape rows ka, kb, polygon ranges ix and pose rows (a batch of one broadcasts)."""
    ka, kb = min(i, arad.shape[0] - 1), min(i, brad.shape[0] - 1)
    ix = (aoff[ka], aoff[ka + 1] - aoff[ka], boff[kb], boff[kb + 1] - boff[kb])
    return ka, kb, ix, (min(i, npos_a - 1), min(i, nrot_a - 1), min(i, npos_b - 1), min(i, nrot_b - 1))


def _distance_loop(a_floats, a_ints, b_floats, b_ints, poses, rtol, atol, eps, witness, work, out, wit):
    """Every pair of a batch, in as many contiguous blocks as ``work`` has (:func:`workspace`, one per
    block); ``poses``: (pos_a, rot_a, pos_b, rot_b), each of N or 1 rows; ``out``: (distance, status,
    tol, solver), N each; ``wit``: (normal, point_a, point_b), N x 3 or 0 x 3. A pair whose EPA ran out
    of room has solver EPA_STOPPED: the caller reruns it (:func:`_rerun_loop`)."""
    avx, avy, aeang, aetab, _, _, aoff, arad, acen = unpack(a_floats, a_ints)
    bvx, bvy, beang, betab, _, _, boff, brad, bcen = unpack(b_floats, b_ints)
    P = (avx, avy, aeang, aetab, bvx, bvy, beang, betab)
    dist_out, status_out, tol_out, solver_out = out
    normal_out, pa_out, pb_out = wit
    n = dist_out.shape[0]
    blocks = work[0].shape[0]
    for bp in prange(blocks):
        blk = np.int64(bp)  # prange's index is unsigned
        ws = block_of(work, blk)
        for i in range(blk * n // blocks, (blk + 1) * n // blocks):
            d, t, code, nrm, p = _pair(i, P, aoff, arad, acen, boff, brad, bcen, poses, rtol, atol, eps, witness, ws)
            _store(
                i, d, t, code, nrm, p, witness, dist_out, status_out, tol_out, solver_out, normal_out, pa_out, pb_out
            )


@jit(inline="always")
def _pair(i, P, aoff, arad, acen, boff, brad, bcen, poses, rtol, atol, eps, witness, ws):
    """:func:`pair_distance` of pair i of a batch in workspace ``ws`` (a batch of one broadcasts by index)."""
    pos_a, rot_a, pos_b, rot_b = poses
    ka, kb, ix, r = pair_index(i, arad, aoff, brad, boff, pos_a.shape[0], rot_a.shape[0], pos_b.shape[0],
                               rot_b.shape[0])  # fmt: skip
    return pair_distance(P, ix, acen[ka], bcen[kb], arad[ka], brad[kb], pos_a[r[0]], rot_a[r[1]], pos_b[r[2]],
                         rot_b[r[3]], rtol, atol, eps, witness, ws)  # fmt: skip


@jit(inline="always")
def _store(i, d, t, code, n, p, witness, dist_out, status_out, tol_out, solver_out, normal_out, pa_out, pb_out):
    """Row i of the outputs of :func:`_distance_loop` (arrays, not their tuples: tuples of arrays
    written inside a parallel loop's body did not reach the caller's arrays)."""
    dist_out[i] = d
    tol_out[i] = t
    status_out[i] = signed_status(d, t)
    solver_out[i] = code
    if witness:
        for c in range(3):
            normal_out[i, c] = n[c]
            pa_out[i, c] = p[c]
            pb_out[i, c] = p[c] + d * n[c]


def _rerun_loop(a_floats, a_ints, b_floats, b_ints, poses, rtol, atol, eps, witness, pairs, blocks, out, wit):
    """The pairs ``pairs`` (indices) whose EPA ran out of the batch loop's room, with EPA's largest room
    (the same answer as growing it step by step: a room only matters once it is full), in ``blocks``
    contiguous blocks that each allocate that room (some 10 MB) once."""
    avx, avy, aeang, aetab, _, _, aoff, arad, acen = unpack(a_floats, a_ints)
    bvx, bvy, beang, betab, _, _, boff, brad, bcen = unpack(b_floats, b_ints)
    P = (avx, avy, aeang, aetab, bvx, bvy, beang, betab)
    dist_out, status_out, tol_out, solver_out = out
    normal_out, pa_out, pb_out = wit
    m = pairs.shape[0]
    for bp in prange(blocks):
        blk = np.int64(bp)  # prange's index is unsigned
        ws = block_of(workspace(1, EPA_ROOM[-1]), 0)
        for k in range(blk * m // blocks, (blk + 1) * m // blocks):
            i = pairs[k]
            d, t, code, nrm, p = _pair(i, P, aoff, arad, acen, boff, brad, bcen, poses, rtol, atol, eps, witness, ws)
            _store(
                i, d, t, code, nrm, p, witness, dist_out, status_out, tol_out, solver_out, normal_out, pa_out, pb_out
            )


# The batch loop allocates nothing (its workspace comes in): no reference counting (jit's default); the
# second pass allocates EPA's largest room and counts.
distance_serial, distance_parallel = twins(_distance_loop, "distance", error_model="numpy")
rerun_serial, rerun_parallel = twins(_rerun_loop, "distance_rerun", error_model="numpy", refcounts=True)
