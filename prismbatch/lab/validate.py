"""Monte Carlo validation at scale: prismbatch against python-fcl and an exact LP.

:func:`validate` draws ``n_pairs`` pose pairs from each named distribution,
runs prismbatch on all of them, python-fcl on finite stand-ins (all pairs or a
subsample) and the exact signed-margin LP (:func:`prismbatch.lab.exact.margin_lp`)
on a random subsample plus every pair where prismbatch and FCL disagree, and
counts, per case, where they agree. :func:`format_validation` gives the
terminal summary, :func:`write_validation` the Markdown report, CSV tables,
JSON metadata and the replay file of every disagreement.

Reproducibility
---------------
Pairs are generated in fixed blocks of :data:`BLOCK_SIZE` pairs. Block ``i`` of
distribution ``d`` draws everything (its two shapes, its poses, its FCL and LP
subsamples) from ``numpy.random.SeedSequence(seed, spawn_key=(j, i))``, ``j``
the index of ``d`` in :data:`DISTRIBUTION_NAMES` (the same stream whichever
distributions are selected). A chunk is a range of blocks, described by
``(config, distribution, first block, number of blocks)`` only; merged results
(counts, records) are put in block order, so they do not depend on the chunk
size, on the worker count or on the order in which chunks finish. Only the
timings differ between runs.

Touching band
-------------
Per pair, with ``S = R_a + R_b + |c_b - c_a|`` (end-face radii about the area
centroids and the distance of the world centroids: the scene scale of the
test suite, ``tests/test_agreement.py``)::

    tol  = atol + rtol S + 4 eps (|c_a| + |c_b|)     (prismbatch's pair tolerance)
    band = max(tol, 1e-7 S)                          (the LP is trusted to ~1e-7 S)

An LP margin beyond ``+band`` means the bodies overlap, beyond ``-band`` that
they are separated by more than ``2 band``; prismbatch must agree with both.
Disagreements with ``|margin| <= band`` are "inside band" (allowed, counted).

Stand-ins
---------
FCL has no semi-infinite prism: each pair uses extrusions of length
``standin_lengths(...).length`` (see :func:`prismbatch.lab.peers.standin_lengths`:
provably long enough except for axes within ~1e-6 rad of parallel, flagged
unsound), rounded up to a power of two so that FCL objects can be reused
within a block. The rule is checked: wherever the LP is run with margin
``> -band``, the LP margin of the finite stand-ins is computed too; a pair
whose semi-infinite bodies overlap (beyond the band) but whose stand-ins do
not is counted as "stand-in too short", separately from real disagreements.
(Where the semi-infinite bodies are separated, the stand-ins, being subsets,
are too.)

Contacts
--------
With ``contact_check=True`` prismbatch is also run with ``contact=True`` on
every pair and every hit's contact point is checked, vectorised in NumPy,
against both bodies: the point-in-prism residual (largest violated half-space,
a lower bound of the distance) must be at most ``2 tol + 4 eps |x|``, the
documented bound plus the rounding of the point's own coordinates (contacts of
nearly parallel axes can lie very far out). Non-finite contacts on hits are
counted separately.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..collide import DEFAULT_RTOL, Collider, pair_scale_tolerance
from ..shapes import Prism

__all__ = ["validate", "ValidationResult", "format_validation", "write_validation", "run_chunk",
           "generate_block", "make_config", "BLOCK_SIZE", "DISTRIBUTION_NAMES", "SHAPE_KINDS",
           "RECORD_KINDS", "LP_REL"]

#: Pairs per block: the unit of generation and seeding (not the chunk size).
BLOCK_SIZE = 4096

#: Every distribution, in the order that fixes its seed stream (spawn_key[0]).
DISTRIBUTION_NAMES = ("facing", "free", "near-contact", "degenerate")

#: Shape families: regular n-gons, random convex polygons, cylinders fitted by n-gons.
SHAPE_KINDS = ("regular", "random", "cylinder")

#: Cases the ``degenerate`` distribution builds exactly (prismbatch.lab.casegen).
DEGENERATE_CASES = (2, 3, 4, 7, 8)

#: Record kinds, most severe first (a pair with several gets the first as "kind").
RECORD_KINDS = ("outside band", "non-finite", "invalid contact", "stand-in too short", "inside band")

#: Accuracy floor of the LP reference, relative to the scene scale S.
LP_REL = 1e-7

_NC = 12  # case index 0..11 (0 unused)
_CASE_COUNTERS = ("pairs_case", "hits_case", "fcl_in_band", "fcl_out_pb", "fcl_out_fcl", "fcl_standin_short",
                  "fcl_unarbitrated", "lp_band", "lp_in_band", "lp_out")
_INT_COUNTERS = ("pairs", "hits", "fcl_pairs", "lp_pairs", "lp_arbitration", "lp_failed", "standin_checked",
                 "standin_short", "standin_unsound", "contact_checked", "contact_invalid", "nonfinite",
                 "bad_case", "status_mismatch", "degenerate_substituted", "near_contact_unseparated",
                 "exact_pairs", "exact_wrong", "exact_band", "exact_unknown")
_MAX_COUNTERS = ("contact_max_ratio", "standin_max_dev")
_TIMES = ("gen", "pb", "pb_contact", "fcl", "fcl_setup", "lp", "check")


# ---------------------------------------------------------------------------
# configuration
# ---------------------------------------------------------------------------


def make_config(n_pairs=100_000, *, distributions=("facing", "free", "near-contact", "degenerate"),
                shapes="regular", vertices=(36, 360), seed=0, dtype="float64", rtol=None, atol=0.0,
                fcl=True, lp_samples=2000, contact_check=True, max_band_records=1000):
    """Check the validation settings and return them as a plain, JSON-able dict.

    See :func:`validate` for the parameters. The dict is what chunk tasks
    receive (with the distribution and block range): no arrays.
    """
    if isinstance(n_pairs, bool) or not isinstance(n_pairs, (int, np.integer)) or n_pairs < 1:
        raise ValueError(f"n_pairs must be an integer >= 1, got {n_pairs!r}")
    if isinstance(distributions, str):
        distributions = (distributions,)
    distributions = tuple(distributions)
    if not distributions:
        raise ValueError("distributions must name at least one of " + ", ".join(DISTRIBUTION_NAMES))
    for d in distributions:
        if d not in DISTRIBUTION_NAMES:
            raise ValueError(f"distributions: unknown distribution {d!r}; choose from "
                             + ", ".join(DISTRIBUTION_NAMES) + " ('stiff' is the stiff=True option)")
    if len(set(distributions)) != len(distributions):
        raise ValueError(f"distributions: repeated names in {distributions}")
    shapes = (shapes,) if isinstance(shapes, str) else tuple(shapes)
    if not shapes or any(s not in SHAPE_KINDS for s in shapes):
        raise ValueError(f"shapes must be one of {SHAPE_KINDS} or a sequence of them (cycled per block), "
                         f"got {shapes!r}")
    vertices = (vertices,) if isinstance(vertices, (int, np.integer)) else tuple(vertices)
    if not vertices or any(isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 3
                           for v in vertices):
        raise ValueError(f"vertices must be an integer >= 3 or a sequence of them, got {vertices!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    dt = np.dtype(dtype) if not isinstance(dtype, str) else np.dtype(dtype)
    if dt not in DEFAULT_RTOL:
        raise ValueError(f"dtype must be 'float64' or 'float32', got {dtype!r}")
    rtol = float(DEFAULT_RTOL[dt] if rtol is None else rtol)
    atol = float(atol)
    if not (math.isfinite(rtol) and rtol >= 0 and math.isfinite(atol) and atol >= 0):
        raise ValueError(f"rtol and atol must be finite and >= 0, got rtol={rtol}, atol={atol}")
    if isinstance(fcl, bool):
        fcl_frac = 1.0 if fcl else 0.0
    elif isinstance(fcl, (float, int, np.floating, np.integer)) and 0.0 < float(fcl) <= 1.0:
        fcl_frac = float(fcl)
    else:
        raise ValueError(f"fcl must be True, False or a fraction in (0, 1] of the pairs, got {fcl!r}")
    if isinstance(lp_samples, bool) or not isinstance(lp_samples, (int, np.integer)) or lp_samples < 0:
        raise ValueError(f"lp_samples must be an integer >= 0 (per distribution), got {lp_samples!r}")
    if not isinstance(contact_check, (bool, np.bool_)):
        raise TypeError(f"contact_check must be True or False, got {contact_check!r}")
    if (isinstance(max_band_records, bool) or not isinstance(max_band_records, (int, np.integer))
            or max_band_records < 0):
        raise ValueError(f"max_band_records must be an integer >= 0, got {max_band_records!r}")
    return {"n_pairs": int(n_pairs), "distributions": list(distributions), "shapes": list(shapes),
            "vertices": [int(v) for v in vertices], "seed": int(seed), "dtype": dt.name, "rtol": rtol,
            "atol": atol, "fcl_fraction": fcl_frac, "lp_samples": int(lp_samples),
            "contact_check": bool(contact_check), "max_band_records": int(max_band_records),
            "block_size": BLOCK_SIZE, "lp_rel": LP_REL}


def _n_blocks(cfg):
    return -(-cfg["n_pairs"] // cfg["block_size"])


def _block_len(cfg, block):
    B = cfg["block_size"]
    return min(B, cfg["n_pairs"] - block * B)


def _streams(cfg, distribution, block):
    """Independent generators for (shapes, poses, fcl subsample, lp subsample) of one block."""
    ss = np.random.SeedSequence(cfg["seed"], spawn_key=(DISTRIBUTION_NAMES.index(distribution), block))
    return [np.random.default_rng(s) for s in ss.spawn(4)]


# ---------------------------------------------------------------------------
# generation
# ---------------------------------------------------------------------------


def _make_shape(kind, n, rng):
    """One polygon of a family with ``n`` vertices, random size, phase and offset."""
    if kind == "cylinder":
        r = rng.uniform(0.5, 1.5)
        # Fitted n-gon: circumscribed about the circle (contains it, like the paper's 3600-gon).
        return Prism.regular(n, r / math.cos(math.pi / n), phase=rng.uniform(0, 2 * np.pi),
                             centre=rng.uniform(-0.3, 0.3, 2) * r)
    radius = rng.uniform(1.0, 3.0)
    centre = rng.uniform(-0.3, 0.3, 2) * radius
    if kind == "regular":
        return Prism.regular(n, radius, phase=rng.uniform(0, 2 * np.pi), centre=centre)
    # random: vertices on a random ellipse at jittered angles (convex position;
    # jitter within strata keeps neighbours apart and no gap above pi).
    for _ in range(20):
        ang = 2 * np.pi * (np.arange(n) + rng.uniform(0.1, 0.9, n)) / n
        aspect = rng.uniform(0.3, 1.0)
        th = rng.uniform(0, 2 * np.pi)
        c, s = math.cos(th), math.sin(th)
        pts = np.column_stack([np.cos(ang), aspect * np.sin(ang)]) @ np.array([[c, s], [-s, c]])
        try:
            return Prism(pts * radius + centre)
        except ValueError:  # rounding made a near-straight turn a dent: draw again
            continue
    raise RuntimeError(f"could not draw a random convex {n}-gon")


def _block_shapes(cfg, block, rng):
    kind = cfg["shapes"][block % len(cfg["shapes"])]
    v = cfg["vertices"]
    return _make_shape(kind, v[block % len(v)], rng), _make_shape(kind, v[(block + 1) % len(v)], rng)


def _world_centres(shape, pos, rot):
    return pos + rot[:, :, :2] @ shape.centre


def _near_contact(sa, sb, m, rng, rtol):
    """Poses a few tolerances from touching, on both sides.

    Start overlapping (b's end-face centroid inside a), move b along a random
    direction that separates them, bisect prismbatch's decision to the
    boundary, then step off it by a log-uniform distance in
    [0.1, 1e4] x rtol x S, inward or outward with equal odds. The set of hitting
    translations along a line is an interval, so the boundary is unique.
    """
    from ..sampling import facing_poses, free_poses

    R = max(sa.radius, sb.radius)
    h = m // 2
    parts = [facing_poses(h, rng, radius=R), free_poses(m - h, rng, radius=R)]
    pos_a, rot_a, pos_b, rot_b = (np.concatenate([p[i] for p in parts]) for i in range(4))
    ca = _world_centres(sa, pos_a, rot_a)
    depth = rng.uniform(0.05, 1.0, m) * sa.radius
    pos_b = ca + depth[:, None] * rot_a[:, :, 2] - rot_b[:, :, :2] @ sb.centre
    col = Collider(sa, sb)
    far = 4.0 * (sa.radius + sb.radius)
    u = np.zeros((m, 3))
    todo = np.ones(m, bool)
    for _ in range(30):
        cand = rng.standard_normal((m, 3))
        cand /= np.linalg.norm(cand, axis=1, keepdims=True)
        if not todo.any():
            continue  # keep the stream's use independent of the outcome
        miss = ~col.collide(pos_a, rot_a, pos_b + far * cand, rot_b).hit
        ok = todo & miss
        u[ok] = cand[ok]
        todo &= ~ok
    lo, hi = np.zeros(m), np.full(m, far)
    for _ in range(56):
        mid = 0.5 * (lo + hi)
        hit = col.collide(pos_a, rot_a, pos_b + mid[:, None] * u, rot_b).hit
        lo = np.where(hit, mid, lo)
        hi = np.where(hit, hi, mid)
    cb = _world_centres(sb, pos_b + hi[:, None] * u, rot_b)
    S = sa.radius + sb.radius + np.linalg.norm(cb - ca, axis=1)
    rel = 10.0 ** rng.uniform(math.log10(0.1 * rtol), math.log10(1e4 * rtol), m)
    sign = np.where(rng.random(m) < 0.5, -1.0, 1.0)
    s = np.where(todo, 0.0, hi + sign * rel * S)  # never separated: left overlapping (a sure hit)
    return pos_a, rot_a, pos_b + s[:, None] * u, rot_b, int(todo.sum())


def _degenerate(sa, sb, m, rng, block):
    """Exact cases 2, 3, 4, 7, 8 (prismbatch.lab.casegen), half hits; a random world frame on odd blocks."""
    from .casegen import case_poses

    k = len(DEGENERATE_CASES)
    sizes = [m // k + (1 if j < m % k else 0) for j in range(k)]
    parts, substituted = [], 0
    for j, size in enumerate(sizes):
        if size == 0:
            continue
        for t in range(k):  # a case the shapes cannot produce (e.g. no clear vertex): the next one
            case = DEGENERATE_CASES[(j + t) % k]
            try:
                parts.append(case_poses(case, size, sa, sb, rng, hit_fraction=0.5,
                                        world_transform=bool(block % 2)))
                break
            except RuntimeError:
                substituted += size
        else:
            raise RuntimeError(f"degenerate: no case of {DEGENERATE_CASES} can be built for these shapes "
                               f"({sa!r}, {sb!r})")
    return tuple(np.concatenate([p[i] for p in parts]) for i in range(4)) + (substituted,)


@dataclass
class Block:
    """Inputs of one block: two shapes and (m,) pose pairs (float64, rounded to the run's dtype)."""

    distribution: str
    block: int
    spawn_key: tuple
    shape_a: Prism
    shape_b: Prism
    pos_a: np.ndarray
    rot_a: np.ndarray
    pos_b: np.ndarray
    rot_b: np.ndarray
    rngs: list = field(repr=False, default=None)
    notes: dict = field(default_factory=dict)


def generate_block(config, distribution, block):
    """Regenerate the inputs of one block of a validation run.

    Parameters
    ----------
    config : dict
        ``ValidationResult.config`` (or :func:`make_config`'s output).
    distribution : str
        One of ``config["distributions"]``.
    block : int
        Block number, ``0 <= block < ceil(n_pairs / BLOCK_SIZE)``.

    Returns
    -------
    Block
        Shapes and poses exactly as the run used them (float64 arrays holding
        values rounded to the run's dtype).
    """
    if distribution not in DISTRIBUTION_NAMES:
        raise ValueError(f"distribution must be one of {DISTRIBUTION_NAMES}, got {distribution!r}")
    if not (0 <= int(block) < _n_blocks(config)):
        raise ValueError(f"block must be in [0, {_n_blocks(config)}), got {block}")
    block = int(block)
    m = _block_len(config, block)
    rng_shape, rng_pose, rng_fcl, rng_lp = _streams(config, distribution, block)
    sa, sb = _block_shapes(config, block, rng_shape)
    notes = {}
    if distribution == "facing":
        from ..sampling import facing_poses
        P = facing_poses(m, rng_pose, radius=max(sa.radius, sb.radius))
    elif distribution == "free":
        from ..sampling import free_poses
        P = free_poses(m, rng_pose, radius=max(sa.radius, sb.radius))
    elif distribution == "near-contact":
        *P, notes["near_contact_unseparated"] = _near_contact(sa, sb, m, rng_pose, config["rtol"])
    else:
        *P, notes["degenerate_substituted"] = _degenerate(sa, sb, m, rng_pose, block)
    dt = np.dtype(config["dtype"])
    # Every method sees the poses prismbatch sees (rounded to the run's dtype).
    P = [np.ascontiguousarray(np.asarray(x, dtype=dt), dtype=np.float64) for x in P]
    return Block(distribution, block, (DISTRIBUTION_NAMES.index(distribution), block), sa, sb, *P,
                 rngs=[rng_fcl, rng_lp], notes=notes)


# ---------------------------------------------------------------------------
# one block
# ---------------------------------------------------------------------------


def _pair_scale_tol(cfg, sa, sb, pos_a, rot_a, pos_b, rot_b):
    S, tol = pair_scale_tolerance(sa, sb, pos_a, rot_a, pos_b, rot_b, rtol=cfg["rtol"], atol=cfg["atol"],
                                  dtype=cfg["dtype"])
    return S, tol, np.maximum(tol, LP_REL * S)


def _residuals(shape, pos, rot, x):
    """Point-in-prism residual of points x (m, 3) for one shape at m poses (vectorised)."""
    from .exact import polygon_halfplanes

    n2, h = polygon_halfplanes(shape.xy)
    local = np.einsum("mji,mj->mi", rot, x - pos)  # R^T (x - p)
    out = -local[:, 2]
    step = max(1, 2_000_000 // len(h))
    for s in range(0, len(x), step):
        side = local[s:s + step, :2] @ n2.T - h
        out[s:s + step] = np.maximum(out[s:s + step], side.max(axis=1))
    return out


def _empty_counts():
    c = {k: np.zeros(_NC, np.int64) for k in _CASE_COUNTERS}
    c["fcl_conf"] = np.zeros((_NC, 2, 2), np.int64)
    c["lp_conf"] = np.zeros((_NC, 2, 2), np.int64)
    c.update({k: 0 for k in _INT_COUNTERS})
    c.update({k: 0.0 for k in _MAX_COUNTERS})
    return c


def _merge_counts(acc, c):
    for k, v in c.items():
        if k in _MAX_COUNTERS:
            acc[k] = max(acc[k], v)
        else:
            acc[k] = acc[k] + v
    return acc


def _record(cfg, blk, k, kinds, *, tol, band, scale, hit, case, contact, fcl, length, lp, lp_fin, at_fault):
    kinds = sorted(set(kinds), key=RECORD_KINDS.index)
    f = lambda x: None if x is None or not math.isfinite(x) else float(x)  # noqa: E731
    return {
        "kind": kinds[0], "kinds": kinds, "at_fault": at_fault,
        "distribution": blk.distribution, "block": blk.block, "index": int(k), "seed": cfg["seed"],
        "spawn_key": list(blk.spawn_key),
        "shape_a": blk.shape_a.xy.tolist(), "shape_b": blk.shape_b.xy.tolist(),
        "pos_a": blk.pos_a[k].tolist(), "rot_a": blk.rot_a[k].tolist(),
        "pos_b": blk.pos_b[k].tolist(), "rot_b": blk.rot_b[k].tolist(),
        "dtype": cfg["dtype"], "rtol": cfg["rtol"], "atol": cfg["atol"], "tol": float(tol),
        "band": float(band), "scale": float(scale),
        "prismbatch": {"hit": bool(hit), "case": int(case),
                       "contact": None if contact is None else [float(x) for x in contact]},
        "references": {"fcl": None if fcl is None else bool(fcl), "standin_length": f(length),
                       "lp_margin": f(lp), "lp_margin_standin": f(lp_fin)},
    }


def _process_block(cfg, distribution, block, threads=None):
    """Generate and check one block; returns ``(key, counts, times, records)``."""
    from .exact import margin_lp
    from .peers import standin_lengths

    times = dict.fromkeys(_TIMES, 0.0)
    times["fcl_pairs"] = times["lp_calls"] = 0
    t0 = time.perf_counter()
    blk = generate_block(cfg, distribution, block)
    times["gen"] = time.perf_counter() - t0
    rng_fcl, rng_lp = blk.rngs
    sa, sb = blk.shape_a, blk.shape_b
    P = (blk.pos_a, blk.rot_a, blk.pos_b, blk.rot_b)
    m = len(blk.pos_a)
    c = _empty_counts()
    for k, v in blk.notes.items():
        c[k] += int(v)
    S, tol, band = _pair_scale_tol(cfg, sa, sb, *P)
    parallel = None if threads is None else threads > 1

    # prismbatch: status only (timed like FCL), then with contacts.
    col = Collider(sa, sb, rtol=cfg["rtol"], atol=cfg["atol"], dtype=cfg["dtype"])
    # prismbatch gets the poses in its own dtype (its orthonormality check depends on it)
    Pc = tuple(np.ascontiguousarray(x, dtype=cfg["dtype"]) for x in P)
    t = time.perf_counter()
    r = col.collide(*Pc, parallel=parallel)
    times["pb"] = time.perf_counter() - t
    hit, case = r.hit.copy(), r.case.astype(np.int64)
    bad_case = (case < 1) | (case > 11)
    c["bad_case"] = int(bad_case.sum())
    case = np.where(bad_case, 0, case)
    contact = None
    kinds = {}  # pair index -> list of record kinds

    def flag(k, kind):
        kinds.setdefault(int(k), []).append(kind)

    if cfg["contact_check"]:
        t = time.perf_counter()
        rc = col.collide(*Pc, contact=True, parallel=parallel)
        times["pb_contact"] = time.perf_counter() - t
        contact = np.asarray(rc.contact, dtype=np.float64)
        c["status_mismatch"] = int(np.sum((rc.hit != r.hit) | (rc.case != r.case)))
        t = time.perf_counter()
        hi = np.flatnonzero(hit)
        finite = np.isfinite(contact[hi]).all(axis=1)
        for k in hi[~finite]:
            flag(k, "non-finite")
        c["nonfinite"] = int((~finite).sum())
        ok = hi[finite]
        if ok.size:
            x = contact[ok]
            res = np.maximum(_residuals(sa, blk.pos_a[ok], blk.rot_a[ok], x),
                             _residuals(sb, blk.pos_b[ok], blk.rot_b[ok], x))
            eps = float(np.finfo(np.dtype(cfg["dtype"])).eps)
            bound = 2 * tol[ok] + 4 * eps * np.linalg.norm(x, axis=1)
            bad = res > bound
            for k in ok[bad]:
                flag(k, "invalid contact")
            c["contact_checked"] = int(ok.size)
            c["contact_invalid"] = int(bad.sum())
            c["contact_max_ratio"] = float(np.max(res / tol[ok]))
        times["check"] = time.perf_counter() - t
    np.add.at(c["pairs_case"], case, 1)
    np.add.at(c["hits_case"], case[hit], 1)
    c["pairs"], c["hits"] = m, int(hit.sum())

    # stand-in lengths (power of two >= the rule: FCL objects reused within the block)
    sl = standin_lengths(sa.xy, sb.xy, *P)
    Lq = 2.0 ** np.ceil(np.log2(sl.length))

    # FCL on all pairs or a subsample
    fcl_hit = np.full(m, -1, np.int8)
    sel = rng_fcl.random(m) < cfg["fcl_fraction"] if cfg["fcl_fraction"] < 1.0 else np.ones(m, bool)
    fidx = np.flatnonzero(sel) if cfg["fcl_fraction"] > 0.0 else np.zeros(0, np.int64)
    if fidx.size:
        from .peers import FCLPeer

        for L in np.unique(Lq[fidx]):
            grp = fidx[Lq[fidx] == L]
            t = time.perf_counter()
            peer = FCLPeer(sa.xy, sb.xy, float(L))
            items = peer.prepare(*(x[grp] for x in P))
            times["fcl_setup"] += time.perf_counter() - t
            t = time.perf_counter()
            fcl_hit[grp] = peer.run(items)
            times["fcl"] += time.perf_counter() - t
        times["fcl_pairs"] = int(fidx.size)
        c["fcl_pairs"] = int(fidx.size)
        c["standin_unsound"] = int((~sl.sound[fidx]).sum())
        np.add.at(c["fcl_conf"], (case[fidx], hit[fidx].astype(int), fcl_hit[fidx].astype(int)), 1)

    # LP: a random subsample (its share of lp_samples) + every FCL disagreement
    nb = _n_blocks(cfg)
    share = min(m, (block + 1) * cfg["lp_samples"] // nb - block * cfg["lp_samples"] // nb)
    lp_idx = np.sort(rng_lp.choice(m, share, replace=False)) if share else np.zeros(0, np.int64)
    dis = fidx[hit[fidx] != fcl_hit[fidx].astype(bool)]
    todo = np.union1d(lp_idx, dis)
    lp = np.full(m, np.nan)
    lp_fin = np.full(m, np.nan)
    xa, xb = sa.xy, sb.xy
    for k in todo:
        t = time.perf_counter()
        try:
            lp[k] = margin_lp(xa, blk.pos_a[k], blk.rot_a[k], xb, blk.pos_b[k], blk.rot_b[k])
            if cfg["fcl_fraction"] > 0.0 and lp[k] > -band[k]:
                # stand-in check; below -band the stand-ins (subsets) are separated too
                lp_fin[k] = margin_lp(xa, blk.pos_a[k], blk.rot_a[k], xb, blk.pos_b[k], blk.rot_b[k],
                                      length_a=Lq[k], length_b=Lq[k])
                times["lp_calls"] += 1
        except RuntimeError:
            c["lp_failed"] += 1
        times["lp"] += time.perf_counter() - t
        times["lp_calls"] += 1
    c["lp_pairs"], c["lp_arbitration"] = int(lp_idx.size), int(np.setdiff1d(dis, lp_idx).size)
    chk = np.flatnonzero(np.isfinite(lp_fin))
    c["standin_checked"] = int(chk.size)
    short = np.zeros(m, bool)
    short[chk] = (lp[chk] > band[chk]) & (lp_fin[chk] <= band[chk])
    c["standin_short"] = int(short.sum())
    meet = chk[lp[chk] > band[chk]]
    if meet.size:
        c["standin_max_dev"] = float(np.max(np.abs(lp_fin[meet] - lp[meet]) / S[meet]))

    # The LP is not certain inside its band: there the exact reference judges
    # the pair at tol itself (gap <= tol must hit, gap > 2 tol must miss).
    exact = _exact_verdicts(blk, sa, sb, tol, np.union1d(lp_idx, dis)[
        np.abs(lp[np.union1d(lp_idx, dis)]) <= band[np.union1d(lp_idx, dis)]], c)
    fault = {}
    # LP subsample: confusion and disagreements
    ok = lp_idx[np.isfinite(lp[lp_idx])]
    truth = lp[ok] > 0
    np.add.at(c["lp_conf"], (case[ok], hit[ok].astype(int), truth.astype(int)), 1)
    inb = np.abs(lp[ok]) <= band[ok]
    np.add.at(c["lp_band"], case[ok[inb]], 1)
    wrong = hit[ok] != truth
    np.add.at(c["lp_in_band"], case[ok[wrong & inb]], 1)
    np.add.at(c["lp_out"], case[ok[wrong & ~inb]], 1)
    for k in ok[wrong & inb]:
        flag(k, "inside band")
    for k in ok[wrong & ~inb]:
        flag(k, "outside band")
        fault[int(k)] = "prismbatch"
    for k, verdict in exact.items():  # judged at tol by the exact reference
        if (verdict == "hit") != bool(hit[k]) and verdict in ("hit", "miss"):
            c["exact_wrong"] += 1
            flag(k, "outside band")
            fault[int(k)] = "prismbatch (exact reference, at tol)"
    # FCL disagreements, arbitrated by the LP (by the exact reference inside the LP's band)
    for k in dis:
        cs = case[k]
        if not np.isfinite(lp[k]):
            c["fcl_unarbitrated"][cs] += 1
            flag(k, "outside band")
            fault.setdefault(int(k), "unknown (LP failed)")
        elif abs(lp[k]) <= band[k]:
            c["fcl_in_band"][cs] += 1
            if exact.get(int(k)) in ("hit", "miss") and (exact[int(k)] == "hit") == bool(hit[k]):
                fault.setdefault(int(k), "fcl (exact reference, at tol)")
            flag(k, "inside band")
        elif hit[k] != (lp[k] > 0):
            c["fcl_out_pb"][cs] += 1
            flag(k, "outside band")
            fault[int(k)] = "prismbatch"
        elif short[k]:
            c["fcl_standin_short"][cs] += 1
            flag(k, "stand-in too short")
            fault.setdefault(int(k), "stand-in")
        else:
            c["fcl_out_fcl"][cs] += 1
            flag(k, "outside band")
            fault.setdefault(int(k), "fcl")
    for k in np.flatnonzero(short):
        if k not in dis:  # FCL was right anyway (or not run on it): still a failed stand-in check
            flag(k, "stand-in too short")
            fault.setdefault(int(k), "stand-in")

    records = []
    for k in sorted(kinds):
        records.append(_record(
            cfg, blk, k, kinds[k], tol=tol[k], band=band[k], scale=S[k], hit=hit[k], case=case[k],
            contact=None if contact is None or not hit[k] else contact[k],
            fcl=None if fcl_hit[k] < 0 else bool(fcl_hit[k]), length=Lq[k] if fcl_hit[k] >= 0 else None,
            lp=lp[k], lp_fin=lp_fin[k], at_fault=fault.get(k)))
    return (DISTRIBUTION_NAMES.index(distribution), block), c, times, records


def _exact_verdicts(blk, sa, sb, tol, idx, c):
    """Exact verdicts at tol ("hit", "miss", "band", "unknown") for pairs idx; counts them in c."""
    if not len(idx):
        return {}
    from .exact_gap import judge_pair

    out = {}
    for k in idx:
        v = judge_pair(sa.xy, blk.pos_a[k], blk.rot_a[k], sb.xy, blk.pos_b[k], blk.rot_b[k], tol[k]).verdict
        out[int(k)] = v
        c["exact_band"] += v == "band"
        c["exact_unknown"] += v == "unknown"
    c["exact_pairs"] += len(idx)
    return out


def run_chunk(config, distribution, first_block, n_blocks, threads=None):
    """Run blocks ``first_block .. first_block + n_blocks - 1`` of one distribution.

    The unit of work sent to Dask workers: its arguments are the settings and
    a block range, never arrays.

    Parameters
    ----------
    config : dict
        From :func:`make_config`.
    distribution : str
        Distribution name.
    first_block, n_blocks : int
        Block range.
    threads : int or None, optional
        Numba threads for this task (set with ``numba.set_num_threads``,
        which is per calling thread); None keeps the current setting.

    Returns
    -------
    list of tuple
        One ``(key, counts, times, records)`` per block, in block order.
    """
    if threads is not None:
        import numba

        numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))
    return [_process_block(config, distribution, b, threads) for b in range(first_block, first_block + n_blocks)]


# ---------------------------------------------------------------------------
# result, merge, driver
# ---------------------------------------------------------------------------


@dataclass
class ValidationResult:
    """Merged outcome of :func:`validate`.

    Attributes
    ----------
    config : dict
        The settings (:func:`make_config`).
    counts : dict
        Per distribution, the counters: ``pairs``, ``hits``; per case (arrays
        indexed by case number 0-11, 0 unused) ``pairs_case``, ``hits_case``;
        ``fcl_conf`` / ``lp_conf`` (12, 2, 2) confusion counts indexed
        ``[case, prismbatch hit, reference hit]``; FCL disagreements
        ``fcl_in_band``, ``fcl_out_pb`` (prismbatch wrong outside the band),
        ``fcl_out_fcl`` (FCL wrong, stand-in long enough),
        ``fcl_standin_short``, ``fcl_unarbitrated``; LP subsample
        ``lp_band`` (pairs inside the band), ``lp_in_band``, ``lp_out``
        (disagreements); ``standin_checked``, ``standin_short``,
        ``standin_unsound``, ``standin_max_dev`` (max |finite - semi-infinite
        LP margin| / S where the bodies meet); ``contact_checked``,
        ``contact_invalid``, ``contact_max_ratio`` (max residual / tol),
        ``nonfinite``, ``bad_case``, ``status_mismatch``.
    times : dict
        Per distribution, seconds: ``pb`` (status batches, compile excluded),
        ``pb_contact``, ``fcl`` (queries), ``fcl_setup``, ``lp`` and the
        numbers ``fcl_pairs``, ``lp_calls``.
    records : list of dict
        Disagreements (see :data:`RECORD_KINDS`) in (distribution, block,
        index) order; "inside band" ones capped at
        ``config["max_band_records"]``.
    records_total : int
        Number of records before the cap.
    compile_time : float
        Seconds of the first (compiling or cache-loading) calls, in-process.
    wall_time : float
        Seconds of the Monte Carlo run (compile included; the stiff suite,
        when requested, reports its own time).
    execution : dict
        Scheduler, workers and thread counts.
    stiff : object or None
        The stiff suite's report (``prismbatch.lab.stiff``) when requested.
    """

    config: dict
    counts: dict
    times: dict
    records: list
    records_total: int
    compile_time: float
    wall_time: float
    execution: dict
    stiff: object = None

    def totals(self):
        """Counters summed over the distributions."""
        acc = _empty_counts()
        for c in self.counts.values():
            _merge_counts(acc, c)
        return acc

    @property
    def ok(self):
        """True when prismbatch has no disagreement outside the band (nor an unarbitrated one), no
        invalid contact and no non-finite or invalid output (the stiff suite reports its own)."""
        t = self.totals()
        return (int(t["fcl_out_pb"].sum()) == 0 and int(t["lp_out"].sum()) == 0 and t["exact_wrong"] == 0
                and int(t["fcl_unarbitrated"].sum()) == 0 and t["contact_invalid"] == 0
                and t["nonfinite"] == 0 and t["bad_case"] == 0 and t["status_mismatch"] == 0)

    def outcome(self):
        """Everything that must not depend on chunking or workers (no timings)."""
        return {"config": self.config, "records_total": self.records_total, "records": self.records,
                "counts": {d: {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in c.items()}
                           for d, c in self.counts.items()}}


def _warm(dtype):
    """Compile (or load from the on-disk cache) the kernels a run uses; returns seconds."""
    t = time.perf_counter()
    a, b = Prism.regular(5, 2.0), Prism.regular(6, 2.5)
    P = (np.zeros((2, 3)), np.broadcast_to(np.diag([1.0, -1.0, -1.0]), (2, 3, 3)).copy(),
         np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 0.0]]), np.broadcast_to(np.eye(3), (2, 3, 3)).copy())
    for dt in {np.dtype(dtype), np.dtype(np.float64)}:  # generation uses float64
        col = Collider(a, b, dtype=dt)
        for contact in (False, True):
            for par in (False, True):
                col.collide(*P, contact=contact, parallel=par)
    return time.perf_counter() - t


