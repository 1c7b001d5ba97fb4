"""Timing study against python-fcl and coal: the paper's Table I and Fig. 7.

Scene (the paper's Fig. 6 sizes): a is a regular n-gon of circumradius 2, b a
regular n-gon of circumradius 2.5, both with the same n. For every vertex count
n and every case (1-9 as in the paper, 10-11 added) the poses come from
:func:`prismbatch.lab.casegen.case_poses` (half hits, half mostly near misses;
cases 1 and 5 never collide). A case that casegen cannot build for a shape
(e.g. degenerate cases on very fine polygons, whose neighbouring vertices fall
inside the tolerance band) is reported as *missing*, with casegen's message.
Every method sees the SAME poses in the same run.

Two kinds of series, kept apart:

Single-query latency (what the paper measured)
    One Python call per pose pair, on pose arrays prepared before the timed
    loop: ``prismbatch`` = :meth:`prismbatch.Collider.collide_pair` (the
    compiled one-pair path); ``prismbatch_batch1`` =
    :meth:`prismbatch.Collider.collide` on a batch of one pair ((1, 3) and
    (1, 3, 3) arrays: the general vectorised path with its argument parsing);
    ``fcl`` / ``coal`` = :class:`prismbatch.lab.peers.FCLPeer` /
    :class:`~prismbatch.lab.peers.CoalPeer` (two ``setTransform`` calls, a fresh
    request and result, ``collide``) on finite stand-ins of length
    :func:`prismbatch.lab.peers.fcl_standin_length` (maximised over all poses of
    that vertex count; the geometry is built once, outside the timing). One
    *repeat* is one loop over all poses of a case; its mean per-query time is
    loop time / poses. Methods are interleaved within each repeat (so slow
    drifts of the machine hit all of them alike), a full untimed warm-up pass
    comes first, and the garbage collector is off while timing. Reported: the
    median over repeats of the wall-clock time, with min, max and quartiles;
    as cross-checks, the calling thread's CPU time (blind to time lost to
    other processes) and how many CPUs other processes kept busy meanwhile
    (from /proc/stat).

Batch throughput
    Pairs per second through :meth:`prismbatch.Collider.collide` on a case's
    poses tiled to ``batch_pairs`` pairs (the same poses, repeated, so that a
    call lasts long enough to time), with the serial kernel
    (``parallel=False``, one thread) and the parallel one (``parallel=True``,
    ``numba.get_num_threads()`` threads); also on all cases' poses together.
    The peers have no batch call: ``collide_batch`` is a Python loop over the
    (untiled) poses of all cases, timed as such. Median of repeats.

Compile time is excluded from both: the first call of each prismbatch path
(compile, or load from Numba's cache, or nothing if this process already
had it) is timed on its own and reported.

Growth: a least-squares line ``t = intercept + slope * n`` per method, per case
and for the average over cases, reported as µs per 1000 vertices, with the
ratio of slopes prismbatch / peer next to the paper's projection / SWIFT
(0.037 / 1.3 ms per 1000 vertices = 2.8 %). prismbatch's cost grows like
log n, so its line fits poorly (see r²); the slope is still the paper's
measure.

Agreement: the peers' hit flags are compared with prismbatch's on the timed
poses. Disagreements are counted, never hidden: in the cases built with an
exact zero (2, 3, 4, 7, 8) every hit is an exact touching contact (depth 0), which
a peer may legitimately call a miss ("touching within tol"); other
disagreements are adjudicated (up to ``lp_checks`` per cell) with the exact
LP margin of :func:`prismbatch.lab.exact.margin_lp` when scipy is installed.

:func:`run_study` returns a :class:`StudyResult`; :func:`format_study` gives
the text summary; :func:`write_study` writes CSV, JSON, Markdown and figures.
"""

from __future__ import annotations

import gc
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .report import new_figure, package_versions, progress as _progress_bar, run_metadata, save_figure, write_csv, write_json
from .casegen import CASE_NUMBERS, EXACT_CASES, case_poses
from ..collide import CASES, Collider, pair_scale_tolerance
from ..shapes import Prism

__all__ = ["run_study", "format_study", "write_study", "plot_study", "fit_growth", "StudyResult",
           "PAPER_TABLE1_MS", "PAPER_GROWTH_MS_PER_1000", "PAPER_VERTICES", "PAPER_SOURCE",
           "RADIUS_A", "RADIUS_B", "METHODS", "PEERS", "DEFAULTS", "QUICK"]

#: Where the paper's numbers come from.
PAPER_SOURCE = ("Efficient Collision Detection and Detach Control for Convex Prisms in Precision "
                "Manipulation: Table I (3600-vertex end faces, Intel i3 3.30 GHz, average ms per query, "
                "100 poses per case) and Sec. VI-A / Fig. 7 (growth per 1000 vertices)")

#: The paper's Table I, ms per query at 3600 vertices, cases 1-9.
PAPER_TABLE1_MS = {
    "projection": dict(zip(range(1, 10), (0.03, 0.10, 0.17, 0.31, 0.09, 0.55, 0.12, 0.20, 0.29))),
    "swift": dict(zip(range(1, 10), (5.03, 4.96, 5.02, 5.06, 4.99, 4.95, 5.01, 5.09, 4.91))),
}
#: The paper's fitted growth (Fig. 7c), ms per 1000 vertices; ratio 2.8 %.
PAPER_GROWTH_MS_PER_1000 = {"projection": 0.037, "swift": 1.3}
#: Vertex counts of the paper's Fig. 7.
PAPER_VERTICES = (36, 180, 360, 1800, 3600)

#: The scene of the paper's Fig. 6: circumradii of a and b.
RADIUS_A = 2.0
RADIUS_B = 2.5

#: Method keys of the single-query series and what they time.
METHODS = {
    "prismbatch": "Collider.collide_pair, one call per pair",
    "prismbatch_batch1": "Collider.collide on a batch of one pair",
    "fcl": "python-fcl: setTransform x2 + collide, fresh request/result",
    "coal": "coal: setTransform x2 + collide, fresh request/result",
}
PEERS = ("fcl", "coal")

#: Defaults of the full study and of ``quick=True``.
DEFAULTS = dict(vertices=(36, 180, 360, 1800, 3600, 7200), poses_per_case=300, repeats=5, batch_pairs=100_000)
QUICK = dict(vertices=(36, 360, 1800, 3600), poses_per_case=100, repeats=3, batch_pairs=20_000)

_PAPER_CASES = tuple(range(1, 10))


