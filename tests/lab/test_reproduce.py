"""`prismbatch reproduce --quick`: one output folder with every part, a report
that shows every figure, and the notebook that redraws the figures from the
CSV files (executed here on that output)."""

import json
import re
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("matplotlib")
pytest.importorskip("fcl")
pytest.importorskip("scipy")

from prismbatch.cli import main  # noqa: E402
from prismbatch.lab.reproduce import PARTS  # noqa: E402

pytestmark = [pytest.mark.slow, pytest.mark.needs_fcl, pytest.mark.needs_coal]

ROOT = Path(__file__).resolve().parents[2]
NOTEBOOK = ROOT / "notebooks" / "reproduce.ipynb"


@pytest.fixture(scope="module")
def quick_output(tmp_path_factory):
    """One `prismbatch reproduce --quick` run through the command line, shared by the tests."""
    out = tmp_path_factory.mktemp("reproduce")
    assert main(["reproduce", "--quick", "--no-progress", "--out", str(out)]) == 0
    return out


def test_every_part_writes_csv_json_and_figures(quick_output):
    names = {p.name for p in quick_output.iterdir()}
    for prefix in ("validation", "study", "workprec", "experiment"):
        assert any(n.startswith(prefix) and n.endswith(".csv") for n in names), prefix
        assert any(n.startswith(prefix) and n.endswith(".json") for n in names), prefix
    for prefix in ("study", "workprec", "experiment"):
        pngs = [n for n in names if n.startswith(prefix) and n.endswith(".png")]
        assert pngs and all(n[:-4] + ".svg" in names for n in pngs), prefix
    meta = json.loads((quick_output / "reproduce.json").read_text())
    assert meta["parts"] == list(PARTS) and meta["quick"] is True and meta["seed"] == 0
    assert meta["machine"]["numba_threads"] >= 1 and meta["versions"]["numba"]
    assert set(meta["wall_s"]) == set(PARTS)
    assert set(meta["files"]) <= names


def test_report_shows_every_figure_and_the_side_by_side_table(quick_output):
    report = (quick_output / "report.md").read_text()
    shown = set(re.findall(r"!\[[^\]]*\]\(([^)]+)\)", report))
    pngs = {p.name for p in quick_output.glob("*.png")}
    assert pngs and pngs <= shown
    assert all((quick_output / f).exists() for f in shown)
    # the paper's Table I ratios (projection / SWIFT) beside ours (prismbatch / FCL)
    assert "SWIFT" in report and "FCL" in report
    for title in ("Timing study", "Work-precision", "Experiment", "alidation"):
        assert title in report


def test_validation_part_passes_its_own_checks(quick_output):
    meta = json.loads((quick_output / "validation.json").read_text())
    text = json.dumps(meta)
    assert '"ok": true' in text


def test_notebook_redraws_every_figure_from_the_csvs(quick_output, tmp_path, monkeypatch):
    import matplotlib

    matplotlib.use("Agg")
    monkeypatch.setenv("PRISMBATCH_RESULTS", str(quick_output))
    monkeypatch.setenv("PRISMBATCH_REDRAWN", str(tmp_path))
    nb = json.loads(NOTEBOOK.read_text())
    ns = {}
    for cell in nb["cells"]:
        if cell["cell_type"] == "code":
            exec(compile("".join(cell["source"]), str(NOTEBOOK), "exec"), ns)  # noqa: S102 - our notebook
    figs = ns["FIGURES"]
    expected = {
        "fig7ab_latency_per_case",
        "fig7c_average",
        "table1",
        "throughput",
        "workprec",
        "fig10_contours",
        "fig11a_trajectory",
        "fig11bc_states_inputs",
    }
    assert set(figs) == expected
    for name, fig in figs.items():
        assert (tmp_path / f"{name}.png").stat().st_size > 0
        for ax in fig.axes:
            if ax.get_visible():
                assert ax.get_xlabel() and ax.get_ylabel(), name
                # the axes hold finite data: lines, bars or markers
                ys = [np.asarray(line.get_ydata(), dtype=float) for line in ax.get_lines()]
                ys += [np.array([p.get_height() for p in ax.patches], dtype=float)]
                assert any(np.isfinite(y).any() for y in ys), name
    import matplotlib.pyplot as plt

    plt.close("all")


def test_reproduce_rejects_unknown_parts(tmp_path, capsys):
    assert main(["reproduce", "--parts", "nonsense", "--out", str(tmp_path)]) == 2
    assert "unknown part" in capsys.readouterr().err


def test_report_opens_with_the_papers_numbers_beside_ours(quick_output):
    report = (quick_output / "report.md").read_text()
    head = report.split("| part | wall time |")[0]
    assert "## The paper's numbers beside ours" in head
    rows = [ln for ln in head.splitlines() if ln.startswith("| ") and not ln.startswith("| quantity")]
    names = [r.split(" | ")[0][2:] for r in rows]
    assert [f"Table I, case {c}" for c in range(1, 10)] == names[:9]
    for want in (
        "Fig. 7 growth with n",
        "experiment: case sequence",
        "experiment: first collision",
        "experiment: contact class",
        "experiment: detection cost",
    ):
        assert want in names
    verdicts = [r.rstrip(" |").split(" | ")[-1] for r in rows]
    assert all(v.startswith(("reproduced", "not reproduced", "not measured", "peer not run")) for v in verdicts)
    # the stiff suite's tables are a linked file, not part of the report
    assert "validation_stiff.md" in report and (quick_output / "validation_stiff.md").exists()
