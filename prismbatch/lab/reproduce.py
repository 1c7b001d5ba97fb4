"""``prismbatch reproduce``: every result of the project in one output folder.

Runs, in order, a short Monte Carlo validation (:mod:`prismbatch.lab.validate`,
with the stiff suite), the timing study against python-fcl and coal
(:mod:`prismbatch.lab.study`: Table I and Fig. 7), the work-precision study
(:mod:`prismbatch.lab.workprec`) and the paper's manipulation experiment
(:mod:`prismbatch.lab.experiment`), and writes into one folder:

- each part's own files (CSV tables, JSON metadata, Markdown, figures as PNG
  and SVG), prefixed ``validation_``, ``stiff_``, ``study_``, ``workprec_``
  and ``experiment_``;
- ``report.md``: every part's report with its figures shown inline;
- ``reproduce.json``: versions, CPU, threads, seeds, settings, the wall time
  of each part and the list of files.

``quick=True`` shrinks every part (a few minutes on 2 cores). The notebook
``notebooks/reproduce.ipynb`` redraws the figures from the CSV files.
"""

from __future__ import annotations

import re
import time
from pathlib import Path

from .report import progress, run_metadata, write_json, write_text
from .verdicts import paper_table

__all__ = ["PARTS", "run_reproduce"]

#: The parts, in the order they run.
PARTS = ("validation", "study", "workprec", "experiment")


def _validation(out, quick, seed, show):
    from .validate import validate, write_validation

    res = validate(
        n_pairs=5_000 if quick else 100_000,
        shapes=("regular", "random", "cylinder"),
        seed=seed,
        lp_samples=300 if quick else 2000,
        max_band_records=100 if quick else 1000,
        stiff="quick" if quick else True,
        progress=show,
    )
    return write_validation(res, out), res


def _study(out, quick, seed, show):
    from .study import run_study, write_study

    res = run_study(quick=quick, seed=seed, progress=show)
    return write_study(res, out), res


def _workprec(out, quick, seed, show):
    from .workprec import run_work_precision, write_work_precision

    res = run_work_precision(quick=quick, seed=seed, progress=show)
    return write_work_precision(res, out), res


def _experiment(out, quick, seed, show):
    from .experiment import run_experiment, write_experiment

    res = run_experiment("square")
    return write_experiment(res, out), res


_RUNNERS = {"validation": _validation, "study": _study, "workprec": _workprec, "experiment": _experiment}
_TITLES = {
    "validation": "Monte Carlo validation and the stiff suite",
    "study": "Timing study against FCL (Table I, Fig. 7)",
    "workprec": "Error against run time (work-precision)",
    "experiment": "The manipulation experiment (Sec. VI-B)",
}


def _files(paths):
    """Flatten a part's dict of written paths into a list of file paths."""
    out = []
    for v in (paths or {}).values():
        if isinstance(v, (list, tuple)):
            out += [str(x) for x in v]
        elif isinstance(v, dict):
            out += _files(v)
        elif v:
            out.append(str(v))
    return out


def _section(part, files):
    """One report section: the part's own Markdown (headings demoted one level,
    figure links turned into inline images), plus any figure it does not show."""
    # A part's own page is embedded; a page it links (the stiff tables) stays a linked file.
    md = [f for f in files if f.endswith(".md") and "stiff" not in Path(f).name]
    pngs = [Path(f).name for f in files if f.endswith(".png")]
    L = []
    for f in md:
        text = Path(f).read_text(encoding="utf-8")
        text = re.sub(r"^(#+) ", lambda m: "#" + m.group(1) + " ", text, flags=re.M)
        # "- [name.png](name.png)" -> an inline image
        text = re.sub(r"^- \[([^\]]*)\]\(([^)]+\.png)\)", r"![\1](\2)", text, flags=re.M)
        L += [text.rstrip(), ""]
    shown = "\n".join(L)
    missing = [n for n in pngs if f"]({n})" not in shown]
    if not L:
        L = [f"## {_TITLES[part]}", ""]
    if missing:
        L += ["### More figures", ""] + [f"![{n}]({n})\n" for n in missing]
    return L


def run_reproduce(out_dir, *, quick=False, seed=0, parts=None, progress_bar=True, log=print):
    """Run the chosen parts and write everything into ``out_dir``.

    Parameters
    ----------
    out_dir : str or Path
        Output folder (created if needed).
    quick : bool, optional
        Smaller runs of every part (minutes, not an hour).
    seed : int, optional
        Seed of every random part.
    parts : sequence of str, optional
        A subset of :data:`PARTS` (in any order; they run in PARTS order);
        default all.
    progress_bar : bool, optional
        Show progress bars (tqdm, if installed) on stderr.
    log : callable, optional
        Receives one line per finished part.

    Returns
    -------
    dict
        ``report`` (path of report.md), ``json`` (reproduce.json), ``files``
        (every file written) and ``wall_s`` (seconds per part).
    """
    parts = PARTS if parts is None else tuple(parts)
    unknown = [p for p in parts if p not in PARTS]
    if unknown:
        raise ValueError(f"unknown part(s) {unknown}; choose from {list(PARTS)}")
    if not parts:
        raise ValueError("parts is empty: choose at least one of " + ", ".join(PARTS))
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    chosen = [p for p in PARTS if p in parts]
    wall, files, sections, results = {}, [], [], {}
    bar = progress(len(chosen), enabled=progress_bar, unit="part", desc="reproduce")
    for part in chosen:
        bar.set_description(f"reproduce: {part}")
        t0 = time.perf_counter()
        paths, results[part] = _RUNNERS[part](out, quick, seed, progress_bar)
        wall[part] = time.perf_counter() - t0
        part_files = _files(paths)
        files += part_files
        sections += _section(part, part_files)
        log(f"{part}: {len(part_files)} file(s) in {wall[part]:.1f} s")
        bar.update(1)
    bar.close()
    meta = run_metadata(
        description="prismbatch reproduce: validation, timing study, work-precision, experiment",
        quick=quick,
        seed=seed,
        parts=chosen,
        wall_s=wall,
        files=sorted(Path(f).name for f in files),
    )
    json_path = write_json(out / "reproduce.json", meta)
    v = meta["versions"]
    head = [
        "# prismbatch: reproduction report",
        "",
        f"prismbatch {v['prismbatch']}, numba {v['numba']}, numpy {v['numpy']}, python-fcl {v['python-fcl']}, "
        f"coal {v['coal']}; {meta['machine']['cpu']}, {meta['machine']['numba_threads']} Numba thread(s); "
        f"seed {seed}; {'quick' if quick else 'full'} run.",
        "",
        *paper_table(results.get("study"), results.get("experiment")),
        "| part | wall time |",
        "|---|---|",
        *(f"| {p} | {wall[p]:.1f} s |" for p in chosen),
        "",
        "Figures are in this folder as PNG and SVG; the CSV files hold every number shown; "
        "`notebooks/reproduce.ipynb` redraws the figures from them.",
        "",
    ]
    report = out / "report.md"
    write_text(report, "\n".join(head + sections) + "\n")
    return {"report": str(report), "json": json_path, "files": files + [str(report), json_path], "wall_s": wall}