@dataclass
class StudyResult:
    """Everything :func:`run_study` measured.

    Attributes
    ----------
    settings : dict
        The arguments actually used (after ``quick`` defaults), seeds, scene.
    methods : dict
        Method key -> label with the library version (``"python-fcl 0.7.0.11"``).
    latency : list of dict
        One row per (case, vertices, method): ``median_us``, ``min_us``,
        ``q1_us``, ``q3_us``, ``max_us`` (wall-clock mean time per query of
        each repeat, µs), ``thread_cpu_median_us`` (the same from the calling
        thread's CPU time: a cross-check that ignores time lost to other
        processes), ``poses``, ``repeats``, ``hits`` (the method's hit
        count), ``other_cpus`` (CPUs kept busy by other processes while the
        cell was timed, from /proc/stat; None where unavailable).
    throughput : list of dict
        One row per (case or ``"all"``, vertices, mode): ``threads``,
        ``pairs`` per call, ``median_pairs_per_s``, ``min_pairs_per_s``,
        ``max_pairs_per_s``, ``repeats``.
    agreement : list of dict
        One row per (case, vertices, peer): ``disagreements``,
        ``pb_hit_peer_miss``, ``pb_miss_peer_hit``, ``touching_exact`` (pb hit
        on a pose built exactly touching), LP adjudication counts.
    missing : list of dict
        (vertices, case, reason) for cases casegen could not build.
    growth : list of dict
        Least-squares growth per (method, series): ``slope_us_per_1000``,
        ``intercept_us``, ``r2``, ``points``, ratios of slopes to the peers.
    table1 : list of dict
        Per case at ``settings["table_vertices"]``, then the average over the
        paper's cases: µs per query of each method (wall clock; ``*_cpu_us``:
        thread CPU time), ratios, the paper's numbers (µs) and ratio.
    compile : dict
        First-call seconds of each prismbatch path (excluded from timings).
    notes : list of str
        Skipped peers and other remarks.
    """

    settings: dict
    methods: dict
    latency: list
    throughput: list
    agreement: list
    missing: list
    growth: list
    table1: list
    compile: dict
    notes: list = field(default_factory=list)
    environment: dict = field(default_factory=dict)

    def latency_us(self, method, case, vertices, stat="median_us"):
        """``stat`` (default: median µs per query) of ``method`` for one cell, or None if not measured."""
        for r in self.latency:
            if r["method"] == method and r["case"] == case and r["vertices"] == vertices:
                return r[stat]
        return None


# ---------------------------------------------------------------------------
# argument checks
# ---------------------------------------------------------------------------


def _int_tuple(x, name, minimum):
    try:
        vals = tuple(x)
    except TypeError:
        raise TypeError(f"{name} must be a sequence of integers, got {type(x).__name__}") from None
    if not vals:
        raise ValueError(f"{name} must not be empty")
    out = []
    for v in vals:
        if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)):
            raise TypeError(f"{name} must hold integers, got {v!r}")
        if v < minimum:
            raise ValueError(f"{name} values must be >= {minimum}, got {v}")
        out.append(int(v))
    if len(set(out)) != len(out):
        raise ValueError(f"{name} has repeated values: {out}")
    return tuple(out)


def _positive_int(v, name):
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)):
        raise TypeError(f"{name} must be an integer, got {v!r}")
    if v < 1:
        raise ValueError(f"{name} must be >= 1, got {v}")
    return int(v)


# ---------------------------------------------------------------------------
# statistics
# ---------------------------------------------------------------------------


def fit_growth(vertices, times):
    """Least-squares line ``t = intercept + slope * n``.

    Parameters
    ----------
    vertices : array_like, shape (k,)
        Vertex counts n (at least two distinct values).
    times : array_like, shape (k,)
        Times per query (any unit) at those counts.

    Returns
    -------
    slope_per_1000 : float
        Growth per 1000 vertices, in the unit of ``times``.
    intercept : float
        Fitted time at n = 0, same unit.
    r2 : float
        Coefficient of determination (NaN if the times are all equal).

    Raises
    ------
    ValueError
        Fewer than two distinct vertex counts, mismatched lengths or
        non-finite values.
    """
    n = np.asarray(vertices, dtype=float).ravel()
    t = np.asarray(times, dtype=float).ravel()
    if n.shape != t.shape:
        raise ValueError(f"vertices and times must have the same length, got {n.size} and {t.size}")
    if not (np.isfinite(n).all() and np.isfinite(t).all()):
        raise ValueError("vertices and times must be finite")
    if np.unique(n).size < 2:
        raise ValueError("fit_growth needs at least two distinct vertex counts")
    A = np.column_stack([np.ones_like(n), n])
    (b0, b1), *_ = np.linalg.lstsq(A, t, rcond=None)
    ss_res = float(np.sum((t - (b0 + b1 * n)) ** 2))
    ss_tot = float(np.sum((t - t.mean()) ** 2))
    r2 = 1.0 - ss_res / ss_tot if ss_tot > 0 else math.nan
    return float(b1 * 1000.0), float(b0), r2


def _stats(values):
    v = np.asarray(values, dtype=float)
    q1, med, q3 = np.percentile(v, [25, 50, 75])
    return {"median": float(med), "min": float(v.min()), "q1": float(q1), "q3": float(q3), "max": float(v.max())}


class _NoGC:
    def __enter__(self):
        self.was = gc.isenabled()
        gc.collect()
        gc.disable()

    def __exit__(self, *exc):
        if self.was:
            gc.enable()


# ---------------------------------------------------------------------------
# the run
# ---------------------------------------------------------------------------


def _versions():
    v = package_versions()
    return {"prismbatch": v["prismbatch"], "fcl": v["python-fcl"], "coal": v["coal"]}


def _method_labels(versions):
    return {"prismbatch": f"prismbatch {versions['prismbatch']} collide_pair",
            "prismbatch_batch1": f"prismbatch {versions['prismbatch']} collide (batch of 1)",
            "fcl": f"python-fcl {versions['fcl']}",
            "coal": f"coal {versions['coal']}"}


def _compile_times():
    """First call of each prismbatch path on a tiny scene (compile or cache load)."""
    from .._kernels import batch as _batch

    a, b = Prism.regular(5, RADIUS_A), Prism.regular(6, RADIUS_B)
    col = Collider(a, b)
    pa = np.zeros((4, 3))
    ra = np.broadcast_to(np.diag([1.0, -1.0, -1.0]), (4, 3, 3)).copy()
    pb_ = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [5.0, 0.0, 0.0], [1.0, 1.0, -0.5]])
    rb = np.broadcast_to(np.eye(3), (4, 3, 3)).copy()
    loaded = {name: bool(getattr(getattr(_batch, name, None), "signatures", None))
              for name in ("collide_pair", "collide_serial", "collide_parallel")}
    perf = time.perf_counter
    out = {}
    t0 = perf()
    col.collide_pair(pa[0], ra[0], pb_[0], rb[0])
    out["collide_pair_s"] = perf() - t0
    t0 = perf()
    col.collide(pa, ra, pb_, rb, parallel=False)
    out["collide_serial_s"] = perf() - t0
    t0 = perf()
    col.collide(pa, ra, pb_, rb, parallel=True)
    out["collide_parallel_s"] = perf() - t0
    # The same calls again: what a warm call costs, to read the above against.
    t0 = perf()
    col.collide(pa, ra, pb_, rb, parallel=False)
    out["second_serial_call_s"] = perf() - t0
    out["already_compiled_in_process"] = loaded
    out["numba_cache_dir"] = os.environ.get("NUMBA_CACHE_DIR") or "(default: next to the sources)"
    return out


