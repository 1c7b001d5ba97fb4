"""What the study derives from its latency rows: the growth fits (Fig. 7c) and Table I."""

from __future__ import annotations

import math

import numpy as np

from .constants import METHODS, PAPER_CASES, PAPER_TABLE1_MS, PEERS

#: A straight line's slope counts as "growth per 1000 vertices" (and slopes are compared between
#: methods) only where the line explains the times at least this well; a cost that grows like log n
#: gives a line of low r², whose slope can even come out negative.
LINEAR_R2_MIN = 0.9


def _line_fit(x, t):
    """Least-squares ``t = b0 + b1 x``: ``(b1, b0, r2)``, r2 NaN if the times are all equal."""
    A = np.column_stack([np.ones_like(x), x])
    (b0, b1), *_ = np.linalg.lstsq(A, t, rcond=None)
    ss_res = float(np.sum((t - (b0 + b1 * x)) ** 2))
    ss_tot = float(np.sum((t - t.mean()) ** 2))
    return float(b1), float(b0), (1.0 - ss_res / ss_tot if ss_tot > 0 else math.nan)


def _checked_series(vertices, times):
    n = np.asarray(vertices, dtype=float).ravel()
    t = np.asarray(times, dtype=float).ravel()
    if n.shape != t.shape:
        raise ValueError(f"vertices and times must have the same length, got {n.size} and {t.size}")
    if not (np.isfinite(n).all() and np.isfinite(t).all()):
        raise ValueError("vertices and times must be finite")
    if np.unique(n).size < 2:
        raise ValueError("fit_growth needs at least two distinct vertex counts")
    if (n <= 0).any():
        raise ValueError("vertex counts must be positive")
    return n, t


def fit_growth(vertices, times):
    """Least-squares line ``t = intercept + slope * n``.

    Parameters
    ----------
    vertices : array_like, shape (k,)
        Vertex counts n (at least two distinct values).
    times : array_like, shape (k,)
        Times per query (any unit) at those counts.

    Returns
    -------
    slope_per_1000 : float
        Growth per 1000 vertices, in the unit of ``times``.
    intercept : float
        Fitted time at n = 0, same unit.
    r2 : float
        Coefficient of determination (NaN if the times are all equal).

    Raises
    ------
    ValueError
        Fewer than two distinct vertex counts, mismatched lengths or
        non-finite values.
    """
    n, t = _checked_series(vertices, times)
    slope, icpt, r2 = _line_fit(n, t)
    return slope * 1000.0, icpt, r2


def fit_log_growth(vertices, times):
    """Least-squares ``t = intercept + slope * log2(n)``: the model of an O(log n) search.

    Returns
    -------
    slope_per_doubling : float
        Growth each time n doubles, in the unit of ``times``.
    intercept : float
        Fitted time at n = 1.
    r2 : float
        Coefficient of determination (NaN if the times are all equal).
    """
    n, t = _checked_series(vertices, times)
    return _line_fit(np.log2(n), t)


def average_series(res, method, cases):
    """{n: mean over ``cases`` of the median µs}, only for n where every one of them was measured."""
    out = {}
    for n in res.settings["vertices"]:
        v = [res.latency_us(method, c, n) for c in cases]
        if v and all(x is not None for x in v):
            out[n] = float(np.mean(v))
    return out


def _avg_cases(res):
    """Cases of the average: the paper's 1-9 among those timed at every vertex count."""
    ok = [
        c
        for c in res.settings["cases"]
        if all(res.latency_us("prismbatch", c, n) is not None for n in res.settings["vertices"])
    ]
    paper = [c for c in ok if c in PAPER_CASES]
    return paper or ok


def growth_rows(res):
    """Growth fits per (method, series): each case and the average over cases (``StudyResult.growth``)."""
    rows = []
    series = {}
    avg_cases = _avg_cases(res)
    for method in res.methods:
        for case in res.settings["cases"]:
            pts = {r["vertices"]: r["median_us"] for r in res.latency if r["method"] == method and r["case"] == case}
            series[(method, f"case {case}")] = pts
        series[(method, "average")] = average_series(res, method, avg_cases)
    fits = {}
    for key, pts in series.items():
        if len(pts) >= 2:
            fits[key] = (fit_growth(list(pts), list(pts.values())), fit_log_growth(list(pts), list(pts.values())), pts)
    for (method, name), ((slope, icpt, r2), (lslope, licpt, lr2), pts) in fits.items():
        ns = sorted(pts)
        row = {
            "method": method,
            "series": name,
            "slope_us_per_1000": slope,
            "intercept_us": icpt,
            "r2": r2,
            "log_slope_us_per_doubling": lslope,
            "log_intercept_us": licpt,
            "r2_log": lr2,
            # the model that explains the times better (NaN r2, flat times: the line)
            "model": "log" if lr2 > r2 else "linear",
            "growth_factor": pts[ns[-1]] / pts[ns[0]] if pts[ns[0]] > 0 else None,
            "points": len(pts),
            "cases": ",".join(map(str, avg_cases)) if name == "average" else name[5:],
            "slope_ratio_vs_fcl": None,
            "slope_ratio_vs_coal": None,
        }
        for peer in PEERS:
            other = fits.get((peer, name))
            # Slopes compare only where both are lines that hold (see LINEAR_R2_MIN).
            if other is not None and other[0][0] > 0 and min(r2, other[0][2]) >= LINEAR_R2_MIN:
                row[f"slope_ratio_vs_{peer}"] = slope / other[0][0]
        rows.append(row)
    return rows


