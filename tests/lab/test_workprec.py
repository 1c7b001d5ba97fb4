"""Work-precision study (prismbatch/workprec.py): exact labels, contract, statistics, files.

The labels of the near-contact construction are checked three independent ways:
analytically from the stored poses (b's vertex inside the exact cylinder for hits;
a separating plane for misses), and with the LP reference on polygons that
bracket the cylinder (inscribed for hits, circumscribed for misses).
"""

import json
import math

import numpy as np
import pytest

from prismbatch.lab.exact import margin_lp, point_in_prism_residual, polygon_halfplanes
from prismbatch.lab.workprec import (
    METHODS,
    fit_order,
    format_work_precision,
    geometric_error,
    near_contact_poses,
    noise_floor,
    run_work_precision,
    vertices_needed,
    wilson_interval,
    write_work_precision,
)
from prismbatch.shapes import Prism

pytestmark = [pytest.mark.slow, pytest.mark.needs_fcl]

VERTS = (8, 128, 10000)
N_POSES = 3000
B = Prism.regular(6, 1.25)


@pytest.fixture(scope="module")
def result():
    return run_work_precision(vertices=VERTS, n_poses=N_POSES, repeats=1, seed=3, progress=False)


def _b_vertices_world(P, xy):
    return P.pos_b[:, None, :] + np.einsum("nij,kj->nki", P.rot_b[:, :, :2], xy)


def _pb_tolerance(P, rtol, eps, ra=1.0, rb=1.25):
    """README's pair tolerance, written out here (regular polygons: centre = local origin)."""
    ca, cb = P.pos_a, P.pos_b
    return rtol * (ra + rb + np.linalg.norm(cb - ca, axis=1)) + 4 * eps * (
        np.linalg.norm(ca, axis=1) + np.linalg.norm(cb, axis=1)
    )


def test_labels_exact_from_the_cylinder_geometry():
    P = near_contact_poses(2000, np.random.default_rng(11))
    r = P.radius
    d_a = P.rot_a[:, :, 2]
    d_b = P.rot_b[:, :, 2]
    u = P.u
    assert np.allclose(np.linalg.norm(u, axis=1), 1.0)
    assert np.all(np.sum(u * d_a, axis=1) < -0.17)  # finite support, away from edge-on
    assert np.all(np.sum(u * d_b, axis=1) > 0.49)  # b's body leaves in +u: its lowest point is on the end face
    # the cylinder's support value in u, by brute force over its rim (its body recedes: u . d_a < 0)
    th = np.linspace(0, 2 * np.pi, 10001)
    u_loc = np.einsum("nji,nj->ni", P.rot_a, u)
    h_a = np.max(u_loc[:, :2] @ np.stack([r * np.cos(th), r * np.sin(th)]), axis=1) + np.sum(u * P.pos_a, axis=1)
    # analytic value r |u_xy| (local) bounds the sampled one from above, to rim sampling
    h_exact = r * np.sqrt(1 - np.sum(u * d_a, axis=1) ** 2)
    assert np.all(h_a <= h_exact + 1e-15) and np.all(h_exact - h_a < 1e-7)
    low_b = np.min(np.einsum("nki,ni->nk", _b_vertices_world(P, B.xy), u), axis=1)
    miss = ~P.hit
    # misses: a separating plane with exactly the sampled gap between the support values
    assert np.allclose(low_b[miss] - h_exact[miss], P.gap[miss], rtol=1e-6, atol=1e-14)
    assert np.all(low_b[miss] - h_exact[miss] > 0)
    # hits: b's vertex strictly inside the exact cylinder, at depth |g| min(sin b, cos b)
    v = np.einsum("nji,nj->ni", P.rot_a, _b_vertices_world(P, B.xy)[np.arange(len(P)), P.vertex] - P.pos_a)
    depth = np.minimum(v[:, 2], r - np.hypot(v[:, 0], v[:, 1]))
    hit = P.hit
    assert np.all(depth[hit] > 0)
    expect = -P.gap[hit] * np.minimum(np.sin(P.beta[hit]), np.cos(P.beta[hit]))
    assert np.allclose(depth[hit], expect, rtol=1e-6, atol=1e-15)
    assert np.allclose(P.depth_in_cylinder(B), depth, rtol=0, atol=1e-15)
    # gaps: both signs, log-uniform over the requested decades
    assert 0.4 < hit.mean() < 0.6
    lg = np.log10(np.abs(P.gap) / r)
    assert lg.min() >= -8 and lg.max() <= -1 and np.ptp(lg) > 6.5


