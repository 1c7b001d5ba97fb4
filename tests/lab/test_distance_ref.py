"""The signed-distance references (``prismbatch/lab/distance_ref.py``) against each other and against
cases with known answers: the feature brute force, the QP and the separating-axis bound bracket the same
gap; the reference bodies keep their orientation far from their origin; the separating-axis depth of an
analytic overlap. ``tests/engine/test_distance.py`` judges the kernels by these references."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import prismbatch as pb
from prismbatch.distance import distance
from prismbatch.lab.distance_ref import Body, gap_features, gap_qp, residual, sat_separation

from helpers import make_pairs, sliver_far_from_origin


def test_reference_gap_methods_agree():
    """Feature brute force, QP (HiGHS) and the SAT lower bound bracket the same gap."""
    rng = np.random.default_rng(101)
    d = make_pairs(rng, 60, "free", "smallmed")
    n_sep = 0
    for k in range(len(d)):
        A, B = Body(d.polys_a[k], d.pos_a[k], d.rot_a[k]), Body(d.polys_b[k], d.pos_b[k], d.rot_b[k])
        sep, _ = sat_separation(A, B)
        if sep <= 0:
            continue
        n_sep += 1
        S = d.scale[k]
        g = gap_features(A, B)
        qp, x, y, lower = gap_qp(A, B)
        assert sep <= g + 1e-12 * S  # SAT: a lower bound of the gap
        assert lower <= g + 1e-12 * S  # the QP's certificate: a lower bound too
        assert g <= qp + 1e-7 * S  # the QP's points are (to its feasibility) in the bodies
        assert qp - lower <= 1e-6 * S  # ... and its certificate closes the bracket
        assert max(residual(A, x[None])[0], residual(B, y[None])[0]) <= 1e-6 * S
    assert n_sep >= 20


def test_reference_body_orients_a_sliver_far_from_the_origin():
    """A counter-clockwise sliver about 1.5e5 from its origin, whose plain shoelace sum rounds negative:
    the reference body keeps its orientation, so a point inside has a negative residual."""
    xy = sliver_far_from_origin()
    body = Body(xy, np.zeros(3), np.eye(3))
    inside = np.array([[*xy.mean(axis=0), 1.0]])
    assert residual(body, inside)[0] < 0 < residual(body, inside + [0.0, 0.0, -2.0])[0]


def test_reference_sat_on_an_analytic_overlap():
    """Identical prisms in the same pose: the shortest way out is sideways, by the polygon's minimum width."""
    for n, R in ((4, 1.0), (6, 2.0), (5, 1.5), (7, 0.5)):
        xy = np.column_stack([R * np.cos(2 * np.pi * np.arange(n) / n), R * np.sin(2 * np.pi * np.arange(n) / n)])
        width = 2 * R * np.cos(np.pi / n) if n % 2 == 0 else R * (1 + np.cos(np.pi / n))
        Q = Rotation.from_rotvec([0.3, -0.2, 0.9]).as_matrix()
        sep, _ = sat_separation(Body(xy, [1.0, 2.0, 3.0], Q), Body(xy, [1.0, 2.0, 3.0], Q))
        assert sep == pytest.approx(-width, rel=1e-12)
        r = distance(pb.Prism(xy), pb.Prism(xy), [1.0, 2.0, 3.0], Q, [1.0, 2.0, 3.0], Q)
        assert r.distance[0] == pytest.approx(-width, abs=10 * r.tol[0])


def test_the_qp_solver_prints_nothing():
    """highspy's constructor writes a licence banner to file descriptor 1 in a fresh process; the lab's
    solvers must not (``prismbatch validate ... > report`` had it in the report)."""
    import subprocess
    import sys

    code = "from prismbatch.lab.highs import new_highs; new_highs(1.0); new_highs(1.0); print('done')"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out == "done\n"


def test_float32_rotations_read_as_float64_against_the_exact_gap():
    """A float32 rotation read in float64 is orthonormal only to about 1e-7, and the package takes it as the
    exact linear map it is. The references must too: with side normals mapped by R instead of its inverse
    transpose, their gaps were up to 6 tol off the exact gap (rational arithmetic) and their depths up to 20
    tol off prismbatch's. Separated pairs against the exact bounds; overlapping ones by their sign."""
    import math

    from prismbatch.lab.distance_ref import signed_distance_reference
    from prismbatch.lab.exact_gap import gap_bounds

    rng = np.random.default_rng(7)
    a, b = pb.Prism.regular(5, 1.0), pb.Prism.regular(6, 1.3, phase=0.2)
    n_sep = 0
    for k in range(40):
        f32 = lambda x: np.asarray(x, dtype=np.float32).astype(float)  # noqa: E731
        ra = f32(Rotation.random(random_state=rng.integers(1 << 30)).as_matrix())
        rb = ra if k % 3 == 0 else f32(Rotation.random(random_state=rng.integers(1 << 30)).as_matrix())
        pa = f32(rng.uniform(-3, 3, 3))
        pb_ = f32(pa + rng.uniform(-3, 3, 3))
        tol = distance(a, b, *(np.float32(x) for x in (pa, ra, pb_, rb))).tol[0]
        value, kind = signed_distance_reference(a.xy, pa, ra, b.xy, pb_, rb)
        g = gap_bounds(a.xy, pa, ra, b.xy, pb_, rb)
        if g.lo > 0:
            n_sep += 1
            assert kind == "features", k
            assert math.sqrt(g.lo) - 1e-3 * tol <= value <= math.sqrt(g.hi) + 1e-3 * tol, k
        else:
            assert value <= tol, k
    assert n_sep >= 15
