"""Prediction queries for ``prismbatch predict``: read from a file or drawn for a demonstration, and answered.

A query set is two shapes and ``N`` pose pairs, with, for the time of impact,
b's motion (velocity, angular velocity, horizon), and, for the probability of
collision, the covariance of b's pose noise (and optionally a's). Either part
may be missing; :func:`answer` computes what the queries have.

File format (NumPy ``.npz``, arrays under these names; see :data:`KEYS`):
``xy_a``, ``xy_b`` (k, 2) end-face polygons; ``pos_a``, ``rot_a``, ``pos_b``,
``rot_b`` poses in any form :func:`prismbatch.collide` takes (matrices,
quaternions with ``quat_order``, rotation vectors are not guessed: pass
(N, 3, 3) or (N, 4)); ``velocity``, ``angular_velocity`` (3,) or (N, 3) and
``horizon`` (scalar or (N,)); ``cov_b``, ``cov_a`` (6, 6) or (N, 6, 6).
"""

from __future__ import annotations

import time
import zipfile
from pathlib import Path

import numpy as np

from ..motion import STATUS as TOI_STATUS
from ..motion import time_of_impact
from ..probability import METHODS
from ..sampling import facing_poses
from ..shapes import Prism
from .predict import predict

__all__ = ["KEYS", "MEANINGS", "read_queries", "demo_queries", "answer", "csv_table"]

#: The arrays a query file may hold, and what each is.
KEYS = {
    "xy_a": "(k, 2) a's end-face polygon (required)",
    "xy_b": "(m, 2) b's end-face polygon (required)",
    "pos_a": "(3,) or (N, 3) a's position (required)",
    "rot_a": "(3, 3), (N, 3, 3) or quaternions (N, 4) a's rotation (required)",
    "pos_b": "(3,) or (N, 3) b's position (required)",
    "rot_b": "b's rotation, as rot_a (required)",
    "velocity": "(3,) or (N, 3) b's linear velocity, world frame (time of impact)",
    "angular_velocity": "(3,) or (N, 3) b's angular velocity about its position, world frame",
    "horizon": "scalar or (N,) how far ahead to look, > 0 (default: --horizon)",
    "cov_b": "(6, 6) or (N, 6, 6) covariance of b's pose noise (dp, dtheta) (probability)",
    "cov_a": "(6, 6) or (N, 6, 6) covariance of a's pose noise, independent of b's",
}
_REQUIRED = ("xy_a", "xy_b", "pos_a", "rot_a", "pos_b", "rot_b")


def read_queries(path):
    """The queries of a ``.npz`` file as a dict of arrays (ValueError naming a missing or unknown key;
    OSError where the file is not a NumPy archive or is cut short)."""
    if Path(path).is_file() and not zipfile.is_zipfile(path):  # (np.load would take it for a pickle)
        raise OSError(f"{path}: not a .npz query file (not a zip archive)")
    try:
        with np.load(path, allow_pickle=False) as f:
            q = {k: f[k] for k in f.files}
    except (zipfile.BadZipFile, EOFError) as exc:
        raise OSError(f"{path}: not a readable .npz query file ({exc})") from exc
    unknown = sorted(set(q) - set(KEYS))
    if unknown:
        raise ValueError(f"{path}: unknown arrays {unknown}; a query file holds {sorted(KEYS)}")
    missing = [k for k in _REQUIRED if k not in q]
    if missing:
        raise ValueError(f"{path}: missing arrays {missing}")
    if "velocity" not in q and "cov_b" not in q:
        raise ValueError(f"{path}: nothing to predict: give velocity (time of impact) and/or cov_b (probability)")
    if "angular_velocity" in q and "velocity" not in q:
        raise ValueError(f"{path}: angular_velocity needs velocity")
    return q


