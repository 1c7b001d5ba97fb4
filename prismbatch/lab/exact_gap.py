"""Exact Euclidean gap of two semi-infinite prisms, with certificates checked in rational arithmetic.

Independent of the kernels (it imports nothing from them). A body is the exact
affine image ``{p + R [u, v, t] : (u, v) in polygon, t >= 0}`` of the float
inputs taken as exact rationals. A float QP (HiGHS) suggests the closest
points; the features they lie on (end face, side face, end edge, lateral edge,
vertex) are then solved exactly, and the pair of points is accepted only when
verified exactly: both points inside their bodies, and n = x_b - x_a supporting
both (max of n.x over a at x_a, min over b at x_b). Then ``gap² = |n|²`` exactly.
When no feature pair verifies, exact bounds from rational separating planes
and rational points inside the bodies decide the verdict where they can.

:func:`judge_pair` turns the gap into the verdict of the tolerance contract:
"hit" (gap <= tol), "miss" (gap > 2 tol), "band" (in between) or "unknown"
(not certified; counted, never guessed). Needs highspy (the ``exact`` extra).
"""

from __future__ import annotations

import itertools
from fractions import Fraction
from typing import NamedTuple

import numpy as np

from ..geometry import exact_area2
from .highs import import_highspy, new_highs

__all__ = ["Judgement", "judge_pair", "gap_bounds", "check_contact", "exact_quat_matrix"]

F0 = Fraction(0)


def _q(x):
    return Fraction(float(x))


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def exact_dot(u, v):
    """Exact ``u . v`` of two float 3-vectors, as a rational."""
    return _dot([_q(x) for x in u], [_q(x) for x in v])


def _sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def exact_quat_matrix(q, order):
    """The exact rational rotation matrix of a float quaternion (order "wxyz" or "xyzw")."""
    q = [_q(v) for v in q]
    w, x, y, z = q if order == "wxyz" else (q[3], q[0], q[1], q[2])
    s = Fraction(2) / (w * w + x * x + y * y + z * z)
    return [
        [1 - s * (y * y + z * z), s * (x * y - w * z), s * (x * z + w * y)],
        [s * (x * y + w * z), 1 - s * (x * x + z * z), s * (y * z - w * x)],
        [s * (x * z - w * y), s * (y * z + w * x), 1 - s * (x * x + y * y)],
    ]


class _Body:
    """Exact and float data of one prism: p, the columns of R, the CCW polygon."""

    def __init__(self, xy, pos, rot):
        xy = np.asarray(xy, dtype=float)
        q = [(_q(u), _q(v)) for u, v in xy]
        # counter-clockwise by the exact area: a float shoelace sum of coordinates far from the origin
        # rounds to the wrong sign on slivers, and every inside test below would then be inverted
        if exact_area2(q) < 0:
            xy, q = xy[::-1], q[::-1]
        self.fxy = np.ascontiguousarray(xy)
        self.n = len(xy)
        self.xy = q
        R = [[r if isinstance(r, Fraction) else _q(r) for r in row] for row in np.asarray(rot, dtype=object)]
        self.p = tuple(_q(v) for v in pos)
        self.c0 = (R[0][0], R[1][0], R[2][0])
        self.c1 = (R[0][1], R[1][1], R[2][1])
        self.d = (R[0][2], R[1][2], R[2][2])
        self.fR = np.array([[float(r) for r in row] for row in R])
        self.fp = np.asarray(pos, dtype=float)
        e = np.roll(self.fxy, -1, axis=0) - self.fxy
        self.fnormal = np.column_stack([e[:, 1], -e[:, 0]])  # outward normals of the CCW edges
        self.foffset = np.einsum("ij,ij->i", self.fnormal, self.fxy)

    def local(self, u, v, t):
        """World point of local (u, v, t), exact."""
        return tuple(self.p[i] + self.c0[i] * u + self.c1[i] * v + self.d[i] * t for i in range(3))

    def inside_polygon(self, u, v):
        """Exact test that (u, v) lies in the closed polygon (float screen, exact where close)."""
        fu, fv = float(u), float(v)
        val = self.fnormal @ np.array([fu, fv]) - self.foffset
        scale = np.abs(self.fnormal).sum(axis=1) * (abs(fu) + abs(fv) + np.abs(self.fxy).sum(axis=1)) + 1e-300
        if np.any(val > 1e-12 * scale):
            return False
        for k in np.flatnonzero(val > -1e-12 * scale):
            (x0, y0), (x1, y1) = self.xy[k], self.xy[(k + 1) % self.n]
            if (x1 - x0) * (v - y0) - (y1 - y0) * (u - x0) < 0:
                return False
        return True

    def support(self, nvec, sign):
        """Exact max (sign +1) or min (sign -1) of n.x over the body; None if unbounded."""
        nd = _dot(nvec, self.d) * sign
        if nd > 0:
            return None
        a0, a1 = _dot(nvec, self.c0), _dot(nvec, self.c1)
        f = (self.fxy @ np.array([float(a0), float(a1)])) * sign
        top = f.max()
        slack = 1e-12 * (abs(top) + np.abs(self.fxy).max() * (abs(float(a0)) + abs(float(a1)))) + 1e-300
        best = None
        for k in np.flatnonzero(f >= top - slack):
            u, v = self.xy[k]
            val = (a0 * u + a1 * v) * sign
            best = val if best is None or val > best else best
        return sign * (best + sign * _dot(nvec, self.p))


