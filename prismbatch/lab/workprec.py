"""Work-precision study: how many vertices does a cylinder need, and what does that cost?

A semi-infinite cylinder is approximated by a regular n-gon prism and collided
with an exact polygonal prism on near-contact poses whose exact status is known
by construction. For each method the study measures the time per query and the
misclassification rate against the exact cylinder, and draws error against time
(a work-precision diagram) and error against n.

Scene
-----
Object a is a semi-infinite cylinder of radius ``r`` at the origin with its
axis down (the paper's scene: ``rot_a = diag(1, -1, -1)``, ``d_a = -z``).
prismbatch and python-fcl see it as the regular n-gon prism
``Prism.regular(n, r)``: the n-gon is INSCRIBED in the circle (its vertices
lie on it, vertex 0 on local +x), so it lies inside the cylinder and its
largest radial deficit is the geometric error ``r (1 - cos(pi / n))``
(at the edge midpoints). Object b is an exact polygon: the paper's Fig. 6
hexagon, scaled to the cylinder in the paper's ratio (circumradius
``1.25 r``, as 2.5 : 2). Only a's end face is approximated, so every error
comes from the n-gon (or from the method's own tolerance).

One cylinder and one polygon, not two cylinders: the exact status then
follows from the cylinder's support function alone (below), with no exact
cylinder-cylinder reference to write and trust.

Near-contact poses with exact labels (:func:`near_contact_poses`)
------------------------------------------------------------------
In a's local frame (local z = d_a, into the body) draw a unit direction
``u = (sin b cos f, sin b sin f, -cos b)`` with the angle ``b`` between u
and the end face's outward normal ``-d_a`` uniform in ``beta_range``
(default 10-80 degrees) and the azimuth ``f`` uniform. The cylinder's
support point in u is then the rim point ``s = (r cos f, r sin f, 0)``
(``u . d_a < 0``: the support is finite and, b being away from 0 and 90
degrees, unique). b gets a random rotation whose axis makes an angle
uniform in ``tilt_range`` (default 5-60 degrees) with u, so ``u . d_b > 0``
and b's lowest point in u is an end-face vertex ``v``; b is placed so that
``v = s + g u``. The signed gap ``g`` has ``|g| / r`` log-uniform in
``gap_range`` (default 1e-8 .. 1e-1) and either sign with probability 1/2.

* ``g > 0``: the cylinder lies in ``{x : u . x <= u . s}`` and b in
  ``{x : u . x >= u . s + g}``: the plane through ``s + (g/2) u`` normal to
  u separates them at distance ``g`` (an exact miss; the gap is exactly g,
  as s and v are the closest points). The inscribed n-gon lies inside the
  cylinder, so the miss holds for every n.
* ``g < 0``: ``v = s - |g| u`` has local coordinates
  ``(r - |g| sin b) (cos f, sin f)`` and height ``t = |g| cos b > 0``: it is
  strictly inside the cylinder, at depth ``|g| min(sin b, cos b)`` from its
  surface (an exact hit; b's vertex is in a's interior, not edge-on on the
  rim). A coarse inscribed n-gon misses the near hits whose depth is below
  about the geometric error.

The poses are built in float64; their rounding (about 1e-16 r) is far below
the smallest gap (1e-8 r).

Methods (the same poses for every method)
-----------------------------------------
* ``pb64_batch`` / ``pb32_batch``: :meth:`prismbatch.Collider.collide` on all
  poses in one call, one thread (``parallel=False``); time per query = call
  time / N. The poses are converted to the dtype before timing (as a user
  storing them in that precision would).
* ``pb64_pair`` / ``pb32_pair``: :meth:`prismbatch.Collider.collide_pair`,
  one Python call per pose pair (the single-query latency; it also returns
  the contact point).
* ``fcl_ngon``: python-fcl (``fcl.Convex``, default GJK solver libccd) on
  finite stand-ins of both n-gon prisms (:class:`prismbatch.lab.peers.FCLPeer`).
* ``fcl_cylinder``: python-fcl's own ``fcl.Cylinder(r, L)`` as the
  exact-shape peer against b's finite stand-in; FCL's cylinder is centred on
  its origin along its local z, so it is shifted by ``L/2`` along d_a to put
  its end face on a's. Its errors come only from FCL's GJK tolerance.

FCL's own errors: with its default request python-fcl misses overlaps shallower
than about 1e-6 in absolute length units, whatever the stand-in length or the
scene's size (checked here with r = 0.1, 1 and 10 and L from 2 r to 100 r:
the deepest missed overlap was 1.3e-6, 0.8-1.5e-6 and 1.2e-6 length units).
Its misclassification rate therefore depends on the scene's units; with
r = 1 it plateaus at the fraction of poses with overlaps below about 1e-6 r.

Both FCL rows use one stand-in length ``L``, the largest
:func:`prismbatch.lab.peers.fcl_standin_length` over the poses. Truncation cannot
change a label here: b's vertex that makes a hit lies within ``|g|`` of a's
end face, and shrinking bodies keeps misses.

float32 (``pb32_*``) stores shapes and poses in single precision, but Numba
promotes much of the arithmetic to float64, so these rows measure float32
storage (poses rounded to about 6e-8 of their size) plus float32's default
``rtol = 1e-5``. That tolerance counts pairs within about 1e-5 of the scene
size (here a few 1e-5 r) as touching, i.e. as hits: the near misses with
``g`` below it are reported as hits, which is a misclassification against
the exact labels (a safe one), and is reported as such; the columns
``fp_beyond_tol`` / ``fn_beyond_tol`` count only the errors the tolerance
does NOT explain.

Errors
------
* Misclassification rate = wrong / N with a Wilson score 95 % interval;
  split into missed hits (``fn``, rate among exact hits) and false hits
  (``fp``, rate among exact misses). ``max_fn_depth`` and ``max_fp_gap`` give
  the largest |g| / r of each kind of error: the resolution the method
  actually achieved.
* Monte Carlo noise floor: the Wilson upper bound at zero errors,
  ``z^2 / (N + z^2)`` (about 3.8 / N): rates below it cannot be told from 0
  with N poses. Zero-error points are drawn at that bound as open
  down-pointing markers.
* Explained or not: ``fn_beyond_tol`` counts missed hits whose b vertex lies
  inside the method's own polygon (the n-gon, or the cylinder for
  ``fcl_cylinder``) by more than the method's tolerance (prismbatch's pair
  tolerance; 0 for FCL); ``fp_beyond_tol`` counts false hits with a gap above
  twice that tolerance. For prismbatch both must be 0 (its contract); for FCL
  they count GJK tolerance effects.
* Geometric error ``r (1 - cos(pi / n))`` against n, with the order fitted by
  least squares on log-log axes (about 2: ``1 - cos x ~ x^2 / 2``).

Because ``|g|`` is log-uniform, the fraction of poses with ``|g|`` below the
geometric error falls by a constant step per factor of n (about
``2 log10(factor) / 7`` of the hits), not as a power of n; past about n =
3e4 the n-gon's error (5e-9 r) falls below the smallest gap and the rate
reaches the method's own floor.

Timing: median over ``repeats`` full passes over the N poses (min and max
kept; a method stops repeating once its passes at one n took 30 s, so
python-fcl on the largest n-gons may get one pass: the ``passes`` column);
compile time
(or Numba cache load) is measured once per dtype and path before the timed
passes and reported separately, as is each method's setup time per n (shape
construction). The machine's load makes timings noisy.

:func:`run_work_precision` returns a :class:`WorkPrecisionResult`;
:func:`format_work_precision` gives text lines; :func:`write_work_precision`
writes ``workprec.csv``, ``workprec_geometry.csv``, ``workprec.json``,
``workprec.md`` and the figures ``workprec_error_vs_time`` and
``workprec_error_vs_n`` (PNG and SVG).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .report import (new_figure, package_versions, progress as _progress, run_metadata, save_figure,
                      write_csv, write_json)
from ..collide import DEFAULT_RTOL, Collider, pair_scale_tolerance
from ..sampling import AXIS_DOWN
from ..shapes import Prism

__all__ = ["run_work_precision", "write_work_precision", "format_work_precision", "plot_work_precision",
           "WorkPrecisionResult", "NearContactPoses", "near_contact_poses", "wilson_interval",
           "noise_floor", "geometric_error", "fit_order", "vertices_needed", "METHODS",
           "DEFAULT_VERTICES", "QUICK_VERTICES"]

#: Method keys, in the order of the rows and legends.
METHODS = ("pb64_batch", "pb64_pair", "pb32_batch", "pb32_pair", "fcl_ngon", "fcl_cylinder")

DEFAULT_VERTICES = (8, 16, 32, 64, 128, 360, 1000, 3600, 10000, 36000, 100000)
QUICK_VERTICES = (8, 32, 128, 1000, 3600, 10000)
DEFAULT_POSES, QUICK_POSES = 20_000, 10_000
DEFAULT_REPEATS, QUICK_REPEATS = 3, 2

#: Near-contact construction: |gap| / r range (log-uniform), angle of u from a's end-face normal and of
#: b's axis from u (degrees).
GAP_RANGE = (1e-8, 1e-1)
BETA_RANGE_DEG = (10.0, 80.0)
TILT_RANGE_DEG = (5.0, 60.0)

#: b's circumradius relative to the cylinder's radius (the paper's Fig. 6 hexagon : pentagon, 2.5 : 2).
B_SCALE = 1.25
B_VERTICES = 6

#: Timed passes of one method and n stop early once they took this long (s): the slowest
#: rows (python-fcl on 1e5-gons, about 3 ms per query) get fewer passes.
_PASS_BUDGET_S = 30.0

_Z95 = 1.959963984540054  # two-sided 95 % normal quantile
_FCL_MISSING = "python-fcl is not installed: pip install 'prismbatch[fcl]' (or run with fcl=False)"


# ---------------------------------------------------------------------------
# statistics and geometry helpers
# ---------------------------------------------------------------------------


def wilson_interval(k, n, z=_Z95):
    """Wilson score interval for a binomial proportion.

    Parameters
    ----------
    k : int or array_like
        Number of successes (here: misclassified poses), ``0 <= k <= n``.
    n : int or array_like
        Number of trials (> 0).
    z : float, optional
        Normal quantile (default: two-sided 95 %).

    Returns
    -------
    (low, high) : tuple of float or numpy.ndarray
        The interval; it contains ``k / n``. NaN where ``n == 0``.
    """
    k = np.asarray(k, dtype=float)
    n = np.asarray(n, dtype=float)
    if np.any(k < 0) or np.any(k > n):
        raise ValueError(f"k must satisfy 0 <= k <= n, got k={k}, n={n}")
    with np.errstate(invalid="ignore", divide="ignore"):
        p = k / n
        den = 1.0 + z * z / n
        mid = (p + z * z / (2 * n)) / den
        half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
        lo, hi = np.clip(mid - half, 0.0, 1.0), np.clip(mid + half, 0.0, 1.0)
    # exact ends: the interval must contain p even after rounding
    lo = np.where(k == 0, 0.0, np.minimum(lo, p))
    hi = np.where(k == n, 1.0, np.maximum(hi, p))
    if lo.ndim == 0:
        return float(lo), float(hi)
    return lo, hi


def noise_floor(n, z=_Z95):
    """Monte Carlo noise floor: the Wilson upper bound at zero errors, ``z^2 / (n + z^2)``."""
    n = float(n)
    if not n > 0:
        raise ValueError(f"n must be > 0, got {n}")
    return z * z / (n + z * z)


def geometric_error(n, radius=1.0):
    """Largest radial deficit ``radius (1 - cos(pi / n))`` of the inscribed regular n-gon.

    Computed as ``2 radius sin^2(pi / (2 n))`` (no cancellation for large n).
    """
    n = np.asarray(n, dtype=float)
    if np.any(n < 3):
        raise ValueError(f"n must be >= 3, got {n}")
    return radius * 2.0 * np.sin(np.pi / (2.0 * n)) ** 2


def fit_order(n, err):
    """Least-squares fit ``log err = log C - p log n``; returns ``(p, C)`` (order and constant)."""
    x, y = np.log(np.asarray(n, dtype=float)), np.log(np.asarray(err, dtype=float))
    if x.size < 2:
        raise ValueError("fit_order needs at least two points")
    slope, icpt = np.polyfit(x, y, 1)
    return float(-slope), float(math.exp(icpt))


def vertices_needed(rel_error):
    """Smallest n whose inscribed n-gon has ``1 - cos(pi / n) <= rel_error``."""
    e = float(rel_error)
    if not (0.0 < e < 1.0):
        raise ValueError(f"rel_error must be in (0, 1), got {rel_error}")
    n = max(3, math.ceil(math.pi / (2.0 * math.asin(math.sqrt(e / 2.0)))))
    while n > 3 and geometric_error(n - 1) <= e:  # guard the ceil against rounding
        n -= 1
    while geometric_error(n) > e:
        n += 1
    return int(n)


# ---------------------------------------------------------------------------
# poses with exact labels
# ---------------------------------------------------------------------------


@dataclass
class NearContactPoses:
    """Near-contact pose pairs of the cylinder (a) and b with exact labels.

    Attributes
    ----------
    pos_a, rot_a, pos_b, rot_b : numpy.ndarray
        (N, 3) and (N, 3, 3) float64 poses (a's are the same for every pair).
    gap : numpy.ndarray, shape (N,)
        Signed gap g (length units): > 0 the bodies are exactly g apart,
        < 0 b's vertex ``v`` is inside the cylinder.
    beta : numpy.ndarray, shape (N,)
        Angle (rad) between u and the end face's outward normal ``-d_a``.
    u : numpy.ndarray, shape (N, 3)
        World direction of the construction.
    vertex : numpy.ndarray of int, shape (N,)
        Index of b's vertex ``v`` in ``shape_b.xy``.
    hit : numpy.ndarray of bool, shape (N,)
        Exact label: True iff the cylinder and b intersect (``g < 0``).
    radius : float
        Cylinder radius r.
    """

    pos_a: np.ndarray
    rot_a: np.ndarray
    pos_b: np.ndarray
    rot_b: np.ndarray
    gap: np.ndarray
    beta: np.ndarray
    u: np.ndarray
    vertex: np.ndarray
    hit: np.ndarray
    radius: float

    def __len__(self):
        return self.gap.shape[0]

    def vertex_local(self, shape_b):
        """b's vertex ``v`` of every pair in a's local frame, (N, 3)."""
        xy = np.asarray(shape_b.xy)[self.vertex]
        vw = self.pos_b + np.einsum("nij,nj->ni", self.rot_b[:, :, :2], xy)
        return np.einsum("nji,nj->ni", self.rot_a, vw - self.pos_a)

    def depth_in_cylinder(self, shape_b):
        """Depth of ``v`` inside the exact cylinder: ``min(t, r - |q|)`` (< 0 outside)."""
        loc = self.vertex_local(shape_b)
        return np.minimum(loc[:, 2], self.radius - np.hypot(loc[:, 0], loc[:, 1]))

    def depth_in_ngon(self, shape_b, n):
        """Depth of ``v`` inside a's inscribed regular n-gon prism (vertex 0 on local +x); < 0 outside."""
        loc = self.vertex_local(shape_b)
        step = 2.0 * np.pi / n
        th = np.mod(np.arctan2(loc[:, 1], loc[:, 0]), 2.0 * np.pi)
        mid = (np.floor(th / step) + 0.5) * step  # the edge whose sector holds v
        side = self.radius * math.cos(math.pi / n) - (loc[:, 0] * np.cos(mid) + loc[:, 1] * np.sin(mid))
        return np.minimum(loc[:, 2], side)


def _unit_rows(x):
    return x / np.linalg.norm(x, axis=1, keepdims=True)


def _frames_with_axis(d, spin):
    """Rotations (N, 3, 3) with third column ``d`` (unit rows) and a spin angle about it."""
    ref = np.where(np.abs(d[:, :1]) < 0.9, np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]))
    x = _unit_rows(ref - np.sum(ref * d, axis=1, keepdims=True) * d)
    y = np.cross(d, x)
    c, s = np.cos(spin)[:, None], np.sin(spin)[:, None]
    x, y = c * x + s * y, -s * x + c * y
    return np.stack([x, y, d], axis=2)


