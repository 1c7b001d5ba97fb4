"""Collision probability of a large query set, in chunks, in-process or on Dask: :func:`predict`.

The queries are split into chunks of consecutive queries. Chunk ``[start, stop)`` runs
:func:`prismbatch.probability.collision_probability` on its queries with
``query_index = start .. stop - 1`` and the run's seed, so query ``i`` draws from
``SeedSequence(seed, spawn_key=(i,))`` wherever it runs: the merged result equals one in-process
call with the same seed, whatever the chunk size and the number of workers. Chunks carry their
own poses and covariances (the inputs are the user's, not regenerated from a seed as in
``validate``).
"""

from __future__ import annotations

import numpy as np

from ..poses import as_pose
from ..probability import ProbabilityResult, broadcast_queries, collision_probability
from .checks import check_int

__all__ = ["predict", "run_part", "warm"]


def predict(shape_a, shape_b, pos_a, rot_a, pos_b, rot_b, cov_b, *, cov_a=None, seed=0, chunk_size=1024,
            workers=None, scheduler=None, quat_order=None, **options):  # fmt: skip
    """:func:`~prismbatch.probability.collision_probability` of many queries, in chunks.

    Parameters
    ----------
    shape_a, shape_b, pos_a, rot_a, pos_b, rot_b, cov_b, cov_a, quat_order
        As :func:`~prismbatch.probability.collision_probability`.
    seed : int or None, optional
        Root seed (None: drawn once here, so every chunk shares it; kept in the result).
    chunk_size : int, optional
        Queries per chunk (a Dask task).
    workers : int, optional
        Start a local Dask cluster of this many processes.
    scheduler : str, optional
        Address of an existing Dask scheduler. Neither: chunks run here, one after another.
    **options
        ``rel_error``, ``confidence``, ``max_samples``, ``method``, ``rtol``, ``atol``, ``dtype``:
        passed to every chunk.

    Returns
    -------
    result : ProbabilityResult
        All queries, in order.
    execution : dict
        ``scheduler`` ("in-process" or the Dask one), ``chunks`` and, on Dask, what
        :func:`prismbatch.lab.cluster.run_tasks` reports.
    """
    check_int(chunk_size, "chunk_size")
    bad = set(options) - {"rel_error", "confidence", "max_samples", "method", "rtol", "atol", "dtype"}
    if bad:
        raise TypeError(f"predict got unexpected options {sorted(bad)}")
    if seed is None:
        seed = int(np.random.SeedSequence().entropy)
    pa, ra = as_pose(pos_a, rot_a, quat_order=quat_order, name="a")
    pb, rb = as_pose(pos_b, rot_b, quat_order=quat_order, name="b")
    n, poses = broadcast_queries(pa, ra, pb, rb, cov_b, cov_a)
    covs = [None if c is None else np.asarray(c) for c in (cov_b, cov_a)]
    args = []
    for start in range(0, n, int(chunk_size)):
        stop = min(n, start + int(chunk_size))
        part = [x[start:stop] for x in poses]
        part += [c if c is None or c.ndim != 3 else c[start:stop] for c in covs]
        args.append((shape_a, shape_b, *part, seed, start, options))
    results = [None] * len(args)
    if scheduler is None and workers is None:
        for i, a in enumerate(args):
            results[i] = run_part(*a)
        execution = {"scheduler": "in-process"}
    else:
        from .cluster import run_tasks

        warm()  # compile (or load) in-process first: workers then load from the cache
        execution = run_tasks(
            run_part,
            args,
            lambda i, r: results.__setitem__(i, r),
            warm=(warm,),
            scheduler=scheduler,
            workers=workers,
            name="predict",
        )
    execution["chunks"] = len(args)
    first = results[0]
    return ProbabilityResult.concatenate(results, seed, first.confidence, first.rel_error), execution


def run_part(shape_a, shape_b, pos_a, rot_a, pos_b, rot_b, cov_b, cov_a, seed, start, options, threads=None):
    """One chunk: queries ``start ..`` of :func:`predict` (a Dask task; ``threads``: Numba threads)."""
    if threads is not None:
        from .validate import set_numba_threads

        set_numba_threads(threads)
    index = np.arange(start, start + len(pos_b))
    return collision_probability(
        shape_a, shape_b, pos_a, rot_a, pos_b, rot_b, cov_b, cov_a=cov_a, seed=seed, query_index=index, **options
    )


def warm():
    """Compile (or load from Numba's cache) the kernels :func:`predict` uses; returns the seconds taken."""
    import time

    from ..shapes import Prism

    t = time.perf_counter()
    a = b = Prism.regular(4, 1.0)
    cov = np.diag([0.0, 0.0, 0.01, 0.0, 0.0, 0.0])
    collision_probability(a, b, np.zeros(3), np.diag([1.0, -1.0, -1.0]), [0, 0, 0.2], np.eye(3), cov, seed=0)
    return time.perf_counter() - t
