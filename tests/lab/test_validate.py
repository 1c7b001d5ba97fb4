"""prismbatch.lab.validate: a short Monte Carlo run over every distribution, the replay
round trip, chunking invariance and the stand-in length rule.

The run's own verdicts are not trusted blindly: records are re-checked with
an independent re-run of prismbatch and the LP, regenerated from their seeds,
and the vectorised contact residual is compared with
``prismbatch.lab.exact.point_in_prism_residual``.
"""

from __future__ import annotations

import json
import sys
import types

import numpy as np
import pytest

pytest.importorskip("scipy")
pytest.importorskip("fcl")

import prismbatch as pb  # noqa: E402
from prismbatch.lab import validate as V  # noqa: E402
from prismbatch.lab.exact import margin_lp, point_in_prism_residual  # noqa: E402
from prismbatch.lab.peers import fcl_standin_length, standin_lengths  # noqa: E402

pytestmark = [pytest.mark.slow, pytest.mark.needs_fcl]

N_SHORT = 5000  # per distribution: 20,000 pairs in all


@pytest.fixture(scope="module")
def short_run():
    return V.validate(
        N_SHORT,
        shapes=("regular", "random", "cylinder"),
        vertices=(3, 12, 48),
        seed=11,
        lp_samples=120,
        chunk_size=4096,
        distance_pairs=0,  # the distance section's own tests: test_validate_distance.py
        progress=False,
    )


def test_short_run_has_no_disagreement_outside_band(short_run):
    r = short_run
    assert set(r.counts) == set(V.DISTRIBUTION_NAMES)
    for d, c in r.counts.items():
        assert c["pairs"] == N_SHORT
        assert c["fcl_pairs"] == N_SHORT
        assert c["lp_pairs"] == 120
        # the validation contract: no disagreement outside the band, every contact valid
        assert int(c["fcl_out_pb"].sum()) == 0, d
        assert int(c["lp_out"].sum()) == 0, d
        assert c["contact_invalid"] == 0 and c["nonfinite"] == 0 and c["bad_case"] == 0, d
        assert c["status_mismatch"] == 0, d
        assert c["contact_checked"] == c["hits"] > 0, d
        assert c["contact_max_ratio"] <= 2.0
        assert c["fcl_standin_short"].sum() == 0 and c["standin_short"] == 0, d
        # confusion counts cover exactly the compared pairs
        assert c["fcl_conf"].sum() == N_SHORT and c["lp_conf"].sum() == 120
        assert c["pairs_case"].sum() == N_SHORT
    assert r.ok
    cases = {d: set(np.flatnonzero(c["pairs_case"])) for d, c in r.counts.items()}
    assert cases["degenerate"] == {2, 3, 4, 7, 8}
    assert not cases["facing"] & {10, 11}  # facing axes
    assert cases["free"] & {10, 11}  # random rotations reach the added cases
    # near-contact pairs straddle the boundary: both LP signs, many inside the band, some outside
    nc = r.counts["near-contact"]
    assert nc["lp_conf"][:, :, 0].sum() > 10 and nc["lp_conf"][:, :, 1].sum() > 10
    assert 20 < nc["lp_band"].sum() < 110  # log-uniform offsets: ~3/5 in the band


def test_summary_and_files(short_run, tmp_path):
    lines = V.format_validation(short_run)
    assert any("near-contact" in ln for ln in lines) and lines[-1].startswith("RESULT: OK")
    paths = V.write_validation(short_run, tmp_path)
    for key in ("markdown", "summary_csv", "cases_csv", "json", "replay"):
        assert (tmp_path / paths[key].split("/")[-1]).exists(), key
    meta = json.loads((tmp_path / "validation.json").read_text())
    assert meta["seed"] == 11 and meta["validation"]["n_pairs"] == N_SHORT
    assert meta["machine"]["numba_threads"] >= 1 and meta["versions"]["numpy"]
    import csv

    rows = list(csv.DictReader(open(paths["cases_csv"])))
    fcl_total = sum(int(x["pairs"]) for x in rows if x["reference"] == "fcl" and x["distribution"] == "free")
    assert fcl_total == N_SHORT
    md = open(paths["markdown"]).read()
    assert "## Per case" in md and "near-contact" in md