def _make_peers(names, xy_a, xy_b, length, notes):
    """Build the requested peers; a missing library becomes a note, not an error."""
    from .peers import CoalPeer, FCLPeer

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


def _timed_loops(calls, repeats, cpu=None):
    """Warm-up pass, then ``repeats`` interleaved passes; wall seconds per pass per method.

    With a dict ``cpu``, the calling thread's CPU seconds per pass go there too
    (blind to time the thread spent descheduled by other processes).
    """
    for fn in calls.values():
        fn()
    times = {k: [] for k in calls}
    if cpu is not None:
        cpu.update({k: [] for k in calls})
    perf, tcpu = time.perf_counter, time.thread_time
    with _NoGC():
        for _ in range(repeats):
            for k, fn in calls.items():
                c0 = tcpu()
                t0 = perf()
                fn()
                t1 = perf()
                c1 = tcpu()
                times[k].append(t1 - t0)
                if cpu is not None:
                    cpu[k].append(c1 - c0)
    return times


def _cpu_snapshot():
    """(wall s, busy CPU-seconds of the whole machine or None, CPU-seconds of this process)."""
    busy = None
    try:
        with open("/proc/stat") as fh:
            f = [int(x) for x in fh.readline().split()[1:]]
        busy = (sum(f[:8]) - f[3] - (f[4] if len(f) > 4 else 0)) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError, AttributeError):
        pass
    return time.perf_counter(), busy, time.process_time()


def _other_load(s0, s1):
    """Average number of CPUs kept busy by OTHER processes between two snapshots (None if unknown)."""
    if s0[1] is None or s1[1] is None or s1[0] - s0[0] < 0.05:
        return None
    return max(0.0, ((s1[1] - s0[1]) - (s1[2] - s0[2])) / (s1[0] - s0[0]))


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


def _adjudicate(a, b, poses, idx, pb_hit, limit, rtol):
    """LP margins of up to ``limit`` disagreeing poses: (checked, touching, pb_right, pb_wrong) or Nones."""
    import importlib.util

    if importlib.util.find_spec("scipy") is None:  # exact imports scipy only when solving
        return None, None, None, None
    from .exact import margin_lp

    idx = idx[:limit]
    S, _ = pair_scale_tolerance(a, b, *(p[idx] for p in poses))
    touching = right = wrong = 0
    for j, k in enumerate(idx):
        m = margin_lp(a.xy, poses[0][k], poses[1][k], b.xy, poses[2][k], poses[3][k])
        band = max(rtol, 1e-7) * S[j]  # the LP is trusted to about 1e-7 of the scene size
        if abs(m) <= band:
            touching += 1
        elif (m > 0) == bool(pb_hit[k]):
            right += 1
        else:
            wrong += 1
    return len(idx), touching, right, wrong


