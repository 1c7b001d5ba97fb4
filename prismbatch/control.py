"""Detach controller (the paper's section V, eqs. 42-46), vectorised over pairs.

Once b touches a, b is pushed away along a direction chosen by where the
contact point lies on a. :func:`detach` classifies the contact into the six
rows of eq. (42) and returns the direction and the force
``u_d = eps * |dx| * c``.

Every direction points *out of a*; the sign conventions the paper leaves
implicit and the direction chosen for each of the six rows are in
``docs/methods/detach.md``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ._kernels.batch import use_parallel
from ._kernels.detach import detach_parallel, detach_serial
from .checks import as_real_array, check_flag, indexed_name, real_scalar
from .config import NOT_A_CONTACT_RTOL
from .geometry import row_norms
from .poses import as_pose, as_rotations, common_batch_size
from .shapes import as_prism_set

__all__ = ["detach", "DetachResult", "CONTACT_CLASSES"]

CONTACT_CLASSES = {
    0: "no contact (no hit)",
    1: "a vertex of a's end face",
    2: "an edge of a's end face",
    3: "a lateral edge of a (the contact projects onto a vertex)",
    4: "a side face of a (the contact projects onto an edge)",
    5: "a's end face (s . d_a = 0)",
    6: "inside a (deeper than the tolerance)",
}


def _first_bad(ok):
    """Index of the first False in 1-D ``ok``, or None if all are True."""
    bad = np.flatnonzero(~ok)
    return None if bad.size == 0 else int(bad[0])


def _check_tol(tol, n):
    """``tol`` as a (1,) or (n,) float64 array: a real scalar or one per pair, finite and >= 0."""
    arr = as_real_array(tol, "tol")
    if arr.ndim > 1 or (arr.ndim == 1 and arr.shape[0] not in (1, n)):
        raise ValueError(f"tol must be a scalar or have shape ({n},) (one per pair), got shape {arr.shape}")
    t = np.atleast_1d(arr.astype(np.float64))
    i = _first_bad(np.isfinite(t) & (t >= 0.0))
    if i is not None:
        raise ValueError(f"{indexed_name('tol', i if arr.ndim else None)} must be finite and >= 0, got {t[i]}")
    return t


def _norms(err):
    """Euclidean norms of (N, k) rows (:func:`~prismbatch.geometry.row_norms`: norms of 1e-200 or 1e200
    neither underflow nor overflow in their squares), |x| of (N,) norms, or a scalar's as (1,)."""
    if err.ndim <= 1:
        return np.abs(err).reshape(-1)
    return row_norms(err.reshape(err.shape[0], int(np.prod(err.shape[1:]))))


def _force(eps, errn, direction):
    """``eps * |state error| * direction``; ValueError naming the first contact where it is not finite."""
    with np.errstate(over="ignore", invalid="ignore"):
        mag = eps * np.broadcast_to(errn, direction.shape[:1])
    i = _first_bad(np.isfinite(mag) | np.isnan(direction[:, 0]))  # no contact: NaN force anyway
    if i is not None:
        raise ValueError(
            f"eps = {eps:g} gives pair {i} a non-finite force (eps * |state_error| = {mag[i]:g}); "
            f"eps times the state error's norm must be finite: lower eps or rescale the state error"
        )
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


