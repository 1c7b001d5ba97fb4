"""The distance section of the validation: signed distances against the exact reference, per bucket.

Pairs are placed at a chosen signed distance (:func:`place`: penetrating, touching, gaps of
1e-6 .. 1 of the pair's size) from four families of poses, in blocks of
:data:`DISTANCE_BLOCK` pairs seeded like the other blocks, with
``spawn_key=(DISTANCE_KEY, block)``. On every pair, prismbatch's ``distance`` (with witness
points) and, when installed, coal's are compared with :mod:`prismbatch.lab.distance_ref`; the
method is in ``docs/methods/validation.md`` (Signed distance).
"""

from __future__ import annotations

import time

import numpy as np

from ...collide import Collider
from ...geometry import pair_scale_tolerance
from .generate import make_shape

#: spawn_key[0] of the distance blocks (distributions use 0, 1, 2, ...).
DISTANCE_KEY = 100

#: Pairs per distance block (one block per chunk: a block costs seconds).
DISTANCE_BLOCK = 256

#: Pose families, cycled over the blocks.
DISTANCE_FAMILIES = ("facing", "free", "identical-rotation", "near-parallel")

#: Bucket name -> signed distance as a fraction of the pair's size ``R_a + R_b`` (None: touching).
DISTANCE_BUCKETS = {
    "penetrating 1": -1.0,
    "penetrating 1e-2": -1e-2,
    "touching": None,
    **{f"gap 1e-{k}": 10.0**-k for k in range(6, 0, -1)},
    "gap 1": 1.0,
}

#: How a reference gap was confirmed (``distance_ref.check_gap``), by index.
CHECKS = ("failed", "certificate", "qp")

#: Largest |distance - reference| allowed, in units of the pair's tolerance.
DISTANCE_LIMIT = 10.0

#: Per-pair arrays a distance block returns (merged in block order).
PAIR_FIELDS = (
    "block",
    "index",
    "family",
    "bucket",
    "tol",
    "reference",
    "pb",
    "pb_err",
    "witness",
    "witness_out",
    "witness_ratio",
    "witness_bad",
    "sign_wrong",
    "ref_checked",
    "coal",
    "coal_err",
)


def place(a, b, poses, target, rng, size):
    """Poses of b moved along prismbatch's witness normal to the signed distance ``target * size``.

    Parameters
    ----------
    a, b : Prism
        The two shapes.
    poses : tuple of ndarray
        ``(pos_a, rot_a, pos_b, rot_b)``, (m, 3) and (m, 3, 3).
    target : float or None
        Signed distance as a fraction of ``size``; None: touching, a uniform signed distance
        within 0.1 of each pair's tolerance.
    rng : numpy.random.Generator
        Draws the touching offsets (used only when ``target`` is None).
    size : float
        The length the target is a fraction of (e.g. ``R_a + R_b``).

    Returns
    -------
    tuple of ndarray
        The poses with b's positions moved (contiguous). The pairs are at the target only as
        far as prismbatch's distance is right: the references judge them.
    """
    pa, ra, pb_, rb = poses
    r = Collider(a, b).distance(pa, ra, pb_, rb, witness=True)
    if target is None:
        want = 0.1 * r.tol * rng.uniform(-1, 1, len(r.tol))
    else:
        want = np.full(len(r.tol), target * size)
    moved = pb_ + (want - r.distance)[:, None] * r.normal
    return pa, ra, np.ascontiguousarray(moved), rb


