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

from .._kernels.projection import CASES
from .report import fmt, jsonable, run_metadata, write_json


def _g6(x):
    return fmt(x, ".6g")  # a trace shows six digits: enough to see a tolerance's scale


__all__ = [
    "FORMAT",
    "VERSION",
    "REQUIRED_KEYS",
    "make_record",
    "write_replay",
    "read_replay",
    "replay_record",
    "format_trace",
    "replay",
]

FORMAT = "prismbatch-replay"
VERSION = 1

#: Keys every record must have (others, e.g. "distribution", "block", "seed", are kept and shown).
REQUIRED_KEYS = (
    "kind",
    "shape_a",
    "shape_b",
    "pos_a",
    "rot_a",
    "pos_b",
    "rot_b",
    "dtype",
    "rtol",
    "atol",
    "prismbatch",
    "references",
)


def _floats(x):
    return np.asarray(x, dtype=np.float64).tolist()


def make_record(
    kind,
    shape_a,
    shape_b,
    pos_a,
    rot_a,
    pos_b,
    rot_b,
    *,
    dtype="float64",
    rtol,
    atol=0.0,
    hit,
    case,
    contact=None,
    references=None,
    **source,
):
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
    rec = {
        "kind": str(kind),
        **source,
        "shape_a": xy(shape_a),
        "shape_b": xy(shape_b),
        "pos_a": _floats(pos_a),
        "rot_a": _floats(rot_a),
        "pos_b": _floats(pos_b),
        "rot_b": _floats(rot_b),
        "dtype": str(np.dtype(dtype)),
        "rtol": float(rtol),
        "atol": float(atol),
        "prismbatch": {"hit": bool(hit), "case": int(case), "contact": None if contact is None else _floats(contact)},
        "references": dict(references or {}),
    }
    return rec


#: Number arrays of a record and their shapes (None: any length >= 1).
_ARRAYS = (
    ("shape_a", (None, 2)),
    ("shape_b", (None, 2)),
    ("pos_a", (3,)),
    ("rot_a", (3, 3)),
    ("pos_b", (3,)),
    ("rot_b", (3, 3)),
)
#: Optional record fields printed in a trace's head line.
_SHOWN = ("distribution", "block", "index", "seed", "spawn_key")
_DTYPES = ("float64", "float32")


def _text(x):
    """``str(x)`` with every non-printable character (ANSI escapes, newlines, ...) escaped.

    Text read from a replay file is untrusted: it is never printed raw.
    """
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in str(x))


def _json_type(x):
    """What a JSON value is, for error messages (never the value itself)."""
    if isinstance(x, bool):
        return "a boolean"
    if x is None:
        return "null"
    kinds = ((str, "a string"), (int, "an integer"), (float, "a number"), (list, "an array"), (dict, "an object"))
    return next((name for t, name in kinds if isinstance(x, t)), type(x).__name__)


def _expect(x, types, where, what):
    """ValueError unless ``x`` is an instance of ``types`` (bool never counts as a number)."""
    types = types if isinstance(types, tuple) else (types,)
    if not isinstance(x, types) or (isinstance(x, bool) and bool not in types):
        raise ValueError(f"{where} must be {what}, got {_json_type(x)}")
    return x


def _number(x, where, *, finite=True, null=False):
    """A JSON number as a float (not bool, not a string); finite if asked; None if ``null`` allows it."""
    if x is None and null:
        return None
    _expect(x, (int, float), where, "a number")
    try:
        v = float(x)
    except OverflowError:  # an integer beyond the float range
        v = math.inf
    if finite and not math.isfinite(v):
        raise ValueError(f"{where} must be a finite number, got {v}")
    return v


