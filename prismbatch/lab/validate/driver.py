"""The validation run: check the options, cut the blocks into chunks, run them, merge.

Chunks run in-process or on Dask (:mod:`prismbatch.lab.cluster`); either way the merged
result is the same (``docs/methods/validation.md``).
"""

from __future__ import annotations

import time

from ..checkpoint import Checkpoint, Interrupted
from ..checks import is_int
from .blocks import run_chunk, warm
from .config import block_len, make_config, n_blocks
from .distance import distance_block_len, n_distance_blocks
from .merge import Merger, ValidationResult


def _chunk_specs(cfg, chunk_size):
    per = max(1, int(round(chunk_size / cfg["block_size"])))
    nb = n_blocks(cfg)
    specs = [(d, first, min(per, nb - first)) for d in cfg["distributions"] for first in range(0, nb, per)]
    # the distance section: one block a chunk (each costs seconds), after the pairs
    return specs + [("distance", b, 1) for b in range(n_distance_blocks(cfg))]


def _spec_pairs(cfg, spec):
    d, first, n = spec
    if d == "distance":
        return sum(distance_block_len(cfg, b) for b in range(first, first + n))
    return sum(block_len(cfg, b) for b in range(first, first + n))


def _check_run_options(chunk_size, stiff, workers, scheduler):
    if not is_int(chunk_size) or chunk_size < 1:
        raise ValueError(f"chunk_size must be an integer >= 1, got {chunk_size!r}")
    if stiff not in (False, True, "quick"):
        raise ValueError(f"stiff must be True, False or 'quick', got {stiff!r}")
    if workers is not None and (not is_int(workers) or workers < 1):
        raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
    if scheduler is not None and not isinstance(scheduler, str):
        raise TypeError(f"scheduler must be an address string such as 'tcp://host:8786', got {scheduler!r}")


def _require_extras(cfg):
    """Fail early on missing extras, not after an hour of work."""
    if cfg["lp_samples"] > 0 or cfg["fcl_fraction"] > 0:  # the LP also arbitrates FCL disagreements
        from ..exact import import_linprog

        import_linprog()
    if cfg["fcl_fraction"] > 0:
        from ..peers import import_fcl

        import_fcl()
    if cfg["distance_pairs"] > 0:  # the reference's QP cross-check
        from ..highs import import_highspy

        import_highspy()


def _unit(spec):
    d, first, n = spec
    return f"{d}-{first}-{n}"


def _run_chunks(cfg, specs, merger, scheduler, workers, progress, ckpt):
    """Run every chunk (in-process or on Dask) into ``merger``; returns the execution dict.

    With a checkpoint, chunks it holds are loaded instead of run and each new chunk is saved
    as soon as it is finished.
    """
    from ..report import numba_threads
    from ..report import progress as _progress

    total = cfg["n_pairs"] * len(cfg["distributions"]) + cfg["distance_pairs"]
    with _progress(total, enabled=progress, unit="pair", desc="validate") as bar:

        def done(spec, chunk, loaded=False):
            if ckpt is not None and not loaded:
                ckpt.save(_unit(spec), chunk)
            merger.add(chunk)
            bar.update(_spec_pairs(cfg, spec))

        todo = []
        for spec in specs:
            chunk = ckpt.load(_unit(spec)) if ckpt is not None else None
            if chunk is None:
                todo.append(spec)
            else:
                done(spec, chunk, loaded=True)
        if scheduler is None and workers is None:
            execution = {"scheduler": "in-process", "workers": 1, "numba_threads": numba_threads()}
            for spec in todo:
                done(spec, run_chunk(cfg, *spec))
        else:
            from ..cluster import run_chunks

            execution = run_chunks(cfg, todo, done, scheduler=scheduler, workers=workers)
    execution["chunks_resumed"] = len(specs) - len(todo)
    return execution


