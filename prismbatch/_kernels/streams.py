"""Random numbers inside compiled loops, reproducible whatever the threads or the chunking.

Sample ``u`` of a stream with 64-bit key ``key`` has its own generator, SplitMix64 (Steele,
Lea and Flood 2014, the output function of Java's ``SplittableRandom``), seeded with the
``u``-th output of the SplitMix64 stream that starts at ``key``: what a sample draws depends
only on ``(key, u)``, so a loop can hand samples to threads in any way and a run can stop and
go on (the counter ``u`` says where). Draws in ``(0, 1)`` take the top 52 bits; standard
normals come from the 256-layer ziggurat of Marsaglia and Tsang (2000), its tables computed from
their r and v as NumPy's are, with NumPy's use of the bits (layer from the low 8, sign from the
next, 52 bits for the abscissa), the tail by Marsaglia's (1964) exact method. State travels as a ``uint64`` value:
``value, state = draw(state, ...)``.
"""

import math

import numpy as np

from .jit import jit

__all__ = ["GOLDEN", "sample_state", "next_u64", "uniform", "normal", "ZIGGURAT", "standard_normals"]

#: SplitMix64's increment (2^64 / golden ratio, odd).
GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_S30, _S27, _S31 = np.uint64(30), np.uint64(27), np.uint64(31)
_ONE, _LOW8, _S8, _S12 = np.uint64(1), np.uint64(0xFF), np.uint64(8), np.uint64(12)
_MANT52 = np.uint64(0x000FFFFFFFFFFFFF)


@jit(inline="always")
def _mix(x):
    """SplitMix64's output function (a bijection of 64-bit words)."""
    x = (x ^ (x >> _S30)) * _M1
    x = (x ^ (x >> _S27)) * _M2
    return x ^ (x >> _S31)


@jit(inline="always")
def sample_state(key, u):
    """The generator state of sample ``u`` (uint64) of the stream ``key`` (uint64)."""
    return _mix(key + (u + _ONE) * GOLDEN)


@jit(inline="always")
def next_u64(state):
    """``(64 random bits, state)``."""
    state = state + GOLDEN
    return _mix(state), state


@jit(inline="always")
def uniform(state):
    """``(U, state)`` with U uniform in (0, 1), both ends excluded: the midpoints of 2^52 cells
    (53 bits would round the top one up to 1.0)."""
    x, state = next_u64(state)
    return ((x >> _S12) + 0.5) * (1.0 / 4503599627370496.0), state


def _ziggurat_tables():
    """``(k, w, f, r)``: the 256-layer tables of the standard normal's ziggurat, from r and v.

    ``w[i] 2^52`` is layer i's right edge ``x_i`` (``x_0`` the base strip's width ``v / f(r)``),
    ``k[i]`` the 52-bit abscissa below which a point of layer i is inside the layer above
    (accepted at once), ``f[i] = exp(-x_i^2 / 2)``.
    """
    r, v, m = 3.6541528853610088, 0.00492867323399, 2.0**52
    k, w, f = np.zeros(256, np.uint64), np.zeros(256), np.zeros(256)
    q = v / math.exp(-0.5 * r * r)
    k[0], w[0], w[255] = np.uint64((r / q) * m), q / m, r / m
    f[0], f[255] = 1.0, math.exp(-0.5 * r * r)
    dn = tn = r
    for i in range(254, 0, -1):
        dn = math.sqrt(-2.0 * math.log(v / dn + math.exp(-0.5 * dn * dn)))
        k[i + 1] = np.uint64((dn / tn) * m)
        tn = dn
        f[i], w[i] = math.exp(-0.5 * dn * dn), dn / m
    return k, w, f, r


#: ``(k, w, f, r)`` of :func:`normal` (pass them to the kernel: module globals would be frozen
#: into every compiled copy).
ZIGGURAT = _ziggurat_tables()


@jit(inline="always", error_model="numpy")
def normal(state, zk, zw, zf, r):
    """``(Z, state)`` with Z standard normal; ``zk, zw, zf, r`` are :data:`ZIGGURAT`."""
    while True:
        bits, state = next_u64(state)
        i = np.int64(bits & _LOW8)
        bits = bits >> _S8
        negative = (bits & _ONE) != 0
        a = (bits >> _ONE) & _MANT52
        x = a * zw[i]
        if negative:
            x = -x
        if a < zk[i]:  # inside the layer above: 99.3 % of draws
            return x, state
        if i == 0:  # the tail beyond r
            while True:
                u1, state = uniform(state)
                u2, state = uniform(state)
                xx = -math.log(u1) / r
                if -2.0 * math.log(u2) > xx * xx:
                    return (-(r + xx) if negative else r + xx), state
        u, state = uniform(state)
        if (zf[i - 1] - zf[i]) * u + zf[i] < math.exp(-0.5 * x * x):  # under the curve in the wedge
            return x, state


@jit(error_model="numpy")
def _fill_normals(key, start, out, zk, zw, zf, r):
    for s in range(out.shape[0]):
        state = sample_state(key, np.uint64(start + s))
        for c in range(out.shape[1]):
            out[s, c], state = normal(state, zk, zw, zf, r)


def standard_normals(key, start, count, k):
    """``(count, k)`` standard normals: row s is what sample ``start + s`` of stream ``key`` draws first."""
    out = np.empty((count, k))
    _fill_normals(np.uint64(key), np.int64(start), out, *ZIGGURAT)
    return out
