"""What the study's and the work-precision study's figures show, checked on their matplotlib objects.

The results are synthetic (made-up times and rates with the real row layout),
so the figures are drawn in a second without timing anything; the drawing
functions are the real ones, with ``save_figure`` replaced by one that keeps
each figure for inspection.
"""

import math

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from matplotlib.container import ErrorbarContainer  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402

from prismbatch.lab.study import plots as study_plots  # noqa: E402
from prismbatch.lab.study.analysis import growth_rows, table1_rows  # noqa: E402
from prismbatch.lab.study.constants import PAPER_TABLE1_MS  # noqa: E402
from prismbatch.lab.study.result import StudyResult  # noqa: E402
from prismbatch.lab.workprec import plots as wp_plots  # noqa: E402
from prismbatch.lab.workprec.result import METHODS as WP_METHODS  # noqa: E402
from prismbatch.lab.workprec.result import WorkPrecisionResult  # noqa: E402
from prismbatch.lab.workprec.scene import geometric_error, vertices_needed  # noqa: E402
from prismbatch.lab.workprec.stats import noise_floor, wilson_interval  # noqa: E402

CASES = tuple(range(1, 12))
VERTS = (36, 360, 1800, 3600)


@pytest.fixture
def drawn(monkeypatch):
    """Figures by file stem: the study and work-precision plots keep them here instead of saving them."""
    figs = {}

    def keep(fig, out_dir, name):
        figs[name] = fig
        return [name]

    monkeypatch.setattr(study_plots, "save_figure", keep)
    monkeypatch.setattr(wp_plots, "save_figure", keep)
    return figs


# ---------------------------------------------------------------------------
# the timing study
# ---------------------------------------------------------------------------


def _study_result():
    rng = np.random.default_rng(5)
    latency = []
    for method, base in (("prismbatch", 2.0), ("prismbatch_batch1", 20.0), ("fcl", 5.0), ("coal", 6.0)):
        for case in CASES:
            for n in VERTS:
                med = base * (1 + 0.1 * case) * (1 + n / 2000 if method in ("fcl", "coal") else 1.0)
                lo, hi = med * rng.uniform(0.7, 0.95), med * rng.uniform(1.05, 1.6)
                row = dict(case=case, vertices=n, method=method, median_us=med, min_us=lo, max_us=hi)
                latency.append(row | dict(q1_us=med, q3_us=med, thread_cpu_median_us=med, poses=10, repeats=3))
    throughput = [
        dict(case="all", vertices=n, mode=mode, threads=2, pairs=1000, median_pairs_per_s=v, min_pairs_per_s=v / 2)
        | dict(max_pairs_per_s=v * 2, repeats=3)
        for mode, v in (("prismbatch_1t", 1e6), ("prismbatch_allt", 2e6), ("fcl_loop", 1e5), ("coal_loop", 1e5))
        for n in VERTS
    ]
    settings = dict(cases=list(CASES), vertices=list(VERTS), repeats=3, poses_per_case=10, table_vertices=3600)
    methods = {
        "prismbatch": "prismbatch 0 collide_pair",
        "prismbatch_batch1": "prismbatch 0 collide (batch of 1)",
        "fcl": "python-fcl 0",
        "coal": "coal 0",
    }
    res = StudyResult(
        settings=settings | dict(batch_pairs=1000),
        methods=methods,
        latency=latency,
        throughput=throughput,
        agreement=[],
        missing=[],
        growth=[],
        table1=[],
        compile={},
    )
    res.growth = growth_rows(res)
    res.table1 = table1_rows(res)
    return res


@pytest.fixture
def study_figures(drawn, tmp_path):
    res = _study_result()
    assert study_plots.plot_study(res, tmp_path)
    return res, drawn


def _case_series(ax):
    """{case: (x, y)} of the per-case error-bar series of a Fig. 7a/7b axes."""
    out = {}
    for c in ax.containers:
        assert isinstance(c, ErrorbarContainer)
        line = c.lines[0]
        out[int(c.get_label().split()[-1])] = (np.asarray(line.get_xdata()), np.asarray(line.get_ydata()))
    return out, {int(c.get_label().split()[-1]): c.lines[0].get_marker() for c in ax.containers}


