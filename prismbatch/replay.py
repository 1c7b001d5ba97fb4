"""Replay files: saved pose pairs (e.g. every disagreement of a validation run)
and a step-by-step trace of how prismbatch decides each of them.

A replay file is JSON::

    {"format": "prismbatch-replay", "version": 1, "meta": {...}, "records": [...]}

Each record holds everything needed to re-run one pair with nothing else at
hand: the two polygons (vertex lists as given to :class:`~prismbatch.Prism`),
the four pose arrays, dtype, rtol and atol, what prismbatch answered when it
was saved, and what the references said. Floats are written with Python's
shortest round-trip repr, so the poses are bit-exact.

``prismbatch replay FILE`` reads the file, re-runs every pair through
:meth:`prismbatch.Collider.explain` (the compiled test with tracing on) and
prints the trace: b's pose in a's centred frame, Δ3, the reach, the case,
each coarse test, the early accept and the planar GJK, and where it exited.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ._report import run_metadata, write_json

__all__ = ["FORMAT", "VERSION", "REQUIRED_KEYS", "make_record", "write_replay", "read_replay",
           "replay_record", "format_trace", "replay"]

FORMAT = "prismbatch-replay"
VERSION = 1

#: Keys every record must have (others, e.g. "distribution", "block", "seed", are kept and shown).
REQUIRED_KEYS = ("kind", "shape_a", "shape_b", "pos_a", "rot_a", "pos_b", "rot_b", "dtype", "rtol", "atol",
                 "prismbatch", "references")


def _floats(x):
    return np.asarray(x, dtype=np.float64).tolist()


def make_record(kind, shape_a, shape_b, pos_a, rot_a, pos_b, rot_b, *, dtype="float64", rtol, atol=0.0,
                hit, case, contact=None, references=None, **source):
    """Build one replay record (a plain dict) from arrays.

    Parameters
    ----------
    kind : str
        Why the pair was saved, e.g. ``"outside band"``, ``"inside band"``,
        ``"invalid contact"``, ``"non-finite"``.
    shape_a, shape_b : Prism or array_like (n, 2)
        The polygons.
    pos_a, rot_a, pos_b, rot_b : array_like
        (3,) positions and (3, 3) rotation matrices.
    dtype, rtol, atol :
        The settings prismbatch ran with.
    hit, case, contact :
        What prismbatch answered.
    references : dict, optional
        What the references answered (e.g. ``{"fcl": False, "lp_margin": -1e-7}``).
    **source :
        Where the pair came from (distribution, block, index, seed, spawn_key, tol, band, ...).
    """
    xy = lambda s: _floats(getattr(s, "xy", s))  # noqa: E731
    rec = {"kind": str(kind), **source, "shape_a": xy(shape_a), "shape_b": xy(shape_b),
           "pos_a": _floats(pos_a), "rot_a": _floats(rot_a), "pos_b": _floats(pos_b), "rot_b": _floats(rot_b),
           "dtype": str(np.dtype(dtype)), "rtol": float(rtol), "atol": float(atol),
           "prismbatch": {"hit": bool(hit), "case": int(case),
                          "contact": None if contact is None else _floats(contact)},
           "references": dict(references or {})}
    return rec


def _check_record(rec, where):
    if not isinstance(rec, dict):
        raise ValueError(f"{where}: a record must be a JSON object, got {type(rec).__name__}")
    missing = [k for k in REQUIRED_KEYS if k not in rec]
    if missing:
        raise ValueError(f"{where}: record lacks {', '.join(missing)}")
    for k, shape in (("pos_a", (3,)), ("rot_a", (3, 3)), ("pos_b", (3,)), ("rot_b", (3, 3))):
        a = np.asarray(rec[k], dtype=float)
        if a.shape != shape:
            raise ValueError(f"{where}: {k} has shape {a.shape}, expected {shape}")


def write_replay(path, records, meta=None):
    """Write ``records`` (dicts, see :func:`make_record`) to a replay file; returns the path.

    ``meta`` (e.g. the run's seed and settings) is stored beside the run's
    machine metadata.
    """
    records = list(records)
    for i, rec in enumerate(records):
        _check_record(rec, f"record {i}")
    doc = {"format": FORMAT, "version": VERSION, "meta": run_metadata(**(meta or {})), "records": records}
    return write_json(path, doc)


def read_replay(path):
    """Read a replay file; returns ``(meta, records)``.

    Raises
    ------
    ValueError
        If the file is not a prismbatch replay file or a record is malformed.
    """
    path = Path(path)
    try:
        with open(path, encoding="utf-8") as f:
            doc = json.load(f)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not JSON ({exc})") from exc
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise ValueError(f"{path}: not a prismbatch replay file (no \"format\": \"{FORMAT}\")")
    if doc.get("version") != VERSION:
        raise ValueError(f"{path}: replay format version {doc.get('version')!r}; this prismbatch reads {VERSION}")
    records = doc.get("records")
    if not isinstance(records, list):
        raise ValueError(f"{path}: \"records\" must be a list")
    for i, rec in enumerate(records):
        _check_record(rec, f"{path}: record {i}")
    return doc.get("meta", {}), records


def replay_record(rec):
    """Re-run one record; returns :meth:`prismbatch.Collider.explain`'s dict."""
    from .collide import Collider
    from .shapes import Prism

    dt = np.dtype(rec["dtype"])
    col = Collider(Prism(rec["shape_a"]), Prism(rec["shape_b"]), rtol=rec["rtol"], atol=rec["atol"], dtype=dt)
    arr = lambda k: np.asarray(rec[k], dtype=dt)  # noqa: E731
    return col.explain(arr("pos_a"), arr("rot_a"), arr("pos_b"), arr("rot_b"))


def _g(x, digits=6):
    if x is None:
        return "-"
    x = float(x)
    return "-" if math.isnan(x) else f"{x:.{digits}g}"


def _known(e, key):
    return not math.isnan(e[key])


def format_trace(rec, e, *, number=None, total=None):
    """The trace of one record as text lines (``e`` from :func:`replay_record`)."""
    from ._projection import CASES

    head = "record" + (f" {number}" if number is not None else "") + (f" of {total}" if total else "")
    src = ", ".join(f"{k} {rec[k]}" for k in ("distribution", "block", "index", "seed", "spawn_key") if k in rec)
    L = [f"{head}: {rec['kind']}" + (f" ({src})" if src else "")]
    na, nb = len(rec["shape_a"]), len(rec["shape_b"])
    L.append(f"  shapes: a {na}-gon, b {nb}-gon; {rec['dtype']}, rtol {_g(rec['rtol'])}, atol {_g(rec['atol'])}")
    saved = rec["prismbatch"]
    refs = rec.get("references") or {}
    ref_txt = ", ".join(f"{k} {v if isinstance(v, (bool, str)) or v is None else _g(v)}" for k, v in refs.items())
    L.append(f"  saved:    prismbatch hit={saved['hit']} case {saved['case']}" + (f"; references: {ref_txt}" if ref_txt else ""))
    same = (e["hit"] == saved["hit"]) and (e["case"] == saved["case"])
    L.append(f"  replayed: prismbatch hit={e['hit']} case {e['case']}"
             + ("  (same as saved)" if same else "  (DIFFERS from the saved answer: the code has changed)"))
    p = (e["p_x"], e["p_y"], e["p_z"])
    L.append(f"  1. b in a's centred frame (origin at a's end-face centre, z into a): p = ({', '.join(_g(v) for v in p)}), "
             f"d_a.d_b = R22 = {_g(e['R22'], 17)}; tol = {_g(e['tol'])}")
    L.append(f"  2. deepest vertex of b's end face: #{int(e['i_top'])}, Δ3 = {_g(e['delta3'], 17)} "
             + ("(< -tol: end face beyond a's plane)" if e["delta3"] < -e["tol"] else
                "(within ±tol: touches a's plane)" if e["delta3"] <= e["tol"] else "(> tol: crosses a's plane)"))
    step = 3
    if _known(e, "reach_T"):
        L.append(f"  {step}. reach: |p_xy| = {_g(e['lateral_offset'])}, |w| (b's axis in a's plane) = "
                 f"{_g(e['axis_xy_length'])}, T = {_g(e['reach_T'])}; height drift |c| T = {_g(e['height_drift'])} -> "
                 + ("perpendicular (c taken as 0, height tol widened to " + _g(e["height_tol"]) + ")"
                    if e["perpendicular"] == 1.0 else "not perpendicular"))
        step += 1
    if _known(e, "near_top_vertices"):
        L.append(f"  {step}. vertices of b within tol of a's plane: {int(e['near_top_vertices'])} (3 means 3 or more)")
        step += 1
    L.append(f"  {step}. case {e['case']}: {CASES[e['case']]}")
    step += 1
    if _known(e, "coarse_margin"):
        if _known(e, "coarse_across"):
            L.append(f"  {step}. coarse test: across the projected axis {_g(e['coarse_across'])}, along it "
                     f"{_g(e['coarse_along'])}, margin R_a + R_b + tol = {_g(e['coarse_margin'])}"
                     + (f"; facing: {_g(e['coarse_facing_lhs'])} vs {_g(e['coarse_facing_rhs'])} "
                        "(reject if left > right)" if _known(e, "coarse_facing_lhs") else ""))
        else:
            L.append(f"  {step}. coarse test (parallel axes): |p_xy| = {_g(e['lateral_offset'])} vs margin "
                     f"{_g(e['coarse_margin'])}")
        step += 1
    if _known(e, "top_vertex_depth_in_Pa"):
        d = e["top_vertex_depth_in_Pa"]
        L.append(f"  {step}. early accept: signed depth of that vertex's projection in P_a = {_g(d)} "
                 + ("(inside: accept)" if d >= 0 else "(outside: go on)"))
        step += 1
    if _known(e, "gjk_hit"):
        L.append(f"  {step}. planar GJK of P_a vs the projection of b (from bottom vertex #{int(e['i_bottom'])}): "
                 f"{'within tol' if e['gjk_hit'] == 1.0 else 'apart'} after {int(e['gjk_iterations'])} iteration(s)")
        step += 1
    L.append(f"  => exit {e['exit']}: {e['exit_reason']}"
             + (f"; contact ({', '.join(_g(v) for v in e['contact'])})" if e["hit"] else ""))
    return L


def replay(path, *, out=print, indices=None):
    """Re-run the pairs of a replay file and print their traces.

    Parameters
    ----------
    path : str or Path
        A file written by :func:`write_replay` (e.g. ``validation_replay.json``).
    out : callable, optional
        Receives each output line (default ``print``).
    indices : sequence of int, optional
        Only these records (0-based); default all.

    Returns
    -------
    list of dict
        One :meth:`~prismbatch.Collider.explain` dict per replayed record, with
        ``"same_as_saved"`` added.
    """
    meta, records = read_replay(path)
    chosen = range(len(records)) if indices is None else list(indices)
    for i in chosen:
        if not 0 <= i < len(records):
            raise ValueError(f"record index {i} out of range: the file holds {len(records)} record(s)")
    seed = meta.get("seed")
    out(f"{path}: {len(records)} record(s)" + (f", run seed {seed}" if seed is not None else "")
        + (f", written by prismbatch {meta['versions']['prismbatch']}" if "versions" in meta else ""))
    results = []
    for i in chosen:
        rec = records[i]
        e = replay_record(rec)
        e["same_as_saved"] = e["hit"] == rec["prismbatch"]["hit"] and e["case"] == rec["prismbatch"]["case"]
        for line in format_trace(rec, e, number=i, total=len(records)):
            out(line)
        results.append(e)
    changed = sum(not e["same_as_saved"] for e in results)
    out(f"replayed {len(results)} record(s); {changed} answer(s) differ from the saved ones")
    return results
