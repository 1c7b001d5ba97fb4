"""Output of a validation run: the terminal summary, the Markdown report, CSV tables, JSON
metadata and the replay file of every disagreement (:func:`write_validation`).
"""

from __future__ import annotations

import numpy as np

from ..report import fmt, write_text
from .config import DISTRIBUTION_NAMES, NC
from .distance import DISTANCE_HEADER, DISTANCE_LIMIT, distance_json, distance_lines, distance_markdown, distance_rows

#: Columns of validation_summary.csv (one row per distribution and a total row).
SUMMARY_HEADER = [
    "distribution",
    "pairs",
    "hits",
    "fcl_pairs",
    "fcl_agree",
    "fcl_disagree_in_band",
    "fcl_disagree_out_band_prismbatch_wrong",
    "fcl_disagree_out_band_fcl_wrong",
    "fcl_standin_too_short",
    "fcl_unarbitrated",
    "lp_pairs",
    "lp_agree",
    "lp_pairs_in_band",
    "lp_disagree_in_band",
    "lp_disagree_out_band",
    "lp_arbitration_pairs",
    "lp_failed",
    "standin_checked",
    "standin_too_short",
    "standin_unsound",
    "standin_max_dev_over_S",
    "contacts_checked",
    "contacts_invalid",
    "contact_max_residual_over_tol",
    "nonfinite_contacts",
    "invalid_cases",
    "status_contact_mismatch",
    "exact_pairs",
    "exact_wrong_at_tol",
    "exact_in_band",
    "exact_unknown",
    "prismbatch_us_per_pair",
    "prismbatch_contact_us_per_pair",
    "fcl_us_per_pair",
    "lp_ms_per_call",
]

#: Columns of validation_cases.csv (one row per distribution, case and reference).
CASES_HEADER = [
    "distribution",
    "case",
    "reference",
    "pairs",
    "pb_hit_ref_hit",
    "pb_hit_ref_miss",
    "pb_miss_ref_hit",
    "pb_miss_ref_miss",
    "disagree_in_band",
    "disagree_out_band_prismbatch_wrong",
    "disagree_out_band_reference_wrong",
    "standin_too_short",
    "unarbitrated",
]


def _per_pair(seconds, n, unit):
    return float("nan") if n == 0 else seconds / n / unit


def _summary_rows(result):
    rows = []
    names = list(result.counts) + ["total"]
    for d in names:
        c = result.counts[d] if d != "total" else result.totals()
        if d == "total":
            t = {k: sum(result.times[x][k] for x in result.times) for k in next(iter(result.times.values()))}
        else:
            t = result.times[d]
        fcl_agree = int(np.trace(c["fcl_conf"], axis1=1, axis2=2).sum())
        lp_agree = int(np.trace(c["lp_conf"], axis1=1, axis2=2).sum())
        rows.append(
            [
                d,
                c["pairs"],
                c["hits"],
                c["fcl_pairs"],
                fcl_agree,
                int(c["fcl_in_band"].sum()),
                int(c["fcl_out_pb"].sum()),
                int(c["fcl_out_fcl"].sum()),
                int(c["fcl_standin_short"].sum()),
                int(c["fcl_unarbitrated"].sum()),
                c["lp_pairs"],
                lp_agree,
                int(c["lp_band"].sum()),
                int(c["lp_in_band"].sum()),
                int(c["lp_out"].sum()),
                c["lp_arbitration"],
                c["lp_failed"],
                c["standin_checked"],
                c["standin_short"],
                c["standin_unsound"],
                c["standin_max_dev"],
                c["contact_checked"],
                c["contact_invalid"],
                c["contact_max_ratio"],
                c["nonfinite"],
                c["bad_case"],
                c["status_mismatch"],
                c["exact_pairs"],
                c["exact_wrong"],
                c["exact_band"],
                c["exact_unknown"],
                _per_pair(t["pb"], c["pairs"], 1e-6),
                _per_pair(t["pb_contact"], c["pairs"], 1e-6),
                _per_pair(t["fcl"], t["fcl_pairs"], 1e-6),
                _per_pair(t["lp"], t["lp_calls"], 1e-3),
            ]
        )
    return rows