@pytest.mark.parametrize("stem", ["study_fig7a_prismbatch", "study_fig7b_peers"])
def test_fig7_cases_sit_side_by_side_at_each_vertex_count(study_figures, stem):
    res, figs = study_figures
    for ax in figs[stem].axes:
        series, markers = _case_series(ax)
        assert sorted(series) == list(CASES)
        assert len(set(markers.values())) == len(CASES)  # a marker of its own per case
        xs = np.array([series[c][0] for c in CASES])  # (case, vertex count)
        logs = np.log10(VERTS)
        half_gap = np.min(np.diff(logs)) / 2
        for j, n in enumerate(VERTS):
            # every case at its own x, in case order, each closer to n than to a neighbouring vertex count
            assert np.all(np.diff(xs[:, j]) > 0), (stem, n)
            assert np.all(np.abs(np.log10(xs[:, j]) - logs[j]) < half_gap)
        assert np.all(xs[:, :-1].max(axis=0) < xs[:, 1:].min(axis=0))  # the groups of two counts never meet
        method = "prismbatch" if "7a" in stem else next(m for m, lab in res.methods.items() if lab in ax.get_title())
        for c in CASES:  # the heights are the medians, untouched by the shift
            expect = [res.latency_us(method, c, n) for n in VERTS]
            np.testing.assert_allclose(series[c][1], expect)
        assert "(µs)" in ax.get_ylabel() and "vertices n" in ax.get_xlabel()
        assert ax.get_xscale() == "log" and [int(t) for t in ax.get_xticks()] == list(VERTS)


def test_table1_puts_the_paper_and_this_machine_on_separate_panels(study_figures):
    res, figs = study_figures
    fig = figs["study_table1"]
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert len(axes) == 2
    ax_paper, ax_here = axes
    assert ax_paper.get_title() != ax_here.get_title()
    assert "paper" in ax_paper.get_title() and "i3" in ax_paper.get_title()
    assert "this machine" in ax_here.get_title() and "i3" not in ax_here.get_title()
    assert ax_paper.get_shared_x_axes().joined(ax_paper, ax_here)
    for ax in axes:
        assert ax.get_xlabel() == "case" and "µs" in ax.get_ylabel() and ax.get_yscale() == "log"

    def bars(ax):
        """{legend label: bar heights} of one panel."""
        return {c.get_label(): np.array([p.get_height() for p in c.patches]) for c in ax.containers}

    paper, here = bars(ax_paper), bars(ax_here)
    assert set(paper) == {"projection method", "SWIFT"}
    assert set(here) == {res.methods[m] for m in ("prismbatch", "fcl", "coal")}
    rows = [r for r in res.table1 if isinstance(r["case"], int)]
    swift = [1e3 * PAPER_TABLE1_MS["swift"].get(r["case"], math.nan) for r in rows]
    np.testing.assert_allclose(paper["SWIFT"], swift)
    np.testing.assert_allclose(here[res.methods["fcl"]], [r["fcl_us"] for r in rows])


def test_fig7c_keys_the_fit_lines_only_when_one_is_drawn(drawn, tmp_path):
    res = _study_result()
    study_plots._fig7c(res, tmp_path)
    assert any("least-squares fit" in t.get_text() for t in drawn["study_fig7c_average"].legends[0].get_texts())
    res.growth = []  # nothing fitted (one vertex count, say): no dashed line, no key for it
    study_plots._fig7c(res, tmp_path)
    fig = drawn["study_fig7c_average"]
    assert not [ln for ln in fig.axes[0].get_lines() if ln.get_linestyle() == "--"]
    assert not any("least-squares fit" in t.get_text() for t in fig.legends[0].get_texts())


# ---------------------------------------------------------------------------
# work-precision
# ---------------------------------------------------------------------------

WP_N = (8, 128, 1000, 10000)
N_POSES = 5000
RTOL32 = 2e-5  # not the default: the note must state the run's value
TOL32 = 8.5e-5


