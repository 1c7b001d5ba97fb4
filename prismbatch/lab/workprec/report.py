"""Reporting a work-precision run: the text summary, and the files (CSV tables, JSON metadata,
Markdown summary, figures) written by :func:`write_work_precision`."""

from __future__ import annotations

import math
from pathlib import Path

from ..checkpoint import resumed_note
from ..report import fmt, run_metadata, write_csv, write_json, write_text
from .plots import plot_work_precision
from .result import WorkPrecisionResult
from .run import STAT_KEYS
from .scene import vertices_needed

#: Relative geometric errors whose needed vertex counts the reports quote.
NEEDED_REL_ERRORS = (1e-3, 1e-6, 1e-9)

CSV_COLS = (
    *("method", "label", "shape", "n", "geom_rel_error", "t_median_us", "t_min_us", "t_max_us", "passes", "setup_ms"),
    *STAT_KEYS[:-2],  # the error statistics of a row, with the tolerance before the beyond-tol counts
    "tolerance",
    *STAT_KEYS[-2:],
    "passes_agree",
)


def needed_vertices():
    """``{relative error: vertices needed}`` for :data:`NEEDED_REL_ERRORS`."""
    return {e: vertices_needed(e) for e in NEEDED_REL_ERRORS}


def compile_times(result):
    """'float64_batch 1.23 s, ...': the first-call times, for the text and Markdown summaries."""
    return ", ".join(f"{k} {t:.2f} s" for k, t in result.compile_s.items())


def _text_row(r):
    """One row of the text table ('-' for a method that did not run)."""
    ran = math.isfinite(r["rate"])
    mx = max(r["max_fn_depth"], r["max_fp_gap"]) if ran else math.nan
    return (
        f"{r['method']:<13}{'exact' if r['n'] is None else r['n']:>7}  {fmt(r['t_median_us'], '9.2f')}  "
        f"{fmt(r['rate'], '9.2e')}  [{fmt(r['ci_low'], '.2e')}, {fmt(r['ci_high'], '.2e')}]  "
        f"{fmt(r['fn'], '11')}  {fmt(r['fp'], '10')}  {fmt(mx, '15.2e')}  "
        f"{fmt(r['fn_beyond_tol'], 'd') if ran else '-'}/"
        f"{fmt(r['fp_beyond_tol'], 'd') if ran else '-'}"
    )


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
    lines = [
        f"prismbatch {v.get('prismbatch')} work-precision study: a = semi-infinite cylinder r = {s['radius']:g} "
        f"as inscribed n-gon, b = {s['shape_b']}",
        f"   {s['n_poses']:,} near-contact poses (|gap|/r log-uniform {s['gap_range_rel'][0]:g}..."
        f"{s['gap_range_rel'][1]:g}; {s['exact_hits']:,} exact hits, {s['exact_misses']:,} exact misses), "
        f"seed {s['seed']}, median of {s['repeats']} pass(es); noise floor (95 % bound at 0 errors) "
        f"{s['noise_floor']:.2g}",
        f"geometric error r(1 - cos(pi/n)): fitted order {g['order']:.3f} (constant {g['constant']:.3f}, "
        f"theory 2 and pi^2/2 = {g['constant_theory']:.3f}); vertices needed for a relative error of "
        + ", ".join(f"{e:g}: {k}" for e, k in needed_vertices().items()),
        "compile or cache load (excluded): " + compile_times(result),
        f"{'method':<13}{'n':>7}  {'us/query':>9}  {'misclass.':>9}  {'95% CI':>19}  {'missed hits':>11}  "
        f"{'false hits':>10}  {'max |g|/r wrong':>15}  beyond tol",
    ]
    lines += [_text_row(r) for r in result.rows]
    lines.append(
        "   (beyond tol: missed hits with b's vertex inside the method's polygon by more than its "
        "tolerance / false hits farther than twice it; prismbatch tolerance median "
        f"{s['median_tolerance_rel']['float64']:.1e} r (float64), "
        f"{s['median_tolerance_rel']['float32']:.1e} r "
        "(float32: its rtol 1e-5 reports near misses as hits); timings are noisy)"
    )
    return lines


