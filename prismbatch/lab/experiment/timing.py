"""Timing replays of a recorded trajectory: per-sample calls, one batched call, python-fcl.

See docs/methods/experiment.md.
"""

from __future__ import annotations

import time

import numpy as np

from ..timing import best_of
from .model import batch_poses


def _fcl_replay(res, shape_a, shape_b, repeats):
    """The same poses through python-fcl on finite stand-ins (raises ImportError without it)."""
    from ..peers import FCLPeer, standin_length

    g = res.geometry
    out = {}
    L = standin_length(shape_a.xy, shape_b.xy, g["pos_a"], g["rot_a"], res.dc, g["rot_b"])
    t0 = time.perf_counter()
    peer = FCLPeer(shape_a.xy, shape_b.xy, L)
    out["fcl_build_s"] = time.perf_counter() - t0
    items = peer.prepare(g["pos_a"], g["rot_a"], res.dc, g["rot_b"])
    best, h = best_of(repeats, lambda: peer.run(items))
    out["fcl_ms"] = 1e3 * best
    out["fcl_standin_length_mm"] = float(L)
    out["fcl_hits"] = int(h.sum())
    out["fcl_disagreements"] = int((h != res.hit).sum())
    out["fcl_disagreement_s"] = [float(x) for x in res.t[h != res.hit]]
    return out


def replay_timing(res, col, shape_a, shape_b, *, fcl, repeats):
    """Replay the recorded poses: one collide_pair call per sample, one batched call, python-fcl.

    Parameters
    ----------
    res : ExperimentResult
        The run whose poses (``res.dc``) are replayed.
    col : prismbatch.Collider
        The run's collider (compiled).
    shape_a, shape_b : prismbatch.Prism
        The run's shapes (for the python-fcl stand-ins).
    fcl : bool
        Include python-fcl (a note instead when it is not installed).
    repeats : int
        Each replay is repeated this many times; the fastest counts.

    Returns
    -------
    dict
        ``pair_ms``, ``batch_ms``, ``batch_agrees_with_loop``, ``fcl_ms`` (None
        without python-fcl) and the python-fcl details or ``fcl_note``.
    """
    g = res.geometry
    pa1, ra1, rb1 = batch_poses(g)
    poses = [np.ascontiguousarray(p) for p in res.dc]
    pa, ra, rb = g["pos_a"], g["rot_a"], g["rot_b"]

    def pair_loop():
        for p in poses:
            col.collide_pair(pa, ra, p, rb)

    out = {}
    out["pair_ms"] = 1e3 * best_of(repeats, pair_loop)[0]
    allp = np.ascontiguousarray(res.dc)
    col.collide(pa1, ra1, allp[:2], rb1, parallel=False)  # the same kernel, warm
    best, rb_ = best_of(repeats, lambda: col.collide(pa1, ra1, allp, rb1, parallel=False))
    out["batch_ms"] = 1e3 * best
    out["batch_agrees_with_loop"] = bool(np.array_equal(rb_.hit, res.hit) and np.array_equal(rb_.case, res.case))
    out["fcl_ms"] = None
    if fcl:
        try:
            out.update(_fcl_replay(res, shape_a, shape_b, repeats))
        except ImportError as exc:
            out["fcl_note"] = str(exc)
    return out
