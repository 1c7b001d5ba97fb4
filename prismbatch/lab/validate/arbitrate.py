"""Who is wrong, per pair: the LP within its trust band, the exact reference inside it, FCL.

The rules (touching band, stand-in check) are in ``docs/methods/validation.md``. The
functions here count into a block's counters and flag pairs in a :class:`Verdicts`, from
which :func:`make_records` builds the disagreement records.
"""

from __future__ import annotations

import math

import numpy as np

from .config import RECORD_KINDS


class Verdicts:
    """Per pair index: the record kinds flagged (``kinds``) and who is at fault (``fault``)."""

    def __init__(self):
        self.kinds = {}  # pair index -> list of record kinds
        self.fault = {}  # pair index -> who is at fault

    def flag(self, k, kind):
        """Add a record kind (one of :data:`RECORD_KINDS`) to pair ``k``."""
        self.kinds.setdefault(int(k), []).append(kind)


def check_standins(lp, lp_fin, band, S, c):
    """Stand-in check: pairs whose bodies overlap beyond the band but whose stand-ins do not.

    Returns the (m,) boolean "stand-in too short" mask; counts ``standin_*`` in ``c``.
    """
    chk = np.flatnonzero(np.isfinite(lp_fin))
    c["standin_checked"] = int(chk.size)
    short = np.zeros(len(lp), bool)
    short[chk] = (lp[chk] > band[chk]) & (lp_fin[chk] <= band[chk])
    c["standin_short"] = int(short.sum())
    meet = chk[lp[chk] > band[chk]]
    if meet.size:
        c["standin_max_dev"] = float(np.max(np.abs(lp_fin[meet] - lp[meet]) / S[meet]))
    return short


def exact_verdicts(blk, tol, idx, c):
    """Exact verdicts at tol ("hit", "miss", "band", "unknown") for pairs idx; counts them in c."""
    if not len(idx):
        return {}
    from ..exact_gap import judge_pair

    sa, sb = blk.shape_a, blk.shape_b
    out = {}
    for k in idx:
        v = judge_pair(sa.xy, blk.pos_a[k], blk.rot_a[k], sb.xy, blk.pos_b[k], blk.rot_b[k], tol[k]).verdict
        out[int(k)] = v
        c["exact_band"] += v == "band"
        c["exact_unknown"] += v == "unknown"
    c["exact_pairs"] += len(idx)
    return out


def _judge_lp_sample(lp_idx, lp, band, hit, case, c, verdicts):
    """LP subsample: confusion counts and disagreements (prismbatch wrong outside the band)."""
    ok = lp_idx[np.isfinite(lp[lp_idx])]
    truth = lp[ok] > 0
    np.add.at(c["lp_conf"], (case[ok], hit[ok].astype(int), truth.astype(int)), 1)
    inb = np.abs(lp[ok]) <= band[ok]
    np.add.at(c["lp_band"], case[ok[inb]], 1)
    wrong = hit[ok] != truth
    np.add.at(c["lp_in_band"], case[ok[wrong & inb]], 1)
    np.add.at(c["lp_out"], case[ok[wrong & ~inb]], 1)
    for k in ok[wrong & inb]:
        verdicts.flag(k, "inside band")
    for k in ok[wrong & ~inb]:
        verdicts.flag(k, "outside band")
        verdicts.fault[int(k)] = "prismbatch"


def _judge_exact(exact, hit, c, verdicts):
    """Pairs judged at tol by the exact reference: prismbatch wrong where it says hit or miss."""
    for k, verdict in exact.items():
        if (verdict == "hit") != bool(hit[k]) and verdict in ("hit", "miss"):
            c["exact_wrong"] += 1
            verdicts.flag(k, "outside band")
            verdicts.fault[int(k)] = "prismbatch (exact reference, at tol)"


