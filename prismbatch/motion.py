"""Time of impact of a moving prism against a fixed one: :func:`time_of_impact`.

a stays where it is; b moves with a constant linear velocity v and angular
velocity w, both in world coordinates, w about b's position:

    p_b(t) = p_b + v t,    R_b(t) = exp(t [w]x) R_b.

The answer for each pair is the first time in [0, horizon] at which the
bodies touch (within the touching tolerance of :func:`~prismbatch.collide`),
0 if they already do, inf if they do not within the horizon. It comes from
conservative advancement on :func:`~prismbatch.distance`: from a gap d the time
advances by a step that a proven bound on the closing rate keeps free of
contact. b is semi-infinite, so its points far along the axis move without
bound when the axis turns; only the part of b within S / sigma of its end face
along the axis can make the first contact (``S = R_a + R_b + |c_b - c_a|``,
sigma = 1 when the axes face each other and ``|d_a x d_b|`` when they point the
same way). The rate is bounded directionally: along the computed normal, by
how fast b's support point (or a's, seen from b) approaches, which near a
contact is the distance's own rate, so few steps are needed. No step can jump
over a contact, however fast the motion. The method and its proof are in
``docs/methods/time-of-impact.md`` and :mod:`prismbatch._kernels.motion`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._kernels.batch import use_parallel, work_blocks
from ._kernels.distance import EPA_ROOM, workspace
from ._kernels.jit import first_call
from ._kernels.motion import (
    CLEAR,
    CONTACT,
    RERUN,
    UNDECIDED,
    toi_parallel,
    toi_rerun_parallel,
    toi_rerun_serial,
    toi_serial,
)
from .checks import integer, refuse_masked
from .collide import collider_for
from .results import BatchResult

__all__ = ["time_of_impact", "impact_times", "TimeOfImpactResult", "STATUS", "CONTACT", "CLEAR", "UNDECIDED"]

#: Default iteration cap of one pair.
DEFAULT_MAX_ITER = 1000

#: Meaning of :attr:`TimeOfImpactResult.status`.
STATUS = {
    CONTACT: "contact: the bodies touch (distance <= tol) at time, and not before it",
    CLEAR: "clear: no contact within the horizon (time is inf)",
    UNDECIDED: "undecided: the iteration cap was reached; no contact before time (a lower bound), none claimed",
}


@dataclass(frozen=True)
class TimeOfImpactResult(BatchResult):
    """Result of :func:`time_of_impact` for ``N`` pairs.

    Attributes
    ----------
    time : numpy.ndarray, shape (N,)
        The first time at which the bodies touch, in [0, horizon]; inf when
        they do not within the horizon. Where ``status`` is :data:`UNDECIDED`
        it is how far the motion was proven free of contact: a lower bound,
        not a contact.
    status : numpy.ndarray of int8, shape (N,)
        :data:`CONTACT` (1), :data:`CLEAR` (0) or :data:`UNDECIDED` (-1); see
        :data:`STATUS`.
    iterations : numpy.ndarray of int32, shape (N,)
        Advancement steps taken (one distance query more than this).
    distance : numpy.ndarray, shape (N,)
        Signed distance at ``time`` (at most the pair's tolerance where
        ``status`` is CONTACT; NaN where CLEAR).
    """

    time: np.ndarray
    status: np.ndarray
    iterations: np.ndarray
    distance: np.ndarray
    _pos_b: np.ndarray | None = None
    _rot_b: np.ndarray | None = None
    _contact: np.ndarray | None = None

    def _extra(self, name, flag):
        value = getattr(self, "_" + name)
        if value is None:
            raise AttributeError(f"{name} was not computed: call time_of_impact(..., {flag}=True)")
        return value

    @property
    def hit(self) -> np.ndarray:
        """(N,) bool: the bodies touch within the horizon (``status == CONTACT``)."""
        return self.status == CONTACT

    @property
    def pos_b(self) -> np.ndarray:
        """(N, 3) b's position at ``time``, NaN rows where CLEAR (``pose=True``)."""
        return self._extra("pos_b", "pose")

    @property
    def rot_b(self) -> np.ndarray:
        """(N, 3, 3) b's rotation at ``time``, NaN where CLEAR (``pose=True``)."""
        return self._extra("rot_b", "pose")

    @property
    def contact(self) -> np.ndarray:
        """(N, 3) the contact at ``time``: the midpoint of the witness points of
        :func:`~prismbatch.distance`; NaN rows unless CONTACT (``contact=True``)."""
        return self._extra("contact", "contact")

    def __repr__(self):
        n = len(self)
        counts = {STATUS[s].split(":")[0]: int(np.count_nonzero(self.status == s)) for s in STATUS}
        return f"TimeOfImpactResult({n} pair{'s' * (n != 1)}; {counts})"

    def columns(self) -> dict:
        """The result as named 1-D columns (``pandas.DataFrame(result.columns())`` takes them)."""
        out = {"time": self.time, "status": self.status, "iterations": self.iterations, "distance": self.distance}
        for name, arr in (("pos_b", self._pos_b), ("contact", self._contact)):
            if arr is not None:
                out.update({f"{name}_{c}": arr[:, j] for j, c in enumerate("xyz")})
        if self._rot_b is not None:
            out.update({f"rot_b_{i}{j}": self._rot_b[:, i, j] for i in range(3) for j in range(3)})
        return out