def run_study(*, vertices=None, cases=CASE_NUMBERS, poses_per_case=None, repeats=None, batch_pairs=None,
              peers=PEERS, seed=0, quick=False, progress=True, lp_checks=10, table_vertices=3600):
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
        Vertex count of Table I (default 3600, as the paper); must be among
        ``vertices``.

    Returns
    -------
    StudyResult

    Raises
    ------
    ValueError, TypeError
        Bad arguments (the message names the argument).
    """
    base = QUICK if quick else DEFAULTS
    vertices = _int_tuple(base["vertices"] if vertices is None else vertices, "vertices", 3)
    cases = _int_tuple(cases, "cases", 1)
    bad = [c for c in cases if c not in CASE_NUMBERS]
    if bad:
        raise ValueError(f"cases must be among {CASE_NUMBERS}, got {bad}")
    poses_per_case = _positive_int(base["poses_per_case"] if poses_per_case is None else poses_per_case,
                                   "poses_per_case")
    repeats = _positive_int(base["repeats"] if repeats is None else repeats, "repeats")
    batch_pairs = _positive_int(base["batch_pairs"] if batch_pairs is None else batch_pairs, "batch_pairs")
    if isinstance(peers, str):
        raise TypeError(f"peers must be a sequence of names, e.g. ('fcl', 'coal'), got the string {peers!r}")
    peers = tuple(peers)
    unknown = [p for p in peers if p not in PEERS]
    if unknown:
        raise ValueError(f"peers must be among {PEERS}, got {unknown}")
    if len(set(peers)) != len(peers):
        raise ValueError(f"peers has repeated names: {peers}")
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    if isinstance(lp_checks, (bool, np.bool_)) or not isinstance(lp_checks, (int, np.integer)) or lp_checks < 0:
        raise ValueError(f"lp_checks must be a non-negative integer, got {lp_checks!r}")
    if table_vertices not in vertices:
        raise ValueError(f"table_vertices ({table_vertices}) must be one of vertices {vertices}")
    vertices = tuple(sorted(vertices))

    import numba

    versions = _versions()
    labels = _method_labels(versions)
    notes = []
    threads = numba.get_num_threads()
    env = {"loadavg_start": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
           "numba_threads": threads}
    compile_s = _compile_times()

    latency, throughput, agreement, missing = [], [], [], []
    rtol = 1e-9
    bar = _progress_bar(len(vertices) * len(cases), enabled=progress, unit="cell", desc="study")
    t_start = time.perf_counter()
    try:
        for n in vertices:
            a, b = Prism.regular(n, RADIUS_A), Prism.regular(n, RADIUS_B)
            col = Collider(a, b)
            rtol = col.rtol
            # Poses of every case first: the stand-in length is shared by the cell's peers.
            poses = {}
            for case in cases:
                rng = np.random.default_rng([seed, n, case])
                try:
                    poses[case] = case_poses(case, poses_per_case, a, b, rng, hit_fraction=0.5)
                except (ValueError, RuntimeError) as exc:
                    missing.append({"vertices": n, "case": case, "reason": str(exc)})
            if not poses:
                bar.update(len(cases))
                continue
            from .peers import fcl_standin_length

            length = max(fcl_standin_length(a.xy, b.xy, P[0][k], P[2][k])
                         for P in poses.values() for k in range(len(P[0])))
            built = _make_peers(peers, a.xy, b.xy, length, notes) if peers else {}

            for case in cases:
                bar.set_description(f"study n={n} case {case}")
                if case not in poses:
                    bar.update(1)
                    continue
                P = poses[case]
                m = len(P[0])
                f = np.ascontiguousarray
                pairs = [(f(P[0][k]), f(P[1][k]), f(P[2][k]), f(P[3][k])) for k in range(m)]
                ones = [(f(P[0][k:k + 1]), f(P[1][k:k + 1]), f(P[2][k:k + 1]), f(P[3][k:k + 1])) for k in range(m)]
                calls = {"prismbatch": _pair_loop(col, pairs), "prismbatch_batch1": _batch1_loop(col, ones)}
                items = None
                for name, peer in built.items():
                    items = items if items is not None else peer.prepare(*P)
                    calls[name] = _peer_loop(peer, items)
                hits = {k: fn() for k, fn in calls.items()}  # answers (also a first warm-up)
                cpu = {}
                snap = _cpu_snapshot()
                times = _timed_loops(calls, repeats, cpu)
                other = _other_load(snap, _cpu_snapshot())
                for k, tt in times.items():
                    s = _stats(np.asarray(tt) / m * 1e6)
                    latency.append({"case": case, "vertices": n, "method": k, "median_us": s["median"],
                                    "min_us": s["min"], "q1_us": s["q1"], "q3_us": s["q3"], "max_us": s["max"],
                                    "thread_cpu_median_us": float(np.median(cpu[k])) / m * 1e6,
                                    "poses": m, "repeats": repeats, "hits": int(hits[k].sum()),
                                    "other_cpus": other})
                ref = hits["prismbatch"]
                if not np.array_equal(hits["prismbatch_batch1"], ref):
                    notes.append(f"n={n} case {case}: collide on one pair and collide_pair disagree on "
                                 f"{int((hits['prismbatch_batch1'] != ref).sum())} poses")
                for name in built:
                    h = hits[name]
                    idx = np.flatnonzero(h != ref)
                    pb_hit_miss = int(np.count_nonzero(ref[idx]))
                    exact_touch = pb_hit_miss if case in EXACT_CASES else 0
                    # Exact touching hits are explained by construction; adjudicate the rest.
                    rest = idx if case not in EXACT_CASES else idx[~ref[idx]]
                    chk = _adjudicate(a, b, P, rest, ref, lp_checks, rtol) if (lp_checks and rest.size) \
                        else ((0, 0, 0, 0) if lp_checks else (None, None, None, None))
                    agreement.append({"case": case, "vertices": n, "peer": name, "poses": m,
                                      "pb_hits": int(ref.sum()), "peer_hits": int(h.sum()),
                                      "disagreements": int(idx.size), "pb_hit_peer_miss": pb_hit_miss,
                                      "pb_miss_peer_hit": int(idx.size) - pb_hit_miss,
                                      "touching_exact": exact_touch, "other": int(rest.size),
                                      "lp_checked": chk[0], "lp_touching": chk[1], "lp_pb_right": chk[2],
                                      "lp_pb_wrong": chk[3]})
                throughput += _throughput_pb(col, P, case, n, batch_pairs, repeats, threads)
                bar.update(1)
            # all cases together
            allP = tuple(np.concatenate([poses[c][i] for c in poses]) for i in range(4))
            throughput += _throughput_pb(col, allP, "all", n, batch_pairs, repeats, threads)
            for name, peer in built.items():
                tt = _timed_loops({name: lambda peer=peer: peer.collide_batch(*allP)}, repeats)[name]
                s = _stats(len(allP[0]) / np.asarray(tt))
                throughput.append({"case": "all", "vertices": n, "mode": f"{name}_loop", "threads": 1,
                                   "pairs": len(allP[0]), "median_pairs_per_s": s["median"],
                                   "min_pairs_per_s": s["min"], "max_pairs_per_s": s["max"], "repeats": repeats})
    finally:
        bar.close()
    env["loadavg_end"] = list(os.getloadavg()) if hasattr(os, "getloadavg") else None
    env["study_seconds"] = time.perf_counter() - t_start

    methods = {k: labels[k] for k in METHODS if k in {r["method"] for r in latency}}
    for p in peers:
        if versions.get(p) is None and not any(nt.startswith(p) for nt in notes):
            notes.append(f"{p} not installed: skipped")
    settings = {"vertices": list(vertices), "cases": list(cases), "poses_per_case": poses_per_case,
                "repeats": repeats, "batch_pairs": batch_pairs, "peers": list(peers), "seed": seed,
                "quick": bool(quick), "lp_checks": lp_checks, "table_vertices": table_vertices,
                "hit_fraction": 0.5, "radius_a": RADIUS_A, "radius_b": RADIUS_B, "rtol": rtol,
                "pose_seed_rule": "numpy.random.default_rng([seed, vertices, case])",
                "numba_threads": threads}
    res = StudyResult(settings=settings, methods=methods, latency=latency, throughput=throughput,
                      agreement=agreement, missing=missing, growth=[], table1=[], compile=compile_s,
                      notes=notes, environment=env)
    res.growth = _growth(res)
    res.table1 = _table1(res)
    return res


def _throughput_pb(col, P, case, n, batch_pairs, repeats, threads):
    m = len(P[0])
    reps = -(-batch_pairs // m)
    T = tuple(np.ascontiguousarray(np.concatenate([x] * reps)[:batch_pairs]) for x in P)
    rows = []
    for mode, par, k in (("prismbatch_1t", False, 1), ("prismbatch_allt", True, threads)):
        tt = _timed_loops({mode: lambda par=par: col.collide(*T, parallel=par)}, repeats)[mode]
        s = _stats(batch_pairs / np.asarray(tt))
        rows.append({"case": case, "vertices": n, "mode": mode, "threads": k, "pairs": batch_pairs,
                     "median_pairs_per_s": s["median"], "min_pairs_per_s": s["min"],
                     "max_pairs_per_s": s["max"], "repeats": repeats})
    return rows


def _average_series(res, method, cases):
    """{n: mean over ``cases`` of the median µs}, only for n where every one of them was measured."""
    out = {}
    for n in res.settings["vertices"]:
        v = [res.latency_us(method, c, n) for c in cases]
        if v and all(x is not None for x in v):
            out[n] = float(np.mean(v))
    return out


def _avg_cases(res):
    """Cases of the average: the paper's 1-9 among those timed at every vertex count."""
    ok = [c for c in res.settings["cases"]
          if all(res.latency_us("prismbatch", c, n) is not None for n in res.settings["vertices"])]
    paper = [c for c in ok if c in _PAPER_CASES]
    return paper or ok


def _growth(res):
    rows = []
    series = {}
    avg_cases = _avg_cases(res)
    for method in res.methods:
        for case in res.settings["cases"]:
            pts = {r["vertices"]: r["median_us"] for r in res.latency if r["method"] == method and r["case"] == case}
            series[(method, f"case {case}")] = pts
        series[(method, "average")] = _average_series(res, method, avg_cases)
    fits = {}
    for key, pts in series.items():
        if len(pts) >= 2:
            fits[key] = fit_growth(list(pts), list(pts.values())) + (len(pts),)
    for (method, name), (slope, icpt, r2, k) in fits.items():
        row = {"method": method, "series": name, "slope_us_per_1000": slope, "intercept_us": icpt, "r2": r2,
               "points": k, "cases": ",".join(map(str, avg_cases)) if name == "average" else name[5:],
               "slope_ratio_vs_fcl": None, "slope_ratio_vs_coal": None}
        for peer in PEERS:
            other = fits.get((peer, name))
            if other is not None and other[0] > 0:
                row[f"slope_ratio_vs_{peer}"] = slope / other[0]
        rows.append(row)
    return rows


