#!/usr/bin/env python
"""Core benchmark of prismbatch against python-fcl and coal.

What is measured (see benchmarks/README.md for how to run it):

* per-pair time of ``prismbatch`` at 36, 360 and 3600 vertices, on *facing*
  (paper-like) poses and on fully random (*free*) poses;
* one thread (``Collider.collide(..., parallel=False)`` with
  ``numba.set_num_threads(1)``) and all threads (``parallel=True`` with every
  Numba thread), status-only and with contact points;
* python-fcl and coal on the SAME pose pairs in the same run: a fixed subset
  of the prismbatch pairs, on which prismbatch is timed again so that the
  ratio compares identical work; each peer query is setTransform (both
  objects) + collide with a fresh request/result, the geometry being built
  once;
* agreement of the hit flags on that subset (the peers use finite stand-ins
  of length ``standin_length`` (proven per pair); disagreements are counted, adjudicated
  with the LP reference of tests/reference.py when available, and written out
  with reproducers, never treated as failures);
* first-call (compile) time of the serial and of the parallel kernel in fresh
  subprocesses with an empty Numba cache, and the first-call time again with
  that cache warm.

Timings are medians over repeats with min/max and quartiles.  Each repeat
times one call over all pairs of a set (prismbatch) or one Python loop over
the subset (peers); per-pair time = call time / number of pairs.

Results: a Markdown report on stdout plus ``results.csv``, ``meta.json`` and
``disagreements.json`` in ``--out`` (default benchmarks/results/).
"""

from __future__ import annotations

import argparse
import csv
import datetime as _dt
import importlib.util
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from bench_floor import COLD_BATCHES, cold_compile

from prismbatch.lab.report import fmt, run_metadata
from prismbatch.lab.timing import IdleWaiter, cpu_snapshot, other_load, stats, thread_use, threads, timed_loops
from prismbatch.sampling import facing_poses, free_poses

HERE = Path(__file__).resolve().parent
REPO = HERE.parent

SIZES = (36, 360, 3600)
RADIUS_A = 2.0
RADIUS_B = 2.5
FACING_MAX_TILT_DEG = 15.0
TARGETS = {36: 10.0, 3600: 20.0}  # FCL / prismbatch(1 thread), per pair


# ---------------------------------------------------------------------------
# pose generators
# ---------------------------------------------------------------------------
def poses_facing(rng, n):
    """Paper-like scene (prismbatch.sampling.facing_poses): a pointing down, b up, tilted <= 15 deg."""
    return facing_poses(n, rng, radius=RADIUS_B, max_tilt=np.deg2rad(FACING_MAX_TILT_DEG))


def poses_free(rng, n):
    """Uniform random rotations for both, centres uniform in [-5, 5]^3 (prismbatch.sampling.free_poses)."""
    return free_poses(n, rng, radius=RADIUS_B)


POSE_SETS = {"facing": poses_facing, "free": poses_free}


# ---------------------------------------------------------------------------
# timing helpers
# ---------------------------------------------------------------------------
def time_repeats(fn, repeats, warmup=1):
    """Run fn() warmup + repeats times; wall and process-CPU seconds per repeat."""
    cpu = {}
    walls = timed_loops({"fn": fn}, repeats, cpu=cpu, cpu_clock=time.process_time, warmup=warmup)["fn"]
    return np.array(walls), np.array(cpu["fn"])


def summarize(walls, cpus, n_pairs):
    """Per-pair statistics in microseconds, and process CPU time / wall time (~1 on one thread, ~k on k)."""
    us = stats(np.asarray(walls) / n_pairs * 1e6)
    out = {f"{k}_us": v for k, v in us.items()}
    cpu_per_wall = float(np.sum(cpus) / max(np.sum(walls), 1e-12))
    return {**out, "repeats": len(walls), "n_pairs": int(n_pairs), "cpu_per_wall": cpu_per_wall}