def _case_rows(result):
    rows = []
    for d, c in result.counts.items():
        for cs in range(1, NC):
            for ref in ("fcl", "lp"):
                m = c[f"{ref}_conf"][cs]
                if m.sum() == 0:
                    continue
                if ref == "fcl":
                    extra = [
                        c["fcl_in_band"][cs],
                        c["fcl_out_pb"][cs],
                        c["fcl_out_fcl"][cs],
                        c["fcl_standin_short"][cs],
                        c["fcl_unarbitrated"][cs],
                    ]
                else:
                    extra = [c["lp_in_band"][cs], c["lp_out"][cs], 0, 0, 0]
                rows.append(
                    [d, cs, ref, int(m.sum()), int(m[1, 1]), int(m[1, 0]), int(m[0, 1]), int(m[0, 0])]
                    + [int(x) for x in extra]
                )
    return rows


def _run_text(execution):
    """How the run was executed, e.g. "in-process, 1 worker(s)" (an interrupted run has no worker count)."""
    workers = execution.get("workers")
    return f"{execution.get('scheduler')}" + ("" if workers is None else f", {workers} worker(s)")


def format_validation(result):
    """Terminal summary of a :class:`ValidationResult` as a list of lines.

    Parameters
    ----------
    result : ValidationResult

    Returns
    -------
    list of str
    """
    cfg = result.config
    L = [
        f"prismbatch validate: {cfg['n_pairs']:,} pairs per distribution, shapes {'/'.join(cfg['shapes'])}, "
        f"vertices {cfg['vertices']}, dtype {cfg['dtype']} (rtol {cfg['rtol']:g}), seed {cfg['seed']}",
        f"  run: {_run_text(result.execution)}; "
        f"wall {result.wall_time:.1f} s; compile/cache load {result.compile_time:.1f} s (excluded)",
    ]
    for row in _summary_rows(result):
        r = dict(zip(SUMMARY_HEADER, row))
        L.append(f"{r['distribution']}: {r['pairs']:,} pairs, {r['hits']:,} hits")
        if r["fcl_pairs"]:
            L.append(
                f"  vs FCL ({r['fcl_pairs']:,} pairs): agree {r['fcl_agree']:,}; disagree inside band "
                f"{r['fcl_disagree_in_band']}, outside band: prismbatch wrong "
                f"{r['fcl_disagree_out_band_prismbatch_wrong']}, "
                f"FCL wrong {r['fcl_disagree_out_band_fcl_wrong']}, "
                f"stand-in too short {r['fcl_standin_too_short']}, unarbitrated {r['fcl_unarbitrated']}"
            )
        if r["lp_pairs"]:
            L.append(
                f"  vs LP ({r['lp_pairs']:,} random pairs, {r['lp_pairs_in_band']} in band): agree "
                f"{r['lp_agree']:,}; disagree inside band {r['lp_disagree_in_band']}, outside band "
                f"{r['lp_disagree_out_band']}; LP failures {r['lp_failed']}"
            )
        if r["exact_pairs"]:
            L.append(
                f"  exact reference at tol ({r['exact_pairs']} pairs the LP could not settle): prismbatch wrong "
                f"{r['exact_wrong_at_tol']}, in [tol, 2 tol] {r['exact_in_band']}, not certified "
                f"{r['exact_unknown']}"
            )
        if r["standin_checked"]:
            L.append(
                f"  stand-in check: {r['standin_checked']} pairs, too short {r['standin_too_short']}, "
                f"max |finite - infinite margin|/S {r['standin_max_dev_over_S']:.1e}; capped (unsound) "
                f"lengths {r['standin_unsound']}"
            )
        if cfg["contact_check"]:
            L.append(
                f"  contacts: {r['contacts_checked']:,} checked, {r['contacts_invalid']} invalid, max "
                f"residual {r['contact_max_residual_over_tol']:.3g} tol; non-finite {r['nonfinite_contacts']}"
            )
        L.append(
            f"  time per pair: prismbatch {r['prismbatch_us_per_pair']:.3g} us (status), "
            f"{r['prismbatch_contact_us_per_pair']:.3g} us (contact); FCL {r['fcl_us_per_pair']:.3g} us; "
            f"LP {r['lp_ms_per_call']:.3g} ms per call"
        )
    kinds = {}
    for rec in result.records:
        kinds[rec["kind"]] = kinds.get(rec["kind"], 0) + 1
    L.append(
        f"records: {result.records_total} disagreement(s) in all, {len(result.records)} saved "
        f"({', '.join(f'{k}: {v}' for k, v in kinds.items()) or 'none'})"
    )
    L.extend(distance_lines(result))
    L.append("RESULT: " + _verdict(result))
    if result.stiff is not None:
        L.extend(result.stiff.summary_lines())
    return L


