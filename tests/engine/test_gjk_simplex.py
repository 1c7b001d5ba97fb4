"""The 3-D GJK's closest-point step (prismbatch._kernels.gjk3d.closest), the accurate cross product
(prismbatch._kernels.vec3.cross_accurate) and the 2-vector length (vec3.length2) against exact rational
references written here.

Slivers are the hard case: a triangle 2.5e5 long and 4e-3 high (its edges at a sine of 1.6e-8), from
GJK on two prisms whose axes are 3e-14 rad apart, had its plane moved by 2.2 tol by a plain cross
product's rounding, and Ericson's region tests (differences of products of dot products) were
rounding noise on it (tests/data/distance_nearly_parallel_size_ratio.json).
"""

import math
from fractions import Fraction

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st

from prismbatch._kernels.gjk3d import closest
from prismbatch._kernels.vec3 import PLAIN_CROSS_SIN2, cross_accurate, length2

EPS = np.finfo(np.float64).eps


def _q(v):
    return [Fraction(float(x)) for x in v]


def _sub(a, b):
    return [x - y for x, y in zip(a, b)]


def _dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def _cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def _segment_dist2(a, b):
    """Exact squared distance from the origin to segment ab."""
    e = _sub(b, a)
    ee = _dot(e, e)
    t = Fraction(0) if ee == 0 else min(max(-_dot(a, e) / ee, Fraction(0)), Fraction(1))
    p = [x + t * y for x, y in zip(a, e)]
    return _dot(p, p)


def triangle_dist2(a, b, c):
    """Exact squared distance from the origin to triangle abc: its plane's foot if that lies inside
    (all three signed areas at the foot of one sign), else the nearest edge."""
    best = min(_segment_dist2(a, b), _segment_dist2(b, c), _segment_dist2(a, c))
    n = _cross(_sub(b, a), _sub(c, a))
    nn = _dot(n, n)
    if nn > 0:
        h = _dot(n, a) / nn
        p = [h * x for x in n]
        w = [_dot(n, _cross(_sub(q, p), _sub(r, p))) for q, r in ((b, c), (c, a), (a, b))]
        if all(x >= 0 for x in w):
            best = min(best, _dot(p, p))
    return best


def _sliver(rng, length, height, off_plane):
    """A triangle ``length`` long and ``height`` high (its third vertex over the long edge), turned at
    random, placed with the origin ``off_plane`` from its plane over a random point inside it (where
    the closest point is the plane's foot and the vertices are ``length`` away: the tilt of a rough
    normal is multiplied by that lever)."""
    t = rng.uniform(0.2, 0.8)
    pts = np.array([[0.0, 0.0, 0.0], [length, 0.0, 0.0], [t * length, height, 0.0]])
    w = rng.dirichlet(np.ones(3))
    pts = pts - w @ pts + [0.0, 0.0, off_plane * rng.choice([-1.0, 1.0])]
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return pts @ q.T


def _closest_of(tri):
    W = np.zeros((8, 3))
    W[:3] = tri
    m, vx, vy, vz, inside, _ = closest(W, np.zeros((8, 3), dtype=np.int64), np.zeros(8), 3)
    return np.array([vx, vy, vz]), m


@settings(max_examples=200, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    log_length=st.floats(-3, 6),
    log_aspect=st.floats(-14, 0),
    log_off=st.floats(-14, 0),
)
@example(seed=0, log_length=5.4, log_aspect=-7.8, log_off=-9.3)  # the recorded sliver's proportions
def test_closest_point_of_a_triangle_against_the_exact_distance(seed, log_length, log_aspect, log_off):
    # |v| within rounding of the triangle's own size of the exact distance of the float triangle, however
    # thin: the normal's tilt times the lever, at most about eps / sine with the plain cross product kept
    # above a sine of sqrt(PLAIN_CROSS_SIN2) (1e-3). On the recorded sliver the plain normal was off by
    # 7.4e-10, some 3e6 eps, which its 1e5 lever made 2.2 tol
    rng = np.random.default_rng(seed)
    length = 10.0**log_length
    tri = _sliver(rng, length, length * 10.0**log_aspect, length * 10.0**log_off)
    v, m = _closest_of(tri)
    exact = float(triangle_dist2(*map(_q, tri))) ** 0.5
    scale = np.abs(tri).max()
    assert 1 <= m <= 3
    bound = 2 * EPS / math.sqrt(PLAIN_CROSS_SIN2) * scale
    assert abs(np.linalg.norm(v) - exact) <= bound, (np.linalg.norm(v), exact, scale)


