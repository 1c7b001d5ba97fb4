"""Judging one stiff-suite PairSet in one dtype against its ground truth.

Tolerances and bands per pair, the LP margins where the LP is trusted, the
collider's answers on the (rounded) poses, and the counts of a report row.
See docs/methods/stiff-suite.md.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ...config import DEFAULT_RTOL
from ...shapes import Prism, PrismSet
from ..exact import lp_trust_band, margin_lp
from .certificates import EPS64, contact_certified, plane_certificate
from .geometry import centre_radius, world_centres


def shape_of(polys):
    """One Prism when every pair shares the same polygon object, else a PrismSet."""
    first = polys[0]
    if all(p is first for p in polys):
        return Prism(first)
    return PrismSet(polys)


def _lp_untrusted(Ra, Rb):
    """Axes pointing the same way within 1e-8 rad, not exactly: the LP's blind spot."""
    da, db = Ra[:, 2], Rb[:, 2]
    sine = float(np.linalg.norm(np.cross(da, db)))
    return float(da @ db) > 0 and 0.0 < sine < 1e-8


def margins(ps):
    """Exact LP margin per pair (NaN where untrusted) and whether it is trusted."""
    m = np.full(len(ps), np.nan)
    trusted = np.zeros(len(ps), bool)
    for k in range(len(ps)):
        if _lp_untrusted(ps.rot_a[k], ps.rot_b[k]):
            continue
        try:
            m[k] = margin_lp(ps.polys_a[k], ps.pos_a[k], ps.rot_a[k], ps.polys_b[k], ps.pos_b[k], ps.rot_b[k])
            trusted[k] = True
        except RuntimeError:  # HiGHS gave up: certificates decide
            pass
    return m, trusted


def _geometry(ps):
    """Per pair: S, |c_a| + |c_b|, |p_a| + |p_b| + 2 (rho_a + rho_b) (rho: largest |vertex|), and the
    end-face centres' L1 norms in their local frames, |k_a|_1 + |k_b|_1."""
    n = len(ps)
    S, csum, big, local = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    for k in range(n):
        local[k] = np.abs(centre_radius(ps.polys_a[k])[0]).sum() + np.abs(centre_radius(ps.polys_b[k])[0]).sum()
        wa, ra, wb, rb = world_centres(ps.polys_a[k], ps.pos_a[k], ps.rot_a[k], ps.polys_b[k], ps.pos_b[k], ps.rot_b[k])
        S[k] = ra + rb + np.linalg.norm(wb - wa)
        csum[k] = np.linalg.norm(wa) + np.linalg.norm(wb)
        rho = np.max(np.abs(ps.polys_a[k])) + np.max(np.abs(ps.polys_b[k]))
        big[k] = np.linalg.norm(ps.pos_a[k]) + np.linalg.norm(ps.pos_b[k]) + 2 * math.sqrt(2) * rho
    return S, csum, big, local


def _need(ps, m, trusted, tol, lo_slack, hi_slack, band_lp):
    """+1 must hit, -1 must miss, 0 inside the band, 2 unknown (certificates decide)."""
    need = np.zeros(len(ps), np.int8)
    if not ps.lp:
        g = ps.gap
        need[g <= tol * (1 - 1e-6) - lo_slack] = 1
        need[g > 2 * tol * (1 + 1e-6) + hi_slack] = -1
        return need
    need[trusted & (m > np.maximum(band_lp, lo_slack))] = 1
    need[trusted & (m < -np.maximum(band_lp, tol + hi_slack))] = -1
    need[~trusted] = 2
    return need


class _Tolerances(NamedTuple):
    S: np.ndarray  # pair scale
    tol64: np.ndarray  # float64 pair tolerance
    tol: np.ndarray  # this dtype's pair tolerance
    slack: np.ndarray  # how far rounding to this dtype moved the bodies
    eps: float  # this dtype's machine epsilon


def _tolerances(ps, dt):
    """Pair tolerances in float64 and in ``dt``, and the required answers in both (``_need``)."""
    rtol, eps = DEFAULT_RTOL[dt], float(np.finfo(dt).eps)
    S, csum, big, local = _geometry(ps)
    tol64 = DEFAULT_RTOL[np.dtype(np.float64)] * S + EPS64 * (4 * csum + 8 * local)  # collide's pair tolerance
    tol = rtol * S + eps * (4 * csum + 8 * local)
    slack = np.zeros(len(ps)) if dt == np.float64 else 2 * eps * big  # bodies moved by rounding to float32
    return _Tolerances(S, tol64, tol, slack, eps)


def _rounder(dt):
    """``rnd(xy)``: the polygon as the kernel saw it in ``dt`` (float64 values, one copy per polygon)."""
    memo = {}

    def rnd(xy):  # one rounded copy per distinct polygon (keeps the half-plane cache warm)
        if dt == np.float64:
            return xy
        if id(xy) not in memo:
            memo[id(xy)] = (xy, np.asarray(xy, dt).astype(np.float64))
        return memo[id(xy)][1]

    return rnd