# --- features: x = base + sum_i s_i g_i over an affine piece of the boundary ---


def _features(body, q, t, slack, direction=None):
    """Candidate boundary pieces near the float local point (q, t): (name, base, gens, to_local).

    The edges nearest to q, and, given a float direction n (outward from the
    body towards the other), the edges at the vertices extreme along n: with
    thousands of short edges the float point alone can sit several edges away.
    """
    val = body.fnormal @ q - body.foffset
    scale = np.hypot(body.fnormal[:, 0], body.fnormal[:, 1])
    dist = -val / scale  # >= 0 inside: distance to each edge line
    near = list(np.argsort(np.abs(dist))[:4])
    near = [k for k in near if abs(dist[k]) <= slack] or near[:1]
    if direction is not None:
        proj = body.fxy @ (body.fR[:, :2].T @ direction)
        for k in np.argsort(-proj)[:3]:
            near += [int(k), int((k - 1) % body.n)]
    near = list(dict.fromkeys(int(k) for k in near))
    # A point near the rim belongs to the end face and to the side faces:
    # try both (for parallel axes the closest points often sit on the sides).
    ends = [True, False]
    out = []
    for on_end in ends:
        if on_end:
            out.append(("end face", [], on_end))
        for k in near:
            out.append((f"edge {k}", [k], on_end))
            out.append((f"vertex {k}", [k, "v0"], on_end))
            out.append((f"vertex {(k + 1) % body.n}", [k, "v1"], on_end))
    feats = []
    seen = set()
    for name, spec, on_end in out:
        key = (name if len(spec) != 2 else f"vertex {(spec[0] + (spec[1] == 'v1')) % body.n}", on_end)
        if key in seen:
            continue
        seen.add(key)
        if not spec:
            base = body.local(F0, F0, F0)
            gens = [body.c0, body.c1]
            feats.append((name, base, gens, lambda s: (s[0], s[1], F0)))
            continue
        k = spec[0]
        (x0, y0), (x1, y1) = body.xy[k], body.xy[(k + 1) % body.n]
        if len(spec) == 2:
            u, v = (x0, y0) if spec[1] == "v0" else (x1, y1)
            base = body.local(u, v, F0)
            gens = [] if on_end else [body.d]
            feats.append(
                (
                    name + ("" if on_end else " (lateral edge)"),
                    base,
                    gens,
                    (lambda s, u=u, v=v: (u, v, F0)) if on_end else (lambda s, u=u, v=v: (u, v, s[0])),
                )
            )
        else:
            base = body.local(x0, y0, F0)
            e = tuple(body.c0[i] * (x1 - x0) + body.c1[i] * (y1 - y0) for i in range(3))
            gens = [e] if on_end else [e, body.d]
            feats.append(
                (
                    name + ("" if on_end else " (side face)"),
                    base,
                    gens,
                    (
                        lambda s, x0=x0, y0=y0, dx=x1 - x0, dy=y1 - y0: (
                            x0 + s[0] * dx,
                            y0 + s[0] * dy,
                            s[1] if len(s) > 1 else F0,
                        )
                    ),
                )
            )
    return feats


