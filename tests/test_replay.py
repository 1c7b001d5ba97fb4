"""Replay files and the step-by-step trace (prismbatch.replay, Collider.explain)."""

import json

import numpy as np
import pytest

import prismbatch as pb
from prismbatch._projection import EXITS
from prismbatch.casegen import case_poses
from prismbatch.replay import make_record, read_replay, replay, write_replay


def _pairs():
    """Poses of every case, hits and misses, for a pentagon a and a 7-gon b."""
    a = pb.Prism(np.c_[2 * np.cos(np.arange(5) * 2 * np.pi / 5 + 0.3), 2 * np.sin(np.arange(5) * 2 * np.pi / 5 + 0.3)])
    b = pb.Prism.regular(7, 2.5, phase=0.1)
    rng = np.random.default_rng(7)
    out = []
    for case in (1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11):
        pa, ra, pbp, rb = case_poses(case, 4, a, b, rng, world_transform=True)
        out += [(a, b, pa[k], ra[k], pbp[k], rb[k]) for k in range(4)]
    return out


def test_explain_matches_collide_and_an_independent_frame():
    for a, b, pa, ra, pbp, rb in _pairs():
        col = pb.Collider(a, b)
        e = col.explain(pa, ra, pbp, rb)
        r = col.collide(pa[None], ra[None], pbp[None], rb[None], contact=True)
        assert e["hit"] == bool(r.hit[0]) and e["case"] == int(r.case[0])
        if e["hit"]:
            np.testing.assert_allclose(e["contact"], r.contact[0], rtol=0, atol=1e-12)
        # b's pose in a's centred frame, recomputed here in NumPy.
        ca = pa + ra[:, :2] @ a.centre
        cb = pbp + rb[:, :2] @ b.centre
        p = ra.T @ (cb - ca)
        R = ra.T @ rb
        np.testing.assert_allclose([e["p_x"], e["p_y"], e["p_z"]], p, atol=1e-12)
        np.testing.assert_allclose([e[f"R{i}{j}"] for i in range(3) for j in range(3)], R.ravel(), atol=1e-12)
        # Δ3: height of b's deepest end-face vertex (polygon about its centre).
        q = np.asarray(b.xy) - b.centre
        d3 = p[2] + np.max(q @ R[2, :2])
        assert abs(e["delta3"] - d3) <= 1e-12
        assert e["exit"] in EXITS and e["exit_reason"] == EXITS[e["exit"]]
        # Exits 8 and 9 are the only ones that report a collision.
        assert e["hit"] == (e["exit"] in (8, 9))
        if e["exit"] in (9, 10):
            assert e["gjk_hit"] == (1.0 if e["hit"] else 0.0)
        else:
            assert np.isnan(e["gjk_hit"])


def test_replay_round_trip_is_bit_exact_and_reproduces_answers(tmp_path):
    recs = []
    for k, (a, b, pa, ra, pbp, rb) in enumerate(_pairs()):
        r = pb.Collider(a, b).collide_pair(pa, ra, pbp, rb)
        recs.append(make_record("test", a, b, pa, ra, pbp, rb, rtol=1e-9, hit=r.hit, case=r.case,
                                contact=r.contact if r.hit else None, references={"lp_margin": None},
                                distribution="cases", index=k, seed=7))
    path = write_replay(tmp_path / "r.json", recs, meta={"seed": 7})
    meta, back = read_replay(path)
    assert meta["seed"] == 7 and len(back) == len(recs)
    for r0, r1 in zip(recs, back):
        for key in ("pos_a", "rot_a", "pos_b", "rot_b", "shape_a", "shape_b"):
            assert np.array_equal(np.asarray(r0[key]), np.asarray(r1[key]))  # bit-exact
    lines = []
    res = replay(path, out=lines.append)
    assert len(res) == len(recs) and all(e["same_as_saved"] for e in res)
    text = "\n".join(lines)
    assert text.count("=> exit") == len(recs)
    assert "0 answer(s) differ" in text


def test_replay_reports_a_changed_answer(tmp_path):
    a, b, pa, ra, pbp, rb = _pairs()[0]
    r = pb.Collider(a, b).collide_pair(pa, ra, pbp, rb)
    rec = make_record("test", a, b, pa, ra, pbp, rb, rtol=1e-9, hit=not r.hit, case=r.case)
    path = write_replay(tmp_path / "r.json", [rec])
    lines = []
    res = replay(path, out=lines.append)
    assert not res[0]["same_as_saved"]
    assert any("DIFFERS" in line for line in lines)


def test_bad_replay_files_raise(tmp_path):
    p = tmp_path / "x.json"
    p.write_text("{not json")
    with pytest.raises(ValueError, match="not JSON"):
        read_replay(p)
    p.write_text(json.dumps({"format": "other"}))
    with pytest.raises(ValueError, match="not a prismbatch replay file"):
        read_replay(p)
    p.write_text(json.dumps({"format": "prismbatch-replay", "version": 1, "records": [{"kind": "x"}]}))
    with pytest.raises(ValueError, match="lacks"):
        read_replay(p)
    with pytest.raises(ValueError, match="out of range"):
        a, b, pa, ra, pbp, rb = _pairs()[0]
        rec = make_record("t", a, b, pa, ra, pbp, rb, rtol=1e-9, hit=False, case=1)
        replay(write_replay(tmp_path / "ok.json", [rec]), out=lambda s: None, indices=[3])


def test_pair_scale_tolerance_matches_the_kernels_tolerance():
    from prismbatch.collide import pair_scale_tolerance

    pairs = _pairs()
    for dtype in (np.float64, np.float32):
        for a, b, pa, ra, pbp, rb in pairs[::3]:
            S, tol = pair_scale_tolerance(a, b, pa[None], ra[None], pbp[None], rb[None], atol=1e-12, dtype=dtype)
            e = pb.Collider(a, b, atol=1e-12, dtype=dtype).explain(pa, ra, pbp, rb)
            assert tol[0] == pytest.approx(e["tol"], rel=1e-5 if dtype == np.float32 else 1e-12)
            assert S[0] > a.radius + b.radius