def test_replay_round_trip(short_run, tmp_path):
    """Records re-run from the replay file give the recorded answers, and
    regenerating the block from (config, distribution, block) gives the
    recorded inputs bit for bit."""
    paths = V.write_validation(short_run, tmp_path)
    from prismbatch.lab.replay import read_replay

    meta, recs = read_replay(paths["replay"])
    assert meta["seed"] == short_run.config["seed"]
    assert len(recs) == len(short_run.records) > 0
    rng = np.random.default_rng(0)
    pick = rng.choice(len(recs), min(25, len(recs)), replace=False)
    blocks = {}
    for i in pick:
        rec = recs[i]
        assert rec["kind"] in V.RECORD_KINDS
        a, b = pb.Prism(rec["shape_a"]), pb.Prism(rec["shape_b"])
        P = [np.array(rec[k]) for k in ("pos_a", "rot_a", "pos_b", "rot_b")]
        res = pb.collide(a, b, *P, rtol=rec["rtol"], atol=rec["atol"], dtype=np.dtype(rec["dtype"]), contact=True)
        assert bool(res.hit[0]) == rec["prismbatch"]["hit"] and int(res.case[0]) == rec["prismbatch"]["case"]
        if rec["prismbatch"]["contact"] is not None:
            assert res.contact[0].tolist() == rec["prismbatch"]["contact"]
        ref = rec["references"]
        if ref["lp_margin"] is not None:
            m = margin_lp(a.xy, P[0], P[1], b.xy, P[2], P[3])
            assert m == ref["lp_margin"]
            inside = abs(m) <= rec["band"]
            assert (rec["kind"] == "inside band") == inside
        if ref["fcl"] is not None:
            from prismbatch.lab.peers import FCLPeer

            assert FCLPeer(a.xy, b.xy, ref["standin_length"]).collide(*P) == ref["fcl"]
        key = (rec["distribution"], rec["block"])
        if key not in blocks:
            blocks[key] = V.generate_block(short_run.config, *key)
        blk = blocks[key]
        k = rec["index"]
        assert blk.shape_a.xy.tolist() == rec["shape_a"] and blk.shape_b.xy.tolist() == rec["shape_b"]
        for name in ("pos_a", "rot_a", "pos_b", "rot_b"):
            assert getattr(blk, name)[k].tolist() == rec[name]
        assert rec["spawn_key"] == [V.DISTRIBUTION_NAMES.index(rec["distribution"]), rec["block"]]


def test_results_do_not_depend_on_chunk_size():
    kw = dict(
        distributions=("free", "near-contact"),
        vertices=(4, 9),
        shapes=("random", "regular"),
        seed=5,
        lp_samples=20,
        fcl=0.3,
        distance_pairs=300,  # two blocks of the distance section (256 + 44)
        progress=False,
    )
    r1 = V.validate(4200, chunk_size=4096, **kw)  # two blocks: 4096 + 104 pairs
    r2 = V.validate(4200, chunk_size=100_000, **kw)
    assert r1.outcome() == r2.outcome()
    c = r1.counts["free"]
    assert 0.2 * 4200 < c["fcl_pairs"] < 0.4 * 4200  # the FCL subsample option
    assert r1.ok


def test_vectorised_residual_matches_exact():
    rng = np.random.default_rng(3)
    shape = V.make_shape("random", 17, rng)
    from prismbatch.sampling import random_rotations

    m = 200
    pos, rot = rng.normal(size=(m, 3)), random_rotations(m, rng)
    x = rng.normal(size=(m, 3)) * 3
    got = V.residuals(shape, pos, rot, x)
    want = [point_in_prism_residual(shape.xy, pos[k], rot[k], x[k]) for k in range(m)]
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    assert (got > 0).any() and (got < 0).any()


# ---------------------------------------------------------------------------
# stand-in length rule
# ---------------------------------------------------------------------------


