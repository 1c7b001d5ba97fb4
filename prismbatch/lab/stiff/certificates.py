"""Certificates that decide a pair where the LP is silent or overruled.

A separating plane (its finiteness signs checked in exact rational
arithmetic) proves a miss; a contact point inside both bodies within
``2 tol`` proves a hit. See docs/methods/stiff-suite.md.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np

from ...geometry import point_in_prism_residual
from .geometry import polygon_planes

EPS64 = float(np.finfo(np.float64).eps)


def _world(xy, p, R):
    return p + np.asarray(xy, float) @ R[:, :2].T


def plane_certificate(xy_a, pos_a, rot_a, xy_b, pos_b, rot_b, *, top=12):
    """Largest gap shown by a separating plane between two semi-infinite prisms (or -inf).

    Candidate normals n (pointing from a to b): a's end-face and side normals,
    b's (negated), and ``±`` cross products of the axes and edge directions.
    A plane is valid only if both bodies are bounded along it,
    ``n . d_a <= 0 <= n . d_b``: these signs are checked in exact rational
    arithmetic on the float inputs (a candidate that fails them is also tried
    projected exactly onto the planes normal to ``d_a``, to ``d_b`` and to both). The gap
    ``min_b n.x - max_a n.x`` is then
    evaluated in float64 over the end-face vertices (error ~1e-16 of the
    coordinates).

    Returns
    -------
    float
        A lower bound on the Euclidean distance between the bodies, or -inf.
    """
    pa, Ra, pb_, Rb = (np.asarray(v, float) for v in (pos_a, rot_a, pos_b, rot_b))
    Wa, Wb = _world(xy_a, pa, Ra), _world(xy_b, pb_, Rb)
    da, db = Ra[:, 2], Rb[:, 2]
    ea = np.roll(Wa, -1, axis=0) - Wa
    eb = np.roll(Wb, -1, axis=0) - Wb
    na = np.cross(ea, da)  # a's side normals up to sign (fixed below by validity)
    nb = np.cross(eb, db)
    # d_a x (d_b - d_a) = d_a x d_b without the cancellation for nearly parallel axes
    cand = [da[None], db[None], na, nb, np.cross(da, db - da)[None], np.cross(da, eb), np.cross(ea, db)]
    if len(ea) * len(eb) <= 4096:
        cand.append(np.cross(ea[:, None, :], eb[None, :, :]).reshape(-1, 3))
    C = np.concatenate(cand)
    C = np.concatenate([C, -C])
    nn = np.linalg.norm(C, axis=1)
    C = C[nn > 1e-300] / nn[nn > 1e-300, None]
    sa, sb = C @ da, C @ db
    ok = (sa <= 1e-12) & (sb >= -1e-12)
    if not ok.any():
        return -math.inf
    C = C[ok]
    val = (Wb @ C.T).min(axis=0) - (Wa @ C.T).max(axis=0)
    best = -math.inf
    fa = [Fraction(float(v)) for v in da]
    fb = [Fraction(float(v)) for v in db]
    # Best float value first; many near-valid candidates fail the exact signs for nearly
    # parallel axes, so go on until `top` of them pass.
    found = 0
    for idx in np.argsort(-val)[: 50 * top]:
        if val[idx] <= best:
            break
        for n in _valid_variants(C[idx], fa, fb):
            g = (float(np.min(Wb @ n)) - float(np.max(Wa @ n))) / float(np.linalg.norm(n))
            best = max(best, g)
            found += 1
        if found >= top:
            break
    return best


def _fdot(u, v):
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


def _valid_variants(n, fa, fb):
    """``n`` itself and ``n`` projected exactly onto the plane normal to d_a, to d_b, or to both, each kept
    only when ``n . d_a <= 0 <= n . d_b`` holds exactly (rational arithmetic). Returned as float
    vectors; rounding them back moves the supports by ~1e-16 of the coordinates only."""
    fn = [Fraction(float(v)) for v in n]
    out = []
    for proj in (None, fa, fb, "both"):
        m = fn
        if proj == "both":  # normal to both axes (d_a x d_b for nearly parallel axes)
            aa, ab, bb = _fdot(fa, fa), _fdot(fa, fb), _fdot(fb, fb)
            det = aa * bb - ab * ab
            if det == 0:
                continue
            na_, nb_ = _fdot(fn, fa), _fdot(fn, fb)
            al, be = (na_ * bb - nb_ * ab) / det, (nb_ * aa - na_ * ab) / det
            m = [x - al * y - be * z for x, y, z in zip(fn, fa, fb)]
        elif proj is not None:
            c = _fdot(fn, proj) / _fdot(proj, proj)
            m = [x - c * y for x, y in zip(fn, proj)]
        if _fdot(m, fa) <= 0 <= _fdot(m, fb):
            v = np.array([float(x) for x in m])
            if np.any(v != 0):
                out.append(v)
                if proj is None:
                    break  # n is valid as it is
    return out


def _residual(xy, pos, rot, x):
    """Largest violation of a world point against one body's half-spaces (<= 0: inside), the polygon's planes kept."""
    return point_in_prism_residual(xy, pos, rot, x, planes=polygon_planes(xy))


def contact_certified(xy_a, pos_a, rot_a, xy_b, pos_b, rot_b, x, tol, eps=EPS64):
    """Is ``x`` inside both bodies within ``2 tol`` (plus the rounding of its own coordinates)?"""
    x = np.asarray(x, float)
    if not np.all(np.isfinite(x)):
        return False
    slack = 2.0 * tol + 8.0 * eps * (np.linalg.norm(x) + np.linalg.norm(pos_a) + np.linalg.norm(pos_b))
    return _residual(xy_a, pos_a, rot_a, x) <= slack and _residual(xy_b, pos_b, rot_b, x) <= slack
