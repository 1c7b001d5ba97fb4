"""Small 3-vector helpers for the distance kernels (tuples and rows of (n, 3) arrays), inlined."""

from .jit import jit


@jit(inline="always")
def cross(a, b):
    """a x b."""
    return a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]


@jit(inline="always")
def dot(a, b):
    """a . b."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@jit(inline="always")
def sub(a, b):
    """a - b."""
    return a[0] - b[0], a[1] - b[1], a[2] - b[2]


@jit(inline="always")
def row(V, i):
    """Row i of V as a tuple."""
    return V[i, 0], V[i, 1], V[i, 2]


@jit(inline="always")
def diff(V, i, j):
    """Row i minus row j of V."""
    return sub(row(V, i), row(V, j))
