"""The detach controller's kernel (eqs. 42-46): contact class and direction per contact.

One loop over contacts, compiled serial and parallel; the public wrapper is
:func:`prismbatch.control.detach`.
"""

import math

import numpy as np
from numba import prange

from ..config import NOT_A_CONTACT_RTOL
from .batch import frame_inverse
from .jit import jit, twins
from .planar import point_polygon_distance, wedge_edge

NONE, VERTEX, END_EDGE, LATERAL_EDGE, SIDE_FACE, END_FACE, INSIDE = 0, 1, 2, 3, 4, 5, 6
#: Kernel-only code: the point lies outside a by more than its margin (detach raises).
NOT_ON_A = -1
EPS64 = float(np.finfo(np.float64).eps)


@jit(inline="always")
def seg_dist(px, py, x0, y0, x1, y1):
    """Distance from p to segment [x0, x1] and the segment parameter in [0, 1]."""
    ex = x1 - x0
    ey = y1 - y0
    ee = ex * ex + ey * ey
    f = ((px - x0) * ex + (py - y0) * ey) / ee if ee > 0.0 else 0.0
    f = min(max(f, 0.0), 1.0)
    return math.hypot(px - x0 - f * ex, py - y0 - f * ey), f


@jit(inline="always")
def outward_normal(Ra, ex, ey):
    """World outward unit normal of a's side face along local CCW edge (ex, ey)."""
    en = math.hypot(ex, ey)
    nlx = ey / en
    nly = -ex / en
    return (Ra[0, 0] * nlx + Ra[0, 1] * nly, Ra[1, 0] * nlx + Ra[1, 1] * nly, Ra[2, 0] * nlx + Ra[2, 1] * nly)


@jit(inline="always")
def outward_dir(nx, ny, nz, ex, ey, ez, dbx, dby, dbz, dax, day, daz):
    """Eqs. (43)-(46) for a vertex or end-face edge, all vectors in world frame.

    e: edge (or edge sum), n: outward side normal. Returns a unit vector.
    """
    ee = ex * ex + ey * ey + ez * ez
    k = (dbx * ex + dby * ey + dbz * ez) / ee
    # d_b projected on the plane normal to e
    vx = dbx - k * ex
    vy = dby - k * ey
    vz = dbz - k * ez
    vn = math.sqrt(vx * vx + vy * vy + vz * vz)
    if vn > 1e-12 and vx * nx + vy * ny + vz * nz >= 0.0:
        return vx / vn, vy / vn, vz / vn
    if vn <= 1e-12:  # d_b along the edge: leave between the side face and the end face
        cx = nx - dax
        cy = ny - day
        cz = nz - daz
    else:
        # e x d_v, oriented out of a (towards n - d_a)
        cx = ey * vz - ez * vy
        cy = ez * vx - ex * vz
        cz = ex * vy - ey * vx
        if cx * (nx - dax) + cy * (ny - day) + cz * (nz - daz) < 0.0:
            cx, cy, cz = -cx, -cy, -cz
    cn = math.sqrt(cx * cx + cy * cy + cz * cz)
    return cx / cn, cy / cn, cz / cn


