"""Detach controller (the paper's section V, eqs. 42-46), vectorised over pairs.

Once b touches a, b is pushed away along a direction chosen by where the
contact point lies on a. :func:`detach` classifies the contact into the six
rows of eq. (42) and returns the direction and the force
``u_d = eps * |dx| * c``.

Sign conventions (the paper leaves the orientation of its edge vectors
implicit): every direction is made to point *out of a*. With e the edge (or,
at a vertex, the sum of the two edges beside it, v_next - v_prev) and n the
outward normal of a's side face (or the outward bisector at the vertex):

row 1 vertex of a's end face   d_v = d_b projected on the plane normal to e;
                               c_v = d_v if d_v . n >= 0, else the unit vector
                               normal to e and d_v that points out of a (eqs. 43-44)
row 2 edge of a's end face     the same with the edge vector (eqs. 45-46)
row 3 lateral edge of a        n (normal to d_a and to the sum of the edges)
row 4 side face of a           n (normal to the side face)
row 5 a's end face             -d_a
row 6 inside a                 the shortest way out: the outward normal of the
                               nearest side face, or -d_a if the end face is
                               nearer (the unnumbered equation after (46));
                               returned as a unit vector, its length is ``depth``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from ._kernels.batch import _variant, use_parallel
from ._kernels.planar import point_polygon_distance, wedge_edge
from .config import NOT_A_CONTACT_RTOL
from .poses import _as_real_array, _where, as_pose, as_rotations, common_batch_size, real_scalar
from .shapes import as_prism_set

__all__ = ["detach", "DetachResult", "CONTACT_CLASSES"]

NONE, VERTEX, END_EDGE, LATERAL_EDGE, SIDE_FACE, END_FACE, INSIDE = 0, 1, 2, 3, 4, 5, 6
#: Kernel-only code: the point lies outside a by more than tol (detach raises).
_NOT_ON_A = -1
EPS64 = float(np.finfo(np.float64).eps)

CONTACT_CLASSES = {
    0: "no contact (no hit)",
    1: "a vertex of a's end face",
    2: "an edge of a's end face",
    3: "a lateral edge of a (the contact projects onto a vertex)",
    4: "a side face of a (the contact projects onto an edge)",
    5: "a's end face (s . d_a = 0)",
    6: "inside a (deeper than the tolerance)",
}


@njit(cache=True, inline="always")
def _seg_dist(px, py, x0, y0, x1, y1):
    """Distance from p to segment [x0, x1] and the segment parameter in [0, 1]."""
    ex = x1 - x0
    ey = y1 - y0
    ee = ex * ex + ey * ey
    f = ((px - x0) * ex + (py - y0) * ey) / ee if ee > 0.0 else 0.0
    f = min(max(f, 0.0), 1.0)
    return math.hypot(px - x0 - f * ex, py - y0 - f * ey), f


@njit(cache=True, inline="always")
def _outward_normal(Ra, ex, ey):
    """World outward unit normal of a's side face along local CCW edge (ex, ey)."""
    en = math.hypot(ex, ey)
    nlx = ey / en
    nly = -ex / en
    return (Ra[0, 0] * nlx + Ra[0, 1] * nly, Ra[1, 0] * nlx + Ra[1, 1] * nly,
            Ra[2, 0] * nlx + Ra[2, 1] * nly)


@njit(cache=True, inline="always")
def _outward_dir(nx, ny, nz, ex, ey, ez, dbx, dby, dbz, dax, day, daz):
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


