"""One pose pair at the lowest latency: :meth:`Collider.collide_pair <prismbatch.Collider.collide_pair>`.

The pair's checks and test run in one compiled call (``prismbatch._kernels.one_pair.collide_pair``), closed to
every signature but its own, so that the dispatcher's type checks stay short; what it does not take is
converted here first. :class:`OnePairQueries` holds the methods :class:`~prismbatch.Collider` inherits;
:func:`kernel_array` is the one conversion of pose arrays for every kernel.
"""

from __future__ import annotations

import threading
from typing import NamedTuple

import numpy as np

from ._kernels import one_pair as _one_pair
from ._kernels.distance_pair import WITNESS_TYPE, distance_pair
from ._kernels.one_pair import CONTACT_TYPE, PAIR_SHAPE_PROBLEM, close_kernel, pair_signature
from ._kernels.projection import CASES
from .poses import as_pose, position_message, rotation_message, transforms_as_written

__all__ = ["PairResult", "OnePairQueries", "HIT_CASE", "as_written", "kernel_array", "pair_problem_message"]


class PairResult(NamedTuple):
    """Result of :meth:`Collider.collide_pair <prismbatch.Collider.collide_pair>`: hit, case and contact of one pair."""

    hit: bool
    case: int
    contact: np.ndarray