def near_contact_poses(n, rng, *, radius=1.0, shape_b=None, gap_range=GAP_RANGE,
                       beta_range=tuple(np.radians(BETA_RANGE_DEG)),
                       tilt_range=tuple(np.radians(TILT_RANGE_DEG)), hit_fraction=0.5):
    """Near-contact poses of a semi-infinite cylinder (a) and a polygonal prism (b), exact labels.

    See the module docstring for the construction and why its labels are exact.

    Parameters
    ----------
    n : int
        Number of pose pairs (>= 1).
    rng : numpy.random.Generator
        Source of randomness.
    radius : float, optional
        Cylinder radius r (> 0).
    shape_b : Prism, optional
        b's prism (default: regular hexagon of circumradius ``1.25 radius``).
    gap_range : (float, float), optional
        Range of ``|g| / r``, sampled log-uniformly (0 < low <= high).
    beta_range : (float, float), optional
        Range (rad) of the angle between u and a's outward end-face normal,
        inside (0, pi/2).
    tilt_range : (float, float), optional
        Range (rad) of the angle between b's axis and u, inside [0, pi/2).
    hit_fraction : float, optional
        Probability of ``g < 0`` (a hit).

    Returns
    -------
    NearContactPoses
    """
    n = _check_int(n, "n", 1)
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    radius = _check_positive(radius, "radius")
    if shape_b is None:
        shape_b = Prism.regular(B_VERTICES, B_SCALE * radius)
    if not isinstance(shape_b, Prism):
        raise TypeError(f"shape_b must be a prismbatch.Prism, got {type(shape_b).__name__}")
    lo, hi = (float(v) for v in gap_range)
    if not (0.0 < lo <= hi and np.isfinite(hi)):
        raise ValueError(f"gap_range must satisfy 0 < low <= high < inf, got {gap_range}")
    b0, b1 = (float(v) for v in beta_range)
    if not (0.0 < b0 <= b1 < np.pi / 2):
        raise ValueError(f"beta_range must lie inside (0, pi/2) with low <= high, got {beta_range}")
    t0, t1 = (float(v) for v in tilt_range)
    if not (0.0 <= t0 <= t1 < np.pi / 2):
        raise ValueError(f"tilt_range must lie inside [0, pi/2) with low <= high, got {tilt_range}")
    if not (0.0 <= float(hit_fraction) <= 1.0):
        raise ValueError(f"hit_fraction must be in [0, 1], got {hit_fraction}")

    rot_a1 = AXIS_DOWN.astype(float)
    pos_a1 = np.zeros(3)
    beta = rng.uniform(b0, b1, n)
    phi = rng.uniform(0.0, 2.0 * np.pi, n)
    mag = radius * np.exp(rng.uniform(math.log(lo), math.log(hi), n))
    hit = rng.uniform(size=n) < float(hit_fraction)
    gap = np.where(hit, -mag, mag)
    # a's local frame: z = d_a (into the body); u has u . d_a = -cos(beta) < 0
    u_loc = np.column_stack([np.sin(beta) * np.cos(phi), np.sin(beta) * np.sin(phi), -np.cos(beta)])
    s_loc = np.column_stack([radius * np.cos(phi), radius * np.sin(phi), np.zeros(n)])
    u = u_loc @ rot_a1.T
    s = pos_a1 + s_loc @ rot_a1.T
    # b's axis at angle tilt from u (so u . d_b > 0: b's lowest point in u is on its end face)
    tilt = rng.uniform(t0, t1, n)
    psi = rng.uniform(0.0, 2.0 * np.pi, n)
    e1 = _frames_with_axis(u, np.zeros(n))
    d_b = (np.cos(tilt)[:, None] * u + np.sin(tilt)[:, None] * (np.cos(psi)[:, None] * e1[:, :, 0]
                                                                + np.sin(psi)[:, None] * e1[:, :, 1]))
    rot_b = _frames_with_axis(_unit_rows(d_b), rng.uniform(0.0, 2.0 * np.pi, n))
    xy_b = np.asarray(shape_b.xy)
    heights = np.einsum("nk,nkj->nj", u, rot_b[:, :, :2]) @ xy_b.T  # (N, n_b): u . (R_b [x, y, 0])
    vertex = np.argmin(heights, axis=1)
    v_rel = np.einsum("nij,nj->ni", rot_b[:, :, :2], xy_b[vertex])
    pos_b = s + gap[:, None] * u - v_rel
    pos_a = np.broadcast_to(pos_a1, (n, 3)).copy()
    rot_a = np.broadcast_to(rot_a1, (n, 3, 3)).copy()
    return NearContactPoses(pos_a, rot_a, pos_b, rot_b, gap, beta, u, vertex, hit, radius)


