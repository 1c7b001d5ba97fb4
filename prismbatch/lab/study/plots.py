"""The study's figures: Fig. 7a-c, Table I as bars, and batch throughput (matplotlib)."""

from __future__ import annotations

import numpy as np

from ..report import cpu_name, fmt, legend_below, new_figure, pct, save_figure
from .analysis import average_series, growth_model_text, growth_row
from .constants import PAPER_GROWTH_MS_PER_1000, PAPER_TABLE_VERTICES, PEERS

_SHORT = {"fcl": "FCL", "coal": "coal"}
_METHOD_STYLE = {"prismbatch": ("C0", "o"), "prismbatch_batch1": ("C9", "v"), "fcl": ("C3", "s"), "coal": ("C2", "^")}
# One marker per case 1-11: cases whose colours are close (1 and 11) still differ.
_CASE_MARKERS = "osD^v<>phX*"


def _case_colour(case):
    import matplotlib

    return matplotlib.colormaps["tab20"]((2 * (case - 1)) % 20 + (1 if case > 10 else 0))


def _case_dodge(cases, vertices):
    """A factor per case that shifts its points along log n, so that the cases' bars at one n sit side by side.

    The shifts spread evenly over a band of half the smallest gap between two
    vertex counts (in decades, at most 0.25), centred on n: bands of
    neighbouring counts never meet.
    """
    logs = np.log10(sorted(set(vertices)))
    band = min(0.25, 0.5 * float(np.min(np.diff(logs)))) if len(logs) > 1 else 0.25
    shifts = np.linspace(-band / 2, band / 2, len(cases)) if len(cases) > 1 else [0.0]
    return {case: 10.0**d for case, d in zip(cases, shifts)}


def _log_axes(ax, x=True, y=True):
    """Log scales with plain numbers as tick labels (5, 20, 1000 rather than 5x10^0)."""
    from matplotlib.ticker import FuncFormatter, LogFormatter, LogLocator

    fmt = FuncFormatter(lambda v, _: f"{v:,.0f}" if v >= 1 and v == int(v) else f"{v:g}")
    for on, axis, setter in ((x, ax.xaxis, ax.set_xscale), (y, ax.yaxis, ax.set_yscale)):
        if on:
            setter("log")
            axis.set_major_formatter(fmt)
            # Label the 2 and 5 minor ticks only when a decade or less is shown.
            lo, hi = ax.get_xlim() if axis is ax.xaxis else ax.get_ylim()
            if lo > 0 and hi / lo < 30:
                axis.set_minor_locator(LogLocator(subs=(2.0, 5.0)))
                axis.set_minor_formatter(fmt)
            else:  # the minor ticks matplotlib labels on a short range: 60, not 6x10^1
                axis.set_minor_formatter(LogFormatter(labelOnlyBase=False))


def _vertex_axes(ax, ylabel):
    """Log-log axes over the vertex count n, labelled, with a grid."""
    _log_axes(ax)
    ax.set_xlabel("end-face vertices n (each prism)")
    ax.set_ylabel(ylabel)
    ax.grid(True, which="both", alpha=0.3)


def _min_max_bars(rows, median, lo, hi):
    """Medians of ``rows`` and their error bars down to ``lo`` and up to ``hi`` (keys)."""
    y = np.array([r[median] for r in rows])
    return y, [y - np.array([r[lo] for r in rows]), np.array([r[hi] for r in rows]) - y]


def _per_case_axes(ax, res, method):
    """Each case's median time per query against n, with min-max bars, the cases side by side at each n."""
    from matplotlib.ticker import NullLocator

    cases = res.settings["cases"]
    dodge = _case_dodge(cases, res.settings["vertices"])
    for case in cases:
        rows = sorted(
            (r for r in res.latency if r["method"] == method and r["case"] == case), key=lambda r: r["vertices"]
        )
        if not rows:
            continue
        x = np.array([r["vertices"] for r in rows], dtype=float) * dodge[case]
        y, err = _min_max_bars(rows, "median_us", "min_us", "max_us")
        ax.errorbar(
            x,
            y,
            yerr=err,
            marker=_CASE_MARKERS[(case - 1) % len(_CASE_MARKERS)],
            ms=4,
            lw=0.8,
            elinewidth=0.9,
            capsize=1.5,
            capthick=0.6,
            color=_case_colour(case),
            label=f"case {case}",
        )
    _vertex_axes(ax, "time per query (µs)")
    ns = sorted(set(res.settings["vertices"]))
    ax.set_xticks(ns, [f"{n:,}" for n in ns])  # a tick (and grid line) at the centre of each group
    ax.xaxis.set_minor_locator(NullLocator())
    ax.set_xlabel("end-face vertices n (each prism)\nthe cases' points sit side by side about each n")
    ax.set_title(res.methods.get(method, method), fontsize=10)


