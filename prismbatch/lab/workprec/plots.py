"""The work-precision figures: error against time per query (``{stem}_error_vs_time``) and error
against n (``{stem}_error_vs_n``), PNG and SVG (needs matplotlib)."""

from __future__ import annotations

import math
import textwrap
from dataclasses import dataclass

import numpy as np

from ..report import cpu_name, legend_below, new_figure, save_figure
from .result import METHODS, method_labels
from .scene import vertices_needed

_STYLE = {  # colour, marker, linestyle
    "pb64_batch": ("tab:blue", "o", "-"),
    "pb64_pair": ("tab:blue", "s", "--"),
    "pb32_batch": ("tab:green", "o", "-"),
    "pb32_pair": ("tab:green", "s", "--"),
    "fcl_ngon": ("tab:red", "d", "-"),
    "fcl_cylinder": ("black", "*", "none"),
}


@dataclass
class _Context:
    """What both figures share: the result, legend labels, noise floor and the y range."""

    result: object
    labels: dict
    floor: float
    y_min: float
    rate_rows: list
    cyl: list
    floor_label: str
    zero_label: str


def _series(result, method):
    return [r for r in result.rows if r["method"] == method and math.isfinite(r["rate"])]


def _same_labels(result, m1, m2):
    """True when two methods reported identical hits at every n (then one curve is drawn)."""
    keys = [k for k in result.predictions if k[0] == m1]
    return bool(keys) and all(
        (m2, k[1]) in result.predictions and np.array_equal(result.predictions[k], result.predictions[(m2, k[1])])
        for k in keys
    )


def _draw_rates(ax, xs, rows, method, label, y_min):
    """Rates with Wilson error bars; zero-error points at their upper bound as open down-triangles.

    Returns True if it drew a zero-error point (then the axes need :func:`_zero_key`).
    """
    col, mk, ls = _STYLE[method]
    xs = np.asarray(xs, dtype=float)
    rate = np.array([r["rate"] for r in rows])
    lo = np.array([r["ci_low"] for r in rows])
    hi = np.array([r["ci_high"] for r in rows])
    pos = rate > 0
    if len(xs) > 1:
        ax.plot(xs, np.where(pos, rate, hi), color=col, linestyle=ls, linewidth=1.2, alpha=0.8)
    if pos.any():
        ax.errorbar(
            xs[pos],
            rate[pos],
            yerr=[rate[pos] - np.maximum(lo[pos], y_min), hi[pos] - rate[pos]],
            fmt=mk,
            color=col,
            markersize=9 if mk == "*" else 5,
            capsize=2,
            linestyle="none",
            label=label,
        )
    if (~pos).any():
        ax.plot(
            xs[~pos],
            hi[~pos],
            marker="v",
            markerfacecolor="none",
            color=col,
            linestyle="none",
            markersize=6,
            label=None if pos.any() else label,
        )
    return bool((~pos).any())


def _zero_key(ax, ctx):
    """The legend key of the open down-triangles; only for axes where one is drawn."""
    ax.plot([], [], marker="v", markerfacecolor="none", color="0.3", linestyle="none", label=ctx.zero_label)


def _float32_note(ax, ctx, x, ha):
    """Say on the rate axes that the float32 rows level off at float32's tolerance, not by failing."""
    s = ctx.result.settings
    tol = s["median_tolerance_rel"]["float32"]
    text = (
        f"The float32 rows level off by design, at float32's tolerance: rtol = {s['rtol']['float32']:g} of the "
        f"pair's size (median {tol:.1e} r over these poses). Near misses within it are reported as hits (the "
        f"tolerance allows either answer there), so once the n-gon's geometric error falls below it "
        f"(n >= {vertices_needed(tol):,}) the rate stops falling."
    )
    ax.text(
        x,
        0.2,
        textwrap.fill(text, 52),
        transform=ax.transAxes,
        ha=ha,
        va="bottom",
        fontsize=8,
        color=_STYLE["pb32_batch"][0],
        bbox=dict(boxstyle="round", facecolor="white", edgecolor="0.7", alpha=0.9),
    )


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


def _log_axes(axes, xlabel):
    for ax in axes:
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(xlabel)
        ax.grid(True, which="both", alpha=0.3)


# ---------------------------------------------------------------------------
# error against time
# ---------------------------------------------------------------------------


