"""What the study derives from its latency rows: the growth fits (Fig. 7c) and Table I."""

from __future__ import annotations

import math

import numpy as np

from .constants import METHODS, PAPER_CASES, PAPER_TABLE1_MS, PEERS


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
    n = np.asarray(vertices, dtype=float).ravel()
    t = np.asarray(times, dtype=float).ravel()
    if n.shape != t.shape:
        raise ValueError(f"vertices and times must have the same length, got {n.size} and {t.size}")
    if not (np.isfinite(n).all() and np.isfinite(t).all()):
        raise ValueError("vertices and times must be finite")
    if np.unique(n).size < 2:
        raise ValueError("fit_growth needs at least two distinct vertex counts")
    A = np.column_stack([np.ones_like(n), n])
    (b0, b1), *_ = np.linalg.lstsq(A, t, rcond=None)
    ss_res = float(np.sum((t - (b0 + b1 * n)) ** 2))
    ss_tot = float(np.sum((t - t.mean()) ** 2))
    r2 = 1.0 - ss_res / ss_tot if ss_tot > 0 else math.nan
    return float(b1 * 1000.0), float(b0), r2


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
            fits[key] = fit_growth(list(pts), list(pts.values())) + (len(pts),)
    for (method, name), (slope, icpt, r2, k) in fits.items():
        row = {
            "method": method,
            "series": name,
            "slope_us_per_1000": slope,
            "intercept_us": icpt,
            "r2": r2,
            "points": k,
            "cases": ",".join(map(str, avg_cases)) if name == "average" else name[5:],
            "slope_ratio_vs_fcl": None,
            "slope_ratio_vs_coal": None,
        }
        for peer in PEERS:
            other = fits.get((peer, name))
            if other is not None and other[0] > 0:
                row[f"slope_ratio_vs_{peer}"] = slope / other[0]
        rows.append(row)
    return rows


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
