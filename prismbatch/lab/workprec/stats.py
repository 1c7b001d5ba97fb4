"""Statistics of the work-precision study: Wilson intervals, the noise floor, the fitted order and
the misclassification counts of one method against the exact labels."""

from __future__ import annotations

import math

import numpy as np

from ...importance import wilson

Z95 = 1.959963984540054  # two-sided 95 % normal quantile


def wilson_interval(k, n, z=Z95):
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
    lo, hi = wilson(k, n, z)
    if lo.ndim == 0:
        return float(lo), float(hi)
    return lo, hi


def noise_floor(n, z=Z95):
    """Monte Carlo noise floor: the Wilson upper bound at zero errors, ``z^2 / (n + z^2)``.

    Parameters
    ----------
    n : int
        Number of trials (> 0).
    z : float, optional
        Normal quantile (default: two-sided 95 %).

    Returns
    -------
    float
    """
    n = float(n)
    if not n > 0:
        raise ValueError(f"n must be > 0, got {n}")
    return z * z / (n + z * z)


def fit_order(n, err):
    """Least-squares fit ``log err = log C - p log n``; returns ``(p, C)`` (order and constant).

    Parameters
    ----------
    n, err : array_like
        At least two points (both > 0).

    Returns
    -------
    (float, float)
    """
    x, y = np.log(np.asarray(n, dtype=float)), np.log(np.asarray(err, dtype=float))
    if x.size < 2:
        raise ValueError("fit_order needs at least two points")
    slope, icpt = np.polyfit(x, y, 1)
    return float(-slope), float(math.exp(icpt))


def error_stats(pred, P, depth, tol):
    """Misclassification counts, rates and Wilson intervals of reported hits ``pred`` against the
    exact labels of the poses ``P``; ``depth`` and ``tol`` give the errors the tolerance explains."""
    N = len(P)
    r = P.radius
    hit = P.hit
    fn = hit & ~pred
    fp = ~hit & pred
    wrong = int(fn.sum() + fp.sum())
    nh, nm = int(hit.sum()), int((~hit).sum())
    lo, hi = wilson_interval(wrong, N)
    out = dict(
        n_queries=N,
        exact_hits=nh,
        exact_misses=nm,
        wrong=wrong,
        rate=wrong / N,
        ci_low=lo,
        ci_high=hi,
        fn=int(fn.sum()),
        fp=int(fp.sum()),
    )
    for k, cnt, tot in (("fn", int(fn.sum()), nh), ("fp", int(fp.sum()), nm)):
        out[f"{k}_rate"] = cnt / tot if tot else math.nan
        out[f"{k}_ci_low"], out[f"{k}_ci_high"] = wilson_interval(cnt, tot) if tot else (math.nan, math.nan)
    out["max_fn_depth"] = float(np.max(-P.gap[fn])) / r if fn.any() else 0.0
    out["max_fp_gap"] = float(np.max(P.gap[fp])) / r if fp.any() else 0.0
    out["fn_beyond_tol"] = int(np.sum(fn & (depth > tol)))
    out["fp_beyond_tol"] = int(np.sum(fp & (P.gap > 2.0 * tol)))
    return out
