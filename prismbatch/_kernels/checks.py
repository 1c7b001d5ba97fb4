"""Input checks compiled for speed (the NumPy versions cost more than the collision kernel)."""

import math

import numpy as np
from numba import prange

from .jit import jit


@jit(inline="always")
def _rotation_ok(R, tol):
    """R finite, orthonormal within ``tol`` (every ``|R^T R - I|`` entry) and proper (det > 0).

    Branch-free over the six distinct entries of the symmetric ``R^T R``: a NaN or inf makes a
    comparison False, so non-finite matrices fail too. In float64 whatever R's dtype (float32
    entries convert exactly), so float32 poses are judged as their float64 copies were.
    """
    f = np.float64
    a0, a1, a2 = f(R[0, 0]), f(R[1, 0]), f(R[2, 0])
    b0, b1, b2 = f(R[0, 1]), f(R[1, 1]), f(R[2, 1])
    c0, c1, c2 = f(R[0, 2]), f(R[1, 2]), f(R[2, 2])
    ok = abs(a0 * a0 + a1 * a1 + a2 * a2 - 1.0) <= tol
    ok &= abs(b0 * b0 + b1 * b1 + b2 * b2 - 1.0) <= tol
    ok &= abs(c0 * c0 + c1 * c1 + c2 * c2 - 1.0) <= tol
    ok &= abs(a0 * b0 + a1 * b1 + a2 * b2) <= tol
    ok &= abs(a0 * c0 + a1 * c1 + a2 * c2) <= tol
    ok &= abs(b0 * c0 + b1 * c1 + b2 * c2) <= tol
    det = a0 * (b1 * c2 - c1 * b2) - b0 * (a1 * c2 - c1 * a2) + c0 * (a1 * b2 - b1 * a2)
    return ok & (det > 0.0)


@jit(inline="always")
def orthonormality_error(R):
    """The largest entry of ``|R^T R - I|``, in float64 whatever R's dtype."""
    f = np.float64
    err = 0.0
    for j in range(3):
        for k in range(j, 3):
            g = f(R[0, j]) * f(R[0, k]) + f(R[1, j]) * f(R[1, k]) + f(R[2, j]) * f(R[2, k])
            if j == k:
                g -= 1.0
            err = max(err, abs(g))
    return err


@jit
def _rotation_problem(R, tol):
    """(kind, value) of a matrix :func:`_rotation_ok` rejects: 1 non-finite, 2 not orthonormal (the
    largest error), 3 a reflection (det); in float64, as there."""
    f = np.float64
    for j in range(3):
        for k in range(3):
            if not math.isfinite(R[j, k]):
                return 1, 0.0
    err = orthonormality_error(R)
    if err > tol:
        return 2, err
    det = (
        f(R[0, 0]) * (f(R[1, 1]) * f(R[2, 2]) - f(R[1, 2]) * f(R[2, 1]))
        - f(R[0, 1]) * (f(R[1, 0]) * f(R[2, 2]) - f(R[1, 2]) * f(R[2, 0]))
        + f(R[0, 2]) * (f(R[1, 0]) * f(R[2, 1]) - f(R[1, 1]) * f(R[2, 0]))
    )
    return 3, det


@jit(inline="always")
def rotation_problem(R, tol):
    """(kind, value) of one (3, 3) matrix, as :func:`first_bad_rotation` classifies it (kind 0: good)."""
    if _rotation_ok(R, tol):
        return 0, 0.0
    return _rotation_problem(R, tol)


@jit
def first_bad_rotation(Rb, tol):
    """One pass over (N, 3, 3): (index, kind, value) of the first bad matrix.

    kind 0: all good; 1: non-finite; 2: not orthonormal (value = max error);
    3: reflection (value = det). A compiled loop: the NumPy version
    (matmul + det over the batch) cost more than the collision kernel; the pass tests each
    matrix without branches and classifies only the first it rejects.
    """
    for i in range(Rb.shape[0]):
        kind, val = rotation_problem(Rb[i], tol)
        if kind != 0:
            return i, kind, val
    return -1, 0, 0.0


def _first_bad_rotation_chunks(Rb, tol, first):
    """:func:`first_bad_rotation` of each of ``len(first)`` equal chunks of ``Rb``, written to
    ``first[c] = (index, kind, value)`` (index -1 where the chunk is good): the first bad matrix of
    the batch is the first chunk's that has one."""
    n = Rb.shape[0]
    m = first.shape[0]
    for c in prange(m):
        lo = c * n // m
        i, kind, val = first_bad_rotation(Rb[lo : (c + 1) * n // m], tol)
        first[c, 0] = i + lo if kind != 0 else -1.0
        first[c, 1] = kind
        first[c, 2] = val


first_bad_rotation_parallel = jit(parallel=True)(_first_bad_rotation_chunks)


@jit
def poses_ok(pos_a, rot_a, pos_b, rot_b, limit, tol):
    """Whether every position coordinate is within ``limit`` (NaN is not) and every rotation is one
    :func:`_rotation_ok` accepts, in one serial pass over (N, 3) and (N, 3, 3) arrays: the check of a
    small batch whose arrays the kernels take as they are (the NumPy checks cost tens of µs a call).
    Only a yes or no: on no, the NumPy checks run and name the first bad input.

    Each array's loop returns at its first failure (the rotations' is :func:`first_bad_rotation`'s):
    accumulated with ``ok &=`` instead, the rotations' loop took 39 ns a pair against 9.6 (200,000
    facing pairs in cache, one thread, 2026-11-28).
    """
    return (
        _positions_ok(pos_a, limit)
        and _positions_ok(pos_b, limit)
        and first_bad_rotation(rot_a, tol)[0] < 0
        and first_bad_rotation(rot_b, tol)[0] < 0
    )


@jit(inline="always")
def _positions_ok(P, limit):
    for i in range(P.shape[0]):
        for j in range(3):
            if not abs(np.float64(P[i, j])) <= limit:
                return False
    return True
