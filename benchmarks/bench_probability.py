#!/usr/bin/env python
"""Collision probability under pose noise: sampling rate, samples needed, interval coverage.

1. **Rate.** Samples per second of ``collision_probability`` with plain sampling run to its
   budget (one query, and many queries at once), against ``Collider.collide`` on the same
   number of ready-made pose pairs, in the same run (medians over repeats); and of importance
   sampling (p = 1e-4), against collide on poses drawn as its proposal draws them.
2. **Samples needed** at ``rel_error`` 0.1 (95 %) for p = 1e-2, 1e-4 and 1e-6 on the known-answer
   case (two unit squares facing, b's height uncertain by 0.1, small sideways shifts and spins
   about the axis: p = Phi(-height / 0.1) exactly): plain sampling run where affordable, its
   theoretical count ``z^2 (1 - p) / (p rel^2)`` otherwise, against importance sampling
   (medians over seeds).
3. **Coverage** of the 95 % intervals over repeated runs (different seeds) on the known-answer
   case at the three levels, and with isotropic noise in all six components (rotations
   included: one likeliest collision per corner that a tilt lowers) on facing squares,
   triangles and 12-gons of circumradius 1 at height 0.5. Their answers come from long plain
   runs: :data:`REFERENCES` (measured once, 2-4 x 10^8 samples each; ``--reference N``
   measures them again with N plain samples each).

    python benchmarks/bench_probability.py [--quick] [--repeats 200] [--reference N] [--out FILE.json]
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np

import prismbatch as pb
from prismbatch.probability import collision_probability

SQ = pb.Prism.regular(4, 1.0)
DOWN = np.diag([1.0, -1.0, -1.0])
FACING_COV = np.diag([0.05**2, 0.05**2, 0.1**2, 0.0, 0.0, 0.1**2])
LEVELS = {1e-2: 0.232635, 1e-4: 0.371902, 1e-6: 0.475342}  # height giving p = Phi(-height / 0.1)
ISO = np.eye(6) * 1e-2  # 0.1 in every translation and rotation component
#: Isotropic cases: (polygon, height of b, p, 95 % interval of p) from plain sampling, 2e9 samples
#: each, seed 12345 (hits: squares 1087488, triangles 703927, 12-gons 1997839). The earlier
#: references of 2-4e8 samples had the triangles' p 0.6 % low (1.6 of their standard errors),
#: which alone pulled that case's measured coverage down.
REFERENCES = {
    "squares": (SQ, 0.5, 5.437443e-4, (5.427236e-4, 5.447669e-4)),
    "triangles": (pb.Prism.regular(3, 1.0), 0.5, 3.519637e-4, (3.511426e-4, 3.527867e-4)),
    "12-gons": (pb.Prism.regular(12, 1.0), 0.5, 9.989200e-4, (9.975365e-4, 1.0003054e-3)),
}


def phi_tail(x):
    return 0.5 * math.erfc(x / math.sqrt(2))


def median_time(f, repeats):
    ts = []
    for _ in range(repeats):
        t = time.perf_counter()
        f()
        ts.append(time.perf_counter() - t)
    return float(np.median(ts))


def _sampling_time(col, pos_b, repeats, **kw):
    """Median seconds of ``collision_probability`` on the facing squares (b at ``pos_b``, noise
    FACING_COV), after one call that compiles or loads its kernels."""
    call = lambda: col.collision_probability(np.zeros(3), DOWN, pos_b, np.eye(3), FACING_COV, **kw)  # noqa: E731
    call()
    return median_time(call, repeats)


def _collide_rate(col, pos_b, spin, repeats):
    """Pairs/s of ``collide`` on facing pairs: a fixed, b at ``pos_b`` (m, 3) turned by ``spin`` (m,)
    about its axis."""
    m = len(spin)
    c, s = np.cos(spin), np.sin(spin)
    R = np.zeros((m, 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1], R[:, 2, 2] = c, -s, s, c, 1.0
    pa, ra = np.zeros((m, 3)), np.broadcast_to(DOWN, (m, 3, 3)).copy()
    col.collide(pa, ra, pos_b, R)
    return m / median_time(lambda: col.collide(pa, ra, pos_b, R), repeats)


def rate(n_samples, n_queries, repeats):
    """Samples/s of plain sampling (budget spent) and pairs/s of collide on as many pairs."""
    per = n_samples // n_queries
    col = pb.Collider(SQ, SQ)
    kw = dict(rel_error=1e-9, max_samples=per, method="plain", seed=0)
    t_prob = _sampling_time(col, np.tile([0.0, 0.0, 0.1], (n_queries, 1)), repeats, **kw)
    rng = np.random.default_rng(0)
    pos = np.column_stack([rng.normal(0, 0.05, (n_samples, 2)), 0.1 + rng.normal(0, 0.1, n_samples)])
    return per * n_queries / t_prob, _collide_rate(col, pos, rng.normal(0, 0.1, n_samples), repeats)


def importance_rate(n_samples, repeats):
    """Samples/s of importance sampling (one query at p = 1e-4, budget spent) and pairs/s of collide
    on poses drawn as its proposal draws them: 90 % about the likeliest collision (b lowered by its
    height, spread 1.2 in standard units), 10 % from the nominal noise. Its samples land near
    contact, where collide does more work than on the nominal poses of :func:`rate`."""
    h = LEVELS[1e-4]
    col = pb.Collider(SQ, SQ)
    kw = dict(rel_error=1e-9, max_samples=n_samples, method="importance", seed=0)
    t_prob = _sampling_time(col, [0, 0, h], repeats, **kw)
    rng = np.random.default_rng(0)
    z = rng.normal(size=(n_samples, 4))  # x, y, height, spin in standard units
    near = rng.uniform(size=n_samples) >= 0.1
    z[near] = np.array([0.0, 0.0, -h / 0.1, 0.0]) + 1.2 * z[near]
    pos = np.column_stack([0.05 * z[:, 0], 0.05 * z[:, 1], h + 0.1 * z[:, 2]])
    return n_samples / t_prob, _collide_rate(col, pos, 0.1 * z[:, 3], repeats)


def needed(seeds, plain_up_to):
    rows = []
    for p, h in LEVELS.items():
        pos = np.tile([0.0, 0.0, h], (seeds, 1))
        imp = collision_probability(SQ, SQ, np.zeros(3), DOWN, pos, np.eye(3), FACING_COV, seed=1, method="importance")
        theory = 1.96**2 * (1 - p) / (p * 0.01)
        if p >= plain_up_to:
            pl = collision_probability(
                SQ, SQ, np.zeros(3), DOWN, pos[:5], np.eye(3), FACING_COV, seed=1, method="plain", max_samples=10**8
            )
            plain = float(np.median(pl.samples))
        else:
            plain = None
        rows.append(
            dict(
                p=p,
                exact=phi_tail(h / 0.1),
                plain_run=plain,
                plain_theory=theory,
                importance_median=float(np.median(imp.samples)),
                importance_max=int(imp.samples.max()),
                importance_converged=float(imp.converged.mean()),
            )
        )
    return rows


def reference(shape, height, samples):
    """p and its 95 % interval by plain sampling (``samples`` of them) of an isotropic case."""
    r = collision_probability(
        shape, shape, np.zeros(3), DOWN, [0, 0, height], np.eye(3), ISO, seed=99, method="plain", rel_error=1e-9,
        max_samples=samples,
    )  # fmt: skip
    return float(r.p[0]), (float(r.low[0]), float(r.high[0]))


def coverage(repeats, quick, ref_samples):
    out = []
    for j, (p, h) in enumerate(LEVELS.items()):  # a seed per case: rows on one seed share their draws
        pos = np.tile([0.0, 0.0, h], (repeats, 1))
        t = time.perf_counter()
        r = collision_probability(SQ, SQ, np.zeros(3), DOWN, pos, np.eye(3), FACING_COV, seed=2 + j)
        exact = phi_tail(h / 0.1)
        out.append(_cov_row(f"facing, p = {p:g}", r, exact, time.perf_counter() - t))
    for j, (name, (shape, h, answer, interval)) in enumerate(({} if quick else REFERENCES).items()):
        if ref_samples:
            answer, interval = reference(shape, h, ref_samples)
        pos = np.tile([0.0, 0.0, h], (repeats, 1))
        t = time.perf_counter()
        r = collision_probability(shape, shape, np.zeros(3), DOWN, pos, np.eye(3), ISO, seed=5 + j)
        row = _cov_row(f"isotropic 6-D noise, {name}, height {h}", r, answer, time.perf_counter() - t)
        row["reference_interval"] = list(interval)
        out.append(row)
    return out


def _cov_row(name, r, answer, seconds):
    covered = (r.low <= answer) & (answer <= r.high)
    return dict(
        case=name,
        answer=answer,
        runs=len(r),
        covered=float(covered.mean()),
        low_side=float(np.mean(r.high < answer)),  # misses with the interval below the answer
        high_side=float(np.mean(r.low > answer)),
        mean_p_over_answer=float(r.p.mean() / answer),
        converged=float(r.converged.mean()),
        median_samples=float(np.median(r.samples)),
        mean_samples=float(np.mean(r.samples)),
        methods={int(m): int(c) for m, c in zip(*np.unique(r.method, return_counts=True))},
        seconds=seconds,
    )


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="small sizes, no isotropic coverage cases")
    ap.add_argument("--repeats", type=int, default=1000, help="runs per coverage case (default 1000)")
    ap.add_argument(
        "--reference", type=int, default=0, help="measure the isotropic answers with this many plain samples"
    )
    ap.add_argument("--out", help="write every figure to this JSON file")
    a = ap.parse_args()
    n = 1 << 18 if a.quick else 1 << 21
    res = {"threads": __import__("numba").get_num_threads()}
    res["rate_one_query"] = rate(n, 1, 3)
    res["rate_256_queries"] = rate(n, 256, 3)
    res["rate_importance"] = importance_rate(n, 3)
    res["needed"] = needed(5 if a.quick else 20, 1e-4)
    res["coverage"] = coverage(30 if a.quick else a.repeats, a.quick, a.reference)
    print(f"Numba threads: {res['threads']}\n")
    print("| rate | samples/s | collide pairs/s | ratio |\n|---|---|---|---|")
    for k in ("rate_one_query", "rate_256_queries", "rate_importance"):
        s, c = res[k]
        print(f"| {k} | {s:.3g} | {c:.3g} | {s / c:.2f} |")
    print("\n| p | plain (run) | plain (theory) | IS median | IS max | IS converged |\n|---|---|---|---|---|---|")
    for r in res["needed"]:
        pr = "-" if r["plain_run"] is None else f"{r['plain_run']:.0f}"
        print(
            f"| {r['p']:g} | {pr} | {r['plain_theory']:.3g} | {r['importance_median']:.0f} | "
            f"{r['importance_max']} | {r['importance_converged']:.2f} |"
        )
    # +-: the coverage's own sampling error (95 %; 1.5 % at 200 runs, 0.7 % at 1000)
    print(
        "\n| case | runs | covered | +- | high < answer | low > answer | mean p / answer | converged | median samples |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for r in res["coverage"]:
        pm = 1.96 * math.sqrt(r["covered"] * (1 - r["covered"]) / r["runs"])
        print(
            f"| {r['case']} | {r['runs']} | {r['covered']:.3f} | {pm:.3f} | {r['low_side']:.3f} | "
            f"{r['high_side']:.3f} | {r['mean_p_over_answer']:.4f} | {r['converged']:.2f} | {r['median_samples']:.0f} |"
        )
    print("\n| case | methods | mean samples | s |\n|---|---|---|---|")
    for r in res["coverage"]:
        print(f"| {r['case']} | {r['methods']} | {r['mean_samples']:.0f} | {r['seconds']:.1f} |")
    if a.out:
        with open(a.out, "w") as f:
            json.dump(res, f, indent=1)


if __name__ == "__main__":
    main()
