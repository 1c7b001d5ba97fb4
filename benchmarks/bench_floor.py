#!/usr/bin/env python
"""prismbatch against the floor: how far each path is from what any exact method must do per pair.

The floor is a compiled loop that reads both poses, forms b's height above a's
end plane and the cosine between the axes, and makes one comparison: every
exact method has to do at least that. Each row times prismbatch on one thread
(``Collider.collide(..., parallel=False)``) over a set of pose pairs of one kind
and divides by the floor measured on the same pairs in the same run:

* early exits: the paper's facing poses that prismbatch settles as case 1 or 5;
* GJK pairs: facing poses that reach the planar GJK (case 6);
* the facing mix, and fully random (free) poses;

at 36, 3600 and 100,000 vertices, on 200,000 pairs (their poses, 38 MB, stay near the 32 MB
cache of the machine the README's figures come from) and, at 36 and 3600 vertices, on
2,000,000 pairs (384 MB: every pose comes from main memory, as in a bulk run, and the floor
is then bound by memory, not by arithmetic). Then the latency of one query
(``collide_pair``, ``Collider.collide`` and ``pb.collide`` on one plain pair,
against a trivial ``@njit`` call taking the same four arrays; ``Collider.collide`` on batches
of 10 and 100 pairs and ``Collider.distance`` on 10, per call), two threads
against one on 10^6 pairs (and, as what the machine allows, two one-thread processes
running at once against one alone), status only against contacts, float32 against
float64, the cold compile of the serial and of the parallel path (each in a fresh process with an
empty Numba cache), and the build of a ``PrismSet`` of 100,000 polygons.

Medians over repeats, all in one run; print a Markdown table and, with
``--out``, write it with a JSON of every figure and the machine.

    python benchmarks/bench_floor.py [--quick] [--out DIR]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numba
import numpy as np

import prismbatch as pb
from prismbatch.lab.report import fmt, run_metadata, write_json
from prismbatch.lab.timing import stats, threads, timed_loops
from prismbatch.sampling import facing_poses, free_poses

RADIUS_A, RADIUS_B = 2.0, 2.5
BULK_PAIRS = 2_000_000  # poses of 384 MB: well beyond the caches of a server CPU


@numba.njit(cache=True)
def floor_loop(pos_a, rot_a, pos_b, rot_b, out):
    """Read both poses, b's height along a's axis and the axes' cosine, one compare per pair."""
    for i in range(pos_a.shape[0]):
        h = 0.0
        c = 0.0
        for k in range(3):
            h += rot_a[i, k, 2] * (pos_b[i, k] - pos_a[i, k])
            c += rot_a[i, k, 2] * rot_b[i, k, 2]
        out[i] = h + c > 0.0
    return out


@numba.njit(cache=True)
def trivial_call(pos_a, rot_a, pos_b, rot_b):
    return pos_a[0] + rot_a[0, 0] + pos_b[0] + rot_b[0, 0]


def _subset(poses, mask):
    return tuple(np.ascontiguousarray(x[mask]) for x in poses)


def _per_pair_ns(fn, n, repeats):
    return 1e9 * stats(timed_loops({"f": fn}, repeats)["f"])["median"] / n


def pose_sets(col, n_pairs, rng):
    """The pose sets of the rows, by name: facing poses settled early and those that reach GJK (by
    ``col``'s case), the whole facing mix, and free poses; each C-contiguous."""
    facing = tuple(np.ascontiguousarray(x) for x in facing_poses(n_pairs, rng, radius=RADIUS_B))
    free = tuple(np.ascontiguousarray(x) for x in free_poses(n_pairs, rng, radius=RADIUS_B))
    case = col.collide(*facing, parallel=False).case
    return {
        "early exits (cases 1, 5)": _subset(facing, (case == 1) | (case == 5)),
        "GJK pairs (case 6)": _subset(facing, case == 6),
        "facing mix": facing,
        "free poses": free,
    }


def kernel_rows(n_vertices, n_pairs, repeats, rng):
    """Per-pair ns of each pose kind at one polygon size, and the floor on the same pairs."""
    a, b = pb.Prism.regular(n_vertices, RADIUS_A), pb.Prism.regular(n_vertices, RADIUS_B)
    col = pb.Collider(a, b)
    sets = pose_sets(col, n_pairs, rng)
    rows = []
    for name, poses in sets.items():
        n = len(poses[0])
        out = np.empty(n, dtype=np.bool_)
        t_floor = _per_pair_ns(lambda p=poses, o=out: floor_loop(*p, o), n, repeats)
        t_pb = _per_pair_ns(lambda p=poses: col.collide(*p, parallel=False), n, repeats)
        rows.append(
            {
                "vertices": n_vertices,
                "set": name,
                "pairs": n,
                "pose_mb": sum(x.nbytes for x in poses) / 1e6,
                "floor_ns": t_floor,
                "prismbatch_ns": t_pb,
            }
        )
    return rows


