"""The stiff suite's report: summary lines, CSV table, JSON and a Markdown section.

See docs/methods/stiff-suite.md.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ..report import fmt, write_csv, write_json, write_text

_COLS = (
    "family",
    "param",
    "value",
    "dtype",
    "truth",
    "pairs",
    "hits",
    "non_finite",
    "disagreements_outside_band",
    "inside_band",
    "unresolved",
    "certified_over_lp",
    "rounding_explained",
    "contact_outside_2tol",
    "departures",
    "departures_hit",
    "max_departure_rel",
    "max_departure_tol64",
    "cases",
)


@dataclass
class StiffReport:
    """Result of :func:`run_stiff_suite`.

    Attributes
    ----------
    rows : list of dict
        One per (family, parameter value, dtype), keys: ``family``, ``param``
        (what ``value`` measures), ``value``, ``dtype``, ``truth``
        ("construction" or "LP + certificates"), ``pairs``, ``hits``,
        ``non_finite`` (hits with a non-finite contact, misses with a non-NaN
        one), ``disagreements_outside_band`` (answers contradicting the ground
        truth outside this dtype's band), ``inside_band``, ``unresolved`` (no
        LP and no certificate could decide), ``certified_over_lp`` (the LP
        was overruled by a certificate), ``rounding_explained`` (float32 only: a
        constructed answer contradicted, but a certificate on the float32-rounded
        poses shows the rounded bodies do touch / part), ``contact_outside_2tol`` (hits whose
        contact is not within 2 tol of both bodies), ``departures`` (answers
        differing from the float64-required one, outside the float64 band),
        ``departures_hit`` (of those, hits where float64 must miss),
        ``max_departure_rel`` (largest ``|gap|/S`` or ``|LP margin|/S`` among
        departures), ``max_departure_tol64`` (the same in float64 tolerances),
        ``cases`` (case histogram "case:count").
    quick : bool
    seed : int
    seconds : float
        Wall time of the run (noisy: shared machine).
    meta : dict
        :func:`prismbatch.lab.report.run_metadata`.
    """

    rows: list
    quick: bool
    seed: int
    seconds: float
    meta: dict = field(default_factory=dict)

    def _f64(self):
        return [r for r in self.rows if r["dtype"] == "float64"]

    @property
    def ok(self) -> bool:
        """float64 has zero NaN/inf, zero disagreements outside the band and nothing unresolved."""
        f = self._f64()
        return bool(f) and all(
            r["non_finite"] == 0 and r["disagreements_outside_band"] == 0 and r["unresolved"] == 0 for r in f
        )

    def _tot(self, dtype, key):
        return sum(r[key] for r in self.rows if r["dtype"] == dtype)

    def summary_lines(self) -> list:
        """A few lines: totals per dtype and where float32 departs."""
        out = [
            f"stiff suite ({'quick' if self.quick else 'full'}, seed {self.seed}): "
            f"{len({(r['family'], r['value']) for r in self.rows})} family/value sets, "
            f"{self.seconds:.1f} s; float64 {'OK' if self.ok else 'FAILED'}"
        ]
        for dt in sorted({r["dtype"] for r in self.rows}, reverse=True):
            t = lambda k: self._tot(dt, k)  # noqa: E731
            out.append(
                f"  {dt}: {t('pairs')} pairs, {t('hits')} hits, non-finite {t('non_finite')}, "
                f"outside band {t('disagreements_outside_band')}, inside band {t('inside_band')}, "
                f"unresolved {t('unresolved')}, LP overruled {t('certified_over_lp')}, "
                f"rounding-explained {t('rounding_explained')}, "
                f"contacts beyond 2 tol {t('contact_outside_2tol')}, departures from float64 "
                f"{t('departures')}"
            )
        dep = [r for r in self.rows if r["dtype"] == "float32" and r["departures"]]
        if dep:
            worst = max(dep, key=lambda r: r["max_departure_rel"])
            out.append(
                f"  float32 departs in {len(dep)} sets; largest |gap|/S {worst['max_departure_rel']:.3g} "
                f"({worst['max_departure_tol64']:.3g} float64 tol) in {worst['family']} "
                f"{worst['param']}={fmt(worst['value'])}"
            )
        return out

    def csv_tables(self) -> dict:
        """``{"stiff": (header, rows)}``: every row of :attr:`rows`."""
        return {"stiff": (list(_COLS), [[r[c] for c in _COLS] for r in self.rows])}

    def json(self) -> dict:
        """Everything as plain JSON-able data (metadata, settings, rows, ok)."""
        return {
            "meta": self.meta,
            "quick": self.quick,
            "seed": self.seed,
            "seconds": self.seconds,
            "ok": self.ok,
            "rows": self.rows,
        }

    def markdown(self) -> str:
        """A report section: how the suite works, the float64 table, the float32 departure table."""
        L = [
            "## Stiff and extreme suite",
            "",
            f"{'Quick' if self.quick else 'Full'} run, seed {self.seed}, {self.seconds:.0f} s "
            "(wall time on a shared machine, noisy). "
            f"float64: **{'no NaN/inf and no disagreement outside the touching band' if self.ok else 'FAILED'}**.",
            "",
            "Ground truth: *construction* families have a known separating plane and two witness points "
            "at the constructed gap (exact to the rounding of float64 coordinates, ~1e-15 S); *LP* "
            "families use random poses and the exact LP margin (`prismbatch.lab.exact.margin_lp`, trusted "
            "outside max(tol, 1e-7 S)), overruled only by certificates (a contact inside both bodies "
            "within 2 tol; a separating plane, its finiteness signs checked in exact arithmetic), and not "
            "used at all for axes pointing the same way within 1e-8 rad. S = R_a + R_b + |c_b - c_a|; "
            "float64 tol ~ 1e-9 S. A pair is inside the band when its gap is in (tol, 2 tol] "
            "(LP: |margin| <= max(tol, 1e-7 S)).",
            "",
            "float32 runs receive the same poses and polygons rounded to float32 (rounding a pose moves "
            "the bodies by ~1e-7 S: part of what a float32 user gets) and are judged against the float64 "
            "ground truth. This measures float32 *storage*: Numba promotes much of the kernels' "
            "arithmetic to float64.",
            "",
            "### float64",
            "",
            "| family | parameter | value | truth | pairs | hits | NaN/inf | outside band | inside band | "
            "unresolved | LP overruled | contact > 2 tol | cases |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        for r in self._f64():
            L.append(
                f"| {r['family']} | {r['param']} | {fmt(r['value'])} | {r['truth']} | {r['pairs']} | "
                f"{r['hits']} | {r['non_finite']} | {r['disagreements_outside_band']} | {r['inside_band']} | "
                f"{r['unresolved']} | {r['certified_over_lp']} | {r['contact_outside_2tol']} | {r['cases']} |"
            )
        f32 = [r for r in self.rows if r["dtype"] == "float32"]
        if f32:
            L += [
                "",
                "### Where float32 departs",
                "",
                "*departs*: answer differs from the float64-required one (pairs outside the float64 band); "
                "*as hits*: of those, hits where float64 must miss (float32's wider tolerance, 1e-5 S); "
                "*largest |gap|/S*: the largest |gap| (or |LP margin|) relative to S among departing "
                "pairs, also in float64 tolerances; *outside own band*: contradicts the ground truth "
                "beyond float32's own band (2 tol32 plus the pose rounding near the end faces); "
                "*rounding*: contradicts it, but the float32-rounded bodies are certified to touch "
                "(or part) as answered (nearly parallel axes: rounding turns a 1e-12 rad tilt by "
                "~1e-7 rad, and the bodies then meet far away).",
                "",
                "| family | parameter | value | pairs | hits | NaN/inf | departs | as hits | largest gap/S | "
                "in float64 tol | outside own band | rounding | unresolved | contact > 2 tol32 |",
                "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
            ]
            for r in f32:
                L.append(
                    f"| {r['family']} | {r['param']} | {fmt(r['value'])} | {r['pairs']} | {r['hits']} | "
                    f"{r['non_finite']} | {r['departures']} | {r['departures_hit']} | "
                    f"{fmt(r['max_departure_rel'])} | {fmt(r['max_departure_tol64'])} | "
                    f"{r['disagreements_outside_band']} | {r['rounding_explained']} | {r['unresolved']} | "
                    f"{r['contact_outside_2tol']} |"
                )
        return "\n".join(L) + "\n"


def write_stiff_report(report, out_dir):
    """Write ``stiff.csv``, ``stiff.json`` and ``stiff.md`` into ``out_dir``.

    Parameters
    ----------
    report : StiffReport
    out_dir : str or pathlib.Path

    Returns
    -------
    list of str
        The written paths.
    """
    out = Path(out_dir)
    files = []
    for name, (header, rows) in report.csv_tables().items():
        files.append(write_csv(out / f"{name}.csv", header, rows))
    files.append(write_json(out / "stiff.json", report.json()))
    md = out / "stiff.md"
    write_text(md, report.markdown())
    files.append(str(md))
    return files