def _solve(Mat, rhs, guess):
    """Exact least-squares solution of Mat s = rhs via normal equations; free variables take ``guess``."""
    m = len(guess)
    if m == 0:
        return []
    A = [[sum(Mat[r][i] * Mat[r][j] for r in range(3)) for j in range(m)] for i in range(m)]
    b = [sum(Mat[r][i] * rhs[r] for r in range(3)) for i in range(m)]
    fixed = {}
    rows = list(range(m))
    piv = []
    for col in range(m):
        r = next((r for r in rows if A[r][col] != 0), None)
        if r is None:
            fixed[col] = guess[col]
            continue
        rows.remove(r)
        piv.append((r, col))
        for r2 in range(m):
            if r2 != r and A[r2][col] != 0:
                f = A[r2][col] / A[r][col]
                A[r2] = [A[r2][j] - f * A[r][j] for j in range(m)]
                b[r2] -= f * b[r]
    s = [None] * m
    for col, val in fixed.items():
        s[col] = val
    for r, col in piv:
        s[col] = (b[r] - sum(A[r][j] * fixed[j] for j in fixed)) / A[r][col]
    return s


#: Feature pairs solved exactly per pair (the float ranking puts the right one first in practice).
MAX_EXACT_CANDIDATES = 16


def _float_rank(A, B, cand, slack):
    """(infeasibility, distance) of a candidate feature pair, in float."""
    _, _, ba, ga, toa, _, bb, gb, tob = cand
    G = np.array([[float(c) for c in g] for g in ga] + [[-float(c) for c in g] for g in gb]).reshape(-1, 3).T
    rhs = np.array([float(b) - float(a) for a, b in zip(ba, bb)])
    s = np.linalg.lstsq(G, rhs, rcond=None)[0] if G.shape[1] else np.zeros(0)
    la, lb = toa(list(s[: len(ga)])), tob(list(s[len(ga) :]))
    bad = 0.0
    for body, loc in ((A, la), (B, lb)):
        q = np.array([float(loc[0]), float(loc[1])])
        bad = max(
            bad,
            -float(loc[2]),
            float(np.max((body.fnormal @ q - body.foffset) / np.hypot(body.fnormal[:, 0], body.fnormal[:, 1]))),
        )
    dist = np.linalg.norm(G @ s - rhs) if G.shape[1] else np.linalg.norm(rhs)
    return (bad > 1e-12 * slack * 1e6, dist)  # slack is 1e-6 of the scene: infeasible beyond 1e-12 of it


def _float_params(base, gens, x):
    """Float parameters of the point of the affine piece nearest to x."""
    if not gens:
        return []
    G = np.array([[float(c) for c in g] for g in gens]).T
    return np.linalg.lstsq(G, x - np.array([float(c) for c in base]), rcond=None)[0]


class Gap(NamedTuple):
    """Exact bounds on the squared gap; ``exact`` when both equal (certified closest points)."""

    lo: Fraction
    hi: Fraction | None
    points: tuple | None