def time_of_impact(
    shape_a,
    shape_b,
    pos_a,
    rot_a=None,
    pos_b=None,
    rot_b=None,
    velocity=None,
    angular_velocity=None,
    *,
    horizon,
    pose=False,
    contact=False,
    max_iter=DEFAULT_MAX_ITER,
    quat_order=None,
    rtol=None,
    atol=0.0,
    dtype=np.float64,
    parallel=None,
):
    """First time at which a moving prism b touches a fixed prism a, for a batch of motions.

    Parameters
    ----------
    shape_a, shape_b, pos_a, rot_a, pos_b, rot_b, quat_order, rtol, atol, dtype, parallel
        As for :func:`~prismbatch.collide`: the same shapes, pose forms,
        broadcasting, tolerance and threading; the poses are those at t = 0
        (with 4x4 transforms, ``time_of_impact(a, b, T_a, T_b, velocity=v, ...)``).
    velocity : array_like, shape (3,) or (N, 3)
        b's linear velocity in world coordinates.
    angular_velocity : array_like, shape (3,) or (N, 3), optional
        b's angular velocity in world coordinates, about b's position
        (default none): ``R_b(t) = exp(t [w]x) R_b``.
    horizon : float or array_like, shape (N,)
        The end of the time window, finite and > 0.
    pose : bool, optional
        Also give b's pose at ``time`` (``pos_b``, ``rot_b``).
    contact : bool, optional
        Also give the contact point at ``time``.
    max_iter : int, optional
        Iteration cap per pair (default 1000); a pair that reaches it is
        reported :data:`UNDECIDED`, never as a contact.

    Returns
    -------
    TimeOfImpactResult
        ``time`` (N,), ``status`` (N,) int8, ``iterations`` (N,), ``distance``
        (N,) and, on request, ``pos_b`` (N, 3), ``rot_b`` (N, 3, 3), ``contact`` (N, 3).

    Notes
    -----
    Conservative advancement: from a gap d > tol the time advances by the
    longest step tau that one of three bounds proves free of contact, tau V < g:
    g the separation along the computed normal n of the support planes of the
    parts of a and b that can touch, and V the rate at which b's support along
    -n, or a's support along -n turning with b, can approach (essentially
    ``v.u + r*.(u x w)``, u = -n, r* the support point's lever, plus terms for
    the turn of u over the step and for b's points along its axis up to S / sigma,
    sigma = 1 while the axes face each other, else ``|d_a x d_b|``); or the gap
    d - m (m the distance's error bound) along the exact normal with a
    whole-body bound ``|v| cos(max(0, angle(-v, n) - phi)) + |w| rho_b +
    |w x d_b| beta``. No step passes a contact, however fast the motion.

    Time tolerance: the reported time lies between the first time the bodies
    come within ``tol`` of each other and the first time they touch (both to the
    distance's accuracy, 1e-3 tol); when the distance falls at a rate r there,
    that is a window of tol / r. Motions along which b's axis turns towards
    a's own direction (theta -> 0) or that graze a for long can need many steps;
    at ``max_iter`` the pair is :data:`UNDECIDED`.

    Raises
    ------
    TypeError, ValueError
        Bad shapes, poses or tolerances (as :func:`~prismbatch.collide`), or a
        velocity, angular velocity, horizon or max_iter that is not finite, of
        another shape or of another batch size.

    Examples
    --------
    >>> import numpy as np, prismbatch as pb
    >>> from prismbatch.motion import time_of_impact
    >>> a, b = pb.Prism.regular(4, 1.0), pb.Prism.regular(4, 1.0)
    >>> down = np.diag([1.0, -1.0, -1.0])          # a's axis points down, b's up
    >>> r = time_of_impact(a, b, [0, 0, 0], down, [0, 0, 2.0], np.eye(3), [0, 0, -4.0], horizon=1.0)
    >>> float(r.time[0].round(6)), r.status.tolist()
    (0.5, [1])
    """
    col = collider_for(shape_a, shape_b, rtol, atol, dtype)  # checks and packs the shapes (kept for repeat calls)
    return col.time_of_impact(
        pos_a,
        rot_a,
        pos_b,
        rot_b,
        velocity,
        angular_velocity,
        horizon=horizon,
        pose=pose,
        contact=contact,
        max_iter=max_iter,
        quat_order=quat_order,
        parallel=parallel,
    )