# ---------------------------------------------------------------------------
# peers
# ---------------------------------------------------------------------------
def _load_reference():
    """tests/reference.py (LP ground truth) if present and scipy is installed."""
    path = REPO / "tests" / "reference.py"
    if not path.exists():
        return None
    try:
        spec = importlib.util.spec_from_file_location("_prismbatch_test_reference", path)
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        return mod
    except Exception:  # noqa: BLE001 - optional diagnostics only
        return None


# ---------------------------------------------------------------------------
# one (n, pose set) cell
# ---------------------------------------------------------------------------
def bench_cell(n, pose_name, args, all_threads, ref, log, waiter):
    import prismbatch as pb
    from prismbatch.lab.peers import CoalPeer, FCLPeer, standin_length

    load_start = _loadavg()
    snap0 = cpu_snapshot()
    rng = np.random.default_rng([args.seed, n, list(POSE_SETS).index(pose_name)])
    pos_a, rot_a, pos_b, rot_b = POSE_SETS[pose_name](rng, args.n_pairs)
    a = pb.Prism.regular(n, RADIUS_A)
    b = pb.Prism.regular(n, RADIUS_B)
    col = pb.Collider(a, b)
    rep = args.repeats
    rows = {}

    def measure(fn, repeats, n_pairs, warmup=1):
        """time_repeats + summarize; with --wait-idle, re-measure (up to 2 more
        times) when other processes kept a CPU busy during the measurement."""
        for attempt in range(3):
            s0 = cpu_snapshot()
            walls, cpus = time_repeats(fn, repeats, warmup)
            # /proc/stat counts in clock ticks: judge other processes over >= 0.5 s
            # (padding a short measurement with a sleep when waiting is enabled).
            short = time.perf_counter() - s0[0] < 0.5
            if short and waiter.active:
                time.sleep(0.5 - (time.perf_counter() - s0[0]))
            other = None if short and not waiter.active else other_load(s0, cpu_snapshot())
            if not waiter.active or other is None or other < waiter.threshold or attempt == 2:
                break
            log(f"  contended measurement ({other:.2f} other CPUs busy): waiting, re-measuring")
            waiter.wait()
        r = summarize(walls, cpus, n_pairs)
        r["other_cpus"] = other
        r["attempts"] = attempt + 1
        return r

    def pb_call(P, R_a, Q, R_b, contact, parallel):
        return lambda: col.collide(P, R_a, Q, R_b, contact=contact, parallel=parallel)

    full = (pos_a, rot_a, pos_b, rot_b)
    M = min(args.n_peer, args.n_pairs)
    sub = tuple(x[:M] for x in full)

    # --- prismbatch, full set ---
    with threads(1):
        res_full = col.collide(*full, parallel=False)
        res_contact = col.collide(*full, contact=True, parallel=False)
        for key, contact in (("pb_1t_status", False), ("pb_1t_contact", True)):
            rows[key] = measure(pb_call(*full, contact, False), rep, args.n_pairs)
    with threads(all_threads):
        for key, contact in (("pb_all_status", False), ("pb_all_contact", True)):
            rows[key] = measure(pb_call(*full, contact, True), rep, args.n_pairs)
        rows["pb_all_status"]["cpu_per_wall_timed"] = rows["pb_all_status"]["cpu_per_wall"]
        rows["pb_all_status"]["cpu_per_wall"] = thread_use(pb_call(*full, False, True))
    # latency of a call with a single pair (fixed per-call overhead dominates)
    one = tuple(x[:1] for x in full)
    with threads(1):
        rows["pb_1t_single_pair_call"] = summarize(
            *time_repeats(pb_call(*one, False, False), max(rep, 200), warmup=5), 1
        )
        pair = tuple(np.ascontiguousarray(x[0]) for x in full)
        rows["pb_collide_pair_call"] = summarize(
            *time_repeats(lambda: col.collide_pair(*pair), max(rep, 200), warmup=5), 1
        )
    res_par = col.collide(*full, parallel=True)
    mismatch_serial_parallel = int(np.count_nonzero(res_par.hit != res_full.hit))
    mismatch_status_contact = int(np.count_nonzero(res_contact.hit != res_full.hit))

    # --- kernel only (private API: no pose validation/conversion); diagnostic ---
    try:
        from prismbatch._kernels import batch as _batch

        kp = [np.ascontiguousarray(x, dtype=np.float64) for x in full]
        for key, k_threads, parallel in (("kernel_1t_status", 1, False), ("kernel_all_status", all_threads, True)):
            with threads(k_threads):
                fn = lambda parallel=parallel: _batch.run(  # noqa: E731
                    col._a, col._b, *kp, args.n_pairs, col.rtol, col.atol, False, parallel
                )
                rows[key] = measure(fn, rep, args.n_pairs)
                rows[key]["cpu_per_wall"] = thread_use(fn)
    except Exception as exc:  # noqa: BLE001 - private API may change
        log(f"  (kernel-only timing skipped: {type(exc).__name__}: {exc})")

    # --- same subset for prismbatch and the peers ---
    with threads(1):
        res_sub = col.collide(*sub, parallel=False)
        rows["sub_pb_1t_status"] = measure(pb_call(*sub, False, False), rep, M)

    length = standin_length(a.xy, b.xy, *(x[:M] for x in sub))
    items = FCLPeer.prepare(*sub)
    peer_hits = {}
    fpeer = FCLPeer(a.xy, b.xy, length)
    peer_hits["fcl"] = fpeer.run(items)
    rows["sub_fcl"] = measure(lambda: fpeer.run(items), args.peer_repeats, M, warmup=0)
    try:
        cpeer = CoalPeer(a.xy, b.xy, length)
        peer_hits["coal"] = cpeer.run(items)
        rows["sub_coal"] = measure(lambda: cpeer.run(items), args.peer_repeats, M, warmup=0)
    except ImportError:
        log("  (coal not installed: skipped)")

    # --- agreement on the subset ---
    agreement = {}
    repro = []
    for name, h in peer_hits.items():
        idx = np.flatnonzero(h != res_sub.hit)
        agreement[name] = {
            "disagreements": int(len(idx)),
            "n": int(M),
            "pb_hit_peer_miss": int(np.count_nonzero(res_sub.hit[idx])),
            "pb_miss_peer_hit": int(np.count_nonzero(~res_sub.hit[idx])),
        }
        for k in idx[: args.max_repro]:
            k = int(k)
            entry = {
                "n": n,
                "poses": pose_name,
                "peer": name,
                "index": k,
                "shape_a": f"Prism.regular({n}, {RADIUS_A})",
                "shape_b": f"Prism.regular({n}, {RADIUS_B})",
                "pos_a": sub[0][k].tolist(),
                "rot_a": sub[1][k].tolist(),
                "pos_b": sub[2][k].tolist(),
                "rot_b": sub[3][k].tolist(),
                "pb_hit": bool(res_sub.hit[k]),
                "pb_case": int(res_sub.case[k]),
                "peer_hit": bool(h[k]),
                "standin_length": length,
            }
            if ref is not None:
                try:
                    entry["lp_margin_semi_infinite"] = ref.margin_lp(
                        a.xy, sub[0][k], sub[1][k], b.xy, sub[2][k], sub[3][k]
                    )
                    entry["lp_margin_finite_standins"] = ref.margin_lp(
                        a.xy, sub[0][k], sub[1][k], b.xy, sub[2][k], sub[3][k], length_a=length, length_b=length
                    )
                    lp_hit = entry["lp_margin_semi_infinite"] >= 0.0
                    entry["verdict"] = (
                        "prismbatch agrees with LP (semi-infinite)"
                        if lp_hit == entry["pb_hit"]
                        else "prismbatch DISAGREES with LP (semi-infinite)"
                    )
                except Exception as exc:  # noqa: BLE001
                    entry["lp_error"] = f"{type(exc).__name__}: {exc}"
            repro.append(entry)

    other = other_load(snap0, cpu_snapshot())
    lp = [e for e in repro if "verdict" in e]
    for name in agreement:
        mine = [e for e in lp if e["peer"] == name]
        agreement[name]["lp_checked"] = len(mine)
        agreement[name]["lp_pb_right"] = sum(e["verdict"].startswith("prismbatch agrees") for e in mine)
    info = {
        "n": n,
        "poses": pose_name,
        "load_avg_1min_at_start": load_start,
        "other_processes_cpus": other,
        "hit_fraction": float(res_full.hit.mean()),
        "hit_fraction_subset": float(res_sub.hit.mean()),
        "case_counts": res_full.case_counts(),
        "standin_length": float(length),
        "serial_vs_parallel_hit_mismatches": mismatch_serial_parallel,
        "status_vs_contact_hit_mismatches": mismatch_status_contact,
        "agreement": agreement,
    }
    return rows, info, repro


