"""Running the work-precision study: time and score every method on the same near-contact poses.

:func:`run_work_precision` builds the poses (:mod:`.scene`), measures compile time, then for each n
times prismbatch (float64/float32, batch and single query) and python-fcl on the n-gon, and once
python-fcl's exact Cylinder; it returns a :class:`.result.WorkPrecisionResult`. Method and
defaults: ``docs/methods/work-precision.md``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from ...collide import Collider
from ...config import DEFAULT_RTOL
from ...geometry import pair_scale_tolerance
from ...shapes import Prism
from ..checkpoint import Checkpoint, Interrupted, run_unit
from ..checks import check_int, check_positive, check_vertex_counts
from ..report import package_versions
from ..report import progress as make_progress_bar
from ..timing import seconds_of
from .result import METHODS, WorkPrecisionResult, method_labels
from .scene import (
    B_SCALE,
    B_VERTICES,
    BETA_RANGE_DEG,
    GAP_RANGE,
    TILT_RANGE_DEG,
    NearContactPoses,
    geometric_error,
    near_contact_poses,
)
from .stats import error_stats, fit_order, noise_floor

DEFAULT_VERTICES = (8, 16, 32, 64, 128, 360, 1000, 3600, 10000, 36000, 100000)
QUICK_VERTICES = (8, 32, 128, 1000, 3600, 10000)
DEFAULT_POSES, QUICK_POSES = 20_000, 10_000
DEFAULT_REPEATS, QUICK_REPEATS = 3, 2

#: Timed passes of one method and n stop early once they took this long (s): the slowest
#: rows (python-fcl on 1e5-gons, about 3 ms per query) get fewer passes.
PASS_BUDGET_S = 30.0

# raised from run_work_precision, which both Python callers and `prismbatch workprec` reach: name both ways out
FCL_MISSING = (
    "python-fcl is not installed: pip install 'prismbatch[fcl]' (or skip its rows: fcl=False in "
    "Python, --no-fcl on the command line)"
)

#: The columns of a row taken from :func:`.stats.error_stats` (NaN when the method did not run).
STAT_KEYS = (
    "n_queries",
    "exact_hits",
    "exact_misses",
    "wrong",
    "rate",
    "ci_low",
    "ci_high",
    "fn",
    "fn_rate",
    "fn_ci_low",
    "fn_ci_high",
    "fp",
    "fp_rate",
    "fp_ci_low",
    "fp_ci_high",
    "max_fn_depth",
    "max_fp_gap",
    "fn_beyond_tol",
    "fp_beyond_tol",
)


# ---------------------------------------------------------------------------
# timing
# ---------------------------------------------------------------------------


def timed_call(call):
    """``(seconds, hits)`` of one ``call()`` returning the hits of a full pass."""
    t = time.perf_counter()
    h = call()
    return time.perf_counter() - t, h


def pair_pass(col, its):
    """One ``collide_pair`` call per pose pair: ``(seconds, hits)``; the output is allocated untimed."""
    f = col.collide_pair
    out = np.empty(len(its), dtype=bool)
    t = time.perf_counter()
    for k, (pa, ra, pb_, rb) in enumerate(its):
        out[k] = f(pa, ra, pb_, rb).hit
    return time.perf_counter() - t, out


def timed_passes(fn, repeats, budget_s=PASS_BUDGET_S):
    """Run ``fn()`` -> (seconds, hits) up to ``repeats`` times, stopping early once the passes so far
    took more than ``budget_s``; returns (times, hits of the first pass, all passes agree)."""
    times, first, same = [], None, True
    for _ in range(repeats):
        if times and sum(times) > budget_s:
            break
        t, h = fn()
        times.append(t)
        if first is None:
            first = h
        else:
            same &= bool(np.array_equal(first, h))
    return np.array(times), first, same


# ---------------------------------------------------------------------------
# the rows
# ---------------------------------------------------------------------------


@dataclass
class RowTable:
    """The rows of a run (one per method and n) and the reported hits behind them."""

    P: NearContactPoses
    labels: dict
    radius: float
    rows: list = field(default_factory=list)
    preds: dict = field(default_factory=dict)

    def add(self, method, n, times, hits, same, setup_s, depth, tol_m, geom_rel):
        """One row; ``times`` and ``hits`` None for a method that did not run (its columns NaN)."""
        stats = error_stats(hits, self.P, depth, tol_m) if hits is not None else {}
        t_us = 1e6 * times / len(self.P) if times is not None else None
        row = dict(
            method=method,
            label=self.labels[method],
            shape="cylinder" if n is None else "n-gon",
            n=n,
            geom_rel_error=geom_rel,
            t_median_us=float(np.median(t_us)) if t_us is not None else math.nan,
            t_min_us=float(np.min(t_us)) if t_us is not None else math.nan,
            t_max_us=float(np.max(t_us)) if t_us is not None else math.nan,
            passes=0 if times is None else len(times),
            setup_ms=1e3 * setup_s if setup_s is not None else math.nan,
            passes_agree=same,
        )
        for k in STAT_KEYS:
            row[k] = stats.get(k, math.nan)
        radius = self.radius
        row["tolerance"] = float(np.median(tol_m)) / radius if np.ndim(tol_m) else float(tol_m) / radius
        self.rows.append(row)
        if hits is not None:
            self.preds[(method, n)] = hits

    def sort(self):
        """Rows in :data:`METHODS` order, then by n."""
        order = {m: i for i, m in enumerate(METHODS)}
        self.rows.sort(key=lambda r: (order[r["method"]], -1 if r["n"] is None else r["n"]))


# ---------------------------------------------------------------------------
# the steps of a run
# ---------------------------------------------------------------------------


def resolve_arguments(vertices, n_poses, repeats, seed, radius, quick):
    """Defaults filled in and checked: ``(sorted vertex counts, n_poses, repeats, seed, radius)``."""
    if vertices is None:
        vertices = QUICK_VERTICES if quick else DEFAULT_VERTICES
    try:
        verts = sorted(check_vertex_counts({check_int(v, "vertices", 3) for v in vertices}))
    except TypeError as exc:
        raise TypeError(f"vertices must be a sequence of integers >= 3: {exc}") from None
    if not verts:
        raise ValueError("vertices must not be empty")
    n_poses = check_int(
        QUICK_POSES if quick and n_poses is None else DEFAULT_POSES if n_poses is None else n_poses, "n_poses", 2
    )
    repeats = check_int(
        QUICK_REPEATS if quick and repeats is None else DEFAULT_REPEATS if repeats is None else repeats, "repeats", 1
    )
    seed = check_int(seed, "seed", 0)
    radius = check_positive(radius, "radius")
    return verts, n_poses, repeats, seed, radius


def fcl_available(fcl):
    """Whether to run the python-fcl rows; ImportError if asked for and not installed."""
    if not fcl:
        return False
    try:
        import fcl as _fcl  # noqa: F401, PLC0415
    except ImportError as exc:
        raise ImportError(FCL_MISSING) from exc
    return True


def poses_per_dtype(P):
    """The poses converted to float64 and float32 before any timing: batch arrays and per-pair views."""
    arrays, items = {}, {}
    for dt in (np.float64, np.float32):
        A = tuple(np.ascontiguousarray(x, dtype=dt) for x in (P.pos_a, P.rot_a, P.pos_b, P.rot_b))
        arrays[dt] = A
        items[dt] = [tuple(np.ascontiguousarray(x[k]) for x in A) for k in range(len(P))]
    return arrays, items


def measure_compile(probe, shape_b, arrays, items):
    """First-call time (compile or cache load) per dtype and path, excluded from the timings."""
    compile_s = {}
    for dt, tag in ((np.float64, "float64"), (np.float32, "float32")):
        col = Collider(probe, shape_b, dtype=dt)
        A = arrays[dt]
        compile_s[f"{tag}_batch"] = seconds_of(lambda: col.collide(*(x[:2] for x in A), parallel=False))
        compile_s[f"{tag}_pair"] = seconds_of(lambda: col.collide_pair(*items[dt][0]))
    return compile_s


def fcl_standins(probe, shape_b, P):
    """python-fcl's stand-in length ``L`` (largest over the poses) and its prepared poses."""
    from ..peers import FCLPeer, standin_length  # noqa: PLC0415

    L = standin_length(probe.xy, shape_b.xy, P.pos_a, P.rot_a, P.pos_b, P.rot_b)
    return L, FCLPeer.prepare(P.pos_a, P.rot_a, P.pos_b, P.rot_b)