def _verdict(result):
    """The run's one-line verdict; a run that compared against no reference says so."""
    cfg = result.config
    prefix = ""
    if result.partial is not None:
        p = result.partial
        dist = ""
        if p.get("distance_pairs_total"):
            dist = f" and {p['distance_pairs_done']:,} of {p['distance_pairs_total']:,} signed-distance pairs"
        prefix = (
            f"PARTIAL ({p['pairs_done']:,} of {p['pairs_total']:,} pairs{dist}; "
            "the same command with --resume continues): "
        )
    return prefix + _verdict_of_pairs(result, cfg)


def _verdict_of_pairs(result, cfg):
    if not result.ok:
        n = result.distance_failures()
        return "FAILURES (see the records" + (f"; {n} distance pairs failed)" if n else ")")
    dist = ""
    if result.distance is not None:
        n = len(result.distance["pairs"]["pb"])
        dist = f"; signed distances within {DISTANCE_LIMIT:g} tol of the exact reference on {n:,} pairs"
    if cfg["fcl_fraction"] == 0.0 and cfg["lp_samples"] == 0:
        checked = "contacts valid" if cfg["contact_check"] else "nothing else checked either"
        return (
            "NO COMPARISON: no reference ran (FCL off and --lp-samples 0), so hit/miss answers were not "
            f"checked; {checked}{dist}"
        )
    return "OK, no disagreement outside the touching band, contacts valid" + dist


def _markdown(result):
    cfg = result.config
    L = [
        "# prismbatch validation",
        "",
        f"{cfg['n_pairs']:,} pose pairs per distribution ({', '.join(cfg['distributions'])}); shapes "
        f"{', '.join(cfg['shapes'])} with vertex counts {cfg['vertices']}; dtype {cfg['dtype']}, rtol "
        f"{cfg['rtol']:g}, atol {cfg['atol']:g}; seed {cfg['seed']}. FCL on "
        f"{cfg['fcl_fraction']:.0%} of the pairs, the exact LP on {cfg['lp_samples']:,} random pairs per "
        f"distribution plus every FCL disagreement. Run: {_run_text(result.execution)}, "
        f"wall {result.wall_time:.1f} s.",
        "",
        "Touching band per pair: `band = max(tol, 1e-7 S)`, `S = R_a + R_b + |c_b - c_a|`. Outside it the "
        "LP decides; inside it any answer is allowed. FCL runs on finite stand-ins of length "
        "`peers.standin_lengths` (rounded up to a power of two), checked against the LP.",
        "",
        f"**Result: {_verdict(result)}.**",
        "",
        "## Summary",
        "",
    ]
    rows = [dict(zip(SUMMARY_HEADER, r)) for r in _summary_rows(result)]
    tables = (
        (
            "Agreement (disagreements outside the band are split by who the LP says is wrong)",
            [
                ("distribution", "distribution"),
                ("pairs", "pairs"),
                ("hits", "hits"),
                ("FCL pairs", "fcl_pairs"),
                ("FCL agree", "fcl_agree"),
                ("FCL disagree, in band", "fcl_disagree_in_band"),
                ("outside, prismbatch wrong", "fcl_disagree_out_band_prismbatch_wrong"),
                ("outside, FCL wrong", "fcl_disagree_out_band_fcl_wrong"),
                ("stand-in too short", "fcl_standin_too_short"),
                ("LP pairs", "lp_pairs"),
                ("LP in band", "lp_pairs_in_band"),
                ("LP disagree, in band", "lp_disagree_in_band"),
                ("LP disagree, outside", "lp_disagree_out_band"),
            ],
        ),
        (
            "Checks",
            [
                ("distribution", "distribution"),
                ("contacts checked", "contacts_checked"),
                ("invalid contacts", "contacts_invalid"),
                ("max residual / tol", "contact_max_residual_over_tol"),
                ("non-finite contacts", "nonfinite_contacts"),
                ("invalid cases", "invalid_cases"),
                ("stand-ins checked", "standin_checked"),
                ("stand-in too short", "standin_too_short"),
                ("capped stand-ins", "standin_unsound"),
                ("max stand-in margin change / S", "standin_max_dev_over_S"),
                ("LP arbitration pairs", "lp_arbitration_pairs"),
                ("LP failures", "lp_failed"),
            ],
        ),
        (
            "Time per pair (same pairs; noisy; compile excluded: " + f"{result.compile_time:.1f} s)",
            [
                ("distribution", "distribution"),
                ("prismbatch status (µs)", "prismbatch_us_per_pair"),
                ("prismbatch with contact (µs)", "prismbatch_contact_us_per_pair"),
                ("FCL (µs)", "fcl_us_per_pair"),
                ("LP (ms per call)", "lp_ms_per_call"),
            ],
        ),
    )
    for title, cols in tables:
        L += [f"### {title}", "", "| " + " | ".join(c[0] for c in cols) + " |", "|" + "---|" * len(cols)]
        L += ["| " + " | ".join(fmt(r[c[1]], none="nan") for c in cols) + " |" for r in rows]
        L.append("")
    L += ["## Per case", ""]
    L.append("| " + " | ".join(h.replace("_", " ") for h in CASES_HEADER) + " |")
    L.append("|" + "---|" * len(CASES_HEADER))
    for row in _case_rows(result):
        L.append("| " + " | ".join(fmt(x, none="nan") for x in row) + " |")
    L += [
        "",
        "## Disagreement records",
        "",
        f"{result.records_total} records ({len(result.records)} kept in `validation_replay.json`), with full "
        "inputs (shapes, poses, seed, spawn key).",
    ]
    dist = distance_markdown(result)
    if dist:
        L += ["", *dist]
    if result.stiff is not None:  # its long tables live in their own file
        L += [
            "",
            "## Stiff and extreme suite",
            "",
            *result.stiff.summary_lines(),
            "",
            f"Its tables: [{STIFF_MARKDOWN}]({STIFF_MARKDOWN}).",
        ]
    return "\n".join(L) + "\n"


