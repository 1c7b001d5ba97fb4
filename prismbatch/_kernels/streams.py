"""Random numbers inside compiled loops, reproducible whatever the threads or the chunking.

Sample ``u`` of a stream with 64-bit key ``key`` has its own generator, SplitMix64 (Steele,
Lea and Flood 2014, the output function of Java's ``SplittableRandom``), seeded with the
``u``-th output of the SplitMix64 stream that starts at ``key``: what a sample draws depends
only on ``(key, u)``, so a loop can hand samples to threads in any way and a run can stop and
go on (the counter ``u`` says where). Draws in ``(0, 1)`` take the top 52 bits; standard
normals come from the 256-layer ziggurat of Marsaglia and Tsang (2000), its tables computed from
their r and v as NumPy's are, with NumPy's use of the bits (layer from the low 8, sign from the
next, 52 bits for the abscissa), the tail by Marsaglia's (1964) exact method. State travels as a ``uint64`` value:
``value, state = draw(state, ...)``. Stream keys come from NumPy's ``SeedSequence``
(:func:`spawned_keys` forms many at once).
"""

import math

import numpy as np

from .jit import jit

__all__ = ["GOLDEN", "sample_state", "next_u64", "uniform", "normal", "ZIGGURAT", "standard_normals", "spawned_keys"]

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


# numpy.random.SeedSequence's hashing constants (numpy/random/bit_generator.pyx)
_INIT_A, _MULT_A, _INIT_B, _MULT_B = 0x43B0D7E5, 0x931E8875, 0x8B51F9DD, 0x58F38DED
_MIX_L, _MIX_R, _MASK32, _SHIFT16 = np.uint64(0xCA01F9DD), np.uint64(0x4973F715), np.uint64(0xFFFFFFFF), np.uint64(16)


def _hashmix(words, const, mult=_MULT_A):
    """SeedSequence's ``hashmix`` of 32-bit ``words`` (uint64 array) with the hash constant
    ``const`` (then moved on to ``const * mult``); the constant depends only on how many words
    were hashed before, not on them."""
    v = ((words ^ np.uint64(const)) * np.uint64(const * mult & 0xFFFFFFFF)) & _MASK32
    return v ^ (v >> _SHIFT16)


def spawned_keys(seed, keys, child):
    """``SeedSequence(seed, spawn_key=(k, child)).generate_state(1, np.uint64)[0]`` for every k of
    ``keys`` (integers >= 0 below 2^63; ``child`` below 2^32), formed for all keys at once (one SeedSequence a key
    cost 19 us, some 3 % of the sampling time of 256 queries).

    SeedSequence hashes the seed's 32-bit words into a pool of four and mixes them, then mixes
    every word of the spawn key into each pool word. The first part is the pool of
    ``SeedSequence(seed)``, the same for every key, and its hash constant has moved on by the
    number of words hashed. The tests compare this with SeedSequence itself.
    """
    keys = np.asarray(keys, dtype=np.uint64)
    seed_words = max(1, (int(seed).bit_length() + 31) // 32)
    calls = 16 + 4 * max(0, seed_words - 4)  # hashmix calls on the seed: 4 into the pool, 12 mixing it
    start = _INIT_A * pow(_MULT_A, calls, 1 << 32) & 0xFFFFFFFF
    seed_pool = np.random.SeedSequence(seed).pool.astype(np.uint64)
    out = np.empty(len(keys), np.uint64)
    wide = keys > _MASK32  # keys of two words
    for group in (~wide, wide):
        k = keys[group]
        words = [k & _MASK32] + ([k >> np.uint64(32)] if group is wide else []) + [np.full(len(k), child, np.uint64)]
        pool = np.tile(seed_pool, (len(k), 1))
        const = start
        for w in words:
            for d in range(4):
                r = (_MIX_L * pool[:, d] - _MIX_R * _hashmix(w, const)) & _MASK32
                pool[:, d] = r ^ (r >> _SHIFT16)
                const = const * _MULT_A & 0xFFFFFFFF
        low = _hashmix(pool[:, 0], _INIT_B, _MULT_B)  # generate_state: the pool's words hashed from INIT_B
        out[group] = low | (_hashmix(pool[:, 1], _INIT_B * _MULT_B & 0xFFFFFFFF, _MULT_B) << np.uint64(32))
    return out