def detach(shape_a, contact, pos_a, rot_a, rot_b, state_error, *, eps=10.0, tol=None, quat_order=None, parallel=None):
    """Detach direction and force for contacts on prism a (eqs. 42-46).

    Parameters
    ----------
    shape_a : Prism or PrismSet
        Prism a (one shared, or one per pair).
    contact : array_like, shape (N, 3), or DistanceResult
        Contact points in world coordinates (``collide(..., contact=True).contact``);
        NaN rows (no hit) give class 0 and NaN directions. Or the result of
        :func:`prismbatch.distance` with ``witness=True``: then the contact
        is ``point_a`` (on a's boundary, where the bodies really touch, so
        the class is never 6 "inside"), the direction is the penetration
        normal (the shortest way out) and ``depth`` the penetration depth;
        separated pairs (status 1) are not contacts.
    pos_a, rot_a : array_like
        a's poses, as for :func:`prismbatch.collide`.
    rot_b : array_like
        b's rotations (its axis d_b enters rows 1 and 2).
    state_error : array_like
        The state error ``x - x_d``; its Euclidean norm scales the force.
        (N, k) rows for N pairs, or (N,) norms; for a single pair (a
        batch of one: one contact and single poses) a (k,) vector is that
        pair's error.
    eps : float, optional
        The detach gain ε (the paper uses 10): a real scalar, finite and
        >= 0, and small enough that ``eps * |state error|`` is finite for
        every pair in contact.
    tol : float or array_like of shape (N,), optional
        Distance within which the contact counts as on a feature (vertex,
        edge, face): one value for every pair, or one per pair; finite and
        >= 0. Default: 1e-9 times a's end-face radius plus a rounding
        floor (of a's position and its end face's offset from a's own
        origin); pass the pair tolerance of :func:`collide`
        (:func:`prismbatch.geometry.pair_scale_tolerance`) or a physical
        tolerance for simulated contacts. A contact just outside a (by less
        than the refusal margin) takes the class of a's nearest feature.
        The nearest vertex and edge are searched from the contact's polar
        wedge outwards while a's edges come nearer or stay within tol (a
        tol larger than the edges there, on a finely divided flat side,
        walks over several). On a polygon thinner than 2 tol a contact
        can be within tol of both sides; it is then classed by the
        features the search reaches.
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
    measured = _from_distance(contact)
    if measured is not None:
        contact = measured.contact
    elif dataclasses.is_dataclass(contact):  # a CollisionResult, say: its contact points are a field
        raise TypeError(
            f"contact must be points (N, 3) or a DistanceResult, got a {type(contact).__name__}; "
            "pass collide(..., contact=True).contact"
        )
    c = as_real_array(contact, "contact").astype(np.float64)
    if c.ndim == 1:
        c = c[None, :]
    if c.ndim != 2 or c.shape[1] != 3:
        raise ValueError(f"contact must have shape (N, 3), got {np.shape(contact)}")
    nan_rows = np.isnan(c).any(axis=1)
    i = _first_bad(~(np.isinf(c).any(axis=1) | (nan_rows & ~np.isnan(c).all(axis=1))))
    if i is not None:
        raise ValueError(f"contact[{i}] = {c[i].tolist()}: a contact is finite, or all NaN for no contact")
    err = as_real_array(state_error, "state_error").astype(np.float64)
    if not np.all(np.isfinite(err)):
        raise ValueError("state_error contains NaN or inf")
    n = common_batch_size(pa, ra, np.zeros(3), rb, n_shapes=len(set_a) if per else None)
    if n == 1:
        n = len(c)  # the contacts set the batch when every pose is single
    if err.ndim == 1 and n == 1:
        err = err[None, :]  # the one pair's error vector (with more pairs, (N,) are their norms)
    errn = _norms(err)
    if len(c) not in (1, n) or len(errn) not in (1, n):
        raise ValueError(
            f"batch sizes do not match: contact has {len(c)} rows, state_error {len(errn)}, poses and shapes {n}"
        )
    eps = real_scalar(eps, "eps", 0.0)
    if tol is None:  # (the rounding floor counts the end face's offset from a's own origin, as collide's does)
        reach = set_a.radius + np.abs(set_a.centre).sum(axis=1) + np.abs(pa).max(initial=0.0)
        tol_arr = 1e-9 * set_a.radius + 16 * np.finfo(np.float64).eps * reach
    else:
        tol_arr = _check_tol(tol, n)
    cls = np.empty(n, dtype=np.int8)
    direction = np.empty((n, 3))
    depth = np.empty(n)
    cc = np.ascontiguousarray(np.broadcast_to(c, (n, 3)))
    check_flag(parallel, "parallel", allow_none=True)
    kern = detach_parallel if use_parallel(parallel, n) else detach_serial
    kern(
        set_a.vx,
        set_a.vy,
        set_a.vertex_angle,
        set_a.inv_edge_len,
        set_a.offsets,
        set_a.radius,
        set_a.centre,
        np.ascontiguousarray(pa.reshape(-1, 3)),
        np.ascontiguousarray(ra.reshape(-1, 3, 3)),
        np.ascontiguousarray(rb.reshape(-1, 3, 3)),
        cc,
        np.ascontiguousarray(tol_arr),
        cls,
        direction,
        depth,
    )
    i = _first_bad(cls >= 0)
    if i is not None:
        where = f"contact[{i}]" if len(c) == n else f"contact (of pair {i})"
        raise ValueError(
            f"{where} = {cc[i].tolist()} lies outside a by more than tol + "
            f"{NOT_A_CONTACT_RTOL:g} x a's radius: not a contact point of a (pass "
            f"collide(..., contact=True).contact)"
        )
    if measured is not None:  # where the bodies really touch: out along the penetration normal
        hit = cls > 0
        direction[hit] = np.broadcast_to(measured.normal, (n, 3))[hit]
        depth[hit] = np.broadcast_to(measured.depth, (n,))[hit]
    force = _force(eps, errn, direction)
    return DetachResult(cls, direction, force, depth)


@dataclass(frozen=True)
class _Measured:
    contact: np.ndarray
    normal: np.ndarray
    depth: np.ndarray


def _from_distance(result):
    """The contact point, normal and depth of a :func:`prismbatch.distance` result; None for plain points."""
    from .distance import SEPARATED, DistanceResult

    if not isinstance(result, DistanceResult):
        return None
    try:
        normal, point_a = result.normal, result.point_a
    except AttributeError:
        raise ValueError("detach needs the witness points of the distance: call distance(..., witness=True)") from None
    apart = (result.status == SEPARATED)[:, None]
    depth = np.maximum(-result.distance, 0.0)
    return _Measured(np.where(apart, np.nan, point_a), np.where(apart, np.nan, normal), depth)