def _numbers(x, shape, where, **kw):
    """Check nested JSON arrays of numbers of ``shape`` (None: any length >= 1); ``kw`` as :func:`_number`."""
    if not shape:
        return _number(x, where, **kw)
    n = shape[0]
    _expect(x, list, where, f"an array of length {n}" if n else "a non-empty array")
    if len(x) != n if n else not x:
        raise ValueError(f"{where} has length {len(x)}, expected {n if n else '>= 1'}")
    for j, v in enumerate(x):
        _numbers(v, shape[1:], f"{where}[{j}]", **kw)
    return x


def _scalar(x, where):
    """A JSON string, number, boolean or null (a value shown as text)."""
    if isinstance(x, (int, float)) and not isinstance(x, bool):
        return _number(x, where, finite=False)
    return _expect(x, (str, bool, type(None)), where, "a string, number, boolean or null")


def _check_record(rec, where):
    """ValueError naming ``where`` and the field unless ``rec`` follows the record schema."""
    _expect(rec, dict, where, "a JSON object (a record)")
    missing = [k for k in REQUIRED_KEYS if k not in rec]
    if missing:
        raise ValueError(f"{where}: record lacks {', '.join(missing)}")
    _expect(rec["kind"], str, f"{where}: kind", "a string")
    for k, shape in _ARRAYS:
        _numbers(rec[k], shape, f"{where}: {k}")
    if not isinstance(rec["dtype"], str) or rec["dtype"] not in _DTYPES:
        raise ValueError(f'{where}: dtype must be "float64" or "float32", got {_short(rec["dtype"])}')
    for k in ("rtol", "atol"):
        v = _number(rec[k], f"{where}: {k}")
        if v < 0:
            raise ValueError(f"{where}: {k} must be >= 0, got {v:g}")
    saved = _expect(rec["prismbatch"], dict, f"{where}: prismbatch", "a JSON object")
    for k, t, what in (("hit", bool, "true or false"), ("case", int, "an integer")):
        _expect(saved.get(k), t, f"{where}: prismbatch.{k}", what)
    if saved["case"] not in CASES:
        raise ValueError(
            f"{where}: prismbatch.case must be a case number {min(CASES)}..{max(CASES)}, got {_short(saved['case'])}"
        )
    if saved.get("contact") is not None:
        _numbers(saved["contact"], (3,), f"{where}: prismbatch.contact", finite=False, null=True)
    refs = _expect(rec["references"], dict, f"{where}: references", "a JSON object")
    for k, v in refs.items():
        _scalar(v, f"{where}: references[{_text(repr(k))}]")
    for k in _SHOWN:
        if k in rec:
            _check_shown(rec[k], f"{where}: {k}")


def _check_shown(x, where):
    """A scalar, or an array of scalars (e.g. spawn_key)."""
    for j, v in enumerate(x if isinstance(x, list) else [x]):
        _scalar(v, f"{where}[{j}]" if isinstance(x, list) else where)


def _short(x):
    """A short, safe rendering of a JSON value for error messages."""
    return _json_type(x) if isinstance(x, (list, dict)) else _text(repr(x))[:60]


def write_replay(path, records, meta=None):
    """Write ``records`` (dicts, see :func:`make_record`) to a replay file; returns the path.

    ``meta`` (e.g. the run's seed and settings) is stored beside the run's
    machine metadata.
    """
    records = list(records)
    for i, rec in enumerate(records):
        _check_record(jsonable(rec), f"record {i}")  # as it will be written (NumPy scalars -> Python)
    doc = {"format": FORMAT, "version": VERSION, "meta": run_metadata(**(meta or {})), "records": records}
    return write_json(path, doc)


