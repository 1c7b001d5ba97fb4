"""Public collision API: :func:`collide` and :class:`Collider`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._kernels import batch as _batch
from ._kernels import one_pair as _one_pair
from ._kernels.checks import poses_ok
from ._kernels.distance_pair import distance_pair
from ._kernels.projection import CASES
from .checks import check_flag, real_scalar
from .config import DEFAULT_RTOL, MAX_RTOL, SUPPORTED_RANGE
from .pair import OnePairQueries, PairResult, as_written, kernel_array
from .poses import (
    as_pose,
    broadcast_size,
    common_batch_size,
    ortho_tolerance,
)
from .results import BatchResult, new_result
from .shapes import as_prism_set

__all__ = [
    "collide",
    "Collider",
    "CollisionResult",
    "PairResult",
    "CASES",
    "collider_for",
]


@dataclass(frozen=True)
class CollisionResult(BatchResult):
    """Result of :func:`collide` for ``N`` pose pairs.

    Attributes
    ----------
    hit : numpy.ndarray of bool, shape (N,)
        True where the prisms intersect or touch within the pair's tolerance
        (with ``collide(..., margin=m)``: where they come within m of each other).
    case : numpy.ndarray of int8, shape (N,)
        Case number of the relative pose (1-9 as in the paper, 10-11 added;
        see :data:`prismbatch.CASES`); 0 (not classified) for a query with
        ``margin > 0``.
    """

    hit: np.ndarray
    case: np.ndarray
    _contact: np.ndarray | None = None

    @property
    def contact(self) -> np.ndarray:
        """(N, 3) contact points in world coordinates, NaN rows where no hit.

        Each point lies inside both prisms within twice the pair's tolerance.
        Only available when :func:`collide` was called with ``contact=True``.
        """
        if self._contact is None:
            raise AttributeError("contact points were not computed: call collide(..., contact=True)")
        return self._contact

    def __repr__(self):
        n = len(self)
        extra = ", with contacts" if self._contact is not None else ""
        hits = int(np.count_nonzero(self.hit))
        return (
            f"CollisionResult({n} pair{'s' * (n != 1)}, {hits} hit{'s' * (hits != 1)}{extra}; "
            f"cases {self.case_counts()})"
        )

    def columns(self) -> dict:
        """The result as named 1-D columns (``pandas.DataFrame(result.columns())`` takes them):
        ``hit``, ``case`` and, when computed, ``contact_x``, ``contact_y``, ``contact_z``."""
        out = {"hit": self.hit, "case": self.case}
        if self._contact is not None:
            out.update(contact_x=self._contact[:, 0], contact_y=self._contact[:, 1], contact_z=self._contact[:, 2])
        return out

    def case_counts(self) -> dict:
        """Number of pairs per case number (cases that occur only)."""
        vals, cnt = np.unique(self.case, return_counts=True)
        return {int(v): int(c) for v, c in zip(vals, cnt)}


class Collider(OnePairQueries):
    """Two shapes fixed once, queried for many poses (like coal's ComputeCollision).

    Parameters
    ----------
    shape_a, shape_b : Prism or PrismSet
        A :class:`~prismbatch.Prism` shared by every pair, or a
        :class:`~prismbatch.PrismSet` holding one prism per pair.
    rtol : float, optional
        Relative tolerance (default 1e-9 for float64, 1e-5 for float32).
    atol : float, optional
        Absolute tolerance added to the relative one (default 0).
    dtype : {numpy.float64, numpy.float32}, optional
        Precision of the stored shapes and poses.
    """

    def __init__(self, shape_a, shape_b, *, rtol=None, atol=0.0, dtype=np.float64):
        dt = np.dtype(dtype)
        if dt not in DEFAULT_RTOL:
            raise TypeError(f"dtype must be numpy.float64 or numpy.float32, got {dt}")
        self.dtype = dt
        self.rtol = real_scalar(DEFAULT_RTOL[dt] if rtol is None else rtol, "rtol", 0.0, MAX_RTOL)
        self.atol = real_scalar(atol, "atol", 0.0, SUPPORTED_RANGE[dt.name][1])
        set_a, self._a_per = as_prism_set(shape_a, "shape_a", dt)
        set_b, self._b_per = as_prism_set(shape_b, "shape_b", dt)
        self._max_magnitude = SUPPORTED_RANGE[dt.name][1]
        self.shape_a, self.shape_b = shape_a, shape_b
        self._a = set_a.kernel_arrays(dt)
        self._b = set_b.kernel_arrays(dt)
        self._eps = float(np.finfo(dt).eps)
        # Orthonormality tolerance of poses of the compute dtype, which the one-pair kernels check
        # (others are parsed by as_pose, with the rule of their own dtype).
        self._ortho_tol = ortho_tolerance(dt, dt)
        self._pair_kernel = _one_pair.collide_pair[dt]
        self._distance_kernel = distance_pair[dt]
        self._distance_fast = None  # (bundle, result builder), set by the first one-pair distance
        self._bundles = {}  # (ortho_tol_a, ortho_tol_b) -> pair bundle of the one-pair kernels (single prisms)
        # Set by the first one-pair query (which compiles or closes the kernel): the bundle of poses of the
        # compute dtype, which the fast path takes as they are.
        self._fast_bundle = None
        self._n_shapes = None
        for per, s, nm in ((self._a_per, set_a, "shape_a"), (self._b_per, set_b, "shape_b")):
            if per:
                if self._n_shapes is not None and self._n_shapes != len(s):
                    raise ValueError(
                        f"shape_a and shape_b are PrismSets of different sizes ({self._n_shapes} and {len(s)})"
                    )
                self._n_shapes = len(s)

    def collide(
        self, pos_a, rot_a=None, pos_b=None, rot_b=None, *, contact=False, margin=0.0, quat_order=None, parallel=None
    ):
        """Test the pose pairs; see :func:`collide` for the arguments."""
        if contact is not False and contact is not True:  # (the common values skip the check's call)
            check_flag(contact, "contact")
        if parallel is not None:
            check_flag(parallel, "parallel")
        if not (margin.__class__ is float and margin == 0.0):  # the plain query skips the check's cost
            margin = real_scalar(margin, "margin", 0.0, self._max_magnitude)
            if margin > 0.0:  # early-stopping GJK (no case, no contact): _kernels/margin.py
                from ._kernels.margin import run as run_margin

                if contact:
                    raise ValueError(
                        "contact=True needs margin=0: a margin hit need not touch (for the nearest points "
                        "use distance(..., witness=True))"
                    )
                pos_a, rot_a, pos_b, rot_b = as_written("collide", pos_a, rot_a, pos_b, rot_b)
                n, pa, ra, pb, rb = self._batch_poses(pos_a, rot_a, pos_b, rot_b, quat_order, parallel)
                hit = run_margin(self._a, self._b, pa, ra, pb, rb, n, margin, self.rtol, self.atol, parallel)
                return CollisionResult(hit, np.zeros(n, dtype=np.int8))
        # One plain pair: the compiled one-pair path (same kernel, far less Python). The poses' dimensions
        # first: a batch that the closed kernel refused would cost some 0.1 ms in Numba's TypeError.
        r = None
        if (
            pos_a.__class__ is pos_b.__class__ is rot_a.__class__ is _ndarray
            and pos_a.ndim == pos_b.ndim == 1
            and rot_a.ndim == 2
            and getattr(rot_b, "ndim", 2) == 2
        ):
            r = self._fast_pair(pos_a, rot_a, pos_b, rot_b, quat_order)
        if r is None:
            pos_a, rot_a, pos_b, rot_b = as_written("collide", pos_a, rot_a, pos_b, rot_b)
            if self._is_single_pair(pos_a, rot_a, pos_b, rot_b, quat_order) or self._is_transform_pair(
                pos_a, rot_a, pos_b, rot_b, quat_order
            ):  # (the first one-pair query; two 4x4 transforms)
                r = self.collide_pair(pos_a, rot_a, pos_b, rot_b)
        if r is not None:
            hit, case = _empty(1, dtype=bool), _empty(1, dtype=np.int8)  # (np.array([x]) costs twice)
            hit[0], case[0] = r.hit, r.case
            return _collision_result(hit, case, r.contact[None, :].astype(self.dtype) if contact else None)
        n, pa, ra, pb, rb = self._batch_poses(pos_a, rot_a, pos_b, rot_b, quat_order, parallel)
        hit, case, cont = _batch.run(
            self._a,
            self._b,
            pa,
            ra,
            pb,
            rb,
            n,
            self.rtol,
            self.atol,
            bool(contact),
            None if parallel is None else bool(parallel),
        )
        return CollisionResult(hit, case, cont if contact else None)

    def distance(self, pos_a, rot_a=None, pos_b=None, rot_b=None, *, witness=False, quat_order=None, parallel=None):
        """Signed distance of the pose pairs; see :func:`prismbatch.distance` for the arguments."""
        # One plain pair: checks and set-up in one compiled call (a controller's query).
        res = self._fast_distance(pos_a, rot_a, pos_b, rot_b, witness, quat_order, parallel)
        if res is not None:
            return res
        from .distance import signed_distance  # distance builds on this module

        pos_a, rot_a, pos_b, rot_b = as_written("distance", pos_a, rot_a, pos_b, rot_b)
        check_flag(witness, "witness")
        check_flag(parallel, "parallel", allow_none=True)
        if self._is_single_pair(pos_a, rot_a, pos_b, rot_b, quat_order):
            pair = (kernel_array(x, x.shape, self.dtype) for x in (pos_a, rot_a, pos_b, rot_b))
            return self._pair_distance(*pair, witness)
        poses = self._batch_poses(pos_a, rot_a, pos_b, rot_b, quat_order, parallel)
        return signed_distance(
            self._a,
            self._b,
            *poses,
            rtol=self.rtol,
            atol=self.atol,
            dtype=self.dtype,
            witness=witness,
            parallel=parallel,
        )

    def time_of_impact(
        self,
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
        max_iter=None,
        quat_order=None,
        parallel=None,
    ):
        """First contact of b moving against a; see :func:`prismbatch.motion.time_of_impact` for the arguments."""
        from .motion import impact_times  # motion builds on this module

        pos_a, rot_a, pos_b, rot_b = as_written("time_of_impact", pos_a, rot_a, pos_b, rot_b)
        check_flag(pose, "pose")
        check_flag(contact, "contact")
        check_flag(parallel, "parallel", allow_none=True)
        poses = self._batch_poses(pos_a, rot_a, pos_b, rot_b, quat_order, parallel)
        return impact_times(
            self._a,
            self._b,
            *poses,
            velocity,
            angular_velocity,
            horizon,
            rtol=self.rtol,
            atol=self.atol,
            dtype=self.dtype,
            max_iter=max_iter,
            pose=pose,
            contact=contact,
            parallel=parallel,
        )

    def collision_probability(self, pos_a, rot_a, pos_b, rot_b, cov_b, *, cov_a=None, rel_error=0.1,
                              confidence=0.95, max_samples=None, seed=None, method="auto", query_index=None,
                              quat_order=None, parallel=None):  # fmt: skip
        """Probability of collision under Gaussian pose noise; see
        :func:`prismbatch.probability.collision_probability` for the arguments."""
        from .probability import estimate  # probability builds on this module

        return estimate(self, pos_a, rot_a, pos_b, rot_b, cov_b, cov_a=cov_a, rel_error=rel_error,
                        confidence=confidence, max_samples=max_samples, seed=seed, method=method,
                        query_index=query_index, quat_order=quat_order, parallel=parallel)  # fmt: skip

    def _batch_poses(self, pos_a, rot_a, pos_b, rot_b, quat_order, parallel):
        """``(n, pos_a, rot_a, pos_b, rot_b)``: the poses checked, sized and converted once for the kernels."""
        if quat_order is None:
            plain = self._plain_batch(pos_a, rot_a, pos_b, rot_b, parallel)
            if plain is not None:
                return plain
        pa, ra = as_pose(pos_a, rot_a, quat_order=quat_order, name="a", dtype=self.dtype, parallel=parallel)
        pb, rb = as_pose(pos_b, rot_b, quat_order=quat_order, name="b", dtype=self.dtype, parallel=parallel)
        n = common_batch_size(pa, ra, pb, rb, n_shapes=self._n_shapes)
        dt = self.dtype
        pa, pb = kernel_array(pa, (-1, 3), dt), kernel_array(pb, (-1, 3), dt)
        ra, rb = kernel_array(ra, (-1, 3, 3), dt), kernel_array(rb, (-1, 3, 3), dt)
        return n, pa, ra, pb, rb

    def _plain_batch(self, pos_a, rot_a, pos_b, rot_b, parallel):
        """:meth:`_batch_poses` of a serial batch whose arrays the kernels take as they are (C-contiguous,
        writeable, aligned ndarrays of the compute dtype; positions (3,) or (N, 3), rotation matrices (3, 3)
        or (N, 3, 3); sizes that broadcast), judged valid by one compiled pass; else None: the pose parser
        then judges and names what is wrong. On a batch of one the parser took 53 µs a call, this path 9 µs
        (2026-11-27, a slow day for the machine). The layout is tested here, not by
        :func:`~prismbatch.pair.kernel_array`'s four calls: with them, collide on 1 to 100 pairs took 12-19 %
        longer (distance 2-6 %)."""
        dt, sizes = self.dtype, [self._n_shapes]
        for x, core in ((pos_a, 1), (rot_a, 2), (pos_b, 1), (rot_b, 2)):
            if x.__class__ is not _ndarray or x.dtype != dt:
                return None
            shape, flags = x.shape, x.flags
            if not (flags.c_contiguous and flags.writeable and flags.aligned) or shape[-core:] != (3, 3)[:core]:
                return None
            if x.ndim == core + 1:
                sizes.append(shape[0])
            elif x.ndim != core:
                return None
        n = broadcast_size(sizes)
        if n is None or _batch.use_parallel(parallel, n):  # sizes that do not broadcast; a batch checked on threads
            return None
        pa, ra, pb, rb = pos_a.reshape(-1, 3), rot_a.reshape(-1, 3, 3), pos_b.reshape(-1, 3), rot_b.reshape(-1, 3, 3)
        if not poses_ok(pa, ra, pb, rb, self._max_magnitude, self._ortho_tol):
            return None
        return n, pa, ra, pb, rb

    def explain(self, pos_a, rot_a=None, pos_b=None, rot_b=None, *, quat_order=None):
        """Step-by-step record of how one pose pair is decided (for ``prismbatch replay``).

        Runs the same compiled test as :meth:`collide_pair` with tracing on, on
        the same pose forms (a position with a rotation in any form, or two 4x4
        transforms: ``explain(T_a, T_b)``).

        Returns
        -------
        dict
            Every field of ``prismbatch._kernels.projection.TRACE_FIELDS`` (a's centred
            frame: b's position ``p`` and rotation ``R``, the pair's tolerance (the test decides at it
            plus the rounding allowance), Δ3,
            the reach, the coarse-test quantities, the early-accept depth, the
            GJK outcome, ...; NaN where the test never got there), plus
            ``exit_reason`` (text), ``hit``, ``case`` and ``contact`` (world).
        """
        from ._kernels.projection import EXITS, TRACE_FIELDS, TRACE_SIZE

        if self._a_per or self._b_per:
            raise TypeError("explain needs single Prism shapes, not PrismSets")
        pos_a, rot_a, pos_b, rot_b = as_written("explain", pos_a, rot_a, pos_b, rot_b)
        self.collide_pair(pos_a, rot_a, pos_b, rot_b, quat_order=quat_order)  # the same input checks
        Pa, Ra, _ = self._one_pose(pos_a, rot_a, quat_order, "a")
        Pb, Rb, _ = self._one_pose(pos_b, rot_b, quat_order, "b")
        trace = np.full(TRACE_SIZE, np.nan)
        a, b = self._a, self._b
        hit, case, cx, cy, cz = _batch.pair_world(
            *_batch.all_fields(a),
            0,
            *_batch.pair_fields(b),
            0,
            Pa,
            Ra,
            None,
            Pb,
            Rb,
            self.rtol,
            self.atol,
            self._eps,
            True,
            trace,
        )
        out = {name: float(v) for name, v in zip(TRACE_FIELDS, trace)}
        out["exit"] = int(trace[TRACE_FIELDS.index("exit")])
        out["exit_reason"] = EXITS[out["exit"]]
        out.update(hit=bool(hit), case=int(case), contact=[float(cx), float(cy), float(cz)])
        return out


def _collision_result(hit, case, contact):
    """``CollisionResult(hit, case, contact)``, built fast (:func:`~prismbatch.results.new_result`)."""
    return new_result(CollisionResult, {"hit": hit, "case": case, "_contact": contact})


_empty, _ndarray = np.empty, np.ndarray  # (module globals: one attribute lookup less in a one-pair query)


def collide(
    shape_a,
    shape_b,
    pos_a,
    rot_a=None,
    pos_b=None,
    rot_b=None,
    *,
    contact=False,
    margin=0.0,
    quat_order=None,
    rtol=None,
    atol=0.0,
    dtype=np.float64,
    parallel=None,
):
    """Collision status of two convex semi-infinite prisms for a batch of poses.

    Parameters
    ----------
    shape_a, shape_b : Prism or PrismSet
        One prism shared by all pairs, or a PrismSet with one prism per pair.
    pos_a, pos_b : array_like, shape (3,) or (N, 3); or (4, 4) / (N, 4, 4)
        Positions of the prisms' local origins in world coordinates, or
        homogeneous transforms (then leave ``rot_a``/``rot_b`` as None;
        ``collide(a, b, T_a, T_b)`` with two transforms also works).
    rot_a, rot_b : array_like or scipy.spatial.transform.Rotation
        Rotations whose columns are the local axes in world coordinates:
        (3, 3) / (N, 3, 3) matrices, a scipy ``Rotation``, or quaternions
        (4,) / (N, 4) together with ``quat_order``.
    contact : bool, optional
        Also compute contact points (a status-only call skips that work).
        Only with ``margin=0``.
    margin : float, optional
        Security margin (coal's ``security_margin``), a finite real >= 0.
        With ``margin > 0`` a pair is a hit iff the bodies come within
        ``margin`` of each other (signed distance <= margin; pairs within the
        pair's tolerance of that may go either way), decided by a GJK that
        stops as soon as its bounds settle the question (a few support
        searches a pair, far less than :func:`~prismbatch.distance.distance`).
        Such a query classifies no relative pose (``case`` is 0) and computes
        no contact (``contact=True`` raises ValueError: use
        ``distance(..., witness=True)`` for the nearest points). ``margin=0``
        (default) is the plain test.
    quat_order : {"wxyz", "xyzw"}, optional
        Component order of quaternion rotations (required for quaternions).
    rtol, atol : float, optional
        Tolerance of touching: a pair's tolerance is
        ``atol + rtol * (R_a + R_b + |c_b - c_a|) + 4 eps (|c_a| + |c_b|) + 8 eps (|k_a|_1 + |k_b|_1)``
        (R: end-face radii, c: end-face centres in world coordinates, k: the same in the
        prisms' local frames, eps: machine epsilon of ``dtype``). Bodies within it count as
        colliding; a reported hit means the bodies are within sqrt(2) (tol + rho) of each
        other (1.8 (tol + rho) for axes perpendicular within tol/4 over a's reach), where
        ``rho = 4 eps (R_a + R_b + |c_b - c_a|_1 + |k_a|_1 + |k_b|_1)`` is the rounding allowance
        the test is decided with (:data:`~prismbatch.config.ROUNDING_ALLOWANCE`).
    dtype : {numpy.float64, numpy.float32}, optional
        Precision of the stored shapes and poses (float32 halves memory
        traffic; its default rtol is 1e-5).
    parallel : bool or None, optional
        Spread pairs over Numba's threads (``numba.get_num_threads()``). None
        (default) does so for batches of 4096 pairs or more; thread start-up
        costs more than a small batch.

    Returns
    -------
    CollisionResult
        ``hit`` (N,) bool, ``case`` (N,) int8 (0 with ``margin > 0``) and,
        with ``contact=True``, ``contact`` (N, 3) world points (NaN rows where
        there is no hit).

    Raises
    ------
    TypeError, ValueError
        Bad shapes, poses, tolerances or batch sizes; the message says which
        argument and index.

    Examples
    --------
    >>> import numpy as np, prismbatch as pb
    >>> a, b = pb.Prism.regular(5, 2.0), pb.Prism.regular(6, 2.5)
    >>> down = np.diag([1.0, -1.0, -1.0])          # a's axis points down
    >>> r = pb.collide(a, b, [0, 0, 0], down, [[0, 0, 1.0], [0, 0, 0.0]], np.eye(3))
    >>> r.hit.tolist(), r.case.tolist()
    ([False, True], [1, 4])
    >>> pb.collide(a, b, [0, 0, 0], down, [[0, 0, 1.0], [0, 0, 0.5]], np.eye(3), margin=0.75).hit.tolist()
    [False, True]
    """
    col = collider_for(shape_a, shape_b, rtol, atol, dtype)
    return col.collide(
        pos_a, rot_a, pos_b, rot_b, contact=contact, margin=margin, quat_order=quat_order, parallel=parallel
    )


_recent = {}  # key -> (a, b, Collider); the shapes are kept alive so their ids stay theirs
_DTYPES = {np.float64: np.dtype(np.float64), np.float32: np.dtype(np.float32)}


def collider_for(shape_a, shape_b, rtol, atol, dtype):
    """The Collider behind the module-level queries (:func:`collide`, ``distance``,
    ``time_of_impact``, ``collision_probability``): the last few are kept, as a loop
    calling them on the same shapes would otherwise rebuild and recheck them every call."""
    try:
        dt = _DTYPES.get(dtype) or np.dtype(dtype)  # (np.dtype() alone costs a one-pair query 0.1 µs)
        key = (id(shape_a), id(shape_b), type(rtol), rtol, type(atol), atol, dt)
        hit = _recent.get(key)
    except TypeError:  # an unhashable tolerance or dtype, or no dtype: Collider says what is wrong with it
        return Collider(shape_a, shape_b, rtol=rtol, atol=atol, dtype=dtype)
    if hit is not None and hit[0] is shape_a and hit[1] is shape_b:
        return hit[2]
    col = Collider(shape_a, shape_b, rtol=rtol, atol=atol, dtype=dtype)
    try:
        while len(_recent) >= 8:
            _recent.pop(next(iter(_recent)), None)
    except (RuntimeError, StopIteration):  # another thread changed it meanwhile; it is only a cache
        pass
    _recent[key] = (shape_a, shape_b, col)
    return col