def time_prismbatch(table, n, shape_b, arrays, items, tol, repeats, depth, geom_rel):
    """The four prismbatch rows at ``n`` (float64/float32, batch and pair); returns a's n-gon prism.

    ``tol`` (dtype -> per-pair tolerance) is filled in at the first n and kept for the others.
    """
    P, radius = table.P, table.radius
    perf = time.perf_counter
    t0 = perf()
    shape_a = Prism.regular(n, radius)
    cols = {
        np.float64: Collider(shape_a, shape_b, dtype=np.float64),
        np.float32: Collider(shape_a, shape_b, dtype=np.float32),
    }
    setup_pb = perf() - t0
    for dt, tag in ((np.float64, "pb64"), (np.float32, "pb32")):
        if tol[dt] is None:
            tol[dt] = pair_scale_tolerance(shape_a, shape_b, P.pos_a, P.rot_a, P.pos_b, P.rot_b, dtype=dt)[1]
        col, A, its = cols[dt], arrays[dt], items[dt]

        def batch(col=col, A=A):
            return timed_call(lambda: col.collide(*A, parallel=False).hit)

        def pair(col=col, its=its):
            return pair_pass(col, its)

        for kind, fn in (("batch", batch), ("pair", pair)):
            times, h, same = timed_passes(fn, repeats)
            table.add(f"{tag}_{kind}", n, times, h, same, setup_pb, depth, tol[dt], geom_rel)
    return shape_a


