"""The study as text: the summary lines of :func:`format_study` and the Markdown page."""

from __future__ import annotations

import os
from pathlib import Path

from ..checkpoint import resumed_note
from ..report import fmt, pct
from .analysis import growth_model_text, growth_row
from .constants import PAPER_GROWTH_MS_PER_1000, PAPER_SOURCE, PAPER_TABLE_VERTICES


def format_study(res):
    """The study's summary as text lines (Table I, growth, throughput, agreement, compile).

    Parameters
    ----------
    res : StudyResult

    Returns
    -------
    list of str
    """
    s = res.settings
    L = [
        f"prismbatch timing study: regular n-gons of circumradius {s['radius_a']:g} (a) and {s['radius_b']:g} (b); "
        f"n = {', '.join(map(str, s['vertices']))}; cases {', '.join(map(str, s['cases']))}; "
        f"{s['poses_per_case']} poses per case (casegen, half hits), {s['repeats']} repeats after a warm-up; "
        f"seed {s['seed']}"
    ]
    L.append("methods: " + "; ".join(f"{k} = {v}" for k, v in res.methods.items()))
    L.append("")
    L += _table1_lines(res)
    L.append("")
    L += _growth_lines(res)
    L.append("")
    L += _throughput_lines(res)
    L.append("")
    L += _agreement_lines(res)
    L += _run_lines(res)
    return L


def _not_comparable(n):
    """The warning a Table I at another vertex count than the paper's needs (none at 3600)."""
    if n == PAPER_TABLE_VERTICES:
        return []
    return [
        f"Note: the paper's columns are its {PAPER_TABLE_VERTICES}-vertex figures; this table is at {n} vertices,",
        "so only the ratios within a row, not the numbers across the two, are comparable.",
        "",
    ]


def _table1_lines(res):
    L = [*_not_comparable(res.settings["table_vertices"])] + [
        f"Table I at {res.settings['table_vertices']} vertices: single-query latency, µs per query (median of "
        "repeats); paper in µs (ms x 1000)",
        f"{'case':>8} {'pb':>8} {'pb(b1)':>8} {'FCL':>8} {'coal':>8} {'pb/FCL':>8} {'pb/coal':>8}"
        f" | {'paper':>7} {'SWIFT':>7} {'pap/SW':>7} | disagree FCL/coal",
    ]
    for r in res.table1:
        if r["missing"]:
            L.append(f"{str(r['case']):>8}   missing (casegen could not build it)")
            continue
        L.append(
            f"{str(r['case']).replace('average ', 'avg '):>8} {fmt(r['prismbatch_us']):>8} "
            f"{fmt(r['prismbatch_batch1_us']):>8} {fmt(r['fcl_us']):>8} {fmt(r['coal_us']):>8} "
            f"{pct(r['pb_over_fcl']):>8} {pct(r['pb_over_coal']):>8} | {fmt(r['paper_projection_us']):>7} "
            f"{fmt(r['paper_swift_us']):>7} {pct(r['paper_ratio']):>7} | "
            f"{fmt(r['fcl_disagreements'], 'd')}/{fmt(r['coal_disagreements'], 'd')}"
        )
    return L


def _growth_lines(res):
    s = res.settings
    pg = PAPER_GROWTH_MS_PER_1000
    L = [
        f"Growth with n (average over cases {next((r['cases'] for r in res.growth if r['series'] == 'average'), '-')}; "
        f"n = {', '.join(map(str, s['vertices']))}): the factor from the smallest to the largest n, and the model "
        "that fits better, a line t = a + b n or t = a + b log2 n:"
    ]
    for m in res.methods:
        g = growth_row(res, m)
        if g is None:
            continue
        extra = ""
        if m.startswith("prismbatch") and (g["slope_ratio_vs_fcl"] is not None or g["slope_ratio_vs_coal"] is not None):
            extra = f"; line slope vs FCL {pct(g['slope_ratio_vs_fcl'])}, vs coal {pct(g['slope_ratio_vs_coal'])}"
        L.append(f"   {res.methods[m]}: x{fmt(g['growth_factor'], '.3g')}; {growth_model_text(g)}{extra}")
    L.append(
        f"   paper: projection {1e3 * pg['projection']:g} µs vs SWIFT {1e3 * pg['swift']:g} µs "
        f"per 1000 vertices = {pct(pg['projection'] / pg['swift'])}"
    )
    return L


def _throughput_lines(res):
    s = res.settings
    L = ["Batch throughput, all cases' poses, pairs/s (median):"]
    for nn in s["vertices"]:
        row = {r["mode"]: r for r in res.throughput if r["case"] == "all" and r["vertices"] == nn}
        if not row:
            continue
        parts = []
        for mode, r in row.items():
            lab = {
                "prismbatch_1t": "pb 1 thread",
                "prismbatch_allt": f"pb {r['threads']} threads",
                "fcl_loop": "FCL loop",
                "coal_loop": "coal loop",
            }[mode]
            parts.append(f"{lab} {r['median_pairs_per_s']:.3g}")
        L.append(f"   n={nn}: " + ", ".join(parts))
    L.append(
        f"   (peers: collide_batch is a Python loop; pb: Collider.collide on poses tiled to {s['batch_pairs']} pairs)"
    )
    return L