# ---------------------------------------------------------------------------
# the study
# ---------------------------------------------------------------------------


def _check_int(v, name, minimum):
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
        raise TypeError(f"{name} must be an integer, got {type(v).__name__}")
    if v < minimum:
        raise ValueError(f"{name} must be >= {minimum}, got {v}")
    return int(v)


def _check_positive(v, name):
    try:
        f = float(v)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a real number, got {type(v).__name__}") from None
    if not (math.isfinite(f) and f > 0):
        raise ValueError(f"{name} must be finite and > 0, got {v}")
    return f


@dataclass
class WorkPrecisionResult:
    """Everything one run of the study produced.

    Attributes
    ----------
    settings : dict
        Parameters of the run (radius, b's shape, vertex counts, N, repeats,
        seed, ranges, stand-in length, tolerances).
    rows : list of dict
        One row per method and n (``fcl_cylinder``: one row, ``n`` None);
        the columns of ``workprec.csv``.
    geometry : dict
        ``n``, ``abs_error``, ``rel_error`` arrays and the fitted ``order``
        and ``constant``.
    compile_s : dict
        First-call time (compile or cache load) per dtype and path, s.
    poses : NearContactPoses
        The poses every method saw, with exact labels.
    predictions : dict
        ``(method, n) -> (N,) bool`` reported hits (``n`` None for the cylinder).
    versions : dict
        Package versions (legends).
    """

    settings: dict
    rows: list
    geometry: dict
    compile_s: dict
    poses: NearContactPoses
    predictions: dict = field(default_factory=dict)
    versions: dict = field(default_factory=dict)

    def row(self, method, n=None):
        """The row of ``method`` at ``n`` (``n`` ignored for ``fcl_cylinder``)."""
        for r in self.rows:
            if r["method"] == method and (method == "fcl_cylinder" or r["n"] == n):
                return r
        raise KeyError(f"no row for method {method!r}, n={n}")