def _chunk_specs(cfg, chunk_size):
    per = max(1, int(round(chunk_size / cfg["block_size"])))
    nb = _n_blocks(cfg)
    return [(d, first, min(per, nb - first)) for d in cfg["distributions"] for first in range(0, nb, per)]


def _spec_pairs(cfg, spec):
    d, first, n = spec
    return sum(_block_len(cfg, b) for b in range(first, first + n))


class _Merger:
    """Accumulates block results in block order, whatever order chunks arrive in."""

    def __init__(self, cfg):
        self.cfg = cfg
        self.counts = {d: _empty_counts() for d in cfg["distributions"]}
        self.times = {d: {**dict.fromkeys(_TIMES, 0.0), "fcl_pairs": 0, "lp_calls": 0}
                      for d in cfg["distributions"]}
        self.records = []
        self.total = 0
        self.band_total = 0

    def add(self, chunk):
        new = []
        for key, c, t, recs in chunk:
            d = DISTRIBUTION_NAMES[key[0]]
            _merge_counts(self.counts[d], c)
            for k, v in t.items():
                self.times[d][k] += v
            new.extend(recs)
            self.total += len(recs)
        order = lambda r: (r["spawn_key"][0], r["block"], r["index"])  # noqa: E731
        # Every record is kept except "inside band" ones (expected, and plenty near contact):
        # the first max_band_records of those in block order, the same set for any chunking.
        self.band_total += sum(r["kind"] == "inside band" for r in new)
        recs = sorted(self.records + new, key=order)
        band = [r for r in recs if r["kind"] == "inside band"][: self.cfg["max_band_records"]]
        keep = {id(r) for r in band}
        self.records = [r for r in recs if r["kind"] != "inside band" or id(r) in keep]