def _detach_loop(avx, avy, avang, ainv, aoff, arad, acen, pos_a, rot_a, rot_b, contact, tol,
                   cls_out, dir_out, depth_out):
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
        x = Ra[0, 0] * qx + Ra[1, 0] * qy + Ra[2, 0] * qz
        y = Ra[0, 1] * qx + Ra[1, 1] * qy + Ra[2, 1] * qz
        z = Ra[0, 2] * qx + Ra[1, 2] * qy + Ra[2, 2] * qz
        t = tol[min(i, tol.shape[0] - 1)]
        # nearest vertex and edge among the wedge's neighbourhood (O(log n))
        k = wedge_edge(avang, s, m, x, y)
        best_v = math.inf
        iv = 0
        best_e = math.inf
        ie = 0
        for j in range(k - 1, k + 3):
            jj = j % m
            dv = math.hypot(x - avx[s + jj], y - avy[s + jj])
            if dv < best_v:
                best_v = dv
                iv = jj
        for j in range(k - 1, k + 2):
            jj = j % m
            j1 = (jj + 1) % m
            de, _ = _seg_dist(x, y, avx[s + jj], avy[s + jj], avx[s + j1], avy[s + j1])
            if de < best_e:
                best_e = de
                ie = jj
        on_end = abs(z) <= t
        near_v = best_v <= t
        near_e = best_e <= t
        # Not a contact of a: above its end face, or beside its polygon (the
        # wedge edge line bounds the distance from below), by more than t plus
        # a margin that holds every contact collide returns (within 2 of its
        # own tolerances, and the rounding of far coordinates).
        far = t + NOT_A_CONTACT_RTOL * arad[ka] + 8.0 * EPS64 * (
            abs(contact[i, 0]) + abs(contact[i, 1]) + abs(contact[i, 2]) + abs(ox) + abs(oy) + abs(oz))
        if z < -far or point_polygon_distance(avx, avy, avang, ainv, s, m, x, y) < -far:
            cls_out[i] = _NOT_ON_A
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
        nx, ny, nz = _outward_normal(Ra, ex, ey)
        dax = Ra[0, 2]
        day = Ra[1, 2]
        daz = Ra[2, 2]
        depth = 0.0
        if on_end and (near_v or near_e):  # rows 1, 2: eqs. (43)-(46)
            c = VERTEX if near_v else END_EDGE
            cx, cy, cz = _outward_dir(nx, ny, nz, wex, wey, wez, Rb[0, 2], Rb[1, 2], Rb[2, 2], dax, day, daz)
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
                d = ((avx[s + j1] - avx[s + j]) * (y - avy[s + j])
                     - (avy[s + j1] - avy[s + j]) * (x - avx[s + j])) * ainv[s + j]
                if d < dmin:
                    dmin = d
                    jmin = j
            if z <= dmin:
                depth = max(z, 0.0)
                cx, cy, cz = -dax, -day, -daz
            else:
                depth = max(dmin, 0.0)
                j1 = (jmin + 1) % m
                cx, cy, cz = _outward_normal(Ra, avx[s + j1] - avx[s + jmin], avy[s + j1] - avy[s + jmin])
        cls_out[i] = c
        dir_out[i, 0] = cx
        dir_out[i, 1] = cy
        dir_out[i, 2] = cz
        depth_out[i] = depth


_detach_serial = njit(cache=True)(_variant(_detach_loop, "detach_serial"))
_detach_parallel = njit(cache=True, parallel=True)(_variant(_detach_loop, "detach_parallel"))


def _first_bad(ok):
    """Index of the first False in 1-D ``ok``, or None if all are True."""
    bad = np.flatnonzero(~ok)
    return None if bad.size == 0 else int(bad[0])


def _check_tol(tol, n):
    """``tol`` as a (1,) or (n,) float64 array: a real scalar or one per pair, finite and >= 0."""
    arr = _as_real_array(tol, "tol")
    if arr.ndim > 1 or (arr.ndim == 1 and arr.shape[0] not in (1, n)):
        raise ValueError(f"tol must be a scalar or have shape ({n},) (one per pair), got shape {arr.shape}")
    t = np.atleast_1d(arr.astype(np.float64))
    i = _first_bad(np.isfinite(t) & (t >= 0.0))
    if i is not None:
        raise ValueError(f"{_where('tol', i if arr.ndim else None)} must be finite and >= 0, got {t[i]}")
    return t


def _force(eps, errn, direction):
    """``eps * |state error| * direction``; ValueError naming the first contact where it is not finite."""
    with np.errstate(over="ignore", invalid="ignore"):
        mag = eps * np.broadcast_to(errn, direction.shape[:1])
    i = _first_bad(np.isfinite(mag) | np.isnan(direction[:, 0]))  # no contact: NaN force anyway
    if i is not None:
        raise ValueError(f"eps = {eps:g} gives pair {i} a non-finite force (eps * |state_error| = {mag[i]:g}); "
                         f"eps times the state error's norm must be finite: lower eps or rescale the state error")
    return mag[:, None] * direction  # NaN where there is no contact, as the direction


@dataclass(frozen=True)
class DetachResult:
    """Output of :func:`detach` for N pairs.

    Attributes
    ----------
    contact_class : numpy.ndarray of int8, shape (N,)
        Row of eq. (42), see :data:`CONTACT_CLASSES` (0 where there is no contact).
    direction : numpy.ndarray, shape (N, 3)
        Unit detach direction in world coordinates (NaN where no contact).
    force : numpy.ndarray, shape (N, 3)
        ``eps * |state error| * direction``.
    depth : numpy.ndarray, shape (N,)
        For class 6 (inside), the distance to the nearest face of a; 0 otherwise.
    """

    contact_class: np.ndarray
    direction: np.ndarray
    force: np.ndarray
    depth: np.ndarray


