"""The experiment's constants, the paper's reported values and the result record.

See docs/methods/experiment.md.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: Object a: number of end-face vertices and side length (mm).
PRISMS = {"square": (4, 3.0), "triangle": (3, 2.8)}
PLANTS = ("velocity", "force")
#: Where detach takes a contact from (see :func:`run_experiment`).
CONTACT_FROM = ("distance", "collide")

#: The instants of the paper's Fig. 10 (projected contours), in s.
FIG10_TIMES = (0.0, 1.0, 2.0, 3.0, 3.5, 4.0, 5.0, 5.9)

#: What the paper reports for the experiment (Sec. VI-B, Figs. 9-11), for comparison only.
PAPER = {
    "case_sequence": [5, 6, 1],
    "fig10_cases": [5, 5, 5, 6, 6, 6, 6, 6],  # "the first three contours correspond to case 5; the rest to case 6"
    "case1_after_s": 6.0,
    "collision_s": 3.5,
    "contact_class": 4,  # "the contact point lies on the side face"
    "collisions": 1,
    "detection_ms": 121.0,
    "swift_ms": 3375.0,
}

UM = 1e-3  # 1 µm in mm


@dataclass
class ExperimentResult:
    """Everything one run produced. Arrays have one row per sample (``n_steps + 1``).

    Positions are in mm, inputs in mm/s (velocity plant) or mN (force plant);
    :func:`format_summary` and :func:`write_experiment` convert to µm, µm/s, µN.
    """

    params: dict
    t: np.ndarray  # (N,) s
    dc: np.ndarray  # (N, 3) ΔC = b's end-face centre - a's, mm
    case: np.ndarray  # (N,) int8, pb.CASES
    hit: np.ndarray  # (N,) bool
    contact_class: np.ndarray  # (N,) int8, CONTACT_CLASSES (0: no hit)
    contact: np.ndarray  # (N, 3) contact point, world mm (NaN: no hit)
    direction: np.ndarray  # (N, 3) detach direction (NaN: no hit)
    u_pd: np.ndarray  # (N, 3) attraction (PD) input
    u_d: np.ndarray  # (N, 3) detach input (0 where no hit)
    detect_s: np.ndarray  # (N,) time of the per-sample collide call, s
    geometry: dict  # shapes and poses: xy_a, xy_b, xy_b_real, pos_a, rot_a, rot_b
    summary: dict = field(default_factory=dict)
    timing: dict = field(default_factory=dict)
    alarm: dict = field(default_factory=dict)  # collision alarm (alarm.collision_alarm); empty if not run

    @property
    def error(self):
        """(N,) |x - x_d| in mm."""
        return np.linalg.norm(self.dc - np.asarray(self.params["xd_um"]) * UM, axis=1)


def batch_poses(geometry):
    """a's position and both rotations of a run's ``geometry`` as contiguous one-pair batches."""
    pa1 = geometry["pos_a"].reshape(1, 3)
    ra1 = np.ascontiguousarray(geometry["rot_a"].reshape(1, 3, 3))
    rb1 = np.ascontiguousarray(geometry["rot_b"].reshape(1, 3, 3))
    return pa1, ra1, rb1
