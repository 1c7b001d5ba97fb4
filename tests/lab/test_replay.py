"""Replay files and the step-by-step trace (prismbatch.lab.replay, Collider.explain)."""

import json

import numpy as np
import pytest

import prismbatch as pb
from prismbatch._kernels.projection import EXITS
from prismbatch.lab.casegen import case_poses
from prismbatch.lab.replay import make_record, read_replay, replay, write_replay


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
    centre_exits = 0
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
        # Exits 8, 9 and 11 are the only ones that report a collision.
        assert e["hit"] == (e["exit"] in (8, 9, 11))
        if e["exit"] == 11:  # b's end-face centre: at a's plane within tol, and inside P_a
            assert e["centre_depth_in_Pa"] >= 0.0 and e["p_z"] >= -e["height_tol"]
            cz = 0.5 * (e["p_z"] + max(e["p_z"], 0.0))  # on b's face, or halfway to a's plane
            np.testing.assert_allclose(e["contact"], ca + ra @ [e["p_x"], e["p_y"], cz], atol=1e-9)
            centre_exits += 1
        if e["exit"] in (9, 10):
            assert e["gjk_hit"] == (1.0 if e["hit"] else 0.0)
        else:
            assert np.isnan(e["gjk_hit"])
    assert centre_exits > 0  # the early accept by b's centre was taken


def test_replay_round_trip_is_bit_exact_and_reproduces_answers(tmp_path):
    recs = []
    for k, (a, b, pa, ra, pbp, rb) in enumerate(_pairs()):
        r = pb.Collider(a, b).collide_pair(pa, ra, pbp, rb)
        recs.append(
            make_record(
                "test",
                a,
                b,
                pa,
                ra,
                pbp,
                rb,
                rtol=1e-9,
                hit=r.hit,
                case=r.case,
                contact=r.contact if r.hit else None,
                references={"lp_margin": None},
                distribution="cases",
                index=k,
                seed=7,
            )
        )
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
    from prismbatch.geometry import pair_scale_tolerance

    pairs = _pairs()
    for dtype in (np.float64, np.float32):
        for a, b, pa, ra, pbp, rb in pairs[::3]:
            S, tol = pair_scale_tolerance(a, b, pa[None], ra[None], pbp[None], rb[None], atol=1e-12, dtype=dtype)
            e = pb.Collider(a, b, atol=1e-12, dtype=dtype).explain(pa, ra, pbp, rb)
            assert tol[0] == pytest.approx(e["tol"], rel=1e-5 if dtype == np.float32 else 1e-12)
            assert S[0] > a.radius + b.radius


def _good_record():
    a, b, pa, ra, pbp, rb = _pairs()[0]
    r = pb.Collider(a, b).collide_pair(pa, ra, pbp, rb)
    return make_record(
        "test",
        a,
        b,
        pa,
        ra,
        pbp,
        rb,
        rtol=1e-9,
        hit=r.hit,
        case=r.case,
        references={"fcl": True, "lp_margin": None},
        distribution="cases",
        index=0,
        spawn_key=[1, 2],
    )


def _write_doc(tmp_path, doc):
    p = tmp_path / "bad.json"
    p.write_text(doc if isinstance(doc, str) else json.dumps(doc))
    return p


def _doc(**changes):
    """A valid replay document with one record, with ``changes`` applied to that record (None: delete)."""
    rec = json.loads(json.dumps(_good_record()))
    for key, value in changes.items():
        obj, *path = key.split(".")
        target, leaf = (rec, obj) if not path else (rec[obj], path[0])
        if value is None:
            del target[leaf]
        else:
            target[leaf] = value
    return {"format": "prismbatch-replay", "version": 1, "meta": {"seed": 7}, "records": [rec]}


def test_deeply_nested_file_is_a_clear_error(tmp_path):
    p = _write_doc(tmp_path, "[" * 100_000 + "]" * 100_000)
    with pytest.raises(ValueError, match=r"bad\.json: not a replay file: JSON nesting too deep"):
        read_replay(p)
    p = _write_doc(
        tmp_path, '{"format": "prismbatch-replay", "version": 1, "records": [' + "[" * 100_000 + "]" * 100_000 + "]}"
    )
    with pytest.raises(ValueError, match="nesting too deep"):
        read_replay(p)