def detach(shape_a, contact, pos_a, rot_a, rot_b, state_error, *, eps=10.0, tol=None, quat_order=None,
           parallel=None):
    """Detach direction and force for contacts on prism a (eqs. 42-46).

    Parameters
    ----------
    shape_a : Prism or PrismSet
        Prism a (one shared, or one per pair).
    contact : array_like, shape (N, 3)
        Contact points in world coordinates (``collide(..., contact=True).contact``);
        NaN rows (no hit) give class 0 and NaN directions.
    pos_a, rot_a : array_like
        a's poses, as for :func:`prismbatch.collide`.
    rot_b : array_like
        b's rotations (its axis d_b enters rows 1 and 2).
    state_error : array_like
        The state error ``x - x_d``; its Euclidean norm scales the force.
        (N, k) rows for N pairs, or (N,) norms; for a single pair (one
        contact row) a (k,) vector is that pair's error.
    eps : float, optional
        The detach gain ε (the paper uses 10): a real scalar, finite and
        >= 0, and small enough that ``eps * |state error|`` is finite for
        every pair in contact.
    tol : float or array_like of shape (N,), optional
        Distance within which the contact counts as on a feature (vertex,
        edge, face): one value for every pair, or one per pair; finite and
        >= 0. Default: 1e-9 times a's end-face radius plus a rounding
        floor; pass the pair tolerance of :func:`collide` or a physical
        tolerance for simulated contacts.
    parallel : bool or None, optional
        Spread pairs over Numba's threads; None (default) does so for large
        batches only (thread start-up costs more than small batches).

    Returns
    -------
    DetachResult

    Raises
    ------
    TypeError
        If ``eps`` or ``tol`` is not real numeric (a string, bool, object).
    ValueError
        If ``eps`` is not a scalar, negative, NaN or inf, or makes the
        force of a contact non-finite (the message names the pair); if
        ``tol`` is not a scalar or a length-N array, or is negative, NaN or
        inf (the message names the first offending index); and on bad
        poses, contacts, state errors or batch sizes.
    """
    set_a, per = as_prism_set(shape_a, "shape_a")
    pa, ra = as_pose(pos_a, rot_a, quat_order=quat_order, name="a")
    rb = as_rotations(rot_b, quat_order=quat_order, name="rot_b")
    c = _as_real_array(contact, "contact").astype(np.float64)
    if c.ndim == 1:
        c = c[None, :]
    if c.ndim != 2 or c.shape[1] != 3:
        raise ValueError(f"contact must have shape (N, 3), got {np.shape(contact)}")
    nan_rows = np.isnan(c).any(axis=1)
    i = _first_bad(~(np.isinf(c).any(axis=1) | (nan_rows & ~np.isnan(c).all(axis=1))))
    if i is not None:
        raise ValueError(f"contact[{i}] = {c[i].tolist()}: a contact is finite, or all NaN for no contact")
    err = _as_real_array(state_error, "state_error").astype(np.float64)
    if not np.all(np.isfinite(err)):
        raise ValueError("state_error contains NaN or inf")
    if err.ndim == 1 and len(c) == 1:
        err = err[None, :]  # one pair's error vector
    # (N, k) rows -> their norms, (N,) -> as given (abs), a scalar -> one value
    errn = np.sqrt(np.square(err).sum(axis=tuple(range(1, err.ndim)))) if err.ndim >= 1 else np.abs(err).reshape(1)
    n = common_batch_size(pa, ra, np.zeros(3), rb, n_shapes=len(set_a) if per else None)
    if n == 1:
        n = len(c)  # the contacts set the batch when every pose is single
    if len(c) not in (1, n) or len(errn) not in (1, n):
        raise ValueError(f"batch sizes do not match: contact has {len(c)} rows, state_error {len(errn)}, "
                         f"poses and shapes {n}")
    eps = real_scalar(eps, "eps", 0.0)
    if tol is None:
        tol_arr = 1e-9 * set_a.radius + 16 * np.finfo(np.float64).eps * (
            set_a.radius + np.abs(pa).max(initial=0.0))
    else:
        tol_arr = _check_tol(tol, n)
    cls = np.empty(n, dtype=np.int8)
    direction = np.empty((n, 3))
    depth = np.empty(n)
    cc = np.ascontiguousarray(np.broadcast_to(c, (n, 3)))
    if parallel is not None and not isinstance(parallel, (bool, np.bool_)):
        raise TypeError(f"parallel must be True, False or None, got {parallel!r}")
    kern = _detach_parallel if use_parallel(parallel, n) else _detach_serial
    kern(set_a.vx, set_a.vy, set_a.vertex_angle, set_a.inv_edge_len, set_a.offsets, set_a.radius, set_a.centre,
                   np.ascontiguousarray(pa.reshape(-1, 3)), np.ascontiguousarray(ra.reshape(-1, 3, 3)),
                   np.ascontiguousarray(rb.reshape(-1, 3, 3)), cc, np.ascontiguousarray(tol_arr), cls, direction,
                   depth)
    i = _first_bad(cls >= 0)
    if i is not None:
        raise ValueError(f"contact[{i}] = {cc[i].tolist()} lies outside a by more than tol + "
                         f"{NOT_A_CONTACT_RTOL:g} x a's radius: not a contact point of a (pass "
                         f"collide(..., contact=True).contact)")
    force = _force(eps, errn, direction)
    return DetachResult(cls, direction, force, depth)
