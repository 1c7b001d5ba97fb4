"""The timing study (prismbatch.lab.study) on a tiny scene: structure, consistency, files.

No timing thresholds: only that every measurement is there, positive and
internally consistent, that the peers agree with prismbatch away from touching
configurations, and that the growth fit recovers known slopes.
"""

import csv
import json

import numpy as np
import pytest

import prismbatch as pb
from prismbatch.lab import study
from prismbatch.lab.casegen import CASE_NUMBERS, EXACT_CASES, HIT_AND_MISS_CASES, case_poses
from prismbatch.lab.study import fit_growth, format_study, run_study, write_study

from reference import margin_lp

pytestmark = [pytest.mark.slow, pytest.mark.needs_fcl, pytest.mark.needs_coal]

VERTS = (8, 24, 60)
POSES = 10


@pytest.fixture(scope="module")
def res():
    return run_study(
        vertices=VERTS,
        cases=CASE_NUMBERS,
        poses_per_case=POSES,
        repeats=2,
        batch_pairs=64,
        progress=False,
        lp_checks=3,
        table_vertices=24,
    )


def test_every_cell_timed_for_every_method(res):
    peers = [p for p in ("fcl", "coal") if p in res.methods]
    assert "fcl" in peers  # python-fcl is a test dependency
    methods = ["prismbatch", "prismbatch_batch1", *peers]
    assert not res.missing
    for n in VERTS:
        for case in CASE_NUMBERS:
            for m in methods:
                rows = [r for r in res.latency if (r["case"], r["vertices"], r["method"]) == (case, n, m)]
                assert len(rows) == 1, (case, n, m)
                r = rows[0]
                assert r["poses"] == POSES and r["repeats"] == 2
                q = [r[k] for k in ("min_us", "q1_us", "median_us", "q3_us", "max_us")]
                assert np.all(np.isfinite(q)) and q[0] > 0 and q == sorted(q)
                assert r["thread_cpu_median_us"] > 0
    assert len(res.latency) == len(VERTS) * len(CASE_NUMBERS) * len(methods)


def test_hits_follow_casegen_and_peers_agree_off_touching(res):
    for r in res.latency:
        if r["method"] != "prismbatch":
            continue
        # casegen's contract: half hits in the hit-and-miss cases, none in 1 and 5
        want = round(POSES * 0.5) if r["case"] in HIT_AND_MISS_CASES else 0
        assert r["hits"] == want, r
    assert res.agreement
    for a in res.agreement:
        pb_hits = res_hits(res, "prismbatch", a)
        peer_hits = res_hits(res, a["peer"], a)
        assert a["pb_hits"] == pb_hits and a["peer_hits"] == peer_hits
        assert peer_hits == pb_hits - a["pb_hit_peer_miss"] + a["pb_miss_peer_hit"]
        assert a["disagreements"] == a["pb_hit_peer_miss"] + a["pb_miss_peer_hit"]
        if a["case"] in EXACT_CASES:
            # pb hits there are exact touching contacts: a peer may call them misses
            assert a["touching_exact"] == a["pb_hit_peer_miss"]
        else:
            # elsewhere a disagreement must be inside the LP's touching band
            assert a["touching_exact"] == 0
            assert a["disagreements"] == (a["lp_touching"] or 0), a


def res_hits(res, method, cell):
    return next(
        r["hits"]
        for r in res.latency
        if (r["method"], r["case"], r["vertices"]) == (method, cell["case"], cell["vertices"])
    )


def test_exact_case_disagreements_are_touching_by_lp(res):
    """Where a peer misses an exact-case hit, the independent LP margin is ~0 (touching)."""
    rows = [a for a in res.agreement if a["case"] in EXACT_CASES and a["pb_hit_peer_miss"]]
    if not rows:
        pytest.skip("no peer disagreed on a touching pose in this run")
    a = rows[0]
    n, case = a["vertices"], a["case"]
    A, B = pb.Prism.regular(n, study.RADIUS_A), pb.Prism.regular(n, study.RADIUS_B)
    P = case_poses(case, POSES, A, B, np.random.default_rng([res.settings["seed"], n, case]), hit_fraction=0.5)
    hit = pb.collide(A, B, *P).hit
    assert int(hit.sum()) == a["pb_hits"]  # the same poses the study timed
    for k in np.flatnonzero(hit)[:3]:
        assert abs(margin_lp(A.xy, P[0][k], P[1][k], B.xy, P[2][k], P[3][k])) <= 1e-7 * 10