class OnePairQueries:
    """The one-pair methods of :class:`~prismbatch.Collider` (which sets the attributes they read: ``dtype``,
    ``rtol``, ``atol``, ``_eps``, ``_a``, ``_b``, ``_a_per``, ``_b_per``, ``_max_magnitude``, ``_ortho_tol``,
    ``_pair_kernel``, ``_distance_kernel``, ``_bundles``, ``_fast_bundle`` and ``_distance_fast``)."""

    def collide_pair(self, pos_a, rot_a=None, pos_b=None, rot_b=None, *, quat_order=None):
        """One pose pair at the lowest latency: one compiled call, checks included.

        For loops that query one pair at a time (a controller, a single-query
        timing study); both shapes must be single prisms. Each pose is a (3,)
        position with a rotation in any form :func:`collide` takes, or a 4x4
        transform (``collide_pair(T_a, T_b)``); the fastest form is a (3,)
        position and a (3, 3) matrix of the Collider's dtype (views such as
        ``T[:3, 3]`` and ``T[:3, :3]`` included); other forms are converted first.
        The contact point costs a few flops here and is always returned (NaN
        when no hit).

        Returns
        -------
        PairResult
            ``(hit, case, contact)``; ``contact`` is a float64 (3,) array
            whatever the Collider's dtype, as the kernel forms it (a float32
            Collider's batch calls store contacts in float32: this point,
            rounded).

        Raises
        ------
        ValueError
            As :meth:`collide` for non-finite, non-orthonormal or reflected poses.
        """
        res = self._fast_pair(pos_a, rot_a, pos_b, rot_b, quat_order)
        if res is None:
            return self._converted_pair(pos_a, rot_a, pos_b, rot_b, quat_order)
        return res

    def _fast_pair(self, pos_a, rot_a, pos_b, rot_b, quat_order):
        """The :class:`PairResult` of one pair whose poses the closed kernel takes as they are, else None.

        The common case, kept short (a one-pair query takes about a microsecond): the kernel, closed to
        other signatures, takes (3,) and (3, 3) arrays of the compute dtype only (views and read-only
        arrays too).
        """
        bundle = self._fast_bundle  # None until the first query (and always for PrismSets)
        if bundle is None or quat_order is not None or not plain_poses(self.dtype, pos_a, rot_a, pos_b, rot_b):
            return None
        contact = _empty(3)
        try:
            code = self._pair_kernel(bundle, pos_a, rot_a, pos_b, rot_b, contact)
        except TypeError:  # (a pose with another number of dimensions: the converted path names it)
            return None
        if code >= 0:
            return _new_tuple(PairResult, HIT_CASE[code] + (contact,))
        if code == -PAIR_SHAPE_PROBLEM:  # the converted path says which pose has which shape
            return None
        raise ValueError(pair_problem_message(-code, contact[0], self._ortho_tol, self._max_magnitude))

    def _pair_bundle(self, ortho_tol_a, ortho_tol_b):
        """The one-pair kernels' bundle (shapes and scalars) for these orthonormality tolerances (cached)."""
        key = (ortho_tol_a, ortho_tol_b)
        bundle = self._bundles.get(key)
        if bundle is None:
            bundle = _one_pair.pair_bundle(self._a, self._b, self.rtol, self.atol, self._eps, *key, self._max_magnitude)
            self._bundles[key] = bundle
        return bundle

    def _converted_pair(self, pos_a, rot_a, pos_b, rot_b, quat_order):
        """:meth:`collide_pair` with its arguments checked and converted (and the first call)."""
        if self._a_per or self._b_per:
            raise TypeError("collide_pair needs single Prism shapes, not PrismSets")
        pos_a, rot_a, pos_b, rot_b = as_written("collide_pair", pos_a, rot_a, pos_b, rot_b)
        if self._is_transform_pair(pos_a, rot_a, pos_b, rot_b, quat_order):
            # Two 4x4 transforms of the compute dtype: their blocks go to the kernel as views. A pose it
            # rejects is checked again below, for the message that names the transform.
            try:
                res = self._fast_pair(pos_a[:3, 3], pos_a[:3, :3], pos_b[:3, 3], pos_b[:3, :3], None)
            except ValueError:
                res = None
            if res is not None:
                return res
        Pa, Ra, ta = self._one_pose(pos_a, rot_a, quat_order, "a")
        Pb, Rb, tb = self._one_pose(pos_b, rot_b, quat_order, "b")
        contact = np.empty(3)
        closed(_one_pair.collide_pair[self.dtype], self.dtype, CONTACT_TYPE)
        code = self._pair_kernel(self._pair_bundle(ta, tb), Pa, Ra, Pb, Rb, contact)
        self._fast_bundle = self._pair_bundle(self._ortho_tol, self._ortho_tol)
        if code < 0:
            raise ValueError(pair_problem_message(-code, contact[0], ta if -code <= 4 else tb, self._max_magnitude))
        return _new_tuple(PairResult, HIT_CASE[code] + (contact,))

    def _fast_distance(self, pos_a, rot_a, pos_b, rot_b, witness, quat_order, parallel):
        """:meth:`distance` of one pair whose poses the closed one-pair kernel takes as they are (the rule of
        :meth:`collide_pair`'s), else None: one compiled call, checks included."""
        fast = self._distance_fast  # (bundle, result) once the first one-pair distance closed the kernel
        if witness.__class__ is _np_bool:  # (np.True_ from an array of flags: the same query)
            witness = bool(witness)
        if not (
            fast is not None
            and quat_order is None
            and (witness is True or witness is False)
            and (parallel is None or parallel is True or parallel is False)
            and plain_poses(self.dtype, pos_a, rot_a, pos_b, rot_b)
            and pos_a.ndim == pos_b.ndim == 1  # (a batch that the closed kernel refused would cost 0.1 ms)
            and rot_a.ndim == rot_b.ndim == 2
        ):
            return None
        bundle, result = fast
        try:
            out = self._distance_kernel(bundle, pos_a, rot_a, pos_b, rot_b, witness)
        except TypeError:  # (a guard: the signature takes whatever the checks above let through)
            return None
        if out[0] == PAIR_SHAPE_PROBLEM:  # the batch's parser says which pose has which shape
            return None
        return self._pair_distance_result(out, result, witness)

    def _pair_distance(self, pos_a, rot_a, pos_b, rot_b, witness):
        """:meth:`distance` of one pair of C-contiguous arrays of the compute dtype (and the first call, which
        closes the one-pair kernel)."""
        from .distance import pair_distance_result  # (distance imports the module of Collider)

        closed(distance_pair[self.dtype], self.dtype, WITNESS_TYPE)
        bundle = self._pair_bundle(self._ortho_tol, self._ortho_tol)
        out = self._distance_kernel(bundle, pos_a, rot_a, pos_b, rot_b, bool(witness))
        self._distance_fast = (bundle, pair_distance_result)
        return self._pair_distance_result(out, pair_distance_result, witness)

    def _pair_distance_result(self, out, result, witness):
        """``result(out, witness)``, or the ValueError of the first bad pose (arrays of the compute dtype)."""
        if out[0]:
            raise ValueError(pair_problem_message(out[0], out[1], self._ortho_tol, self._max_magnitude))
        return result(out, witness)

    def _one_pose(self, pos, rot, quat_order, name):
        """``(P, R, orthonormality tolerance)`` of one body's pose for the one-pair kernel."""
        dt = self.dtype
        if (
            quat_order is None
            and pos.__class__ is rot.__class__ is np.ndarray  # (subclasses, e.g. masked arrays, are parsed)
            and pos.dtype == dt
            and rot.dtype == dt
            and pos.shape == (3,)
            and rot.shape == (3, 3)
        ):
            # arrays of the compute dtype: checked by the kernel, with messages naming the argument. Others
            # are parsed as the batch parses them (a float64 rotation judged before its rounding to float32,
            # a float64 position out of float32's range named so, not as the inf it would round to), and so
            # are other shapes, whatever their dtype (one message for a (1, 3) position, "a batch of 1").
            return kernel_array(pos, (3,), dt), kernel_array(rot, (3, 3), dt), self._ortho_tol
        P, R = as_pose(pos, rot, quat_order=quat_order, name=name, dtype=self.dtype)  # checked here
        if P.shape != (3,) or R.shape != (3, 3):
            n = R.shape[0] if R.ndim == 3 else P.shape[0]
            which = f"rot_{name}" if R.ndim == 3 else f"pos_{name}"
            raise ValueError(f"collide_pair takes one pose per body; {which} is a batch of {n} (use collide)")
        # as_pose applied the orthonormality rule of the input's dtype; the kernel's check must not be stricter.
        return kernel_array(P, (3,), self.dtype), kernel_array(R, (3, 3), self.dtype), np.inf

    def _is_single_pair(self, pos_a, rot_a, pos_b, rot_b, quat_order):
        """One plain pair (:func:`plain_poses`) of (3,) positions and (3, 3) rotations, for single prisms."""
        if self._a_per or self._b_per or quat_order is not None:
            return False
        return (
            plain_poses(self.dtype, pos_a, rot_a, pos_b, rot_b)
            and pos_a.shape == pos_b.shape == (3,)
            and rot_a.shape == rot_b.shape == (3, 3)
        )

    def _is_transform_pair(self, pos_a, rot_a, pos_b, rot_b, quat_order):
        """Two (4, 4) ndarrays of the compute dtype, each with a last row of exactly [0, 0, 0, 1], for single
        prisms (as :func:`~prismbatch.poses.transforms_as_written` leaves them: rotations None)."""
        if self._a_per or self._b_per or quat_order is not None or rot_a is not None or rot_b is not None:
            return False
        return _plain_transform(pos_a, self.dtype) and _plain_transform(pos_b, self.dtype)