def impact_times(
    a_arrays,
    b_arrays,
    n,
    pos_a,
    rot_a,
    pos_b,
    rot_b,
    velocity,
    angular_velocity,
    horizon,
    *,
    rtol,
    atol,
    dtype,
    max_iter,
    pose,
    contact,
    parallel,
):
    """:func:`time_of_impact` for shapes and poses already checked and packed (by a :class:`~prismbatch.Collider`).

    Parameters
    ----------
    a_arrays, b_arrays, n, pos_a, rot_a, pos_b, rot_b, rtol, atol, dtype
        As :func:`prismbatch.distance.signed_distance`.
    velocity, angular_velocity, horizon, max_iter
        As :func:`time_of_impact`, not yet checked (``max_iter`` None: the default); they may
        widen a batch of one.
    pose, contact, parallel
        As :func:`time_of_impact` (checked).

    Returns
    -------
    TimeOfImpactResult
    """
    vel = _vectors(velocity, "velocity")
    omg = np.zeros((1, 3)) if angular_velocity is None else _vectors(angular_velocity, "angular_velocity")
    hor = _horizons(horizon)
    max_iter = integer(DEFAULT_MAX_ITER if max_iter is None else max_iter, "max_iter", 1, 2**31 - 1)
    n = _batch_size(n, vel.shape[0], omg.shape[0], hor.shape[0])
    time = np.empty(n)
    status = np.empty(n, dtype=np.int8)
    iterations = np.empty(n, dtype=np.int32)
    dist = np.empty(n)
    k, kc = (n if pose else 0), (n if contact else 0)
    pos_out, rot_out, contact_out = np.empty((k, 3)), np.empty((k, 3, 3)), np.empty((kc, 3))
    parallel = use_parallel(parallel, n)
    kern = toi_parallel if parallel else toi_serial
    blocks = work_blocks(n, parallel)
    work = (np.empty((blocks, 3)), np.empty((blocks, 3, 3)), *workspace(blocks, EPA_ROOM[0]))  # b's pose, distance's
    args = (a_arrays.floats, a_arrays.ints, b_arrays.floats, b_arrays.ints, (pos_a, rot_a, pos_b, rot_b))
    args += ((vel, omg, hor), float(rtol), float(atol), float(np.finfo(dtype).eps), int(max_iter))
    outs = ((time, status, iterations, dist), (pos_out, rot_out), contact_out)
    first_call(("time_of_impact", kern, np.dtype(dtype)), kern, *args, work, *outs)
    again = np.flatnonzero(status == RERUN)  # EPA out of the batch's room: rarely needed
    if again.size:
        again_parallel = use_parallel(parallel, again.size)
        kern = toi_rerun_parallel if again_parallel else toi_rerun_serial
        blocks = work_blocks(again.size, again_parallel)
        first_call(("time_of_impact_rerun", kern, np.dtype(dtype)), kern, *args, again, blocks, *outs)
    return TimeOfImpactResult(
        time,
        status,
        iterations,
        dist,
        pos_out if pose else None,
        rot_out if pose else None,
        contact_out if contact else None,
    )


def _vectors(x, name):
    """(m, 3) float64 C-contiguous rows from (3,) or (m, 3), finite; TypeError / ValueError naming ``name``."""
    if x is None:
        raise TypeError(f"time_of_impact needs {name}: a (3,) or (N, 3) array")
    refuse_masked(x, name)
    a = None if isinstance(x, (str, bytes)) else np.asarray(x)
    if a is None or a.dtype.kind not in "iuf":
        raise TypeError(f"{name} must be a real (3,) or (N, 3) array, got {type(x).__name__}")
    if a.ndim == 1 and a.shape == (3,):
        a = a[None]
    if a.ndim != 2 or a.shape[1] != 3 or a.shape[0] == 0:
        raise ValueError(f"{name} must have shape (3,) or (N, 3), got {np.shape(x)}")
    a = np.ascontiguousarray(a, dtype=np.float64)
    if not np.isfinite(a).all():
        row = int(np.flatnonzero(~np.isfinite(a).all(axis=1))[0])
        raise ValueError(f"{name}[{row}] contains non-finite values (NaN or inf)")
    return a


def _horizons(x):
    """(m,) float64 horizons, finite and > 0."""
    refuse_masked(x, "horizon")
    a = None if isinstance(x, (str, bytes, bool, np.bool_)) else np.asarray(x)
    if a is None or a.dtype.kind not in "iuf":
        raise TypeError(f"horizon must be a real number or (N,) array, got {type(x).__name__} {x!r}")
    if a.ndim > 1 or a.size == 0:
        raise ValueError(f"horizon must be a scalar or of shape (N,), got shape {a.shape}")
    a = np.ascontiguousarray(a.reshape(-1), dtype=np.float64)
    bad = ~(np.isfinite(a) & (a > 0))
    if bad.any():
        raise ValueError(f"horizon must be finite and > 0, got {a[bad][0]!r}")
    return a


def _batch_size(n, nv, nw, nh):
    """The batch size of poses (n) and motions together; a batch of one broadcasts."""
    entries = (("poses", n), ("velocity", nv), ("angular_velocity", nw), ("horizon", nh))
    big = {s for _, s in entries if s != 1}
    if len(big) > 1:
        raise ValueError("batch sizes do not match: " + ", ".join(f"{nm} has {s}" for nm, s in entries))
    return big.pop() if big else 1