def latency_rows(repeats):
    """One query: µs per call of each entry point on one plain pair, and a trivial njit call."""
    a, b = pb.Prism.regular(36, RADIUS_A), pb.Prism.regular(36, RADIUS_B)
    col = pb.Collider(a, b)
    poses = tuple(np.ascontiguousarray(x) for x in facing_poses(100, np.random.default_rng(1), radius=RADIUS_B))
    one, ten = tuple(x[0] for x in poses), tuple(x[:10] for x in poses)
    calls = {
        "trivial @njit call, same 4 arrays": lambda: trivial_call(*one),
        "Collider.collide_pair": lambda: col.collide_pair(*one),
        "Collider.collide, one pair": lambda: col.collide(*one),
        "pb.collide, one pair": lambda: pb.collide(a, b, *one),
        # small batches (a controller's few candidates): the per-call cost around the kernel
        "Collider.collide, a batch of 10": lambda: col.collide(*ten),
        "Collider.collide, a batch of 100": lambda: col.collide(*poses),
        "Collider.distance, a batch of 10": lambda: col.distance(*ten),
    }
    return {k: 1e6 * v for k, v in seconds_per_call(calls, repeats).items()}


def seconds_per_call(calls, repeats, loops=2000):
    """Median seconds per call of each of ``calls`` (name -> function of no arguments), ``loops`` calls a pass."""

    def many(f):
        def run():
            for _ in range(loops):
                f()

        return run

    times = timed_loops({k: many(f) for k, f in calls.items()}, repeats)
    return {k: stats(v)["median"] / loops for k, v in times.items()}


def bulk_rows(n_pairs, repeats, rng):
    """10^6-pair figures: threads, status against contacts, float32 against float64 (ms per call)."""
    a, b = pb.Prism.regular(36, RADIUS_A), pb.Prism.regular(36, RADIUS_B)
    poses = tuple(np.ascontiguousarray(x) for x in facing_poses(n_pairs, rng, radius=RADIUS_B))
    poses32 = tuple(x.astype(np.float32) for x in poses)
    c64, c32 = pb.Collider(a, b), pb.Collider(a, b, dtype=np.float32)
    out = {}
    with threads(1):
        t = timed_loops(
            {
                "status, float64, 1 thread": lambda: c64.collide(*poses, parallel=False),
                "contacts, float64, 1 thread": lambda: c64.collide(*poses, parallel=False, contact=True),
                "status, float32, 1 thread": lambda: c32.collide(*poses32, parallel=False),
            },
            repeats,
        )
    out.update({k: 1e3 * stats(v)["median"] for k, v in t.items()})
    k = min(2, numba.config.NUMBA_NUM_THREADS)
    with threads(k):
        t = timed_loops({f"status, float64, {k} threads": lambda: c64.collide(*poses, parallel=True)}, repeats)
    out.update({kk: 1e3 * stats(v)["median"] for kk, v in t.items()})
    return out


_ONE_THREAD_PROCESS = """
import sys, time, numpy as np
import prismbatch as pb
from prismbatch.sampling import facing_poses
n, repeats, seed, ra, rb = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4]), float(sys.argv[5])
col = pb.Collider(pb.Prism.regular(36, ra), pb.Prism.regular(36, rb))
poses = tuple(np.ascontiguousarray(x) for x in facing_poses(n, np.random.default_rng(seed), radius=rb))
col.collide(*poses, parallel=False)
print("ready", flush=True)
sys.stdin.readline()
for _ in range(repeats):
    t0 = time.perf_counter()
    col.collide(*poses, parallel=False)
    print(time.perf_counter() - t0, flush=True)
"""