def _csv_value(x):
    if x is None:
        return ""
    if isinstance(x, float):
        return "" if not math.isfinite(x) else repr(x)
    return x


def _markdown_row(r):
    """One row of the Markdown table ('-' for a method that did not run)."""
    if not math.isfinite(r["rate"]):
        return f"| {r['label']} | {r['n'] or 'exact'} | - | - | - | - | - | - |"
    return (
        f"| {r['label']} | {'exact' if r['n'] is None else r['n']} | {r['t_median_us']:.2f} "
        f"({r['t_min_us']:.2f}-{r['t_max_us']:.2f}) | {r['rate']:.2e} | "
        f"[{r['ci_low']:.1e}, {r['ci_high']:.1e}] | {r['fn']} | {r['fp']} | "
        f"{r['fn_beyond_tol']} / {r['fp_beyond_tol']} |"
    )


def _markdown(result, figures):
    s, g = result.settings, result.geometry
    out = [
        "# Work-precision: a cylinder as an n-gon prism",
        "",
        *resumed_note(s.get("resumed_vertices")),
        f"a = semi-infinite cylinder of radius {s['radius']:g} (axis down), approximated by the regular n-gon "
        f"INSCRIBED in its circle; b = {s['shape_b']}. {s['n_poses']:,} near-contact poses with exact labels "
        f"(|gap|/r log-uniform in [{s['gap_range_rel'][0]:g}, {s['gap_range_rel'][1]:g}], half hits); the same "
        "poses for every method. Misclassification rate with Wilson 95 % intervals; Monte Carlo noise floor "
        f"(upper bound at zero errors) {s['noise_floor']:.2g}. Time per query: median of {s['repeats']} pass(es), "
        "compile excluded; timings are noisy (shared machine). See `docs/methods/work-precision.md` for the "
        "construction.",
        "",
        f"Geometric error r(1 - cos(pi/n)): fitted order **{g['order']:.3f}** (constant {g['constant']:.3f}; "
        f"theory 2 and pi^2/2). Vertices needed: "
        + ", ".join(f"relative error {e:g} -> n = {k}" for e, k in needed_vertices().items())
        + ".",
        "",
        "float32 rows: float32 storage plus its default rtol 1e-5, which reports near misses within about "
        f"{s['median_tolerance_rel']['float32']:.1e} r as hits (safe side); they are counted as misclassifications. "
        "`beyond tol` counts the errors the method's tolerance does not explain (missed hits with b's vertex "
        "inside the method's polygon by more than its tolerance / false hits farther than twice it).",
        "",
        "| method | n | µs/query (min-max) | misclassified | 95 % CI | missed hits | false hits | beyond tol |",
        "|---|---|---|---|---|---|---|---|",
    ]
    out += [_markdown_row(r) for r in result.rows]
    out += ["", "Compile or cache load (excluded): " + compile_times(result) + "."]
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
    paths["csv"] = write_csv(
        out / "workprec.csv", CSV_COLS, [[_csv_value(r[c]) for c in CSV_COLS] for r in result.rows]
    )
    g = result.geometry
    p_ord, const = g["order"], g["constant"]
    paths["geometry_csv"] = write_csv(
        out / "workprec_geometry.csv",
        ("n", "radius", "abs_error", "rel_error", "fit_rel_error"),
        [
            [int(n), result.settings["radius"], repr(float(a)), repr(float(e)), repr(float(const * n**-p_ord))]
            for n, a, e in zip(g["n"], g["abs_error"], g["rel_error"])
        ],
    )
    fig_files = plot_work_precision(result, out) if figures else []
    meta = run_metadata(
        study="work_precision",
        settings=result.settings,
        seeds={"poses": result.settings["seed"]},
        fitted_order=g["order"],
        fitted_constant=g["constant"],
        compile_s=result.compile_s,
        vertices_needed={str(e): k for e, k in needed_vertices().items()},
        rows=result.rows,
        files=[Path(f).name for f in fig_files],
    )
    paths["json"] = write_json(out / "workprec.json", meta)
    md = out / "workprec.md"
    write_text(md, _markdown(result, fig_files))
    paths["markdown"] = str(md)
    paths["figures"] = fig_files
    return paths
