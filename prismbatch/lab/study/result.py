"""What :func:`prismbatch.lab.study.run_study` returns: the :class:`StudyResult` record."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class StudyResult:
    """Everything :func:`run_study` measured.

    Attributes
    ----------
    settings : dict
        The arguments actually used (after ``quick`` defaults), seeds, scene.
    methods : dict
        Method key -> label with the library version (``"python-fcl 0.7.0.11"``).
    latency : list of dict
        One row per (case, vertices, method): ``median_us``, ``min_us``,
        ``q1_us``, ``q3_us``, ``max_us`` (wall-clock mean time per query of
        each repeat, µs), ``thread_cpu_median_us`` (the same from the calling
        thread's CPU time: a cross-check that ignores time lost to other
        processes), ``poses``, ``repeats``, ``hits`` (the method's hit
        count), ``other_cpus`` (CPUs kept busy by other processes while the
        cell was timed, from /proc/stat; None where unavailable).
    throughput : list of dict
        One row per (case or ``"all"``, vertices, mode): ``threads``,
        ``pairs`` per call, ``median_pairs_per_s``, ``min_pairs_per_s``,
        ``max_pairs_per_s``, ``repeats``.
    agreement : list of dict
        One row per (case, vertices, peer): ``disagreements``,
        ``pb_hit_peer_miss``, ``pb_miss_peer_hit``, ``touching_exact`` (pb hit
        on a pose built exactly touching), LP adjudication counts.
    missing : list of dict
        (vertices, case, reason) for cases casegen could not build.
    growth : list of dict
        Least-squares growth per (method, series): ``slope_us_per_1000``,
        ``intercept_us``, ``r2``, ``points``, ratios of slopes to the peers.
    table1 : list of dict
        Per case at ``settings["table_vertices"]``, then the average over the
        paper's cases: µs per query of each method (wall clock; ``*_cpu_us``:
        thread CPU time), ratios, the paper's numbers (µs) and ratio.
    compile : dict
        First-call seconds of each prismbatch path (excluded from timings).
    notes : list of str
        Skipped peers and other remarks.
    """

    settings: dict
    methods: dict
    latency: list
    throughput: list
    agreement: list
    missing: list
    growth: list
    table1: list
    compile: dict
    notes: list = field(default_factory=list)
    environment: dict = field(default_factory=dict)

    def latency_us(self, method, case, vertices, stat="median_us"):
        """``stat`` (default: median µs per query) of ``method`` for one cell, or None if not measured."""
        for r in self.latency:
            if r["method"] == method and r["case"] == case and r["vertices"] == vertices:
                return r[stat]
        return None
