"""Signed distance between two convex semi-infinite prisms: :func:`distance`.

The gap when the bodies are apart, minus the penetration depth (the shortest
translation of b that leaves the bodies touching) when they overlap, with the
touching tolerance of :func:`~prismbatch.collide` and, on request, the
direction and the two points that realise it. The method (3-D GJK and EPA on
the Minkowski difference, whose unbounded part is cut where it cannot matter)
is in :mod:`prismbatch._kernels.distance` and ``docs/methods/distance.md``.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

from ._kernels.batch import use_parallel, work_blocks
from ._kernels.distance import (
    AXES_DEPTH,
    EPA_DEPTH,
    EPA_ROOM,
    EPA_STOPPED,
    FLAT,
    GJK_GAP,
    GJK_STALLED,
    PENETRATING,
    PLANAR_DEPTH,
    PLANAR_GAP,
    SEPARATED,
    TOUCHING,
    distance_parallel,
    distance_serial,
    rerun_parallel,
    rerun_serial,
    workspace,
)
from ._kernels.jit import first_call
from .collide import collider_for
from .results import BatchResult, new_result

__all__ = ["distance", "signed_distance", "DistanceResult", "STATUS", "SOLVERS", "SEPARATED", "TOUCHING", "PENETRATING"]

#: Meaning of :attr:`DistanceResult.status`.
STATUS = {
    SEPARATED: "separated: distance > tol",
    TOUCHING: "touching: |distance| <= tol",
    PENETRATING: "penetrating: distance < -tol",
}

#: Meaning of :attr:`DistanceResult.solver`.
SOLVERS = {
    GJK_GAP: "GJK: the gap, to 1e-3 tol (0.1 tol where rounding on very fine polygons stops GJK short)",
    EPA_DEPTH: "EPA: the depth, to 1e-3 tol",
    EPA_STOPPED: "EPA stopped early (out of room, or rounding): the depth reported is an upper bound",
    FLAT: "the Minkowski difference is flat around the origin: touching, to 1e-3 tol",
    GJK_STALLED: "GJK stalled on rounding (nearly coplanar faces: nearly parallel axes) after proving a gap: "
    "the gap reported is an upper bound, attained by the witness points",
    PLANAR_DEPTH: "exactly parallel axes pointing the same way, where EPA stopped early: the depth of the end faces' "
    "overlap in the plane (exact)",
    AXES_DEPTH: "other axes pointing the same way, where EPA stopped early (seen on nearly parallel ones): the depth "
    "by the separating-axis theorem over the Minkowski difference's candidate facet normals (exact to rounding)",
    PLANAR_GAP: "exactly parallel axes (either way round), end faces apart in the plane: the gap is their planar "
    "distance by 2-D GJK to 1e-3 tol, with the axial distance of facing end faces in quadrature",
}


@dataclass(frozen=True)
class DistanceResult(BatchResult):
    """Result of :func:`distance` for ``N`` pose pairs.

    Attributes
    ----------
    distance : numpy.ndarray, shape (N,)
        Signed distance: the Euclidean gap when positive, minus the
        penetration depth (the length of the shortest translation of b that
        leaves the bodies touching) when negative.
    status : numpy.ndarray of int8, shape (N,)
        :data:`SEPARATED` (1), :data:`TOUCHING` (0, ``|distance| <= tol``) or
        :data:`PENETRATING` (-1); see :data:`STATUS`.
    tol : numpy.ndarray, shape (N,)
        Each pair's touching tolerance, the one :func:`~prismbatch.collide` uses.
    solver : numpy.ndarray of int8, shape (N,)
        Which computation gave the value (see :data:`SOLVERS`).
    """

    distance: np.ndarray
    status: np.ndarray
    tol: np.ndarray
    solver: np.ndarray
    _normal: np.ndarray | None = None
    _point_a: np.ndarray | None = None
    _point_b: np.ndarray | None = None

    def _witness(self, name):
        value = getattr(self, "_" + name)
        if value is None:
            raise AttributeError(f"{name} was not computed: call distance(..., witness=True)")
        return value

    @property
    def normal(self) -> np.ndarray:
        """(N, 3) unit direction from a towards b: moving b by ``-distance * normal`` leaves
        the bodies touching (with ``witness=True`` only)."""
        return self._witness("normal")

    @property
    def point_a(self) -> np.ndarray:
        """(N, 3) a point on a's boundary where the distance is realised (``witness=True``)."""
        return self._witness("point_a")

    @property
    def point_b(self) -> np.ndarray:
        """(N, 3) the matching point on b's boundary, ``point_a + distance * normal`` (``witness=True``)."""
        return self._witness("point_b")

    def __repr__(self):
        n = len(self)
        counts = {STATUS[s].split(":")[0]: int(np.count_nonzero(self.status == s)) for s in STATUS}
        extra = ", with witnesses" if self._normal is not None else ""
        return f"DistanceResult({n} pair{'s' * (n != 1)}{extra}; {counts})"

    def columns(self) -> dict:
        """The result as named 1-D columns (``pandas.DataFrame(result.columns())`` takes them)."""
        out = {"distance": self.distance, "status": self.status, "tol": self.tol, "solver": self.solver}
        if self._normal is not None:
            for name, arr in (("normal", self._normal), ("point_a", self._point_a), ("point_b", self._point_b)):
                out.update({f"{name}_{c}": arr[:, j] for j, c in enumerate("xyz")})
        return out