def validate(n_pairs=100_000, *, distributions=("facing", "free", "near-contact", "degenerate"),
             shapes="regular", vertices=(36, 360), seed=0, chunk_size=50_000, dtype="float64", rtol=None,
             atol=0.0, fcl=True, lp_samples=2000, contact_check=True, max_band_records=1000, stiff=False,
             scheduler=None, workers=None, progress=True):
    """Monte Carlo validation of prismbatch against python-fcl and the exact LP.

    Parameters
    ----------
    n_pairs : int, optional
        Pose pairs PER DISTRIBUTION (default 100,000). Processed in chunks
        of blocks: memory stays bounded for any ``n_pairs``.
    distributions : sequence of str, optional
        Any of ``"facing"`` (the paper's scene), ``"free"`` (uniform
        rotations, centres in a box), ``"near-contact"`` (within 0.1 to 1e4
        tolerances of touching, both sides) and ``"degenerate"`` (exact cases
        2, 3, 4, 7, 8 from :func:`prismbatch.lab.casegen.case_poses`).
    shapes : str or sequence of str, optional
        ``"regular"``, ``"random"`` (random convex polygons) or
        ``"cylinder"`` (circles fitted by circumscribed n-gons); a sequence is
        cycled over the blocks. Each block draws its own two shapes.
    vertices : int or sequence of int, optional
        Vertex counts, cycled over the blocks (a: ``vertices[i]``, b:
        ``vertices[i + 1]``, modulo the length).
    seed : int, optional
        The one seed; block ``i`` of distribution ``j`` uses
        ``SeedSequence(seed, spawn_key=(j, i))``.
    chunk_size : int, optional
        Pairs per chunk (rounded to whole blocks of :data:`BLOCK_SIZE`); does
        not change the results.
    dtype : {"float64", "float32"}, optional
        prismbatch's precision (poses are rounded to it for every method).
    rtol, atol : float, optional
        prismbatch's tolerances (default rtol per dtype, atol 0).
    fcl : bool or float, optional
        python-fcl on every pair (True, 6-50 us per pair), none (False) or
        on a random fraction in (0, 1] (for runs well above 1e6 pairs).
    lp_samples : int, optional
        Pairs per distribution on which the exact LP runs (milliseconds
        each), spread over the blocks; the LP also runs on every pair where
        prismbatch and FCL disagree.
    contact_check : bool, optional
        Compute contacts and check every hit's contact against both bodies.
    max_band_records : int, optional
        "inside band" records kept (the first ones in block order; they are
        allowed and plentiful near contact). Every other record is kept; all
        are counted.
    stiff : bool or "quick", optional
        Also run ``prismbatch.lab.stiff.run_stiff_suite`` (in-process).
    scheduler : str, optional
        Address of an existing Dask scheduler to send chunks to.
    workers : int, optional
        Start a local Dask cluster with this many worker processes (when no
        ``scheduler`` is given). Without either, runs in-process.
    progress : bool, optional
        Progress bar over pairs (tqdm, when installed).

    Returns
    -------
    ValidationResult

    Raises
    ------
    ValueError, TypeError
        Bad arguments (the message names the argument).
    ImportError
        A needed optional dependency is missing (scipy for the LP,
        python-fcl, dask); the message names the extra to install.
    """
    cfg = make_config(n_pairs, distributions=distributions, shapes=shapes, vertices=vertices, seed=seed,
                      dtype=dtype, rtol=rtol, atol=atol, fcl=fcl, lp_samples=lp_samples,
                      contact_check=contact_check, max_band_records=max_band_records)
    if isinstance(chunk_size, bool) or not isinstance(chunk_size, (int, np.integer)) or chunk_size < 1:
        raise ValueError(f"chunk_size must be an integer >= 1, got {chunk_size!r}")
    if stiff not in (False, True, "quick"):
        raise ValueError(f"stiff must be True, False or 'quick', got {stiff!r}")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, (int, np.integer))
                                or workers < 1):
        raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
    if scheduler is not None and not isinstance(scheduler, str):
        raise TypeError(f"scheduler must be an address string such as 'tcp://host:8786', got {scheduler!r}")
    # fail early on missing extras, not after an hour of work
    if cfg["lp_samples"] > 0 or cfg["fcl_fraction"] > 0:  # the LP also arbitrates FCL disagreements
        from .exact import _linprog
        _linprog()
    if cfg["fcl_fraction"] > 0:
        from .peers import _import_fcl
        _import_fcl()
    from .report import numba_threads
    from .report import progress as _progress

    t_start = time.perf_counter()
    compile_time = _warm(cfg["dtype"])
    specs = _chunk_specs(cfg, chunk_size)
    merger = _Merger(cfg)
    total = cfg["n_pairs"] * len(cfg["distributions"])
    with _progress(total, enabled=progress, unit="pair", desc="validate") as bar:
        if scheduler is None and workers is None:
            execution = {"scheduler": "in-process", "workers": 1, "numba_threads": numba_threads()}
            for spec in specs:
                merger.add(run_chunk(cfg, *spec))
                bar.update(_spec_pairs(cfg, spec))
        else:
            from .cluster import run_chunks

            def done(spec, chunk):
                merger.add(chunk)
                bar.update(_spec_pairs(cfg, spec))

            execution = run_chunks(cfg, specs, done, scheduler=scheduler, workers=workers)
    wall = time.perf_counter() - t_start  # the Monte Carlo run; the stiff suite reports its own time
    rep = None
    if stiff:
        from .stiff import run_stiff_suite

        rep = run_stiff_suite(quick=stiff == "quick", seed=cfg["seed"], progress=progress)
    return ValidationResult(cfg, merger.counts, merger.times, merger.records, merger.total, compile_time,
                            wall, execution, rep)


