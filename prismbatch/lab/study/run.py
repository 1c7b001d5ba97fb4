"""The measurement: :func:`run_study` and its steps (scene, latency, agreement, throughput).

Method: docs/methods/study.md.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field

import numpy as np

from ...collide import Collider
from ...config import DEFAULT_RTOL
from ...shapes import Prism
from ..casegen import CASE_NUMBERS, case_poses
from ..checkpoint import Checkpoint, Interrupted, run_unit
from ..checks import check_int, check_int_tuple, check_vertex_counts, is_int
from ..report import package_versions
from ..report import progress as progress_bar
from ..timing import cpu_snapshot, other_load, stats, timed_loops
from .agreement import agreement_rows
from .analysis import growth_rows, table1_rows
from .constants import DEFAULTS, METHODS, PAPER_TABLE_VERTICES, PEERS, QUICK, RADIUS_A, RADIUS_B
from .result import StudyResult
from .timing import compile_times

# ---------------------------------------------------------------------------
# argument checks
# ---------------------------------------------------------------------------


def _check_arguments(
    vertices, cases, poses_per_case, repeats, batch_pairs, peers, seed, quick, lp_checks, table_vertices
):
    """The arguments of :func:`run_study` checked, with the ``quick`` or full defaults filled in."""
    base = QUICK if quick else DEFAULTS
    vertices = check_vertex_counts(check_int_tuple(base["vertices"] if vertices is None else vertices, "vertices", 3))
    cases = check_int_tuple(cases, "cases", 1)
    bad = [c for c in cases if c not in CASE_NUMBERS]
    if bad:
        raise ValueError(f"cases must be among {CASE_NUMBERS}, got {bad}")
    poses_per_case = check_int(base["poses_per_case"] if poses_per_case is None else poses_per_case, "poses_per_case")
    repeats = check_int(base["repeats"] if repeats is None else repeats, "repeats")
    batch_pairs = check_int(base["batch_pairs"] if batch_pairs is None else batch_pairs, "batch_pairs")
    if isinstance(peers, str):
        raise TypeError(f"peers must be a sequence of names, e.g. ('fcl', 'coal'), got the string {peers!r}")
    peers = tuple(peers)
    unknown = [p for p in peers if p not in PEERS]
    if unknown:
        raise ValueError(f"peers must be among {PEERS}, got {unknown}")
    if len(set(peers)) != len(peers):
        raise ValueError(f"peers has repeated names: {peers}")
    if not is_int(seed) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    if not is_int(lp_checks) or lp_checks < 0:
        raise ValueError(f"lp_checks must be a non-negative integer, got {lp_checks!r}")
    if table_vertices is None:  # the paper's 3600 when measured, else the largest count measured
        table_vertices = PAPER_TABLE_VERTICES if PAPER_TABLE_VERTICES in vertices else max(vertices)
    elif table_vertices not in vertices:
        raise ValueError(
            f"the Table I vertex count (--table-vertices / table_vertices) {table_vertices} is not among "
            f"the vertex counts measured {tuple(sorted(vertices))}"
        )
    return tuple(sorted(vertices)), cases, poses_per_case, repeats, batch_pairs, peers, table_vertices


# ---------------------------------------------------------------------------
# methods and peers
# ---------------------------------------------------------------------------


def _versions():
    v = package_versions()
    return {"prismbatch": v["prismbatch"], "fcl": v["python-fcl"], "coal": v["coal"]}


def _method_labels(versions):
    return {
        "prismbatch": f"prismbatch {versions['prismbatch']} collide_pair",
        "prismbatch_batch1": f"prismbatch {versions['prismbatch']} collide (batch of 1)",
        "fcl": f"python-fcl {versions['fcl']}",
        "coal": f"coal {versions['coal']}",
    }


def _make_peers(names, xy_a, xy_b, length, notes):
    """Build the requested peers; a missing library becomes a note, not an error."""
    from ..peers import CoalPeer, FCLPeer

    built = {}
    for name in names:
        cls = FCLPeer if name == "fcl" else CoalPeer
        try:
            built[name] = cls(xy_a, xy_b, length)
        except ImportError as exc:
            msg = f"{name} skipped: {exc}"
            if msg not in notes:
                notes.append(msg)
    return built


def _pair_loop(col, pairs):
    cp = col.collide_pair

    def run():
        out = np.empty(len(pairs), dtype=bool)
        for k, (pa, ra, pb_, rb) in enumerate(pairs):
            out[k] = cp(pa, ra, pb_, rb).hit
        return out

    return run


def _batch1_loop(col, ones):
    c = col.collide

    def run():
        out = np.empty(len(ones), dtype=bool)
        for k, (pa, ra, pb_, rb) in enumerate(ones):
            out[k] = c(pa, ra, pb_, rb).hit[0]
        return out

    return run


def _peer_loop(peer, items):
    return lambda: peer.run(items)


# ---------------------------------------------------------------------------
# the steps of one vertex count
# ---------------------------------------------------------------------------


@dataclass
class _Tables:
    """The rows collected so far (they become the StudyResult's lists)."""

    latency: list = field(default_factory=list)
    throughput: list = field(default_factory=list)
    agreement: list = field(default_factory=list)
    missing: list = field(default_factory=list)
    notes: list = field(default_factory=list)

    def extend(self, other):
        """Append the rows of ``other`` (one vertex count's, measured or loaded from a checkpoint)."""
        for name in ("latency", "throughput", "agreement", "missing", "notes"):
            getattr(self, name).extend(getattr(other, name))


def _scene_poses(n, a, b, cases, poses_per_case, seed, missing):
    """Poses of every case at ``n`` vertices ({case: pose arrays}); unbuildable cases go to ``missing``."""
    poses = {}
    for case in cases:
        rng = np.random.default_rng([seed, n, case])
        try:
            poses[case] = case_poses(case, poses_per_case, a, b, rng, hit_fraction=0.5)
        except (ValueError, RuntimeError) as exc:
            missing.append({"vertices": n, "case": case, "reason": str(exc)})
    return poses


def _scene_peers(a, b, poses, peers, notes):
    """The peers of one vertex count, on stand-ins long enough for every pose of every case."""
    from ..peers import standin_length

    length = max(standin_length(a.xy, b.xy, *P) for P in poses.values())
    return _make_peers(peers, a.xy, b.xy, length, notes) if peers else {}


def _latency_calls(col, built, P):
    """The single-query loops of one case: method key -> function returning the hit flags of all poses."""
    m = len(P[0])
    f = np.ascontiguousarray
    pairs = [(f(P[0][k]), f(P[1][k]), f(P[2][k]), f(P[3][k])) for k in range(m)]
    ones = [(f(P[0][k : k + 1]), f(P[1][k : k + 1]), f(P[2][k : k + 1]), f(P[3][k : k + 1])) for k in range(m)]
    calls = {"prismbatch": _pair_loop(col, pairs), "prismbatch_batch1": _batch1_loop(col, ones)}
    items = None
    for name, peer in built.items():
        items = items if items is not None else peer.prepare(*P)
        calls[name] = _peer_loop(peer, items)
    return calls


def _latency_series(calls, case, n, m, repeats):
    """Time the single-query loops of one case; (hit flags by method, latency rows)."""
    hits = {k: fn() for k, fn in calls.items()}  # answers (also a first warm-up)
    cpu = {}
    snap = cpu_snapshot()
    times = timed_loops(calls, repeats, cpu)
    other = other_load(snap, cpu_snapshot())
    rows = []
    for k, tt in times.items():
        s = stats(np.asarray(tt) / m * 1e6)
        rows.append(
            {
                "case": case,
                "vertices": n,
                "method": k,
                "median_us": s["median"],
                "min_us": s["min"],
                "q1_us": s["q1"],
                "q3_us": s["q3"],
                "max_us": s["max"],
                "thread_cpu_median_us": float(np.median(cpu[k])) / m * 1e6,
                "poses": m,
                "repeats": repeats,
                "hits": int(hits[k].sum()),
                "other_cpus": other,
            }
        )
    return hits, rows


def _throughput_row(case, n, mode, threads, pairs, seconds, repeats):
    s = stats(pairs / np.asarray(seconds))
    return {
        "case": case,
        "vertices": n,
        "mode": mode,
        "threads": threads,
        "pairs": pairs,
        "median_pairs_per_s": s["median"],
        "min_pairs_per_s": s["min"],
        "max_pairs_per_s": s["max"],
        "repeats": repeats,
    }


def _throughput_pb(col, P, case, n, batch_pairs, repeats, threads):
    """Pairs/s of Collider.collide on ``P`` tiled to ``batch_pairs``, serial and parallel."""
    m = len(P[0])
    reps = -(-batch_pairs // m)
    T = tuple(np.ascontiguousarray(np.concatenate([x] * reps)[:batch_pairs]) for x in P)
    rows = []
    for mode, par, k in (("prismbatch_1t", False, 1), ("prismbatch_allt", True, threads)):
        tt = timed_loops({mode: lambda par=par: col.collide(*T, parallel=par)}, repeats)[mode]
        rows.append(_throughput_row(case, n, mode, k, batch_pairs, tt, repeats))
    return rows


def _throughput_all(col, built, poses, n, batch_pairs, repeats, threads):
    """Throughput on all cases' poses together: prismbatch's batch call and each peer's Python loop."""
    allP = tuple(np.concatenate([poses[c][i] for c in poses]) for i in range(4))
    rows = _throughput_pb(col, allP, "all", n, batch_pairs, repeats, threads)
    for name, peer in built.items():
        tt = timed_loops({name: lambda peer=peer: peer.collide_batch(*allP)}, repeats)[name]
        rows.append(_throughput_row("all", n, f"{name}_loop", 1, len(allP[0]), tt, repeats))
    return rows


def _measure_case(col, a, b, built, P, case, n, cfg, out):
    """Latency, agreement and throughput of one (case, n) cell, appended to ``out``."""
    m = len(P[0])
    hits, rows = _latency_series(_latency_calls(col, built, P), case, n, m, cfg["repeats"])
    out.latency += rows
    ref = hits["prismbatch"]
    if not np.array_equal(hits["prismbatch_batch1"], ref):
        out.notes.append(
            f"n={n} case {case}: collide on one pair and collide_pair disagree on "
            f"{int((hits['prismbatch_batch1'] != ref).sum())} poses"
        )
    out.agreement += agreement_rows(a, b, P, hits, built, case, n, cfg["lp_checks"], col.rtol)
    out.throughput += _throughput_pb(col, P, case, n, cfg["batch_pairs"], cfg["repeats"], cfg["threads"])


def _measure_vertices(n, col, a, b, cfg, bar, out):
    """Every case at ``n`` vertices, then the all-cases throughput."""
    cases = cfg["cases"]
    poses = _scene_poses(n, a, b, cases, cfg["poses_per_case"], cfg["seed"], out.missing)
    if not poses:
        bar.update(len(cases))
        return
    built = _scene_peers(a, b, poses, cfg["peers"], out.notes)
    for case in cases:
        bar.set_description(f"study n={n} case {case}")
        if case in poses:
            _measure_case(col, a, b, built, poses[case], case, n, cfg, out)
        bar.update(1)
    out.throughput += _throughput_all(col, built, poses, n, cfg["batch_pairs"], cfg["repeats"], cfg["threads"])


# ---------------------------------------------------------------------------
# the run
# ---------------------------------------------------------------------------


def run_study(
    *,
    vertices=None,
    cases=CASE_NUMBERS,
    poses_per_case=None,
    repeats=None,
    batch_pairs=None,
    peers=PEERS,
    seed=0,
    quick=False,
    progress=True,
    lp_checks=10,
    table_vertices=None,
    checkpoint_dir=None,
    resume=False,
):
    """Time prismbatch against python-fcl and coal per case and vertex count.

    Parameters
    ----------
    vertices : sequence of int, optional
        Vertex counts n of both end faces (regular n-gons of circumradius 2
        and 2.5). Default ``DEFAULTS["vertices"]`` (36 ... 7200), or
        ``QUICK["vertices"]`` with ``quick=True``.
    cases : sequence of int, optional
        Cases to time (1-11; default all).
    poses_per_case : int, optional
        Pose pairs per case and vertex count (default 300; quick 100).
    repeats : int, optional
        Timed passes over the poses after one warm-up pass (default 5; quick 3).
    batch_pairs : int, optional
        Pairs per vectorised call in the throughput series (a case's poses
        tiled to this length; default 100000; quick 20000).
    peers : sequence of {"fcl", "coal"}, optional
        Peer libraries; one that is not installed is skipped with a note.
    seed : int, optional
        Seed of the pose generators (each (n, case) cell gets its own stream).
    quick : bool, optional
        Smaller defaults for a smoke run (about a minute); explicit arguments
        still win.
    progress : bool, optional
        Show a progress bar on stderr (tqdm, if installed).
    lp_checks : int, optional
        Disagreements adjudicated with the exact LP per (case, n, peer)
        (needs scipy; 0 turns it off).
    table_vertices : int, optional
        Vertex count of Table I, among ``vertices``; by default 3600 (the
        paper's) when measured, else the largest count measured. At another
        count the report says that the paper's columns are not comparable.
    checkpoint_dir : str or path-like, optional
        Save each vertex count's rows when finished, under
        ``checkpoint_dir/checkpoint/study`` (:class:`~prismbatch.lab.checkpoint.Checkpoint`).
    resume : bool, optional
        Load the vertex counts an earlier run with the same settings finished
        there (their timings are that run's; ``settings["resumed_vertices"]``
        lists them).

    Returns
    -------
    StudyResult

    Raises
    ------
    ValueError, TypeError
        Bad arguments (the message names the argument).
    """
    vertices, cases, poses_per_case, repeats, batch_pairs, peers, table_vertices = _check_arguments(
        vertices, cases, poses_per_case, repeats, batch_pairs, peers, seed, quick, lp_checks, table_vertices
    )

    import numba

    versions = _versions()
    labels = _method_labels(versions)
    out = _Tables()
    threads = numba.get_num_threads()
    env = {"loadavg_start": list(os.getloadavg()) if hasattr(os, "getloadavg") else None, "numba_threads": threads}
    compile_s = compile_times()
    cfg = {
        "cases": cases,
        "poses_per_case": poses_per_case,
        "repeats": repeats,
        "batch_pairs": batch_pairs,
        "peers": peers,
        "seed": seed,
        "lp_checks": lp_checks,
        "threads": threads,
    }

    ckpt = None
    if checkpoint_dir is not None:
        ckpt = Checkpoint(checkpoint_dir, "study", {**cfg, "vertices": vertices, "quick": quick}, resume=resume)
    bar = progress_bar(len(vertices) * len(cases), enabled=progress, unit="cell", desc="study")
    t_start = time.perf_counter()
    resumed, finished = [], []

    def measure(n):
        a, b = Prism.regular(n, RADIUS_A), Prism.regular(n, RADIUS_B)
        cell = _Tables()
        _measure_vertices(n, Collider(a, b), a, b, cfg, bar, cell)
        return cell

    try:
        for n in vertices:
            cell, loaded = run_unit(ckpt, f"vertices-{n}", lambda n=n: measure(n))
            if loaded:
                resumed.append(n)
                bar.update(len(cases))
            out.extend(cell)
            finished.append(n)
    except KeyboardInterrupt:
        raise Interrupted(len(finished), len(vertices), "vertex count", checkpoint=ckpt) from None
    finally:
        bar.close()
    env["loadavg_end"] = list(os.getloadavg()) if hasattr(os, "getloadavg") else None
    env["study_seconds"] = time.perf_counter() - t_start

    methods = {k: labels[k] for k in METHODS if k in {r["method"] for r in out.latency}}
    for p in peers:
        if versions.get(p) is None and not any(nt.startswith(p) for nt in out.notes):
            out.notes.append(f"{p} not installed: skipped")
    settings = {
        "vertices": list(vertices),
        "cases": list(cases),
        "poses_per_case": poses_per_case,
        "repeats": repeats,
        "batch_pairs": batch_pairs,
        "peers": list(peers),
        "seed": seed,
        "quick": bool(quick),
        "lp_checks": lp_checks,
        "table_vertices": table_vertices,
        "hit_fraction": 0.5,
        "radius_a": RADIUS_A,
        "radius_b": RADIUS_B,
        "rtol": DEFAULT_RTOL[np.dtype(np.float64)],  # every Collider of the study uses the default
        "pose_seed_rule": "numpy.random.default_rng([seed, vertices, case])",
        "numba_threads": threads,
        "resumed_vertices": resumed,
    }
    res = StudyResult(
        settings=settings,
        methods=methods,
        latency=out.latency,
        throughput=out.throughput,
        agreement=out.agreement,
        missing=out.missing,
        growth=[],
        table1=[],
        compile=compile_s,
        notes=out.notes,
        environment=env,
    )
    res.growth = growth_rows(res)
    res.table1 = table1_rows(res)
    return res