def _fig7a(res, out_dir):
    s = res.settings
    fig = new_figure(figsize=(7.5, 5.0), layout="constrained")
    ax = fig.add_subplot()
    _per_case_axes(ax, res, "prismbatch")
    ax.set_title(
        f"Fig. 7a: {res.methods['prismbatch']}, one Python call per pair\n"
        f"median of {s['repeats']} repeats over {s['poses_per_case']} poses per case (bars: min-max)",
        fontsize=10,
    )
    legend_below(fig, [ax], ncol=6)
    return save_figure(fig, out_dir, "study_fig7a_prismbatch")


def _fig7b(res, out_dir):
    peers = [p for p in PEERS if p in res.methods]
    if not peers:
        return []
    fig = new_figure(figsize=(6.0 * len(peers), 5.0), layout="constrained")
    axes = [fig.add_subplot(1, len(peers), i + 1) for i in range(len(peers))]
    for ax, p in zip(axes, peers):
        _per_case_axes(ax, res, p)
        ax.set_title(f"Fig. 7b: {res.methods[p]} (finite stand-ins)", fontsize=10)
    lo = min(ax.get_ylim()[0] for ax in axes)
    hi = max(ax.get_ylim()[1] for ax in axes)
    for ax in axes:
        ax.set_ylim(lo, hi)
    legend_below(fig, [axes[0]], ncol=11 if len(peers) > 1 else 6)
    return save_figure(fig, out_dir, "study_fig7b_peers")


def _growth_label(res, m, g):
    """Legend label of method ``m`` in Fig. 7c: its growth factor, the model that fits it and, where
    both are straight lines that hold, prismbatch's slope as a share of the peers'."""
    lab = res.methods[m]
    if g is not None:
        s = res.settings["vertices"]
        lab += f": ×{fmt(g['growth_factor'], '.3g')} from n = {min(s)} to {max(s)}; " + growth_model_text(g)
        if m.startswith("prismbatch"):
            rat = [
                f"{pct(g[f'slope_ratio_vs_{p}'])} of {_SHORT[p]}'s"
                for p in PEERS
                if g[f"slope_ratio_vs_{p}"] is not None
            ]
            if rat:
                lab += " (" + ", ".join(rat) + ")"
    return lab


def _fig7c(res, out_dir):
    s = res.settings
    fig = new_figure(figsize=(7.5, 5.0), layout="constrained")
    ax = fig.add_subplot()
    avg = next((r["cases"] for r in res.growth if r["series"] == "average"), "")
    nn = np.geomspace(min(s["vertices"]), max(s["vertices"]), 200)
    fitted = False
    for m in res.methods:
        pts = average_series(res, m, [int(c) for c in avg.split(",") if c])
        if not pts:
            continue
        col, mk = _METHOD_STYLE[m]
        g = growth_row(res, m)
        lab = _growth_label(res, m, g)
        if g is not None:
            if g["model"] == "log":
                fit = g["log_intercept_us"] + g["log_slope_us_per_doubling"] * np.log2(nn)
            else:
                fit = g["intercept_us"] + g["slope_us_per_1000"] * nn / 1000.0
            ax.plot(nn[fit > 0], fit[fit > 0], "--", color=col, lw=1)
            fitted = True
        ax.plot(list(pts), list(pts.values()), marker=mk, color=col, lw=0, ms=6, label=lab)
    pg = PAPER_GROWTH_MS_PER_1000
    if fitted:  # a legend key for the dashed lines, only when one is drawn
        ax.plot([], [], "--", color="grey", label="least-squares fit, t = a + b n or t = a + b log2 n (the better r²)")
    _vertex_axes(ax, "mean time per query over cases (µs)")
    ax.set_title(
        f"Fig. 7c: average over cases {avg}, single-query latency\n"
        f"paper: projection {1e3 * pg['projection']:g} vs SWIFT {1e3 * pg['swift']:g} µs / 1000 vertices "
        f"({pct(pg['projection'] / pg['swift'])})",
        fontsize=10,
    )
    legend_below(fig, [ax], ncol=1)
    return save_figure(fig, out_dir, "study_fig7c_average")


def _table1_panel(ax, rows, bars, title):
    """Grouped bars of ``bars`` ((key, label, colour, hatch), missing labels dropped) per case of ``rows``."""
    bars = [b for b in bars if b[1] is not None]
    w = 0.8 / len(bars)
    x = np.arange(len(rows))
    for i, (key, lab, col, hatch) in enumerate(bars):
        y = np.array([np.nan if r[key] is None else r[key] for r in rows], dtype=float)
        ax.bar(
            x + (i - (len(bars) - 1) / 2) * w,
            y,
            w,
            label=lab,
            color="white" if hatch else col,
            edgecolor=col,
            hatch=hatch,
            lw=1,
        )
    ax.set_xlabel("case")
    ax.set_ylabel("time per query (µs, log scale)")
    ax.grid(True, axis="y", which="both", alpha=0.3)
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=8, ncol=len(bars), loc="upper left")