def demo_queries(n, seed, *, sigma_pos=0.02, sigma_rot=0.01):
    """``n`` random queries from ``seed``: the paper's facing scene, b moving towards a, noisy poses.

    a: a square of radius 1 with its axis down at the origin; b: a 36-gon of
    radius 0.5 facing it (:func:`prismbatch.sampling.facing_poses`), moving at a
    speed in [0.1, 1] towards a point near a's end-face centre, with isotropic
    position noise ``sigma_pos`` and rotation noise ``sigma_rot`` (rad) per axis.
    """
    rng = np.random.default_rng(seed)
    pos_a, rot_a, pos_b, rot_b = facing_poses(n, rng, radius=1.0)
    target = np.column_stack([rng.uniform(-1.0, 1.0, (n, 2)), np.zeros(n)])
    heading = target - pos_b
    heading /= np.maximum(np.linalg.norm(heading, axis=1, keepdims=True), 1e-12)
    cov = np.diag([sigma_pos**2] * 3 + [sigma_rot**2] * 3)
    return dict(
        xy_a=Prism.regular(4, 1.0).xy,
        xy_b=Prism.regular(36, 0.5).xy,
        pos_a=pos_a,
        rot_a=rot_a,
        pos_b=pos_b,
        rot_b=rot_b,
        velocity=heading * rng.uniform(0.1, 1.0, (n, 1)),
        cov_b=cov,
    )


def answer(q, *, horizon, seed, quat_order=None, workers=None, scheduler=None, chunk_size=1024, **options):
    """Time of impact and probability of collision of the queries ``q`` (what they have).

    Parameters
    ----------
    q : dict
        As :func:`read_queries` returns.
    horizon : float
        The horizon of queries without their own.
    seed : int
        Root seed of the probability's sampling.
    quat_order, workers, scheduler, chunk_size, **options
        As :func:`prismbatch.lab.predict.predict` (``rel_error``, ``confidence``, ``max_samples``).

    Returns
    -------
    dict
        ``toi`` (a :class:`prismbatch.motion.TimeOfImpactResult` or None),
        ``probability`` (a :class:`prismbatch.probability.ProbabilityResult` or
        None), ``execution`` and ``seconds`` per part.
    """
    a, b = Prism(q["xy_a"], name="xy_a"), Prism(q["xy_b"], name="xy_b")
    poses = (q["pos_a"], q["rot_a"], q["pos_b"], q["rot_b"])
    out = {"toi": None, "probability": None, "execution": None, "seconds": {}}
    if "velocity" in q:
        t0 = time.perf_counter()
        out["toi"] = time_of_impact(
            a,
            b,
            *poses,
            q["velocity"],
            q.get("angular_velocity"),
            horizon=q.get("horizon", horizon),
            contact=True,
            quat_order=quat_order,
        )
        out["seconds"]["time_of_impact"] = time.perf_counter() - t0
    if "cov_b" in q:
        t0 = time.perf_counter()
        out["probability"], out["execution"] = predict(
            a,
            b,
            *poses,
            q["cov_b"],
            cov_a=q.get("cov_a"),
            seed=seed,
            chunk_size=chunk_size,
            workers=workers,
            scheduler=scheduler,
            quat_order=quat_order,
            **options,
        )
        out["seconds"]["probability"] = time.perf_counter() - t0
    return out


def csv_table(res):
    """``(header, rows)`` of one row per query: the time of impact and the probability, where computed."""
    cols = {}
    toi, pr = res["toi"], res["probability"]
    if toi is not None:
        cols["time_of_impact"] = toi.time
        cols["toi_status"] = toi.status
        cols["toi_iterations"] = toi.iterations
        for j, c in enumerate("xyz"):
            cols[f"contact_{c}"] = toi.contact[:, j]
    if pr is not None:
        for name in ("p", "low", "high", "samples", "converged", "method"):
            cols[name if name != "method" else "p_method"] = getattr(pr, name)
    n = len(next(iter(cols.values())))
    header = ["query", *cols]
    rows = [[i, *(_cell(v[i]) for v in cols.values())] for i in range(n)]
    return header, rows


def _cell(x):
    if isinstance(x, (bool, np.bool_)):
        return int(x)
    if isinstance(x, (np.integer, int)):
        return int(x)
    return "" if np.isnan(x) else repr(float(x))  # inf stays "inf"; NaN (not computed) empty


#: Column meanings for the JSON metadata.
MEANINGS = {
    "toi_status": {int(k): v for k, v in TOI_STATUS.items()},
    "p_method": {int(k): v for k, v in METHODS.items()},
}