def _judge_fcl(dis, lp, band, hit, case, short, exact, c, verdicts):
    """FCL disagreements, arbitrated by the LP (by the exact reference inside the LP's band)."""
    fault = verdicts.fault
    for k in dis:
        cs = case[k]
        if not np.isfinite(lp[k]):
            c["fcl_unarbitrated"][cs] += 1
            verdicts.flag(k, "outside band")
            fault.setdefault(int(k), "unknown (LP failed)")
        elif abs(lp[k]) <= band[k]:
            c["fcl_in_band"][cs] += 1
            if exact.get(int(k)) in ("hit", "miss") and (exact[int(k)] == "hit") == bool(hit[k]):
                fault.setdefault(int(k), "fcl (exact reference, at tol)")
            verdicts.flag(k, "inside band")
        elif hit[k] != (lp[k] > 0):
            c["fcl_out_pb"][cs] += 1
            verdicts.flag(k, "outside band")
            fault[int(k)] = "prismbatch"
        elif short[k]:
            c["fcl_standin_short"][cs] += 1
            verdicts.flag(k, "stand-in too short")
            fault.setdefault(int(k), "stand-in")
        else:
            c["fcl_out_fcl"][cs] += 1
            verdicts.flag(k, "outside band")
            fault.setdefault(int(k), "fcl")
    for k in np.flatnonzero(short):
        if k not in dis:  # FCL was right anyway (or not run on it): still a failed stand-in check
            verdicts.flag(k, "stand-in too short")
            fault.setdefault(int(k), "stand-in")


def arbitrate(blk, tol, band, hit, case, lp_idx, dis, lp, short, c, verdicts):
    """Decide who is wrong on every pair the LP ran on; counts into ``c``, flags into ``verdicts``.

    Parameters
    ----------
    blk : Block
        The block's inputs.
    tol, band : ndarray
        (m,) pair tolerance and touching band.
    hit, case : ndarray
        (m,) prismbatch's answers.
    lp_idx, dis : ndarray
        Indices of the LP subsample and of the FCL disagreements.
    lp : ndarray
        (m,) LP margins (NaN where not run or failed).
    short : ndarray
        (m,) "stand-in too short" mask (:func:`check_standins`).
    c : dict
        The block's counters.
    verdicts : Verdicts
        Flags and faults, filled in.
    """
    # The LP is not certain inside its band: there the exact reference judges
    # the pair at tol itself (gap <= tol must hit, gap > 2 tol must miss).
    ran = np.union1d(lp_idx, dis)
    exact = exact_verdicts(blk, tol, ran[np.abs(lp[ran]) <= band[ran]], c)
    _judge_lp_sample(lp_idx, lp, band, hit, case, c, verdicts)
    _judge_exact(exact, hit, c, verdicts)
    _judge_fcl(dis, lp, band, hit, case, short, exact, c, verdicts)


def _record(cfg, blk, k, kinds, *, tol, band, scale, hit, case, contact, fcl, length, lp, lp_fin, at_fault):
    """The replay record of pair ``k`` of a block: full inputs, every answer and the verdict."""
    kinds = sorted(set(kinds), key=RECORD_KINDS.index)
    f = lambda x: None if x is None or not math.isfinite(x) else float(x)  # noqa: E731
    return {
        "kind": kinds[0],
        "kinds": kinds,
        "at_fault": at_fault,
        "distribution": blk.distribution,
        "block": blk.block,
        "index": int(k),
        "seed": cfg["seed"],
        "spawn_key": list(blk.spawn_key),
        "shape_a": blk.shape_a.xy.tolist(),
        "shape_b": blk.shape_b.xy.tolist(),
        "pos_a": blk.pos_a[k].tolist(),
        "rot_a": blk.rot_a[k].tolist(),
        "pos_b": blk.pos_b[k].tolist(),
        "rot_b": blk.rot_b[k].tolist(),
        "dtype": cfg["dtype"],
        "rtol": cfg["rtol"],
        "atol": cfg["atol"],
        "tol": float(tol),
        "band": float(band),
        "scale": float(scale),
        "prismbatch": {
            "hit": bool(hit),
            "case": int(case),
            "contact": None if contact is None else [float(x) for x in contact],
        },
        "references": {
            "fcl": None if fcl is None else bool(fcl),
            "standin_length": f(length),
            "lp_margin": f(lp),
            "lp_margin_standin": f(lp_fin),
        },
    }


def make_records(cfg, blk, verdicts, *, S, tol, band, hit, case, contact, fcl_hit, length, lp, lp_fin):
    """The records of every flagged pair of a block, in index order."""
    return [
        _record(
            cfg,
            blk,
            k,
            verdicts.kinds[k],
            tol=tol[k],
            band=band[k],
            scale=S[k],
            hit=hit[k],
            case=case[k],
            contact=None if contact is None or not hit[k] else contact[k],
            fcl=None if fcl_hit[k] < 0 else bool(fcl_hit[k]),
            length=length[k] if fcl_hit[k] >= 0 else None,
            lp=lp[k],
            lp_fin=lp_fin[k],
            at_fault=verdicts.fault.get(k),
        )
        for k in sorted(verdicts.kinds)
    ]
