"""Check prismbatch against the exact rational reference on user-like pose families.

For every pair of every family (:mod:`prismbatch.lab.families`) prismbatch's
answer is judged at the pair's own tolerance by :func:`exact_gap.judge_pair`:
a certified gap <= tol must be a hit, a certified gap > 2 tol must be a miss,
and every reported contact point must lie within 2 tol of both bodies, plus
the rounding of its own coordinates (certified the same way). Pairs the reference could not certify are counted
as "unknown", never guessed. Results: per-family counts (Markdown, CSV, JSON)
and every wrong pair as a JSON record with float.hex numbers (the format of
the regression cases in ``tests/data``), so it can become a test.

Needs highspy (the ``exact`` extra) for the float stage of the reference.
"""

from __future__ import annotations

import os
import time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context

import numpy as np

from ..geometry import pair_scale_tolerance
from ..shapes import Prism
from .families import FAMILIES, collide_family, make_family
from .report import write_csv, write_json, write_text

__all__ = ["judge_family", "run_exact_check", "markdown_table", "pair_record"]


def _reference_rotations(ps, k):
    """The rotation matrices the bodies of pair k are defined by (exact ones for quaternions)."""
    if ps.form != "quat":
        return ps.rot_a[k], ps.rot_b[k]
    from .exact_gap import exact_quat_matrix

    return exact_quat_matrix(ps.call_a[k], ps.quat_order), exact_quat_matrix(ps.call_b[k], ps.quat_order)


def _judge_chunk(args):
    """Judge pairs ``idx`` of a family (run in a worker process)."""
    name, n, seed, idx, hits, contacts, tols = args
    from .exact_gap import check_contact, judge_pair

    ps = make_family(name, n, seed)
    rows = []
    for k, hit, cont, tol in zip(idx, hits, contacts, tols):
        ra, rb = _reference_rotations(ps, k)
        j = judge_pair(ps.xy_a[k], ps.pos_a[k], ra, ps.xy_b[k], ps.pos_b[k], rb, tol)
        contact_ok = None
        if hit:
            # The contract: within 2 tol of both bodies, plus the rounding of the
            # contact's own coordinates (far contacts of nearly parallel axes).
            r = 2 * tol + 4 * np.finfo(float).eps * float(np.abs(cont).max())
            contact_ok = check_contact(ps.xy_a[k], ps.pos_a[k], ra, ps.xy_b[k], ps.pos_b[k], rb, cont, r)
        wrong = (j.verdict == "hit" and not hit) or (j.verdict == "miss" and hit)
        rows.append((int(k), j.verdict, bool(hit), wrong, contact_ok))
    return rows


def judge_family(name, n, seed, *, processes=1):
    """Run prismbatch on ``n`` pairs of family ``name`` and judge every pair exactly.

    Returns
    -------
    dict
        ``pairs``, ``must_hit``, ``must_miss``, ``band``, ``unknown``,
        ``wrong``, ``contacts_checked``, ``contacts_invalid``,
        ``contacts_undecided``, ``seconds`` and ``wrong_pairs`` (indices).
    """
    t0 = time.perf_counter()
    ps = make_family(name, n, seed)
    r = collide_family(ps, contact=True)
    A = [Prism(x) for x in ps.xy_a]
    B = [Prism(x) for x in ps.xy_b]
    tols = np.array(
        [
            pair_scale_tolerance(
                A[k], B[k], ps.pos_a[k : k + 1], ps.rot_a[k : k + 1], ps.pos_b[k : k + 1], ps.rot_b[k : k + 1]
            )[1][0]
            for k in range(n)
        ]
    )
    chunks = np.array_split(np.arange(n), max(1, processes * 4))
    jobs = [(name, n, seed, c, r.hit[c], r.contact[c], tols[c]) for c in chunks if len(c)]
    if processes > 1:
        with ProcessPoolExecutor(processes, mp_context=get_context("spawn")) as pool:
            rows = [row for part in pool.map(_judge_chunk, jobs) for row in part]
    else:
        rows = [row for job in jobs for row in _judge_chunk(job)]
    verdicts = [v for _, v, _, _, _ in rows]
    contacts = [c for _, _, h, _, c in rows if h]
    return dict(
        family=name,
        pairs=n,
        must_hit=verdicts.count("hit"),
        must_miss=verdicts.count("miss"),
        band=verdicts.count("band"),
        unknown=verdicts.count("unknown"),
        wrong=sum(w for _, _, _, w, _ in rows),
        contacts_checked=len(contacts),
        contacts_invalid=sum(c is False for c in contacts),
        contacts_undecided=sum(c is None for c in contacts),
        seconds=time.perf_counter() - t0,
        wrong_pairs=[k for k, _, _, w, c in rows if w or c is False],
    )