def _qp(M, r, rows, x0, step):
    """min |M (x0 + step y) - r|^2 over y, s.t. rows (var offset, normal, offset) and t >= 0 (HiGHS)."""
    highspy = import_highspy()
    r0 = (r - M @ x0) / step
    Q = M.T @ M
    c = -(M.T @ r0)
    h = new_highs(2.0)  # (degenerate QPs can cycle; the exact stage decides anyway)
    h.setOptionValue("qp_iteration_limit", 20000)
    inf = highspy.kHighsInf
    lp = highspy.HighsLp()
    lp.num_col_, lp.num_row_ = 6, len(rows)
    lp.col_cost_ = c
    lp.col_lower_ = np.array([-inf, -inf, -x0[2] / step, -inf, -inf, -x0[5] / step])
    lp.col_upper_ = np.full(6, inf)
    lp.row_lower_ = np.full(len(rows), -inf)
    lp.row_upper_ = np.array([(o - nrm @ x0[off : off + 2]) / step for off, nrm, o in rows])
    cols = [[] for _ in range(6)]
    for i, (off, nrm, _) in enumerate(rows):
        cols[off].append((i, nrm[0]))
        cols[off + 1].append((i, nrm[1]))
    start, index, value = [0], [], []
    for col in cols:
        index += [i for i, _ in col]
        value += [v for _, v in col]
        start.append(len(index))
    lp.a_matrix_.format_ = highspy.MatrixFormat.kColwise
    lp.a_matrix_.start_, lp.a_matrix_.index_, lp.a_matrix_.value_ = np.array(start), np.array(index), np.array(value)
    h.passModel(lp)
    hs = highspy.HighsHessian()
    hs.dim_, hs.format_ = 6, highspy.HessianFormat.kTriangular
    st, ix, vl = [0], [], []
    for j in range(6):
        for i in range(j, 6):
            ix.append(i)
            vl.append(Q[i, j])
        st.append(len(ix))
    hs.start_, hs.index_, hs.value_ = np.array(st), np.array(ix), np.array(vl)
    h.passHessian(hs)
    h.run()
    y = np.array(h.getSolution().col_value, dtype=float)
    return x0 + step * y if y.shape == (6,) and np.isfinite(y).all() else x0  # a failed solve keeps x0


def _float_closest(A, B):
    """Closest local points (qa, ta, qb, tb) of the two bodies by a float QP, refined.

    HiGHS solves to about 1e-6 of the scene; each refinement solves again for
    the correction, scaled to the residual, with only the nearby edges.
    """
    M = np.column_stack([A.fR, -B.fR])
    # Local coordinates about each polygon's mean: a polygon far from its own
    # origin (vertices ~1e6, size 1) would cost the QP six digits.
    ca, cb = A.fxy.mean(axis=0), B.fxy.mean(axis=0)
    r = (B.fp + B.fR[:, :2] @ cb) - (A.fp + A.fR[:, :2] @ ca)
    scale = max(np.abs(A.fxy - ca).max(), np.abs(B.fxy - cb).max(), np.linalg.norm(r), 1e-300)
    rows = [
        (off, nrm / np.hypot(*nrm), (o - nrm @ c) / np.hypot(*nrm))
        for body, off, c in ((A, 0, ca), (B, 3, cb))
        for nrm, o in zip(body.fnormal, body.foffset)
    ]
    x = _qp(M, r, rows, np.zeros(6), scale)
    step = scale
    for _ in range(3):
        x[2], x[5] = max(x[2], 0.0), max(x[5], 0.0)
        resid = np.linalg.norm(M @ x - r)
        step = max(1e-3 * step, 1e-14 * scale, resid)
        near = [(off, nrm, o) for off, nrm, o in rows if o - nrm @ x[off : off + 2] <= 1e3 * step]
        x = _qp(M, r, near, x, step)
    return x[:2] + ca, max(x[2], 0.0), x[3:5] + cb, max(x[5], 0.0), scale


def _verify(A, B, la, lb):
    """Exact check of candidate local points; returns gap² if they are the closest points, else None."""
    if not (la[2] >= 0 and lb[2] >= 0 and A.inside_polygon(la[0], la[1]) and B.inside_polygon(lb[0], lb[1])):
        return None
    xa, xb = A.local(*la), B.local(*lb)
    n = _sub(xb, xa)
    g2 = _dot(n, n)
    if g2 == 0:
        return F0
    sa, sb = A.support(n, +1), B.support(n, -1)
    if sa is None or sb is None or sa != _dot(n, xa) or sb != _dot(n, xb):
        return None
    return g2


