"""Importance sampling for :func:`~prismbatch.probability.collision_probability`.

Three parts, all in the standard-normal coordinates ``z`` of the noise (``x = L z``):

- the search for the most likely colliding noise values (design points): damped
  Hasofer-Lind steps on a linearisation the caller supplies, from the nominal pose, from
  both directions of every noise axis (as far out as the caller's linear estimate of the
  boundary) and from random antithetic pairs;
- the defensive mixture proposal about the design points found (its centres and weights; the
  draws and their log weights ``log phi(z) / q(z)`` are made in the compiled sampling loop,
  :func:`prismbatch._kernels.probability.count_serial`);
- :class:`Tally`, the running sums of one estimate and its interval: Wilson's for plain
  sampling, Hall's skewness-corrected one for weighted samples (:func:`hall_interval`).

Components of ``z`` that move nothing (zero columns of ``L``, e.g. a singular covariance)
are drawn from the nominal ``N(0, 1)`` by the proposal too, so they add no variance to the
weights and no start to the search.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "DEFENSIVE",
    "SPREAD",
    "DESIGN_STEPS",
    "DESIGN_PAIRS",
    "design_starts",
    "design_points",
    "centres",
    "hall_interval",
    "wilson",
    "Tally",
]

#: Weight of the nominal distribution in the mixture (bounds the weights by 1 / DEFENSIVE).
DEFENSIVE = 0.1
#: Standard deviation of the mixture's components about their centres (> 1 reaches the parts
#: of a curved collision region between the centres and missed ones; 1.5 needed 1.7-4.2 times
#: the samples for the same coverage, 1.0 lost coverage where a design point was missed).
SPREAD = 1.2
#: Hasofer-Lind steps towards the most likely colliding pose (each one batch distance call).
DESIGN_STEPS = 12
#: Random antithetic pairs of starts of the search, besides the nominal pose and both
#: directions of every noise axis.
DESIGN_PAIRS = 2
_MERGE = 1.0  # design points closer than this (standard deviations) are one centre
_KEEP = 2 * math.log(1e3)  # centres less likely than 1e-3 times the likeliest are dropped
_ON_BOUNDARY = 0.1  # a search ending further from the boundary (standard deviations) found nothing


def design_starts(active, rng, reach=1.0):
    """Starts of the search for one query: ``(S, k)``.

    The nominal pose, ``reach`` standard deviations along both directions of every active
    noise axis, and :data:`DESIGN_PAIRS` random directions one standard deviation out with
    their opposites (drawn from ``rng``). Where the nominal pose is symmetric (parallel faces)
    the distance has a kink, its gradient there sees no rotation, and there is one design
    point per corner that a tilt lowers: the nominal start alone finds none of them, random
    starts miss some (an undercovering, skewed estimate), and the axis pairs reach every
    corner of a square or a triangle. ``reach`` (the caller's linear estimate of the distance
    to the boundary, clipped to [1, 5]) puts the axis starts where a tilt can outweigh a
    nominal one: on a square tilted by 1.5 standard deviations, every search from one standard
    deviation ended at its lowest corner.
    """
    k = len(active)
    axes = reach * np.eye(k)[active]
    u = rng.standard_normal((DESIGN_PAIRS, k)) * active
    u /= np.maximum(np.linalg.norm(u, axis=1, keepdims=True), 1e-300)
    return np.concatenate((np.zeros((1, k)), axes, -axes, u, -u))


def design_points(linearise, z):
    """Hasofer-Lind searches from the starts ``z`` (m, k).

    ``linearise(z)`` returns the signed distance ``d`` (m,) and its gradient ``g`` (m, k) in
    ``z``. Steps go towards the linearised boundary, damped by halving where a step does not
    lower the merit ``|z|^2 / 2 + c |d|`` (``c = 2 max(|z|, |target|) / |g|``; the improved
    HL-RF of Zhang and Der Kiureghian): plain steps oscillate where rotations make the distance
    strongly nonlinear. Returns the end points and their distance over ``|gradient|`` (the
    remaining step, in standard deviations).
    """
    lam = np.ones(len(z))
    d, g = linearise(z)
    for _ in range(DESIGN_STEPS - 1):
        gg = np.einsum("ni,ni->n", g, g)
        ok = gg > 0
        t = np.where(ok, (np.einsum("ni,ni->n", g, z) - d) / np.where(ok, gg, 1.0), 0.0)
        target = t[:, None] * g
        cand = z + lam[:, None] * (target - z)
        dc, gc = linearise(cand)
        c = 2 * np.maximum(np.linalg.norm(z, axis=1), np.linalg.norm(target, axis=1)) / np.sqrt(np.where(ok, gg, 1))
        better = ok & (0.5 * (cand * cand).sum(1) + c * np.abs(dc) < 0.5 * (z * z).sum(1) + c * np.abs(d))
        z, d, g = np.where(better[:, None], cand, z), np.where(better, dc, d), np.where(better[:, None], gc, g)
        lam = np.where(better, 1.0, 0.5 * lam)
    gn = np.linalg.norm(g, axis=1)
    return z, np.where(gn > 0, np.abs(d) / np.where(gn > 0, gn, 1.0), np.inf)


def centres(z, miss, active):
    """The mixture's centres from one query's search ends: ``(mu (J, k), log weights (J,))``.

    Ends that reached the boundary (to within 0.1 standard deviations) are merged when closer
    than one standard deviation; those within a factor 1e-3 of the likeliest are kept,
    weighted by ``exp(-beta^2 / 2)``. With no end on the boundary, the first (the nominal
    start's) is the centre.
    """
    on = miss <= _ON_BOUNDARY
    cand = (z[on] if on.any() else z[:1]) * active
    b = np.linalg.norm(cand, axis=1)
    kept = []
    for r in np.argsort(b, kind="stable"):
        if b[r] ** 2 - b.min() ** 2 > _KEEP:
            break
        if all(np.linalg.norm(cand[r] - cand[q]) > _MERGE for q in kept):
            kept.append(r)
    lw = -0.5 * b[kept] ** 2
    return cand[kept], lw - np.logaddexp.reduce(lw)


def wilson(hits, n, z):
    """Wilson score interval ``(low, high)`` of ``hits`` successes in ``n`` trials (arrays; ``(0, 1)`` where
    ``n == 0``: no trials say nothing)."""
    hits, n = np.asarray(hits, dtype=np.float64), np.asarray(n, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        p = hits / n
        den = 1.0 + z * z / n
        mid = (p + z * z / (2 * n)) / den
        half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
        # exact at the ends (rounding would leave low a hair above 0 for no hits, high below 1 for all),
        # and containing p after rounding
        low = np.where(hits == 0, 0.0, np.minimum(np.clip(mid - half, 0.0, 1.0), p))
        return low, np.where(hits == n, 1.0, np.maximum(np.clip(mid + half, 0.0, 1.0), p))


def hall_interval(mean, se, skew, z):
    """Hall's skewness-corrected interval ``(low, high)`` for a mean.

    ``se`` is the mean's standard error and ``skew`` its skewness (the samples' skewness over
    ``sqrt(n)``). The studentised mean ``T`` is skewed against the samples (low estimates come
    with low variance estimates); ``g(T) = T + a T^2 + a^2 T^3 / 3 + b`` with ``a = skew / 3``,
    ``b = skew / 6`` is normal to second order and monotone (Hall 1992, J. R. Stat. Soc. B 54,
    221-228), so ``mean - g^-1(+-z) se`` are the ends. ``skew = 0`` gives the normal interval.
    """
    a, b = skew / 3, skew / 6
    if abs(a) < 1e-12:
        return mean - (z - b) * se, mean + (z + b) * se

    def inv(x):  # g^-1
        return (np.cbrt(1 + 3 * a * (x - b)) - 1) / a

    return min(mean - inv(z) * se, mean), max(mean - inv(-z) * se, mean)


class Tally:
    """Running count, hits and shifted power sums of the hits' weights ``w = exp(lw)`` of one estimate.

    Sums are of ``exp(lw - shift)`` with a running ``shift`` (the largest log weight so far), so
    probabilities far below 1e-300 keep their relative error.
    """

    def __init__(self):
        self.n, self.hits, self.shift, self.s1, self.s2, self.s3 = 0, 0, -math.inf, 0.0, 0.0, 0.0

    def add_sums(self, m, hits, shift, s1, s2, s3):
        """Count ``m`` samples of which ``hits`` hit, the hits' log weights ``lw`` giving
        ``s_p = sum exp(p (lw - shift))`` for p = 1, 2, 3."""
        self.n += m
        self.hits += hits
        if hits:
            top = max(self.shift, shift)
            old, new = math.exp(self.shift - top), math.exp(shift - top)
            self.s1 = self.s1 * old + s1 * new
            self.s2 = self.s2 * old**2 + s2 * new**2
            self.s3 = self.s3 * old**3 + s3 * new**3
            self.shift = top

    def _moments(self):
        """Mean, its standard error and its skewness, of the shifted weights (n > 0, a hit)."""
        n = self.n
        mean = self.s1 / n
        m2 = max(self.s2 / n - mean * mean, 0.0)
        se = math.sqrt(m2 / max(n - 1, 1))
        if m2 <= 0.0:
            return mean, se, 0.0
        m3 = self.s3 / n - 3 * mean * self.s2 / n + 2 * mean**3
        return mean, se, m3 / m2**1.5 / math.sqrt(n)

    def _ends(self, z):
        mean, se, skew = self._moments()
        return (mean, *hall_interval(mean, se, skew, z))

    def relative_half_width(self, z, normal=False):
        """Half-width of the weighted interval over the estimate (inf with no hit); ``normal``: of
        the uncorrected normal interval (the pilot sizes the estimate with it: a few hits make a
        noisy skewness). Unweighted tallies: :func:`plain_intervals`."""
        if self.hits == 0:
            return math.inf
        if normal:
            mean, se, _ = self._moments()
            return z * se / mean
        mean, lo, hi = self._ends(z)
        return (hi - lo) / 2 / mean

    def log_high(self, z):
        """Logarithm of the weighted interval's upper end (0, i.e. 1, with no hit)."""
        if self.hits == 0:
            return 0.0
        return self.shift + math.log(self._ends(z)[2])

    def interval(self, z):
        """``(p, low, high)`` of the weighted estimate (unweighted tallies: :func:`plain_intervals`)."""
        n = self.n
        if self.hits == 0:  # P_q(hit) >= DEFENSIVE p: the Wilson bound of the hit rate, over DEFENSIVE
            return 0.0, 0.0, min(1.0, float(wilson(0, n, z)[1]) / DEFENSIVE)
        mean, lo, hi = self._ends(z)
        at = lambda v: math.exp(self.shift + math.log(v)) if v > 0 else 0.0  # noqa: E731
        # an upper end below the smallest float64 is rounded up to it (it stays an upper bound)
        return at(mean), at(lo), min(1.0, max(at(hi), math.ulp(0.0)))


def plain_intervals(tallies, z):
    """``(p, low, high, relative half-width)``, arrays over unweighted tallies: their Wilson
    intervals in one NumPy call (one call a query cost some 20 us, a tenth of the sampling time
    of 256 queries). The half-width is inf for a tally with no hit."""
    hits = np.array([t.hits for t in tallies], dtype=np.float64)
    n = np.array([t.n for t in tallies], dtype=np.float64)
    low, high = wilson(hits, n, z)
    p = hits / n
    with np.errstate(divide="ignore", invalid="ignore"):
        return p, low, high, np.where(hits > 0, (high - low) / 2 / p, np.inf)