#: The one-pair kernels (of each kind and dtype) compiled for their one signature and closed to others.
_closed = set()
_closing = threading.Lock()


def closed(kernel, dtype, last):
    """Compile (or load from the cache) the one-pair ``kernel`` for its one signature
    (:func:`~prismbatch._kernels.one_pair.pair_signature` of ``dtype`` and ``last``) and close it to others,
    on its first use in the process; first calls from several threads: one compiles, the others wait."""
    if kernel not in _closed:  # (a set lookup: building the signature costs some 14 µs)
        with _closing:
            if kernel not in _closed:
                close_kernel(kernel, pair_signature(dtype, last))
                _closed.add(kernel)


def plain_poses(dtype, pos_a, rot_a, pos_b, rot_b):
    """Whether the four poses are ndarrays (by class) of ``dtype`` (the same object, or an equal one, which
    has the same byte order): the rule before a closed one-pair kernel. Numba's dispatcher keys arrays by a
    fingerprint that leaves out byte order and alignment, so once it has met an unaligned array it can take
    a big-endian one of the same kind for native and read its bytes wrongly; and a call it refuses costs
    some 0.1 ms in its TypeError (lists, another dtype, two 4x4 transforms)."""
    return (
        pos_a.__class__ is rot_a.__class__ is pos_b.__class__ is rot_b.__class__ is _ndarray
        and (pos_a.dtype is dtype or pos_a.dtype == dtype)  # (==: an equal dtype object, e.g. unpickled;
        and (rot_a.dtype is dtype or rot_a.dtype == dtype)  # it compares byte order too)
        and (pos_b.dtype is dtype or pos_b.dtype == dtype)
        and (rot_b.dtype is dtype or rot_b.dtype == dtype)
    )