# ---------------------------------------------------------------------------
# output
# ---------------------------------------------------------------------------


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
        rows.append([d, c["pairs"], c["hits"], c["fcl_pairs"], fcl_agree, int(c["fcl_in_band"].sum()),
                     int(c["fcl_out_pb"].sum()), int(c["fcl_out_fcl"].sum()), int(c["fcl_standin_short"].sum()),
                     int(c["fcl_unarbitrated"].sum()), c["lp_pairs"], lp_agree, int(c["lp_band"].sum()),
                     int(c["lp_in_band"].sum()), int(c["lp_out"].sum()), c["lp_arbitration"], c["lp_failed"],
                     c["standin_checked"], c["standin_short"], c["standin_unsound"], c["standin_max_dev"],
                     c["contact_checked"], c["contact_invalid"], c["contact_max_ratio"], c["nonfinite"],
                     c["bad_case"], c["status_mismatch"],
                     c["exact_pairs"], c["exact_wrong"], c["exact_band"], c["exact_unknown"],
                     _per_pair(t["pb"], c["pairs"], 1e-6), _per_pair(t["pb_contact"], c["pairs"], 1e-6),
                     _per_pair(t["fcl"], t["fcl_pairs"], 1e-6), _per_pair(t["lp"], t["lp_calls"], 1e-3)])
    return rows