def _max_depth_lp(xy_a, pa, ra, xy_b, pb_, rb):
    """Largest depth along a's axis of a common point of the two bodies (independent LP), or None
    if they do not meet. Plain half-space constraints, no margin."""
    from scipy.optimize import linprog

    from prismbatch.lab.exact import polygon_halfplanes

    A, b = [], []
    for xy, p, R in ((xy_a, pa, ra), (xy_b, pb_, rb)):
        n2, h = polygon_halfplanes(xy)
        for ni, hi in zip(n2, h):  # n . (R^T (x - p))[:2] <= h
            w = R[:, :2] @ ni
            A.append(w)
            b.append(hi + w @ p)
        A.append(-R[:, 2])  # (x - p) . d >= 0
        b.append(-(R[:, 2] @ p))
    res = linprog(-ra[:, 2], A_ub=np.array(A), b_ub=np.array(b), bounds=[(None, None)] * 3, method="highs")
    if res.status == 2:
        return None
    assert res.status == 0, res.message
    return float(ra[:, 2] @ (res.x - pa))


def _tilted(axis_tilt, rng):
    d = np.array([np.sin(axis_tilt), 0.0, np.cos(axis_tilt)])
    from prismbatch.sampling import rotation_with_axis

    spin = rng.uniform(0, 2 * np.pi)
    Z = np.array([[np.cos(spin), -np.sin(spin), 0], [np.sin(spin), np.cos(spin), 0], [0, 0, 1.0]])
    return rotation_with_axis(d) @ Z


def test_standin_rule_bounds_every_common_point():
    """Independent LP: the deepest common point (along either axis) is within
    the bound, for random poses and nearly parallel same-direction axes."""
    rng = np.random.default_rng(8)
    from prismbatch.sampling import random_rotations

    met = 0
    for k in range(120):
        A, B = V.make_shape("random", 7, rng), V.make_shape("regular", 5, rng)
        if k % 2:
            ra, rb = random_rotations(2, rng)
        else:  # same direction, tilt 1e-3 .. 0.3 rad: the bodies may first meet far out
            ra, rb = _tilted(0.0, rng), _tilted(10 ** rng.uniform(-3, -0.5), rng)
        pa = rng.uniform(-2, 2, 3)
        pb_ = pa + rng.uniform(-3, 3, 3)
        sl = standin_lengths(A.xy, B.xy, pa, ra, pb_, rb)
        assert sl.sound[0] and sl.length[0] == pytest.approx(2 * sl.bound[0])
        for xa, p1, r1, xb, p2, r2 in ((A.xy, pa, ra, B.xy, pb_, rb), (B.xy, pb_, rb, A.xy, pa, ra)):
            depth = _max_depth_lp(xa, p1, r1, xb, p2, r2)
            if depth is not None:
                met += 1
                assert depth <= sl.bound[0] * (1 + 1e-9) + 1e-9
    assert met > 40


def test_standin_rule_fixes_slowly_converging_axes():
    """The pose the old rule (4 (|dp| + R_a + R_b)) is known to fail: thin
    prisms 1 apart whose axes converge at 0.02 rad meet ~50 out."""
    sq = 0.05 * np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])  # side 0.1
    d = np.array([-0.02, 0.0, 1.0])
    d /= np.linalg.norm(d)
    rb = np.stack([np.cross([0.0, 1.0, 0.0], d), [0.0, 1.0, 0.0], d], axis=1)
    pa, pb_, I3 = np.zeros(3), np.array([1.0, 0.0, 0.0]), np.eye(3)
    m_inf = margin_lp(sq, pa, I3, sq, pb_, rb)
    assert m_inf > 0.05 - 1e-9
    old = fcl_standin_length(sq, sq, pa, pb_)
    assert margin_lp(sq, pa, I3, sq, pb_, rb, length_a=old, length_b=old) < 0  # the failure
    L = standin_lengths(sq, sq, pa, I3, pb_, rb).length[0]
    assert margin_lp(sq, pa, I3, sq, pb_, rb, length_a=L, length_b=L) == pytest.approx(m_inf, abs=1e-9)
    from prismbatch.lab.peers import FCLPeer

    assert FCLPeer(sq, sq, L).collide(pa, I3, pb_, rb)
    assert not FCLPeer(sq, sq, old).collide(pa, I3, pb_, rb)


