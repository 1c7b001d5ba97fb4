"""Work-precision study: how many vertices does a cylinder need, and what does that cost?

A semi-infinite cylinder, approximated by an inscribed regular n-gon prism, is collided with an exact
hexagonal prism on near-contact poses whose exact status is known by construction; for prismbatch
(float64/float32, batch call and single query) and python-fcl (on the n-gon, and its own Cylinder)
the study measures time per query and the misclassification rate against the exact cylinder.
Method, defaults and outputs: ``docs/methods/work-precision.md``.

Modules: :mod:`.scene` (the scene, :func:`near_contact_poses`, :func:`geometric_error`),
:mod:`.stats` (Wilson intervals, noise floor, fitted order), :mod:`.result` (:data:`METHODS`,
:class:`WorkPrecisionResult`), :mod:`.run` (:func:`run_work_precision`), :mod:`.report`
(:func:`format_work_precision`, :func:`write_work_precision`) and :mod:`.plots`
(:func:`plot_work_precision`). Names imported ``as`` themselves are public but outside ``__all__``:
importable from here as they were before the split.
"""

from .plots import plot_work_precision
from .report import format_work_precision, write_work_precision
from .result import METHODS, WorkPrecisionResult
from .result import method_labels as method_labels
from .run import DEFAULT_POSES as DEFAULT_POSES
from .run import DEFAULT_REPEATS as DEFAULT_REPEATS
from .run import DEFAULT_VERTICES, QUICK_VERTICES, run_work_precision
from .run import QUICK_POSES as QUICK_POSES
from .run import QUICK_REPEATS as QUICK_REPEATS
from .scene import B_SCALE as B_SCALE
from .scene import B_VERTICES as B_VERTICES
from .scene import BETA_RANGE_DEG as BETA_RANGE_DEG
from .scene import GAP_RANGE as GAP_RANGE
from .scene import TILT_RANGE_DEG as TILT_RANGE_DEG
from .scene import NearContactPoses, geometric_error, near_contact_poses, vertices_needed
from .stats import fit_order, noise_floor, wilson_interval

__all__ = [
    "run_work_precision",
    "write_work_precision",
    "format_work_precision",
    "plot_work_precision",
    "WorkPrecisionResult",
    "NearContactPoses",
    "near_contact_poses",
    "wilson_interval",
    "noise_floor",
    "geometric_error",
    "fit_order",
    "vertices_needed",
    "METHODS",
    "DEFAULT_VERTICES",
    "QUICK_VERTICES",
]