def _verdict(nk, h, lp, rounded, cert_c, cert_p, tol_k, tol64_k):
    """One pair's verdict: (count key or None, confirmed float64 truth or None).

    ``nk`` is the required answer (``_need``), ``h`` the answer given; the
    certificates ``cert_c`` (contact) and ``cert_p`` (plane) are evaluated lazily.
    """
    if nk == 0:
        return "inside_band", None
    if nk == 2:
        if h:
            if cert_c():
                return None, 0
            if cert_p() > 2 * tol_k:
                return "disagreements_outside_band", None
            return "unresolved", None
        g = cert_p()
        if g > tol_k:
            return None, (-1 if g > 2 * tol64_k else 0)
        return "unresolved", None
    if (nk == 1) == h:
        return None, None
    if not lp:
        # float32: the rounded bodies may really touch (or part): a tilt of 1e-12 rad changes by
        # ~1e-7 rad when rounded, and nearly parallel bodies then meet (or not) far away
        if rounded and (cert_c() if h else cert_p() > tol_k):
            return "rounding_explained", None
        return "disagreements_outside_band", None
    if h and cert_c():  # the LP missed a real contact
        return "certified_over_lp", 0
    if not h and cert_p() > tol_k:  # the LP saw an overlap that a plane refutes
        return "certified_over_lp", 0
    return "disagreements_outside_band", None


def _judge(ps, r, poses, need, truth64, tl, dt, c):
    """Count every pair's verdict into ``c``; confirmed float64 truths go into ``truth64``."""
    pa, Ra, pb_, Rb = poses
    rnd = _rounder(dt)
    for k in range(len(ps)):
        h = bool(r.hit[k])
        xa, xb = rnd(ps.polys_a[k]), rnd(ps.polys_b[k])
        cert_c = lambda: contact_certified(
            xa,
            pa[k],
            Ra[k],
            xb,
            pb_[k],
            Rb[k],
            r.contact[k],  # noqa: E731
            tl.tol[k] + tl.slack[k],
            tl.eps,
        )
        cert_p = lambda: plane_certificate(xa, pa[k], Ra[k], xb, pb_[k], Rb[k])  # noqa: E731
        if h and np.all(np.isfinite(r.contact[k])) and not cert_c():
            c["contact_outside_2tol"] += 1
        key, truth = _verdict(int(need[k]), h, ps.lp, dt != np.float64, cert_c, cert_p, tl.tol[k], tl.tol64[k])
        if key is not None:
            c[key] += 1
        if truth is not None:
            truth64[k] = truth


def _departures(ps, m, hit, truth64, tl):
    """Answers differing from the float64-required one (outside the float64 band), and the largest."""
    measure = np.abs(ps.gap) if not ps.lp else np.abs(m)
    dep = ((truth64 == 1) & ~hit) | ((truth64 == -1) & hit)
    out = dict(
        departures=int(dep.sum()), departures_hit=int((dep & hit).sum())
    )  # float64 says miss, this dtype says hit
    S, tol64 = tl.S, tl.tol64
    with np.errstate(invalid="ignore"):
        out["max_departure_rel"] = float(np.nanmax(measure[dep] / S[dep])) if dep.any() else 0.0
        out["max_departure_tol64"] = float(np.nanmax(measure[dep] / tol64[dep])) if dep.any() else 0.0
    return out


def run_one(ps, shapes, m, trusted, dt, collider):
    """Evaluate one PairSet in one dtype with the Collider class ``collider``; returns a row's counts."""
    dt = np.dtype(dt)
    tl = _tolerances(ps, dt)
    band_lp = lp_trust_band(tl.tol64, tl.S)
    need64 = _need(ps, m, trusted, tl.tol64, 0.0, 0.0, band_lp)
    need = need64 if dt == np.float64 else _need(ps, m, trusted, tl.tol, tl.slack, tl.slack, band_lp)

    sa, sb = shapes
    P = [np.ascontiguousarray(x, dtype=dt) for x in (ps.pos_a, ps.rot_a, ps.pos_b, ps.rot_b)]
    r = collider(sa, sb, dtype=dt).collide(*P, contact=True)
    # what the kernel saw: poses and polygons rounded to dt (certificates use these)
    poses = tuple(x.astype(np.float64) for x in P)

    c = dict(
        pairs=len(ps),
        hits=int(r.hit.sum()),
        non_finite=0,
        disagreements_outside_band=0,
        inside_band=0,
        unresolved=0,
        certified_over_lp=0,
        rounding_explained=0,
        contact_outside_2tol=0,
    )
    c["non_finite"] = int(
        (~np.isfinite(r.contact[r.hit])).any(axis=1).sum() + (~np.isnan(r.contact[~r.hit])).any(axis=1).sum()
    )
    truth64 = need64.copy()  # confirmed float64 truth for the departure count
    _judge(ps, r, poses, need, truth64, tl, dt, c)
    c.update(_departures(ps, m, r.hit, truth64, tl))
    vals, cnt = np.unique(r.case, return_counts=True)
    c["cases"] = " ".join(f"{int(v)}:{int(n)}" for v, n in zip(vals, cnt))
    return c