def machine_ceiling(n_pairs, repeats, seed):
    """What two cores give two independent one-thread jobs here: each job is a process of its own running
    the serial kernel on the same ``n_pairs`` facing pairs, alone and then two at once (started together).
    Returns the medians (ms per call) and ``2 * alone / together``: the speed-up that a perfectly split
    two-thread call could reach on this machine, to set the two-thread figure against."""

    def run(k):
        args = [sys.executable, "-c", _ONE_THREAD_PROCESS, str(n_pairs), str(repeats), str(seed)]
        args += [str(RADIUS_A), str(RADIUS_B)]
        env = dict(os.environ, NUMBA_NUM_THREADS="1")
        procs = [
            subprocess.Popen(args, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env) for _ in range(k)
        ]
        for p in procs:  # every job warm before any is timed
            if p.stdout.readline().strip() != "ready":
                raise RuntimeError("a timing process failed to start")
        for p in procs:
            p.stdin.write("go\n")
            p.stdin.flush()
        times = [float(x) for p in procs for x in p.communicate()[0].split()]
        if any(p.returncode for p in procs):
            raise RuntimeError("a timing process failed")
        return 1e3 * stats(times)["median"]

    alone, together = run(1), run(2)
    return {"one process alone": alone, "each of two processes at once": together, "ceiling": 2 * alone / together}


_COLD = """
import sys, time, numpy as np
n = int(sys.argv[1])
t0 = time.perf_counter()
import prismbatch as pb
t1 = time.perf_counter()
col = pb.Collider(pb.Prism.regular(6, 2.0), pb.Prism.regular(6, 2.5))
p = np.zeros((n, 3)); r = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
col.collide(p, r, p + 1, r)
t2 = time.perf_counter()
col.collide(p, r, p + 1, r)
t3 = time.perf_counter()
# Numba's own record of the serial pair loop's compile, callees included (both paths compile it; none
# when it came from the cache): its whole compile, and the part spent in LLVM.
from prismbatch._kernels.batch import collide_serial
timers = [(collide_serial.get_metadata(sig) or {}).get("timers", {}) for sig in collide_serial.signatures]
total = sum(t.get("compiler_lock", 0.0) for t in timers)
llvm = sum(t.get("llvm_lock", 0.0) for t in timers)
print(t1 - t0, t2 - t1, t3 - t2, total, llvm)
"""

#: Batch sizes of the first call: 2 pairs take the serial kernel, 10,000 the parallel one (the default
#: from 4096 pairs on); each compiles on its own first use.
COLD_BATCHES = {"serial": 2, "parallel": 10_000}


def cold_compile():
    """Import and first ``collide`` call in a fresh process with an empty Numba cache, then with it warm
    (s), for a batch that takes the serial kernel and one that takes the parallel kernel."""
    res = {}
    for path, n in COLD_BATCHES.items():
        with tempfile.TemporaryDirectory(prefix="pb_cold_") as d:
            env = dict(os.environ, NUMBA_CACHE_DIR=d)
            res[path] = {}
            for label in ("cold", "cached"):
                r = subprocess.run(
                    [sys.executable, "-c", _COLD, str(n)], env=env, capture_output=True, text=True, check=True
                )
                imp, first, second, loop, llvm = (float(x) for x in r.stdout.split())
                res[path][label] = {
                    "import_s": imp,
                    "first_call_s": first,
                    "second_call_s": second,
                    "pair_loop_compile_s": loop,
                    "pair_loop_llvm_s": llvm,
                }
    return res


def prismset_build(n_polygons, rng):
    """Seconds to build a PrismSet of ``n_polygons`` random 3-12-gons, and to query them once."""
    polys = []
    for _ in range(n_polygons):
        k = int(rng.integers(3, 13))
        ang = np.sort(rng.uniform(0, 2 * np.pi, k))
        polys.append(np.column_stack([np.cos(ang), np.sin(ang)]) * rng.uniform(0.5, 2.0))
    t0 = time.perf_counter()
    s = pb.PrismSet(polys)
    build = time.perf_counter() - t0
    poses = facing_poses(n_polygons, rng, radius=RADIUS_B)
    col = pb.Collider(s, pb.Prism.regular(6, RADIUS_B))
    col.collide(*poses)  # first call: compile or cache load
    t0 = time.perf_counter()
    col.collide(*poses)
    return {"polygons": n_polygons, "build_s": build, "query_s": time.perf_counter() - t0}