def read_replay(path):
    """Read a replay file; returns ``(meta, records)``.

    Every field is checked against the schema (see :func:`make_record`)
    before anything uses it.

    Raises
    ------
    ValueError
        If the file is not JSON (or nested too deeply to parse), not a
        prismbatch replay file, or a record or the meta data is malformed;
        the message names the file, the record index and the field.
    """
    where = _text(path)
    doc = _load_json(path, where)
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise ValueError(f'{where}: not a prismbatch replay file (no "format": "{FORMAT}")')
    version = doc.get("version")
    if isinstance(version, bool) or version != VERSION:
        raise ValueError(f"{where}: replay format version {_short(version)}; this prismbatch reads {VERSION}")
    records = _expect(doc.get("records"), list, f'{where}: "records"', "a list")
    for i, rec in enumerate(records):
        _check_record(rec, f"{where}: record {i}")
    meta = _expect(doc.get("meta", {}), dict, f'{where}: "meta"', "a JSON object")
    _scalar(meta.get("seed"), f"{where}: meta.seed")
    versions = _expect(meta.get("versions", {}), dict, f"{where}: meta.versions", "a JSON object")
    _scalar(versions.get("prismbatch"), f"{where}: meta.versions.prismbatch")
    return meta, records


def _load_json(path, where):
    """``json.load`` of ``path``, with every parse failure a ValueError naming the file."""
    try:
        with open(Path(path), encoding="utf-8") as f:
            return json.load(f)
    except RecursionError:
        raise ValueError(f"{where}: not a replay file: JSON nesting too deep") from None
    except ValueError as exc:  # JSONDecodeError, UnicodeDecodeError, integers too long to convert
        raise ValueError(f"{where}: not JSON ({_text(exc)})") from exc


def replay_record(rec):
    """Re-run one record; returns :meth:`prismbatch.Collider.explain`'s dict."""
    from ..collide import Collider
    from ..shapes import Prism

    dt = np.dtype(rec["dtype"])
    a, b = Prism(rec["shape_a"], name="shape_a"), Prism(rec["shape_b"], name="shape_b")
    col = Collider(a, b, rtol=rec["rtol"], atol=rec["atol"], dtype=dt)
    arr = lambda k: np.asarray(rec[k], dtype=dt)  # noqa: E731
    return col.explain(arr("pos_a"), arr("rot_a"), arr("pos_b"), arr("rot_b"))


def _known(e, key):
    return not math.isnan(e[key])