def test_labels_agree_with_lp_on_bracketing_polygons():
    """Hits overlap the inscribed 1024-gon, misses miss the circumscribed one (LP, |g| >= 1e-3 r)."""
    n = 1024
    P = near_contact_poses(40, np.random.default_rng(5), gap_range=(1e-3, 1e-1))
    inner = Prism.regular(n, 1.0).xy
    outer = Prism.regular(n, 1.0 / math.cos(math.pi / n)).xy
    for k in range(len(P)):
        args = (P.pos_a[k], P.rot_a[k], B.xy, P.pos_b[k], P.rot_b[k])
        if P.hit[k]:
            assert margin_lp(inner, *args) > 1e-7
        else:
            assert margin_lp(outer, *args) < -1e-7


def test_depth_in_ngon_matches_point_residual():
    P = near_contact_poses(300, np.random.default_rng(2), gap_range=(1e-6, 1e-1))
    for n in (8, 360):
        xy = Prism.regular(n, 1.0).xy
        vw = _b_vertices_world(P, B.xy)[np.arange(len(P)), P.vertex]
        res = np.array([point_in_prism_residual(xy, P.pos_a[k], P.rot_a[k], vw[k]) for k in range(len(P))])
        d = P.depth_in_ngon(B, n)
        inside = res < 0
        assert np.array_equal(inside, d > 0)
        assert np.allclose(-res[inside], d[inside], atol=1e-13)


def test_prismbatch_float64_keeps_its_contract_and_is_right_away_from_the_band(result):
    P = result.poses
    tol = _pb_tolerance(P, 1e-9, np.finfo(float).eps)
    vw = _b_vertices_world(P, B.xy)[np.arange(len(P)), P.vertex]
    v = np.einsum("nji,nj->ni", P.rot_a, vw - P.pos_a)  # b's vertex in a's frame
    for n in VERTS:
        nrm, h = polygon_halfplanes(Prism.regular(n, 1.0).xy)  # the LP reference's half-planes
        depth = -np.maximum(-v[:, 2], np.max(v[:, :2] @ nrm.T - h, axis=1))
        for m in ("pb64_batch", "pb64_pair"):
            h = result.predictions[(m, n)]
            assert np.all(h[depth > tol]), (m, n)  # b's vertex inside the n-gon: must hit
            assert not np.any(h[P.gap > 2 * tol]), (m, n)  # a true gap beyond 2 tol: must miss
    # the large n-gon: every label right once |g| is well above its geometric error (4.9e-8 r)
    h = result.predictions[("pb64_batch", 10000)]
    far = np.abs(P.gap) > 1e-6
    assert far.sum() > 0.6 * len(P)
    assert np.array_equal(h[far], P.hit[far])
    # a coarse n-gon misses near hits: the inscribed 8-gon loses most of them
    assert result.row("pb64_batch", 8)["fn"] > 0.5 * P.hit.sum()
    assert result.row("pb64_batch", 8)["fp"] == 0


def test_float32_errors_lie_within_its_tolerance_band(result):
    P = result.poses
    tol32 = _pb_tolerance(P, 1e-5, float(np.finfo(np.float32).eps))
    for n in VERTS:
        h = result.predictions[("pb32_batch", n)]
        fp = h & ~P.hit
        assert np.all(P.gap[fp] <= 2 * tol32[fp])
        np.testing.assert_array_equal(h, result.predictions[("pb32_pair", n)])
    # with the fine n-gon its rtol 1e-5 turns near misses into hits (a safe misclassification)
    assert result.row("pb32_batch", 10000)["fp"] > 0


def test_rows_recount_and_intervals_bracket(result):
    P = result.poses
    assert {r["method"] for r in result.rows} == set(METHODS)
    assert len(result.rows) == 5 * len(VERTS) + 1
    for r in result.rows:
        h = result.predictions[(r["method"], r["n"])]
        fn = int(np.sum(P.hit & ~h))
        fp = int(np.sum(~P.hit & h))
        assert (r["fn"], r["fp"], r["wrong"]) == (fn, fp, fn + fp)
        assert r["rate"] == pytest.approx((fn + fp) / len(P))
        assert r["ci_low"] <= r["rate"] <= r["ci_high"]
        assert r["fn_ci_low"] <= r["fn_rate"] <= r["fn_ci_high"]
        assert r["t_median_us"] > 0 and r["t_min_us"] <= r["t_median_us"] <= r["t_max_us"]
    np.testing.assert_array_equal(result.predictions[("pb64_batch", 128)], result.predictions[("pb64_pair", 128)])
    # the exact-shape FCL peer: the same poses, no geometric error; it errs only in a thin band
    cyl = result.row("fcl_cylinder")
    wrong = result.predictions[("fcl_cylinder", None)] != P.hit
    assert cyl["n"] is None and cyl["geom_rel_error"] == 0.0
    assert np.all(np.abs(P.gap[wrong]) < 1e-3)