def markdown(res):
    L = [
        "| vertices | pose set | pairs | poses (MB) | floor (ns/pair) | prismbatch 1 thread (ns/pair) | ratio |",
        "|---" * 7 + "|",
    ]
    for r in res["kernel"]:
        L.append(
            f"| {r['vertices']} | {r['set']} | {r['pairs']} | {fmt(r['pose_mb'], '.0f')} | {fmt(r['floor_ns'])} | "
            f"{fmt(r['prismbatch_ns'])} | {fmt(r['prismbatch_ns'] / r['floor_ns'], '.1f')}x |"
        )
    lat = res["latency_us"]
    base = lat["Collider.collide_pair"]
    L += ["", "| one query | µs per call | ratio |", "|---|---|---|"]
    triv = lat["trivial @njit call, same 4 arrays"]
    for k, v in lat.items():
        ref = f"{fmt(v / triv, '.1f')}x trivial" if k == "Collider.collide_pair" else f"{fmt(v / base, '.1f')}x pair"
        L.append(f"| {k} | {fmt(v)} | {'-' if k.startswith('trivial') else ref} |")
    bulk = res["bulk_ms"]
    L += ["", f"| {res['bulk_pairs']} facing pairs, 36 vertices | ms per call |", "|---|---|"]
    L += [f"| {k} | {fmt(v)} |" for k, v in bulk.items()]
    ceil = res["ceiling"]
    two = [v for k, v in bulk.items() if k.endswith("2 threads")]
    L += [
        f"| the serial call, one process alone | {fmt(ceil['one process alone'])} |",
        f"| the same, each of two processes at once | {fmt(ceil['each of two processes at once'])} |",
        "",
        f"Two threads: {fmt(bulk['status, float64, 1 thread'] / two[0], '.2f')}x one thread"
        if two
        else "Two threads: not measured (one core)",
    ]
    L[-1] += (
        f"; two independent one-thread processes got {fmt(ceil['ceiling'], '.2f')}x the throughput of one "
        "(what the machine gives two jobs that share nothing)."
    )
    L.append("")
    for path, cc in res["compile"].items():
        L.append(
            f"First use, {path} kernel ({COLD_BATCHES[path]:,} pairs; fresh process, empty Numba cache): import "
            f"{fmt(cc['cold']['import_s'], '.2f')} s, first collide {fmt(cc['cold']['first_call_s'], '.2f')} s, of "
            f"which the serial pair loop's compile {fmt(cc['cold']['pair_loop_compile_s'], '.2f')} s (LLVM "
            f"{fmt(cc['cold']['pair_loop_llvm_s'], '.2f')} s, Numba's own passes the rest); with the cache warm "
            f"{fmt(cc['cached']['first_call_s'], '.3f')} s."
        )
    L += [
        f"PrismSet of {res['prismset']['polygons']} polygons: built in {fmt(res['prismset']['build_s'], '.2f')} s, "
        f"queried in {fmt(res['prismset']['query_s'], '.3f')} s.",
    ]
    return "\n".join(L)


def parse_args(doc, stem, argv):
    """The options of this script and of ``profile_collide.py``: ``(args, repeats)``."""
    ap = argparse.ArgumentParser(description=doc.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="small sets and few repeats (a smoke run)")
    ap.add_argument("--repeats", type=int, default=None, help="timed passes per figure (default 7, quick 3)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=None, help=f"write {stem}.md and {stem}.json here")
    args = ap.parse_args(argv)
    return args, args.repeats or (3 if args.quick else 7)


def report(text, res, stem, args, repeats):
    """Print the Markdown ``text``; with ``--out``, write it and the figures ``res`` with the run's metadata."""
    print(text)
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / f"{stem}.md").write_text(text + "\n")
        write_json(args.out / f"{stem}.json", dict(res, meta=run_metadata(repeats=repeats, seed=args.seed)))


def main(argv=None):
    args, rep = parse_args(__doc__, "floor", argv)
    rng = np.random.default_rng(args.seed)
    if args.quick:
        runs = [(36, 20_000), (3600, 20_000)]
    else:  # in cache, and from main memory (BULK_PAIRS) where a run stays short
        runs = [(36, 200_000), (36, BULK_PAIRS), (3600, 200_000), (3600, BULK_PAIRS), (100_000, 200_000)]
    res = {"kernel": []}
    for n, n_pairs in runs:
        print(f"kernel rows at {n} vertices, {n_pairs} pairs ...", file=sys.stderr)
        with threads(1):
            res["kernel"] += kernel_rows(n, n_pairs, rep, rng)
    print("latency ...", file=sys.stderr)
    res["latency_us"] = latency_rows(rep)
    res["bulk_pairs"] = 100_000 if args.quick else 1_000_000
    print("bulk ...", file=sys.stderr)
    res["bulk_ms"] = bulk_rows(res["bulk_pairs"], rep, rng)
    print("two processes ...", file=sys.stderr)
    res["ceiling"] = machine_ceiling(res["bulk_pairs"], rep, args.seed)
    print("cold compile ...", file=sys.stderr)
    res["compile"] = cold_compile()
    res["prismset"] = prismset_build(10_000 if args.quick else 100_000, rng)
    report(markdown(res), res, "floor", args, rep)
    return 0


if __name__ == "__main__":
    sys.exit(main())