def test_lp_adjudication_classifies_touching_right_and_wrong():
    pytest.importorskip("scipy")
    A, B = pb.Prism.regular(12, study.RADIUS_A), pb.Prism.regular(12, study.RADIUS_B)
    rng = np.random.default_rng(3)
    P4 = case_poses(4, 4, A, B, rng)  # hits of case 4: end faces coplanar, touching (margin 0)
    P6 = case_poses(6, 4, A, B, rng)  # case 6 hits overlap, misses are apart
    P = tuple(np.concatenate([x, y]) for x, y in zip(P4, P6))
    hit = pb.collide(A, B, *P).hit
    idx = np.arange(8)
    checked, touching, right, wrong = study._adjudicate(A, B, P, idx, hit, 8, 1e-9)
    m = np.array([margin_lp(A.xy, P[0][k], P[1][k], B.xy, P[2][k], P[3][k]) for k in idx])
    band = np.abs(m) <= 1e-7 * 10
    assert checked == 8 and touching == int(band.sum()) >= 2 and right == 8 - touching and wrong == 0
    # flipping prismbatch's answers turns every decided pose into a "wrong" one
    _, t2, r2, w2 = study._adjudicate(A, B, P, idx, ~hit, 8, 1e-9)
    assert (t2, r2, w2) == (touching, 0, right)
    assert study._adjudicate(A, B, P, idx, hit, 3, 1e-9)[0] == 3  # the limit holds


def test_throughput_rows(res):
    threads = res.settings["numba_threads"]
    for n in VERTS:
        for case in (*CASE_NUMBERS, "all"):
            rows = {r["mode"]: r for r in res.throughput if r["case"] == case and r["vertices"] == n}
            assert {"prismbatch_1t", "prismbatch_allt"} <= set(rows)
            assert rows["prismbatch_1t"]["threads"] == 1 and rows["prismbatch_allt"]["threads"] == threads
            for r in rows.values():
                assert 0 < r["min_pairs_per_s"] <= r["median_pairs_per_s"] <= r["max_pairs_per_s"]
            if case == "all":
                assert rows["fcl_loop"]["pairs"] == POSES * len(CASE_NUMBERS)
                assert rows["prismbatch_1t"]["pairs"] == 64


def test_table1_matches_latency_and_paper(res):
    rows = {r["case"]: r for r in res.table1}
    for case in CASE_NUMBERS:
        r = rows[case]
        pbt, fct = res.latency_us("prismbatch", case, 24), res.latency_us("fcl", case, 24)
        assert r["prismbatch_us"] == pbt and r["fcl_us"] == fct
        assert r["pb_over_fcl"] == pytest.approx(pbt / fct)
        if case <= 9:
            pp, ps = study.PAPER_TABLE1_MS["projection"][case], study.PAPER_TABLE1_MS["swift"][case]
            assert r["paper_ratio"] == pytest.approx(pp / ps)
            assert r["paper_projection_us"] == pytest.approx(1e3 * pp)
        else:
            assert r["paper_ratio"] is None
    avg = [r for r in res.table1 if isinstance(r["case"], str)]
    assert len(avg) == 1
    want = np.mean([res.latency_us("prismbatch", c, 24) for c in range(1, 10)])
    assert avg[0]["prismbatch_us"] == pytest.approx(want)
    # the paper's average: 0.2 ms vs 5 ms
    assert avg[0]["paper_projection_us"] == pytest.approx(
        1e3 * np.mean([0.03, 0.10, 0.17, 0.31, 0.09, 0.55, 0.12, 0.20, 0.29])
    )


def test_fit_growth_recovers_known_slope():
    n = np.array([36, 180, 360, 1800, 3600, 7200])
    slope, icpt, r2 = fit_growth(n, 3.0 + 0.037 * n)
    assert slope == pytest.approx(37.0) and icpt == pytest.approx(3.0) and r2 == pytest.approx(1.0)
    rng = np.random.default_rng(5)
    t = 10.0 + 1.3 * n + rng.normal(0.0, 5.0, n.size)
    slope, icpt, r2 = fit_growth(n, t)
    assert abs(slope - 1300.0) < 10.0 and abs(icpt - 10.0) < 20.0 and r2 > 0.99
    with pytest.raises(ValueError, match="distinct"):
        fit_growth([36, 36], [1.0, 2.0])
    with pytest.raises(ValueError, match="same length"):
        fit_growth([36, 72], [1.0])


