"""Inputs of the validation: the two shapes and the poses of one block, per distribution.

Everything a block draws comes from its own seed streams (:func:`.config.streams`), so
:func:`generate_block` regenerates any block of a run exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ...collide import Collider
from ...shapes import Prism
from .config import DEGENERATE_CASES, DISTRIBUTION_NAMES, block_len, n_blocks, streams


def make_shape(kind, n, rng):
    """One polygon of a family with ``n`` vertices, random size, phase and offset.

    Parameters
    ----------
    kind : {"regular", "random", "cylinder"}
        Shape family (:data:`SHAPE_KINDS`).
    n : int
        Number of vertices.
    rng : numpy.random.Generator
        Source of the size, phase, offset (and, for "random", the vertices).

    Returns
    -------
    Prism
    """
    if kind == "cylinder":
        r = rng.uniform(0.5, 1.5)
        # Fitted n-gon: circumscribed about the circle (contains it, like the paper's 3600-gon).
        return Prism.regular(
            n, r / math.cos(math.pi / n), phase=rng.uniform(0, 2 * np.pi), centre=rng.uniform(-0.3, 0.3, 2) * r
        )
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
    return make_shape(kind, v[block % len(v)], rng), make_shape(kind, v[(block + 1) % len(v)], rng)


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
    from ...sampling import facing_poses, free_poses

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
    from ..casegen import case_poses

    k = len(DEGENERATE_CASES)
    sizes = [m // k + (1 if j < m % k else 0) for j in range(k)]
    parts, substituted = [], 0
    for j, size in enumerate(sizes):
        if size == 0:
            continue
        for t in range(k):  # a case the shapes cannot produce (e.g. no clear vertex): the next one
            case = DEGENERATE_CASES[(j + t) % k]
            try:
                parts.append(case_poses(case, size, sa, sb, rng, hit_fraction=0.5, world_transform=bool(block % 2)))
                break
            except RuntimeError:
                substituted += size
        else:
            raise RuntimeError(
                f"degenerate: no case of {DEGENERATE_CASES} can be built for these shapes ({sa!r}, {sb!r})"
            )
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
    if not (0 <= int(block) < n_blocks(config)):
        raise ValueError(f"block must be in [0, {n_blocks(config)}), got {block}")
    block = int(block)
    m = block_len(config, block)
    rng_shape, rng_pose, rng_fcl, rng_lp = streams(config, distribution, block)
    sa, sb = _block_shapes(config, block, rng_shape)
    notes = {}
    if distribution == "facing":
        from ...sampling import facing_poses

        P = facing_poses(m, rng_pose, radius=max(sa.radius, sb.radius))
    elif distribution == "free":
        from ...sampling import free_poses

        P = free_poses(m, rng_pose, radius=max(sa.radius, sb.radius))
    elif distribution == "near-contact":
        *P, notes["near_contact_unseparated"] = _near_contact(sa, sb, m, rng_pose, config["rtol"])
    else:
        *P, notes["degenerate_substituted"] = _degenerate(sa, sb, m, rng_pose, block)
    dt = np.dtype(config["dtype"])
    # Every method sees the poses prismbatch sees (rounded to the run's dtype).
    P = [np.ascontiguousarray(np.asarray(x, dtype=dt), dtype=np.float64) for x in P]
    return Block(
        distribution,
        block,
        (DISTRIBUTION_NAMES.index(distribution), block),
        sa,
        sb,
        *P,
        rngs=[rng_fcl, rng_lp],
        notes=notes,
    )