def _agreement_lines(res):
    dis = {}
    for r in res.agreement:
        d = dis.setdefault(
            r["peer"], {"n": 0, "dis": 0, "touch": 0, "other": 0, "lpt": 0, "lpr": 0, "lpw": 0, "lpc": 0}
        )
        d["n"] += r["poses"]
        d["dis"] += r["disagreements"]
        d["touch"] += r["touching_exact"]
        d["other"] += r["other"]
        for k, c in (("lpc", "lp_checked"), ("lpt", "lp_touching"), ("lpr", "lp_pb_right"), ("lpw", "lp_pb_wrong")):
            d[k] += r[c] or 0
    return [
        f"Agreement with {peer}: {d['dis']} of {d['n']} poses disagree; {d['touch']} are exact touching "
        f"contacts (touching within tol: prismbatch hit, {peer} miss); {d['other']} others, of which "
        f"{d['lpc']} checked by LP: {d['lpt']} in the touching band, prismbatch right {d['lpr']}, "
        f"wrong {d['lpw']}"
        for peer, d in dis.items()
    ]


def _run_lines(res):
    """Missing cells, first-call times, notes, machine load."""
    L = [f"missing: n={m['vertices']} case {m['case']}: {m['reason']}" for m in res.missing]
    c = res.compile
    L.append(
        f"First call (compile or cache load, excluded): collide_pair {c['collide_pair_s']:.2f} s, "
        f"collide serial {c['collide_serial_s']:.2f} s, parallel {c['collide_parallel_s']:.2f} s "
        f"(a warm call: {1e3 * c['second_serial_call_s']:.2f} ms)"
    )
    L += [f"note: {nt}" for nt in res.notes]
    busy = [r["other_cpus"] for r in res.latency if r.get("other_cpus") is not None]
    if busy:
        worst = max(busy)
        crowded = sum(b > 0.5 for b in busy) / len(busy)
        L.append(
            f"other processes while timing: up to {worst:.1f} CPUs busy (of {os.cpu_count()}); "
            f"{100 * crowded:.0f} % of the cells had more than 0.5 CPU busy"
            + (
                " -- wall-clock latencies are inflated there; compare thread_cpu_median_us in study_latency.csv"
                if worst > 0.5
                else ""
            )
        )
    e = res.environment
    if e.get("loadavg_start") is not None:
        L.append(
            f"load average (1 min) at start {e['loadavg_start'][0]:.2f}, at end {e['loadavg_end'][0]:.2f}; "
            f"{e['numba_threads']} Numba threads; study took {e['study_seconds']:.0f} s"
        )
    return L


def markdown(res, paths):
    """The Markdown page of the study (``study.md``) linking the files in ``paths``."""
    s = res.settings
    L = ["# Timing study: prismbatch vs python-fcl and coal (paper Table I, Fig. 7)", ""]
    L += resumed_note(s.get("resumed_vertices"))
    L += ["```", *format_study(res), "```", ""]
    n = s["table_vertices"]
    L += [
        f"## Table I at {n} vertices (µs per query; ratios next to the paper's)",
        "",
        *_not_comparable(n),
        "| case | prismbatch | FCL | coal | pb / FCL | pb / coal | paper projection | paper SWIFT | "
        "paper proj / SWIFT |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in res.table1:
        if r["missing"]:
            L.append(f"| {r['case']} | missing | | | | | | | |")
            continue
        L.append(
            f"| {r['case']} | {fmt(r['prismbatch_us'])} | {fmt(r['fcl_us'])} | {fmt(r['coal_us'])} | "
            f"{pct(r['pb_over_fcl'])} | {pct(r['pb_over_coal'])} | {fmt(r['paper_projection_us'])} | "
            f"{fmt(r['paper_swift_us'])} | {pct(r['paper_ratio'])} |"
        )
    L += [
        "",
        "## Growth with the vertex count (average over cases)",
        "",
        "Slopes of lines are compared only where both lines hold (r² >= 0.9); a cost that grows like log n "
        "is described by its growth per doubling of n instead.",
        "",
        "| method | growth factor | better model | line: µs / 1000 v (r²) | log: µs per doubling (r²) | "
        "line slope / FCL's | line slope / coal's |",
        "|---|---|---|---|---|---|---|",
    ]
    for m in res.methods:
        g = growth_row(res, m)
        if g is not None:
            pbm = m.startswith("prismbatch")
            L.append(
                f"| {res.methods[m]} | x{fmt(g['growth_factor'], '.3g')} | {g['model']} | "
                f"{g['slope_us_per_1000']:.3g} ({fmt(g['r2'], '.2f')}) | "
                f"{g['log_slope_us_per_doubling']:.3g} ({fmt(g['r2_log'], '.2f')}) | "
                f"{pct(g['slope_ratio_vs_fcl']) if pbm else ''} | {pct(g['slope_ratio_vs_coal']) if pbm else ''} |"
            )
    pg = PAPER_GROWTH_MS_PER_1000
    L.append(
        f"| paper: projection / SWIFT | | line | {1e3 * pg['projection']:g} / {1e3 * pg['swift']:g} | | "
        f"{pct(pg['projection'] / pg['swift'])} | |"
    )
    L += [
        "",
        f"Paper numbers: {PAPER_SOURCE}.",
        "",
        "Single-query latency = one Python call per pair; batch throughput = one vectorised call "
        "(kept apart; see `docs/methods/study.md`). Timings on a shared machine are noisy.",
        "",
    ]
    if paths.get("figures"):
        L += ["## Figures", ""] + [f"![{Path(f).stem}]({Path(f).name})" for f in paths["figures"] if f.endswith(".png")]
    L += ["", "## Files", ""] + [
        f"- [{Path(v).name}]({Path(v).name})" for k, v in paths.items() if isinstance(v, str) and k != "markdown"
    ]
    return "\n".join(L) + "\n"
