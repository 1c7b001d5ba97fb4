"""What a work-precision run produces: the method keys, their legend labels and
:class:`WorkPrecisionResult` (shared by run, report and plots)."""

from __future__ import annotations

from dataclasses import dataclass, field

from .scene import NearContactPoses

#: Method keys, in the order of the rows and legends.
METHODS = ("pb64_batch", "pb64_pair", "pb32_batch", "pb32_pair", "fcl_ngon", "fcl_cylinder")


@dataclass
class WorkPrecisionResult:
    """Everything one run of the study produced.

    Attributes
    ----------
    settings : dict
        Parameters of the run (radius, b's shape, vertex counts, N, repeats,
        seed, ranges, stand-in length, tolerances).
    rows : list of dict
        One row per method and n (``fcl_cylinder``: one row, ``n`` None);
        the columns of ``workprec.csv``.
    geometry : dict
        ``n``, ``abs_error``, ``rel_error`` arrays and the fitted ``order``
        and ``constant``.
    compile_s : dict
        First-call time (compile or cache load) per dtype and path, s.
    poses : NearContactPoses
        The poses every method saw, with exact labels.
    predictions : dict
        ``(method, n) -> (N,) bool`` reported hits (``n`` None for the cylinder).
    versions : dict
        Package versions (legends).
    """

    settings: dict
    rows: list
    geometry: dict
    compile_s: dict
    poses: NearContactPoses
    predictions: dict = field(default_factory=dict)
    versions: dict = field(default_factory=dict)

    def row(self, method, n=None):
        """The row of ``method`` at ``n`` (``n`` ignored for ``fcl_cylinder``)."""
        for r in self.rows:
            if r["method"] == method and (method == "fcl_cylinder" or r["n"] == n):
                return r
        raise KeyError(f"no row for method {method!r}, n={n}")


def method_labels(versions):
    """Legend text per method, naming versions.

    Parameters
    ----------
    versions : dict
        Package versions (``prismbatch``, ``python-fcl``).

    Returns
    -------
    dict
        Method key -> label.
    """
    pbv = versions.get("prismbatch") or "?"
    fv = versions.get("python-fcl") or "?"
    return {
        "pb64_batch": f"prismbatch {pbv} float64, batch call (1 thread)",
        "pb64_pair": f"prismbatch {pbv} float64, single query (collide_pair)",
        "pb32_batch": f"prismbatch {pbv} float32, batch call (1 thread)",
        "pb32_pair": f"prismbatch {pbv} float32, single query (collide_pair)",
        "fcl_ngon": f"python-fcl {fv} Convex n-gon prism (libccd GJK)",
        "fcl_cylinder": f"python-fcl {fv} Cylinder (exact shape, libccd GJK)",
    }
