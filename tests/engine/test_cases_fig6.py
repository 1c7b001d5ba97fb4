"""The paper's Fig. 6 scene: a constructed pose for every case, hit and miss.

a = regular pentagon, circumradius 2, axis down (d_a = [0, 0, -1]) at the
origin, so a's half-space is z <= 0. b = regular hexagon, circumradius 2.5.
Every pose is also checked against the LP reference (tests/reference.py).
"""

import numpy as np
import pytest

import prismbatch as pb

from reference import margin_lp

A = pb.Prism.regular(5, 2.0)
B = pb.Prism.regular(6, 2.5)
DOWN = np.diag([1.0, -1.0, -1.0])


def ry(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rz(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


TH = 0.3  # tilt of b's axis for the non-perpendicular touching cases
R_EDGE = rz(np.pi / 6)  # hexagon turned so that an edge (not a vertex) is extreme along x
X_EDGE = 2.5 * np.cos(np.pi / 6)  # distance of that edge from the centre

# name -> (pos_b, rot_b, expected case, expected hit)
SCENES = {
    # Case 1: b entirely above a's plane, bodies facing away.
    "c1": ([0.5, 0.2, 1.0], np.eye(3), 1, False),
    # Case 2: b tilted about y so the vertex at local +x is lowest, put on the plane.
    "c2_hit": ([-2.5 * np.cos(TH), 0.3, 2.5 * np.sin(TH)], ry(TH), 2, True),
    "c2_miss": ([5 - 2.5 * np.cos(TH), 0.0, 2.5 * np.sin(TH)], ry(TH), 2, False),
    # Case 3: an edge of b on the plane.
    "c3_hit": ([-X_EDGE * np.cos(TH), 0.0, X_EDGE * np.sin(TH)], ry(TH) @ R_EDGE, 3, True),
    "c3_miss": ([4.0 - X_EDGE * np.cos(TH), 0.0, X_EDGE * np.sin(TH)], ry(TH) @ R_EDGE, 3, False),
    # Case 4: end faces coplanar.
    "c4_hit": ([1.0, -0.5, 0.0], np.eye(3), 4, True),
    "c4_hit_rim": ([4.3, 0.0, 0.0], np.eye(3), 4, True),
    "c4_apart": ([-4.3, 0.0, 0.0], np.eye(3), 4, False),
    # Case 5: b dips below the plane but far to the side: coarse test rejects.
    "c5": ([9.0, 3.0, -0.5], ry(0.2), 5, False),
    # Case 6: b dips below the plane, fine polygon test needed.
    "c6_hit": ([0.5, 0.5, -0.5], ry(0.2), 6, True),
    "c6_miss": ([-4.3, 0.0, -0.1], ry(0.05), 6, False),
    # Case 7: perpendicular axes (d_b = +x), one vertex on the plane: half-line.
    "c7_hit": ([-5.0, 0.0, 2.5], ry(np.pi / 2), 7, True),
    "c7_miss": ([3.0, 0.0, 2.5], ry(np.pi / 2), 7, False),
    # Case 8: perpendicular axes, an edge on the plane: unbounded strip.
    "c8_hit": ([-6.0, 1.0, X_EDGE], ry(np.pi / 2) @ R_EDGE, 8, True),
    "c8_miss": ([-6.0, 3.5, X_EDGE], ry(np.pi / 2) @ R_EDGE, 8, False),
    # Case 9: perpendicular axes, b reaches below the plane (Δ3 > 0).
    "c9_hit": ([-5.0, 0.0, 1.0], ry(np.pi / 2), 9, True),
    "c9_miss": ([2.05, 0.0, 1.0], ry(np.pi / 2), 9, False),
    # Case 10 (added): b's axis points into a's half-space; end face above the
    # plane, body comes back through it.
    "c10_hit": ([0.5, 0.0, 1.0], DOWN, 10, True),
    "c10_tilted_hit": ([-6.0, 0.0, 2.0], ry(np.pi - 0.6), 10, True),
    "c10_miss": ([9.0, 0.0, 1.0], DOWN, 10, False),
    # Case 11 (added): b's axis points into a's half-space and its end face
    # already crosses the plane.
    "c11_hit": ([0.0, 1.0, -1.0], ry(np.pi - 0.2), 11, True),
    "c11_miss": ([0.0, 9.0, -1.0], ry(np.pi - 0.2), 11, False),
}


@pytest.mark.parametrize("name", sorted(SCENES))
def test_fig6_scene_case_and_hit(name):
    pos_b, rot_b, case, hit = SCENES[name]
    r = pb.collide(A, B, np.zeros(3), DOWN, pos_b, rot_b, contact=True)
    assert int(r.case[0]) == case, (name, pb.CASES[int(r.case[0])])
    assert bool(r.hit[0]) == hit
    margin = margin_lp(A.xy, np.zeros(3), DOWN, B.xy, np.asarray(pos_b, float), rot_b)
    if hit:
        assert margin >= -1e-9  # touching (margin 0) or overlapping
        assert np.all(np.isfinite(r.contact[0]))
    else:
        assert margin < -1e-6
        assert np.all(np.isnan(r.contact[0]))


def test_every_case_is_constructed():
    assert {s[2] for s in SCENES.values()} == set(pb.CASES)


def test_touching_cases_report_contact_on_the_plane():
    # Cases 2, 3, 7, 8 touch a's end plane: the contact lies on it (z = 0).
    for name in ("c2_hit", "c3_hit", "c7_hit", "c8_hit"):
        pos_b, rot_b, _, _ = SCENES[name]
        r = pb.collide(A, B, np.zeros(3), DOWN, pos_b, rot_b, contact=True)
        assert abs(r.contact[0, 2]) < 1e-7, name  # within the pair tolerance (~1e-8)


def test_case2_contact_is_the_touching_vertex():
    pos_b, rot_b, _, _ = SCENES["c2_hit"]
    r = pb.collide(A, B, np.zeros(3), DOWN, pos_b, rot_b, contact=True)
    vertex = np.asarray(pos_b) + rot_b @ np.array([2.5, 0.0, 0.0])
    np.testing.assert_allclose(r.contact[0], vertex, atol=1e-9)