def _table1(res):
    n = res.settings["table_vertices"]
    rows = []
    for case in res.settings["cases"]:
        t = {m: res.latency_us(m, case, n) for m in METHODS}
        cpu = {m: res.latency_us(m, case, n, "thread_cpu_median_us") for m in METHODS}
        pp = PAPER_TABLE1_MS["projection"].get(case)
        ps = PAPER_TABLE1_MS["swift"].get(case)
        ag = {r["peer"]: r for r in res.agreement if r["case"] == case and r["vertices"] == n}
        rows.append({
            "case": case, "vertices": n, "missing": t["prismbatch"] is None,
            "prismbatch_us": t["prismbatch"], "prismbatch_batch1_us": t["prismbatch_batch1"],
            "fcl_us": t["fcl"], "coal_us": t["coal"],
            "pb_over_fcl": _ratio(t["prismbatch"], t["fcl"]), "pb_over_coal": _ratio(t["prismbatch"], t["coal"]),
            "paper_projection_us": None if pp is None else 1e3 * pp,
            "paper_swift_us": None if ps is None else 1e3 * ps,
            "paper_ratio": _ratio(pp, ps),
            "fcl_disagreements": ag["fcl"]["disagreements"] if "fcl" in ag else None,
            "coal_disagreements": ag["coal"]["disagreements"] if "coal" in ag else None,
            "prismbatch_cpu_us": cpu["prismbatch"], "fcl_cpu_us": cpu["fcl"], "coal_cpu_us": cpu["coal"],
        })
    avg_cases = [c for c in _avg_cases(res) if res.latency_us("prismbatch", c, n) is not None]
    if avg_cases:
        mean = {m: _mean_or_none([res.latency_us(m, c, n) for c in avg_cases]) for m in METHODS}
        paper_cases = [c for c in avg_cases if c in _PAPER_CASES]
        pp = _mean_or_none([PAPER_TABLE1_MS["projection"][c] for c in paper_cases])
        ps = _mean_or_none([PAPER_TABLE1_MS["swift"][c] for c in paper_cases])
        rows.append({
            "case": "average " + ",".join(map(str, avg_cases)), "vertices": n, "missing": False,
            "prismbatch_us": mean["prismbatch"], "prismbatch_batch1_us": mean["prismbatch_batch1"],
            "fcl_us": mean["fcl"], "coal_us": mean["coal"],
            "pb_over_fcl": _ratio(mean["prismbatch"], mean["fcl"]),
            "pb_over_coal": _ratio(mean["prismbatch"], mean["coal"]),
            "paper_projection_us": None if pp is None else 1e3 * pp,
            "paper_swift_us": None if ps is None else 1e3 * ps, "paper_ratio": _ratio(pp, ps),
            "fcl_disagreements": None, "coal_disagreements": None,
            **{f"{k}_cpu_us": _mean_or_none([res.latency_us(k, c, n, "thread_cpu_median_us") for c in avg_cases])
               for k in ("prismbatch", "fcl", "coal")}})
    return rows


def _ratio(x, y):
    return None if x is None or y is None or y == 0 else x / y


def _mean_or_none(v):
    return None if not v or any(x is None for x in v) else float(np.mean(v))


# ---------------------------------------------------------------------------
# text
# ---------------------------------------------------------------------------


def _f(x, spec=".3g", none="-"):
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return none
    if spec == ".3g" and abs(x) >= 1000:
        return f"{x:.0f}"  # 5030 rather than 5.03e+03
    return format(x, spec)


def _pct(x):
    return "-" if x is None else f"{100 * x:.1f} %"


def _growth_row(res, method, series="average"):
    for r in res.growth:
        if r["method"] == method and r["series"] == series:
            return r
    return None