def test_standin_rule_parallel_and_bad_args():
    sq = pb.Prism.regular(4, 1.0).xy
    I3 = np.eye(3)
    # exactly parallel, same direction: bound = S; facing: S as well
    flip = np.diag([1.0, -1.0, -1.0])
    for rb in (I3, flip):
        sl = standin_lengths(sq, sq, np.zeros(3), I3, np.array([0.5, 0.2, 3.0]), rb)
        S = 2.0 + np.linalg.norm([0.5, 0.2, 3.0])
        assert sl.bound[0] == pytest.approx(S) and sl.sound[0]
    tiny = _tilted(1e-9, np.random.default_rng(0))
    sl = standin_lengths(sq, sq, np.zeros(3), I3, np.array([0.5, 0.2, 3.0]), tiny)
    assert not sl.sound[0] and np.isfinite(sl.length[0])
    with pytest.raises(ValueError, match="factor"):
        standin_lengths(sq, sq, np.zeros(3), I3, np.zeros(3), I3, factor=0.5)
    with pytest.raises(ValueError, match="max_ratio"):
        standin_lengths(sq, sq, np.zeros(3), I3, np.zeros(3), I3, max_ratio=float("inf"))


# ---------------------------------------------------------------------------
# arguments, stiff hook
# ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kw,match",
    [
        (dict(n_pairs=0), "n_pairs"),
        (dict(distributions=("stiff",)), "distributions"),
        (dict(distributions=()), "distributions"),
        (dict(shapes="hexagon"), "shapes"),
        (dict(vertices=(2,)), "vertices"),
        (dict(dtype="float16"), "dtype"),
        (dict(fcl=2.0), "fcl"),
        (dict(lp_samples=-1), "lp_samples"),
        (dict(chunk_size=0), "chunk_size"),
        (dict(workers=0), "workers"),
        (dict(stiff="yes"), "stiff"),
        (dict(seed=-1), "seed"),
        (dict(distance_pairs=-1), "distance_pairs"),
        (dict(distance_vertices=(2,)), "distance_vertices"),
    ],
)
def test_bad_arguments(kw, match):
    kw = {"n_pairs": 10, **kw}
    with pytest.raises(ValueError, match=match):
        V.validate(progress=False, **kw)


def test_stiff_hook(tmp_path, monkeypatch):
    """validate(stiff=...) calls prismbatch.lab.stiff.run_stiff_suite and the report carries its section."""
    calls = []

    class Report:
        def summary_lines(self):
            return ["stiff: fake summary"]

        def markdown(self):
            return "## Stiff suite\n\nfake section"

        def csv_tables(self):
            return {"cases": (["a", "b"], [[1, 2]])}

        def json(self):
            return {"fake": True}

    def run_stiff_suite(*, quick=False, seed=0, dtypes=("float64", "float32"), progress=False):
        calls.append((quick, seed))
        return Report()

    fake = types.ModuleType("prismbatch.lab.stiff")
    fake.run_stiff_suite = run_stiff_suite
    monkeypatch.setitem(sys.modules, "prismbatch.lab.stiff", fake)
    r = V.validate(
        50, distributions=("facing",), vertices=(5,), fcl=False, lp_samples=0, stiff="quick", seed=4, progress=False
    )
    assert calls == [(True, 4)]
    assert "stiff: fake summary" in V.format_validation(r)
    paths = V.write_validation(r, tmp_path)
    page = open(paths["markdown"]).read()
    # the summary in validation.md, the section's tables in their own linked page
    assert "stiff: fake summary" in page and "fake section" not in page and "(validation_stiff.md)" in page
    assert len(paths["stiff"]) == 2 and open(paths["stiff"][0]).read().startswith("a,b")
    assert paths["stiff"][1].endswith("validation_stiff.md") and "fake section" in open(paths["stiff"][1]).read()
    assert json.loads(open(paths["json"]).read())["stiff"] == {"fake": True}


def test_a_run_against_no_reference_says_nothing_was_compared():
    r = V.validate(500, distributions=("facing",), fcl=False, lp_samples=0, seed=2, progress=False)
    assert r.ok
    assert V.format_validation(r)[-1].startswith("RESULT: NO COMPARISON: no reference ran")
