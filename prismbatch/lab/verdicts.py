"""Every number of the paper beside ours, with a verdict: the table that opens ``report.md``.

The paper's figures (Table I per case, the Fig. 7 growth, the experiment's
collision time, case sequence, contact class and detection cost) come from
:mod:`prismbatch.lab.study.constants` and :data:`prismbatch.lab.experiment.model.PAPER`;
ours from a :class:`~prismbatch.lab.study.StudyResult` and an
:class:`~prismbatch.lab.experiment.ExperimentResult`. The paper compared against
SWIFT on an i3; we compare against python-fcl on this machine, so a verdict on
timing judges the direction (faster, slower growth), and the ratios are shown
side by side rather than equated.
"""

from __future__ import annotations

from .report import fmt, pct
from .study.analysis import growth_model_text, growth_row

__all__ = ["paper_rows", "paper_table"]


def _timing_verdict(ours, paper, peer="FCL"):
    if ours is None:
        return "not measured"
    if ours < 1.0:
        return f"reproduced: faster than {peer} ({pct(ours)} of its time; paper {pct(paper)} of SWIFT's)"
    return f"not reproduced: {pct(ours)} of {peer}'s time"


def _study_rows(study):
    rows = []
    for r in study.table1:
        n = r["vertices"]
        label = f"Table I, case {r['case']}" if isinstance(r["case"], int) else f"Table I, {r['case']}"
        if r["missing"] or r["paper_projection_us"] is None:
            if not r["missing"]:
                continue  # a case of ours the paper has no number for
            rows.append((label, "-", "missing (casegen could not build it)", "not measured"))
            continue
        paper = f"{fmt(r['paper_projection_us'])} µs vs SWIFT {fmt(r['paper_swift_us'])} µs (3600 v)"
        ours = f"{fmt(r['prismbatch_us'])} µs vs FCL {fmt(r['fcl_us'])} µs ({n} v)"
        rows.append((label, paper, ours, _timing_verdict(r["pb_over_fcl"], r["paper_ratio"])))
    pb, fcl = growth_row(study, "prismbatch"), growth_row(study, "fcl")
    if pb is not None and fcl is not None:
        ns = study.settings["vertices"]
        ours = (
            f"x{fmt(pb['growth_factor'], '.3g')} vs FCL x{fmt(fcl['growth_factor'], '.3g')} from n = {min(ns)} to "
            f"{max(ns)} (prismbatch: {growth_model_text(pb)}; FCL: {growth_model_text(fcl)})"
        )
        slower = pb["growth_factor"] is not None and fcl["growth_factor"] is not None
        slower = slower and pb["growth_factor"] < fcl["growth_factor"]
        rows.append(
            (
                "Fig. 7 growth with n",
                "projection 37 µs vs SWIFT 1300 µs per 1000 vertices (2.8 %, a line)",
                ours,
                "reproduced: grows far slower than the peer" if slower else "not reproduced",
            )
        )
    return rows


def _experiment_rows(exp):
    from .experiment.model import PAPER

    s, tm = exp.summary, exp.timing
    seq = s["case_sequence"]
    t = s["first_collision_s"]
    fc = s["first_contact_class"]
    rows = [
        (
            "experiment: case sequence",
            " → ".join(map(str, PAPER["case_sequence"])),
            " → ".join(map(str, seq)),
            "reproduced" if list(seq) == PAPER["case_sequence"] else "not reproduced",
        ),
        (
            "experiment: first collision",
            f"about {PAPER['collision_s']:g} s",
            fmt(t, ".2f", unit=" s"),
            "reproduced (within 0.5 s)"
            if t is not None and abs(t - PAPER["collision_s"]) <= 0.5
            else "not reproduced (the paper gives no plant parameters; ours are documented in the experiment page)",
        ),
        (
            "experiment: contact class",
            f"{PAPER['contact_class']} (side face)",
            "-" if fc is None else str(fc),
            "reproduced" if fc == PAPER["contact_class"] else "not reproduced",
        ),
        (
            "experiment: colliding episodes",
            str(PAPER["collisions"]),
            str(s["collision_episodes"]),
            "reproduced" if s["collision_episodes"] == PAPER["collisions"] else "not reproduced",
        ),
    ]
    ours_ms, fcl_ms = tm.get("loop_ms", tm.get("pair_ms")), tm.get("fcl_ms")
    paper = f"{PAPER['detection_ms']:g} ms vs SWIFT {PAPER['swift_ms']:g} ms"
    if ours_ms is None or fcl_ms is None:
        rows.append(("experiment: detection cost", paper, fmt(ours_ms, ".3g", unit=" ms"), "peer not run"))
    else:
        ratio = ours_ms / fcl_ms
        rows.append(
            (
                "experiment: detection cost",
                paper,
                f"{fmt(ours_ms, '.3g')} ms vs python-fcl {fmt(fcl_ms, '.3g')} ms",
                _timing_verdict(ratio, PAPER["detection_ms"] / PAPER["swift_ms"], "python-fcl"),
            )
        )
    return rows


def paper_rows(study=None, experiment=None):
    """``(quantity, paper, ours, verdict)`` rows for the parts that ran (either may be None)."""
    rows = []
    if study is not None:
        rows += _study_rows(study)
    if experiment is not None:
        rows += _experiment_rows(experiment)
    return rows


def paper_table(study=None, experiment=None):
    """The rows of :func:`paper_rows` as Markdown lines (empty if neither part ran)."""
    rows = paper_rows(study, experiment)
    if not rows:
        return []
    L = [
        "## The paper's numbers beside ours",
        "",
        "The paper timed the projection method against SWIFT on an Intel i3 (3.3 GHz); this run times "
        "prismbatch against python-fcl on this machine, on the same pose pairs. A timing verdict judges the "
        "direction; the ratios are shown side by side.",
        "",
        "| quantity | paper | this run | verdict |",
        "|---|---|---|---|",
    ]
    L += [f"| {q} | {p} | {o} | {v} |" for q, p, o, v in rows]
    return L + [""]