def format_study(res):
    """The study's summary as text lines (Table I, growth, throughput, agreement, compile).

    Parameters
    ----------
    res : StudyResult

    Returns
    -------
    list of str
    """
    s = res.settings
    L = [f"prismbatch timing study: regular n-gons of circumradius {s['radius_a']:g} (a) and {s['radius_b']:g} (b); "
         f"n = {', '.join(map(str, s['vertices']))}; cases {', '.join(map(str, s['cases']))}; "
         f"{s['poses_per_case']} poses per case (casegen, half hits), {s['repeats']} repeats after a warm-up; "
         f"seed {s['seed']}"]
    L.append("methods: " + "; ".join(f"{k} = {v}" for k, v in res.methods.items()))
    n = s["table_vertices"]
    L.append("")
    L.append(f"Table I at {n} vertices: single-query latency, µs per query (median of repeats); "
             "paper in µs (ms x 1000)")
    L.append(f"{'case':>8} {'pb':>8} {'pb(b1)':>8} {'FCL':>8} {'coal':>8} {'pb/FCL':>8} {'pb/coal':>8}"
             f" | {'paper':>7} {'SWIFT':>7} {'pap/SW':>7} | disagree FCL/coal")
    for r in res.table1:
        if r["missing"]:
            L.append(f"{str(r['case']):>8}   missing (casegen could not build it)")
            continue
        L.append(f"{str(r['case']).replace('average ', 'avg '):>8} {_f(r['prismbatch_us']):>8} "
                 f"{_f(r['prismbatch_batch1_us']):>8} {_f(r['fcl_us']):>8} {_f(r['coal_us']):>8} "
                 f"{_pct(r['pb_over_fcl']):>8} {_pct(r['pb_over_coal']):>8} | {_f(r['paper_projection_us']):>7} "
                 f"{_f(r['paper_swift_us']):>7} {_pct(r['paper_ratio']):>7} | "
                 f"{_f(r['fcl_disagreements'], 'd')}/{_f(r['coal_disagreements'], 'd')}")
    L.append("")
    pg = PAPER_GROWTH_MS_PER_1000
    L.append(f"Growth per 1000 vertices (least-squares line over n = {', '.join(map(str, s['vertices']))}; "
             f"average over cases {next((r['cases'] for r in res.growth if r['series'] == 'average'), '-')}):")
    for m in res.methods:
        g = _growth_row(res, m)
        if g is None:
            continue
        extra = ""
        if m.startswith("prismbatch"):
            extra = (f"; slope ratio vs FCL {_pct(g['slope_ratio_vs_fcl'])}, vs coal {_pct(g['slope_ratio_vs_coal'])}")
        L.append(f"   {res.methods[m]}: {g['slope_us_per_1000']:+.3g} µs per 1000 vertices, intercept "
                 f"{g['intercept_us']:.3g} µs, r² {_f(g['r2'], '.2f')}{extra}")
    L.append(f"   paper: projection {1e3 * pg['projection']:g} µs vs SWIFT {1e3 * pg['swift']:g} µs "
             f"per 1000 vertices = {_pct(pg['projection'] / pg['swift'])}")
    L.append("")
    L.append("Batch throughput, all cases' poses, pairs/s (median):")
    for nn in s["vertices"]:
        row = {r["mode"]: r for r in res.throughput if r["case"] == "all" and r["vertices"] == nn}
        if not row:
            continue
        parts = []
        for mode, r in row.items():
            lab = {"prismbatch_1t": "pb 1 thread", "prismbatch_allt": f"pb {r['threads']} threads",
                   "fcl_loop": "FCL loop", "coal_loop": "coal loop"}[mode]
            parts.append(f"{lab} {r['median_pairs_per_s']:.3g}")
        L.append(f"   n={nn}: " + ", ".join(parts))
    L.append("   (peers: collide_batch is a Python loop; pb: Collider.collide on poses tiled to "
             f"{s['batch_pairs']} pairs)")
    L.append("")
    dis = {}
    for r in res.agreement:
        d = dis.setdefault(r["peer"], {"n": 0, "dis": 0, "touch": 0, "other": 0, "lpt": 0, "lpr": 0, "lpw": 0,
                                       "lpc": 0})
        d["n"] += r["poses"]
        d["dis"] += r["disagreements"]
        d["touch"] += r["touching_exact"]
        d["other"] += r["other"]
        for k, c in (("lpc", "lp_checked"), ("lpt", "lp_touching"), ("lpr", "lp_pb_right"), ("lpw", "lp_pb_wrong")):
            d[k] += r[c] or 0
    for peer, d in dis.items():
        L.append(f"Agreement with {peer}: {d['dis']} of {d['n']} poses disagree; {d['touch']} are exact touching "
                 f"contacts (touching within tol: prismbatch hit, {peer} miss); {d['other']} others, of which "
                 f"{d['lpc']} checked by LP: {d['lpt']} in the touching band, prismbatch right {d['lpr']}, "
                 f"wrong {d['lpw']}")
    for m in res.missing:
        L.append(f"missing: n={m['vertices']} case {m['case']}: {m['reason']}")
    c = res.compile
    L.append(f"First call (compile or cache load, excluded): collide_pair {c['collide_pair_s']:.2f} s, "
             f"collide serial {c['collide_serial_s']:.2f} s, parallel {c['collide_parallel_s']:.2f} s "
             f"(a warm call: {1e3 * c['second_serial_call_s']:.2f} ms)")
    for nt in res.notes:
        L.append(f"note: {nt}")
    busy = [r["other_cpus"] for r in res.latency if r.get("other_cpus") is not None]
    if busy:
        worst = max(busy)
        crowded = sum(b > 0.5 for b in busy) / len(busy)
        L.append(f"other processes while timing: up to {worst:.1f} CPUs busy (of {os.cpu_count()}); "
                 f"{100 * crowded:.0f} % of the cells had more than 0.5 CPU busy"
                 + (" -- wall-clock latencies are inflated there; compare thread_cpu_median_us in "
                    "study_latency.csv" if worst > 0.5 else ""))
    e = res.environment
    if e.get("loadavg_start") is not None:
        L.append(f"load average (1 min) at start {e['loadavg_start'][0]:.2f}, at end {e['loadavg_end'][0]:.2f}; "
                 f"{e['numba_threads']} Numba threads; study took {e['study_seconds']:.0f} s")
    return L


# ---------------------------------------------------------------------------
# files
# ---------------------------------------------------------------------------

_LAT_COLS = ("case", "vertices", "method", "median_us", "min_us", "q1_us", "q3_us", "max_us",
             "thread_cpu_median_us", "poses", "repeats", "hits", "other_cpus")
_THR_COLS = ("case", "vertices", "mode", "threads", "pairs", "median_pairs_per_s", "min_pairs_per_s",
             "max_pairs_per_s", "repeats")
_GRO_COLS = ("method", "series", "cases", "slope_us_per_1000", "intercept_us", "r2", "points",
             "slope_ratio_vs_fcl", "slope_ratio_vs_coal")
_T1_COLS = ("case", "vertices", "missing", "prismbatch_us", "prismbatch_batch1_us", "fcl_us", "coal_us",
            "pb_over_fcl", "pb_over_coal", "paper_projection_us", "paper_swift_us", "paper_ratio",
            "fcl_disagreements", "coal_disagreements", "prismbatch_cpu_us", "fcl_cpu_us", "coal_cpu_us")
_AGR_COLS = ("case", "vertices", "peer", "poses", "pb_hits", "peer_hits", "disagreements", "pb_hit_peer_miss",
             "pb_miss_peer_hit", "touching_exact", "other", "lp_checked", "lp_touching", "lp_pb_right",
             "lp_pb_wrong")


def _cell(v):
    if v is None:
        return ""
    if isinstance(v, (bool, np.bool_)):
        return int(v)
    if isinstance(v, float):
        return "" if not math.isfinite(v) else f"{v:.6g}"
    return v


def _rows(items, cols):
    return [[_cell(r.get(c)) for c in cols] for r in items]


def _markdown(res, paths):
    s = res.settings
    L = ["# Timing study: prismbatch vs python-fcl and coal (paper Table I, Fig. 7)", ""]
    L += ["```", *format_study(res), "```", ""]
    n = s["table_vertices"]
    L += [f"## Table I at {n} vertices (µs per query; ratios next to the paper's)", "",
          "| case | prismbatch | FCL | coal | pb / FCL | pb / coal | paper projection | paper SWIFT | "
          "paper proj / SWIFT |", "|---|---|---|---|---|---|---|---|---|"]
    for r in res.table1:
        if r["missing"]:
            L.append(f"| {r['case']} | missing | | | | | | | |")
            continue
        L.append(f"| {r['case']} | {_f(r['prismbatch_us'])} | {_f(r['fcl_us'])} | {_f(r['coal_us'])} | "
                 f"{_pct(r['pb_over_fcl'])} | {_pct(r['pb_over_coal'])} | {_f(r['paper_projection_us'])} | "
                 f"{_f(r['paper_swift_us'])} | {_pct(r['paper_ratio'])} |")
    L += ["", "## Growth per 1000 vertices (average over cases)", "",
          "| method | slope (µs / 1000 vertices) | intercept (µs) | r² | slope / FCL's | slope / coal's |",
          "|---|---|---|---|---|---|"]
    for m in res.methods:
        g = _growth_row(res, m)
        if g is not None:
            pbm = m.startswith("prismbatch")
            L.append(f"| {res.methods[m]} | {g['slope_us_per_1000']:.3g} | {g['intercept_us']:.3g} | "
                     f"{_f(g['r2'], '.2f')} | {_pct(g['slope_ratio_vs_fcl']) if pbm else ''} | "
                     f"{_pct(g['slope_ratio_vs_coal']) if pbm else ''} |")
    pg = PAPER_GROWTH_MS_PER_1000
    L.append(f"| paper: projection / SWIFT | {1e3 * pg['projection']:g} / {1e3 * pg['swift']:g} | | | "
             f"{_pct(pg['projection'] / pg['swift'])} | |")
    L += ["", f"Paper numbers: {PAPER_SOURCE}.", "",
          "Single-query latency = one Python call per pair; batch throughput = one vectorised call "
          "(kept apart; see `prismbatch/study.py`). Timings on a shared machine are noisy.", ""]
    if paths.get("figures"):
        L += ["## Figures", ""] + [f"![{Path(f).stem}]({Path(f).name})" for f in paths["figures"] if f.endswith(".png")]
    L += ["", "## Files", ""] + [f"- [{Path(v).name}]({Path(v).name})" for k, v in paths.items()
                                  if isinstance(v, str) and k != "markdown"]
    return "\n".join(L) + "\n"