@settings(max_examples=300, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), log_angle=st.floats(-16, 0), log_size=st.floats(-8, 8))
def test_cross_accurate_is_exact_to_its_own_size(seed, log_angle, log_size):
    # each component within 2 eps of itself (plus a term of order eps^2 |a| |b|), where the plain
    # cross product is off by eps |a| |b|: for nearly parallel a, b that is all of a x b
    rng = np.random.default_rng(seed)
    a = rng.normal(size=3) * 10.0**log_size
    b = a + rng.normal(size=3) * np.linalg.norm(a) * 10.0**log_angle
    got = cross_accurate((a[0], a[1], a[2]), (b[0], b[1], b[2]))
    want = _cross(_q(a), _q(b))
    size = np.linalg.norm(a) * np.linalg.norm(b)
    for g, w in zip(got, want):
        assert abs(Fraction(g) - w) <= 2 * EPS * abs(w) + 4 * EPS**2 * Fraction(size), (g, float(w))


_LENGTH_CASES = [
    (0.0, 0.0),
    (3.0, 4.0),
    (1e-160, 2e-161),  # squares below the smallest normal
    (1e-155, 0.0),
    (1e200, 1e199),  # squares overflow
    (5e-324, 0.0),
    (1e-15, 1e-200),  # one square underflows, far below an ulp of the other
]


@settings(max_examples=400, deadline=None)
@given(
    mx=st.floats(1, 2),
    my=st.floats(-2, 2),
    ex=st.integers(-1100, 1022),
    ey=st.integers(-1100, 1022),
    single=st.booleans(),
)
@example(mx=1.0, my=1.0, ex=-532, ey=-535, single=False)  # both squares underflow: hypot's side
@example(mx=1.0, my=1.0, ex=-63, ey=-83, single=True)  # float32 squares near its smallest normal
@example(mx=1.0, my=1.0, ex=64, ey=0, single=True)  # a float32 square that would overflow
@example(mx=1.0, my=1.75, ex=127, ey=127, single=True)  # the float32 length itself overflows: inf is right
def test_length2_is_within_an_ulp_or_two_of_the_exact_length(mx, my, ex, ey, single):
    # |got - |(x, y)|| <= 2 eps |(x, y)| (plus the spacing of subnormal results), judged in rationals: the
    # square of got widened by that much brackets x^2 + y^2.
    # Inputs from far below the smallest normal to far above where squares overflow, both dtypes.
    dt = np.float32 if single else np.float64
    with np.errstate(over="ignore", under="ignore"):
        x, y = dt(math.ldexp(mx, ex)), dt(math.ldexp(my, ey))
    if not (np.isfinite(x) and np.isfinite(y)):
        return
    got = length2(x, y)
    eps = float(np.finfo(dt).eps)
    want2 = Fraction(float(x)) ** 2 + Fraction(float(y)) ** 2
    if want2 == 0:
        assert got == 0.0
        return
    if np.isinf(got):  # only where the length itself is beyond the dtype's largest finite number
        assert want2 > Fraction(float(np.finfo(dt).max)) ** 2, (x, y)
        return
    g, tiny = Fraction(float(got)), Fraction(float(np.finfo(dt).smallest_subnormal))  # (a subnormal result's spacing)
    lo, hi = max(g * (1 - Fraction(2 * eps)) - tiny, Fraction(0)), g * (1 + Fraction(2 * eps)) + tiny
    assert lo**2 <= want2 <= hi**2, (x, y, got)


def test_length2_matches_hypot_on_edge_values():
    for x, y in _LENGTH_CASES:
        assert math.isclose(length2(x, y), math.hypot(x, y), rel_tol=4e-16, abs_tol=0.0), (x, y)
    assert math.isnan(length2(math.nan, 1.0)) and length2(math.inf, 1.0) == math.inf
