"""Small vector helpers for the kernels (tuples and rows of (n, 3) arrays), error-free sums and
products (and a cross product accurate to its own size from them), the length of a 2-vector, and the
exponential of a rotation vector; inlined."""

import math

from .jit import jit

#: Where x^2 + y^2 lies in this range its square root is within about an ulp of |(x, y)|, in float32 as in
#: float64: no square overflows, and a square that underflows is far below an ulp of the sum.
_SQUARES_SAFE = (1e-30, 1e30)


@jit(inline="always")
def length2(x, y):
    """|(x, y)|: ``sqrt(x^2 + y^2)`` where the squares are safe, else ``math.hypot``, which scales to avoid
    overflow and underflow but took 12.7 ns a call against 1.9 (200,000 calls, 2026-11-28)."""
    s = x * x + y * y
    if _SQUARES_SAFE[0] <= s <= _SQUARES_SAFE[1]:
        return math.sqrt(s)
    return math.hypot(x, y)


@jit(inline="always")
def cross(a, b):
    """a x b."""
    return a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]


@jit(inline="always")
def two_sum(a, b):
    """``(s, e)``: s = fl(a + b) and its rounding error, s + e = a + b exactly (Knuth)."""
    s = a + b
    t = s - a
    return s, (a - (s - t)) + (b - t)


@jit(inline="always")
def two_product(a, b):
    """``(p, e)``: p = fl(a b) and its rounding error, p + e = a b exactly (Dekker's split, no FMA
    needed; exact for |a|, |b| below 1e290, far above the supported range)."""
    p = a * b
    c = 134217729.0 * a  # 2^27 + 1
    ah = c - (c - a)
    c = 134217729.0 * b
    bh = c - (c - b)
    al, bl = a - ah, b - bh
    return p, ((ah * bh - p) + ah * bl + al * bh) + al * bl


@jit(inline="always")
def _det2(a, b, c, d):
    """a d - b c to within about eps of the result (the products' rounding errors added back), where the
    plain difference loses eps |a d| to cancellation."""
    p, e = two_product(a, d)
    q, f = two_product(b, c)
    return (p - q) + (e - f)


@jit(inline="always")
def cross_accurate(a, b):
    """a x b, each component to within about eps of itself: the plain :func:`cross` is off by up to
    eps |a| |b| per component, which for nearly parallel a, b (a sliver triangle's edges) is a large
    part of |a x b|, and tilts the normal by eps / sin(a, b)."""
    return _det2(a[1], a[2], b[1], b[2]), _det2(a[2], a[0], b[2], b[0]), _det2(a[0], a[1], b[0], b[1])


#: Below this squared sine of the angle of a and b, :func:`normal` takes :func:`cross_accurate`: the plain
#: product's direction is off by about eps / sine, which moves a plane 1e5 from the origin by 1e-3 of a
#: tol of 3e-5 (rtol 1e-9) at a sine of 1e-3; above it the plain product is kept (the accurate one costs
#: EPA and the margin query a quarter of their time).
PLAIN_CROSS_SIN2 = 1e-6


@jit(inline="always")
def cross_and_sizes(a, b):
    """``(n, nn, lim)``: the plain n = a x b, nn = |n|^2 and lim = |a|^2 |b|^2; nn / lim is the squared
    sine of the angle of a and b (to within about eps / sine: enough to tell how parallel they are)."""
    n = cross(a, b)
    return n, dot(n, n), dot(a, a) * dot(b, b)


@jit(inline="always")
def plain_cross_too_tilted(nn, lim):
    """True where the plain product's direction is not good enough for a plane's normal
    (:data:`PLAIN_CROSS_SIN2`; nn, lim from :func:`cross_and_sizes`)."""
    return nn < PLAIN_CROSS_SIN2 * lim


@jit(inline="always")
def normal(a, b):
    """a x b as a plane's normal: the plain :func:`cross` where a and b are far enough from parallel
    (:data:`PLAIN_CROSS_SIN2`), :func:`cross_accurate` where not."""
    n, nn, lim = cross_and_sizes(a, b)
    if plain_cross_too_tilted(nn, lim):
        return cross_accurate(a, b)
    return n


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


# Taylor coefficients in u = t^2 of sin(t) / t and (1 - cos t) / t^2, lowest first, to the term
# that falls below 1e-19 for t <= 1 (the sampled rotations are mostly smaller).
_SINC_SERIES = tuple((-1.0) ** k / math.factorial(2 * k + 1) for k in range(10))
_COSC_SERIES = tuple((-1.0) ** k / math.factorial(2 * k + 2) for k in range(10))


@jit(inline="always")
def _series10(c, u, u2, u4, u8):
    """``c[0] + c[1] u + ... + c[9] u^9`` by Estrin's scheme: four dependent steps where
    Horner's rule takes ten, a latency the sampling loop waited on."""
    low = (c[0] + c[1] * u) + (c[2] + c[3] * u) * u2
    high = (c[4] + c[5] * u) + (c[6] + c[7] * u) * u2
    return (low + high * u4) + (c[8] + c[9] * u) * u8


@jit(inline="always", error_model="numpy")
def rodrigues_coefficients(u):
    """``(sin t / t, (1 - cos t) / t^2)`` of the angle ``t = sqrt(u)``, u >= 0.

    For t <= 1 their series in u (no square root, division or sine, whose latency held up the
    sampling loop); beyond, from the sine and cosine of t / 2 (no digits lost either way).
    """
    if u <= 1.0:
        u2 = u * u
        u4 = u2 * u2
        u8 = u4 * u4
        return _series10(_SINC_SERIES, u, u2, u4, u8), _series10(_COSC_SERIES, u, u2, u4, u8)
    t = math.sqrt(u)
    h = math.sin(0.5 * t) / (0.5 * t)
    return h * math.cos(0.5 * t), 0.5 * h * h


@jit(inline="always")
def rotate_by(tx, ty, tz, R0, R):
    """``R = exp([theta]x) R0``, theta = (tx, ty, tz), written into R (3 x 3): Rodrigues,
    ``I + a K + b K^2`` with K = [theta]x and a, b from :func:`rodrigues_coefficients`."""
    xx, yy, zz = tx * tx, ty * ty, tz * tz
    a, b = rodrigues_coefficients(xx + yy + zz)
    e00, e11, e22 = 1.0 - b * (yy + zz), 1.0 - b * (xx + zz), 1.0 - b * (xx + yy)
    e01, e10 = b * tx * ty - a * tz, b * tx * ty + a * tz
    e02, e20 = b * tx * tz + a * ty, b * tx * tz - a * ty
    e12, e21 = b * ty * tz - a * tx, b * ty * tz + a * tx
    for j in range(3):
        r0, r1, r2 = R0[0, j], R0[1, j], R0[2, j]
        R[0, j] = e00 * r0 + e01 * r1 + e02 * r2
        R[1, j] = e10 * r0 + e11 * r1 + e12 * r2
        R[2, j] = e20 * r0 + e21 * r1 + e22 * r2
