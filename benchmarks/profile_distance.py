#!/usr/bin/env python
"""Where a signed distance's time goes: GJK's and EPA's iterations and time, per distance bucket.

The pairs are ``bench_distance.py``'s (regular n-gons of circumradius 2 and 2.5, the paper's
facing poses, b moved along prismbatch's witness normal to each bucket's signed distance). For
each bucket, one thread, medians of 7 interleaved passes:

* GJK's iterations (mean and largest) and its time per pair: a compiled loop that forms each
  pair's cut Minkowski difference as ``pair_distance`` does and runs a copy of GJK whose only
  change is a counter;
* on the pairs GJK leaves to EPA, EPA's iterations and its time per such pair (the loop again,
  with a counting copy of EPA after GJK, less the loop without it);
* the whole query (``prismbatch.distance(..., parallel=False)``).

The counting copies are built from the kernels' own source with one line added (the script stops
if that line's anchor is gone), so they do what the kernels do.

    python benchmarks/profile_distance.py [--pairs N] [--out DIR]
"""

from __future__ import annotations

import argparse
import inspect
import math
from pathlib import Path

import numpy as np

import prismbatch as pb
from prismbatch._kernels import distance as dist_kernels
from prismbatch._kernels import gjk3d
from prismbatch._kernels.batch import centres_and_tolerance
from prismbatch._kernels.jit import jit
from prismbatch._kernels.minkowski import cut_difference
from prismbatch.config import DEFAULT_RTOL
from prismbatch.lab.report import run_metadata, write_json, write_text
from prismbatch.lab.timing import stats, timed_loops
from prismbatch.lab.validate.distance import DISTANCE_BUCKETS, place
from prismbatch.sampling import facing_poses
from prismbatch.shapes import as_prism_set

RADIUS_A, RADIUS_B = 2.0, 2.5
BUCKETS = ("penetrating 1", "penetrating 1e-2", "touching", "gap 1e-6", "gap 1e-2", "gap 1")


def _counting_copy(kernel, anchor, slot):
    """``kernel`` compiled again from its source with ``cnt[slot] += 1`` after the line ``anchor``
    and a last argument ``cnt``."""
    src = inspect.getsource(kernel.py_func)
    head = src[src.index("def ") : src.index("):\n")]
    if anchor not in src:
        raise RuntimeError(f"{kernel.__name__}'s source changed: {anchor.strip()!r} not found")
    indent = anchor[: len(anchor) - len(anchor.lstrip())] + "    "
    src = src.replace(head, head + ", cnt", 1).replace(anchor, f"{anchor}\n{indent}cnt[{slot}] += 1", 1)
    src = src[src.index("def ") :]  # without the decorator
    namespace = dict(vars(inspect.getmodule(kernel.py_func)))
    exec(src, namespace)
    return jit(namespace[kernel.__name__])


gjk_counted = _counting_copy(gjk3d.gjk, "    for _ in range(GJK_MAX_ITER):", 0)
epa_counted = _counting_copy(dist_kernels.epa, "    while True:", 1)


@jit(refcounts=True)
def _loop(P, aoff, arad, acen, boff, brad, bcen, pos_a, rot_a, pos_b, rot_b, rtol, eps, with_epa, iters):
    """GJK on every pair (and EPA where GJK leaves the pair to it, if ``with_epa``), as pair_distance
    sets them up; iters[i] = (GJK's, EPA's iterations). Returns the count of pairs EPA would take."""
    work = dist_kernels.block_of(dist_kernels.workspace(1, dist_kernels.EPA_ROOM[0]), 0)
    W, I, lam = work[0], work[1], work[2]
    ix = (aoff[0], aoff[1] - aoff[0], boff[0], boff[1] - boff[0])
    cnt = np.zeros(2, np.int64)
    to_epa = 0
    for i in range(pos_a.shape[0]):
        ox, oy, oz, dx, dy, dz, tol = centres_and_tolerance(
            acen[0, 0], acen[0, 1], bcen[0, 0], bcen[0, 1], pos_a[i], rot_a[i], pos_b[i], rot_b[i], arad[0],
            brad[0], rtol, 0.0, eps,
        )  # fmt: skip
        L = dist_kernels.BOX * (arad[0] + brad[0] + math.sqrt(dx * dx + dy * dy + dz * dz))
        acc = max(dist_kernels.ACC_FRACTION * tol, dist_kernels.ACC_EPS * dist_kernels.EPS64 * L)
        loose = max(dist_kernels.LOOSE_FRACTION * tol, acc)
        fr, cone, _, _, k = cut_difference(rot_a[i], rot_b[i], dx, dy, dz, L)
        acc, loose = k * acc, k * loose  # in D_L's units, as pair_distance runs them
        cnt[0] = cnt[1] = 0
        m, _, _, _, inside, lower = gjk_counted(P, ix, fr, cone, 0.0, 0.0, 0.0, acc, loose, W, I, lam, cnt)
        if inside and not lower > acc:
            to_epa += 1
            if with_epa:
                epa_counted(P, ix, fr, cone, W, I, m, acc, work, cnt)
        iters[i, 0], iters[i, 1] = cnt[0], cnt[1]
    return to_epa


