"""One block of the validation, step by step: prismbatch (and its contacts), FCL, the LP.

:func:`run_chunk` (a range of blocks) is the unit of work sent to Dask workers and
:func:`warm` loads the kernels a worker needs; :mod:`.arbitrate` decides who is wrong.
"""

from __future__ import annotations

import time

import numpy as np

from ...collide import Collider
from ...geometry import pair_scale_tolerance
from ...shapes import Prism
from ..exact import lp_trust_band
from .arbitrate import Verdicts, arbitrate, check_standins, make_records
from .config import DISTRIBUTION_NAMES, n_blocks
from .generate import generate_block
from .merge import empty_counts, empty_times


def pair_scale_tol(cfg, sa, sb, pos_a, rot_a, pos_b, rot_b):
    """Per pair: scene scale S, prismbatch's tolerance and the touching band.

    The band is :func:`~prismbatch.lab.exact.lp_trust_band`.
    """
    S, tol = pair_scale_tolerance(
        sa, sb, pos_a, rot_a, pos_b, rot_b, rtol=cfg["rtol"], atol=cfg["atol"], dtype=cfg["dtype"]
    )
    return S, tol, lp_trust_band(tol, S)


def residuals(shape, pos, rot, x):
    """Point-in-prism residual of points x (m, 3) for one shape at m poses (vectorised).

    Parameters
    ----------
    shape : Prism
        The body's end face.
    pos, rot : ndarray
        (m, 3) positions and (m, 3, 3) rotations of the body.
    x : ndarray
        (m, 3) points, one per pose.

    Returns
    -------
    ndarray
        (m,) largest violated half-space per point (<= 0 inside the body).
    """
    from ..exact import polygon_halfplanes

    n2, h = polygon_halfplanes(shape.xy)
    local = np.einsum("mji,mj->mi", rot, x - pos)  # R^T (x - p)
    out = -local[:, 2]
    step = max(1, 2_000_000 // len(h))
    for s in range(0, len(x), step):
        side = local[s : s + step, :2] @ n2.T - h
        out[s : s + step] = np.maximum(out[s : s + step], side.max(axis=1))
    return out


def _poses(blk):
    return blk.pos_a, blk.rot_a, blk.pos_b, blk.rot_b


def _check_contacts(cfg, blk, hit, contact, tol, c, verdicts):
    """Every hit's contact against both bodies: residual <= 2 tol + 4 eps |x|, and finite."""
    hi = np.flatnonzero(hit)
    finite = np.isfinite(contact[hi]).all(axis=1)
    for k in hi[~finite]:
        verdicts.flag(k, "non-finite")
    c["nonfinite"] = int((~finite).sum())
    ok = hi[finite]
    if ok.size:
        x = contact[ok]
        res = np.maximum(
            residuals(blk.shape_a, blk.pos_a[ok], blk.rot_a[ok], x),
            residuals(blk.shape_b, blk.pos_b[ok], blk.rot_b[ok], x),
        )
        eps = float(np.finfo(np.dtype(cfg["dtype"])).eps)
        bound = 2 * tol[ok] + 4 * eps * np.linalg.norm(x, axis=1)
        bad = res > bound
        for k in ok[bad]:
            verdicts.flag(k, "invalid contact")
        c["contact_checked"] = int(ok.size)
        c["contact_invalid"] = int(bad.sum())
        c["contact_max_ratio"] = float(np.max(res / tol[ok]))


def _run_prismbatch(cfg, blk, tol, threads, c, times, verdicts):
    """prismbatch: status only (timed like FCL), then with contacts; returns (hit, case, contact)."""
    parallel = None if threads is None else threads > 1
    col = Collider(blk.shape_a, blk.shape_b, rtol=cfg["rtol"], atol=cfg["atol"], dtype=cfg["dtype"])
    # prismbatch gets the poses in its own dtype (its orthonormality check depends on it)
    Pc = tuple(np.ascontiguousarray(x, dtype=cfg["dtype"]) for x in _poses(blk))
    t = time.perf_counter()
    r = col.collide(*Pc, parallel=parallel)
    times["pb"] = time.perf_counter() - t
    hit, case = r.hit.copy(), r.case.astype(np.int64)
    bad_case = (case < 1) | (case > 11)
    c["bad_case"] = int(bad_case.sum())
    case = np.where(bad_case, 0, case)
    contact = None
    if cfg["contact_check"]:
        t = time.perf_counter()
        rc = col.collide(*Pc, contact=True, parallel=parallel)
        times["pb_contact"] = time.perf_counter() - t
        contact = np.asarray(rc.contact, dtype=np.float64)
        c["status_mismatch"] = int(np.sum((rc.hit != r.hit) | (rc.case != r.case)))
        t = time.perf_counter()
        _check_contacts(cfg, blk, hit, contact, tol, c, verdicts)
        times["check"] = time.perf_counter() - t
    np.add.at(c["pairs_case"], case, 1)
    np.add.at(c["hits_case"], case[hit], 1)
    c["pairs"], c["hits"] = len(hit), int(hit.sum())
    return hit, case, contact


def _run_fcl(cfg, blk, length, sound, hit, case, c, times):
    """python-fcl on all pairs or a subsample, on stand-ins of ``length``; returns (fidx, fcl_hit).

    ``fcl_hit`` is -1 where FCL did not run, else 0 or 1.
    """
    m = len(hit)
    fcl_hit = np.full(m, -1, np.int8)
    sel = blk.rngs[0].random(m) < cfg["fcl_fraction"] if cfg["fcl_fraction"] < 1.0 else np.ones(m, bool)
    fidx = np.flatnonzero(sel) if cfg["fcl_fraction"] > 0.0 else np.zeros(0, np.int64)
    if fidx.size:
        from ..peers import FCLPeer

        P = _poses(blk)
        for L in np.unique(length[fidx]):  # one FCL object pair per stand-in length
            grp = fidx[length[fidx] == L]
            t = time.perf_counter()
            peer = FCLPeer(blk.shape_a.xy, blk.shape_b.xy, float(L))
            items = peer.prepare(*(x[grp] for x in P))
            times["fcl_setup"] += time.perf_counter() - t
            t = time.perf_counter()
            fcl_hit[grp] = peer.run(items)
            times["fcl"] += time.perf_counter() - t
        times["fcl_pairs"] = int(fidx.size)
        c["fcl_pairs"] = int(fidx.size)
        c["standin_unsound"] = int((~sound[fidx]).sum())
        np.add.at(c["fcl_conf"], (case[fidx], hit[fidx].astype(int), fcl_hit[fidx].astype(int)), 1)
    return fidx, fcl_hit


def _run_lp(cfg, blk, length, band, hit, fidx, fcl_hit, c, times):
    """The LP on a random subsample (the block's share of lp_samples) and every FCL disagreement.

    Returns ``(lp_idx, dis, lp, lp_fin)``: subsample and disagreement indices, and (m,)
    margins of the semi-infinite bodies and of their stand-ins (NaN where not computed).
    """
    from ..exact import margin_lp

    m, block = len(hit), blk.block
    nb = n_blocks(cfg)
    share = min(m, (block + 1) * cfg["lp_samples"] // nb - block * cfg["lp_samples"] // nb)
    lp_idx = np.sort(blk.rngs[1].choice(m, share, replace=False)) if share else np.zeros(0, np.int64)
    dis = fidx[hit[fidx] != fcl_hit[fidx].astype(bool)]
    todo = np.union1d(lp_idx, dis)
    lp = np.full(m, np.nan)
    lp_fin = np.full(m, np.nan)
    xa, xb = blk.shape_a.xy, blk.shape_b.xy
    for k in todo:
        t = time.perf_counter()
        try:
            lp[k] = margin_lp(xa, blk.pos_a[k], blk.rot_a[k], xb, blk.pos_b[k], blk.rot_b[k])
            if cfg["fcl_fraction"] > 0.0 and lp[k] > -band[k]:
                # stand-in check; below -band the stand-ins (subsets) are separated too
                lp_fin[k] = margin_lp(
                    xa,
                    blk.pos_a[k],
                    blk.rot_a[k],
                    xb,
                    blk.pos_b[k],
                    blk.rot_b[k],
                    length_a=length[k],
                    length_b=length[k],
                )
                times["lp_calls"] += 1
        except RuntimeError:
            c["lp_failed"] += 1
        times["lp"] += time.perf_counter() - t
        times["lp_calls"] += 1
    c["lp_pairs"], c["lp_arbitration"] = int(lp_idx.size), int(np.setdiff1d(dis, lp_idx).size)
    return lp_idx, dis, lp, lp_fin


def process_block(cfg, distribution, block, threads=None):
    """Generate and check one block; returns ``(key, counts, times, records)``."""
    from ..peers import standin_lengths

    times = empty_times()
    t0 = time.perf_counter()
    blk = generate_block(cfg, distribution, block)
    times["gen"] = time.perf_counter() - t0
    c = empty_counts()
    for k, v in blk.notes.items():
        c[k] += int(v)
    P = _poses(blk)
    S, tol, band = pair_scale_tol(cfg, blk.shape_a, blk.shape_b, *P)
    verdicts = Verdicts()
    hit, case, contact = _run_prismbatch(cfg, blk, tol, threads, c, times, verdicts)
    # stand-in lengths (power of two >= the rule: FCL objects reused within the block)
    sl = standin_lengths(blk.shape_a.xy, blk.shape_b.xy, *P)
    length = 2.0 ** np.ceil(np.log2(sl.length))
    fidx, fcl_hit = _run_fcl(cfg, blk, length, sl.sound, hit, case, c, times)
    lp_idx, dis, lp, lp_fin = _run_lp(cfg, blk, length, band, hit, fidx, fcl_hit, c, times)
    short = check_standins(lp, lp_fin, band, S, c)
    arbitrate(blk, tol, band, hit, case, lp_idx, dis, lp, short, c, verdicts)
    records = make_records(
        cfg,
        blk,
        verdicts,
        S=S,
        tol=tol,
        band=band,
        hit=hit,
        case=case,
        contact=contact,
        fcl_hit=fcl_hit,
        length=length,
        lp=lp,
        lp_fin=lp_fin,
    )
    return (DISTRIBUTION_NAMES.index(distribution), block), c, times, records


def run_chunk(config, distribution, first_block, n_blocks, threads=None):
    """Run blocks ``first_block .. first_block + n_blocks - 1`` of one distribution.

    The unit of work sent to Dask workers: its arguments are the settings and
    a block range, never arrays.

    Parameters
    ----------
    config : dict
        From :func:`make_config`.
    distribution : str
        Distribution name, or ``"distance"`` for blocks of the distance section.
    first_block, n_blocks : int
        Block range.
    threads : int or None, optional
        Numba threads for this task (set with ``numba.set_num_threads``,
        which is per calling thread); None keeps the current setting.

    Returns
    -------
    list of tuple
        One ``(key, counts, times, records)`` per block, in block order.
    """
    if threads is not None:
        set_numba_threads(threads)
    if distribution == "distance":  # the distance section's blocks (.distance)
        from .distance import process_distance_block

        return [process_distance_block(config, b) for b in range(first_block, first_block + n_blocks)]
    return [process_block(config, distribution, b, threads) for b in range(first_block, first_block + n_blocks)]


def set_numba_threads(k):
    """Set the calling thread's Numba thread count to ``k``, clamped to ``[1, NUMBA_NUM_THREADS]``.

    ``numba.set_num_threads`` applies to the calling thread only: Dask workers
    call it once (:func:`prismbatch.lab.cluster.run_chunks`) and every chunk
    task again (:func:`run_chunk`).

    Parameters
    ----------
    k : int
        Requested number of threads.

    Returns
    -------
    int
        The thread count now in effect.
    """
    import numba

    numba.set_num_threads(max(1, min(int(k), numba.config.NUMBA_NUM_THREADS)))
    return numba.get_num_threads()


def warm(dtype):
    """Compile (or load from the on-disk cache) the kernels a validation run uses.

    Called in-process before a run (its time is reported as the compile time)
    and on each Dask worker before chunks are submitted
    (:func:`prismbatch.lab.cluster.run_chunks`).

    Parameters
    ----------
    dtype : str or numpy.dtype
        prismbatch's precision for the run; float64 is always warmed too
        (pose generation uses it).

    Returns
    -------
    float
        Seconds taken.
    """
    t = time.perf_counter()
    a, b = Prism.regular(5, 2.0), Prism.regular(6, 2.5)
    P = (
        np.zeros((2, 3)),
        np.broadcast_to(np.diag([1.0, -1.0, -1.0]), (2, 3, 3)).copy(),
        np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 0.0]]),
        np.broadcast_to(np.eye(3), (2, 3, 3)).copy(),
    )
    for dt in {np.dtype(dtype), np.dtype(np.float64)}:  # generation uses float64
        col = Collider(a, b, dtype=dt)
        for contact in (False, True):
            for par in (False, True):
                col.collide(*P, contact=contact, parallel=par)
    return time.perf_counter() - t
