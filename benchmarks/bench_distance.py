#!/usr/bin/env python
"""prismbatch's signed distance against coal and python-fcl, per distance bucket, in one run.

The same pose pairs for every method: regular n-gons of circumradius 2 and 2.5
(36 and 3600 vertices), b placed at a chosen signed distance from a: first a
random pose (the paper's facing scene, or fully random), then b moved along
prismbatch's witness normal so that the distance is the bucket's (penetrating
by 1e-2 .. 1 of the size; touching, within a tenth of the tolerance; gaps of
1e-6, 1e-4, 1e-2 and 1 of the size). coal and python-fcl run on finite
stand-ins of the prisms, long enough not to matter (``peers.standin_length``,
doubled), and are timed per query in a Python loop, as users call them;
prismbatch is timed per pair on one thread (``parallel=False``), with and
without witness points, and one query at a time (``Collider.distance`` on one
pair in a Python loop, as the peers are timed). The distance error against coal is reported in units
of the pair's tolerance, per bucket, against coal's depth with an EPA tolerance of
1e-12 (with its default, timed here as users call it, coal's depth was off by up to
about 1e-4 of the scene) and its gap with its defaults (a tight GJK tolerance made it
report gaps of 0.0). ``collide(..., margin=m)`` is timed against a plain
``collide`` and against ``distance`` on the same pairs, for m = 1e-8 S (ten
tolerances) and 1e-3 S (the ratios from the thread CPU time of the interleaved
calls, which a busy machine disturbs less than wall time), with its answers checked
against ``distance <= m`` outside the touching band (the count of pairs that disagree
is reported; it should be 0).

Medians over repeats, all in one run; a Markdown table on stdout and, with
``--out``, the table and a JSON of every figure and the machine.

    python benchmarks/bench_distance.py [--quick] [--out DIR]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numba
import numpy as np

import prismbatch as pb
from prismbatch.lab.peers import CoalDistancePeer, FCLDistancePeer, standin_length
from prismbatch.lab.report import fmt, run_metadata, write_json, write_text
from prismbatch.lab.timing import stats, threads, timed_loops
from prismbatch.lab.validate.distance import DISTANCE_BUCKETS, place
from prismbatch.sampling import facing_poses, free_poses

RADIUS_A, RADIUS_B = 2.0, 2.5
#: The buckets timed here (a subset of the validation's, prismbatch.lab.validate.distance).
BUCKETS = {k: DISTANCE_BUCKETS[k] for k in ("penetrating 1", "penetrating 1e-2", "touching")}
BUCKETS.update({k: DISTANCE_BUCKETS[k] for k in ("gap 1e-6", "gap 1e-4", "gap 1e-2", "gap 1")})
#: Margins of the ``collide(..., margin=m)`` timing, as fractions of the size S.
MARGINS = (1e-8, 1e-3)


def _per_pair_us(fn, n, repeats):
    return 1e6 * stats(timed_loops({"f": fn}, repeats)["f"])["median"] / n


def bucket_rows(n_vertices, n_pairs, repeats, rng, peers):
    """Per bucket: µs per pair of each method and prismbatch's error against coal (in tol)."""
    a, b = pb.Prism.regular(n_vertices, RADIUS_A), pb.Prism.regular(n_vertices, RADIUS_B)
    col = pb.Collider(a, b)
    base = {
        "facing": tuple(np.ascontiguousarray(x) for x in facing_poses(n_pairs, rng, radius=RADIUS_B)),
        "free": tuple(np.ascontiguousarray(x) for x in free_poses(n_pairs, rng, radius=RADIUS_B)),
    }
    rows = []
    for family, poses in base.items():
        for bucket, target in BUCKETS.items():
            P = place(a, b, poses, target, rng, RADIUS_A + RADIUS_B)
            n = len(P[0])
            L = 2.0 * max(standin_length(a.xy, b.xy, *(x[k] for x in P)) for k in range(n))
            row = {"vertices": n_vertices, "family": family, "bucket": bucket, "pairs": n, "standin_length": L}
            ref = pb.distance(a, b, *P)
            S = RADIUS_A + RADIUS_B
            one_by_one = list(zip(*P))  # each pair's (3,) and (3, 3) rows
            calls = {  # interleaved in one loop: their ratios share the machine's state
                "pb": lambda P=P: pb.distance(a, b, *P, parallel=False),
                # one query at a time in a Python loop, as the peers are timed (a controller's use)
                "pb_one": lambda one_by_one=one_by_one: [col.distance(*pair) for pair in one_by_one],
                "pb_witness": lambda P=P: pb.distance(a, b, *P, witness=True, parallel=False),
                "collide": lambda P=P: col.collide(*P, parallel=False),
            }
            for frac in MARGINS:
                calls[f"margin_{frac:g}"] = lambda P=P, m=frac * S: col.collide(*P, margin=m, parallel=False)
            cpu = {}  # thread CPU time too: blind to the time other processes take the core
            for k, t in timed_loops(calls, repeats, cpu=cpu).items():
                row[f"{k}_us"] = 1e6 * stats(t)["median"] / n
                row[f"{k}_cpu_us"] = 1e6 * stats(cpu[k])["median"] / n
            row["margin_disagree"] = 0
            for frac in MARGINS:
                hit = col.collide(*P, margin=frac * S).hit
                wrong = (np.abs(ref.distance - frac * S) > ref.tol) & (hit != (ref.distance <= frac * S))
                row["margin_disagree"] += int(np.count_nonzero(wrong))
            for name, cls in peers.items():
                if name == "fcl" and (target is None or abs(target) < 1e-2):
                    continue  # python-fcl's signed distance aborts the process near touching (see --fcl)
                peer = cls(a.xy, b.xy, L)
                items = peer.prepare(*P)
                row[f"{name}_us"] = _per_pair_us(lambda peer=peer, items=items: peer.run(items), n, 1)
                d_peer = peer.run(items)[0]
                if name == "coal":  # judge depths with a tight EPA tolerance (coal's default is coarse)
                    tight = cls(a.xy, b.xy, L, tolerance=1e-12).run(items)[0]
                    d_peer = np.where(d_peer < 0, tight, d_peer)
                with np.errstate(over="ignore", invalid="ignore"):  # a peer's answer may be non-finite or huge
                    err = np.abs(ref.distance - d_peer) / ref.tol
                row[f"err_vs_{name}_max_tol"] = float(err.max())
                row[f"{name}_over_10_tol"] = int(np.count_nonzero(~(err <= 10.0)))
                row[f"err_vs_{name}_median_tol"] = float(np.median(err))
            rows.append(row)
    return rows


