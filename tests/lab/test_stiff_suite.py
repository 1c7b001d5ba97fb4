"""The stiff and extreme suite (prismbatch.lab.stiff): its ground truth, its verdicts, its report.

The constructions are checked against the independent LP; the suite's
verdicts against the documented tolerances; and the suite must notice
planted wrong answers and NaN contacts (so a clean report means something).
"""

import math

import numpy as np
import pytest

import prismbatch as pb
import prismbatch.lab.stiff as st

from reference import margin_lp, point_in_prism_residual

pytestmark = [pytest.mark.slow]


@pytest.fixture(scope="module")
def quick_report():
    return st.run_stiff_suite(quick=True, seed=3)


def test_quick_suite_float64_clean_and_complete(quick_report):
    r = quick_report
    want = {(f, float(v), dt) for f, spec in st.FAMILIES.items() for v in spec[1] for dt in ("float64", "float32")}
    assert {(x["family"], x["value"], x["dtype"]) for x in r.rows} == want
    f64 = [x for x in r.rows if x["dtype"] == "float64"]
    assert all(x["pairs"] > 0 for x in r.rows)
    assert sum(x["non_finite"] for x in f64) == 0
    assert sum(x["disagreements_outside_band"] for x in f64) == 0
    assert sum(x["unresolved"] for x in f64) == 0
    assert r.ok
    # every family decides something on both sides (no family of all hits or all misses)
    for fam in st.FAMILIES:
        rows = [x for x in f64 if x["family"] == fam]
        assert 0 < sum(x["hits"] for x in rows) < sum(x["pairs"] for x in rows), fam


def test_float32_departs_exactly_between_the_two_tolerances(quick_report):
    # separation s = gap / S: float64 (tol 1e-9 S) must hit s <= 1e-10 and miss s >= 3e-9;
    # float32 (tol 1e-5 S, plus ~1e-7 S of pose rounding) hits everything up to 1e-6.
    sep = {(x["value"], x["dtype"]): x for x in quick_report.rows if x["family"] == "separation"}
    for (s, dt), x in sep.items():
        if dt == "float64":
            assert x["departures"] == 0
            if s <= 1e-10:
                assert x["hits"] == x["pairs"], s
            if s >= 3e-9:
                assert x["hits"] == 0, s
        else:
            assert x["disagreements_outside_band"] == 0, s
            if s <= 1e-6:
                assert x["hits"] == x["pairs"], s
            if 3e-9 <= s <= 1e-6:
                assert x["departures"] == x["departures_hit"] == x["pairs"], s
                assert math.isclose(x["max_departure_rel"], s, rel_tol=1e-3)
                assert 0.5 * s / 1e-9 < x["max_departure_tol64"] <= s / 1e-9 * (1 + 1e-6)
            if s >= 1e-4:
                # a hit here is only allowed where the float32-rounded bodies are certified to touch
                # (nearly parallel axes whose tilt direction the rounding turned towards a)
                assert x["hits"] == x["rounding_explained"] == x["departures"], s


def test_report_outputs(quick_report, tmp_path):
    r = quick_report
    lines = r.summary_lines()
    assert lines and all(isinstance(s, str) for s in lines)
    md = r.markdown()
    assert "### float64" in md and "### Where float32 departs" in md and "storage" in md
    assert md.count("\n| separation |") == 2 * len(st.FAMILIES["separation"][1])
    ((header, rows),) = r.csv_tables().values()
    assert len(rows) == len(r.rows) and all(len(row) == len(header) for row in rows)
    j = r.json()
    assert j["ok"] is True and len(j["rows"]) == len(r.rows) and "versions" in j["meta"]
    files = st.write_stiff_report(r, tmp_path)
    assert all((tmp_path / f).exists() for f in ("stiff.csv", "stiff.json", "stiff.md")) and len(files) == 3


def _draw(rng, n):
    return [st.random_polygon(rng, radius=float(rng.uniform(0.5, 2))) for _ in range(n)]


def _check_against_lp(ps, label, overlap_depth=True):
    S = np.array(
        [
            st.pair_scale(ps.polys_a[k], ps.pos_a[k], ps.rot_a[k], ps.polys_b[k], ps.pos_b[k], ps.rot_b[k])
            for k in range(len(ps))
        ]
    )
    for k in range(len(ps)):
        m = margin_lp(ps.polys_a[k], ps.pos_a[k], ps.rot_a[k], ps.polys_b[k], ps.pos_b[k], ps.rot_b[k])
        g = ps.gap[k]
        if g > 1e-6 * S[k]:
            assert m < 0 and 2 * abs(m) <= g * (1 + 1e-6) + 1e-9 * S[k], (label, k, g, m)  # gap >= 2 |margin|
            plane = st.plane_certificate(
                ps.polys_a[k], ps.pos_a[k], ps.rot_a[k], ps.polys_b[k], ps.pos_b[k], ps.rot_b[k]
            )
            # a lower bound (SAT normals, not necessarily the closest direction) that never exceeds the gap
            assert 0 < plane <= g * (1 + 1e-6) + 1e-12 * S[k], (label, k, g, plane)
        elif g < -1e-6 * S[k]:
            # coplanar end faces overlap in a slab a few ulp thick: the LP sees them touching
            assert m > 0 if overlap_depth else m > -1e-12 * S[k], (label, k, g, m)


