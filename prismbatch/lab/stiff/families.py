"""The stiff suite's families: exact constructions and LP-judged random poses, by parameter value.

:data:`FAMILIES` maps each family name to its parameter, the values it is run
for, its generator ``gen(rng, n, value) -> PairSet`` and its kind of ground
truth. See docs/methods/stiff-suite.md.
"""

from __future__ import annotations

import math

import numpy as np

from ...sampling import random_rotations
from .constructions import PairSet, concat, coplanar_pairs, face_pairs, side_pairs
from .geometry import (
    R_DOWN,
    axis_rotation,
    collinear_polygon,
    down_rotation,
    random_polygon,
    rot_z,
    sliver_polygon,
    with_axis,
)

#: Relative separations cycled through by the constructed families other than ``separation``:
#: overlaps, clear hits, the float64 band (3e-9), float32's range (1e-7 .. 1e-5), clear misses.
_S_CYCLE = (-1e-3, -1e-9, 1e-15, 1e-12, 3e-9, 1e-7, 1e-5, 1e-3)


def _polys(rng, n):
    return [random_polygon(rng, radius=float(rng.uniform(0.5, 2.0))) for _ in range(n)]


def _cycle(n, rng):
    s = np.array([_S_CYCLE[k % len(_S_CYCLE)] for k in range(n)])
    return s[rng.permutation(n)]


def _tilted_up(rng, n, max_tilt):
    out = []
    for _ in range(n):
        az = rng.uniform(0, 2 * np.pi)
        t = max_tilt * math.sqrt(rng.uniform())
        d = np.array([math.sin(t) * math.cos(az), math.sin(t) * math.sin(az), math.cos(t)])
        out.append(with_axis(d, rng.uniform(0, 2 * np.pi)))
    return out


def _perp_rotation(v, az, vz, spin):
    """A rotation whose axis has z component ``vz`` (``|vz| = v``) and azimuth ``az``."""
    c = math.sqrt(1.0 - v * v)
    return with_axis(np.array([c * math.cos(az), c * math.sin(az), vz]), spin)


def _mixed(rng, A, B, seps, scale=1.0):
    """Half face constructions (facing, tilt up to 60 deg), half side constructions (tilt 1e-12..1e-1)."""
    n = len(A)
    h = (n + 1) // 2
    f = face_pairs(rng, A[:h], B[:h], _tilted_up(rng, h, math.radians(60)), seps[:h], scale=scale)
    if n == h:
        return f
    tilts = 10.0 ** rng.uniform(-12, -1, n - h)
    s = side_pairs(rng, A[h:], B[h:], tilts, seps[h:], scale=scale)
    return concat(f, s)


# --- constructed families: the ground truth is the construction --------------


def _fam_separation(rng, n, s):
    return _mixed(rng, _polys(rng, n), _polys(rng, n), np.full(n, s))


def _fam_perp_gap(rng, n, v):
    rots = []
    for _ in range(n):
        az = rng.uniform(0, 2 * np.pi)
        rots.append(_perp_rotation(v, az, v, rng.uniform(0, 2 * np.pi)))
    return face_pairs(rng, _polys(rng, n), _polys(rng, n), rots, _cycle(n, rng))


def _tilt_of(v):
    """Angle whose 1 - cos is v (accurate for tiny v)."""
    return 2.0 * math.asin(math.sqrt(v / 2.0))


def _fam_antiparallel_gap(rng, n, v):
    t = _tilt_of(v)
    rots = []
    for _ in range(n):
        az = rng.uniform(0, 2 * np.pi)
        rots.append(axis_rotation([math.cos(az), math.sin(az), 0.0], t) @ rot_z(rng.uniform(0, 2 * np.pi)))
    return face_pairs(rng, _polys(rng, n), _polys(rng, n), rots, _cycle(n, rng))


def _fam_parallel_gap(rng, n, v):
    return side_pairs(rng, _polys(rng, n), _polys(rng, n), np.full(n, _tilt_of(v)), _cycle(n, rng))


def _fam_coplanar(rng, n, ulps):
    return coplanar_pairs(rng, _polys(rng, n), ulps, _cycle(n, rng))


def _fam_scale(rng, n, scale):
    A = [p * scale for p in _polys(rng, n)]
    B = [p * scale for p in _polys(rng, n)]
    return _mixed(rng, A, B, _cycle(n, rng), scale)


_REGULAR_CACHE = {}


def _fam_vertices(rng, n, nv):
    nv = int(nv)
    if nv not in _REGULAR_CACHE:
        ang = 2 * np.pi * np.arange(nv) / nv
        _REGULAR_CACHE[nv] = (
            np.column_stack([2.0 * np.cos(ang), 2.0 * np.sin(ang)]),
            np.column_stack([1.5 * np.cos(ang + 0.3), 1.5 * np.sin(ang + 0.3)]),
        )
    A, B = _REGULAR_CACHE[nv]
    return _mixed(rng, [A] * n, [B] * n, _cycle(n, rng))


def _special_pair_polys(rng, n, make, param):
    """Polygon pairs where a, b or both (cycling) are ``make(rng, param, size)``."""
    A, B = _polys(rng, n), _polys(rng, n)
    for k in range(n):  # a special, b special, both
        if k % 3 != 1:
            A[k] = make(rng, param, float(rng.uniform(0.5, 2.0)))
        if k % 3 != 0:
            B[k] = make(rng, param, float(rng.uniform(0.5, 2.0)))
    return A, B


def _sliver_pair_polys(rng, n, aspect):
    return _special_pair_polys(rng, n, sliver_polygon, aspect)


def _fam_sliver(rng, n, aspect):
    return _mixed(rng, *_sliver_pair_polys(rng, n, aspect), _cycle(n, rng))