def _peers(fcl):
    out = {}
    for name, cls in (("coal", CoalDistancePeer), ("fcl", FCLDistancePeer))[: 2 if fcl else 1]:
        try:
            cls._import()
        except ImportError as exc:
            print(f"{name} skipped: {exc}")
            continue
        out[name] = cls
    return out


def markdown(rows, peers):
    head = ["n", "poses", "bucket", "pairs", "prismbatch µs", "+ witness µs", "one query µs", "collide µs"]
    for frac in MARGINS:
        head += [f"margin {frac:g} S µs", "/ collide", "distance /"]
    head += ["margin wrong"]
    for p in peers:
        head += [f"{p} µs", f"{p} / prismbatch", f"{p} / one query", f"max |pb - {p}| / tol", f"{p} > 10 tol"]
    L = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        cells = [r["vertices"], r["family"], r["bucket"], r["pairs"], fmt(r["pb_us"]), fmt(r["pb_witness_us"])]
        cells += [fmt(r["pb_one_us"])]
        cells += [fmt(r["collide_us"])]
        for frac in MARGINS:
            t = r[f"margin_{frac:g}_us"]
            cpu = r[f"margin_{frac:g}_cpu_us"]
            cells += [fmt(t), fmt(cpu / r["collide_cpu_us"]), fmt(r["pb_cpu_us"] / cpu)]
        cells += [r["margin_disagree"]]
        for p in peers:
            if f"{p}_us" not in r:
                cells += ["-", "-", "-", "-", "-"]
                continue
            cells += [
                fmt(r[f"{p}_us"]),
                fmt(r[f"{p}_us"] / r["pb_us"]),
                fmt(r[f"{p}_us"] / r["pb_one_us"]),
                fmt(r[f"err_vs_{p}_max_tol"], none="inf"),
                fmt(r[f"{p}_over_10_tol"]),
            ]
        L.append("| " + " | ".join(str(c) for c in cells) + " |")
    return "\n".join(L) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer pairs and repeats (a smoke run)")
    ap.add_argument("--out", metavar="DIR", help="write distance.md and distance.json to DIR")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument(
        "--fcl",
        action="store_true",
        help="also python-fcl, on the buckets at least 1e-2 of the size from touching only: its signed "
        "distance aborted the whole process (a C++ std::logic_error in libccd's EPA) on a touching pair here",
    )
    args = ap.parse_args(argv)
    n_pairs, repeats = (100, 2) if args.quick else (1000, 5)
    rng = np.random.default_rng(args.seed)
    peers = _peers(args.fcl)
    a = pb.Prism.regular(5, 1.0)
    pb.distance(a, a, np.zeros(3), np.eye(3), np.ones(3), np.eye(3), parallel=False)  # compile outside timing
    pb.distance(a, a, np.zeros(3), np.eye(3), np.ones(3), np.eye(3), witness=True, parallel=False)
    rows = []
    with threads(1):
        for n in (36, 3600):
            rows += bucket_rows(n, n_pairs, repeats, rng, peers)
    table = markdown(rows, list(peers))
    print(table)
    if args.out:
        out = Path(args.out)
        write_text(out / "distance.md", "# Signed distance: prismbatch against coal and python-fcl\n\n" + table)
        meta = run_metadata(benchmark="bench_distance", seed=args.seed, pairs=n_pairs, repeats=repeats)
        write_json(out / "distance.json", {**meta, "numba_threads": numba.get_num_threads(), "rows": rows})


if __name__ == "__main__":
    main()