def write_study(result, out_dir, *, figures=True):
    """Write the study to ``out_dir``.

    Parameters
    ----------
    result : StudyResult
    out_dir : str or path-like
    figures : bool, optional
        Also draw the figures (needs matplotlib).

    Returns
    -------
    dict
        Paths: ``table1``, ``latency``, ``throughput``, ``growth``,
        ``agreement`` (CSV), ``json``, ``markdown`` and ``figures`` (list of
        PNG and SVG paths; empty without ``figures``).
    """
    if not isinstance(result, StudyResult):
        raise TypeError(f"result must be a StudyResult, got {type(result).__name__}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {"table1": write_csv(out / "study_table1.csv", _T1_COLS, _rows(result.table1, _T1_COLS)),
             "latency": write_csv(out / "study_latency.csv", _LAT_COLS, _rows(result.latency, _LAT_COLS)),
             "throughput": write_csv(out / "study_throughput.csv", _THR_COLS, _rows(result.throughput, _THR_COLS)),
             "growth": write_csv(out / "study_growth.csv", _GRO_COLS, _rows(result.growth, _GRO_COLS)),
             "agreement": write_csv(out / "study_agreement.csv", _AGR_COLS, _rows(result.agreement, _AGR_COLS)),
             "json": str(out / "study.json"), "markdown": str(out / "study.md"), "figures": []}
    if figures:
        paths["figures"] = plot_study(result, out)
    meta = run_metadata(description="prismbatch timing study vs python-fcl and coal (paper Table I, Fig. 7)",
                        settings=result.settings, methods=result.methods, method_descriptions=METHODS,
                        compile_s=result.compile, environment=result.environment, notes=result.notes,
                        missing=result.missing, table1=result.table1, growth=result.growth,
                        paper={"source": PAPER_SOURCE, "table1_ms": PAPER_TABLE1_MS,
                               "growth_ms_per_1000": PAPER_GROWTH_MS_PER_1000, "vertices": PAPER_VERTICES},
                        cases={int(k): v for k, v in CASES.items()},
                        files={k: (os.path.basename(v) if isinstance(v, str) else [os.path.basename(x) for x in v])
                               for k, v in paths.items()})
    write_json(paths["json"], meta)
    with open(paths["markdown"], "w", encoding="utf-8") as fh:
        fh.write(_markdown(result, paths))
    return paths


# ---------------------------------------------------------------------------
# figures
# ---------------------------------------------------------------------------

_SHORT = {"fcl": "FCL", "coal": "coal"}
_METHOD_STYLE = {"prismbatch": ("C0", "o"), "prismbatch_batch1": ("C9", "v"), "fcl": ("C3", "s"),
                 "coal": ("C2", "^")}


def _case_colour(case):
    import matplotlib

    return matplotlib.colormaps["tab20"]((2 * (case - 1)) % 20 + (1 if case > 10 else 0))


def _log_axes(ax, x=True, y=True):
    """Log scales with plain numbers as tick labels (5, 20, 1000 rather than 5x10^0)."""
    from matplotlib.ticker import FuncFormatter, LogLocator

    fmt = FuncFormatter(lambda v, _: f"{v:,.0f}" if v >= 1 and v == int(v) else f"{v:g}")
    for on, axis, setter in ((x, ax.xaxis, ax.set_xscale), (y, ax.yaxis, ax.set_yscale)):
        if on:
            setter("log")
            axis.set_major_formatter(fmt)
            # Label the 2 and 5 minor ticks only when a decade or less is shown.
            lo, hi = (ax.get_xlim() if axis is ax.xaxis else ax.get_ylim())
            if lo > 0 and hi / lo < 30:
                axis.set_minor_locator(LogLocator(subs=(2.0, 5.0)))
                axis.set_minor_formatter(fmt)


def _legend_below(fig, ax, ncol=3):
    """Legend under the axes, outside the data."""
    h, lab = ax.get_legend_handles_labels()
    fig.legend(h, lab, loc="outside lower center", ncol=ncol, fontsize=8)


def _per_case_axes(ax, res, method):
    for case in res.settings["cases"]:
        rows = sorted((r for r in res.latency if r["method"] == method and r["case"] == case),
                      key=lambda r: r["vertices"])
        if not rows:
            continue
        x = [r["vertices"] for r in rows]
        y = np.array([r["median_us"] for r in rows])
        lo = y - np.array([r["min_us"] for r in rows])
        hi = np.array([r["max_us"] for r in rows]) - y
        ax.errorbar(x, y, yerr=[lo, hi], marker="o", ms=3, lw=1.2, capsize=2, color=_case_colour(case),
                    label=f"case {case}")
    _log_axes(ax)
    ax.set_xlabel("end-face vertices n (each prism)")
    ax.set_ylabel("time per query (µs)")
    ax.grid(True, which="both", alpha=0.3)
    ax.set_title(res.methods.get(method, method), fontsize=10)


