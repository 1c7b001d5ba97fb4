#!/usr/bin/env python
"""Where collide's time goes: the per-pair kernel taken apart in stages, path by path.

Each stage is a compiled loop over the same pose pairs that does what the kernel does up to a
point, built from the kernel's own inlined pieces (``prismbatch._kernels``), so the difference
between two stages is what that step costs per pair:

1. the floor: read both poses, b's height along a's axis and the axes' cosine, one compare
   (``bench_floor.py``'s loop);
2. the relative pose: a's end-face centre and b's in world axes, the exact inverse of a's
   rotation, b's position and rotation in a's centred frame, the axes' exact difference;
3. the pair tolerance (its square roots: ``|c_b - c_a|``, ``|c_a|``, ``|c_b|``), and the test whether
   c_b - c_a must be summed again in twice the precision (objects far from the origins), as the kernel
   forms them (``centres_and_tolerance``, before the relative pose);
4. the radius exit (case 1 proven from b's circumradius and tilt: one more square root);
5. b's deepest vertex (an extreme-vertex search: bucket lookup and binary search) and the
   vertex exit;
6. the early-accept tests: whether b's deepest vertex and its end-face centre project into a's
   polygon (two point-in-polygon searches), and b's highest vertex (the planar GJK's start),
   for every pair that passed stage 5 (the kernel skips some of these after its coarse tests,
   so on the mixes this stage is an upper bound of their cost);
7. the whole kernel (``collide_serial`` on the prepared arrays, no contact);
8. ``Collider.collide(..., parallel=False)``: the Python entry, which checks and converts the
   poses (finite, orthonormal to the tolerance, in range) before the kernel.

Stages 2-5 run for every pair whatever the pair's path (they stop where the kernel would go on),
so on pairs that leave early stage 5 is the kernel's work, and on case-6 pairs the step from
stage 6 to the kernel is the coarse tests and the planar GJK. The planar GJK's iteration count on those pairs
comes from the kernel's trace (``Collider.explain``) on a sample.

One query (``Collider.collide_pair`` on one plain pair of 36-gons), taken apart the same way: a
trivial ``@njit`` call with the same four pose arrays; the compiled one-pair kernel called with
all its arguments (one array holding both prisms and the scalars, the four poses, the contact's
output array: each crosses Numba's dispatcher, which types and unboxes it); then the
result tuple; then the whole method (its checks of the call's form).

What a search costs grows with the polygon's size because its loads depend on each other: each
step of a binary search reads the entry the last step chose. The last table times such a chain of
dependent loads (a pointer chase over a random cycle) over working sets of the size of one polygon
array (n entries of 8 bytes) and of all eight arrays the kernel searches in a pair (a's vertices,
polar angles and inverse edge lengths, b's vertices, edge angles and bucket table), at each n.

One thread, medians over repeats, all figures from one run:

    python benchmarks/profile_collide.py [--quick] [--out DIR]
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numba
import numpy as np

import prismbatch as pb
from prismbatch._kernels.batch import (
    centres_and_tolerance,
    centres_world,
    collide_serial,
    frame_inverse,
    relative_pose,
)
from prismbatch._kernels.jit import jit
from prismbatch._kernels.one_pair import collide_pair, pair_bundle
from prismbatch._kernels.planar import extreme_vertex, point_polygon_distance
from prismbatch._kernels.projection import surely_above, surely_above_by_radius
from prismbatch.config import SUPPORTED_RANGE
from prismbatch.lab.report import fmt
from prismbatch.lab.timing import stats, threads, timed_loops
from prismbatch.pair import HIT_CASE, PairResult
from prismbatch.poses import ortho_tolerance
from prismbatch.sampling import facing_poses

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_floor import (  # noqa: E402  (the same floor, sets and options)
    RADIUS_A,
    RADIUS_B,
    floor_loop,
    parse_args,
    pose_sets,
    report,
    seconds_per_call,
    trivial_call,
)

#: Polygon sizes (vertices): as ``bench_floor.py``'s rows.
SIZES = (36, 3600, 100_000)

STAGES = (
    "floor",
    "relative pose",
    "tolerance",
    "radius exit",
    "vertex exit",
    "early accept",
    "kernel",
    "Collider.collide",
)


# Compiled as the kernels are (prismbatch's jit: without Numba's reference counting). Under plain
# njit every pose view handed to the tolerance's rarely taken branch was counted, atomically, on every
# pair: the stages then cost more than the whole kernel (the tolerance stage 67 ns against the kernel's
# 47 on early exits, 2026-11-28).
@jit(error_model="numpy")
def _staged(stage, A, B, pos_a, rot_a, pos_b, rot_b, rtol, eps, out):
    """The kernel's steps for one prism pair up to ``stage`` (2 to 6): ``out[i]`` depends on each
    step's result, so no step is left out by the compiler."""
    avx, avy, avang, ainv, aoff, arad, acen = A
    bvx, bvy, beang, betab, boff, brad, bcen = B
    acx, acy, bcx, bcy = acen[0, 0], acen[0, 1], bcen[0, 0], bcen[0, 1]
    sb, nb = boff[0], boff[1] - boff[0]
    for i in range(pos_a.shape[0]):
        Pa, Ra, Pb, Rb = pos_a[i], rot_a[i], pos_b[i], rot_b[i]
        if stage == 2:
            ox, oy, oz, dx, dy, dz = centres_world(acx, acy, bcx, bcy, Pa, Ra, Pb, Rb)
            tol = 0.0
        else:  # as the kernel: the tolerance with the centres, before the relative pose
            ox, oy, oz, dx, dy, dz, tol = centres_and_tolerance(
                acx, acy, bcx, bcy, Pa, Ra, Pb, Rb, arad[0], brad[0], rtol, 0.0, eps
            )
        inv = frame_inverse(Ra)
        px, py, pz, r00, r01, r10, r11, r20, r21 = relative_pose(inv, dx, dy, dz, Rb)
        s = 1.0 if Ra[0, 2] * Rb[0, 2] + Ra[1, 2] * Rb[1, 2] + Ra[2, 2] * Rb[2, 2] >= 0.0 else -1.0
        ex, ey, ez = Rb[0, 2] - s * Ra[0, 2], Rb[1, 2] - s * Ra[1, 2], Rb[2, 2] - s * Ra[2, 2]
        r22 = s + (inv[6] * ex + inv[7] * ey + inv[8] * ez)
        if stage == 2:
            out[i] = pz + r22 + r00 + r11 > 0.0
            continue
        if stage == 3:
            out[i] = pz + r22 > tol
            continue
        above = surely_above_by_radius(pz, r20, r21, r22, brad[0], tol)
        if stage == 4 or above:
            out[i] = above
            continue
        imax = extreme_vertex(bvx, bvy, beang, betab, sb, nb, r20, r21)
        above = surely_above(bvx, bvy, sb, imax, pz, r20, r21, r22, tol)
        if stage == 5 or above:
            out[i] = above
            continue
        r02, r12 = inv[0] * ex + inv[1] * ey + inv[2] * ez, inv[3] * ex + inv[4] * ey + inv[5] * ez
        tx = px + r00 * bvx[sb + imax] + r01 * bvy[sb + imax]
        ty = py + r10 * bvx[sb + imax] + r11 * bvy[sb + imax]
        inside = point_polygon_distance(avx, avy, avang, ainv, 0, aoff[1], tx, ty) >= 0.0
        inside |= point_polygon_distance(avx, avy, avang, ainv, 0, aoff[1], px, py) >= 0.0
        imin = extreme_vertex(bvx, bvy, beang, betab, sb, nb, -r20, -r21)
        out[i] = inside or imin + r02 + r12 > 0.0