def test_growth_rows_match_independent_fit(res):
    for g in res.growth:
        if g["series"] == "average":
            cases = [int(c) for c in g["cases"].split(",")]
            assert cases == list(range(1, 10))
            y = [np.mean([res.latency_us(g["method"], c, n) for c in cases]) for n in VERTS]
        else:
            y = [res.latency_us(g["method"], int(g["series"].split()[1]), n) for n in VERTS]
        b1, b0 = np.polyfit(VERTS, y, 1)
        assert g["slope_us_per_1000"] == pytest.approx(1000 * b1, rel=1e-6, abs=1e-9)
        assert g["intercept_us"] == pytest.approx(b0, rel=1e-6, abs=1e-9)
        c1, c0 = np.polyfit(np.log2(VERTS), y, 1)
        assert g["log_slope_us_per_doubling"] == pytest.approx(c1, rel=1e-6, abs=1e-9)
        assert g["log_intercept_us"] == pytest.approx(c0, rel=1e-6, abs=1e-9)
        assert g["model"] == ("log" if g["r2_log"] > g["r2"] else "linear")
        assert g["growth_factor"] == pytest.approx(y[-1] / y[0])
        if g["method"] == "prismbatch":
            other = next(h for h in res.growth if h["method"] == "fcl" and h["series"] == g["series"])
            if other["slope_us_per_1000"] > 0 and min(g["r2"], other["r2"]) >= 0.9:
                assert g["slope_ratio_vs_fcl"] == pytest.approx(g["slope_us_per_1000"] / other["slope_us_per_1000"])
            else:  # a slope of a line that does not hold is not compared
                assert g["slope_ratio_vs_fcl"] is None


def test_log_growth_is_told_apart_from_a_line():
    from prismbatch.lab.study.analysis import fit_log_growth

    n = np.array([36, 180, 360, 1800, 3600, 7200])
    per_doubling, icpt, r2 = fit_log_growth(n, 0.5 + 0.02 * np.log2(n))
    assert per_doubling == pytest.approx(0.02) and icpt == pytest.approx(0.5) and r2 == pytest.approx(1.0)
    # a log-shaped cost: the line fits worse than the log model
    t = 0.5 + 0.02 * np.log2(n)
    assert fit_growth(n, t)[2] < fit_log_growth(n, t)[2]


def test_format_study(res):
    lines = format_study(res)
    assert all(isinstance(x, str) for x in lines)
    text = "\n".join(lines)
    assert "Table I at 24 vertices" in text and "Growth with n" in text and "First call" in text
    assert res.compile["collide_pair_s"] >= 0 and res.compile["collide_parallel_s"] >= 0


def test_write_study_files(res, tmp_path):
    pytest.importorskip("matplotlib")
    paths = write_study(res, tmp_path)
    for key, cols, n in (
        ("latency", "median_us", len(res.latency)),
        ("throughput", "median_pairs_per_s", len(res.throughput)),
        ("growth", "slope_us_per_1000", len(res.growth)),
        ("table1", "pb_over_fcl", len(res.table1)),
        ("agreement", "disagreements", len(res.agreement)),
    ):
        with open(paths[key], newline="") as f:
            rows = list(csv.DictReader(f))
        assert len(rows) == n and cols in rows[0]
    with open(paths["latency"], newline="") as f:
        first = next(csv.DictReader(f))
    assert float(first["median_us"]) == pytest.approx(res.latency[0]["median_us"], rel=1e-5)
    meta = json.loads(open(paths["json"], encoding="utf-8").read())
    assert meta["settings"]["vertices"] == list(VERTS) and "collide_pair_s" in meta["compile_s"]
    assert meta["paper"]["table1_ms"]["swift"]["1"] == 5.03
    md = open(paths["markdown"], encoding="utf-8").read()
    assert "Table I" in md and "study_fig7c_average.png" in md
    names = {p.rsplit("/", 1)[-1] for p in paths["figures"]}
    for stem in (
        "study_fig7a_prismbatch",
        "study_fig7b_peers",
        "study_fig7c_average",
        "study_table1",
        "study_throughput",
    ):
        assert {f"{stem}.png", f"{stem}.svg"} <= names
    assert (tmp_path / "study_table1.png").stat().st_size > 1000


def test_missing_cases_are_reported():
    """A cell is missing exactly when casegen cannot build it (fine polygons, case 2)."""
    n = 12000
    r = run_study(
        vertices=(n,),
        cases=(2, 4),
        poses_per_case=4,
        repeats=1,
        batch_pairs=8,
        peers=(),
        progress=False,
        table_vertices=n,
    )
    A, B = pb.Prism.regular(n, study.RADIUS_A), pb.Prism.regular(n, study.RADIUS_B)
    for case in (2, 4):
        try:
            case_poses(case, 4, A, B, np.random.default_rng([0, n, case]))
            buildable = True
        except (ValueError, RuntimeError):
            buildable = False
        timed = r.latency_us("prismbatch", case, n) is not None
        listed = [m for m in r.missing if m["case"] == case and m["vertices"] == n]
        assert timed == buildable and bool(listed) == (not buildable)
        assert all(m["reason"] for m in listed)
    assert any(m["case"] == 2 for m in r.missing)  # the degenerate case needs coarser polygons
    assert next(t for t in r.table1 if t["case"] == 2)["missing"]
    assert not r.growth  # one vertex count: nothing to fit
    assert "missing: n=12000 case 2" in "\n".join(format_study(r))


