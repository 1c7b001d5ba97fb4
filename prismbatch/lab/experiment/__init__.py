"""The paper's precision-manipulation experiment (Sec. VI-B), in simulation.

Object a (a square or triangular prism, axis down) stays put; object b (a
glass cylinder fitted by a regular polygon) is driven towards a goal by a PD
"attraction", and whenever :meth:`prismbatch.Collider.collide` reports a hit
the detach controller (:func:`prismbatch.control.detach`) pushes it away for
one step. The plants, the controller and how the detection cost is measured
are described in docs/methods/experiment.md.

:func:`run_experiment` returns an :class:`ExperimentResult`;
:func:`write_experiment` writes the trajectory (CSV), metadata (JSON), a
Markdown summary and the figures (PNG and SVG; needs matplotlib).

Modules: ``model`` (constants, :class:`ExperimentResult`), ``run`` (the
simulation), ``summary`` and ``timing`` (what is derived from a run),
``contour`` (Fig. 10 geometry), ``report`` (text, CSV, JSON, Markdown) and
``plots`` (figures).
"""

from .contour import contour_panels, projected_contour
from .model import FIG10_TIMES, PAPER, PLANTS, PRISMS, ExperimentResult
from .plots import plot_experiment
from .report import format_summary, write_experiment
from .run import run_experiment

__all__ = [
    "contour_panels",
    "plot_experiment",
    "run_experiment",
    "write_experiment",
    "format_summary",
    "ExperimentResult",
    "projected_contour",
    "PRISMS",
    "PLANTS",
    "PAPER",
    "FIG10_TIMES",
]