SUMMARY_HEADER = ["distribution", "pairs", "hits", "fcl_pairs", "fcl_agree", "fcl_disagree_in_band",
                  "fcl_disagree_out_band_prismbatch_wrong", "fcl_disagree_out_band_fcl_wrong",
                  "fcl_standin_too_short", "fcl_unarbitrated", "lp_pairs", "lp_agree", "lp_pairs_in_band",
                  "lp_disagree_in_band", "lp_disagree_out_band", "lp_arbitration_pairs", "lp_failed",
                  "standin_checked", "standin_too_short", "standin_unsound", "standin_max_dev_over_S",
                  "contacts_checked", "contacts_invalid", "contact_max_residual_over_tol", "nonfinite_contacts",
                  "invalid_cases", "status_contact_mismatch", "exact_pairs", "exact_wrong_at_tol", "exact_in_band",
                  "exact_unknown", "prismbatch_us_per_pair",
                  "prismbatch_contact_us_per_pair", "fcl_us_per_pair", "lp_ms_per_call"]

CASES_HEADER = ["distribution", "case", "reference", "pairs", "pb_hit_ref_hit", "pb_hit_ref_miss",
                "pb_miss_ref_hit", "pb_miss_ref_miss", "disagree_in_band", "disagree_out_band_prismbatch_wrong",
                "disagree_out_band_reference_wrong", "standin_too_short", "unarbitrated"]