def _collinear_pair_polys(rng, n, bulge):
    return _special_pair_polys(rng, n, collinear_polygon, bulge)


def _fam_collinear(rng, n, bulge):
    return _mixed(rng, *_collinear_pair_polys(rng, n, bulge), _cycle(n, rng))


# --- LP families: random poses near contact ---------------------------------


def _lp_set(A, B, pa, Ra, pb_, Rb):
    return PairSet(
        list(A), list(B), np.array(pa), np.array(Ra), np.array(pb_), np.array(Rb), np.full(len(A), np.nan), True
    )


def _fam_perp_lp(rng, n, v):
    """a down; b's axis at |d_a . d_b| = v, tilted towards or away from a's body at random."""
    A, B = _polys(rng, n), _polys(rng, n)
    Ra = [down_rotation(rng) for _ in range(n)]
    Rb = []
    for _ in range(n):
        az, sgn = rng.uniform(0, 2 * np.pi), rng.choice([-1.0, 1.0])
        Rb.append(_perp_rotation(v, az, sgn * v, rng.uniform(0, 2 * np.pi)))
    pa = rng.uniform(-1, 1, (n, 3))
    pb_ = pa + np.column_stack([rng.uniform(-3.5, 3.5, (n, 2)), rng.uniform(-2.0, 2.0, n)])
    return _lp_set(A, B, pa, Ra, pb_, Rb)


def _near_parallel_lp(rng, n, tilt, facing):
    A, B = _polys(rng, n), _polys(rng, n)
    Ra = [down_rotation(rng) for _ in range(n)]
    base = np.eye(3) if facing else R_DOWN
    Rb = [
        axis_rotation([math.cos(t), math.sin(t), 0.0], tilt) @ rot_z(s) @ base
        for t, s in rng.uniform(0, 2 * np.pi, (n, 2))
    ]
    pa = rng.uniform(-1, 1, (n, 3))
    pb_ = pa + np.column_stack([rng.uniform(-3.0, 3.0, (n, 2)), rng.uniform(-1.0, 1.0, n)])
    return _lp_set(A, B, pa, Ra, pb_, Rb)


def _fam_antiparallel_lp(rng, n, tilt):
    return _near_parallel_lp(rng, n, tilt, True)


def _fam_parallel_lp(rng, n, tilt):
    return _near_parallel_lp(rng, n, tilt, False)


def _free_lp(rng, A, B, scale=1.0):
    n = len(A)
    pa = rng.uniform(-1.5, 1.5, (n, 3)) * scale
    pb_ = rng.uniform(-1.5, 1.5, (n, 3)) * scale
    return _lp_set(A, B, pa, random_rotations(n, rng), pb_, random_rotations(n, rng))


def _fam_scale_lp(rng, n, scale):
    return _free_lp(rng, [p * scale for p in _polys(rng, n)], [p * scale for p in _polys(rng, n)], scale)


def _fam_sliver_lp(rng, n, aspect):
    return _free_lp(rng, *_sliver_pair_polys(rng, n, aspect))


def _fam_collinear_lp(rng, n, bulge):
    return _free_lp(rng, *_collinear_pair_polys(rng, n, bulge))


_SEPARATIONS = (-1e-3, -1e-9, -1e-15, 0.0) + tuple(10.0**k for k in range(-15, -2)) + (3e-9,)
_PERP = (1e-1, 1e-3, 1e-6, 1e-9, 1e-12, 1e-16, 0.0)
_PAR = (1e-1, 1e-4, 1e-8, 1e-12, 1e-16, 0.0)
_TILTS = (1e-2, 1e-4, 1e-6, 1e-8, 1e-10, 1e-12, 1e-16, 0.0)

#: name -> (parameter name, values, generator(rng, n, value), truth)
FAMILIES = {
    "separation": ("gap/S", tuple(sorted(_SEPARATIONS)), _fam_separation, "construction"),
    "perpendicular_gap": ("|d_a.d_b|", _PERP, _fam_perp_gap, "construction"),
    "perpendicular_lp": ("|d_a.d_b|", _PERP, _fam_perp_lp, "LP + certificates"),
    "antiparallel_gap": ("1-|d_a.d_b|", _PAR, _fam_antiparallel_gap, "construction"),
    "antiparallel_lp": ("tilt (rad)", _TILTS, _fam_antiparallel_lp, "LP + certificates"),
    "parallel_gap": ("1-|d_a.d_b|", _PAR, _fam_parallel_gap, "construction"),
    "parallel_lp": ("tilt (rad)", _TILTS, _fam_parallel_lp, "LP + certificates"),
    "coplanar": ("ulps", (-4, -1, 0, 1, 4), _fam_coplanar, "construction"),
    "scale": ("scale", (1e-6, 1e-3, 1.0, 1e3), _fam_scale, "construction"),
    "scale_lp": ("scale", (1e-6, 1e-3, 1.0, 1e3), _fam_scale_lp, "LP + certificates"),
    "vertices": ("vertices", (3, 4, 10, 100, 1000, 10_000, 100_000), _fam_vertices, "construction"),
    "sliver": ("aspect", (1e-2, 1e-4, 1e-6), _fam_sliver, "construction"),
    "sliver_lp": ("aspect", (1e-2, 1e-4, 1e-6), _fam_sliver_lp, "LP + certificates"),
    "collinear": ("bulge", (1e-3, 1e-6, 1e-9, 1e-12, 0.0), _fam_collinear, "construction"),
    "collinear_lp": ("bulge", (1e-6, 1e-12, 0.0), _fam_collinear_lp, "LP + certificates"),
}

#: pairs per (family, value): (construction, LP) for quick and full runs
SIZES = {True: (8, 4), False: (320, 96)}