# Kept as one long function: the per-pair hot path (not split into calls, which would add call and
# tuple overhead per pair; a measured split is future work).
def detach_loop(
    avx, avy, avang, ainv, aoff, arad, acen, pos_a, rot_a, rot_b, contact, tol, cls_out, dir_out, depth_out
):
    n = cls_out.shape[0]
    nsa = aoff.shape[0] - 1
    npa = pos_a.shape[0]
    nra = rot_a.shape[0]
    nrb = rot_b.shape[0]
    for ip in prange(n):
        i = np.int64(ip)
        sx = contact[i, 0]
        if not (math.isfinite(sx) and math.isfinite(contact[i, 1]) and math.isfinite(contact[i, 2])):
            cls_out[i] = NONE
            dir_out[i, 0] = math.nan
            dir_out[i, 1] = math.nan
            dir_out[i, 2] = math.nan
            depth_out[i] = math.nan
            continue
        ka = min(i, nsa - 1)
        Ra = rot_a[min(i, nra - 1)]
        Pa = pos_a[min(i, npa - 1)]
        Rb = rot_b[min(i, nrb - 1)]
        s = aoff[ka]
        m = aoff[ka + 1] - s
        # contact in a's centred frame
        ox = Pa[0] + Ra[0, 0] * acen[ka, 0] + Ra[0, 1] * acen[ka, 1]
        oy = Pa[1] + Ra[1, 0] * acen[ka, 0] + Ra[1, 1] * acen[ka, 1]
        oz = Pa[2] + Ra[2, 0] * acen[ka, 0] + Ra[2, 1] * acen[ka, 1]
        qx = contact[i, 0] - ox
        qy = contact[i, 1] - oy
        qz = contact[i, 2] - oz
        # by Ra's inverse, not its transpose: a float32 rotation is orthonormal only to about 1e-7, and its
        # transpose put contacts on a's vertices 1e-7 of their distance off, in class 6 ("inside")
        i00, i01, i02, i10, i11, i12, i20, i21, i22 = frame_inverse(Ra)
        x = i00 * qx + i01 * qy + i02 * qz
        y = i10 * qx + i11 * qy + i12 * qz
        z = i20 * qx + i21 * qy + i22 * qz
        t = tol[min(i, tol.shape[0] - 1)]
        # nearest vertex and edge: the wedge's neighbourhood (O(log n)), then the walks below
        k = wedge_edge(avang, s, m, x, y)
        best_v = math.inf
        iv = 0
        best_e = math.inf
        ie = 0
        fe = 0.5
        for j in range(k - 1, k + 3):
            jj = j % m
            dv = math.hypot(x - avx[s + jj], y - avy[s + jj])
            if dv < best_v:
                best_v = dv
                iv = jj
        ends = (0.0, 0.0)  # distances of edges k - 1 and k + 1, where the walks below start
        for j in range(k - 1, k + 2):
            jj = j % m
            j1 = (jj + 1) % m
            de, f = seg_dist(x, y, avx[s + jj], avy[s + jj], avx[s + j1], avy[s + j1])
            if j == k - 1:
                ends = (de, ends[1])
            elif j == k + 1:
                ends = (ends[0], de)
            if de < best_e:
                best_e = de
                ie = jj
                fe = f
        # On past the neighbourhood, each way, while the edges come nearer or stay within t: where t
        # exceeds the edges (a physical tol on a finely divided flat side) the wedge's edge need not be the
        # nearest. Usually one more edge each way.
        for side in range(2):
            step = -1 if side == 0 else 1
            prev = ends[side]
            j = k - 2 if side == 0 else k + 2
            for _ in range(m - 3):
                jj = j % m
                j1 = (jj + 1) % m
                de, f = seg_dist(x, y, avx[s + jj], avy[s + jj], avx[s + j1], avy[s + j1])
                if de < best_e:
                    best_e = de
                    ie = jj
                    fe = f
                jv = jj if side == 0 else j1  # the vertex this edge adds
                dv = math.hypot(x - avx[s + jv], y - avy[s + jv])
                if dv < best_v:
                    best_v = dv
                    iv = jv
                if de > t and de >= prev:
                    break
                prev = de
                j += step
        # On the end face, or above it: a contact just outside a (collide's lies within its own tolerance
        # of both bodies, which can exceed t) touches a where it is nearest, not "inside".
        on_end = z <= t
        near_v = best_v <= t
        near_e = best_e <= t
        beside = point_polygon_distance(avx, avy, avang, ainv, s, m, x, y)  # < 0: outside the polygon
        if beside < 0.0 and not (near_v or near_e):  # beside a: its nearest vertex or edge
            if fe == 0.0 or fe == 1.0:
                near_v = True
                iv = ie if fe == 0.0 else (ie + 1) % m
            else:
                near_e = True
        # Not a contact of a: above its end face, or beside its polygon (the
        # wedge edge line bounds the distance from below), by more than t plus
        # a margin that holds every contact collide returns (within 2 of its
        # own tolerances, and the rounding of far coordinates).
        far = (
            t
            + NOT_A_CONTACT_RTOL * arad[ka]
            + 8.0 * EPS64 * (abs(contact[i, 0]) + abs(contact[i, 1]) + abs(contact[i, 2]) + abs(ox) + abs(oy) + abs(oz))
        )
        if z < -far or beside < -far:
            cls_out[i] = NOT_ON_A
            dir_out[i, 0] = math.nan
            dir_out[i, 1] = math.nan
            dir_out[i, 2] = math.nan
            depth_out[i] = math.nan
            continue
        # edge vectors and outward normals in a's local frame
        if near_v:
            ip_ = (iv - 1) % m
            in_ = (iv + 1) % m
            ex = avx[s + in_] - avx[s + ip_]
            ey = avy[s + in_] - avy[s + ip_]
        else:
            e1 = (ie + 1) % m
            ex = avx[s + e1] - avx[s + ie]
            ey = avy[s + e1] - avy[s + ie]
        # edge (or edge sum) and outward side normal, in world coordinates
        wex = Ra[0, 0] * ex + Ra[0, 1] * ey
        wey = Ra[1, 0] * ex + Ra[1, 1] * ey
        wez = Ra[2, 0] * ex + Ra[2, 1] * ey
        nx, ny, nz = outward_normal(Ra, ex, ey)
        dax = Ra[0, 2]
        day = Ra[1, 2]
        daz = Ra[2, 2]
        depth = 0.0
        if on_end and (near_v or near_e):  # rows 1, 2: eqs. (43)-(46)
            c = VERTEX if near_v else END_EDGE
            cx, cy, cz = outward_dir(nx, ny, nz, wex, wey, wez, Rb[0, 2], Rb[1, 2], Rb[2, 2], dax, day, daz)
        elif near_v or near_e:  # rows 3, 4: normal to the lateral edge / side face
            c = LATERAL_EDGE if near_v else SIDE_FACE
            cx, cy, cz = nx, ny, nz
        elif on_end:
            c = END_FACE
            cx, cy, cz = -dax, -day, -daz
        else:
            c = INSIDE
            # shortest way out: nearest side plane (O(n) scan) or the end face
            dmin = math.inf
            jmin = 0
            for j in range(m):
                j1 = (j + 1) % m
                d = (
                    (avx[s + j1] - avx[s + j]) * (y - avy[s + j]) - (avy[s + j1] - avy[s + j]) * (x - avx[s + j])
                ) * ainv[s + j]
                if d < dmin:
                    dmin = d
                    jmin = j
            if z <= dmin:
                depth = max(z, 0.0)
                cx, cy, cz = -dax, -day, -daz
            else:
                depth = max(dmin, 0.0)
                j1 = (jmin + 1) % m
                cx, cy, cz = outward_normal(Ra, avx[s + j1] - avx[s + jmin], avy[s + j1] - avy[s + jmin])
        cls_out[i] = c
        dir_out[i, 0] = cx
        dir_out[i, 1] = cy
        dir_out[i, 2] = cz
        depth_out[i] = depth


detach_serial, detach_parallel = twins(detach_loop, "detach")