def distance(
    shape_a,
    shape_b,
    pos_a,
    rot_a=None,
    pos_b=None,
    rot_b=None,
    *,
    witness=False,
    quat_order=None,
    rtol=None,
    atol=0.0,
    dtype=np.float64,
    parallel=None,
):
    """Signed distance between two convex semi-infinite prisms for a batch of poses.

    Parameters
    ----------
    shape_a, shape_b, pos_a, rot_a, pos_b, rot_b, quat_order, rtol, atol, dtype, parallel
        As for :func:`~prismbatch.collide`: the same shapes, pose forms,
        broadcasting, tolerance and threading.
    witness : bool, optional
        Also compute ``normal``, ``point_a`` and ``point_b``.

    Returns
    -------
    DistanceResult
        ``distance`` (N,), ``status`` (N,) int8, ``tol`` (N,), ``solver``
        (N,) int8 and, with ``witness=True``, ``normal``, ``point_a`` and
        ``point_b`` (N, 3) in world coordinates, with
        ``point_b - point_a = distance * normal``.

    Notes
    -----
    The value is accurate to about 1e-3 of the pair's tolerance (0.1 of it
    where rounding stops GJK short on very fine polygons, about 1e5 vertices;
    up to 0.61 of it seen where GJK stalls on nearly parallel axes after
    proving a gap, ``solver`` 4), and to float64 rounding of the scene's size. Where the bodies are nearly
    parallel, point the same way and meet (or pass) far from both end faces,
    the witness points lie there, at about gap / tilt, and are accurate only to
    the rounding of their own coordinates; the distance and normal are not
    affected.

    Raises
    ------
    TypeError, ValueError
        Bad shapes, poses, tolerances or batch sizes, as :func:`~prismbatch.collide`.

    Examples
    --------
    >>> import numpy as np, prismbatch as pb
    >>> from prismbatch.distance import distance
    >>> a, b = pb.Prism.regular(4, 1.0), pb.Prism.regular(4, 1.0)
    >>> down = np.diag([1.0, -1.0, -1.0])          # a's axis points down, b's up
    >>> r = distance(a, b, [0, 0, 0], down, [[0, 0, 0.5], [0, 0, -0.25]], np.eye(3))
    >>> r.distance.round(12).tolist(), r.status.tolist()
    ([0.5, -0.25], [1, -1])
    """
    col = collider_for(shape_a, shape_b, rtol, atol, dtype)  # checks and packs the shapes (kept for repeat calls)
    return col.distance(pos_a, rot_a, pos_b, rot_b, witness=witness, quat_order=quat_order, parallel=parallel)