@pytest.mark.parametrize(
    "doc, match",
    [
        ([1, 2], r"not a prismbatch replay file"),
        ({"format": "prismbatch-replay", "version": True, "records": []}, r"replay format version True"),
        ({"format": "prismbatch-replay", "version": "1", "records": []}, r"replay format version '1'"),
        ({"format": "prismbatch-replay", "version": 1, "records": {}}, r"\"records\" must be a list, got an object"),
        (
            {"format": "prismbatch-replay", "version": 1, "records": [[1, 2]]},
            r"record 0 must be a JSON object \(a record\), got an array",
        ),
        ({"format": "prismbatch-replay", "version": 1, "meta": [], "records": []}, r"\"meta\" must be a JSON object"),
        (
            {"format": "prismbatch-replay", "version": 1, "meta": {"versions": "x"}, "records": []},
            r"meta\.versions must be a JSON object, got a string",
        ),
        (
            {"format": "prismbatch-replay", "version": 1, "meta": {"seed": [1]}, "records": []},
            r"meta\.seed must be a string, number, boolean or null, got an array",
        ),
    ],
)
def test_malformed_document_is_a_clear_error(tmp_path, doc, match):
    with pytest.raises(ValueError, match=r"bad\.json: .*" + match):
        read_replay(_write_doc(tmp_path, doc))


@pytest.mark.parametrize(
    "changes, match",
    [
        ({"pos_a": None}, r"record lacks pos_a"),
        ({"prismbatch": None, "references": None}, r"record lacks prismbatch, references"),
        ({"prismbatch.hit": None}, r"prismbatch\.hit must be true or false, got null"),
        ({"kind": 3}, r"kind must be a string, got an integer"),
        ({"pos_a": [0, 0, True]}, r"pos_a\[2\] must be a number, got a boolean"),
        ({"pos_b": ["0", 0, 0]}, r"pos_b\[0\] must be a number, got a string"),
        ({"rot_a": [[1, 0, 0], [0, 1, 0], [0, 0, "1"]]}, r"rot_a\[2\]\[2\] must be a number, got a string"),
        ({"rot_b": [[1, 0, 0], [0, 1, 0]]}, r"rot_b has length 2, expected 3"),
        ({"rot_b": {"a": 1}}, r"rot_b must be an array of length 3, got an object"),
        ({"pos_a": [0, 0, None]}, r"pos_a\[2\] must be a number, got null"),
        ({"pos_a": [0, 0, 10**400]}, r"pos_a\[2\] must be a finite number, got inf"),
        ({"shape_a": [[0, 0], [1, 0], [1]]}, r"shape_a\[2\] has length 1, expected 2"),
        ({"shape_b": []}, r"shape_b has length 0, expected >= 1"),
        ({"shape_b": [[0, 0], [1, False], [0, 1]]}, r"shape_b\[1\]\[1\] must be a number, got a boolean"),
        ({"dtype": "float16"}, r"dtype must be \"float64\" or \"float32\", got 'float16'"),
        ({"dtype": ["float64"]}, r"dtype must be .* got an array"),
        ({"rtol": "1e-9"}, r"rtol must be a number, got a string"),
        ({"atol": False}, r"atol must be a number, got a boolean"),
        ({"rtol": -1.0}, r"rtol must be >= 0, got -1"),
        ({"prismbatch": []}, r"prismbatch must be a JSON object, got an array"),
        ({"prismbatch.case": True}, r"prismbatch\.case must be an integer, got a boolean"),
        ({"prismbatch.contact": [0, "x", 0]}, r"prismbatch\.contact\[1\] must be a number, got a string"),
        ({"references": [1]}, r"references must be a JSON object, got an array"),
        ({"references.fcl": [True]}, r"references\['fcl'\] must be a string, number, boolean or null, got an array"),
        ({"spawn_key": [1, {"x": 2}]}, r"spawn_key\[1\] must be a string, number, boolean or null, got an object"),
        ({"distribution": {"a": 1}}, r"distribution must be a string, number, boolean or null, got an object"),
    ],
)
def test_malformed_record_names_file_record_and_field(tmp_path, changes, match):
    p = _write_doc(tmp_path, _doc(**changes))
    with pytest.raises(ValueError, match=r"^.*bad\.json: record 0: " + match):
        read_replay(p)
    with pytest.raises(ValueError, match=match):  # replay reads through the same check
        replay(p, out=lambda s: None)


def test_json_nan_in_a_pose_is_rejected(tmp_path):
    p = _write_doc(tmp_path, json.dumps(_doc(pos_b=[float("nan"), 0.0, 1.0])))  # JSON's NaN literal
    assert "NaN" in p.read_text()
    with pytest.raises(ValueError, match=r"record 0: pos_b\[0\] must be a finite number, got nan"):
        read_replay(p)


