"""Timing study against python-fcl and coal: the paper's Table I and Fig. 7, and batch throughput.

The scene, the two series (single-query latency, batch throughput), the growth
fit and the agreement check are described in docs/methods/study.md.

Modules: ``constants`` (the paper's numbers, scene, methods, defaults),
``result`` (:class:`StudyResult`), ``timing`` (timed passes, statistics,
machine load), ``run`` (:func:`run_study`), ``agreement`` (peers vs
prismbatch, LP adjudication), ``analysis`` (:func:`fit_growth`, Table I),
``report`` (:func:`format_study`), ``plots`` (:func:`plot_study`) and
``files`` (:func:`write_study`).
"""

from .agreement import adjudicate
from .analysis import fit_growth
from .constants import (
    DEFAULTS,
    METHODS,
    PAPER_GROWTH_MS_PER_1000,
    PAPER_SOURCE,
    PAPER_TABLE1_MS,
    PAPER_VERTICES,
    PEERS,
    QUICK,
    RADIUS_A,
    RADIUS_B,
)
from .files import write_study
from .plots import plot_study
from .report import format_study
from .result import StudyResult
from .run import run_study

__all__ = [
    "run_study",
    "format_study",
    "write_study",
    "plot_study",
    "fit_growth",
    "StudyResult",
    "PAPER_TABLE1_MS",
    "PAPER_GROWTH_MS_PER_1000",
    "PAPER_VERTICES",
    "PAPER_SOURCE",
    "RADIUS_A",
    "RADIUS_B",
    "METHODS",
    "PEERS",
    "DEFAULTS",
    "QUICK",
]

#: The name the LP adjudication had in the single-module version (tests/test_study.py uses it).
_adjudicate = adjudicate