def pair_record(ps, k, tol, said_hit, verdict):
    """One pair as a JSON-ready dict with float.hex numbers (the tests/data format)."""
    hx = lambda a: [float(v).hex() for v in np.ravel(a)]  # noqa: E731
    rec = dict(
        family=ps.family,
        xy_a=[hx(p) for p in ps.xy_a[k]],
        xy_b=[hx(p) for p in ps.xy_b[k]],
        pos_a=hx(ps.pos_a[k]),
        rot_a=hx(ps.rot_a[k]),
        pos_b=hx(ps.pos_b[k]),
        rot_b=hx(ps.rot_b[k]),
        quat_a=None,
        quat_b=None,
        quat_order=None,
        tol=float(tol).hex(),
        exact={"verdict": verdict},
        prismbatch_said={"hit": bool(said_hit)},
    )
    if ps.form == "quat":
        rec.update(quat_a=hx(ps.call_a[k]), quat_b=hx(ps.call_b[k]), quat_order=ps.quat_order)
    return rec


def markdown_table(results):
    """Per-family counts as a Markdown table."""
    head = (
        "| family | pairs | must hit | must miss | in band | unknown | wrong | contacts checked | "
        "invalid | undecided | s |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
    )
    rows = [
        f"| {r['family']} | {r['pairs']} | {r['must_hit']} | {r['must_miss']} | {r['band']} | {r['unknown']} | "
        f"{r['wrong']} | {r['contacts_checked']} | {r['contacts_invalid']} | {r['contacts_undecided']} | "
        f"{r['seconds']:.0f} |"
        for r in results
    ]
    tot = {
        k: sum(r[k] for r in results)
        for k in (
            "pairs",
            "must_hit",
            "must_miss",
            "band",
            "unknown",
            "wrong",
            "contacts_checked",
            "contacts_invalid",
            "contacts_undecided",
        )
    }
    rows.append(
        f"| **all** | {tot['pairs']} | {tot['must_hit']} | {tot['must_miss']} | {tot['band']} | "
        f"{tot['unknown']} | {tot['wrong']} | {tot['contacts_checked']} | {tot['contacts_invalid']} | "
        f"{tot['contacts_undecided']} | |"
    )
    return "\n".join([head, *rows])


def run_exact_check(pairs_per_family, *, families=None, seed=0, processes=1, out=None, progress=print):
    """Judge every family; write ``exact_check.md``, ``.csv``, ``.json`` and the wrong pairs to ``out``.

    Returns the list of per-family result dicts (see :func:`judge_family`).
    """
    families = list(FAMILIES) if families is None else list(families)
    if out is not None:
        os.makedirs(out, exist_ok=True)
    results = []
    for name in families:
        res = judge_family(name, pairs_per_family, seed, processes=processes)
        results.append(res)
        if progress:
            progress(
                f"{name}: {res['pairs']} pairs, wrong {res['wrong']}, in band {res['band']}, "
                f"unknown {res['unknown']}, invalid contacts {res['contacts_invalid']} ({res['seconds']:.0f} s)"
            )
    if out is not None:
        _write(results, out, pairs_per_family, seed)
    return results


def _write(results, out, n, seed):
    table = markdown_table(results)
    write_text(os.path.join(out, "exact_check.md"), f"# Exact check (seed {seed}, {n} pairs per family)\n\n{table}\n")
    keys = [k for k in results[0] if k != "wrong_pairs"]
    write_csv(os.path.join(out, "exact_check.csv"), keys, [[r[k] for k in keys] for r in results])
    write_json(os.path.join(out, "exact_check.json"), {"seed": seed, "pairs_per_family": n, "results": results})
    wrong = []
    for r in results:
        if r["wrong_pairs"]:
            ps = make_family(r["family"], n, seed)
            for k in r["wrong_pairs"]:
                A, B = Prism(ps.xy_a[k]), Prism(ps.xy_b[k])
                tol = pair_scale_tolerance(
                    A, B, ps.pos_a[k : k + 1], ps.rot_a[k : k + 1], ps.pos_b[k : k + 1], ps.rot_b[k : k + 1]
                )[1][0]
                said = bool(
                    collide_family(
                        ps._replace(
                            xy_a=[ps.xy_a[k]],
                            xy_b=[ps.xy_b[k]],
                            pos_a=ps.pos_a[k : k + 1],
                            rot_a=ps.rot_a[k : k + 1],
                            pos_b=ps.pos_b[k : k + 1],
                            rot_b=ps.rot_b[k : k + 1],
                            call_a=_row(ps.call_a, k),
                            call_b=_row(ps.call_b, k),
                        )
                    ).hit[0]
                )
                wrong.append(pair_record(ps, k, tol, said, "see exact_check.json"))
    write_json(os.path.join(out, "exact_check_wrong.json"), wrong)


def _row(call, k):
    return call[k : k + 1] if isinstance(call, np.ndarray) else call[[k]]