def time_fcl_ngon(table, n, shape_a, shape_b, L, fcl_items, repeats, depth, geom_rel):
    """The ``fcl_ngon`` row at ``n`` (NaN when ``fcl_items`` is None: python-fcl not run)."""
    if fcl_items is None:
        table.add("fcl_ngon", n, None, None, None, None, depth, 0.0, geom_rel)
        return
    from ..peers import FCLPeer  # noqa: PLC0415

    t0 = time.perf_counter()
    peer = FCLPeer(shape_a.xy, shape_b.xy, L)
    setup = time.perf_counter() - t0
    times, h, same = timed_passes(lambda: timed_call(lambda: peer.run(fcl_items)), repeats)
    table.add("fcl_ngon", n, times, h, same, setup, depth, 0.0, geom_rel)


def time_fcl_cylinder(table, shape_b, L, fcl_on, repeats):
    """The ``fcl_cylinder`` row: python-fcl's exact Cylinder, independent of n (NaN when not ``fcl_on``)."""
    P = table.P
    depth_c = P.depth_in_cylinder(shape_b)
    if not fcl_on:
        table.add("fcl_cylinder", None, None, None, None, None, depth_c, 0.0, 0.0)
        return
    from ..peers import FCLCylinderPeer  # noqa: PLC0415

    t0 = time.perf_counter()
    peer = FCLCylinderPeer(table.radius, shape_b.xy, L)
    setup = time.perf_counter() - t0
    cyl_items = peer.prepare(P.pos_a, P.rot_a, P.pos_b, P.rot_b)
    times, h, same = timed_passes(lambda: timed_call(lambda: peer.run(cyl_items)), repeats)
    table.add("fcl_cylinder", None, times, h, same, setup, depth_c, 0.0, 0.0)


def geometry_summary(verts, radius):
    """Geometric error of every n and its fitted order (theory: 2 and pi^2 / 2)."""
    g_abs = geometric_error(np.array(verts), radius)
    p_ord, const = fit_order(verts, g_abs / radius)
    return dict(
        n=np.array(verts),
        abs_error=g_abs,
        rel_error=g_abs / radius,
        order=p_ord,
        constant=const,
        constant_theory=math.pi**2 / 2,
    )


def run_settings(*, radius, verts, n_poses, repeats, seed, quick, P, L, fcl_on, tol):
    """The ``settings`` of a :class:`.result.WorkPrecisionResult`."""
    return dict(
        radius=radius,
        shape_a=f"cylinder of radius {radius:g} as inscribed regular n-gon (vertex 0 on local +x)",
        shape_b=f"regular {B_VERTICES}-gon, circumradius {B_SCALE * radius:g} (the paper's hexagon scaled 2.5:2)",
        rot_a="diag(1, -1, -1) (axis down)",
        vertices=verts,
        n_poses=n_poses,
        repeats=repeats,
        seed=seed,
        quick=bool(quick),
        gap_range_rel=GAP_RANGE,
        beta_range_deg=BETA_RANGE_DEG,
        tilt_range_deg=TILT_RANGE_DEG,
        hit_fraction=0.5,
        exact_hits=int(P.hit.sum()),
        exact_misses=int((~P.hit).sum()),
        noise_floor=noise_floor(n_poses),
        fcl_standin_length=L,
        fcl=fcl_on,
        fcl_solver="python-fcl default CollisionRequest (GST_LIBCCD)",
        rtol={"float64": DEFAULT_RTOL[np.dtype(np.float64)], "float32": DEFAULT_RTOL[np.dtype(np.float32)]},
        median_tolerance_rel={
            "float64": float(np.median(tol[np.float64])) / radius,
            "float32": float(np.median(tol[np.float32])) / radius,
        },
        timing="median of repeats of a full pass over the N poses; compile time excluded",
    )