def bucket_rows(n_vertices, n_pairs, repeats, rng):
    a, b = pb.Prism.regular(n_vertices, RADIUS_A), pb.Prism.regular(n_vertices, RADIUS_B)
    A, B = (as_prism_set(s, name)[0].kernel_arrays() for s, name in ((a, "a"), (b, "b")))
    P = (A.vx, A.vy, A.edge_angle, A.edge_table, B.vx, B.vy, B.edge_angle, B.edge_table)
    eps = float(np.finfo(np.float64).eps)
    rtol = DEFAULT_RTOL[np.dtype(np.float64)]
    poses = tuple(np.ascontiguousarray(x) for x in facing_poses(n_pairs, rng, radius=RADIUS_B))
    rows = []
    for bucket in BUCKETS:
        pairs = place(a, b, poses, DISTANCE_BUCKETS[bucket], rng, RADIUS_A + RADIUS_B)
        n = len(pairs[0])
        iters = np.zeros((n, 2), np.int64)
        args = (P, A.offsets, A.radius, A.centre, B.offsets, B.radius, B.centre, *pairs, rtol, eps)
        n_epa = _loop(*args, True, iters)  # (compiles; the counts are the same on every run)
        scratch = np.zeros((n, 2), np.int64)
        calls = {  # interleaved: their differences share the machine's state
            "gjk": lambda args=args: _loop(*args, False, scratch),
            "both": lambda args=args: _loop(*args, True, scratch),
            "whole": lambda pairs=pairs: pb.distance(a, b, *pairs, parallel=False),
        }
        t = {k: stats(v)["median"] for k, v in timed_loops(calls, repeats).items()}
        gjk_s, both_s, whole_s = t["gjk"], t["both"], t["whole"]
        epa = iters[iters[:, 1] > 0, 1]
        rows.append(
            {
                "vertices": n_vertices,
                "bucket": bucket,
                "pairs": n,
                "gjk_iterations_mean": float(iters[:, 0].mean()),
                "gjk_iterations_max": int(iters[:, 0].max()),
                "gjk_us": 1e6 * gjk_s / n,
                "epa_pairs": int(n_epa),
                "epa_iterations_mean": float(epa.mean()) if epa.size else None,
                "epa_iterations_max": int(epa.max()) if epa.size else None,
                "epa_us_per_epa_pair": 1e6 * (both_s - gjk_s) / n_epa if n_epa else None,
                "distance_us": 1e6 * whole_s / n,
            }
        )
    return rows


def markdown(rows):
    def f(x, fmt):
        return "-" if x is None else format(x, fmt)

    out = [
        "| n | bucket | GJK iterations mean (max) | GJK µs | EPA pairs | EPA iterations mean (max) "
        "| EPA µs a pair it runs on | distance µs |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        out.append(
            f"| {r['vertices']} | {r['bucket']} | {r['gjk_iterations_mean']:.1f} ({r['gjk_iterations_max']}) "
            f"| {r['gjk_us']:.2f} | {r['epa_pairs']} of {r['pairs']} "
            f"| {f(r['epa_iterations_mean'], '.1f')} ({f(r['epa_iterations_max'], 'd')}) "
            f"| {f(r['epa_us_per_epa_pair'], '.2f')} | {r['distance_us']:.2f} |"
        )
    return "\n".join(out) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pairs", type=int, default=2000, help="pose pairs per bucket (default 2000)")
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", metavar="DIR", help="write profile_distance.md and profile_distance.json to DIR")
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    rows = [r for n in (36, 3600) for r in bucket_rows(n, args.pairs, args.repeats, rng)]
    table = markdown(rows)
    print(table)
    if args.out:
        out = Path(args.out)
        write_text(out / "profile_distance.md", table)
        write_json(out / "profile_distance.json", {"machine": run_metadata(), "args": vars(args), "rows": rows})


if __name__ == "__main__":
    main()