def validate(
    n_pairs=100_000,
    *,
    distributions=("facing", "free", "near-contact", "degenerate"),
    shapes="regular",
    vertices=(36, 360),
    seed=0,
    chunk_size=50_000,
    dtype="float64",
    rtol=None,
    atol=0.0,
    fcl=True,
    lp_samples=2000,
    contact_check=True,
    max_band_records=1000,
    distance_pairs=None,
    distance_vertices=(3, 36),
    stiff=False,
    scheduler=None,
    workers=None,
    progress=True,
    checkpoint_dir=None,
    resume=False,
):
    """Monte Carlo validation of prismbatch against python-fcl and the exact LP.

    Parameters
    ----------
    n_pairs : int, optional
        Pose pairs PER DISTRIBUTION (default 100,000). Processed in chunks
        of blocks: memory stays bounded for any ``n_pairs``.
    distributions : sequence of str, optional
        Any of ``"facing"`` (the paper's scene), ``"free"`` (uniform
        rotations, centres in a box), ``"near-contact"`` (within 0.1 to 1e4
        tolerances of touching, both sides) and ``"degenerate"`` (exact cases
        2, 3, 4, 7, 8 from :func:`prismbatch.lab.casegen.case_poses`).
    shapes : str or sequence of str, optional
        ``"regular"``, ``"random"`` (random convex polygons) or
        ``"cylinder"`` (circles fitted by circumscribed n-gons); a sequence is
        cycled over the blocks. Each block draws its own two shapes.
    vertices : int or sequence of int, optional
        Vertex counts, cycled over the blocks (a: ``vertices[i]``, b:
        ``vertices[i + 1]``, modulo the length).
    seed : int, optional
        The one seed; block ``i`` of distribution ``j`` uses
        ``SeedSequence(seed, spawn_key=(j, i))``.
    chunk_size : int, optional
        Pairs per chunk (rounded to whole blocks of :data:`BLOCK_SIZE`); does
        not change the results.
    dtype : {"float64", "float32"}, optional
        prismbatch's precision (poses are rounded to it for every method).
    rtol, atol : float, optional
        prismbatch's tolerances (default rtol per dtype, atol 0).
    fcl : bool or float, optional
        python-fcl on every pair (True, 6-50 us per pair), none (False) or
        on a random fraction in (0, 1] (for runs well above 1e6 pairs).
    lp_samples : int, optional
        Pairs per distribution on which the exact LP runs (milliseconds
        each), spread over the blocks; the LP also runs on every pair where
        prismbatch and FCL disagree.
    contact_check : bool, optional
        Compute contacts and check every hit's contact against both bodies.
    max_band_records : int, optional
        "inside band" records kept (the first ones in block order; they are
        allowed and plentiful near contact). Every other record is kept; all
        are counted.
    distance_pairs : int, optional
        Pairs of the distance section (default: the smaller of 1,000 and
        ``n_pairs``; 0: no section): prismbatch's signed distance, its witness
        points and its sign against ``collide``, and coal's distance when
        installed, against the exact reference, per distance bucket
        (``docs/methods/validation.md``). Milliseconds a pair for 3- and
        36-gons, a second for two 360-gons (the reference visits every pair
        of edges).
    distance_vertices : int or sequence of int, optional
        Vertex counts of the distance section, cycled over its blocks like
        ``vertices`` (default 3 and 36); its shape kinds are ``shapes``.
    stiff : bool or "quick", optional
        Also run ``prismbatch.lab.stiff.run_stiff_suite`` (in-process).
    scheduler : str, optional
        Address of an existing Dask scheduler to send chunks to.
    workers : int, optional
        Start a local Dask cluster with this many worker processes (when no
        ``scheduler`` is given). Without either, runs in-process.
    progress : bool, optional
        Progress bar over pairs (tqdm, when installed).
    checkpoint_dir : str or path-like, optional
        Save every finished chunk under ``checkpoint_dir/checkpoint/validate``
        (:class:`~prismbatch.lab.checkpoint.Checkpoint`); :func:`write_validation`
        removes it once the report is written.
    resume : bool, optional
        With ``checkpoint_dir``: load the chunks an earlier run with the same
        settings finished there; the counts equal an uninterrupted run's.

    Returns
    -------
    ValidationResult

    Raises
    ------
    ValueError, TypeError
        Bad arguments (the message names the argument).
    ImportError
        A needed optional dependency is missing (scipy for the LP,
        python-fcl, dask); the message names the extra to install.
    prismbatch.lab.checkpoint.Interrupted
        SIGINT (or SIGTERM, turned into SIGINT by the CLI) during the run; its
        ``result`` is the partial :class:`ValidationResult` of the chunks finished.
    """
    cfg = make_config(
        n_pairs,
        distributions=distributions,
        shapes=shapes,
        vertices=vertices,
        seed=seed,
        dtype=dtype,
        rtol=rtol,
        atol=atol,
        fcl=fcl,
        lp_samples=lp_samples,
        contact_check=contact_check,
        max_band_records=max_band_records,
        distance_pairs=distance_pairs,
        distance_vertices=distance_vertices,
    )
    _check_run_options(chunk_size, stiff, workers, scheduler)
    _require_extras(cfg)
    t_start = time.perf_counter()
    compile_time = warm(cfg["dtype"])
    specs = _chunk_specs(cfg, chunk_size)
    ckpt = None
    if checkpoint_dir is not None:
        ckpt = Checkpoint(checkpoint_dir, "validate", {**cfg, "chunk_size": chunk_size}, resume=resume)
    merger = Merger(cfg)

    def result(execution, rep=None, partial=None):
        wall = time.perf_counter() - t_start  # the Monte Carlo run; the stiff suite reports its own time
        pairs = merger.distance.pairs()
        dist = None if pairs is None else {"pairs": pairs, "times": merger.distance.times}
        return ValidationResult(
            cfg,
            merger.counts,
            merger.times,
            merger.records,
            merger.total,
            compile_time,
            wall,
            execution,
            rep,
            partial=partial,
            checkpoint=ckpt,
            distance=dist,
        )

    try:
        execution = _run_chunks(cfg, specs, merger, scheduler, workers, progress, ckpt)
    except KeyboardInterrupt:
        done = sum(c["pairs"] for c in merger.counts.values())
        total = cfg["n_pairs"] * len(cfg["distributions"])
        dist = merger.distance.pairs()
        partial = {
            "pairs_done": done,
            "pairs_total": total,
            "distance_pairs_done": 0 if dist is None else len(dist["pb"]),
            "distance_pairs_total": cfg["distance_pairs"],
        }
        exc = Interrupted(done + partial["distance_pairs_done"], total + cfg["distance_pairs"], "pair", checkpoint=ckpt)
        exc.result = result({"scheduler": "interrupted"}, partial=partial)
        raise exc from None
    res = result(execution)
    if stiff:
        from ..stiff import run_stiff_suite

        res.stiff = run_stiff_suite(quick=stiff == "quick", seed=cfg["seed"], progress=progress)
    return res