def plot_study(res, out_dir):
    """Draw the study's figures (PNG and SVG) into ``out_dir``; returns the file paths.

    Figures: ``study_fig7a_prismbatch`` (prismbatch per case vs n),
    ``study_fig7b_peers`` (each peer per case vs n), ``study_fig7c_average``
    (average per method with the fitted growth), ``study_table1`` (per-case
    bars at Table I's vertex count, with the paper's), ``study_throughput``
    (pairs/s of the batch call vs n).
    """
    files = []
    s = res.settings
    # Fig. 7a
    fig = new_figure(figsize=(7.5, 5.0), layout="constrained")
    ax = fig.add_subplot()
    _per_case_axes(ax, res, "prismbatch")
    ax.set_title(f"Fig. 7a: {res.methods['prismbatch']}, one Python call per pair\n"
                 f"median of {s['repeats']} repeats over {s['poses_per_case']} poses per case (bars: min-max)",
                 fontsize=10)
    _legend_below(fig, ax, ncol=6)
    files += save_figure(fig, out_dir, "study_fig7a_prismbatch")
    # Fig. 7b
    peers = [p for p in PEERS if p in res.methods]
    if peers:
        fig = new_figure(figsize=(6.0 * len(peers), 5.0), layout="constrained")
        axes = [fig.add_subplot(1, len(peers), i + 1) for i in range(len(peers))]
        for ax, p in zip(axes, peers):
            _per_case_axes(ax, res, p)
            ax.set_title(f"Fig. 7b: {res.methods[p]} (finite stand-ins)", fontsize=10)
        lo = min(ax.get_ylim()[0] for ax in axes)
        hi = max(ax.get_ylim()[1] for ax in axes)
        for ax in axes:
            ax.set_ylim(lo, hi)
        _legend_below(fig, axes[0], ncol=11 if len(peers) > 1 else 6)
        files += save_figure(fig, out_dir, "study_fig7b_peers")
    # Fig. 7c
    fig = new_figure(figsize=(7.5, 5.0), layout="constrained")
    ax = fig.add_subplot()
    avg = next((r["cases"] for r in res.growth if r["series"] == "average"), "")
    nn = np.geomspace(min(s["vertices"]), max(s["vertices"]), 200)
    for m in res.methods:
        pts = _average_series(res, m, [int(c) for c in avg.split(",") if c])
        if not pts:
            continue
        col, mk = _METHOD_STYLE[m]
        g = _growth_row(res, m)
        lab = res.methods[m]
        if g is not None:
            lab += f": {g['slope_us_per_1000']:+.3g} µs / 1000 vertices"
            if m.startswith("prismbatch"):
                rat = [f"{_pct(g[f'slope_ratio_vs_{p}'])} of {_SHORT[p]}'s" for p in PEERS
                       if g[f"slope_ratio_vs_{p}"] is not None]
                if rat:
                    lab += " (" + ", ".join(rat) + ")"
            fit = g["intercept_us"] + g["slope_us_per_1000"] * nn / 1000.0
            ax.plot(nn[fit > 0], fit[fit > 0], "--", color=col, lw=1)
        ax.plot(list(pts), list(pts.values()), marker=mk, color=col, lw=0, ms=6, label=lab)
    pg = PAPER_GROWTH_MS_PER_1000
    ax.plot([], [], "--", color="grey", label="least-squares line t = a + b n")
    _log_axes(ax)
    ax.set_xlabel("end-face vertices n (each prism)")
    ax.set_ylabel("mean time per query over cases (µs)")
    ax.grid(True, which="both", alpha=0.3)
    ax.set_title(f"Fig. 7c: average over cases {avg}, single-query latency\n"
                 f"paper: projection {1e3 * pg['projection']:g} vs SWIFT {1e3 * pg['swift']:g} µs / 1000 vertices "
                 f"({_pct(pg['projection'] / pg['swift'])})", fontsize=10)
    _legend_below(fig, ax, ncol=1)
    files += save_figure(fig, out_dir, "study_fig7c_average")
    # Table I bars
    rows = [r for r in res.table1 if isinstance(r["case"], int)]
    fig = new_figure(figsize=(9.0, 5.0), layout="constrained")
    ax = fig.add_subplot()
    bars = [("prismbatch_us", res.methods.get("prismbatch"), "C0", None),
            ("fcl_us", res.methods.get("fcl"), "C3", None), ("coal_us", res.methods.get("coal"), "C2", None),
            ("paper_projection_us", "paper: projection (i3 3.3 GHz)", "C0", "//"),
            ("paper_swift_us", "paper: SWIFT (i3 3.3 GHz)", "C3", "//")]
    bars = [b for b in bars if b[1] is not None]
    w = 0.8 / len(bars)
    x = np.arange(len(rows))
    for i, (key, lab, col, hatch) in enumerate(bars):
        y = np.array([np.nan if r[key] is None else r[key] for r in rows], dtype=float)
        ax.bar(x + (i - (len(bars) - 1) / 2) * w, y, w, label=lab, color="white" if hatch else col,
               edgecolor=col, hatch=hatch, lw=1)
    for i, r in enumerate(rows):
        if r["missing"]:
            ax.text(x[i], 1.0, "missing", rotation=90, ha="center", va="bottom", fontsize=8)
    ax.set_xticks(x, [str(r["case"]) for r in rows])
    _log_axes(ax, x=False)
    ax.set_xlabel("case")
    ax.set_ylabel("time per query (µs)")
    ax.grid(True, axis="y", which="both", alpha=0.3)
    ax.set_title(f"Table I at {s['table_vertices']} vertices: single-query latency (this machine) "
                 "and the paper's numbers", fontsize=10)
    ax.legend(fontsize=8, ncol=2, loc="upper left")
    ax.set_ylim(top=ax.get_ylim()[1] * 8)  # room for the legend above the bars
    files += save_figure(fig, out_dir, "study_table1")
    # Throughput
    fig = new_figure(figsize=(7.5, 5.0), layout="constrained")
    ax = fig.add_subplot()
    style = {"prismbatch_1t": ("C0", "o", "prismbatch {v} collide, 1 thread"),
             "prismbatch_allt": ("C1", "D", "prismbatch {v} collide, {k} threads"),
             "fcl_loop": ("C3", "s", "{fcl}, Python loop"), "coal_loop": ("C2", "^", "{coal}, Python loop")}
    from .. import __version__

    for mode, (col, mk, lab) in style.items():
        rows = sorted((r for r in res.throughput if r["case"] == "all" and r["mode"] == mode),
                      key=lambda r: r["vertices"])
        if not rows:
            continue
        y = np.array([r["median_pairs_per_s"] for r in rows])
        err = [y - np.array([r["min_pairs_per_s"] for r in rows]), np.array([r["max_pairs_per_s"] for r in rows]) - y]
        ax.errorbar([r["vertices"] for r in rows], y, yerr=err, color=col, marker=mk, capsize=2,
                    label=lab.format(v=__version__, k=rows[0]["threads"], fcl=res.methods.get("fcl"),
                                     coal=res.methods.get("coal")))
    _log_axes(ax)
    ax.set_xlabel("end-face vertices n (each prism)")
    ax.set_ylabel("throughput (pose pairs / s)")
    ax.grid(True, which="both", alpha=0.3)
    ax.set_title(f"Batch throughput on all cases' poses (prismbatch: {s['batch_pairs']} pairs per call; "
                 "bars: min-max)", fontsize=10)
    _legend_below(fig, ax, ncol=2)
    files += save_figure(fig, out_dir, "study_throughput")
    return files
