"""Running the stiff suite: every family and value, in each dtype, into a :class:`StiffReport`.

See docs/methods/stiff-suite.md.
"""

from __future__ import annotations

import importlib
import time

import numpy as np

from ...config import DEFAULT_RTOL
from ..report import progress as progress_bar
from ..report import run_metadata
from .evaluate import margins, run_one, shape_of
from .families import FAMILIES, SIZES
from .report import StiffReport


def _check_arguments(dtypes, seed, families):
    """The dtypes (np.dtype list) and family names to run; raises on bad arguments."""
    dts = []
    for d in dtypes if not isinstance(dtypes, str) else (dtypes,):
        dd = np.dtype(d)
        if dd not in DEFAULT_RTOL:
            raise ValueError(f"dtypes: {d!r} is not float64 or float32")
        dts.append(dd)
    if not dts:
        raise ValueError("dtypes is empty")
    if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool):
        raise TypeError(f"seed must be an int, got {type(seed).__name__}")
    names = list(FAMILIES) if families is None else [families] if isinstance(families, str) else list(families)
    unknown = [f for f in names if f not in FAMILIES]
    if unknown or not names:
        raise ValueError(
            f"families: unknown {unknown} (choose from {sorted(FAMILIES)})" if unknown else "families is empty"
        )
    return dts, names


def _collider():
    # looked up on the package at run time, so that a substitute set on prismbatch.lab.stiff.Collider
    # (tests/test_stiff_suite.py does) is the one used
    return importlib.import_module(__package__).Collider


def run_stiff_suite(
    *, quick=False, seed=0, dtypes=("float64", "float32"), progress=False, families=None
) -> StiffReport:
    """Run every stiff/extreme family in each dtype against its known ground truth.

    Parameters
    ----------
    quick : bool
        A few pairs per (family, value) (about 20 s once compiled) instead of
        320 constructed / 96 LP pairs (a few minutes).
    seed : int
        Seed of all pose and polygon draws.
    dtypes : sequence of {"float64", "float32"}
        Precisions to run; the ground truth is always float64.
    progress : bool
        Show a progress bar (needs tqdm).
    families : sequence of str, optional
        Run only these families (keys of :data:`FAMILIES`); default all.

    Returns
    -------
    StiffReport

    Raises
    ------
    ValueError
        Unknown dtype, an empty ``dtypes`` or an unknown family.
    TypeError
        ``seed`` not an integer.
    """
    dts, names = _check_arguments(dtypes, seed, families)
    collider = _collider()
    n_con, n_lp = SIZES[bool(quick)]
    t0 = time.perf_counter()
    rows = []
    jobs = [(f, v) for f in names for v in FAMILIES[f][1]]
    with progress_bar(len(jobs), enabled=progress, unit="set", desc="stiff") as bar:
        for fam, val in jobs:
            pname, _, gen, truth = FAMILIES[fam]
            rng = np.random.default_rng([int(seed), list(FAMILIES).index(fam), FAMILIES[fam][1].index(val)])
            ps = gen(rng, n_lp if truth.startswith("LP") else n_con, val)
            m, trusted = margins(ps) if ps.lp else (None, None)
            shapes = (shape_of(ps.polys_a), shape_of(ps.polys_b))
            for dt in dts:
                c = run_one(ps, shapes, m, trusted, dt, collider)
                rows.append(dict(family=fam, param=pname, value=float(val), dtype=dt.name, truth=truth, **c))
            bar.update(1)
    return StiffReport(
        rows,
        bool(quick),
        int(seed),
        time.perf_counter() - t0,
        run_metadata(suite="stiff", quick=bool(quick), seed=int(seed)),
    )