# ---------------------------------------------------------------------------
# the study
# ---------------------------------------------------------------------------


def run_work_precision(
    *,
    vertices=None,
    n_poses=None,
    radius=1.0,
    repeats=None,
    seed=0,
    quick=False,
    progress=True,
    fcl=True,
    checkpoint_dir=None,
    resume=False,
):
    """Run the work-precision study (``docs/methods/work-precision.md``).

    Parameters
    ----------
    vertices : sequence of int, optional
        Vertex counts n of the cylinder's n-gon (each >= 3). Default
        :data:`DEFAULT_VERTICES` (8 .. 100000), quick :data:`QUICK_VERTICES`.
    n_poses : int, optional
        Number of near-contact pose pairs N (same for every method and n).
        Default 20000, quick 10000.
    radius : float, optional
        Cylinder radius r (b scales with it).
    repeats : int, optional
        Timed passes per method and n; the median is reported. Default 3,
        quick 2.
    seed : int, optional
        Seed of the pose generator.
    quick : bool, optional
        Smaller defaults (about a minute or less).
    progress : bool, optional
        Show a progress bar (needs tqdm).
    fcl : bool, optional
        Run the python-fcl rows (needs python-fcl); when False their times
        and errors are NaN.
    checkpoint_dir : str or path-like, optional
        Save each vertex count's rows when finished, under
        ``checkpoint_dir/checkpoint/workprec``.
    resume : bool, optional
        Load the vertex counts an earlier run with the same settings finished
        there (their timings are that run's; ``settings["resumed_vertices"]``
        lists them).

    Returns
    -------
    WorkPrecisionResult
    """
    verts, n_poses, repeats, seed, radius = resolve_arguments(vertices, n_poses, repeats, seed, radius, quick)
    fcl_on = fcl_available(fcl)

    rng = np.random.default_rng(seed)
    shape_b = Prism.regular(B_VERTICES, B_SCALE * radius)
    P = near_contact_poses(n_poses, rng, radius=radius, shape_b=shape_b)
    versions = package_versions()
    table = RowTable(P, method_labels(versions), radius)
    arrays, items = poses_per_dtype(P)
    probe = Prism.regular(verts[0], radius)
    compile_s = measure_compile(probe, shape_b, arrays, items)
    L, fcl_items = fcl_standins(probe, shape_b, P) if fcl_on else (None, None)

    tol = {np.float64: None, np.float32: None}
    ckpt = None
    if checkpoint_dir is not None:
        key = {"vertices": verts, "n_poses": n_poses, "repeats": repeats, "seed": seed, "radius": radius}
        ckpt = Checkpoint(checkpoint_dir, "workprec", {**key, "fcl": fcl_on}, resume=resume)

    def measure(n):
        """The rows at ``n`` and their hits (a fresh table), with the tolerances they used."""
        part = RowTable(P, table.labels, radius)
        geom_rel = float(geometric_error(n))
        depth = P.depth_in_ngon(shape_b, n)
        shape_a = time_prismbatch(part, n, shape_b, arrays, items, tol, repeats, depth, geom_rel)
        time_fcl_ngon(part, n, shape_a, shape_b, L, fcl_items, repeats, depth, geom_rel)
        return part.rows, part.preds, dict(tol)

    resumed, finished = [], []
    bar = make_progress_bar(len(verts) + 1, enabled=progress, unit="n", desc="work-precision")
    try:
        with bar:
            for n in verts:
                bar.set_description(f"work-precision n={n}")
                (rows, preds, tol_n), loaded = run_unit(ckpt, f"vertices-{n}", lambda n=n: measure(n))
                table.rows += rows
                table.preds.update(preds)
                tol.update(tol_n)  # the first n fixes the per-pair tolerances for the others
                if loaded:
                    resumed.append(n)
                finished.append(n)
                bar.update(1)
            time_fcl_cylinder(table, shape_b, L, fcl_on, repeats)
            bar.update(1)
    except KeyboardInterrupt:
        raise Interrupted(len(finished), len(verts), "vertex count", checkpoint=ckpt) from None

    table.sort()
    settings = run_settings(
        radius=radius,
        verts=verts,
        n_poses=n_poses,
        repeats=repeats,
        seed=seed,
        quick=quick,
        P=P,
        L=L,
        fcl_on=fcl_on,
        tol=tol,
    )
    settings["resumed_vertices"] = resumed
    return WorkPrecisionResult(
        settings, table.rows, geometry_summary(verts, radius), compile_s, P, table.preds, versions
    )