def method_labels(versions):
    """Legend text per method, naming versions."""
    pbv = versions.get("prismbatch") or "?"
    fv = versions.get("python-fcl") or "?"
    return {
        "pb64_batch": f"prismbatch {pbv} float64, batch call (1 thread)",
        "pb64_pair": f"prismbatch {pbv} float64, single query (collide_pair)",
        "pb32_batch": f"prismbatch {pbv} float32, batch call (1 thread)",
        "pb32_pair": f"prismbatch {pbv} float32, single query (collide_pair)",
        "fcl_ngon": f"python-fcl {fv} Convex n-gon prism (libccd GJK)",
        "fcl_cylinder": f"python-fcl {fv} Cylinder (exact shape, libccd GJK)",
    }


def _error_stats(pred, P, depth, tol):
    """Misclassification counts, rates and Wilson intervals against the exact labels."""
    N = len(P)
    r = P.radius
    hit = P.hit
    fn = hit & ~pred
    fp = ~hit & pred
    wrong = int(fn.sum() + fp.sum())
    nh, nm = int(hit.sum()), int((~hit).sum())
    lo, hi = wilson_interval(wrong, N)
    out = dict(n_queries=N, exact_hits=nh, exact_misses=nm, wrong=wrong, rate=wrong / N, ci_low=lo, ci_high=hi,
               fn=int(fn.sum()), fp=int(fp.sum()))
    for k, cnt, tot in (("fn", int(fn.sum()), nh), ("fp", int(fp.sum()), nm)):
        out[f"{k}_rate"] = cnt / tot if tot else math.nan
        out[f"{k}_ci_low"], out[f"{k}_ci_high"] = wilson_interval(cnt, tot) if tot else (math.nan, math.nan)
    out["max_fn_depth"] = float(np.max(-P.gap[fn])) / r if fn.any() else 0.0
    out["max_fp_gap"] = float(np.max(P.gap[fp])) / r if fp.any() else 0.0
    out["fn_beyond_tol"] = int(np.sum(fn & (depth > tol)))
    out["fp_beyond_tol"] = int(np.sum(fp & (P.gap > 2.0 * tol)))
    return out


def _timed_passes(fn, repeats, budget_s=_PASS_BUDGET_S):
    """Run ``fn()`` -> (seconds, hits) up to ``repeats`` times, stopping early once the passes so far
    took more than ``budget_s``; returns (times, hits of the first pass, all passes agree)."""
    times, first, same = [], None, True
    for _ in range(repeats):
        if times and sum(times) > budget_s:
            break
        t, h = fn()
        times.append(t)
        if first is None:
            first = h
        else:
            same &= bool(np.array_equal(first, h))
    return np.array(times), first, same