def _case_rows(result):
    rows = []
    for d, c in result.counts.items():
        for cs in range(1, _NC):
            for ref in ("fcl", "lp"):
                m = c[f"{ref}_conf"][cs]
                if m.sum() == 0:
                    continue
                if ref == "fcl":
                    extra = [c["fcl_in_band"][cs], c["fcl_out_pb"][cs], c["fcl_out_fcl"][cs],
                             c["fcl_standin_short"][cs], c["fcl_unarbitrated"][cs]]
                else:
                    extra = [c["lp_in_band"][cs], c["lp_out"][cs], 0, 0, 0]
                rows.append([d, cs, ref, int(m.sum()), int(m[1, 1]), int(m[1, 0]), int(m[0, 1]), int(m[0, 0])]
                            + [int(x) for x in extra])
    return rows


def format_validation(result):
    """Terminal summary of a :class:`ValidationResult` as a list of lines."""
    cfg = result.config
    L = [f"prismbatch validate: {cfg['n_pairs']:,} pairs per distribution, shapes {'/'.join(cfg['shapes'])}, "
         f"vertices {cfg['vertices']}, dtype {cfg['dtype']} (rtol {cfg['rtol']:g}), seed {cfg['seed']}",
         f"  run: {result.execution.get('scheduler')}, {result.execution.get('workers')} worker(s); "
         f"wall {result.wall_time:.1f} s; compile/cache load {result.compile_time:.1f} s (excluded)"]
    for row in _summary_rows(result):
        r = dict(zip(SUMMARY_HEADER, row))
        L.append(f"{r['distribution']}: {r['pairs']:,} pairs, {r['hits']:,} hits")
        if r["fcl_pairs"]:
            L.append(f"  vs FCL ({r['fcl_pairs']:,} pairs): agree {r['fcl_agree']:,}; disagree inside band "
                     f"{r['fcl_disagree_in_band']}, outside band: prismbatch wrong "
                     f"{r['fcl_disagree_out_band_prismbatch_wrong']}, FCL wrong {r['fcl_disagree_out_band_fcl_wrong']}, "
                     f"stand-in too short {r['fcl_standin_too_short']}, unarbitrated {r['fcl_unarbitrated']}")
        if r["lp_pairs"]:
            L.append(f"  vs LP ({r['lp_pairs']:,} random pairs, {r['lp_pairs_in_band']} in band): agree "
                     f"{r['lp_agree']:,}; disagree inside band {r['lp_disagree_in_band']}, outside band "
                     f"{r['lp_disagree_out_band']}; LP failures {r['lp_failed']}")
        if r["exact_pairs"]:
            L.append(f"  exact reference at tol ({r['exact_pairs']} pairs the LP could not settle): prismbatch wrong "
                     f"{r['exact_wrong_at_tol']}, in [tol, 2 tol] {r['exact_in_band']}, not certified "
                     f"{r['exact_unknown']}")
        if r["standin_checked"]:
            L.append(f"  stand-in check: {r['standin_checked']} pairs, too short {r['standin_too_short']}, "
                     f"max |finite - infinite margin|/S {r['standin_max_dev_over_S']:.1e}; capped (unsound) "
                     f"lengths {r['standin_unsound']}")
        if cfg["contact_check"]:
            L.append(f"  contacts: {r['contacts_checked']:,} checked, {r['contacts_invalid']} invalid, max "
                     f"residual {r['contact_max_residual_over_tol']:.3g} tol; non-finite {r['nonfinite_contacts']}")
        L.append(f"  time per pair: prismbatch {r['prismbatch_us_per_pair']:.3g} us (status), "
                 f"{r['prismbatch_contact_us_per_pair']:.3g} us (contact); FCL {r['fcl_us_per_pair']:.3g} us; "
                 f"LP {r['lp_ms_per_call']:.3g} ms per call")
    kinds = {}
    for rec in result.records:
        kinds[rec["kind"]] = kinds.get(rec["kind"], 0) + 1
    L.append(f"records: {result.records_total} disagreement(s) in all, {len(result.records)} saved "
             f"({', '.join(f'{k}: {v}' for k, v in kinds.items()) or 'none'})")
    L.append("RESULT: " + ("OK, no disagreement outside the touching band, contacts valid" if result.ok
                           else "FAILURES (see the records)"))
    if result.stiff is not None:
        L.extend(result.stiff.summary_lines())
    return L