def n_distance_blocks(cfg):
    """Number of distance blocks of a run."""
    return -(-cfg["distance_pairs"] // DISTANCE_BLOCK)


def distance_block_len(cfg, block):
    """Pairs in distance block ``block`` (the last may be short)."""
    return min(DISTANCE_BLOCK, cfg["distance_pairs"] - block * DISTANCE_BLOCK)


def _tilts(m, rng):
    """(m, 3, 3) rotations about a random horizontal axis by 10^U(-12, -2) rad (Rodrigues)."""
    phi = rng.uniform(0, 2 * np.pi, m)
    k = np.column_stack([np.cos(phi), np.sin(phi), np.zeros(m)])
    th = 10.0 ** rng.uniform(-12, -2, m)
    K = np.zeros((m, 3, 3))
    K[:, 0, 2], K[:, 1, 2], K[:, 2, 0], K[:, 2, 1] = k[:, 1], -k[:, 0], -k[:, 1], k[:, 0]
    return np.eye(3) + np.sin(th)[:, None, None] * K + (1 - np.cos(th))[:, None, None] * (K @ K)


def _base_poses(family, m, rng, radius):
    from ...sampling import facing_poses, free_poses

    if family == "facing":
        return facing_poses(m, rng, radius=radius)
    pa, ra, pb_, rb = free_poses(m, rng, radius=radius)
    if family == "identical-rotation":
        rb = ra.copy()
    elif family == "near-parallel":  # half pointing the same way, half opposite, tilted by 1e-12 .. 1e-2
        flip = np.where(rng.random(m) < 0.5, 1.0, -1.0)
        F = np.zeros((m, 3, 3))
        F[:, 0, 0], F[:, 1, 1], F[:, 2, 2] = 1.0, flip, flip  # diag(1, -1, -1): the axis reversed
        rb = ra @ F @ _tilts(m, rng)
    return pa, ra, pb_, rb


def generate_distance_block(cfg, block):
    """(shape a, shape b, family, bucket index (m,), poses) of one distance block, from the run's seed."""
    ss = np.random.SeedSequence(cfg["seed"], spawn_key=(DISTANCE_KEY, block))
    rng_shape, rng_pose, rng_place = (np.random.default_rng(s) for s in ss.spawn(3))
    kind = cfg["shapes"][block % len(cfg["shapes"])]
    v = cfg["distance_vertices"]
    sa = make_shape(kind, v[block % len(v)], rng_shape)
    sb = make_shape(kind, v[(block + 1) % len(v)], rng_shape)
    family = DISTANCE_FAMILIES[block % len(DISTANCE_FAMILIES)]
    m = distance_block_len(cfg, block)
    bucket = np.arange(m) % len(DISTANCE_BUCKETS)
    P = [np.array(x, dtype=np.float64) for x in _base_poses(family, m, rng_pose, max(sa.radius, sb.radius))]
    for j, target in enumerate(DISTANCE_BUCKETS.values()):
        sel = bucket == j
        moved = place(sa, sb, tuple(x[sel] for x in P), target, rng_place, sa.radius + sb.radius)
        P[2][sel] = moved[2]
    dt = np.dtype(cfg["dtype"])
    P = [np.ascontiguousarray(np.asarray(x, dtype=dt), dtype=np.float64) for x in P]  # as the run sees them
    return sa, sb, family, bucket, P


def _reference(sa, sb, P, S, tol):
    """Per pair: the exact signed distance, how its gap was confirmed (index in :data:`CHECKS`; -1: a depth)
    and the bodies."""
    from ..distance_ref import Body, check_gap, gap_features, sat_separation

    m = len(P[0])
    ref, checked, bodies = np.empty(m), np.full(m, -1, np.int8), []
    for k in range(m):
        A, B = Body(sa.xy, P[0][k], P[1][k]), Body(sb.xy, P[2][k], P[3][k])
        sep, _ = sat_separation(A, B)
        ref[k] = sep
        if sep > 0.0:
            ref[k], x, y = gap_features(A, B, points=True)
            checked[k] = CHECKS.index(check_gap(A, B, ref[k], x, y, tol[k], S[k], sep=sep))
        bodies.append((A, B))
    return ref, checked, bodies


def _coal(sa, sb, P, bucket, times):
    """coal's signed distances (depths with a tight EPA tolerance), timed per bucket with its defaults."""
    from ..peers import CoalDistancePeer, standin_length

    L = 2.0 * standin_length(sa.xy, sb.xy, *P)
    try:
        peer = CoalDistancePeer(sa.xy, sb.xy, L)
    except ImportError:  # coal is optional: the section reports it when installed
        return np.full(len(P[0]), np.nan)
    tight = CoalDistancePeer(sa.xy, sb.xy, L, tolerance=1e-12)  # coal's default EPA depth is coarse
    out = np.empty(len(P[0]))
    for j in range(len(DISTANCE_BUCKETS)):
        idx = np.flatnonzero(bucket == j)
        items = peer.prepare(*(x[idx] for x in P))
        t = time.perf_counter()
        d = peer.run(items)[0]
        times["coal"][j] += time.perf_counter() - t
        out[idx] = np.where(d < 0, tight.run(items)[0], d)
    return out


def process_distance_block(cfg, block):
    """Generate and check one distance block; returns ``(key, pairs, times, [])`` like a block of pairs."""
    from ..distance_ref import residual

    sa, sb, family, bucket, P = generate_distance_block(cfg, block)
    m, nb = len(bucket), len(DISTANCE_BUCKETS)
    times = {"pb": np.zeros(nb), "coal": np.zeros(nb), "pairs": np.bincount(bucket, minlength=nb)}
    col = Collider(sa, sb, rtol=cfg["rtol"], atol=cfg["atol"], dtype=cfg["dtype"])
    Pc = tuple(np.ascontiguousarray(x, dtype=cfg["dtype"]) for x in P)
    # compiled or loaded outside the timing: the whole block once, so that the second pass of the pairs
    # whose EPA needs more room (its own kernel) is loaded too (a first call in a worker took seconds)
    col.distance(*Pc, witness=True, parallel=False)
    dist, tol = np.empty(m), np.empty(m)
    pa, pb_ = np.empty((m, 3)), np.empty((m, 3))
    for j in range(nb):
        idx = np.flatnonzero(bucket == j)
        sub = tuple(x[idx] for x in Pc)
        t = time.perf_counter()
        r = col.distance(*sub, witness=True, parallel=False)
        times["pb"][j] += time.perf_counter() - t
        dist[idx], tol[idx], pa[idx], pb_[idx] = r.distance, r.tol, r.point_a, r.point_b
    hit = col.collide(*Pc).hit
    S, _ = pair_scale_tolerance(sa, sb, *P, rtol=cfg["rtol"], atol=cfg["atol"], dtype=cfg["dtype"])
    ref, checked, bodies = _reference(sa, sb, P, S, tol)
    res = np.array([[residual(A, pa[k][None])[0], residual(B, pb_[k][None])[0]] for k, (A, B) in enumerate(bodies)])
    with np.errstate(invalid="ignore"):
        witness = np.abs(res).max(axis=1) / tol  # off the boundary, either side
        witness_out = np.maximum(res.max(axis=1), 0.0) / tol  # outside its body (a lower bound of the distance)
        # on their boundaries within tol, plus the rounding of the points' own coordinates
        allowed = 1.0 + 4 * np.finfo(np.dtype(cfg["dtype"])).eps * np.abs(np.concatenate([pa, pb_], 1)).max(1) / tol
        witness_ratio = witness / allowed
        witness_bad = ~(witness_ratio <= 1.0)
        pb_err = np.abs(dist - ref) / tol
    coal = _coal(sa, sb, P, bucket, times)
    with np.errstate(over="ignore", invalid="ignore"):
        coal_err = np.abs(coal - ref) / tol
    pairs = {
        "block": np.full(m, block),
        "index": np.arange(m),
        "family": np.full(m, DISTANCE_FAMILIES.index(family)),
        "bucket": bucket,
        "tol": tol,
        "reference": ref,
        "pb": dist,
        "pb_err": np.where(np.isfinite(pb_err), pb_err, np.inf),
        "witness": witness,
        "witness_out": witness_out,
        "witness_ratio": witness_ratio,
        "witness_bad": witness_bad,
        # outside the touching band the sign of the distance is collide's answer
        "sign_wrong": (np.abs(ref) > 2 * tol) & ((dist < 0) != hit),
        "ref_checked": checked,
        "coal": coal,
        "coal_err": coal_err,
    }
    return (DISTANCE_KEY, block), pairs, times, []


class DistanceMerger:
    """Per-pair arrays and per-bucket times of the distance blocks, concatenated in block order."""

    def __init__(self):
        self.blocks = {}
        nb = len(DISTANCE_BUCKETS)
        self.times = {"pb": np.zeros(nb), "coal": np.zeros(nb), "pairs": np.zeros(nb, np.int64)}

    def add(self, block, pairs, times):
        self.blocks[block] = pairs
        for k in self.times:
            self.times[k] = self.times[k] + times[k]

    def pairs(self):
        """Every field of :data:`PAIR_FIELDS` over all blocks, in block order (None without blocks)."""
        if not self.blocks:
            return None
        order = sorted(self.blocks)
        return {f: np.concatenate([self.blocks[b][f] for b in order]) for f in PAIR_FIELDS}


def failures(pairs):
    """Boolean (N,) mask of the failing pairs: off by more than the limit, witness off, sign, unverified."""
    return (pairs["pb_err"] > DISTANCE_LIMIT) | pairs["witness_bad"] | pairs["sign_wrong"] | (pairs["ref_checked"] == 0)


#: Columns of validation_distance.csv (one row per bucket and a total row).
DISTANCE_HEADER = [
    "bucket",
    "target_over_size",
    "pairs",
    "pb_err_max_tol",
    "pb_err_median_tol",
    "pb_over_10_tol",
    "witness_max_tol",
    "witness_outside_max_tol",
    "witness_max_over_allowed",
    "witness_off",
    "sign_disagree_collide",
    "gaps_certified",
    "gaps_qp_only",
    "gaps_unconfirmed",
    "coal_pairs",
    "coal_err_max_tol",
    "coal_err_median_tol",
    "coal_over_10_tol",
    "pb_us_per_pair",
    "coal_us_per_pair",
]


def distance_rows(pairs, times):
    """Rows of :data:`DISTANCE_HEADER`: one per bucket, then ``total``."""
    rows = []
    groups = [(name, t, pairs["bucket"] == j, [j]) for j, (name, t) in enumerate(DISTANCE_BUCKETS.items())]
    groups.append(("total", None, np.ones(len(pairs["bucket"]), bool), list(range(len(DISTANCE_BUCKETS)))))
    nan = float("nan")
    for name, target, sel, js in groups:
        n = int(sel.sum())
        e, c = pairs["pb_err"][sel], pairs["coal_err"][sel]
        cv = c[np.isfinite(pairs["coal"][sel])]
        t_pb, t_coal, npairs = (float(times[k][js].sum()) for k in ("pb", "coal", "pairs"))
        rows.append(
            [
                name,
                "touching" if target is None and name != "total" else ("" if target is None else target),
                n,
                float(e.max()) if n else nan,
                float(np.median(e)) if n else nan,
                int((e > DISTANCE_LIMIT).sum()),
                float(np.nanmax(pairs["witness"][sel])) if n else nan,
                float(np.nanmax(pairs["witness_out"][sel])) if n else nan,
                float(np.nanmax(pairs["witness_ratio"][sel])) if n else nan,
                int(pairs["witness_bad"][sel].sum()),
                int(pairs["sign_wrong"][sel].sum()),
                int((pairs["ref_checked"][sel] == 1).sum()),
                int((pairs["ref_checked"][sel] == 2).sum()),
                int((pairs["ref_checked"][sel] == 0).sum()),
                int(cv.size),
                float(cv.max()) if cv.size else nan,
                float(np.median(cv)) if cv.size else nan,
                int((cv > DISTANCE_LIMIT).sum()),
                1e6 * t_pb / npairs if npairs else nan,
                1e6 * t_coal / npairs if npairs and cv.size else nan,
            ]
        )
    return rows


def failure_records(pairs, limit=100):
    """The first ``limit`` failing pairs (block, index, family, bucket, values), for the JSON report."""
    out = []
    for k in np.flatnonzero(failures(pairs))[:limit]:
        out.append(
            {
                "spawn_key": [DISTANCE_KEY, int(pairs["block"][k])],
                "index": int(pairs["index"][k]),
                "family": DISTANCE_FAMILIES[int(pairs["family"][k])],
                "bucket": list(DISTANCE_BUCKETS)[int(pairs["bucket"][k])],
                "tol": float(pairs["tol"][k]),
                "reference": float(pairs["reference"][k]),
                "distance": float(pairs["pb"][k]),
                "error_tol": float(pairs["pb_err"][k]),
                "witness_tol": float(pairs["witness"][k]),
                "witness_outside_tol": float(pairs["witness_out"][k]),
                "sign_disagrees_with_collide": bool(pairs["sign_wrong"][k]),
                "reference_unverified": bool(pairs["ref_checked"][k] == 0),
            }
        )
    return out


def distance_lines(result):
    """Terminal lines of the distance section (none when it did not run)."""
    if result.distance is None:
        return []
    rows = [dict(zip(DISTANCE_HEADER, r)) for r in distance_rows(**result.distance)]
    t = rows[-1]
    L = [
        f"distance ({t['pairs']:,} pairs, {len(DISTANCE_BUCKETS)} buckets, vs the exact reference): |error| max "
        f"{t['pb_err_max_tol']:.3g} tol, median {t['pb_err_median_tol']:.3g} tol, over {DISTANCE_LIMIT:g} tol "
        f"{t['pb_over_10_tol']}; witnesses off their boundaries max {t['witness_max_tol']:.3g} tol (outside their "
        f"bodies {t['witness_outside_max_tol']:.3g} tol; {t['witness_max_over_allowed']:.3g} of tol + the rounding "
        f"of their coordinates), beyond it {t['witness_off']}; sign vs "
        f"collide wrong {t['sign_disagree_collide']}; reference gaps certified {t['gaps_certified']}, by the QP "
        f"only {t['gaps_qp_only']}, unconfirmed {t['gaps_unconfirmed']}; {t['pb_us_per_pair']:.3g} us per pair"
    ]
    if t["coal_pairs"]:
        L.append(
            f"  coal ({t['coal_pairs']:,} pairs): |error| max {t['coal_err_max_tol']:.3g} tol, median "
            f"{t['coal_err_median_tol']:.3g} tol, over {DISTANCE_LIMIT:g} tol {t['coal_over_10_tol']}; "
            f"{t['coal_us_per_pair']:.3g} us per pair"
        )
    return L


def distance_markdown(result):
    """The Markdown section of the distance validation (empty when it did not run)."""
    from ..report import fmt

    if result.distance is None:
        return []
    cfg = result.config
    L = [
        "## Signed distance",
        "",
        f"{cfg['distance_pairs']:,} pairs in blocks of {DISTANCE_BLOCK} (families {', '.join(DISTANCE_FAMILIES)}, "
        f"cycled per block; vertex counts {cfg['distance_vertices']}), each placed at a bucket's signed distance "
        "(a fraction of R_a + R_b) along prismbatch's witness normal, then judged by the exact reference "
        "(the separating-axis theorem over every candidate axis when the bodies overlap, every feature pair "
        "when they do not, each gap certified by its optimality condition or else cross-checked by a QP). "
        "Errors in units of the pair's tolerance; prismbatch "
        f"fails a pair beyond {DISTANCE_LIMIT:g} tol, with a witness point off its body's boundary by more "
        "than tol, or with the sign of its distance against `collide` outside |reference| <= 2 tol. coal "
        "runs on finite stand-ins (depths with an EPA tolerance of 1e-12, timed with its defaults). "
        "Time per pair on one thread; noisy.",
        "",
    ]
    head = [h.replace("_", " ") for h in DISTANCE_HEADER]
    L += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    L += ["| " + " | ".join(fmt(x, none="nan") for x in r) + " |" for r in distance_rows(**result.distance)]
    n_fail = result.distance_failures()
    L += ["", f"Failing pairs: {n_fail} (the first 100 in `validation.json`, `distance.failures`)."]
    return L


def distance_json(result):
    """The section for validation.json: the bucket rows and the first failing pairs (None without it)."""
    if result.distance is None:
        return None
    rows = [dict(zip(DISTANCE_HEADER, r)) for r in distance_rows(**result.distance)]
    return {
        "block_size": DISTANCE_BLOCK,
        "spawn_key": f"({DISTANCE_KEY}, block)",
        "families": list(DISTANCE_FAMILIES),
        "buckets": {k: v for k, v in DISTANCE_BUCKETS.items()},
        "limit_tol": DISTANCE_LIMIT,
        "rows": rows,
        "failing_pairs": result.distance_failures(),
        "failures": failure_records(result.distance["pairs"]),
    }