def run_work_precision(*, vertices=None, n_poses=None, radius=1.0, repeats=None, seed=0, quick=False,
                       progress=True, fcl=True):
    """Run the work-precision study (module docstring).

    Parameters
    ----------
    vertices : sequence of int, optional
        Vertex counts n of the cylinder's n-gon (each >= 3). Default
        :data:`DEFAULT_VERTICES` (8 .. 100000), quick :data:`QUICK_VERTICES`.
    n_poses : int, optional
        Number of near-contact pose pairs N (same for every method and n).
        Default 50000, quick 5000.
    radius : float, optional
        Cylinder radius r (b scales with it).
    repeats : int, optional
        Timed passes per method and n; the median is reported. Default 3,
        quick 2.
    seed : int, optional
        Seed of the pose generator.
    quick : bool, optional
        Smaller defaults (about a minute or less).
    progress : bool, optional
        Show a progress bar (needs tqdm).
    fcl : bool, optional
        Run the python-fcl rows (needs python-fcl); when False their times
        and errors are NaN.

    Returns
    -------
    WorkPrecisionResult
    """
    if vertices is None:
        vertices = QUICK_VERTICES if quick else DEFAULT_VERTICES
    try:
        verts = sorted({_check_int(v, "vertices", 3) for v in vertices})
    except TypeError as exc:
        raise TypeError(f"vertices must be a sequence of integers >= 3: {exc}") from None
    if not verts:
        raise ValueError("vertices must not be empty")
    n_poses = _check_int(QUICK_POSES if quick and n_poses is None else DEFAULT_POSES if n_poses is None
                         else n_poses, "n_poses", 2)
    repeats = _check_int(QUICK_REPEATS if quick and repeats is None else DEFAULT_REPEATS if repeats is None
                         else repeats, "repeats", 1)
    seed = _check_int(seed, "seed", 0)
    radius = _check_positive(radius, "radius")
    fcl_mod = None
    if fcl:
        try:
            import fcl as fcl_mod  # noqa: PLC0415
        except ImportError as exc:
            raise ImportError(_FCL_MISSING) from exc

    rng = np.random.default_rng(seed)
    shape_b = Prism.regular(B_VERTICES, B_SCALE * radius)
    P = near_contact_poses(n_poses, rng, radius=radius, shape_b=shape_b)
    versions = package_versions()
    labels = method_labels(versions)
    perf = time.perf_counter

    # poses per dtype, converted before any timing; per-pair views for the single-query loops
    arrays = {}
    items = {}
    for dt in (np.float64, np.float32):
        A = tuple(np.ascontiguousarray(x, dtype=dt) for x in (P.pos_a, P.rot_a, P.pos_b, P.rot_b))
        arrays[dt] = A
        items[dt] = [tuple(np.ascontiguousarray(x[k]) for x in A) for k in range(n_poses)]

    # compile (or cache load), excluded from the timings
    compile_s = {}
    probe = Prism.regular(verts[0], radius)
    for dt, tag in ((np.float64, "float64"), (np.float32, "float32")):
        col = Collider(probe, shape_b, dtype=dt)
        A = arrays[dt]
        t0 = perf()
        col.collide(*(x[:2] for x in A), parallel=False)
        compile_s[f"{tag}_batch"] = perf() - t0
        t0 = perf()
        col.collide_pair(*items[dt][0])
        compile_s[f"{tag}_pair"] = perf() - t0

    L = None
    fcl_items = None
    if fcl_mod is not None:
        from .peers import FCLCylinderPeer, FCLPeer, fcl_standin_length  # noqa: PLC0415

        L = max(fcl_standin_length(probe.xy, shape_b.xy, P.pos_a[k], P.pos_b[k]) for k in range(n_poses))
        fcl_items = FCLPeer.prepare(P.pos_a, P.rot_a, P.pos_b, P.rot_b)

    tol = {np.float64: None, np.float32: None}
    rows, preds = [], {}

    def add_row(method, n, times, hits, same, setup_s, depth, tol_m, geom_rel):
        stats = _error_stats(hits, P, depth, tol_m) if hits is not None else {}
        t_us = 1e6 * times / n_poses if times is not None else None
        row = dict(method=method, label=labels[method], shape="cylinder" if n is None else "n-gon", n=n,
                   geom_rel_error=geom_rel,
                   t_median_us=float(np.median(t_us)) if t_us is not None else math.nan,
                   t_min_us=float(np.min(t_us)) if t_us is not None else math.nan,
                   t_max_us=float(np.max(t_us)) if t_us is not None else math.nan,
                   passes=0 if times is None else len(times),
                   setup_ms=1e3 * setup_s if setup_s is not None else math.nan,
                   passes_agree=same)
        keys = ("n_queries", "exact_hits", "exact_misses", "wrong", "rate", "ci_low", "ci_high", "fn", "fn_rate",
                "fn_ci_low", "fn_ci_high", "fp", "fp_rate", "fp_ci_low", "fp_ci_high", "max_fn_depth",
                "max_fp_gap", "fn_beyond_tol", "fp_beyond_tol")
        for k in keys:
            row[k] = stats.get(k, math.nan)
        row["tolerance"] = float(np.median(tol_m)) / radius if np.ndim(tol_m) else float(tol_m) / radius
        rows.append(row)
        if hits is not None:
            preds[(method, n)] = hits

    bar = _progress(len(verts) + 1, enabled=progress, unit="n", desc="work-precision")
    with bar:
        for n in verts:
            bar.set_description(f"work-precision n={n}")
            geom_rel = float(geometric_error(n))
            depth = P.depth_in_ngon(shape_b, n)
            t0 = perf()
            shape_a = Prism.regular(n, radius)
            cols = {np.float64: Collider(shape_a, shape_b, dtype=np.float64),
                    np.float32: Collider(shape_a, shape_b, dtype=np.float32)}
            setup_pb = perf() - t0
            for dt, tag in ((np.float64, "pb64"), (np.float32, "pb32")):
                if tol[dt] is None:
                    tol[dt] = pair_scale_tolerance(shape_a, shape_b, P.pos_a, P.rot_a, P.pos_b, P.rot_b, dtype=dt)[1]
                col, A, its = cols[dt], arrays[dt], items[dt]

                def batch(col=col, A=A):
                    t = perf()
                    h = col.collide(*A, parallel=False).hit
                    return perf() - t, h

                def pair(col=col, its=its):
                    f = col.collide_pair
                    out = np.empty(len(its), dtype=bool)
                    t = perf()
                    for k, (pa, ra, pb_, rb) in enumerate(its):
                        out[k] = f(pa, ra, pb_, rb).hit
                    return perf() - t, out

                for kind, fn in (("batch", batch), ("pair", pair)):
                    times, h, same = _timed_passes(fn, repeats)
                    add_row(f"{tag}_{kind}", n, times, h, same, setup_pb, depth, tol[dt], geom_rel)
            if fcl_mod is not None:
                t0 = perf()
                peer = FCLPeer(shape_a.xy, shape_b.xy, L)
                setup = perf() - t0
                times, h, same = _timed_passes(lambda: _timed_run(peer, fcl_items), repeats)
                add_row("fcl_ngon", n, times, h, same, setup, depth, 0.0, geom_rel)
                del peer
            else:
                add_row("fcl_ngon", n, None, None, None, None, depth, 0.0, geom_rel)
            bar.update(1)
        # the exact-shape peer: does not depend on n
        depth_c = P.depth_in_cylinder(shape_b)
        if fcl_mod is not None:
            t0 = perf()
            peer = FCLCylinderPeer(radius, shape_b.xy, L)
            setup = perf() - t0
            cyl_items = peer.prepare(P.pos_a, P.rot_a, P.pos_b, P.rot_b)
            times, h, same = _timed_passes(lambda: _timed_run(peer, cyl_items), repeats)
            add_row("fcl_cylinder", None, times, h, same, setup, depth_c, 0.0, 0.0)
        else:
            add_row("fcl_cylinder", None, None, None, None, None, depth_c, 0.0, 0.0)
        bar.update(1)

    order = {m: i for i, m in enumerate(METHODS)}
    rows.sort(key=lambda r: (order[r["method"]], -1 if r["n"] is None else r["n"]))
    g_abs = geometric_error(np.array(verts), radius)
    p_ord, const = fit_order(verts, g_abs / radius)
    geometry = dict(n=np.array(verts), abs_error=g_abs, rel_error=g_abs / radius, order=p_ord, constant=const,
                    constant_theory=math.pi ** 2 / 2)
    settings = dict(
        radius=radius, shape_a=f"cylinder of radius {radius:g} as inscribed regular n-gon (vertex 0 on local +x)",
        shape_b=f"regular {B_VERTICES}-gon, circumradius {B_SCALE * radius:g} (the paper's hexagon scaled 2.5:2)",
        rot_a="diag(1, -1, -1) (axis down)", vertices=verts, n_poses=n_poses, repeats=repeats, seed=seed,
        quick=bool(quick), gap_range_rel=GAP_RANGE, beta_range_deg=BETA_RANGE_DEG, tilt_range_deg=TILT_RANGE_DEG,
        hit_fraction=0.5, exact_hits=int(P.hit.sum()), exact_misses=int((~P.hit).sum()),
        noise_floor=noise_floor(n_poses), fcl_standin_length=L, fcl=fcl_mod is not None,
        fcl_solver="python-fcl default CollisionRequest (GST_LIBCCD)",
        rtol={"float64": DEFAULT_RTOL[np.dtype(np.float64)], "float32": DEFAULT_RTOL[np.dtype(np.float32)]},
        median_tolerance_rel={"float64": float(np.median(tol[np.float64])) / radius,
                              "float32": float(np.median(tol[np.float32])) / radius},
        timing="median of repeats of a full pass over the N poses; compile time excluded",
    )
    return WorkPrecisionResult(settings, rows, geometry, compile_s, P, preds, versions)