def _markdown(result):
    cfg = result.config
    L = ["# prismbatch validation", "",
         f"{cfg['n_pairs']:,} pose pairs per distribution ({', '.join(cfg['distributions'])}); shapes "
         f"{', '.join(cfg['shapes'])} with vertex counts {cfg['vertices']}; dtype {cfg['dtype']}, rtol "
         f"{cfg['rtol']:g}, atol {cfg['atol']:g}; seed {cfg['seed']}. FCL on "
         f"{cfg['fcl_fraction']:.0%} of the pairs, the exact LP on {cfg['lp_samples']:,} random pairs per "
         f"distribution plus every FCL disagreement. Run: {result.execution.get('scheduler')}, "
         f"{result.execution.get('workers')} worker(s), wall {result.wall_time:.1f} s.", "",
         "Touching band per pair: `band = max(tol, 1e-7 S)`, `S = R_a + R_b + |c_b - c_a|`. Outside it the "
         "LP decides; inside it any answer is allowed. FCL runs on finite stand-ins of length "
         "`peers.standin_lengths` (rounded up to a power of two), checked against the LP.", "",
         "**Result: " + ("no disagreement outside the band, every contact valid, no non-finite output."
                         if result.ok else "FAILURES, see the replay file.") + "**", "",
         "## Summary", ""]
    rows = [dict(zip(SUMMARY_HEADER, r)) for r in _summary_rows(result)]
    tables = (
        ("Agreement (disagreements outside the band are split by who the LP says is wrong)",
         [("distribution", "distribution"), ("pairs", "pairs"), ("hits", "hits"), ("FCL pairs", "fcl_pairs"),
          ("FCL agree", "fcl_agree"), ("FCL disagree, in band", "fcl_disagree_in_band"),
          ("outside, prismbatch wrong", "fcl_disagree_out_band_prismbatch_wrong"),
          ("outside, FCL wrong", "fcl_disagree_out_band_fcl_wrong"),
          ("stand-in too short", "fcl_standin_too_short"), ("LP pairs", "lp_pairs"),
          ("LP in band", "lp_pairs_in_band"), ("LP disagree, in band", "lp_disagree_in_band"),
          ("LP disagree, outside", "lp_disagree_out_band")]),
        ("Checks",
         [("distribution", "distribution"), ("contacts checked", "contacts_checked"),
          ("invalid contacts", "contacts_invalid"), ("max residual / tol", "contact_max_residual_over_tol"),
          ("non-finite contacts", "nonfinite_contacts"), ("invalid cases", "invalid_cases"),
          ("stand-ins checked", "standin_checked"), ("stand-in too short", "standin_too_short"),
          ("capped stand-ins", "standin_unsound"), ("max stand-in margin change / S", "standin_max_dev_over_S"),
          ("LP arbitration pairs", "lp_arbitration_pairs"), ("LP failures", "lp_failed")]),
        ("Time per pair (same pairs; noisy; compile excluded: " + f"{result.compile_time:.1f} s)",
         [("distribution", "distribution"), ("prismbatch status (µs)", "prismbatch_us_per_pair"),
          ("prismbatch with contact (µs)", "prismbatch_contact_us_per_pair"), ("FCL (µs)", "fcl_us_per_pair"),
          ("LP (ms per call)", "lp_ms_per_call")]),
    )
    for title, cols in tables:
        L += [f"### {title}", "", "| " + " | ".join(c[0] for c in cols) + " |", "|" + "---|" * len(cols)]
        L += ["| " + " | ".join(_fmt(r[c[1]]) for c in cols) + " |" for r in rows]
        L.append("")
    L += ["## Per case", ""]
    L.append("| " + " | ".join(h.replace("_", " ") for h in CASES_HEADER) + " |")
    L.append("|" + "---|" * len(CASES_HEADER))
    for row in _case_rows(result):
        L.append("| " + " | ".join(_fmt(x) for x in row) + " |")
    L += ["", "## Disagreement records", "",
          f"{result.records_total} records ({len(result.records)} kept in `validation_replay.json`), with full "
          "inputs (shapes, poses, seed, spawn key)."]
    if result.stiff is not None:
        L += ["", result.stiff.markdown()]
    return "\n".join(L) + "\n"