def as_written(query, pos_a, rot_a, pos_b, rot_b):
    """The poses with two positional 4x4 transforms read as written
    (:func:`~prismbatch.poses.transforms_as_written`); TypeError naming ``query`` and the body without a pose."""
    pos_a, rot_a, pos_b, rot_b = transforms_as_written(pos_a, rot_a, pos_b, rot_b)
    for body, pos in (("a", pos_a), ("b", pos_b)):
        if pos is None:
            raise TypeError(
                f"{query} needs a pose for {body}: pos_{body} (and rot_{body}, or a 4x4 transform as pos_{body})"
            )
    return pos_a, rot_a, pos_b, rot_b


def _plain_transform(T, dtype):
    """A (4, 4) ndarray of ``dtype`` whose last row is exactly [0, 0, 0, 1] (the pose check accepts it
    within a tolerance: the rest take that path)."""
    return T.__class__ is np.ndarray and T.shape == (4, 4) and T.dtype == dtype and T[3].tolist() == [0, 0, 0, 1]


def kernel_array(x, shape, dtype):
    """``x`` as a C-contiguous, writeable, aligned array of ``dtype`` (copied only if needed).

    Read-only and unaligned inputs (``np.broadcast_to``, frozen arrays, fields of packed records) are
    copied: Numba types them apart, so passing them would compile every batch kernel again.
    """
    if type(x) is np.ndarray and x.dtype == dtype:  # the common case: ``x``, or a view of it
        flags = x.flags
        if flags.c_contiguous and flags.writeable and flags.aligned:
            return x if x.shape == shape else x.reshape(shape)
    a = np.ascontiguousarray(np.reshape(x, shape), dtype=dtype)
    return a if a.flags.writeable and a.flags.aligned else a.copy()


def pair_problem_message(code, val, ortho_tol, max_magnitude):
    """The message of a problem code of the one-pair kernel (the same words as :func:`as_pose`)."""
    body, kind = "ab"[(code - 1) // 4], (code - 1) % 4  # codes 1-4 for a, 5-8 for b
    if kind == 0:
        return position_message("pos_" + body, val, max_magnitude)
    return rotation_message("rot_" + body, kind, val, ortho_tol)  # kinds 1-3 of first_bad_rotation


#: PairResults are built with tuple.__new__: the class's own __new__ is one more Python call (some
#: 50 ns of a one-pair query).
_new_tuple = tuple.__new__
# (module globals: one attribute lookup less in a one-pair query)
_empty, _ndarray, _np_bool = np.empty, np.ndarray, np.bool_
#: ``(hit, case)`` of each return ``2 * case + hit`` of the one-pair kernel: the one place that decodes it
#: (a lookup costs what the arithmetic does, about 47 ns).
HIT_CASE = tuple((bool(code & 1), code >> 1) for code in range(2 * (max(CASES) + 1)))
