"""Argument checks shared by the lab's applications (one message per kind of mistake)."""

from __future__ import annotations

import math

from ..checks import integer, is_int

__all__ = ["is_int", "check_int", "check_positive", "check_int_tuple"]


def check_int(v, name, minimum=1):
    """``v`` as an int; TypeError if it is not an integer (bools refused), ValueError below ``minimum``
    (the engine's :func:`~prismbatch.checks.integer`, here with a default minimum of 1)."""
    return integer(v, name, minimum)


def check_int_tuple(x, name, minimum):
    """A non-empty sequence of distinct integers >= ``minimum``, as a tuple."""
    try:
        vals = tuple(x)
    except TypeError:
        raise TypeError(f"{name} must be a sequence of integers, got {type(x).__name__}") from None
    if not vals:
        raise ValueError(f"{name} must not be empty")
    out = []
    for v in vals:
        if not is_int(v):
            raise TypeError(f"{name} must hold integers, got {v!r}")
        if v < minimum:
            raise ValueError(f"{name} values must be >= {minimum}, got {v}")
        out.append(int(v))
    if len(set(out)) != len(out):
        raise ValueError(f"{name} has repeated values: {out}")
    return tuple(out)


def check_positive(v, name):
    """``v`` as a float; TypeError if it is not a real number, ValueError unless finite and > 0."""
    try:
        f = float(v)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a real number, got {type(v).__name__}") from None
    if not (math.isfinite(f) and f > 0):
        raise ValueError(f"{name} must be finite and > 0, got {v}")
    return f


def check_vertex_counts(vertices, name="vertices"):
    """Refuse, before any work, a vertex count no polygon may have (:data:`~prismbatch.config.MAX_VERTICES`).

    Without this a run would measure the smaller counts first and fail only at the large one.
    """
    from ..config import MAX_VERTICES

    for n in vertices:
        if n > MAX_VERTICES:
            raise ValueError(f"{name}: {n:,} is more than the {MAX_VERTICES:,} vertices a polygon may have")
    return vertices
