"""A demo batch: throughput and hit/case counts on random pose pairs."""

from __future__ import annotations

import time

import numba
import numpy as np

from ..collide import CASES, Collider
from ..sampling import DISTRIBUTIONS
from ..shapes import Prism
from .report import progress as progress_bar

__all__ = ["run_demo"]


def run_demo(
    n_pairs=1_000_000,
    n_vertices=360,
    distribution="facing",
    seed=0,
    chunk=250_000,
    contact=False,
    parallel=True,
    progress=True,
):
    """Collide ``n_pairs`` random pose pairs of the paper's scene, in chunks.

    a is a regular ``n_vertices``-gon of circumradius 2 and b one of
    circumradius 2.5 (the paper's Fig. 6 sizes). Poses come from
    :data:`prismbatch.sampling.DISTRIBUTIONS`, one seed for the whole run.

    Returns
    -------
    dict
        ``compile_s`` (first call on 8 pairs: compilation or cache load),
        ``run_s`` (kernel time over all chunks, pose sampling excluded),
        ``pairs_per_s``, ``hits``, ``case_counts`` and the settings.
    """
    if distribution not in DISTRIBUTIONS:
        raise ValueError(f"distribution must be one of {sorted(DISTRIBUTIONS)}, got {distribution!r}")
    if n_pairs < 1 or chunk < 1:
        raise ValueError("n_pairs and chunk must be >= 1")
    gen = DISTRIBUTIONS[distribution]
    col = Collider(Prism.regular(n_vertices, 2.0), Prism.regular(n_vertices, 2.5))
    rng = np.random.default_rng(seed)

    t0 = time.perf_counter()
    col.collide(*gen(8, np.random.default_rng(seed + 1)), contact=contact, parallel=parallel)
    compile_s = time.perf_counter() - t0

    run_s = 0.0
    hits = 0
    counts = np.zeros(max(CASES) + 1, dtype=np.int64)
    bar = progress_bar(n_pairs, enabled=progress)
    done = 0
    while done < n_pairs:
        m = min(chunk, n_pairs - done)
        poses = gen(m, rng)
        t0 = time.perf_counter()
        r = col.collide(*poses, contact=contact, parallel=parallel)
        run_s += time.perf_counter() - t0
        hits += int(r.hit.sum())
        counts += np.bincount(r.case, minlength=counts.size)
        done += m
        bar.update(m)
    bar.close()
    return {
        "n_pairs": n_pairs,
        "n_vertices": n_vertices,
        "distribution": distribution,
        "seed": seed,
        "contact": contact,
        "threads": numba.get_num_threads() if parallel else 1,
        "compile_s": compile_s,
        "run_s": run_s,
        "pairs_per_s": n_pairs / run_s if run_s > 0 else float("inf"),
        "hits": hits,
        "case_counts": {k: int(v) for k, v in enumerate(counts) if v},
    }