def _wp_result(zero_at=None):
    """A work-precision result; ``zero_at``: (method, n) with no error seen."""
    rng = np.random.default_rng(2)
    geom = geometric_error(np.array(WP_N))
    rows, predictions = [], {}
    hits = rng.random(N_POSES) < 0.5
    for m in WP_METHODS:
        for n, g in zip(WP_N, geom) if m != "fcl_cylinder" else [(None, 0.0)]:
            wrong = int(N_POSES * (0.27 if m.startswith("pb32") and n >= 1000 else min(0.45, 40 * g + 0.02)))
            if (m, n) == zero_at:
                wrong = 0
            lo, hi = wilson_interval(wrong, N_POSES)
            t = {"pb64": 1.0, "pb32": 1.2, "fcl_": 5.0 * (1 + (n or 0) / 100)}[m[:4]]
            rows.append(
                dict(method=m, n=n, rate=wrong / N_POSES, ci_low=lo, ci_high=hi, t_median_us=t, geom_rel_error=g)
                | dict(fn=wrong // 2, max_fn_depth=max(g, 1e-7))
            )
            predictions[(m, n)] = hits  # batch and single query agree: drawn once against n
    settings = dict(radius=1.0, n_poses=N_POSES, noise_floor=noise_floor(N_POSES), gap_range_rel=(1e-8, 0.1))
    settings |= dict(
        rtol={"float64": 1e-9, "float32": RTOL32}, median_tolerance_rel={"float64": 4e-9, "float32": TOL32}
    )
    geometry = dict(n=np.array(WP_N), rel_error=geom, order=2.0, constant=4.93)
    versions = {"prismbatch": "0", "python-fcl": "0"}
    return WorkPrecisionResult(settings, rows, geometry, {}, None, predictions, versions)


def _has_data(handle):
    line = handle.lines[0] if isinstance(handle, ErrorbarContainer) else handle
    return len(np.atleast_1d(line.get_xdata())) > 0


def _legend_entries_are_drawn(fig):
    """Every label of the figure's legend belongs to an artist with data, or keys a marker that is drawn."""
    entries = {}
    for ax in fig.axes:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            entries.setdefault(lab, []).append((ax, h))
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert labels
    for lab in labels:
        ok = False
        for ax, h in entries[lab]:
            if _has_data(h):
                ok = True
            elif isinstance(h, Line2D):  # a key for a marker: drawn somewhere on the same axes
                ok |= any(
                    ln is not h and _has_data(ln) and ln.get_marker() == h.get_marker() and ln.get_linestyle() == "None"
                    for ln in ax.get_lines()
                )
        assert ok, f"legend entry with nothing drawn: {lab!r}"
    return labels


@pytest.mark.parametrize("zero_at", [None, ("pb64_batch", 10000)])
def test_workprec_legend_lists_only_what_is_drawn(drawn, tmp_path, zero_at):
    wp_plots.plot_work_precision(_wp_result(zero_at), tmp_path)
    for stem in ("workprec_error_vs_time", "workprec_error_vs_n"):
        labels = _legend_entries_are_drawn(drawn[stem])
        # the key of the open down-triangles is there exactly when one is drawn
        assert any("no error seen" in lab for lab in labels) == (zero_at is not None), stem


def test_workprec_says_float32_levels_off_at_its_tolerance(drawn, tmp_path):
    wp_plots.plot_work_precision(_wp_result(), tmp_path)
    for stem in ("workprec_error_vs_time", "workprec_error_vs_n"):
        fig = drawn[stem]
        notes = [t.get_text().replace("\n", " ") for ax in fig.axes for t in ax.texts if "float32" in t.get_text()]
        assert len(notes) == 1, stem
        assert f"rtol = {RTOL32:g}" in notes[0] and f"{TOL32:.1e} r" in notes[0]
        assert f"n >= {vertices_needed(TOL32):,}" in notes[0] and "level off" in notes[0]
    # against n, panel (a) draws that tolerance beside the geometric error it explains the plateau with
    ax_geom = drawn["workprec_error_vs_n"].axes[0]
    tol_lines = [ln for ln in ax_geom.get_lines() if "float32 tolerance" in ln.get_label()]
    assert len(tol_lines) == 1 and np.allclose(tol_lines[0].get_ydata(), TOL32)
