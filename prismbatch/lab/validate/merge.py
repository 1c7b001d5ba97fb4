"""Block counters and their merge into a :class:`ValidationResult`, in block order.

Merged counts and records do not depend on the chunk size, the worker count or the order in
which chunks finish (``docs/methods/validation.md``, Reproducibility).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .config import CASE_COUNTERS, DISTRIBUTION_NAMES, INT_COUNTERS, MAX_COUNTERS, NC, TIMES
from .distance import DISTANCE_KEY, DistanceMerger, failures


def empty_counts():
    """Zeroed counters of one block or distribution (see ``ValidationResult.counts``)."""
    c = {k: np.zeros(NC, np.int64) for k in CASE_COUNTERS}
    c["fcl_conf"] = np.zeros((NC, 2, 2), np.int64)
    c["lp_conf"] = np.zeros((NC, 2, 2), np.int64)
    c.update({k: 0 for k in INT_COUNTERS})
    c.update({k: 0.0 for k in MAX_COUNTERS})
    return c


def empty_times():
    """Zeroed timings of one block or distribution (see ``ValidationResult.times``)."""
    return {**dict.fromkeys(TIMES, 0.0), "fcl_pairs": 0, "lp_calls": 0}


def merge_counts(acc, c):
    """Add counters ``c`` into ``acc`` (maxima for the ``*_max_*`` ones); returns ``acc``."""
    for k, v in c.items():
        if k in MAX_COUNTERS:
            acc[k] = max(acc[k], v)
        else:
            acc[k] = acc[k] + v
    return acc


@dataclass
class ValidationResult:
    """Merged outcome of :func:`validate`.

    Attributes
    ----------
    config : dict
        The settings (:func:`make_config`).
    counts : dict
        Per distribution, the counters: ``pairs``, ``hits``; per case (arrays
        indexed by case number 0-11, 0 unused) ``pairs_case``, ``hits_case``;
        ``fcl_conf`` / ``lp_conf`` (12, 2, 2) confusion counts indexed
        ``[case, prismbatch hit, reference hit]``; FCL disagreements
        ``fcl_in_band``, ``fcl_out_pb`` (prismbatch wrong outside the band),
        ``fcl_out_fcl`` (FCL wrong, stand-in long enough),
        ``fcl_standin_short``, ``fcl_unarbitrated``; LP subsample
        ``lp_band`` (pairs inside the band), ``lp_in_band``, ``lp_out``
        (disagreements); ``standin_checked``, ``standin_short``,
        ``standin_unsound``, ``standin_max_dev`` (max of
        ``|finite - semi-infinite LP margin| / S`` where the bodies meet); ``contact_checked``,
        ``contact_invalid``, ``contact_max_ratio`` (max residual / tol),
        ``nonfinite``, ``bad_case``, ``status_mismatch``.
    times : dict
        Per distribution, seconds: ``pb`` (status batches, compile excluded),
        ``pb_contact``, ``fcl`` (queries), ``fcl_setup``, ``lp`` and the
        numbers ``fcl_pairs``, ``lp_calls``.
    records : list of dict
        Disagreements (see :data:`RECORD_KINDS`) in (distribution, block,
        index) order; "inside band" ones capped at
        ``config["max_band_records"]``.
    records_total : int
        Number of records before the cap.
    compile_time : float
        Seconds of the first (compiling or cache-loading) calls, in-process.
    wall_time : float
        Seconds of the Monte Carlo run (compile included; the stiff suite,
        when requested, reports its own time).
    execution : dict
        Scheduler, workers and thread counts.
    stiff : object or None
        The stiff suite's report (``prismbatch.lab.stiff``) when requested.
    partial : dict or None
        For a run stopped early: ``pairs_done`` and ``pairs_total`` (collision pairs), and
        ``distance_pairs_done`` and ``distance_pairs_total`` (the signed-distance section).
    checkpoint : Checkpoint or None
        Where finished chunks were saved (removed once the full report is written).
    distance : dict or None
        The distance section: ``pairs`` (per-pair arrays, :data:`.distance.PAIR_FIELDS`, in
        block order) and ``times`` (per bucket: seconds of prismbatch and coal, pairs); None
        when it did not run.
    """

    config: dict
    counts: dict
    times: dict
    records: list
    records_total: int
    compile_time: float
    wall_time: float
    execution: dict
    stiff: object = None
    partial: dict = None
    checkpoint: object = None
    distance: dict = None

    def distance_failures(self):
        """Pairs of the distance section beyond 10 tol, with witnesses off, the sign against collide
        wrong or a reference gap left unconfirmed (0 without the section)."""
        return 0 if self.distance is None else int(failures(self.distance["pairs"]).sum())

    def totals(self):
        """Counters summed over the distributions."""
        acc = empty_counts()
        for c in self.counts.values():
            merge_counts(acc, c)
        return acc

    @property
    def ok(self):
        """True when prismbatch has no disagreement outside the band (nor an unarbitrated one), no
        invalid contact, no non-finite or invalid output and no failure of the distance section
        (the stiff suite reports its own)."""
        t = self.totals()
        return (
            int(t["fcl_out_pb"].sum()) == 0
            and int(t["lp_out"].sum()) == 0
            and t["exact_wrong"] == 0
            and int(t["fcl_unarbitrated"].sum()) == 0
            and t["contact_invalid"] == 0
            and t["nonfinite"] == 0
            and t["bad_case"] == 0
            and t["status_mismatch"] == 0
            and self.distance_failures() == 0
        )

    def outcome(self):
        """Everything that must not depend on chunking or workers (no timings)."""
        nan_free = lambda v: [None if x != x else x for x in v.tolist()]  # noqa: E731 (NaN != NaN)
        dist = None if self.distance is None else {k: nan_free(v) for k, v in self.distance["pairs"].items()}
        return {
            "distance": dist,
            "config": self.config,
            "records_total": self.records_total,
            "records": self.records,
            "counts": {
                d: {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in c.items()}
                for d, c in self.counts.items()
            },
        }


class Merger:
    """Accumulates block results in block order, whatever order chunks arrive in."""

    def __init__(self, cfg):
        self.cfg = cfg
        self.counts = {d: empty_counts() for d in cfg["distributions"]}
        self.times = {d: empty_times() for d in cfg["distributions"]}
        self.records = []
        self.total = 0
        self.band_total = 0
        self.distance = DistanceMerger()

    def add(self, chunk):
        """Merge one chunk: a list of ``(key, counts, times, records)`` per block (:func:`run_chunk`)."""
        new = []
        for key, c, t, recs in chunk:
            if key[0] == DISTANCE_KEY:
                self.distance.add(key[1], c, t)
                continue
            d = DISTRIBUTION_NAMES[key[0]]
            merge_counts(self.counts[d], c)
            for k, v in t.items():
                self.times[d][k] += v
            new.extend(recs)
            self.total += len(recs)
        order = lambda r: (r["spawn_key"][0], r["block"], r["index"])  # noqa: E731
        # Every record is kept except "inside band" ones (expected, and plenty near contact):
        # the first max_band_records of those in block order, the same set for any chunking.
        self.band_total += sum(r["kind"] == "inside band" for r in new)
        recs = sorted(self.records + new, key=order)
        band = [r for r in recs if r["kind"] == "inside band"][: self.cfg["max_band_records"]]
        keep = {id(r) for r in band}
        self.records = [r for r in recs if r["kind"] != "inside band" or id(r) in keep]
