"""prismbatch.lab.predict: chunked and Dask runs of collision_probability equal one in-process call."""

from __future__ import annotations

import sys

import numpy as np
import pytest

import prismbatch as pb
from prismbatch.lab.predict import predict
from prismbatch.probability import collision_probability

SQ = pb.Prism.regular(4, 1.0)
DOWN = np.diag([1.0, -1.0, -1.0])


def queries(n=10):
    rng = np.random.default_rng(3)
    pos = np.column_stack([rng.normal(0, 0.3, (n, 2)), rng.uniform(-0.1, 0.5, n)])
    cov = np.diag([0.05**2, 0.05**2, 0.1**2, 0.02**2, 0.02**2, 0.1**2])
    covs = cov * rng.uniform(0.5, 2.0, n)[:, None, None]
    return (SQ, SQ, np.zeros(3), DOWN, pos, np.eye(3), covs)


def assert_same(r, ref):
    assert len(r) == len(ref)
    for k, v in ref.columns().items():
        np.testing.assert_array_equal(r.columns()[k], v, err_msg=k)
    assert r.seed == ref.seed


def test_chunks_in_process_match_one_call():
    args = queries()
    ref = collision_probability(*args, seed=7, rel_error=0.2)
    assert (ref.method == 2).any() and (ref.method == 1).any()  # both estimators take part
    for chunk in (1, 3, 100):
        r, info = predict(*args, seed=7, chunk_size=chunk, rel_error=0.2)
        assert info == {"scheduler": "in-process", "chunks": -(-10 // chunk)}
        assert_same(r, ref)


@pytest.mark.slow
def test_local_cluster_matches_in_process():
    pytest.importorskip("distributed")
    args = queries()
    ref = collision_probability(*args, seed=7, rel_error=0.2)
    r, info = predict(*args, seed=7, chunk_size=3, workers=2, rel_error=0.2)
    assert info["scheduler"] == "dask LocalCluster" and info["workers"] == 2 and info["chunks"] == 4
    assert_same(r, ref)


def test_missing_dask_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import fails
    with pytest.raises(ImportError, match=r"prismbatch\[dask\]"):
        predict(*queries(2), seed=1, workers=1)


def test_bad_options():
    with pytest.raises(TypeError, match="unexpected options"):
        predict(*queries(2), seed=1, witness=True)
    with pytest.raises(ValueError, match="chunk_size"):
        predict(*queries(2), seed=1, chunk_size=0)


# --- the predict command ------------------------------------------------------------------------


def _read_csv(path):
    import csv

    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_cli_predict_demo_matches_the_functions(tmp_path, capsys):
    """`prismbatch predict --demo` writes one row per query, equal to direct calls with the same seed."""
    from prismbatch.cli import main
    from prismbatch.lab.queries import demo_queries
    from prismbatch.motion import time_of_impact

    assert main(["predict", "--demo", "12", "--seed", "4", "--max-samples", "20000", "--out", str(tmp_path)]) == 0
    assert "time of impact:" in capsys.readouterr().out
    rows = _read_csv(tmp_path / "predict.csv")
    assert len(rows) == 12
    q = demo_queries(12, 4)
    a, b = pb.Prism(q["xy_a"]), pb.Prism(q["xy_b"])
    poses = (q["pos_a"], q["rot_a"], q["pos_b"], q["rot_b"])
    toi = time_of_impact(a, b, *poses, q["velocity"], horizon=1.0)
    pr = collision_probability(a, b, *poses, q["cov_b"], seed=4, max_samples=20000)
    np.testing.assert_array_equal([float(r["time_of_impact"]) for r in rows], toi.time)
    np.testing.assert_array_equal([float(r["p"]) for r in rows], pr.p)
    np.testing.assert_array_equal([int(r["samples"]) for r in rows], pr.samples)
    meta = __import__("json").loads((tmp_path / "predict.json").read_text())
    assert meta["summary"]["probability"]["queries"] == 12 and meta["settings"]["seed"] == 4


def test_cli_predict_file(tmp_path, capsys):
    """A query file with a motion only gives the time of impact only; bad files are named."""
    from prismbatch.cli import main

    path = tmp_path / "q.npz"
    pos_b = np.array([[0.0, 0.0, 1.0], [3.0, 0.0, 1.0]])
    np.savez(path, xy_a=SQ.xy, xy_b=SQ.xy, pos_a=np.zeros(3), rot_a=DOWN, pos_b=pos_b, rot_b=np.eye(3),
             velocity=np.array([0.0, 0.0, -2.0]))  # fmt: skip
    assert main(["predict", str(path), "--out", str(tmp_path / "out")]) == 0
    rows = _read_csv(tmp_path / "out" / "predict.csv")
    assert "p" not in rows[0]
    assert float(rows[0]["time_of_impact"]) == pytest.approx(0.5, abs=1e-9)  # a gap of 1 closed at speed 2
    assert rows[1]["time_of_impact"] == "inf" and rows[1]["toi_status"] == "0"
    bad = tmp_path / "bad.npz"
    np.savez(bad, xy_a=SQ.xy, xy_b=SQ.xy, pos_a=np.zeros(3), rot_a=DOWN, pos_b=pos_b, rot_b=np.eye(3), speed=1.0)
    assert main(["predict", str(bad)]) == 2
    assert "unknown arrays ['speed']" in capsys.readouterr().err
    np.savez(bad, xy_a=SQ.xy, xy_b=SQ.xy, pos_a=np.zeros(3), rot_a=DOWN, pos_b=pos_b, rot_b=np.eye(3))
    assert main(["predict", str(bad)]) == 2
    assert "nothing to predict" in capsys.readouterr().err
    assert main(["predict", "--demo", "0"]) == 2
    # a file that cannot be read: status 3, one line naming it (not a traceback, not a pickle hint)
    for content in (b"not a zip archive", path.read_bytes()[:200]):
        bad.write_bytes(content)
        assert main(["predict", str(bad)]) == 3
        err = capsys.readouterr().err
        assert f"{bad}: not a .npz query file" in err and "Traceback" not in err and "pickle" not in err
    assert main(["predict", str(tmp_path / "missing.npz")]) == 3
    np.savez(bad, xy_a=SQ.xy, xy_b=SQ.xy[:2], pos_a=np.zeros(3), rot_a=DOWN, pos_b=pos_b, rot_b=np.eye(3),
             velocity=np.array([0.0, 0.0, -2.0]))  # fmt: skip
    assert main(["predict", str(bad)]) == 2
    assert "xy_b: a polygon needs at least 3 vertices" in capsys.readouterr().err