def _fmt(x):
    if isinstance(x, float):
        return "nan" if not math.isfinite(x) else f"{x:.3g}"
    return f"{x}"


def _write_replay(path, records, meta):
    from .replay import write_replay

    return str(write_replay(path, records, meta))


def write_validation(result, out_dir):
    """Write the report files of a :class:`ValidationResult` to ``out_dir``.

    Returns
    -------
    dict
        Paths: ``markdown`` (validation.md), ``summary_csv``
        (validation_summary.csv), ``cases_csv`` (validation_cases.csv),
        ``json`` (validation.json: run metadata, config, seeds, counts,
        times), ``replay`` (validation_replay.json) and ``stiff`` (a list of
        the stiff suite's CSV files, empty without it).
    """
    from pathlib import Path

    from .report import run_metadata, write_csv, write_json

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {}
    md = out / "validation.md"
    md.write_text(_markdown(result), encoding="utf-8")
    paths["markdown"] = str(md)
    paths["summary_csv"] = write_csv(out / "validation_summary.csv", SUMMARY_HEADER, _summary_rows(result))
    paths["cases_csv"] = write_csv(out / "validation_cases.csv", CASES_HEADER, _case_rows(result))
    o = result.outcome()
    meta = run_metadata(validation=result.config, seed=result.config["seed"],
                        seed_rule="numpy.random.SeedSequence(seed, spawn_key=(distribution index, block))",
                        distribution_index={d: DISTRIBUTION_NAMES.index(d) for d in result.config["distributions"]},
                        execution=result.execution, compile_time_s=result.compile_time,
                        wall_time_s=result.wall_time, ok=result.ok)
    paths["json"] = write_json(out / "validation.json", {
        **meta, "counts": o["counts"], "times_s": result.times, "records_total": result.records_total,
        "records_kept": len(result.records),
        "stiff": None if result.stiff is None else result.stiff.json()})
    paths["replay"] = _write_replay(out / "validation_replay.json", result.records,
                                    {k: meta[k] for k in ("validation", "seed", "seed_rule", "distribution_index")})
    paths["stiff"] = []
    if result.stiff is not None:
        for name, (header, rows) in result.stiff.csv_tables().items():
            fname = name if name.startswith("stiff") else f"stiff_{name}"
            paths["stiff"].append(write_csv(out / f"{fname}.csv", header, rows))
    return paths