def growth_model_text(g):
    """The fitted model of a growth row in words, e.g. "+0.21 µs per doubling of n (log fit, r² 0.97)"."""
    best = max((r for r in (g["r2"], g["r2_log"]) if r == r), default=math.nan)
    if not best >= LINEAR_R2_MIN:  # neither model holds: the times do not trend beyond their noise
        return f"no trend beyond the noise (best r² {'-' if best != best else f'{best:.2f}'})"
    if g["model"] == "log":
        return f"{g['log_slope_us_per_doubling']:+.3g} µs per doubling of n (log fit, r² {g['r2_log']:.2f})"
    r2 = "-" if g["r2"] != g["r2"] else f"{g['r2']:.2f}"
    return f"{g['slope_us_per_1000']:+.3g} µs / 1000 vertices (line, r² {r2})"


def growth_row(res, method, series="average"):
    """The growth row of ``method`` and ``series`` in ``res.growth``, or None."""
    for r in res.growth:
        if r["method"] == method and r["series"] == series:
            return r
    return None


def _table1_row(case, n, missing, t, cpu, pp, ps, disagreements):
    """One row of Table I: times ``t`` and ``cpu`` (µs by method), the paper's ms ``pp``, ``ps``."""
    return {
        "case": case,
        "vertices": n,
        "missing": missing,
        "prismbatch_us": t["prismbatch"],
        "prismbatch_batch1_us": t["prismbatch_batch1"],
        "fcl_us": t["fcl"],
        "coal_us": t["coal"],
        "pb_over_fcl": _ratio(t["prismbatch"], t["fcl"]),
        "pb_over_coal": _ratio(t["prismbatch"], t["coal"]),
        "paper_projection_us": None if pp is None else 1e3 * pp,
        "paper_swift_us": None if ps is None else 1e3 * ps,
        "paper_ratio": _ratio(pp, ps),
        "fcl_disagreements": disagreements.get("fcl"),
        "coal_disagreements": disagreements.get("coal"),
        "prismbatch_cpu_us": cpu["prismbatch"],
        "fcl_cpu_us": cpu["fcl"],
        "coal_cpu_us": cpu["coal"],
    }


def table1_rows(res):
    """Table I at ``settings["table_vertices"]``: one row per case, then the average (``StudyResult.table1``)."""
    n = res.settings["table_vertices"]
    rows = []
    for case in res.settings["cases"]:
        t = {m: res.latency_us(m, case, n) for m in METHODS}
        cpu = {m: res.latency_us(m, case, n, "thread_cpu_median_us") for m in METHODS}
        ag = {r["peer"]: r["disagreements"] for r in res.agreement if r["case"] == case and r["vertices"] == n}
        rows.append(
            _table1_row(
                case,
                n,
                t["prismbatch"] is None,
                t,
                cpu,
                PAPER_TABLE1_MS["projection"].get(case),
                PAPER_TABLE1_MS["swift"].get(case),
                ag,
            )
        )
    avg_cases = [c for c in _avg_cases(res) if res.latency_us("prismbatch", c, n) is not None]
    if avg_cases:
        mean = {m: _mean_or_none([res.latency_us(m, c, n) for c in avg_cases]) for m in METHODS}
        cpu = {
            k: _mean_or_none([res.latency_us(k, c, n, "thread_cpu_median_us") for c in avg_cases])
            for k in ("prismbatch", "fcl", "coal")
        }
        paper_cases = [c for c in avg_cases if c in PAPER_CASES]
        pp = _mean_or_none([PAPER_TABLE1_MS["projection"][c] for c in paper_cases])
        ps = _mean_or_none([PAPER_TABLE1_MS["swift"][c] for c in paper_cases])
        rows.append(_table1_row("average " + ",".join(map(str, avg_cases)), n, False, mean, cpu, pp, ps, {}))
    return rows


def _ratio(x, y):
    return None if x is None or y is None or y == 0 else x / y


def _mean_or_none(v):
    return None if not v or any(x is None for x in v) else float(np.mean(v))