def stage_rows(n_vertices, n_pairs, repeats, rng):
    """Per-pair ns of every stage on each pose kind at one polygon size."""
    a, b = pb.Prism.regular(n_vertices, RADIUS_A), pb.Prism.regular(n_vertices, RADIUS_B)
    col = pb.Collider(a, b)
    ka, kb = pb.PrismSet([a.xy]).kernel_arrays(), pb.PrismSet([b.xy]).kernel_arrays()
    A = (ka.vx, ka.vy, ka.vertex_angle, ka.inv_edge_len, ka.offsets, ka.radius, ka.centre)
    B = (kb.vx, kb.vy, kb.edge_angle, kb.edge_table, kb.offsets, kb.radius, kb.centre)
    rtol, eps = col.rtol, float(np.finfo(np.float64).eps)
    sets = pose_sets(col, n_pairs, rng)
    rows = []
    for name, poses in sets.items():
        n = len(poses[0])
        out = np.empty(n, dtype=np.bool_)
        hit, cs, cont = np.empty(n, np.bool_), np.empty(n, np.int8), np.empty((0, 3))
        fns = {
            "floor": lambda p=poses, o=out: floor_loop(*p, o),
            **{
                STAGES[k - 1]: (lambda k=k, p=poses, o=out: _staged(k, A, B, *p, rtol, eps, o)) for k in (2, 3, 4, 5, 6)
            },
            "kernel": lambda p=poses: collide_serial(
                0, n, ka.floats, ka.ints, kb.floats, kb.ints, *p, rtol, 0.0, eps, False, hit, cs, cont
            ),  # fmt: skip
            "Collider.collide": lambda p=poses: col.collide(*p, parallel=False),
        }
        times = timed_loops(fns, repeats)  # interleaved passes: drift hits every stage alike
        row = {"vertices": n_vertices, "set": name, "pairs": n}
        row.update({k: 1e9 * stats(v)["median"] / n for k, v in times.items()})
        rows.append(row)
    return rows