def test_missing_peer_is_a_note(monkeypatch):
    from prismbatch.lab.peers import CoalPeer

    def no_coal():
        raise ImportError("coal is not installed (simulated)")

    monkeypatch.setattr(CoalPeer, "_import", staticmethod(no_coal))
    r = run_study(
        vertices=(8, 16), cases=(1, 6), poses_per_case=4, repeats=1, batch_pairs=8, progress=False, table_vertices=16
    )
    assert "coal" not in r.methods and "fcl" in r.methods
    assert any("coal skipped" in nt for nt in r.notes)
    assert all(t["coal_us"] is None and t["fcl_us"] is not None for t in r.table1)
    assert not [a for a in r.agreement if a["peer"] == "coal"]


@pytest.mark.parametrize(
    "kw, exc, word",
    [
        (dict(vertices=(2, 8)), ValueError, "vertices"),
        (dict(vertices=(8, 8)), ValueError, "vertices"),
        (dict(vertices=8), TypeError, "vertices"),
        (dict(cases=(0,)), ValueError, "cases"),
        (dict(poses_per_case=0), ValueError, "poses_per_case"),
        (dict(repeats=1.5), TypeError, "repeats"),
        (dict(peers=("swift",)), ValueError, "peers"),
        (dict(peers="fcl"), TypeError, "peers"),
        (dict(table_vertices=100), ValueError, "table_vertices"),
        (dict(seed=-1), ValueError, "seed"),
    ],
)
def test_bad_arguments(kw, exc, word):
    args = dict(vertices=(8, 16), poses_per_case=2, repeats=1, progress=False, table_vertices=16)
    args.update(kw)
    with pytest.raises(exc, match=word):
        run_study(**args)


def test_write_study_rejects_other_objects(tmp_path):
    with pytest.raises(TypeError, match="result"):
        write_study({"latency": []}, tmp_path)


def test_table_vertices_defaults_to_the_largest_count_and_says_the_paper_is_not_comparable():
    r = run_study(vertices=(8, 16), cases=(1,), poses_per_case=2, repeats=1, batch_pairs=8, peers=(), progress=False)
    assert r.settings["table_vertices"] == 16
    text = "\n".join(format_study(r))
    assert "paper's columns are its 3600-vertex figures; this table is at 16 vertices" in text


def test_growth_text_names_the_model_and_says_when_neither_holds():
    from prismbatch.lab.study.analysis import growth_model_text

    row = dict(model="linear", r2=0.62, r2_log=0.5, slope_us_per_1000=-0.0841, log_slope_us_per_doubling=0.01)
    assert growth_model_text(row) == "no trend beyond the noise (best r² 0.62)"  # no negative "growth"
    row.update(model="log", r2=0.7, r2_log=0.98, log_slope_us_per_doubling=0.189)
    assert growth_model_text(row) == "+0.189 µs per doubling of n (log fit, r² 0.98)"
    row.update(model="linear", r2=1.0, slope_us_per_1000=8.75)
    assert growth_model_text(row) == "+8.75 µs / 1000 vertices (line, r² 1.00)"


def test_paper_table_growth_row_uses_the_same_model_words_as_the_figure():
    from types import SimpleNamespace

    from prismbatch.lab.verdicts import paper_rows

    flat = dict(
        method="prismbatch",
        series="average",
        growth_factor=0.977,
        model="linear",
        r2=0.3,
        r2_log=0.4,
        slope_us_per_1000=-0.01,
        log_slope_us_per_doubling=0.0,
    )
    line = dict(
        method="fcl",
        series="average",
        growth_factor=6.0,
        model="linear",
        r2=0.99,
        r2_log=0.8,
        slope_us_per_1000=8.75,
        log_slope_us_per_doubling=1.0,
    )
    res = SimpleNamespace(table1=[], settings={"vertices": (36, 3600)}, growth=[flat, line])
    [(name, _, ours, verdict)] = paper_rows(study=res)
    assert name == "Fig. 7 growth with n" and verdict.startswith("reproduced")
    assert "prismbatch: no trend beyond the noise (best r² 0.40)" in ours  # not "linear fit"
    assert "FCL: +8.75 µs / 1000 vertices (line, r² 0.99)" in ours