#: The stiff suite's tables, linked from validation.md.
STIFF_MARKDOWN = "validation_stiff.md"


def _write_replay(path, records, meta):
    from ..replay import write_replay

    return str(write_replay(path, records, meta))


def write_validation(result, out_dir):
    """Write the report files of a :class:`ValidationResult` to ``out_dir``.

    Parameters
    ----------
    result : ValidationResult
    out_dir : str or path-like
        Created if missing.

    Returns
    -------
    dict
        Paths: ``markdown`` (validation.md), ``summary_csv``
        (validation_summary.csv), ``cases_csv`` (validation_cases.csv),
        ``json`` (validation.json: run metadata, config, seeds, counts,
        times), ``replay`` (validation_replay.json), ``distance_csv``
        (validation_distance.csv, with the distance section) and ``stiff`` (a
        list of the stiff suite's CSV files, empty without it).
    """
    from pathlib import Path

    from ..report import run_metadata, write_csv, write_json

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {}
    md = out / "validation.md"
    write_text(md, _markdown(result))
    paths["markdown"] = str(md)
    paths["summary_csv"] = write_csv(out / "validation_summary.csv", SUMMARY_HEADER, _summary_rows(result))
    paths["cases_csv"] = write_csv(out / "validation_cases.csv", CASES_HEADER, _case_rows(result))
    o = result.outcome()
    meta = run_metadata(
        validation=result.config,
        seed=result.config["seed"],
        seed_rule="numpy.random.SeedSequence(seed, spawn_key=(distribution index, block))",
        distribution_index={d: DISTRIBUTION_NAMES.index(d) for d in result.config["distributions"]},
        execution=result.execution,
        compile_time_s=result.compile_time,
        wall_time_s=result.wall_time,
        ok=result.ok,
        partial=result.partial,
    )
    paths["json"] = write_json(
        out / "validation.json",
        {
            **meta,
            "counts": o["counts"],
            "times_s": result.times,
            "records_total": result.records_total,
            "records_kept": len(result.records),
            "stiff": None if result.stiff is None else result.stiff.json(),
            "distance": distance_json(result),
        },
    )
    if result.distance is not None:
        rows = distance_rows(**result.distance)
        paths["distance_csv"] = write_csv(out / "validation_distance.csv", DISTANCE_HEADER, rows)
    paths["replay"] = _write_replay(
        out / "validation_replay.json",
        result.records,
        {k: meta[k] for k in ("validation", "seed", "seed_rule", "distribution_index")},
    )
    paths["stiff"] = []
    if result.stiff is not None:
        for name, (header, rows) in result.stiff.csv_tables().items():
            fname = name if name.startswith("stiff") else f"stiff_{name}"
            paths["stiff"].append(write_csv(out / f"{fname}.csv", header, rows))
        md = out / STIFF_MARKDOWN
        write_text(md, result.stiff.markdown())
        paths["stiff"].append(str(md))
    if result.partial is None and result.checkpoint is not None:
        result.checkpoint.remove()  # every file is written: the finished chunks are no longer needed
    return paths