def gap_bounds(xy_a, pos_a, rot_a, xy_b, pos_b, rot_b):
    """Exact bounds on the squared Euclidean gap of two semi-infinite prisms.

    Returns
    -------
    Gap
        ``lo <= gap² <= hi`` (``hi`` None if no upper bound was certified);
        ``points`` the certified local pre-images when ``lo == hi``.
    """
    A, B = _Body(xy_a, pos_a, rot_a), _Body(xy_b, pos_b, rot_b)
    qa, ta, qb, tb, scale = _float_closest(A, B)
    slack = 1e-6 * scale
    fxa = A.fp + A.fR @ np.array([qa[0], qa[1], ta])
    fxb = B.fp + B.fR @ np.array([qb[0], qb[1], tb])
    nf = fxb - fxa
    nf = nf / np.linalg.norm(nf) if np.linalg.norm(nf) > 1e-12 * scale else None
    fa = _features(A, qa, ta, slack, nf)
    fb = _features(B, qb, tb, slack, None if nf is None else -nf)
    cands = []
    for (na, ba, ga, toa), (nb, bb, gb, tob) in itertools.product(fa, fb):
        gens = ga + [tuple(-c for c in g) for g in gb]
        if len(gens) > 4:
            continue
        cands.append((len(gens), na, ba, ga, toa, nb, bb, gb, tob))
    # Rank the candidates in float (feasible first, then by distance) and
    # verify the most promising ones exactly.
    cands.sort(key=lambda c: _float_rank(A, B, c, slack))
    guess_a, guess_b = [_q(v) for v in (*qa, ta)], [_q(v) for v in (*qb, tb)]
    best_lo, best_hi, pts = F0, None, None
    for _, na, ba, ga, toa, nb, bb, gb, tob in cands[:MAX_EXACT_CANDIDATES]:
        gens = ga + [tuple(-c for c in g) for g in gb]
        Mat = [[g[r] for g in gens] for r in range(3)]
        rhs = _sub(bb, ba)
        # Where the features are parallel the closest pair is not unique: the
        # free parameters take the float solution's values.
        guess = [_q(v) for v in _float_params(ba, ga, fxa)] + [_q(v) for v in _float_params(bb, gb, fxb)]
        s = _solve(Mat, rhs, guess)
        la, lb = toa(s[: len(ga)]), tob(s[len(ga) :])
        g2 = _verify(A, B, la, lb)
        if g2 is not None:
            return Gap(g2, g2, (la, lb))
    # No feature pair verified: bounds from the float solution.
    xa = A.local(*guess_a[:2], guess_a[2])
    xb = B.local(*guess_b[:2], guess_b[2])
    n = _sub(xb, xa)
    for m in _directions(n, A.d, B.d):
        sa, sb = A.support(m, +1), B.support(m, -1)
        if sa is not None and sb is not None and sb > sa:
            best_lo = max(best_lo, (sb - sa) ** 2 / _dot(m, m))
    if A.inside_polygon(*guess_a[:2]) and B.inside_polygon(*guess_b[:2]):
        best_hi = _dot(n, n)
        pts = (tuple(guess_a), tuple(guess_b))
    return Gap(best_lo, best_hi, pts)


def _directions(n, da, db):
    """n, and n made exactly orthogonal to d_a, to d_b, and to both (unbounded bodies need n.d_a <= 0 <= n.d_b)."""
    out = [n] if _dot(n, n) > 0 else []
    for d in (da, db):
        m = tuple(n[i] - _dot(n, d) / _dot(d, d) * d[i] for i in range(3))
        if _dot(m, m) > 0:
            out.append(m)
    c = _cross(da, db)
    if _dot(c, c) > 0:
        k = _dot(n, c)
        if k != 0:
            out.append(tuple(k * ci for ci in c))
    return out


class Judgement(NamedTuple):
    """Verdict of the tolerance contract for one pair, with the exact bounds behind it."""

    verdict: str
    gap2_lo: Fraction
    gap2_hi: Fraction | None