def format_trace(rec, e, *, number=None, total=None):
    """The trace of one record as text lines (``e`` from :func:`replay_record`)."""
    head = "record" + (f" {number}" if number is not None else "") + (f" of {total}" if total else "")
    src = ", ".join(f"{k} {_text(rec[k])}" for k in _SHOWN if k in rec)
    L = [f"{head}: {_text(rec['kind'])}" + (f" ({src})" if src else "")]
    na, nb = len(rec["shape_a"]), len(rec["shape_b"])
    L.append(
        f"  shapes: a {na}-gon, b {nb}-gon; {_text(rec['dtype'])}, rtol {_g6(rec['rtol'])}, atol {_g6(rec['atol'])}"
    )
    saved = rec["prismbatch"]
    refs = rec.get("references") or {}
    ref_txt = ", ".join(
        f"{_text(k)} {_text(v) if isinstance(v, (bool, str)) or v is None else _g6(v)}" for k, v in refs.items()
    )
    L.append(
        f"  saved:    prismbatch hit={saved['hit']} case {saved['case']}"
        + (f"; references: {ref_txt}" if ref_txt else "")
    )
    same = (e["hit"] == saved["hit"]) and (e["case"] == saved["case"])
    L.append(
        f"  replayed: prismbatch hit={e['hit']} case {e['case']}"
        + ("  (same as saved)" if same else "  (DIFFERS from the saved answer: the code has changed)")
    )
    p = (e["p_x"], e["p_y"], e["p_z"])
    L.append(
        f"  1. b in a's centred frame (origin at a's end-face centre, z into a): p = ({', '.join(_g6(v) for v in p)}), "
        f"d_a.d_b = R22 = {fmt(e['R22'], '.17g')}; tol = {_g6(e['tol'])}"
    )
    L.append(
        f"  2. deepest vertex of b's end face: #{int(e['i_top'])}, Δ3 = {fmt(e['delta3'], '.17g')} "
        + (
            "(< -tol: end face beyond a's plane)"
            if e["delta3"] < -e["tol"]
            else "(within ±tol: touches a's plane)"
            if e["delta3"] <= e["tol"]
            else "(> tol: crosses a's plane)"
        )
    )
    step = 3
    if _known(e, "reach_T"):
        L.append(
            f"  {step}. reach: |p_xy| = {_g6(e['lateral_offset'])}, |w| (b's axis in a's plane) = "
            f"{_g6(e['axis_xy_length'])}, T = {_g6(e['reach_T'])}; height drift |c| T = {_g6(e['height_drift'])} -> "
            + (
                "perpendicular (c taken as 0, height tol widened to " + _g6(e["height_tol"]) + ")"
                if e["perpendicular"] == 1.0
                else "not perpendicular"
            )
        )
        step += 1
    if _known(e, "near_top_vertices"):
        L.append(f"  {step}. vertices of b within tol of a's plane: {int(e['near_top_vertices'])} (3 means 3 or more)")
        step += 1
    L.append(f"  {step}. case {e['case']}: {CASES[e['case']]}")
    step += 1
    if _known(e, "coarse_margin"):
        if _known(e, "coarse_across"):
            L.append(
                f"  {step}. coarse test: across the projected axis {_g6(e['coarse_across'])}, along it "
                f"{_g6(e['coarse_along'])}, margin R_a + R_b + tol = {_g6(e['coarse_margin'])}"
                + (
                    f"; facing: {_g6(e['coarse_facing_lhs'])} vs {_g6(e['coarse_facing_rhs'])} (reject if left > right)"
                    if _known(e, "coarse_facing_lhs")
                    else ""
                )
            )
        else:
            L.append(
                f"  {step}. coarse test (parallel axes): |p_xy| = {_g6(e['lateral_offset'])} vs margin "
                f"{_g6(e['coarse_margin'])}"
            )
        step += 1
    for field, what in (("top_vertex_depth_in_Pa", "that vertex's"), ("centre_depth_in_Pa", "b's end-face centre's")):
        if _known(e, field):
            d = e[field]
            L.append(
                f"  {step}. early accept: signed depth of {what} projection in P_a = {_g6(d)} "
                + ("(inside: accept)" if d >= 0 else "(outside: go on)")
            )
            step += 1
    if _known(e, "gjk_hit"):
        L.append(
            f"  {step}. planar GJK of P_a vs the projection of b (from bottom vertex #{int(e['i_bottom'])}): "
            f"{'within tol' if e['gjk_hit'] == 1.0 else 'apart'} after {int(e['gjk_iterations'])} iteration(s)"
        )
        step += 1
    L.append(
        f"  => exit {e['exit']}: {e['exit_reason']}"
        + (f"; contact ({', '.join(_g6(v) for v in e['contact'])})" if e["hit"] else "")
    )
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
    seed, version = meta.get("seed"), meta.get("versions", {}).get("prismbatch")
    out(
        f"{_text(path)}: {len(records)} record(s)"
        + (f", run seed {_text(seed)}" if seed is not None else "")
        + (f", written by prismbatch {_text(version)}" if version is not None else "")
    )
    results = []
    for i in chosen:
        rec = records[i]
        try:
            e = replay_record(rec)
        except (ValueError, TypeError) as exc:  # polygons or poses the collision test rejects
            raise ValueError(f"{_text(path)}: record {i}: {exc}") from exc
        e["same_as_saved"] = e["hit"] == rec["prismbatch"]["hit"] and e["case"] == rec["prismbatch"]["case"]
        for line in format_trace(rec, e, number=i, total=len(records)):
            out(line)
        results.append(e)
    changed = sum(not e["same_as_saved"] for e in results)
    out(f"replayed {len(results)} record(s); {changed} answer(s) differ from the saved ones")
    return results
