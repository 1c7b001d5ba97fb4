"""Agreement of the peers' hit flags with prismbatch's on the timed poses, with LP adjudication."""

from __future__ import annotations

import importlib.util

import numpy as np

from ...geometry import pair_scale_tolerance
from ..casegen import EXACT_CASES


def adjudicate(a, b, poses, idx, pb_hit, limit, rtol):
    """Judge up to ``limit`` disagreeing poses with the exact LP margin.

    Parameters
    ----------
    a, b : Prism
    poses : tuple of numpy.ndarray
        ``(pos_a, rot_a, pos_b, rot_b)`` of all poses of the cell.
    idx : numpy.ndarray of int
        Indices of the disagreeing poses (the first ``limit`` are checked).
    pb_hit : numpy.ndarray of bool
        prismbatch's hit flags for all poses.
    limit : int
    rtol : float
        The Collider's relative tolerance (atol 0, float64, as the study's Collider).

    Returns
    -------
    checked, touching, pb_right, pb_wrong : int or None
        All None when scipy is not installed.
    """
    if importlib.util.find_spec("scipy") is None:  # exact imports scipy only when solving
        return None, None, None, None
    from ..exact import lp_trust_band, margin_lp

    idx = idx[:limit]
    S, tol = pair_scale_tolerance(a, b, *(p[idx] for p in poses), rtol=rtol)
    band = lp_trust_band(tol, S)
    touching = right = wrong = 0
    for j, k in enumerate(idx):
        m = margin_lp(a.xy, poses[0][k], poses[1][k], b.xy, poses[2][k], poses[3][k])
        if abs(m) <= band[j]:
            touching += 1
        elif (m > 0) == bool(pb_hit[k]):
            right += 1
        else:
            wrong += 1
    return len(idx), touching, right, wrong


def agreement_rows(a, b, P, hits, peers, case, n, lp_checks, rtol):
    """One agreement row per peer of one (case, n) cell; ``hits`` maps method keys to hit flags."""
    ref = hits["prismbatch"]
    m = len(P[0])
    rows = []
    for name in peers:
        h = hits[name]
        idx = np.flatnonzero(h != ref)
        pb_hit_miss = int(np.count_nonzero(ref[idx]))
        exact_touch = pb_hit_miss if case in EXACT_CASES else 0
        # Exact touching hits are explained by construction; adjudicate the rest.
        rest = idx if case not in EXACT_CASES else idx[~ref[idx]]
        chk = (
            adjudicate(a, b, P, rest, ref, lp_checks, rtol)
            if (lp_checks and rest.size)
            else ((0, 0, 0, 0) if lp_checks else (None, None, None, None))
        )
        rows.append(
            {
                "case": case,
                "vertices": n,
                "peer": name,
                "poses": m,
                "pb_hits": int(ref.sum()),
                "peer_hits": int(h.sum()),
                "disagreements": int(idx.size),
                "pb_hit_peer_miss": pb_hit_miss,
                "pb_miss_peer_hit": int(idx.size) - pb_hit_miss,
                "touching_exact": exact_touch,
                "other": int(rest.size),
                "lp_checked": chk[0],
                "lp_touching": chk[1],
                "lp_pb_right": chk[2],
                "lp_pb_wrong": chk[3],
            }
        )
    return rows