def _annotate_n(ax, key, ctx):
    """n along the FCL n-gon curve (right of its points) and prismbatch float64 batch (left of its points)."""
    # prismbatch's points crowd together: its labels go in a column left of all its points
    pb_left = min([r["t_median_us"] for r in ctx.rate_rows if r["method"].startswith("pb")] or [1.0])
    for m, off, ha, va in (("fcl_ngon", (3, 6), "left", "bottom"), ("pb64_batch", (-7, 0), "right", "center")):
        pts = [(r["t_median_us"], r[key] if r[key] > 0 else r["ci_high"], r["n"]) for r in _series(ctx.result, m)]
        for x, y, text in _sparse_labels(pts, column=m == "pb64_batch"):
            ax.annotate(
                text,
                (pb_left if m == "pb64_batch" else x, y),
                textcoords="offset points",
                xytext=off,
                ha=ha,
                va=va,
                fontsize=7,
                color=_STYLE[m][0],
            )


def _figure_error_vs_time(ctx, out_dir, stem):
    """(a) misclassification rate and (b) geometric error, both against time per query."""
    result, labels, s = ctx.result, ctx.labels, ctx.result.settings
    fig = new_figure(figsize=(13.5, 7.4), layout="constrained")
    ax1, ax2 = fig.subplots(1, 2)
    zeros = False
    for m in METHODS:
        rows = _series(result, m)
        if not rows:
            continue
        zeros |= _draw_rates(ax1, [r["t_median_us"] for r in rows], rows, m, labels[m], ctx.y_min)
        if m != "fcl_cylinder":
            c, mk, ls = _STYLE[m]
            ax2.plot(
                [r["t_median_us"] for r in rows],
                [r["geom_rel_error"] for r in rows],
                color=c,
                marker=mk,
                linestyle=ls,
                label=labels[m],
                markersize=5,
            )
    ax1.axhline(ctx.floor, color="0.4", linestyle=":", linewidth=1.2, label=ctx.floor_label)
    if zeros:
        _zero_key(ax1, ctx)
    if _series(result, "pb32_batch"):
        _float32_note(ax1, ctx, 0.98, "right")  # prismbatch sits left, the slower peers high
    for ax, key in ((ax1, "rate"), (ax2, "geom_rel_error")):
        _annotate_n(ax, key, ctx)
    if ctx.cyl:
        ax2.axvline(
            ctx.cyl[0]["t_median_us"],
            color="black",
            linestyle="-.",
            linewidth=1,
            label=labels["fcl_cylinder"] + ": its time (no geometric error)",
        )
    _log_axes((ax1, ax2), "time per query (µs; median of passes, one thread; log scale)")
    for ax in (ax1, ax2):
        lo, hi = ax.get_xlim()
        ax.set_xlim(lo / 2.5, hi * 1.6)  # room for the n labels
    ax1.set_ylim(bottom=ctx.y_min, top=1.0)
    ax1.set_ylabel("misclassification rate against the exact cylinder (log scale)")
    ax1.set_title("(a) misclassified near-contact poses (95 % Wilson intervals; numbers: n)", fontsize=10)
    ax2.set_ylabel("geometric error 1 - cos(π/n) = radial deficit / r (log scale)")
    ax2.set_title("(b) geometric error of the inscribed n-gon (numbers: n)", fontsize=10)
    legend_below(fig, (ax1, ax2), ncol=2, frameon=False)
    fig.suptitle(
        f"Work-precision: semi-infinite cylinder (r = {s['radius']:g}) as an n-gon prism against a "
        f"hexagonal prism; {s['n_poses']:,} near-contact poses; {cpu_name()} (shared, timings noisy)",
        fontsize=11,
    )
    return save_figure(fig, out_dir, f"{stem}_error_vs_time")


# ---------------------------------------------------------------------------
# error against n
# ---------------------------------------------------------------------------


def _panel_geometry(ax1, ctx):
    """(a) the geometric error, its fit and the deepest overlap each method missed, against n."""
    result, labels, s, cyl = ctx.result, ctx.labels, ctx.result.settings, ctx.cyl
    g = result.geometry
    nn = np.asarray(g["n"], dtype=float)
    ax1.plot(nn, g["rel_error"], "ko", label="geometric error 1 - cos(π/n) of the inscribed n-gon")
    nf = np.geomspace(nn.min(), nn.max(), 100)
    ax1.plot(
        nf,
        g["constant"] * nf ** -g["order"],
        "k--",
        linewidth=1,
        label=f"least-squares fit {g['constant']:.3f} n^-{g['order']:.3f} (fitted order {g['order']:.3f})",
    )
    for m in ("pb64_batch", "fcl_ngon"):
        rows = [r for r in _series(result, m) if r["fn"] > 0]
        if rows:
            c, mk, _ = _STYLE[m]
            ax1.plot(
                [r["n"] for r in rows],
                [r["max_fn_depth"] for r in rows],
                color=c,
                marker=mk,
                linestyle="none",
                markerfacecolor="none",
                markersize=8 if m == "pb64_batch" else 6,
                label=f"deepest missed hit, |gap| / r: {labels[m]}",
            )
    if cyl and cyl[0]["fn"] > 0:
        ax1.axhline(
            cyl[0]["max_fn_depth"],
            color="black",
            linestyle="-.",
            linewidth=1,
            label=f"deepest missed hit, |gap| / r: {labels['fcl_cylinder']}",
        )
    if _series(result, "pb32_batch"):
        tol = s["median_tolerance_rel"]["float32"]
        ax1.axhline(
            tol,
            color=_STYLE["pb32_batch"][0],
            linestyle=(0, (5, 3)),
            linewidth=1,
            label=f"prismbatch float32 tolerance: rtol {s['rtol']['float32']:g} of the pair's size, median {tol:.1e} r",
        )
    ax1.axhline(
        s["gap_range_rel"][0],
        color="0.4",
        linestyle=":",
        label=f"smallest |gap| / r sampled ({s['gap_range_rel'][0]:g})",
    )
    ax1.set_ylabel("length / r (log scale)")
    ax1.set_title("(a) geometric error and the deepest overlap each method missed", fontsize=10)