def _timed_run(peer, its):
    t = time.perf_counter()
    h = peer.run(its)
    return time.perf_counter() - t, h


# ---------------------------------------------------------------------------
# reporting
# ---------------------------------------------------------------------------


def _g(x, fmt=".3g"):
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    return format(x, fmt)


def format_work_precision(result):
    """The study's summary as text lines.

    Parameters
    ----------
    result : WorkPrecisionResult

    Returns
    -------
    list of str
    """
    s, g = result.settings, result.geometry
    v = result.versions
    lines = [f"prismbatch {v.get('prismbatch')} work-precision study: a = semi-infinite cylinder r = {s['radius']:g} "
             f"as inscribed n-gon, b = {s['shape_b']}",
             f"   {s['n_poses']:,} near-contact poses (|gap|/r log-uniform {s['gap_range_rel'][0]:g}..."
             f"{s['gap_range_rel'][1]:g}; {s['exact_hits']:,} exact hits, {s['exact_misses']:,} exact misses), "
             f"seed {s['seed']}, median of {s['repeats']} pass(es); noise floor (95 % bound at 0 errors) "
             f"{s['noise_floor']:.2g}",
             f"geometric error r(1 - cos(pi/n)): fitted order {g['order']:.3f} (constant {g['constant']:.3f}, "
             f"theory 2 and pi^2/2 = {g['constant_theory']:.3f}); vertices needed for a relative error of "
             + ", ".join(f"{e:g}: {vertices_needed(e)}" for e in (1e-3, 1e-6, 1e-9)),
             "compile or cache load (excluded): " + ", ".join(f"{k} {t:.2f} s" for k, t in result.compile_s.items()),
             f"{'method':<13}{'n':>7}  {'us/query':>9}  {'misclass.':>9}  {'95% CI':>19}  {'missed hits':>11}  "
             f"{'false hits':>10}  {'max |g|/r wrong':>15}  beyond tol"]
    for r in result.rows:
        mx = max(r["max_fn_depth"], r["max_fp_gap"]) if math.isfinite(r["rate"]) else math.nan
        lines.append(f"{r['method']:<13}{'exact' if r['n'] is None else r['n']:>7}  {_g(r['t_median_us'], '9.2f')}  "
                     f"{_g(r['rate'], '9.2e')}  [{_g(r['ci_low'], '.2e')}, {_g(r['ci_high'], '.2e')}]  "
                     f"{_g(r['fn'], '11')}  {_g(r['fp'], '10')}  {_g(mx, '15.2e')}  "
                     f"{_g(r['fn_beyond_tol'], 'd') if math.isfinite(r['rate']) else '-'}/"
                     f"{_g(r['fp_beyond_tol'], 'd') if math.isfinite(r['rate']) else '-'}")
    lines.append("   (beyond tol: missed hits with b's vertex inside the method's polygon by more than its "
                 "tolerance / false hits farther than twice it; prismbatch tolerance median "
                 f"{s['median_tolerance_rel']['float64']:.1e} r (float64), "
                 f"{s['median_tolerance_rel']['float32']:.1e} r "
                 "(float32: its rtol 1e-5 reports near misses as hits); timings are noisy)")
    return lines


_CSV_COLS = ("method", "label", "shape", "n", "geom_rel_error", "t_median_us", "t_min_us", "t_max_us", "passes",
             "setup_ms", "n_queries", "exact_hits", "exact_misses", "wrong", "rate", "ci_low", "ci_high", "fn",
             "fn_rate", "fn_ci_low", "fn_ci_high", "fp", "fp_rate", "fp_ci_low", "fp_ci_high", "max_fn_depth",
             "max_fp_gap", "tolerance", "fn_beyond_tol", "fp_beyond_tol", "passes_agree")


def _csv_value(x):
    if x is None:
        return ""
    if isinstance(x, float):
        return "" if not math.isfinite(x) else repr(x)
    return x


def _markdown(result, figures):
    s, g = result.settings, result.geometry
    out = ["# Work-precision: a cylinder as an n-gon prism", "",
           f"a = semi-infinite cylinder of radius {s['radius']:g} (axis down), approximated by the regular n-gon "
           f"INSCRIBED in its circle; b = {s['shape_b']}. {s['n_poses']:,} near-contact poses with exact labels "
           f"(|gap|/r log-uniform in [{s['gap_range_rel'][0]:g}, {s['gap_range_rel'][1]:g}], half hits); the same "
           "poses for every method. Misclassification rate with Wilson 95 % intervals; Monte Carlo noise floor "
           f"(upper bound at zero errors) {s['noise_floor']:.2g}. Time per query: median of {s['repeats']} pass(es), "
           "compile excluded; timings are noisy (shared machine). See `prismbatch/workprec.py` for the construction.",
           "",
           f"Geometric error r(1 - cos(pi/n)): fitted order **{g['order']:.3f}** (constant {g['constant']:.3f}; "
           f"theory 2 and pi^2/2). Vertices needed: "
           + ", ".join(f"relative error {e:g} -> n = {vertices_needed(e)}" for e in (1e-3, 1e-6, 1e-9)) + ".", "",
           "float32 rows: float32 storage plus its default rtol 1e-5, which reports near misses within about "
           f"{s['median_tolerance_rel']['float32']:.1e} r as hits (safe side); they are counted as misclassifications. "
           "`beyond tol` counts the errors the method's tolerance does not explain (missed hits with b's vertex "
           "inside the method's polygon by more than its tolerance / false hits farther than twice it).", "",
           "| method | n | µs/query (min-max) | misclassified | 95 % CI | missed hits | false hits | beyond tol |",
           "|---|---|---|---|---|---|---|---|"]
    for r in result.rows:
        if not math.isfinite(r["rate"]):
            out.append(f"| {r['label']} | {r['n'] or 'exact'} | - | - | - | - | - | - |")
            continue
        out.append(f"| {r['label']} | {'exact' if r['n'] is None else r['n']} | {r['t_median_us']:.2f} "
                   f"({r['t_min_us']:.2f}-{r['t_max_us']:.2f}) | {r['rate']:.2e} | "
                   f"[{r['ci_low']:.1e}, {r['ci_high']:.1e}] | {r['fn']} | {r['fp']} | "
                   f"{r['fn_beyond_tol']} / {r['fp_beyond_tol']} |")
    out += ["", "Compile or cache load (excluded): "
            + ", ".join(f"{k} {t:.2f} s" for k, t in result.compile_s.items()) + "."]
    if figures:
        out += [""] + [f"![{Path(f).stem}]({Path(f).name})" for f in figures if f.endswith(".png")]
    return "\n".join(out) + "\n"


