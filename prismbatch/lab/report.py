"""Shared plumbing for everything that writes results: run metadata (package
versions, CPU, threads), number formatting, JSON and CSV files, progress bars
and figures.

One place for these so that the experiment, validation, timing study and
``reproduce`` write files the same way. Optional dependencies (matplotlib,
tqdm) are imported only here, only when used.
"""

from __future__ import annotations

import contextlib
import csv
import json
import math
import os
import platform
import sys
from pathlib import Path

import numpy as np

__all__ = [
    "package_versions",
    "cpu_name",
    "numba_threads",
    "run_metadata",
    "jsonable",
    "atomic_open",
    "write_text",
    "write_json",
    "write_csv",
    "check_writable",
    "fmt",
    "pct",
    "progress",
    "new_figure",
    "save_figure",
    "legend_below",
    "MPL_MISSING",
]

MPL_MISSING = "figures need matplotlib: pip install 'prismbatch[plot]'"


def package_versions():
    """Versions of prismbatch, Python and the packages results depend on (None if absent)."""
    from importlib import metadata

    from .. import __version__

    v = {"prismbatch": __version__, "python": platform.python_version()}
    for name in ("numpy", "numba", "scipy", "python-fcl", "coal", "matplotlib", "dask", "distributed"):
        try:
            v[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            v[name] = None
    return v


def cpu_name():
    """The CPU model as the OS reports it."""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def numba_threads():
    """``numba.get_num_threads()`` (the threads a parallel kernel uses now)."""
    import numba

    return numba.get_num_threads()


def run_metadata(**extra):
    """A dict describing the run: versions, machine, threads, command line, plus ``extra``."""
    meta = {
        "versions": package_versions(),
        "machine": {
            "cpu": cpu_name(),
            "cpu_count": os.cpu_count(),
            "platform": platform.platform(),
            "numba_threads": numba_threads(),
        },
        "command": " ".join(sys.argv),
    }
    meta.update(extra)
    return meta


def jsonable(x):
    """``x`` with NumPy scalars/arrays turned into plain Python; non-finite floats become None."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, (np.floating, float)):
        return None if not math.isfinite(float(x)) else float(x)
    return x


@contextlib.contextmanager
def atomic_open(path, mode="w", **kw):
    """Open a temporary file beside ``path``; on success it replaces ``path`` in one rename.

    An interrupt, a full disk or any exception leaves the old ``path`` (or none) and no
    truncated file: the temporary file is removed and the exception propagates.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, mode, **kw) as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(exc, OSError) and exc.filename is None:  # a full disk: say which file
            raise OSError(exc.errno, exc.strerror, str(path)) from None
        raise


def write_text(path, text):
    """Write ``text`` (UTF-8) to ``path`` atomically; returns the path as str."""
    with atomic_open(path, "w", encoding="utf-8") as f:
        f.write(text)
    return str(path)


def write_json(path, obj):
    """Write ``jsonable(obj)`` to ``path`` (UTF-8, indented, atomically); returns the path as str."""
    return write_text(path, json.dumps(jsonable(obj), indent=2, ensure_ascii=False) + "\n")


def write_csv(path, header, rows):
    """Write a CSV file with one header row (atomically); returns the path as str."""
    with atomic_open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(list(header))
        w.writerows(rows)
    return str(path)


def check_writable(out_dir):
    """Create ``out_dir`` if needed and check that a file can be written there, before any work.

    Raises
    ------
    OSError
        The folder cannot be created or written (the message names it).
    """
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
        with atomic_open(out / ".prismbatch-write-check", "w") as f:
            f.write("ok\n")
        os.unlink(out / ".prismbatch-write-check")
    except OSError as exc:
        raise OSError(f"cannot write to --out {out_dir}: {exc.strerror or exc}") from None
    return str(out)


def fmt(x, spec=".3g", none="-", unit=""):
    """``x`` as text for a table or a log line: the one number formatter of the lab.

    ``none`` stands for None and non-finite floats; integers print whole (``str``)
    unless ``spec`` says otherwise; with the default ``spec`` a float between 1000
    and 1e7 prints without exponent (5030, not 5.03e+03); ``unit`` is appended to
    numbers only; anything else (a string) prints as it is.
    """
    if x is None or (isinstance(x, (float, np.floating)) and not math.isfinite(x)):
        return none
    if isinstance(x, (bool, np.bool_, str)):
        return str(x)
    if isinstance(x, (int, np.integer)) and spec == ".3g":
        return str(int(x)) + unit
    if spec == ".3g" and 1000 <= abs(x) < 1e7:
        return f"{x:.0f}{unit}"
    return format(x, spec) + unit


def pct(x):
    """A ratio as a percentage with one decimal ("2.8 %"), "-" for None."""
    return fmt(None if x is None else 100 * x, ".1f", unit=" %")


class _NullBar:
    def update(self, n=1):
        pass

    def set_description(self, desc=None):
        pass

    def close(self):
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def progress(total, *, enabled=True, unit="pair", desc=None):
    """A tqdm progress bar on stderr when wanted and tqdm is installed, else a no-op with
    the same ``update``/``set_description``/``close`` methods (also a context manager)."""
    if enabled:
        try:
            from tqdm import tqdm
        except ImportError:
            return _NullBar()
        return tqdm(total=total, unit=unit, unit_scale=True, leave=False, desc=desc, file=sys.stderr)
    return _NullBar()


def new_figure(**kw):
    """A matplotlib ``Figure`` (no pyplot, no global backend change)."""
    try:
        from matplotlib.figure import Figure
    except ImportError as exc:
        raise ImportError(MPL_MISSING) from exc
    return Figure(**kw)


def save_figure(fig, out_dir, name):
    """Save ``fig`` as ``name.png`` (150 dpi) and ``name.svg`` in ``out_dir``; returns both paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = []
    for ext in ("png", "svg"):
        p = out / f"{name}.{ext}"
        with atomic_open(p, "wb") as f:
            fig.savefig(f, format=ext, dpi=150 if ext == "png" else None)
        files.append(str(p))
    return files


def legend_below(fig, axes, ncol=3, frameon=True):
    """One legend under the axes, outside the data, each label once over all ``axes``."""
    handles, labels = [], []
    for ax in axes:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    fig.legend(handles, labels, loc="outside lower center", ncol=ncol, fontsize=8, frameon=frameon)