# ---------------------------------------------------------------------------
# machine info and output
# ---------------------------------------------------------------------------
def _loadavg():
    try:
        return float(os.getloadavg()[0])
    except (OSError, AttributeError):
        return None


def machine_info():
    """The run's machine and versions (:func:`prismbatch.lab.report.run_metadata`, flattened), Numba's
    threading layer and the commit measured."""
    import numba

    meta = run_metadata()
    try:
        threading_layer = numba.threading_layer()
    except ValueError:
        threading_layer = None
    git = ["git", "-C", str(REPO)]
    try:
        commit = subprocess.run([*git, "rev-parse", "HEAD"], capture_output=True, text=True).stdout.strip() or None
        status = subprocess.run([*git, "status", "--porcelain", "--", "prismbatch"], capture_output=True, text=True)
        dirty = bool(status.stdout.strip())
    except OSError:
        commit, dirty = None, None
    return {
        **meta["versions"],
        "cpu_model": meta["machine"]["cpu"],
        "logical_cpus": meta["machine"]["cpu_count"],
        "platform": meta["machine"]["platform"],
        "numba_threads": meta["machine"]["numba_threads"],
        "numba_threading_layer": threading_layer,
        "git_commit": commit,
        "prismbatch_worktree_dirty": dirty,
        "date_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
    }