def write_work_precision(result, out_dir, *, figures=True):
    """Write the study's files.

    Parameters
    ----------
    result : WorkPrecisionResult
    out_dir : str or path-like
        Folder (created if needed).
    figures : bool, optional
        Also draw the figures (needs matplotlib).

    Returns
    -------
    dict
        Paths: ``csv``, ``geometry_csv``, ``json``, ``markdown`` (str) and
        ``figures`` (list of str; empty when ``figures`` is False).
    """
    if not isinstance(result, WorkPrecisionResult):
        raise TypeError(f"result must be a WorkPrecisionResult, got {type(result).__name__}")
    out = Path(out_dir)
    paths = {}
    paths["csv"] = write_csv(out / "workprec.csv", _CSV_COLS,
                             [[_csv_value(r[c]) for c in _CSV_COLS] for r in result.rows])
    g = result.geometry
    p_ord, const = g["order"], g["constant"]
    paths["geometry_csv"] = write_csv(
        out / "workprec_geometry.csv", ("n", "radius", "abs_error", "rel_error", "fit_rel_error"),
        [[int(n), result.settings["radius"], repr(float(a)), repr(float(e)), repr(float(const * n ** -p_ord))]
         for n, a, e in zip(g["n"], g["abs_error"], g["rel_error"])])
    fig_files = plot_work_precision(result, out) if figures else []
    meta = run_metadata(study="work_precision", settings=result.settings,
                        seeds={"poses": result.settings["seed"]},
                        fitted_order=g["order"], fitted_constant=g["constant"], compile_s=result.compile_s,
                        vertices_needed={str(e): vertices_needed(e) for e in (1e-3, 1e-6, 1e-9)},
                        rows=result.rows, files=[Path(f).name for f in fig_files])
    paths["json"] = write_json(out / "workprec.json", meta)
    md = out / "workprec.md"
    md.write_text(_markdown(result, fig_files), encoding="utf-8")
    paths["markdown"] = str(md)
    paths["figures"] = fig_files
    return paths


# ---------------------------------------------------------------------------
# figures
# ---------------------------------------------------------------------------

_STYLE = {  # colour, marker, linestyle
    "pb64_batch": ("tab:blue", "o", "-"),
    "pb64_pair": ("tab:blue", "s", "--"),
    "pb32_batch": ("tab:green", "o", "-"),
    "pb32_pair": ("tab:green", "s", "--"),
    "fcl_ngon": ("tab:red", "d", "-"),
    "fcl_cylinder": ("black", "*", "none"),
}


def _series(result, method):
    return [r for r in result.rows if r["method"] == method and math.isfinite(r["rate"])]


def _same_labels(result, m1, m2):
    """True when two methods reported identical hits at every n (then one curve is drawn)."""
    keys = [k for k in result.predictions if k[0] == m1]
    return bool(keys) and all((m2, k[1]) in result.predictions
                              and np.array_equal(result.predictions[k], result.predictions[(m2, k[1])])
                              for k in keys)


def _draw_rates(ax, xs, rows, method, floor, label, y_min):
    """Rates with Wilson error bars; zero-error points at their upper bound as open down-triangles."""
    col, mk, ls = _STYLE[method]
    xs = np.asarray(xs, dtype=float)
    rate = np.array([r["rate"] for r in rows])
    lo = np.array([r["ci_low"] for r in rows])
    hi = np.array([r["ci_high"] for r in rows])
    pos = rate > 0
    if len(xs) > 1:
        ax.plot(xs, np.where(pos, rate, hi), color=col, linestyle=ls, linewidth=1.2, alpha=0.8)
    handle = None
    if pos.any():
        handle = ax.errorbar(xs[pos], rate[pos], yerr=[rate[pos] - np.maximum(lo[pos], y_min), hi[pos] - rate[pos]],
                             fmt=mk, color=col, markersize=9 if mk == "*" else 5, capsize=2, linestyle="none",
                             label=label)
    if (~pos).any():
        h = ax.plot(xs[~pos], hi[~pos], marker="v", markerfacecolor="none", color=col, linestyle="none",
                    markersize=6, label=None if pos.any() else label)[0]
        handle = handle or h
    return handle


def _sparse_labels(pts, min_dec=0.14, column=False):
    """n labels for points (x, y, n) along a curve, without overlapping text.

    Points at the same height (zero-error points at their bound) share one
    label "n1-n2"; a label closer than ``min_dec`` decades in y (and 0.4 in x,
    unless the labels go in one ``column``) to the last one drawn is left out.
    """
    groups = []
    for x, y, n in pts:
        if groups and y == groups[-1][1]:
            groups[-1][2].append(n)
        else:
            groups.append([x, y, [n]])
    out, last = [], None
    for x, y, ns in groups:
        lx, ly = math.log10(x), math.log10(y)
        if last is not None and abs(ly - last[1]) < min_dec and (column or abs(lx - last[0]) < 0.4):
            continue
        out.append((x, y, f"{ns[0]}" if len(ns) == 1 else f"{ns[0]}-{ns[-1]}"))
        last = (lx, ly)
    return out


def _legend_below(fig, axes, ncol=2):
    handles, labels = [], []
    for ax in axes:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    fig.legend(handles, labels, loc="outside lower center", ncol=ncol, fontsize=8, frameon=False)