def gjk_iterations(n_vertices, n_pairs, rng):
    """The planar GJK's iterations on a sample of case-6 pairs (from the kernel's trace)."""
    a, b = pb.Prism.regular(n_vertices, RADIUS_A), pb.Prism.regular(n_vertices, RADIUS_B)
    col = pb.Collider(a, b)
    facing = facing_poses(20 * n_pairs, rng, radius=RADIUS_B)
    idx = np.flatnonzero(col.collide(*facing, parallel=False).case == 6)[:n_pairs]
    its = np.array([col.explain(*(x[i] for x in facing))["gjk_iterations"] for i in idx], dtype=float)
    its = its[np.isfinite(its)]
    return {
        "vertices": n_vertices,
        "pairs": int(len(its)),
        "mean": float(its.mean()) if len(its) else math.nan,
        "p50": float(np.median(its)) if len(its) else math.nan,
        "p95": float(np.percentile(its, 95)) if len(its) else math.nan,
        "max": float(its.max()) if len(its) else math.nan,
    }


@numba.njit(cache=True)
def _chase(nxt, steps):
    """Follow ``nxt`` ``steps`` times from 0: each load's address is the last load's value."""
    i = 0
    for _ in range(steps):
        i = nxt[i]
    return i


def load_latency(n_vertices, repeats, rng, steps=1_000_000):
    """ns per dependent load over one polygon array (8 n bytes) and over a pair's eight (64 n bytes)."""
    row = {"vertices": n_vertices}
    for key, nbytes in (("one", 8 * n_vertices), ("pair", 64 * n_vertices)):
        n = max(nbytes // 8, 2)
        perm = rng.permutation(n)
        nxt = np.empty(n, np.int64)
        nxt[perm] = np.roll(perm, 1)  # one cycle through every entry, in random order
        times = timed_loops({key: lambda: _chase(nxt, steps)}, repeats)
        row[key] = 1e9 * stats(times[key])["median"] / steps
        row[key + "_bytes"] = nbytes
    return row


def latency_steps(repeats):
    """ns per call of each step of one ``collide_pair`` query (36-gons, one facing pair)."""
    a, b = pb.Prism.regular(36, RADIUS_A), pb.Prism.regular(36, RADIUS_B)
    col = pb.Collider(a, b)
    ka, kb = pb.PrismSet([a.xy]).kernel_arrays(), pb.PrismSet([b.xy]).kernel_arrays()
    one = tuple(np.ascontiguousarray(x[0]) for x in facing_poses(1, np.random.default_rng(1), radius=RADIUS_B))
    f64 = np.dtype(np.float64)
    bundle = pair_bundle(ka, kb, col.rtol, 0.0, float(np.finfo(f64).eps), ortho_tolerance(f64, f64),
                         ortho_tolerance(f64, f64), SUPPORTED_RANGE["float64"][1])  # fmt: skip
    kernel = collide_pair[f64]

    calls = {
        "trivial @njit call, same 4 arrays": lambda: trivial_call(*one),
        "one-pair kernel, all 6 arguments": lambda: kernel(bundle, *one, np.empty(3)),
        # one expression each (walrus), so that no step adds a Python call of its own
        "+ the result tuple": lambda: (
            (c := np.empty(3)),
            (o := kernel(bundle, *one, c)),
            PairResult(*HIT_CASE[o], c),
        ),
        "Collider.collide_pair": lambda: col.collide_pair(*one),
    }
    return {k: 1e9 * v for k, v in seconds_per_call(calls, repeats).items()}


def markdown(res):
    lines = [
        "| vertices | pose set | " + " | ".join(f"{s} (ns)" for s in STAGES) + " |",
        "|---" * (2 + len(STAGES)) + "|",
    ]
    for r in res["stages"]:
        lines.append(f"| {r['vertices']:,} | {r['set']} | " + " | ".join(fmt(r[s], ".3g") for s in STAGES) + " |")
    lines += ["", "| vertices | case-6 pairs traced | GJK iterations: mean | median | 95th percentile | max |",
              "|---|---|---|---|---|---|"]  # fmt: skip
    for g in res["gjk"]:
        lines.append(
            f"| {g['vertices']:,} | {g['pairs']} | {g['mean']:.2f} | {g['p50']:g} | {g['p95']:g} | {g['max']:g} |"
        )
    lines += ["", "| vertices | dependent load over one polygon array (ns) | over a pair's eight arrays (ns) |",
              "|---|---|---|"]  # fmt: skip
    for m in res["memory"]:
        lines.append(
            f"| {m['vertices']:,} | {fmt(m['one'], '.3g')} ({m['one_bytes']:,} B) "
            f"| {fmt(m['pair'], '.3g')} ({m['pair_bytes']:,} B) |"
        )
    lines += ["", "| one query, step by step | ns per call |", "|---|---|"]
    lines += [f"| {k} | {fmt(v, '.0f')} |" for k, v in res["latency"].items()]
    return "\n".join(lines)


def main(argv=None):
    args, repeats = parse_args(__doc__, "profile", argv)
    n_pairs = 20_000 if args.quick else 200_000
    rng = np.random.default_rng(args.seed)
    with threads(1):
        stages = [r for nv in SIZES for r in stage_rows(nv, n_pairs, repeats, rng)]
        memory = [load_latency(nv, repeats, rng) for nv in SIZES]
        latency = latency_steps(repeats)
    gjk = [gjk_iterations(nv, 50 if args.quick else 500, rng) for nv in SIZES]
    res = {"stages": stages, "gjk": gjk, "memory": memory, "latency": latency, "pairs": n_pairs}
    report(markdown(res), res, "profile", args, repeats)
    return 0


if __name__ == "__main__":
    sys.exit(main())
