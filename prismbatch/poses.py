"""Parsing, validation and broadcasting of rigid-body poses.

Conventions
-----------
A pose is a position ``p`` of shape ``(3,)`` and a rotation ``R`` of shape
``(3, 3)`` whose *columns* are the body's local axes expressed in world
coordinates, so that ``world = p + R @ local``.  Batches of poses are
``(N, 3)`` positions and ``(N, 3, 3)`` rotations.

Everything here is plain NumPy: these functions run once per call on the
Python side, before the Numba kernels, and their job is to turn whatever the
user passed into clean C-contiguous arrays or to fail loudly, naming the
argument and the index of the first offending pose.  Nothing is repaired
silently (no re-normalisation, no re-orthogonalisation).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ._kernels.batch import use_parallel
from ._kernels.checks import first_bad_rotation, first_bad_rotation_parallel
from .checks import as_real_array, indexed_name
from .config import SUPPORTED_RANGE

__all__ = [
    "ortho_tolerance",
    "as_rotations",
    "as_positions",
    "as_pose",
    "broadcast_poses",
    "relative_poses",
]

# Floor of the tolerance on max |R^T R - I| per *compute* dtype; see
# ortho_tolerance for the one rule that also accounts for the input's precision.
# The kernels use the exact inverse of rot_a, so a slightly non-orthonormal
# matrix is still an exact affine map: the check only guards against matrices
# that are not rotations at all.
ORTHO_TOL_F64 = 1e-9
ORTHO_TOL_F32 = 1e-5
ORTHO_TOL = {np.dtype(np.float64): ORTHO_TOL_F64, np.dtype(np.float32): ORTHO_TOL_F32}
# Rounding of the input earns this many of its epsilons on top of the floor.
ORTHO_EPS_FACTOR = 64
#: How to fix a rotation that fails the check (appended to every such error).
ORTHO_HINT = (
    "re-orthonormalise it, e.g. with "
    "scipy.spatial.transform.Rotation.from_matrix(R).as_matrix(), or pass "
    "dtype=np.float32 if the data only has ~6 significant digits"
)
# Quaternions must already be unit length; we do not normalise behind the
# user's back because an off-norm quaternion usually signals a bug upstream.
QUAT_NORM_TOL = 1e-6
# The last row of a homogeneous transform must be [0, 0, 0, 1].
TRANSFORM_ROW_TOL = 1e-12

_QUAT_ORDERS = ("wxyz", "xyzw")
_OUT_DTYPES = (np.dtype(np.float64), np.dtype(np.float32))


# ---------------------------------------------------------------------------
# small helpers
# ---------------------------------------------------------------------------
def _out_dtype(dtype) -> np.dtype:
    try:
        dt = np.dtype(dtype)
    except TypeError as exc:
        raise TypeError(f"dtype must be np.float64 or np.float32, got {dtype!r}") from exc
    if dt not in _OUT_DTYPES:
        raise TypeError(f"dtype must be np.float64 or np.float32, got {dt}")
    return dt


def _as_float(arr: np.ndarray) -> np.ndarray:
    """``arr`` itself if it is float32 or float64 (the checks judge both in float64 without a copy:
    a float64 copy of 10^7 float32 poses cost 1 GB and a third of a float32 call), else a float64 copy."""
    return arr if arr.dtype in _OUT_DTYPES else np.asarray(arr, dtype=np.float64)


def ortho_tolerance(input_dtype, compute_dtype) -> float:
    """Tolerance on max ``|R^T R - I|`` for rotation matrices: the one rule.

    Parameters
    ----------
    input_dtype : numpy dtype
        dtype of the matrices as the user passed them.  Integer (and bool)
        input counts as float64: it is exact.
    compute_dtype : {np.float64, np.float32}
        Precision the collision test runs in.

    Returns
    -------
    float
        ``max(ORTHO_TOL[compute_dtype], 64 * finfo(input_dtype).eps)``:
        1e-9 for float64 data under float64 compute, about 7.6e-6 for
        float32 data under float64 compute, at least 1e-5 under float32
        compute.

    Raises
    ------
    TypeError
        If ``compute_dtype`` is not float64/float32 or ``input_dtype`` is
        not a real numeric dtype.
    """
    floor = ORTHO_TOL[_out_dtype(compute_dtype)]
    dt = np.dtype(input_dtype)
    if dt.kind in "biu":
        dt = np.dtype(np.float64)
    elif dt.kind != "f":
        raise TypeError(f"input_dtype must be a real numeric dtype, got {dt}")
    return max(floor, ORTHO_EPS_FACTOR * float(np.finfo(dt).eps))


def _check_finite(a: np.ndarray, name: str, batched: bool, what: str = "") -> None:
    """Raise naming the first pose whose entries are not all finite."""
    if batched:
        bad = ~np.isfinite(a.reshape(a.shape[0], -1) if a.size else a.reshape(0, 1)).all(axis=1)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise ValueError(f"{indexed_name(name, i)}{what} contains non-finite values (NaN or inf)")
    elif not np.isfinite(a).all():
        raise ValueError(f"{name}{what} contains non-finite values (NaN or inf)")


def _check_positions(p: np.ndarray, name: str, batched: bool, what: str = "", dtype=np.float64) -> None:
    """Raise naming the first position with a coordinate NaN, inf or beyond the supported range.

    The range is :data:`~prismbatch.config.SUPPORTED_RANGE` of the compute
    ``dtype``. One pass: ``|x| <= limit`` is False for NaN too.
    """
    # A NumPy float64 limit: float32 coordinates are compared in float64, as their float64 copies were.
    limit = np.float64(SUPPORTED_RANGE[np.dtype(dtype).name][1])
    ok = np.abs(p) <= limit
    if ok.all():
        return
    rows = ok.reshape(p.shape[0], -1).all(axis=1) if batched else ok.reshape(1, -1).all(axis=1)
    i = int(np.flatnonzero(~rows)[0])
    v = float(np.ravel(p[i] if batched else p)[np.flatnonzero(~np.ravel(ok[i] if batched else ok))[0]])
    raise ValueError(position_message(indexed_name(name, i if batched else None) + what, v, limit))


def position_message(where: str, value: float, limit: float) -> str:
    """The message for a position coordinate ``value`` that is NaN, inf or beyond ``limit`` (every path)."""
    if not math.isfinite(value):
        return f"{where} contains non-finite values (NaN or inf)"
    dtype_note = " for float32" if limit != SUPPORTED_RANGE["float64"][1] else ""
    shown = f"{value:g}"
    if shown.lstrip("-") == f"{limit:g}":  # just past the limit: all the digits, or it reads as the limit
        shown = repr(float(value))
    return (
        f"{where} has a coordinate {shown} outside the supported range |x| <= {limit:g}{dtype_note}; rescale the units"
    )


def rotation_message(where: str, kind: int, value: float, tol: float) -> str:
    """The message for a rotation that :func:`first_bad_rotation` flagged with ``kind`` 1, 2 or 3 (every path)."""
    if kind == 1:
        return f"{where} contains non-finite values (NaN or inf)"
    if kind == 2:
        return f"{where} is not orthonormal: max |R^T R - I| = {value:.3e} > {tol:.3g}; {ORTHO_HINT}"
    return f"{where} is a reflection (det = {value:.6g}); a rotation must have det = +1"


def _check_rotation_matrices(R, name: str, tol: float, batched: bool, what: str = "", parallel=None) -> None:
    """Finite, orthonormal within ``tol``, and proper (det > 0).

    ``R`` is float64 or float32 (judged in float64 arithmetic) of shape (N, 3, 3) if ``batched``
    else (3, 3). ``parallel`` as for
    :func:`~prismbatch.collide`: a large batch is checked in chunks on Numba's threads (a
    serial check held two threads to 1.65x one thread on 10^6 pairs).
    """
    Rb = np.ascontiguousarray(R if batched else R[None])
    if Rb.shape[0] == 0:
        return
    if use_parallel(parallel, Rb.shape[0]):
        first = np.zeros((4 * numba.get_num_threads(), 3))
        first_bad_rotation_parallel(Rb, tol, first)
        bad = np.flatnonzero(first[:, 1])
        i, kind, val = (
            (int(first[bad[0], 0]), int(first[bad[0], 1]), float(first[bad[0], 2])) if len(bad) else (-1, 0, 0.0)
        )
    else:
        i, kind, val = first_bad_rotation(Rb, tol)
    if kind != 0:
        raise ValueError(rotation_message(indexed_name(name, int(i) if batched else None) + what, kind, val, tol))


def _quat_to_matrix(q64: np.ndarray, order: str) -> np.ndarray:
    """(N, 4) float64 quaternions -> (N, 3, 3) rotation matrices."""
    if order == "wxyz":
        w, x, y, z = q64[:, 0], q64[:, 1], q64[:, 2], q64[:, 3]
    else:  # "xyzw"
        x, y, z, w = q64[:, 0], q64[:, 1], q64[:, 2], q64[:, 3]
    # s = 2/|q|^2 instead of 2: the norm was already checked to be within
    # 1e-6 of 1, and this scaling makes the output exactly orthonormal (to
    # rounding) instead of off by ~2e-6, which would fail the 1e-9 check.
    # q and -q give the same matrix since every term is quadratic in q.
    s = 2.0 / (w * w + x * x + y * y + z * z)
    R = np.empty((q64.shape[0], 3, 3))
    R[:, 0, 0] = 1.0 - s * (y * y + z * z)
    R[:, 0, 1] = s * (x * y - z * w)
    R[:, 0, 2] = s * (x * z + y * w)
    R[:, 1, 0] = s * (x * y + z * w)
    R[:, 1, 1] = 1.0 - s * (x * x + z * z)
    R[:, 1, 2] = s * (y * z - x * w)
    R[:, 2, 0] = s * (x * z - y * w)
    R[:, 2, 1] = s * (y * z + x * w)
    R[:, 2, 2] = 1.0 - s * (x * x + y * y)
    return R


def _is_scipy_rotation(obj) -> bool:
    # Duck typing so that scipy stays an optional, lazily used dependency.
    return hasattr(obj, "as_matrix") and hasattr(obj, "as_quat") and not isinstance(obj, np.ndarray)


_ROT_SHAPES = (
    "(3, 3) or (N, 3, 3) rotation matrices, a scipy Rotation, or (4,) / (N, 4) quaternions together with quat_order"
)


# ---------------------------------------------------------------------------
# public API
# ---------------------------------------------------------------------------
def as_rotations(rot, *, quat_order=None, name="rot", dtype=np.float64, parallel=None) -> np.ndarray:
    """Parse and validate one rotation or a batch of rotations.

    Parameters
    ----------
    rot : array_like or scipy.spatial.transform.Rotation
        One of

        * rotation matrices of shape ``(3, 3)`` or ``(N, 3, 3)`` with a real
          numeric dtype; columns are the body axes in world coordinates;
        * a ``scipy.spatial.transform.Rotation`` (single or batched);
        * unit quaternions of shape ``(4,)`` or ``(N, 4)``, only if
          ``quat_order`` is given.
    quat_order : {None, "wxyz", "xyzw"}, optional
        Component order of quaternion input: ``"wxyz"`` is scalar-first
        (fcl, coal, MuJoCo), ``"xyzw"`` is scalar-last (scipy).  There is
        no default because guessing wrong gives a valid but wrong rotation.
    name : str, optional
        Argument name used in error messages.
    dtype : {np.float64, np.float32}, optional
        Output (compute) dtype.  Validation is done in float64; the
        orthonormality tolerance is :func:`ortho_tolerance` of the input
        dtype and this dtype.
    parallel : bool or None, optional
        Check a large batch on Numba's threads; None (default) does so for
        large batches only, as :func:`~prismbatch.collide`.

    Returns
    -------
    numpy.ndarray
        C-contiguous array of shape ``(3, 3)`` for a single rotation or
        ``(N, 3, 3)`` for a batch (the batch-ness of the input is kept).

    Raises
    ------
    TypeError
        If the input dtype is not integer or float (bool, complex, object,
        string), or ``dtype`` is not float64/float32.
    ValueError
        On a wrong shape, a last dimension of 4 without ``quat_order``, an
        unknown ``quat_order``, a quaternion whose norm is not within 1e-6
        of 1, non-finite entries, a matrix that is not orthonormal (max
        ``|R^T R - I|`` above :func:`ortho_tolerance`; the message says how
        to fix it), or a reflection (det < 0).  Messages name ``name`` and
        the index of the first offending rotation.
    """
    out_dt = _out_dtype(dtype)
    if quat_order is not None and quat_order not in _QUAT_ORDERS:
        raise ValueError(f"quat_order must be 'wxyz' (scalar-first) or 'xyzw' (scalar-last), got {quat_order!r}")

    if _is_scipy_rotation(rot):
        R64 = np.asarray(rot.as_matrix(), dtype=np.float64)
        single = getattr(rot, "single", R64.ndim == 2)
        if single and R64.ndim == 3 and R64.shape[0] == 1:  # defensive
            R64 = R64[0]
        batched = R64.ndim == 3
        _check_rotation_matrices(R64, name, ortho_tolerance(np.float64, out_dt), batched, parallel=parallel)
        return np.ascontiguousarray(R64, dtype=out_dt)

    arr = as_real_array(rot, name)
    shape = arr.shape

    if arr.ndim in (1, 2) and shape[-1] == 4:
        if quat_order is None:
            hint = (
                " (a (4, 4) homogeneous transform must be passed as the pose itself with rot=None, not as a rotation)"
                if shape == (4, 4)
                else ""
            )
            raise ValueError(
                f"{name} has shape {shape}, which looks like quaternions; "
                f"quaternions need an explicit quat_order ('wxyz' or 'xyzw'){hint}"
            )
        batched = arr.ndim == 2
        q64 = np.asarray(arr, dtype=np.float64).reshape(-1, 4)
        _check_finite(q64 if batched else q64[0], name, batched)
        norm = np.sqrt(np.einsum("ij,ij->i", q64, q64))
        bad = np.abs(norm - 1.0) > QUAT_NORM_TOL
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise ValueError(
                f"{indexed_name(name, i if batched else None)} is a quaternion of norm "
                f"{norm[i]:.9g}; expected 1 within {QUAT_NORM_TOL:.0e} "
                f"(quaternions are not normalised automatically)"
            )
        R64 = _quat_to_matrix(q64, quat_order)
        if not batched:
            R64 = R64[0]
        # Cheap, and guards the conversion itself (done in float64).
        _check_rotation_matrices(R64, name, ortho_tolerance(np.float64, out_dt), batched, parallel=parallel)
        return np.ascontiguousarray(R64, dtype=out_dt)

    if arr.ndim not in (2, 3) or shape[-2:] != (3, 3):
        hint = ""
        if arr.ndim == 3 and shape[-2:] == (4, 4):
            hint = " ((N, 4, 4) homogeneous transforms must be passed as the pose with rot=None)"
        raise ValueError(f"{name} has shape {shape}; expected {_ROT_SHAPES}{hint}")

    batched = arr.ndim == 3
    R = _as_float(arr)
    _check_rotation_matrices(R, name, ortho_tolerance(arr.dtype, out_dt), batched, parallel=parallel)
    return np.ascontiguousarray(R, dtype=out_dt)


def as_positions(pos, *, name="pos", dtype=np.float64) -> np.ndarray:
    """Parse and validate one position or a batch of positions.

    Parameters
    ----------
    pos : array_like
        Shape ``(3,)`` or ``(N, 3)``, real numeric dtype.
    name : str, optional
        Argument name used in error messages.
    dtype : {np.float64, np.float32}, optional
        Output dtype.  Validation is always done in float64.

    Returns
    -------
    numpy.ndarray
        C-contiguous array of shape ``(3,)`` or ``(N, 3)``.

    Raises
    ------
    TypeError
        If the dtype is not integer or float, or ``dtype`` is not
        float64/float32.
    ValueError
        On a wrong shape, non-finite entries or a coordinate beyond
        :data:`~prismbatch.config.SUPPORTED_RANGE` of ``dtype`` (the message names
        ``name`` and the index of the first bad position).
    """
    out_dt = _out_dtype(dtype)
    arr = as_real_array(pos, name)
    if arr.ndim not in (1, 2) or arr.shape[-1] != 3:
        raise ValueError(f"{name} has shape {arr.shape}; expected (3,) or (N, 3)")
    p = _as_float(arr)
    _check_positions(p, name, arr.ndim == 2, dtype=out_dt)
    return np.ascontiguousarray(p, dtype=out_dt)


def as_pose(pos, rot=None, *, quat_order=None, name="a", dtype=np.float64, parallel=None):
    """Parse one pose or a batch of poses.

    Parameters
    ----------
    pos : array_like
        If ``rot`` is given: positions, ``(3,)`` or ``(N, 3)``.  If ``rot``
        is None: homogeneous transforms ``(4, 4)`` or ``(N, 4, 4)`` whose
        last row is ``[0, 0, 0, 1]`` (within 1e-12).
    rot : array_like or scipy.spatial.transform.Rotation, optional
        Rotations in any form accepted by :func:`as_rotations`.
    quat_order : {None, "wxyz", "xyzw"}, optional
        Required if ``rot`` holds quaternions.
    name : str, optional
        Suffix used in error messages: positions are reported as
        ``"pos_" + name``, rotations as ``"rot_" + name`` and transforms as
        ``"pose_" + name``.
    dtype : {np.float64, np.float32}, optional
        Output (compute) dtype.  Validation is done in float64, with the
        orthonormality tolerance :func:`ortho_tolerance` of the input dtype
        and this dtype.
    parallel : bool or None, optional
        As for :func:`as_rotations`.

    Returns
    -------
    pos : numpy.ndarray
        ``(3,)`` or ``(N, 3)``, C-contiguous.
    rot : numpy.ndarray
        ``(3, 3)`` or ``(N, 3, 3)``, C-contiguous.

    Raises
    ------
    TypeError, ValueError
        As :func:`as_positions` and :func:`as_rotations`; additionally a
        ValueError if a transform's last row is not ``[0, 0, 0, 1]``.

    Notes
    -----
    Positions and rotations are not broadcast against each other here;
    that is :func:`broadcast_poses`'s job, so a single rotation with a
    batch of positions is allowed.
    """
    if rot is not None:
        p = as_positions(pos, name="pos_" + name, dtype=dtype)
        R = as_rotations(rot, quat_order=quat_order, name="rot_" + name, dtype=dtype, parallel=parallel)
        return p, R

    out_dt = _out_dtype(dtype)
    tname = "pose_" + name
    arr = as_real_array(pos, tname)
    if arr.ndim not in (2, 3) or arr.shape[-2:] != (4, 4):
        raise ValueError(
            f"{tname} has shape {arr.shape}; with rot=None the pose must be "
            f"(4, 4) or (N, 4, 4) homogeneous transforms "
            f"(pass the rotation as rot=... to give a position separately)"
        )
    batched = arr.ndim == 3
    T = _as_float(arr)
    _check_finite(T, tname, batched)
    _check_positions(T[..., :3, 3], tname, batched, what=" translation", dtype=out_dt)
    Tb = T if batched else T[None]
    last_row = np.array([0.0, 0.0, 0.0, 1.0])
    row_err = np.abs(Tb[:, 3, :] - last_row).max(axis=1, initial=0.0)
    bad = row_err > TRANSFORM_ROW_TOL
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(
            f"{indexed_name(tname, i if batched else None)} has last row "
            f"{Tb[i, 3, :].tolist()}; a homogeneous transform needs [0, 0, 0, 1]"
        )
    R_block = T[..., :3, :3]
    _check_rotation_matrices(R_block, tname, ortho_tolerance(arr.dtype, out_dt), batched, " rotation block", parallel)
    p = np.ascontiguousarray(T[..., :3, 3], dtype=out_dt)
    R = np.ascontiguousarray(R_block, dtype=out_dt)
    return p, R


def _is_transform(x) -> bool:
    if x is None or _is_scipy_rotation(x):
        return False
    try:
        shape = np.shape(x)
    except (ValueError, TypeError):  # ragged: the pose parser names the problem
        return False
    return len(shape) in (2, 3) and shape[-2:] == (4, 4)


def transforms_as_written(pos_a, rot_a, pos_b, rot_b):
    """The arguments of ``collide(a, b, T_a, T_b)`` rearranged as ``(T_a, None, T_b, None)``.

    Two 4x4 transforms given positionally land in ``pos_a`` and ``rot_a``.
    A rotation is never 4x4, and when ``pos_a`` is a transform ``rot_a``
    must be None, so ``rot_a`` holding a transform can only be ``T_b``.
    Anything else is returned as it is.
    """
    if pos_b is None and rot_b is None and _is_transform(pos_a) and _is_transform(rot_a):
        return pos_a, None, rot_a, None
    return pos_a, rot_a, pos_b, rot_b


def _batch_size(a: np.ndarray, single_ndim: int, name: str) -> int | None:
    """None for a single item, else the leading dimension."""
    a = np.asarray(a)
    core = (3,) if single_ndim == 1 else (3, 3)
    if a.ndim == single_ndim and a.shape == core:
        return None
    if a.ndim == single_ndim + 1 and a.shape[1:] == core:
        return a.shape[0]
    raise ValueError(f"{name} has shape {a.shape}; expected {core} or (N, {', '.join(map(str, core))})")


def common_batch_size(pos_a, rot_a, pos_b, rot_b, *, n_shapes=None, shapes_name="shape set"):
    """Common batch size ``N`` of parsed poses (and a shape set), without copying.

    Single items and batches of one broadcast against anything; any two other
    sizes must agree. Raises ValueError listing every argument's batch size,
    e.g. ``"batch sizes do not match: pos_a has 5, rot_a has 1 (broadcast),
    pos_b has 7, rot_b has 7"``. ``shapes_name``: what ``n_shapes`` counts, for that message.
    """
    arrays = (pos_a, rot_a, pos_b, rot_b)
    names = ("pos_a", "rot_a", "pos_b", "rot_b")
    ndims = (1, 2, 1, 2)
    sizes = [_batch_size(a, nd, nm) for a, nd, nm in zip(arrays, ndims, names)]
    entries = list(zip(names, sizes))
    if n_shapes is not None:
        entries.append((shapes_name, int(n_shapes)))
    n = broadcast_size([s for _, s in entries])
    if n is None:
        parts = []
        for nm, s in entries:
            if s is None:
                parts.append(f"{nm} has 1 (single, broadcast)")
            elif s == 1:
                parts.append(f"{nm} has 1 (broadcast)")
            else:
                parts.append(f"{nm} has {s}")
        raise ValueError("batch sizes do not match: " + ", ".join(parts))
    return n


def broadcast_size(sizes):
    """The batch size ``sizes`` broadcast to (None, a single item, and 1 go with anything); None where
    two others differ."""
    big = {s for s in sizes if s is not None and s != 1}
    return None if len(big) > 1 else (big.pop() if big else 1)


def broadcast_poses(pos_a, rot_a, pos_b, rot_b, *, n_shapes=None, shapes_name="shape set", dtype=np.float64):
    """Broadcast two (batches of) poses to a common batch size ``N``.

    Parameters
    ----------
    pos_a, pos_b : numpy.ndarray
        Already parsed positions, ``(3,)`` or ``(N_i, 3)``.
    rot_a, rot_b : numpy.ndarray
        Already parsed rotations, ``(3, 3)`` or ``(N_i, 3, 3)``.
    n_shapes : int or None, optional
        Batch size imposed by a per-pair shape set (None if the shapes are
        not given per pair).  Takes part in the same broadcasting rule.
    shapes_name : str, optional
        What ``n_shapes`` counts, as the error message names it (a batch of
        covariances, say).
    dtype : {np.float64, np.float32}, optional
        Output dtype (float64 by default).

    Returns
    -------
    N : int
        Common batch size (1 if everything is a single pose).
    arrays : tuple of numpy.ndarray
        ``(pos_a, rot_a, pos_b, rot_b)`` of shapes ``(N, 3)``,
        ``(N, 3, 3)``, ``(N, 3)``, ``(N, 3, 3)``, C-contiguous and
        writeable.  An input that already has the target shape, dtype and
        layout is returned as is (no copy), so it may share memory with
        the caller's array.

    Raises
    ------
    ValueError
        If an array has the wrong shape, or if batch sizes differ and are
        not 1-vs-N.  The message lists every argument's batch size, e.g.
        ``"batch sizes do not match: pos_a has 5, rot_a has 1 (broadcast),
        pos_b has 7, rot_b has 7"``.
    """
    out_dt = _out_dtype(dtype)
    arrays = (pos_a, rot_a, pos_b, rot_b)
    ndims = (1, 2, 1, 2)
    N = common_batch_size(pos_a, rot_a, pos_b, rot_b, n_shapes=n_shapes, shapes_name=shapes_name)

    out = []
    for a, nd in zip(arrays, ndims):
        a = np.asarray(a)
        target = (N,) + a.shape[-nd:]
        if a.shape != target:
            a = np.broadcast_to(a, target)
        a = np.ascontiguousarray(a, dtype=out_dt)
        # broadcast_to views are read-only, and ascontiguousarray keeps such
        # a view when it is already contiguous (e.g. N=1).  Numba kernels with
        # explicit signatures reject read-only arrays, so always hand back
        # writeable memory.
        if not a.flags.writeable:
            a = a.copy()
        out.append(a)
    return N, tuple(out)


def relative_poses(pos_a, rot_a, pos_b, rot_b, *, dtype=np.float64):
    """Pose of ``b`` expressed in the frame of ``a``, for every pair.

    Parameters
    ----------
    pos_a, rot_a, pos_b, rot_b : numpy.ndarray
        Parsed poses, single or batched; broadcast with
        :func:`broadcast_poses`.
    dtype : {np.float64, np.float32}, optional
        Output dtype.  The computation itself is done in float64.

    Returns
    -------
    p_rel : numpy.ndarray
        ``(N, 3)``, ``R_a^T (p_b - p_a)``.
    R_rel : numpy.ndarray
        ``(N, 3, 3)``, ``R_a^T R_b``.

    Raises
    ------
    ValueError
        As :func:`broadcast_poses`.
    """
    out_dt = _out_dtype(dtype)
    _, (pa, Ra, pb, Rb) = broadcast_poses(pos_a, rot_a, pos_b, rot_b)
    # Transpose via the einsum subscripts: no copy of R_a^T is materialised.
    R_rel = np.einsum("nji,njk->nik", Ra, Rb)
    p_rel = np.einsum("nji,nj->ni", Ra, pb - pa)
    return (
        np.ascontiguousarray(p_rel, dtype=out_dt),
        np.ascontiguousarray(R_rel, dtype=out_dt),
    )