def judge_pair(xy_a, pos_a, rot_a, xy_b, pos_b, rot_b, tol):
    """Judge one pair at its tolerance: "hit" (gap <= tol), "miss" (gap > 2 tol), "band", or "unknown".

    Rotations may be float (3, 3) arrays or exact rational matrices (see :func:`exact_quat_matrix`).
    """
    g = gap_bounds(xy_a, pos_a, rot_a, xy_b, pos_b, rot_b)
    t2 = _q(tol) ** 2
    if g.hi is not None and g.hi <= t2:
        return Judgement("hit", g.lo, g.hi)
    if g.lo > 4 * t2:
        return Judgement("miss", g.lo, g.hi)
    if g.lo > t2 and g.hi is not None and g.hi <= 4 * t2:
        return Judgement("band", g.lo, g.hi)
    return Judgement("unknown", g.lo, g.hi)


def check_contact(xy_a, pos_a, rot_a, xy_b, pos_b, rot_b, x, r):
    """Is the point x within r of both bodies? True / False when certified, None otherwise.

    The distance from x to a body is the gap between the body and the point
    (a degenerate prism is not needed: the body's own closest point to x is
    found as a pair gap with a tiny triangle around x would be inexact), so it
    is computed here from the exact local coordinates of x: inside (0), or
    the exact projection onto the nearest feature, verified like the gap.
    """
    results = []
    for xy, pos, rot in ((xy_a, pos_a, rot_a), (xy_b, pos_b, rot_b)):
        results.append(_point_within(_Body(xy, pos, rot), [_q(v) for v in x], _q(r) ** 2))
    if all(v is True for v in results):
        return True
    if any(v is False for v in results):
        return False
    return None


def _point_within(body, x, r2):
    """Exact: is the distance from x to the body <= sqrt(r2)? (None if not certified)."""
    # Local coordinates of x by the exact inverse of R (Cramer).
    c0, c1, d = body.c0, body.c1, body.d
    rel = _sub(x, body.p)

    def det3(a, b, c):
        return (
            a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0])
        )

    D = det3(c0, c1, d)
    u, v, t = det3(rel, c1, d) / D, det3(c0, rel, d) / D, det3(c0, c1, rel) / D
    if t >= 0 and body.inside_polygon(u, v):
        return True
    fq = np.array([float(u), float(v)])
    best = None
    for name, base, gens, to_local in _features(body, fq, max(float(t), 0.0), np.inf):
        Mat = [[g[r] for g in gens] for r in range(3)]
        s = _solve(Mat, _sub(x, base), [F0] * len(gens))
        lu, lv, lt = to_local(s)
        if lt >= 0 and body.inside_polygon(lu, lv):
            y = body.local(lu, lv, lt)
            dd = _dot(_sub(x, y), _sub(x, y))
            best = dd if best is None or dd < best else best
    if best is not None and best <= r2:
        return True
    # Lower bound: the plane through the nearest feature point with normal x - y.
    return False if best is not None and _separated(body, x, r2) else None


def _separated(body, x, r2):
    """Exact proof that x is farther than sqrt(r2) from the body, by the best edge-line or end-plane bound."""
    # Half-spaces containing the body: the end-face plane (n = -d side) and the side planes.
    rel = x
    bounds = []
    nrm_end = (
        tuple(-c for c in _cross(body.c0, body.c1))
        if _dot(_cross(body.c0, body.c1), body.d) > 0
        else _cross(body.c0, body.c1)
    )
    for nvec in [nrm_end] + [_side_normal(body, k) for k in range(body.n)]:
        top = body.support(nvec, +1)
        if top is None:
            continue
        m = _dot(nvec, rel) - top
        if m > 0:
            bounds.append(m * m / _dot(nvec, nvec))
    return bool(bounds) and max(bounds) > r2


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _side_normal(body, k):
    (x0, y0), (x1, y1) = body.xy[k], body.xy[(k + 1) % body.n]
    e = tuple(body.c0[i] * (x1 - x0) + body.c1[i] * (y1 - y0) for i in range(3))
    nvec = _cross(e, body.d)
    # outward: away from the polygon's first vertex not on the edge
    u, v = body.xy[(k + 2) % body.n]
    inner = body.local(u, v, F0)
    return nvec if _dot(nvec, _sub(inner, body.local(x0, y0, F0))) < 0 else tuple(-c for c in nvec)
