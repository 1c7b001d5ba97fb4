"""The stiff and extreme suite: pose pairs where floating point is hardest, with known answers.

Exact constructions with separating-plane certificates and LP-judged random
families, each run for several parameter values in float64 and float32, and
judged against a float64 ground truth. The families, the ground truth, the
touching band and what the float32 columns mean are described in
docs/methods/stiff-suite.md.

Modules: ``geometry`` (polygons, rotations, pair scale), ``constructions``
(exact pair sets), ``certificates`` (plane and contact certificates),
``families`` (:data:`FAMILIES`), ``evaluate`` (one set in one dtype), ``run``
(:func:`run_stiff_suite`) and ``report`` (:class:`StiffReport`).
"""

from ...collide import Collider  # noqa: F401  (run_stiff_suite takes it from here: tests substitute it)
from .certificates import contact_certified, plane_certificate
from .constructions import PairSet, coplanar_pairs, face_pairs, side_pairs
from .families import FAMILIES
from .geometry import (  # noqa: F401  (public in the single-module version)
    R_DOWN,
    axis_rotation,
    collinear_polygon,
    pair_scale,
    random_polygon,
    rot_z,
    sliver_polygon,
    with_axis,
)
from .report import StiffReport, write_stiff_report
from .run import run_stiff_suite

#: The name this helper had in the single-module version (tests/test_stiff_suite.py uses it).
_with_axis = with_axis

__all__ = [
    "StiffReport",
    "run_stiff_suite",
    "write_stiff_report",
    "FAMILIES",
    "PairSet",
    "pair_scale",
    "face_pairs",
    "side_pairs",
    "coplanar_pairs",
    "random_polygon",
    "sliver_polygon",
    "collinear_polygon",
    "axis_rotation",
    "plane_certificate",
    "contact_certified",
]