def test_write_replay_checks_the_same_schema(tmp_path):
    rec = _good_record()
    rec["pos_a"] = [0.0, "1", 0.0]
    with pytest.raises(ValueError, match=r"^record 0: pos_a\[1\] must be a number, got a string"):
        write_replay(tmp_path / "w.json", [rec])
    rec = _good_record()
    rec["references"] = {"fcl": np.bool_(True), "lp": np.float32(1.5)}  # NumPy scalars are written as JSON
    meta, back = read_replay(write_replay(tmp_path / "w.json", [rec]))
    assert back[0]["references"] == {"fcl": True, "lp": 1.5}


def test_huge_coordinates_give_a_clear_error(tmp_path):
    p = _write_doc(tmp_path, _doc(pos_b=[0.0, 0.0, 1e308]))
    read_replay(p)  # a finite number: the schema accepts it, the collision test rejects it by name
    with pytest.raises(
        ValueError,
        match=r"bad\.json: record 0: pos_b has a coordinate 1e\+308 outside the "
        r"supported range",
    ):
        replay(p, out=lambda s: None)
    p = _write_doc(tmp_path, _doc(shape_a=[[0, 0], [1e308, 0], [0, 1e308]]))
    with pytest.raises(ValueError, match=r"bad\.json: record 0: shape_a: .*outside the supported range"):
        replay(p, out=lambda s: None)
    p = _write_doc(tmp_path, _doc(shape_a=[[0, 0], [1, 0], [2, 0]]))
    with pytest.raises(ValueError, match=r"bad\.json: record 0: shape_a: .*zero area"):
        replay(p, out=lambda s: None)


ESC = "\x1b[2J\x1b[31m"


def test_text_fields_are_printed_escaped(tmp_path):
    doc = _doc(kind="evil" + ESC + "\r\n\x07", distribution="d" + ESC, spawn_key=[ESC, 1])
    rec = doc["records"][0]
    rec["references"] = {"fcl" + ESC: "yes" + ESC, "lp": 1e-3}
    doc["meta"] = {"seed": ESC, "versions": {"prismbatch": "0" + ESC}}
    lines = []
    res = replay(_write_doc(tmp_path, doc), out=lines.append)
    assert len(res) == 1
    text = "\n".join(lines)
    assert all(c.isprintable() for line in lines for c in line)
    assert "evil\\x1b[2J\\x1b[31m\\r\\n\\x07" in text
    assert "distribution d\\x1b[2J" in text and "spawn_key ['\\x1b[2J\\x1b[31m', 1]" in text
    assert "fcl\\x1b[2J\\x1b[31m yes\\x1b[2J" in text
    assert "run seed \\x1b[2J" in text and "written by prismbatch 0\\x1b[2J" in text


def test_escapes_in_the_file_name_and_error_messages(tmp_path):
    p = tmp_path / ("x" + ESC + ".json")
    p.write_text(json.dumps(_doc(kind=5)))
    with pytest.raises(ValueError) as info:
        read_replay(p)
    assert all(c.isprintable() for c in str(info.value)) and "x\\x1b[2J" in str(info.value)
    p.write_text(json.dumps(_doc(references={ESC: [1]})))
    with pytest.raises(ValueError) as info:
        read_replay(p)
    assert all(c.isprintable() for c in str(info.value))


@pytest.mark.parametrize(
    "changes, rc", [(None, 2), ({"pos_a": [0, 0, True]}, 2), ({"references": {"fcl": {}}}, 2), ({"kind": ESC}, 0)]
)
def test_cli_prints_one_line_and_no_escape_sequences(tmp_path, capsys, changes, rc):
    from prismbatch.cli import main

    doc = "[" * 100_000 + "]" * 100_000 if changes is None else _doc(**changes)
    assert main(["replay", str(_write_doc(tmp_path, doc))]) == rc
    out, err = capsys.readouterr()
    assert "\x1b" not in out + err and "Traceback" not in err
    assert err == "" if rc == 0 else (err.startswith("prismbatch: error: ") and err.count("\n") == 1)


@pytest.mark.parametrize("case", [99, -1, 10**30, 0])
def test_saved_case_must_be_a_case_number(tmp_path, case):
    doc = _doc()
    doc["records"][0]["prismbatch"]["case"] = case
    p = _write_doc(tmp_path, doc)
    with pytest.raises(ValueError, match=r"bad\.json: record 0: prismbatch\.case must be a case number 1\.\.11"):
        read_replay(p)


def test_cli_a_missing_file_is_status_3(tmp_path, capsys):
    """A file that cannot be read is status 3 (the parser's documented status), as for predict."""
    from prismbatch.cli import main

    assert main(["replay", str(tmp_path / "missing.json")]) == 3
    assert "cannot read" in capsys.readouterr().err