def _panel_rates_vs_n(ax2, ctx):
    """(b) misclassification rate against n; a pair row identical to its batch row is drawn once."""
    result, labels, cyl = ctx.result, ctx.labels, ctx.cyl
    zeros = False
    for m in METHODS:
        rows = _series(result, m)
        if not rows or m == "fcl_cylinder":
            continue
        if m.endswith("_pair") and _same_labels(result, m.replace("_pair", "_batch"), m):
            continue  # identical to the batch call: drawn once
        lab = labels[m]
        if m.endswith("_batch") and _same_labels(result, m, m.replace("_batch", "_pair")):
            lab = lab.replace("batch call (1 thread)", "batch call and collide_pair (identical labels)")
        zeros |= _draw_rates(ax2, [r["n"] for r in rows], rows, m, lab, ctx.y_min)
    if cyl:
        r = cyl[0]
        ax2.axhspan(max(r["ci_low"], ctx.y_min), r["ci_high"], color="0.8", alpha=0.6)
        ax2.axhline(
            r["rate"] if r["rate"] > 0 else r["ci_high"],
            color="black",
            linestyle="-.",
            linewidth=1,
            label=labels["fcl_cylinder"] + " (no n; grey band: 95 % CI)",
        )
    ax2.axhline(ctx.floor, color="0.4", linestyle=":", label=ctx.floor_label)
    if zeros:
        _zero_key(ax2, ctx)
    if _series(result, "pb32_batch"):
        _float32_note(ax2, ctx, 0.02, "left")  # every method misses often at small n: the lower left is free
    ax2.set_ylim(bottom=ctx.y_min, top=1.0)
    ax2.set_ylabel("misclassification rate against the exact cylinder (log scale)")
    ax2.set_title("(b) misclassification rate (95 % Wilson intervals)", fontsize=10)


def _figure_error_vs_n(ctx, out_dir, stem):
    """(a) geometric error and deepest missed overlaps, (b) misclassification rate, both against n."""
    s = ctx.result.settings
    fig = new_figure(figsize=(13.5, 7.0), layout="constrained")
    ax1, ax2 = fig.subplots(1, 2)
    _panel_geometry(ax1, ctx)
    _panel_rates_vs_n(ax2, ctx)
    _log_axes((ax1, ax2), "vertices n of the cylinder's inscribed n-gon (log scale)")
    legend_below(fig, (ax1, ax2), ncol=2, frameon=False)
    fig.suptitle(
        f"Error against n: semi-infinite cylinder (r = {s['radius']:g}) as an inscribed n-gon prism, "
        f"{s['n_poses']:,} near-contact poses (|gap| / r log-uniform in [{s['gap_range_rel'][0]:g}, "
        f"{s['gap_range_rel'][1]:g}])",
        fontsize=11,
    )
    return save_figure(fig, out_dir, f"{stem}_error_vs_n")


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
    s = result.settings
    floor = s["noise_floor"]
    rate_rows = [r for r in result.rows if math.isfinite(r["rate"])]
    ctx = _Context(
        result=result,
        labels=method_labels(result.versions),
        floor=floor,
        y_min=min([floor] + [r["ci_low"] for r in rate_rows if r["rate"] > 0]) / 3.0,
        rate_rows=rate_rows,
        cyl=_series(result, "fcl_cylinder"),
        floor_label=f"Monte Carlo noise floor: 95 % upper bound at 0 errors, N = {s['n_poses']:,}",
        zero_label="open down-triangle: no error seen (drawn at its 95 % upper bound)",
    )
    return _figure_error_vs_time(ctx, out_dir, stem) + _figure_error_vs_n(ctx, out_dir, stem)