def test_wilson_interval_against_scipy():
    stats = pytest.importorskip("scipy.stats")
    for k, n in ((0, 50), (3, 50), (25, 50), (50, 50), (7, 20000)):
        lo, hi = wilson_interval(k, n)
        ci = stats.binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
        assert lo == pytest.approx(ci.low, abs=1e-12) and hi == pytest.approx(ci.high, rel=1e-9, abs=1e-12)
    assert noise_floor(1000) == pytest.approx(wilson_interval(0, 1000)[1])
    with pytest.raises(ValueError, match="k must"):
        wilson_interval(5, 3)


def test_geometric_error_order_and_vertices_needed(result):
    g = result.geometry
    assert g["order"] == pytest.approx(2.0, abs=0.01)
    n = np.array([8, 100, 3600, 100000])
    assert np.allclose(geometric_error(n), 1 - np.cos(np.pi / n), rtol=1e-6)
    p, c = fit_order(n, 3.0 * n**-1.5)
    assert p == pytest.approx(1.5) and c == pytest.approx(3.0)
    for e in (1e-2, 1e-6, 3e-9):
        k = vertices_needed(e)
        assert geometric_error(k) <= e < geometric_error(k - 1)


def test_files_written(result, tmp_path):
    paths = write_work_precision(result, tmp_path)
    for key in ("csv", "geometry_csv", "json", "markdown"):
        assert (tmp_path / paths[key].split("/")[-1]).stat().st_size > 0
    lines = (tmp_path / "workprec.csv").read_text().splitlines()
    assert len(lines) == 1 + len(result.rows)
    assert lines[0].split(",")[:4] == ["method", "label", "shape", "n"]
    assert len((tmp_path / "workprec_geometry.csv").read_text().splitlines()) == 1 + len(VERTS)
    meta = json.loads((tmp_path / "workprec.json").read_text())
    assert meta["fitted_order"] == pytest.approx(result.geometry["order"])
    assert meta["seeds"]["poses"] == 3 and meta["versions"]["prismbatch"]
    names = sorted(p.split("/")[-1] for p in paths["figures"])
    assert names == [
        "workprec_error_vs_n.png",
        "workprec_error_vs_n.svg",
        "workprec_error_vs_time.png",
        "workprec_error_vs_time.svg",
    ]
    assert all((tmp_path / f).stat().st_size > 10_000 for f in names)
    text = "\n".join(format_work_precision(result))
    assert "fitted order" in text and "fcl_cylinder" in text


def test_bad_arguments():
    with pytest.raises(ValueError, match="vertices"):
        run_work_precision(vertices=[2, 8], n_poses=10, progress=False)
    with pytest.raises(TypeError, match="vertices"):
        run_work_precision(vertices=[8.5], n_poses=10, progress=False)
    with pytest.raises(ValueError, match="n_poses"):
        run_work_precision(vertices=[8], n_poses=1, progress=False)
    with pytest.raises(ValueError, match="radius"):
        run_work_precision(vertices=[8], n_poses=10, radius=-1.0, progress=False)
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="gap_range"):
        near_contact_poses(5, rng, gap_range=(0.0, 1e-1))
    with pytest.raises(ValueError, match="beta_range"):
        near_contact_poses(5, rng, beta_range=(0.0, 1.0))
    with pytest.raises(TypeError, match="rng"):
        near_contact_poses(5, 0)
    with pytest.raises(TypeError, match="result"):
        write_work_precision({}, "unused")


def test_without_fcl_the_rows_keep_their_shape():
    res = run_work_precision(vertices=(8, 64), n_poses=50, repeats=1, progress=False, fcl=False)
    assert [r["method"] for r in res.rows] == [m for m in METHODS for _ in range(1 if m == "fcl_cylinder" else 2)]
    fcl_rows = [r for r in res.rows if r["method"].startswith("fcl")]
    assert all(math.isnan(r["rate"]) and math.isnan(r["t_median_us"]) for r in fcl_rows)
    assert all(math.isfinite(r["rate"]) for r in res.rows if r["method"].startswith("pb"))
    assert any("fcl_ngon" in line and " - " in line for line in format_work_precision(res))
