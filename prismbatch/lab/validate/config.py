"""Settings, constants and per-block seeding of the Monte Carlo validation.

See ``docs/methods/validation.md`` (Reproducibility) for the seeding rule.
"""

from __future__ import annotations

import math

import numpy as np

from ...config import DEFAULT_RTOL, LP_TRUST_RTOL
from ..checks import is_int

#: Pairs of the distance section when not given: at most this many (and at most n_pairs).
DEFAULT_DISTANCE_PAIRS = 1000

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

#: Accuracy floor of the LP reference, relative to the scene scale S (the one value: config.LP_TRUST_RTOL).
LP_REL = LP_TRUST_RTOL

# Counter names, internal to the package (see ValidationResult.counts).
NC = 12  # case index 0..11 (0 unused)
CASE_COUNTERS = (
    "pairs_case",
    "hits_case",
    "fcl_in_band",
    "fcl_out_pb",
    "fcl_out_fcl",
    "fcl_standin_short",
    "fcl_unarbitrated",
    "lp_band",
    "lp_in_band",
    "lp_out",
)
INT_COUNTERS = (
    "pairs",
    "hits",
    "fcl_pairs",
    "lp_pairs",
    "lp_arbitration",
    "lp_failed",
    "standin_checked",
    "standin_short",
    "standin_unsound",
    "contact_checked",
    "contact_invalid",
    "nonfinite",
    "bad_case",
    "status_mismatch",
    "degenerate_substituted",
    "near_contact_unseparated",
    "exact_pairs",
    "exact_wrong",
    "exact_band",
    "exact_unknown",
)
MAX_COUNTERS = ("contact_max_ratio", "standin_max_dev")
TIMES = ("gen", "pb", "pb_contact", "fcl", "fcl_setup", "lp", "check")


def _check_fcl(fcl):
    """The FCL fraction of the ``fcl`` argument: True -> 1, False -> 0, or a fraction in (0, 1]."""
    if isinstance(fcl, bool):
        return 1.0 if fcl else 0.0
    if isinstance(fcl, (float, int, np.floating, np.integer)) and 0.0 < float(fcl) <= 1.0:
        return float(fcl)
    raise ValueError(f"fcl must be True, False or a fraction in (0, 1] of the pairs, got {fcl!r}")


def _check_sampling(distributions, shapes, vertices):
    """The distributions, shape kinds and vertex counts as tuples, checked."""
    if isinstance(distributions, str):
        distributions = (distributions,)
    distributions = tuple(distributions)
    if not distributions:
        raise ValueError("distributions must name at least one of " + ", ".join(DISTRIBUTION_NAMES))
    for d in distributions:
        if d not in DISTRIBUTION_NAMES:
            raise ValueError(
                f"distributions: unknown distribution {d!r}; choose from "
                + ", ".join(DISTRIBUTION_NAMES)
                + " ('stiff' is the stiff=True option)"
            )
    if len(set(distributions)) != len(distributions):
        raise ValueError(f"distributions: repeated names in {distributions}")
    shapes = (shapes,) if isinstance(shapes, str) else tuple(shapes)
    if not shapes or any(s not in SHAPE_KINDS for s in shapes):
        raise ValueError(
            f"shapes must be one of {SHAPE_KINDS} or a sequence of them (cycled per block), got {shapes!r}"
        )
    vertices = (vertices,) if isinstance(vertices, (int, np.integer)) else tuple(vertices)
    if not vertices or any(not is_int(v) or v < 3 for v in vertices):
        raise ValueError(f"vertices must be an integer >= 3 or a sequence of them, got {vertices!r}")
    return distributions, shapes, vertices