def _table1_bars(res, out_dir):
    """Table I as bars: the paper's numbers and this machine's on two panels, one case axis, one µs scale."""
    rows = [r for r in res.table1 if isinstance(r["case"], int)]
    fig = new_figure(figsize=(9.0, 7.5), layout="constrained")
    ax_paper, ax_here = fig.subplots(2, 1, sharex=True, sharey=True)
    _table1_panel(
        ax_paper,
        rows,
        [
            ("paper_projection_us", "projection method", "C0", "//"),
            ("paper_swift_us", "SWIFT", "C3", "//"),
        ],
        f"The paper's Table I: measured on an Intel i3 3.30 GHz, {PAPER_TABLE_VERTICES} vertices (its ms as µs)",
    )
    _table1_panel(
        ax_here,
        rows,
        [
            ("prismbatch_us", res.methods.get("prismbatch"), "C0", None),
            ("fcl_us", res.methods.get("fcl"), "C3", None),
            ("coal_us", res.methods.get("coal"), "C2", None),
        ],
        f"This study: measured on this machine ({cpu_name()}), {res.settings['table_vertices']} vertices, "
        f"median of {res.settings['repeats']} repeats",
    )
    x = np.arange(len(rows))
    for i, r in enumerate(rows):
        if r["paper_projection_us"] is None:
            ax_paper.text(
                x[i],
                0.03,
                "not in\nthe paper",
                ha="center",
                va="bottom",
                fontsize=8,
                transform=ax_paper.get_xaxis_transform(),
            )
        if r["missing"]:
            ax_here.text(
                x[i],
                0.03,
                "missing",
                rotation=90,
                ha="center",
                va="bottom",
                fontsize=8,
                transform=ax_here.get_xaxis_transform(),
            )
    ax_here.set_xticks(x, [str(r["case"]) for r in rows])
    ax_paper.tick_params(labelbottom=True)
    _log_axes(ax_here, x=False)
    ax_here.set_ylim(top=ax_here.get_ylim()[1] * 8)  # room for the legends above the bars
    fig.suptitle(
        "Table I: single-query time per case on two different machines; compare the ratios within a panel, "
        "not bar heights across panels",
        fontsize=10,
    )
    return save_figure(fig, out_dir, "study_table1")


def _throughput_figure(res, out_dir):
    from ... import __version__

    fig = new_figure(figsize=(7.5, 5.0), layout="constrained")
    ax = fig.add_subplot()
    style = {
        "prismbatch_1t": ("C0", "o", "prismbatch {v} collide, 1 thread"),
        "prismbatch_allt": ("C1", "D", "prismbatch {v} collide, {k} threads"),
        "fcl_loop": ("C3", "s", "{fcl}, Python loop"),
        "coal_loop": ("C2", "^", "{coal}, Python loop"),
    }
    for mode, (col, mk, lab) in style.items():
        rows = sorted(
            (r for r in res.throughput if r["case"] == "all" and r["mode"] == mode), key=lambda r: r["vertices"]
        )
        if not rows:
            continue
        y, err = _min_max_bars(rows, "median_pairs_per_s", "min_pairs_per_s", "max_pairs_per_s")
        ax.errorbar(
            [r["vertices"] for r in rows],
            y,
            yerr=err,
            color=col,
            marker=mk,
            capsize=2,
            label=lab.format(
                v=__version__, k=rows[0]["threads"], fcl=res.methods.get("fcl"), coal=res.methods.get("coal")
            ),
        )
    _vertex_axes(ax, "throughput (pose pairs / s)")
    ax.set_title(
        f"Batch throughput on all cases' poses (prismbatch: {res.settings['batch_pairs']} pairs per call; "
        "bars: min-max)",
        fontsize=10,
    )
    legend_below(fig, [ax], ncol=2)
    return save_figure(fig, out_dir, "study_throughput")


def plot_study(res, out_dir):
    """Draw the study's figures (PNG and SVG) into ``out_dir``.

    Figures: ``study_fig7a_prismbatch`` (prismbatch per case vs n),
    ``study_fig7b_peers`` (each peer per case vs n), ``study_fig7c_average``
    (average per method with the fitted growth), ``study_table1`` (per-case
    bars at Table I's vertex count, with the paper's), ``study_throughput``
    (pairs/s of the batch call vs n).

    Parameters
    ----------
    res : StudyResult
    out_dir : str or path-like

    Returns
    -------
    list of str
        Paths of the files written.
    """
    files = []
    for draw in (_fig7a, _fig7b, _fig7c, _table1_bars, _throughput_figure):
        files += draw(res, out_dir)
    return files
