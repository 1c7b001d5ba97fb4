#!/usr/bin/env python
"""Time of impact against one signed-distance query per pair, on typical motions, in one run.

The paper's facing scene (``sampling.facing_poses``: a at the origin with its
axis down, b above it within 15 degrees of up, some already touching), regular
n-gons of circumradius 2 and 2.5 (36 and 3600 vertices). Motions over a horizon
of 1:

- ``translate``: b heads for a random point of a's end-face region at a speed
  that gets it there in 0.3 to 2 horizons (some arrive, some do not), no turn;
- ``turn 0.2``: the same plus an angular velocity turning b by up to 0.2 rad
  over the horizon (a gripper re-orienting while it moves);
- ``turn 1``: up to 1 rad over the horizon;
- ``pass by``: a random velocity of the scene's size per horizon and a turn up
  to 0.5 rad, mostly missing a.

Both are timed per pair on one thread (``parallel=False``), medians over
repeats; the ratio is time of impact / distance on the same initial poses.
The iterations columns give the advancement steps per pair (median, 90th
percentile, max).

    python benchmarks/bench_toi.py [--quick] [--pairs N] [--repeats R]
"""

from __future__ import annotations

import argparse

import numpy as np

import prismbatch as pb
from prismbatch.lab.report import fmt
from prismbatch.lab.timing import stats, threads, timed_loops
from prismbatch.sampling import facing_poses

RADIUS_A, RADIUS_B = 2.0, 2.5


def motions(kind, pos_b, rng):
    """(velocity, angular_velocity), (n, 3) each, of the named kind for b starting at ``pos_b``."""
    n = len(pos_b)
    target = np.column_stack([rng.uniform(-RADIUS_A, RADIUS_A, (n, 2)), np.zeros(n)])
    if kind == "pass by":
        vel = rng.normal(size=(n, 3)) * (RADIUS_A + RADIUS_B)
        turn = 0.5
    else:
        vel = (target - pos_b) / rng.uniform(0.3, 2.0, (n, 1))
        turn = {"translate": 0.0, "turn 0.2": 0.2, "turn 1": 1.0}[kind]
    w = rng.normal(size=(n, 3))
    w *= turn * rng.uniform(0, 1, (n, 1)) / np.linalg.norm(w, axis=1, keepdims=True)
    return np.ascontiguousarray(vel), np.ascontiguousarray(w)


def rows_for(n_vertices, n_pairs, repeats, rng):
    a, b = pb.Prism.regular(n_vertices, RADIUS_A), pb.Prism.regular(n_vertices, RADIUS_B)
    col = pb.Collider(a, b)
    pa, ra, pb_, rb = facing_poses(n_pairs, rng, radius=RADIUS_B)
    rows = []
    for kind in ("translate", "turn 0.2", "turn 1", "pass by"):
        vel, w = motions(kind, pb_, rng)
        calls = {
            "distance": lambda: col.distance(pa, ra, pb_, rb, parallel=False),
            "toi": lambda: col.time_of_impact(pa, ra, pb_, rb, vel, w, horizon=1.0, parallel=False),
        }
        t = timed_loops(calls, repeats)
        r = calls["toi"]()
        it = r.iterations
        row = {"vertices": n_vertices, "motion": kind}
        row["distance_us"] = 1e6 * stats(t["distance"])["median"] / n_pairs
        row["toi_us"] = 1e6 * stats(t["toi"])["median"] / n_pairs
        row["ratio"] = row["toi_us"] / row["distance_us"]
        row["contact"] = float(np.mean(r.status == 1))
        row["undecided"] = int(np.count_nonzero(r.status == -1))
        row["iter_median"], row["iter_p90"] = np.percentile(it, [50, 90])
        row["iter_max"] = int(it.max())
        rows.append(row)
    return rows


def markdown(rows):
    head = ["vertices", "motion", "distance µs", "TOI µs", "TOI / distance", "contact", "undecided", "iterations"]
    L = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        its = f"{r['iter_median']:.0f} / {r['iter_p90']:.0f} / {r['iter_max']}"
        cells = [r["vertices"], r["motion"], fmt(r["distance_us"]), fmt(r["toi_us"]), fmt(r["ratio"])]
        cells += [f"{100 * r['contact']:.0f} %", r["undecided"], its]
        L.append("| " + " | ".join(str(c) for c in cells) + " |")
    return "\n".join(L) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer pairs and repeats (a smoke run)")
    ap.add_argument("--pairs", type=int, default=None)
    ap.add_argument("--repeats", type=int, default=None)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    n_pairs, repeats = (500, 3) if args.quick else (5000, 5)
    n_pairs = args.pairs or n_pairs
    repeats = args.repeats or repeats
    rng = np.random.default_rng(args.seed)
    a = pb.Prism.regular(5, 1.0)
    z = np.zeros(3)
    pb.distance(a, a, z, np.eye(3), np.ones(3), np.eye(3), parallel=False)  # compile outside timing
    pb.Collider(a, a).time_of_impact(z, np.eye(3), np.ones(3), np.eye(3), z, horizon=1.0, parallel=False)
    rows = []
    with threads(1):
        for n in (36, 3600):
            rows += rows_for(n, n_pairs, repeats, rng)
    print(f"{n_pairs} pairs per row, one thread, medians of {repeats} repeats\n")
    print(markdown(rows))


if __name__ == "__main__":
    main()