@pytest.mark.parametrize("kind", ["face", "side", "coplanar"])
def test_constructions_agree_with_the_lp(kind):
    rng = np.random.default_rng(7)
    n = 24
    seps = np.tile([-1e-3, -1e-4, 1e-4, 1e-3], n // 4)
    A = _draw(rng, n)
    if kind == "face":
        rots = [
            st._with_axis(np.array([np.sin(t) * np.cos(a), np.sin(t) * np.sin(a), np.cos(t)]), s)
            for t, a, s in rng.uniform(0, [np.pi / 2, 2 * np.pi, 2 * np.pi], (n, 3))
        ]
        ps = st.face_pairs(rng, A, _draw(rng, n), rots, seps)
    elif kind == "side":
        # slivers too: an overlap must stay inside a thin a
        A[::3] = [st.sliver_polygon(rng, 1e-6) for _ in A[::3]]
        ps = st.side_pairs(rng, A, _draw(rng, n), 10.0 ** rng.uniform(-8, -1, n), seps)
    else:
        ps = st.coplanar_pairs(rng, A, -2, seps)  # b's end plane 2 ulp inside a: overlaps are real
    assert np.all(np.sign(ps.gap) == np.sign(seps))
    _check_against_lp(ps, kind, overlap_depth=kind != "coplanar")


def test_face_construction_witness():
    # b's lowest vertex sits at the constructed height above a point of a's end face
    rng = np.random.default_rng(1)
    A, B = _draw(rng, 10), _draw(rng, 10)
    rots = [st._with_axis(np.array([0.6, 0.0, 0.8]), s) for s in rng.uniform(0, 6, 10)]
    ps = st.face_pairs(rng, A, B, rots, np.full(10, 1e-4))
    for k in range(10):
        W = ps.pos_b[k] + B[k] @ ps.rot_b[k][:, :2].T
        low = W[np.argmin(W[:, 2])]
        assert point_in_prism_residual(B[k], ps.pos_b[k], ps.rot_b[k], low) <= 1e-12
        foot = low - np.array([0, 0, ps.gap[k]])
        assert point_in_prism_residual(A[k], ps.pos_a[k], ps.rot_a[k], foot) <= 1e-12


def test_plane_certificate_on_a_known_gap_and_an_overlap():
    sq = np.array([[-1.0, -1], [1, -1], [1, 1], [-1, 1]])
    down = np.diag([1.0, -1, -1])
    for h in (1e-12, 1e-6, 0.5):
        g = st.plane_certificate(sq, np.zeros(3), down, sq, np.array([0.3, 0.2, h]), np.eye(3))
        assert math.isclose(g, h, rel_tol=1e-9, abs_tol=1e-15)
    # b's axis tilted back down through a's plane far away: b is bounded along no plane
    tilt = st.axis_rotation([1.0, 0, 0], np.pi - 1e-3)
    assert st.plane_certificate(sq, np.zeros(3), down, sq, np.array([0, 0, 0.5]), tilt) < 0
    assert st.plane_certificate(sq, np.zeros(3), down, sq, np.array([0.5, 0, -0.5]), np.eye(3)) < 0


class _Wrong(pb.Collider):
    """A collider that answers the first pair of every batch wrongly (or with a NaN contact)."""

    mode = "flip"

    def collide(self, *args, **kw):
        r = super().collide(*args, **kw)
        hit, contact = r.hit.copy(), r.contact.copy()
        if self.mode == "flip":
            hit[0] = not hit[0]
            contact[0] = np.nan if not hit[0] else np.zeros(3)
        else:
            k = int(np.argmax(hit))
            contact[k] = np.nan
        return pb.CollisionResult(hit, r.case, contact)


@pytest.mark.parametrize("mode", ["flip", "nan"])
def test_suite_notices_wrong_answers(monkeypatch, mode):
    monkeypatch.setattr(_Wrong, "mode", mode)
    monkeypatch.setattr(st, "Collider", _Wrong)
    r = st.run_stiff_suite(quick=True, families=["separation", "scale_lp"], dtypes=("float64",))
    assert not r.ok
    if mode == "nan":
        assert all(x["non_finite"] >= 1 for x in r.rows if x["hits"])
    else:
        # a flipped answer is caught unless it fell inside the band; the far-off separations never do
        far = [x for x in r.rows if x["family"] == "separation" and abs(x["value"]) >= 1e-4]
        assert far and all(x["disagreements_outside_band"] >= 1 for x in far)


def test_bad_arguments():
    with pytest.raises(ValueError, match="dtypes"):
        st.run_stiff_suite(quick=True, dtypes=("float16",))
    with pytest.raises(ValueError, match="dtypes"):
        st.run_stiff_suite(quick=True, dtypes=())
    with pytest.raises(ValueError, match="families"):
        st.run_stiff_suite(quick=True, families=["nope"])
    with pytest.raises(TypeError, match="seed"):
        st.run_stiff_suite(quick=True, seed="1")