def make_config(
    n_pairs=100_000,
    *,
    distributions=("facing", "free", "near-contact", "degenerate"),
    shapes="regular",
    vertices=(36, 360),
    seed=0,
    dtype="float64",
    rtol=None,
    atol=0.0,
    fcl=True,
    lp_samples=2000,
    contact_check=True,
    max_band_records=1000,
    distance_pairs=None,
    distance_vertices=(3, 36),
):
    """Check the validation settings and return them as a plain, JSON-able dict.

    See :func:`prismbatch.lab.validate.validate` for the parameters. The dict
    is what chunk tasks receive (with the distribution and block range): no
    arrays.

    Returns
    -------
    dict
        The settings, plus ``block_size`` (:data:`BLOCK_SIZE`), ``lp_rel``
        (:data:`LP_REL`) and ``fcl_fraction`` (from ``fcl``).

    Raises
    ------
    ValueError, TypeError
        Bad arguments (the message names the argument).
    """
    if not is_int(n_pairs) or n_pairs < 1:
        raise ValueError(f"n_pairs must be an integer >= 1, got {n_pairs!r}")
    distributions, shapes, vertices = _check_sampling(distributions, shapes, vertices)
    if not is_int(seed) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    dt = np.dtype(dtype) if not isinstance(dtype, str) else np.dtype(dtype)
    if dt not in DEFAULT_RTOL:
        raise ValueError(f"dtype must be 'float64' or 'float32', got {dtype!r}")
    rtol = float(DEFAULT_RTOL[dt] if rtol is None else rtol)
    atol = float(atol)
    if not (math.isfinite(rtol) and rtol >= 0 and math.isfinite(atol) and atol >= 0):
        raise ValueError(f"rtol and atol must be finite and >= 0, got rtol={rtol}, atol={atol}")
    fcl_frac = _check_fcl(fcl)
    if not is_int(lp_samples) or lp_samples < 0:
        raise ValueError(f"lp_samples must be an integer >= 0 (per distribution), got {lp_samples!r}")
    if not isinstance(contact_check, (bool, np.bool_)):
        raise TypeError(f"contact_check must be True or False, got {contact_check!r}")
    if not is_int(max_band_records) or max_band_records < 0:
        raise ValueError(f"max_band_records must be an integer >= 0, got {max_band_records!r}")
    if distance_pairs is None:
        distance_pairs = min(DEFAULT_DISTANCE_PAIRS, int(n_pairs))
    if not is_int(distance_pairs) or distance_pairs < 0:
        raise ValueError(f"distance_pairs must be an integer >= 0 (0: no distance section), got {distance_pairs!r}")
    dv = (distance_vertices,) if is_int(distance_vertices) else tuple(distance_vertices)
    if not dv or any(not is_int(v) or v < 3 for v in dv):
        raise ValueError(f"distance_vertices must be an integer >= 3 or a sequence of them, got {distance_vertices!r}")
    distance_vertices = dv
    return {
        "n_pairs": int(n_pairs),
        "distributions": list(distributions),
        "shapes": list(shapes),
        "vertices": [int(v) for v in vertices],
        "seed": int(seed),
        "dtype": dt.name,
        "rtol": rtol,
        "atol": atol,
        "fcl_fraction": fcl_frac,
        "lp_samples": int(lp_samples),
        "contact_check": bool(contact_check),
        "max_band_records": int(max_band_records),
        "distance_pairs": int(distance_pairs),
        "distance_vertices": [int(v) for v in distance_vertices],
        "block_size": BLOCK_SIZE,
        "lp_rel": LP_REL,
    }


def n_blocks(cfg):
    """Number of blocks per distribution."""
    return -(-cfg["n_pairs"] // cfg["block_size"])


def block_len(cfg, block):
    """Number of pairs in ``block`` (the last block may be short)."""
    B = cfg["block_size"]
    return min(B, cfg["n_pairs"] - block * B)


def streams(cfg, distribution, block):
    """Independent generators for (shapes, poses, fcl subsample, lp subsample) of one block."""
    ss = np.random.SeedSequence(cfg["seed"], spawn_key=(DISTRIBUTION_NAMES.index(distribution), block))
    return [np.random.default_rng(s) for s in ss.spawn(4)]