def _fmt(x):
    return fmt(x, none="–")


def _cell(rows, key):
    r = rows.get(key)
    return _fmt(r["median_us"]) if r else "–"


def _spread(rows, key):
    r = rows.get(key)
    if not r:
        return "–"
    return f"{_fmt(r['median_us'])} [{_fmt(r['min_us'])}–{_fmt(r['max_us'])}]"


def markdown_report(results, infos, meta, comp):
    L = []
    th = meta["machine"]["numba_threads"]
    L.append("## prismbatch core benchmark\n")
    m = meta["machine"]
    L.append(
        f"Machine: {m['cpu_model']}, {m['logical_cpus']} logical CPUs, Numba threads "
        f"{th} ({m['numba_threading_layer']}); Python {m['python']}, numpy {m['numpy']}, "
        f"numba {m['numba']}, python-fcl {m['python-fcl']}, coal {m['coal']}, "
        f"prismbatch {m['prismbatch']} @ {str(m['git_commit'])[:10]}"
        f"{' (+uncommitted changes)' if m['prismbatch_worktree_dirty'] else ''}.\n"
    )
    a = meta["args"]
    L.append(
        f"Pairs per set: {a['n_pairs']} for prismbatch; peers on the first {a['n_peer']} of "
        f"them (prismbatch re-timed on exactly those). Repeats: {a['repeats']} "
        f"(peers {a['peer_repeats']}); medians. Shapes: regular n-gons of radius "
        f"{RADIUS_A} (a) and {RADIUS_B} (b). Per-pair times in µs.\n"
    )
    L.append("### Summary (per pair, µs, median)\n")
    L.append(
        "| n | poses | hit % | pb 1T status | pb 1T contact | pb all-T status "
        "| pb 1T status (subset) | FCL | coal | FCL / pb 1T | coal / pb 1T | target |"
    )
    L.append("|---:|:---|---:|---:|---:|---:|---:|---:|---:|---:|---:|:---|")
    for (n, pose), rows in results.items():
        info = infos[(n, pose)]
        sub = rows["sub_pb_1t_status"]["median_us"]
        fcl_r = rows["sub_fcl"]["median_us"] / sub
        coal_r = rows["sub_coal"]["median_us"] / sub if "sub_coal" in rows else float("nan")
        tgt = TARGETS.get(n)
        tgt_s = "–" if tgt is None else (f"≥{tgt:.0f}x: " + ("met" if fcl_r >= tgt else "NOT met"))
        L.append(
            f"| {n} | {pose} | {100 * info['hit_fraction']:.1f} | {_cell(rows, 'pb_1t_status')} "
            f"| {_cell(rows, 'pb_1t_contact')} | {_cell(rows, 'pb_all_status')} "
            f"| {_cell(rows, 'sub_pb_1t_status')} | {_cell(rows, 'sub_fcl')} "
            f"| {_cell(rows, 'sub_coal')} | {fcl_r:.1f}x | {coal_r:.1f}x | {tgt_s} |"
        )
    L.append("")
    L.append(
        "### Detail: median [min–max] µs per pair; thread use = process CPU time / wall time; "
        "1-pair call = latency (µs) of one Collider.collide call on one pair, and of one "
        "Collider.collide_pair call (the low-latency path); other procs = "
        "CPUs kept busy by other processes during the cell (from /proc/stat)\n"
    )
    L.append(
        "| n | poses | pb 1T status | pb 1T contact | contact overhead | pb all-T status "
        "| pb all-T contact | all-T speed-up | all-T thread use | kernel-only 1T | "
        "kernel-only all-T (thread use) | FCL | coal | 1-pair call | collide_pair call | other procs (CPUs) |"
    )
    L.append("|---:|:---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for (n, pose), rows in results.items():
        s1, c1 = rows["pb_1t_status"]["median_us"], rows["pb_1t_contact"]["median_us"]
        sa = rows["pb_all_status"]["median_us"]
        ka = rows.get("kernel_all_status")
        ka_s = f"{_spread(rows, 'kernel_all_status')} ({ka['cpu_per_wall']:.2f})" if ka else "–"
        L.append(
            f"| {n} | {pose} | {_spread(rows, 'pb_1t_status')} | {_spread(rows, 'pb_1t_contact')} "
            f"| {100 * (c1 / s1 - 1):+.0f}% | {_spread(rows, 'pb_all_status')} "
            f"| {_spread(rows, 'pb_all_contact')} | {s1 / sa:.2f}x "
            f"| {rows['pb_all_status']['cpu_per_wall']:.2f} | {_spread(rows, 'kernel_1t_status')} "
            f"| {ka_s} | {_spread(rows, 'sub_fcl')} | {_spread(rows, 'sub_coal')} "
            f"| {_cell(rows, 'pb_1t_single_pair_call')} | {_cell(rows, 'pb_collide_pair_call')} "
            f"| {_fmt(infos[(n, pose)]['other_processes_cpus'])} |"
        )
    L.append("")
    L.append("### Agreement on the peer subset (peers use finite stand-ins)\n")
    L.append(
        "| n | poses | subset | stand-in length | FCL disagreements (pb hit / peer hit) "
        "| coal disagreements (pb hit / peer hit) | serial≠parallel | status≠contact |"
    )
    L.append("|---:|:---|---:|---:|---:|---:|---:|---:|")
    for (n, pose), info in infos.items():
        ag = info["agreement"]

        def d(name):
            x = ag.get(name)
            if x is None:
                return "–"
            s = f"{x['disagreements']} ({x['pb_hit_peer_miss']} / {x['pb_miss_peer_hit']})"
            if x.get("lp_checked"):
                s += f"; LP sides with pb in {x['lp_pb_right']}/{x['lp_checked']}"
            return s

        L.append(
            f"| {n} | {pose} | {ag['fcl']['n']} | {info['standin_length']:.1f} | {d('fcl')} "
            f"| {d('coal')} | {info['serial_vs_parallel_hit_mismatches']} "
            f"| {info['status_vs_contact_hit_mismatches']} |"
        )
    L.append("")
    L.append(
        "LP = exact margin of the semi-infinite bodies (tests/reference.py); where it sides "
        "with prismbatch, the disagreement comes from the peers' finite stand-ins. "
        "Reproducers: disagreements.json.\n"
    )
    busy = [
        f"{n}/{pose}"
        for (n, pose), rows in results.items()
        if th > 1 and rows["pb_all_status"]["cpu_per_wall"] < 0.75 * th
    ]
    if busy:
        L.append(
            f"**Warning:** all-thread runs used fewer than {0.75 * th:.1f} of {th} CPUs in "
            f"{', '.join(busy)}: other processes competing for cores, or the Numba cache "
            f"served the serial kernel for parallel=True (see 'other procs' in the detail table; "
            f"load average at start {meta['load_avg_1min_at_start']}).\n"
        )
    if comp:
        L.append("### First call (Numba compile), fresh subprocess (`bench_floor.cold_compile`)\n")
        L.append("| kernel | pairs | cold: first call (s) | cached: first call (s) | import (s) |")
        L.append("|:---|---:|---:|---:|---:|")
        for kind, r in comp.items():
            L.append(
                f"| {kind} | {COLD_BATCHES[kind]} | {r['cold']['first_call_s']:.2f} "
                f"| {r['cached']['first_call_s']:.3f} | {r['cold']['import_s']:.2f} |"
            )
        L.append("")
    return "\n".join(L)


def write_outputs(out_dir, results, infos, meta, repro):
    out_dir.mkdir(parents=True, exist_ok=True)
    if out_dir.resolve() == (HERE / "results").resolve() and not (out_dir / ".gitignore").exists():
        (out_dir / ".gitignore").write_text("# benchmark output, not committed\n*\n")
    fields = [
        "n",
        "poses",
        "measure",
        "median_us",
        "min_us",
        "max_us",
        "q1_us",
        "q3_us",
        "repeats",
        "n_pairs",
        "cpu_per_wall",
        "cpu_per_wall_timed",
        "other_cpus",
        "attempts",
        "hit_fraction",
    ]
    with open(out_dir / "results.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=fields, extrasaction="ignore")
        w.writeheader()
        for (n, pose), rows in results.items():
            for key, r in rows.items():
                w.writerow(
                    {"n": n, "poses": pose, "measure": key, "hit_fraction": infos[(n, pose)]["hit_fraction"], **r}
                )
    meta = dict(meta, cells=[dict(v) for v in infos.values()])
    (out_dir / "meta.json").write_text(json.dumps(meta, indent=2, default=str))
    (out_dir / "disagreements.json").write_text(json.dumps(repro, indent=2))


# ---------------------------------------------------------------------------
def parse_args(argv=None):
    p = argparse.ArgumentParser(
        description="Per-pair collision time of prismbatch vs python-fcl and coal "
        "(36/360/3600 vertices, facing and free poses, 1 and all threads, "
        "status vs contact, first-call compile time)."
    )
    p.add_argument("--quick", action="store_true", help="smaller batches and fewer repeats (well under a minute)")
    p.add_argument(
        "--out",
        type=Path,
        default=HERE / "results",
        help="output directory for results.csv, meta.json, disagreements.json (default: benchmarks/results/)",
    )
    p.add_argument(
        "--sizes", type=int, nargs="+", default=list(SIZES), help="polygon vertex counts (default: 36 360 3600)"
    )
    p.add_argument(
        "--poses", nargs="+", choices=list(POSE_SETS), default=list(POSE_SETS), help="pose sets (default: facing free)"
    )
    p.add_argument("--n-pairs", type=int, default=None, help="pairs per set for prismbatch (default 50000; quick 4000)")
    p.add_argument(
        "--n-peer", type=int, default=None, help="pairs of the same set timed with the peers (default 10000; quick 400)"
    )
    p.add_argument("--repeats", type=int, default=None, help="timed repeats for prismbatch (default 9; quick 3)")
    p.add_argument("--peer-repeats", type=int, default=None, help="timed repeats for the peers (default 5; quick 2)")
    p.add_argument("--seed", type=int, default=20240611, help="random seed")
    p.add_argument(
        "--max-repro", type=int, default=20, help="disagreements per cell written with reproducers (default 20)"
    )
    p.add_argument(
        "--wait-idle",
        type=float,
        default=0.0,
        metavar="SECONDS",
        help="shared machine: before each cell and the compile runs, and again when a "
        "measurement was disturbed (then it is repeated, up to 3 times), wait "
        "for other processes to leave the CPUs idle, spending at most SECONDS "
        "in total on waiting (default 0: never wait)",
    )
    p.add_argument("--skip-compile", action="store_true", help="skip the first-call compile-time subprocesses")
    args = p.parse_args(argv)
    q = args.quick
    if args.n_pairs is None:
        args.n_pairs = 4000 if q else 50000
    if args.n_peer is None:
        args.n_peer = 400 if q else 10000
    if args.repeats is None:
        args.repeats = 3 if q else 9
    if args.peer_repeats is None:
        args.peer_repeats = 2 if q else 5
    return args


def main(argv=None):
    args = parse_args(argv)
    import numba

    def log(msg):
        print(msg, file=sys.stderr, flush=True)

    t_start = time.perf_counter()
    load_start = _loadavg()
    if load_start is not None and load_start > 0.5:
        log(f"warning: load average {load_start:.2f} before start; timings may be disturbed")
    all_threads = numba.get_num_threads()
    ref = _load_reference()
    waiter = IdleWaiter(args.wait_idle, log=log)

    comp = None
    if not args.skip_compile:
        log("first-call compile times (fresh subprocesses)...")
        waiter.wait()
        comp = cold_compile()
        for kind, r in comp.items():
            cold, cached = r["cold"]["first_call_s"], r["cached"]["first_call_s"]
            log(f"  {kind}: cold first call {cold:.2f} s, cached {cached:.3f} s")

    results, infos, repro = {}, {}, []
    for n in args.sizes:
        for pose in args.poses:
            waited = waiter.wait()
            t0 = time.perf_counter()
            rows, info, rp = bench_cell(n, pose, args, all_threads, ref, log, waiter)
            info["waited_for_idle_s"] = waited
            results[(n, pose)] = rows
            infos[(n, pose)] = info
            repro.extend(rp)
            log(
                f"n={n:5d} {pose:6s}: pb 1T {rows['pb_1t_status']['median_us']:.3f} µs, "
                f"FCL {rows['sub_fcl']['median_us']:.2f} µs, "
                f"disagreements {info['agreement']} ({time.perf_counter() - t0:.1f} s)"
            )

    meta = {
        "machine": machine_info(),
        "args": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()},
        "compile_times": comp,
        "targets_fcl_over_pb_1t": TARGETS,
        "elapsed_s": time.perf_counter() - t_start,
        "load_avg_1min_at_start": load_start,
        "load_avg_1min_at_end": _loadavg(),
        "wait_idle_budget_s": args.wait_idle,
        "wait_idle_left_s": max(waiter.left, 0.0),
        "notes": [
            "pb 1T = Collider.collide(parallel=False) under numba.set_num_threads(1)",
            "pb all-T = Collider.collide(parallel=True) with all Numba threads",
            "kernel-only = prismbatch._kernels.batch.run (private), no pose validation/conversion",
            "1-pair call = latency of Collider.collide on a single pair (1 thread); "
            "collide_pair call = latency of Collider.collide_pair",
            "thread use = process CPU time / wall time over >= 0.4 s of back-to-back calls",
            "peers: per query 2x setTransform + collide with fresh request/result; objects built once",
            "coal stand-ins use strip-triangulated caps (peers.coal_prism's fan fails for n >= ~256)",
        ],
    }
    report = markdown_report(results, infos, meta, comp)
    print(report)
    print(f"\n_Total time {meta['elapsed_s']:.0f} s; results in {args.out}_")
    write_outputs(args.out, results, infos, meta, repro)
    return 0


if __name__ == "__main__":
    sys.exit(main())