def plot_work_precision(result, out_dir, *, stem="workprec"):
    """Draw the study's figures.

    Parameters
    ----------
    result : WorkPrecisionResult
    out_dir : str or path-like
    stem : str, optional
        File name prefix.

    Returns
    -------
    list of str
        ``{stem}_error_vs_time`` and ``{stem}_error_vs_n``, PNG and SVG.
    """
    from .report import cpu_name  # noqa: PLC0415

    labels = method_labels(result.versions)
    s = result.settings
    floor = s["noise_floor"]
    N = s["n_poses"]
    files = []
    rate_rows = [r for r in result.rows if math.isfinite(r["rate"])]
    y_min = min([floor] + [r["ci_low"] for r in rate_rows if r["rate"] > 0]) / 3.0
    floor_label = f"Monte Carlo noise floor: 95 % upper bound at 0 errors, N = {N:,}"
    zero_label = "open down-triangle: no error seen (drawn at its 95 % upper bound)"
    cyl = _series(result, "fcl_cylinder")

    # --- work-precision diagram ---
    fig = new_figure(figsize=(13.5, 7.4), layout="constrained")
    ax1, ax2 = fig.subplots(1, 2)
    for m in METHODS:
        rows = _series(result, m)
        if not rows:
            continue
        _draw_rates(ax1, [r["t_median_us"] for r in rows], rows, m, floor, labels[m], y_min)
        if m != "fcl_cylinder":
            c, mk, ls = _STYLE[m]
            ax2.plot([r["t_median_us"] for r in rows], [r["geom_rel_error"] for r in rows], color=c, marker=mk,
                     linestyle=ls, label=labels[m], markersize=5)
    ax1.axhline(floor, color="0.4", linestyle=":", linewidth=1.2, label=floor_label)
    ax1.plot([], [], marker="v", markerfacecolor="none", color="0.3", linestyle="none", label=zero_label)
    # n along the FCL n-gon curve (right of its points) and prismbatch float64 batch (left of its points)
    for ax, key in ((ax1, "rate"), (ax2, "geom_rel_error")):
        # prismbatch's points crowd together: its labels go in a column left of all its points
        pb_left = min([r["t_median_us"] for r in rate_rows if r["method"].startswith("pb")] or [1.0])
        for m, off, ha, va in (("fcl_ngon", (3, 6), "left", "bottom"), ("pb64_batch", (-7, 0), "right", "center")):
            pts = [(r["t_median_us"], r[key] if r[key] > 0 else r["ci_high"], r["n"]) for r in _series(result, m)]
            for x, y, text in _sparse_labels(pts, column=m == "pb64_batch"):
                ax.annotate(text, (pb_left if m == "pb64_batch" else x, y), textcoords="offset points", xytext=off,
                            ha=ha, va=va, fontsize=7, color=_STYLE[m][0])
    if cyl:
        ax2.axvline(cyl[0]["t_median_us"], color="black", linestyle="-.", linewidth=1,
                    label=labels["fcl_cylinder"] + ": its time (no geometric error)")
    for ax in (ax1, ax2):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("time per query (µs; median of passes, one thread; log scale)")
        ax.grid(True, which="both", alpha=0.3)
        lo, hi = ax.get_xlim()
        ax.set_xlim(lo / 2.5, hi * 1.6)  # room for the n labels
    ax1.set_ylim(bottom=y_min, top=1.0)
    ax1.set_ylabel("misclassification rate against the exact cylinder (log scale)")
    ax1.set_title("(a) misclassified near-contact poses (95 % Wilson intervals; numbers: n)", fontsize=10)
    ax2.set_ylabel("geometric error 1 - cos(π/n) = radial deficit / r (log scale)")
    ax2.set_title("(b) geometric error of the inscribed n-gon (numbers: n)", fontsize=10)
    _legend_below(fig, (ax1, ax2))
    fig.suptitle(f"Work-precision: semi-infinite cylinder (r = {s['radius']:g}) as an n-gon prism against a "
                 f"hexagonal prism; {N:,} near-contact poses; {cpu_name()} (shared, timings noisy)", fontsize=11)
    files += save_figure(fig, out_dir, f"{stem}_error_vs_time")

    # --- error against n ---
    fig = new_figure(figsize=(13.5, 7.0), layout="constrained")
    ax1, ax2 = fig.subplots(1, 2)
    g = result.geometry
    nn = np.asarray(g["n"], dtype=float)
    ax1.plot(nn, g["rel_error"], "ko", label="geometric error 1 - cos(π/n) of the inscribed n-gon")
    nf = np.geomspace(nn.min(), nn.max(), 100)
    ax1.plot(nf, g["constant"] * nf ** -g["order"], "k--", linewidth=1,
             label=f"least-squares fit {g['constant']:.3f} n^-{g['order']:.3f} (fitted order {g['order']:.3f})")
    for m in ("pb64_batch", "fcl_ngon"):
        rows = [r for r in _series(result, m) if r["fn"] > 0]
        if rows:
            c, mk, _ = _STYLE[m]
            ax1.plot([r["n"] for r in rows], [r["max_fn_depth"] for r in rows], color=c, marker=mk,
                     linestyle="none", markerfacecolor="none", markersize=8 if m == "pb64_batch" else 6,
                     label=f"deepest missed hit, |gap| / r: {labels[m]}")
    if cyl and cyl[0]["fn"] > 0:
        ax1.axhline(cyl[0]["max_fn_depth"], color="black", linestyle="-.", linewidth=1,
                    label=f"deepest missed hit, |gap| / r: {labels['fcl_cylinder']}")
    ax1.axhline(s["gap_range_rel"][0], color="0.4", linestyle=":",
                label=f"smallest |gap| / r sampled ({s['gap_range_rel'][0]:g})")
    ax1.set_ylabel("length / r (log scale)")
    ax1.set_title("(a) geometric error and the deepest overlap each method missed", fontsize=10)
    ident = []
    for m in METHODS:
        rows = _series(result, m)
        if not rows or m == "fcl_cylinder":
            continue
        if m.endswith("_pair") and _same_labels(result, m.replace("_pair", "_batch"), m):
            ident.append(m)
            continue  # identical to the batch call: drawn once
        lab = labels[m]
        if m.endswith("_batch") and _same_labels(result, m, m.replace("_batch", "_pair")):
            lab = lab.replace("batch call (1 thread)", "batch call and collide_pair (identical labels)")
        _draw_rates(ax2, [r["n"] for r in rows], rows, m, floor, lab, y_min)
    if cyl:
        r = cyl[0]
        ax2.axhspan(max(r["ci_low"], y_min), r["ci_high"], color="0.8", alpha=0.6)
        ax2.axhline(r["rate"] if r["rate"] > 0 else r["ci_high"], color="black", linestyle="-.", linewidth=1,
                    label=labels["fcl_cylinder"] + " (no n; grey band: 95 % CI)")
    ax2.axhline(floor, color="0.4", linestyle=":", label=floor_label)
    ax2.plot([], [], marker="v", markerfacecolor="none", color="0.3", linestyle="none", label=zero_label)
    ax2.set_ylim(bottom=y_min, top=1.0)
    ax2.set_ylabel("misclassification rate against the exact cylinder (log scale)")
    ax2.set_title("(b) misclassification rate (95 % Wilson intervals)", fontsize=10)
    for ax in (ax1, ax2):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("vertices n of the cylinder's inscribed n-gon (log scale)")
        ax.grid(True, which="both", alpha=0.3)
    _legend_below(fig, (ax1, ax2))
    fig.suptitle(f"Error against n: semi-infinite cylinder (r = {s['radius']:g}) as an inscribed n-gon prism, "
                 f"{N:,} near-contact poses (|gap| / r log-uniform in [{s['gap_range_rel'][0]:g}, "
                 f"{s['gap_range_rel'][1]:g}])", fontsize=11)
    files += save_figure(fig, out_dir, f"{stem}_error_vs_n")
    return files
