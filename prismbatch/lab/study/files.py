"""The study's files: CSV tables, the JSON record, the Markdown page and the figures (:func:`write_study`)."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from ...collide import CASES
from ..report import run_metadata, write_csv, write_json, write_text
from .constants import METHODS, PAPER_GROWTH_MS_PER_1000, PAPER_SOURCE, PAPER_TABLE1_MS, PAPER_VERTICES
from .plots import plot_study
from .report import markdown
from .result import StudyResult

_LAT_COLS = (
    "case",
    "vertices",
    "method",
    "median_us",
    "min_us",
    "q1_us",
    "q3_us",
    "max_us",
    "thread_cpu_median_us",
    "poses",
    "repeats",
    "hits",
    "other_cpus",
)
_THR_COLS = (
    "case",
    "vertices",
    "mode",
    "threads",
    "pairs",
    "median_pairs_per_s",
    "min_pairs_per_s",
    "max_pairs_per_s",
    "repeats",
)
_GRO_COLS = (
    "method",
    "series",
    "cases",
    "slope_us_per_1000",
    "intercept_us",
    "r2",
    "log_slope_us_per_doubling",
    "log_intercept_us",
    "r2_log",
    "model",
    "growth_factor",
    "points",
    "slope_ratio_vs_fcl",
    "slope_ratio_vs_coal",
)
_T1_COLS = (
    "case",
    "vertices",
    "missing",
    "prismbatch_us",
    "prismbatch_batch1_us",
    "fcl_us",
    "coal_us",
    "pb_over_fcl",
    "pb_over_coal",
    "paper_projection_us",
    "paper_swift_us",
    "paper_ratio",
    "fcl_disagreements",
    "coal_disagreements",
    "prismbatch_cpu_us",
    "fcl_cpu_us",
    "coal_cpu_us",
)
_AGR_COLS = (
    "case",
    "vertices",
    "peer",
    "poses",
    "pb_hits",
    "peer_hits",
    "disagreements",
    "pb_hit_peer_miss",
    "pb_miss_peer_hit",
    "touching_exact",
    "other",
    "lp_checked",
    "lp_touching",
    "lp_pb_right",
    "lp_pb_wrong",
)


def _cell(v):
    if v is None:
        return ""
    if isinstance(v, (bool, np.bool_)):
        return int(v)
    if isinstance(v, float):
        return "" if not math.isfinite(v) else f"{v:.6g}"
    return v


def _rows(items, cols):
    return [[_cell(r.get(c)) for c in cols] for r in items]


def write_study(result, out_dir, *, figures=True):
    """Write the study to ``out_dir``.

    Parameters
    ----------
    result : StudyResult
    out_dir : str or path-like
    figures : bool, optional
        Also draw the figures (needs matplotlib).

    Returns
    -------
    dict
        Paths: ``table1``, ``latency``, ``throughput``, ``growth``,
        ``agreement`` (CSV), ``json``, ``markdown`` and ``figures`` (list of
        PNG and SVG paths; empty without ``figures``).
    """
    if not isinstance(result, StudyResult):
        raise TypeError(f"result must be a StudyResult, got {type(result).__name__}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {
        "table1": write_csv(out / "study_table1.csv", _T1_COLS, _rows(result.table1, _T1_COLS)),
        "latency": write_csv(out / "study_latency.csv", _LAT_COLS, _rows(result.latency, _LAT_COLS)),
        "throughput": write_csv(out / "study_throughput.csv", _THR_COLS, _rows(result.throughput, _THR_COLS)),
        "growth": write_csv(out / "study_growth.csv", _GRO_COLS, _rows(result.growth, _GRO_COLS)),
        "agreement": write_csv(out / "study_agreement.csv", _AGR_COLS, _rows(result.agreement, _AGR_COLS)),
        "json": str(out / "study.json"),
        "markdown": str(out / "study.md"),
        "figures": [],
    }
    if figures:
        paths["figures"] = plot_study(result, out)
    meta = run_metadata(
        description="prismbatch timing study vs python-fcl and coal (paper Table I, Fig. 7)",
        settings=result.settings,
        methods=result.methods,
        method_descriptions=METHODS,
        compile_s=result.compile,
        environment=result.environment,
        notes=result.notes,
        missing=result.missing,
        table1=result.table1,
        growth=result.growth,
        paper={
            "source": PAPER_SOURCE,
            "table1_ms": PAPER_TABLE1_MS,
            "growth_ms_per_1000": PAPER_GROWTH_MS_PER_1000,
            "vertices": PAPER_VERTICES,
        },
        cases={int(k): v for k, v in CASES.items()},
        files={
            k: (os.path.basename(v) if isinstance(v, str) else [os.path.basename(x) for x in v])
            for k, v in paths.items()
        },
    )
    write_json(paths["json"], meta)
    write_text(paths["markdown"], markdown(result, paths))
    return paths