def pair_distance_result(out, witness):
    """The :class:`DistanceResult` of one pair from the one-pair kernel's output
    (``prismbatch._kernels.distance_pair``; problem 0): each field an array of one pair."""
    _, _, d, t, status, code, n, p, q = out
    dist, tol, st, solver = _empty(1), _empty(1), _empty(1, _int8), _empty(1, _int8)
    dist[0], tol[0], st[0], solver[0] = d, t, status, code
    fields = {"distance": dist, "status": st, "tol": tol, "solver": solver}
    if witness:
        fields.update(_normal=_array((n,)), _point_a=_array((p,)), _point_b=_array((q,)))
    else:
        fields.update(_normal=None, _point_a=None, _point_b=None)  # (as the batch's result holds them)
    return new_result(DistanceResult, fields)


_empty, _array, _int8 = np.empty, np.array, np.int8
#: Each Python thread's workspace for serial calls, built on its first: building one (thirteen arrays
#: returned from a compiled call) cost a small batch more than its distances.
_serial_work = threading.local()


def _workspace(blocks):
    """A workspace of GJK and EPA with ``blocks`` blocks (some 150 kB each); one block is the calling
    thread's own, kept (the kernels need no particular contents on entry)."""
    room = EPA_ROOM[0]
    if blocks != 1:
        return workspace(blocks, room)
    kept = getattr(_serial_work, "kept", None)
    if kept is None or kept[0] != room:
        kept = _serial_work.kept = (room, workspace(1, room))
    return kept[1]


def signed_distance(a_arrays, b_arrays, n, pos_a, rot_a, pos_b, rot_b, *, rtol, atol, dtype, witness, parallel):
    """:func:`distance` for shapes and poses already checked and packed (by a :class:`~prismbatch.Collider`).

    Parameters
    ----------
    a_arrays, b_arrays : PrismArrays
        ``PrismSet.kernel_arrays(dtype)`` of each shape.
    n : int
        Number of pairs.
    pos_a, rot_a, pos_b, rot_b : numpy.ndarray
        C-contiguous, writeable (1 or n, 3) positions and (1 or n, 3, 3) rotations of ``dtype``.
    rtol, atol : float
        Checked tolerances.
    dtype : numpy.dtype
        float64 or float32.
    witness, parallel
        As :func:`distance` (checked).

    Returns
    -------
    DistanceResult
    """
    dist = np.empty(n)
    status = np.empty(n, dtype=np.int8)
    tol = np.empty(n)
    solver = np.empty(n, dtype=np.int8)
    k = n if witness else 0  # status-only calls write no witnesses
    normal, point_a, point_b = np.empty((k, 3)), np.empty((k, 3)), np.empty((k, 3))
    parallel = use_parallel(parallel, n)
    kern = distance_parallel if parallel else distance_serial
    work = _workspace(work_blocks(n, parallel))
    args = (a_arrays.floats, a_arrays.ints, b_arrays.floats, b_arrays.ints, (pos_a, rot_a, pos_b, rot_b), float(rtol))
    args += (float(atol), float(np.finfo(dtype).eps), bool(witness))
    outs = ((dist, status, tol, solver), (normal, point_a, point_b))
    first_call((kern, np.dtype(dtype)), kern, *args, work, *outs)
    again = np.flatnonzero(solver == EPA_STOPPED)  # EPA out of the batch's room: more room, rarely needed
    if again.size:
        again_parallel = use_parallel(parallel, again.size)
        kern = rerun_parallel if again_parallel else rerun_serial
        first_call((kern, np.dtype(dtype)), kern, *args, again, work_blocks(again.size, again_parallel), *outs)
    if not witness:
        return DistanceResult(dist, status, tol, solver)
    return DistanceResult(dist, status, tol, solver, normal, point_a, point_b)
