"""Independent references for the signed distance of two semi-infinite convex prisms.

Shares no code with the kernels: plain NumPy over every feature, plus HiGHS for a QP. Used by
the test suite and by the distance section of ``prismbatch validate``
(``docs/methods/validation.md``). The cost grows with the product of the vertex counts (every
pair of edges is visited, in slices of bounded memory): milliseconds for 36-gons, about a second
for two 360-gons, a few seconds for a 36-gon against a 3600-gon.

* :func:`sat_separation`: ``max_u [min_B u.y - max_A u.x]`` over every candidate axis (facet
  normals of either body and cross products of an edge direction of each: end-face edges and
  the axes), restricted to the directions in which both supports are finite (u.d_a <= 0,
  u.d_b >= 0). The Minkowski difference A - B is a polyhedron whose facet normals are all
  among these axes, so this is exactly minus the penetration depth when the bodies overlap,
  and a positive lower bound of the gap when they do not.
* :func:`gap_features`: the gap by brute force over feature pairs (vertex-face, edge-edge,
  with the lateral edges as rays and the side faces as half-strips), which is exact for
  disjoint convex polyhedra without lines (the closest pair can be taken at an extreme point
  of the set of closest pairs, where one point is a vertex or both lie on edges).
* :func:`gap_qp`: the gap as the convex QP ``min |x - y|^2``, x in A, y in B, by HiGHS (the
  bodies in vertex form), with its certificate: the separation along n = (y - x) / |y - x|,
  a lower bound that meets |y - x| at the optimum. Used to check :func:`gap_features`.
* :func:`check_gap`: confirms a feature gap by its optimality (KKT) condition, a lower bound
  that meets it (the separation along the direction of the closest points, or the SAT value),
  and otherwise by the QP, a second solver.
* :func:`signed_distance_reference`: SAT when the bodies overlap, the feature gap when they
  do not.

A rotation is taken as the exact linear map it is given as (a float32 rotation read in float64 is
orthonormal only to about 1e-7): world normals are mapped by its inverse transpose and every length is
measured in the world.
"""

from __future__ import annotations

import numpy as np

from ..geometry import ccw
from .highs import import_highspy, new_highs

__all__ = [
    "Body",
    "sat_separation",
    "gap_features",
    "gap_qp",
    "check_gap",
    "signed_distance_reference",
    "signed_distance_of",
    "residual",
]

#: Rows (axes or edge pairs) handled at once: bounds the memory of the brute force.
_SLICE = 200_000


class Body:
    """One prism in world coordinates: vertices V (n, 3), axis d, end edges E, side normals N, local data."""

    def __init__(self, xy, pos, rot):
        # counter-clockwise by the area about the mean: the shoelace sum of coordinates far from the
        # origin rounds to the wrong sign on slivers, which flipped every edge normal below
        xy = ccw(xy)
        self.xy = xy
        self.pos = np.asarray(pos, dtype=float).reshape(3)
        self.rot = np.asarray(rot, dtype=float).reshape(3, 3)
        self.V = self.pos + xy @ self.rot[:, :2].T
        self.d = self.rot[:, 2].copy()
        self.E = np.roll(self.V, -1, axis=0) - self.V
        e = np.roll(xy, -1, axis=0) - xy
        n_loc = np.column_stack([e[:, 1], -e[:, 0]]) / np.hypot(e[:, 0], e[:, 1])[:, None]
        self.n_loc = n_loc  # outward unit edge normals, local
        self.h_loc = np.einsum("ij,ij->i", n_loc, xy)
        # World normals of the end plane and side faces: R^-T times the local ones, not R (float32
        # rotations in float64 are orthonormal only to 1e-7; mapping by R left the gaps 2-15 tol off).
        # A local offset (n.u - h) over |R^-T n| is the world distance to the plane.
        inv = np.linalg.inv(self.rot)
        m = inv[2]  # e_z^T R^-1
        self.m_scale = float(np.linalg.norm(m))
        self.m = m / self.m_scale  # unit, into the body (m.d = 1 / m_scale > 0)
        N = n_loc @ inv[:2]
        self.N_scale = np.linalg.norm(N, axis=1)
        self.N = N / self.N_scale[:, None]

    def local(self, p):
        """Local coordinates (q_x, q_y, t) of world points p (k, 3), by the inverse of the matrix as given
        (the body is its affine image: R^T is the inverse only to |R^T R - I|, which at points 1e11 out,
        where nearly parallel axes meet, misjudged residuals by up to 2e5 tol)."""
        return np.linalg.solve(self.rot, (np.asarray(p, dtype=float).reshape(-1, 3) - self.pos).T).T


def residual(body, p):
    """Largest violated half-space of world points p (k, 3), in world lengths: <= 0 inside, a lower
    bound of the distance."""
    loc = body.local(p)
    side = (loc[:, :2] @ body.n_loc.T - body.h_loc) / body.N_scale
    return np.maximum(-loc[:, 2] / body.m_scale, side.max(axis=1))


def _unit_rows(U):
    n = np.linalg.norm(U, axis=1)
    keep = n > 0
    return U[keep] / n[keep, None]


def _axis_cross(a, b):
    """a x b for the two axes, through the exact difference b - s a (keeps a tiny tilt's direction)."""
    s = 1.0 if a @ b >= 0 else -1.0
    return np.cross(a, b - s * a)


def separation_along(A, B, U):
    """``min_B u.y - max_A u.x`` per row of U (finite supports assumed: the end faces carry them)."""
    return (U @ B.V.T).min(axis=1) - (U @ A.V.T).max(axis=1)


def sat_separation(A, B):
    """(value, axis): max over every candidate axis of the separation along it (see the module docstring).

    Finite supports need u.d_a <= 0 and u.d_b >= 0. Axes that are across an axis by
    construction (side normals, cross products with an axis) lie on the boundary of these
    directions; their other sign is tested through the exact difference of the axes
    (e = d_b - s d_a), which keeps a tilt of 1e-13 decisive where u.d_b itself would be
    rounding noise.
    """
    s = 1.0 if A.d @ B.d >= 0 else -1.0
    e = B.d - s * A.d
    groups = [  # (axes, the test each must pass)
        (-A.m[None], "both"),
        (B.m[None], "both"),
        (A.N, "across_a"),
        (-B.N, "across_b"),
        (np.cross(A.E[:, None, :], B.E[None, :, :]).reshape(-1, 3), "both"),
        (np.cross(A.E, B.d[None]), "across_b"),
        (np.cross(A.d[None], B.E), "across_a"),
        (_axis_cross(A.d, B.d)[None], "across_both"),
    ]
    best, axis = -np.inf, None
    for U_all, test in groups:
        for lo in range(0, len(U_all), _SLICE):
            U = _unit_rows(U_all[lo : lo + _SLICE])
            U = np.concatenate([U, -U])
            if test == "both":
                ok = (U @ A.d <= 0) & (U @ B.d >= 0)
            elif test == "across_a":  # u.d_a = 0: need u.d_b = u.e >= 0
                ok = U @ e >= 0
            elif test == "across_b":  # u.d_b = 0: need u.d_a = -s u.e <= 0
                ok = -s * (U @ e) <= 0
            else:
                ok = np.ones(len(U), dtype=bool)
            if ok.any():
                sep = separation_along(A, B, U[ok])
                k = int(np.argmax(sep))
                if sep[k] > best:
                    best, axis = float(sep[k]), U[ok][k]
    return best, axis


def _point_segment(P, Q0, D, tmax):
    """Distances from points P (k, 3) to segments/rays Q0 + t D, t in [0, tmax] (rows paired), and the feet."""
    dd = np.einsum("ij,ij->i", D, D)
    t = np.clip(np.einsum("ij,ij->i", P - Q0, D) / dd, 0.0, tmax)
    inside = (t > 0) & (t < tmax)
    line = np.linalg.norm(np.cross(P - Q0, D), axis=1) / np.sqrt(dd)  # line distance, exact to rounding
    foot = Q0 + t[:, None] * D
    end = np.linalg.norm(P - foot, axis=1)
    return np.where(inside, line, end), foot


def _edges(body):
    """(origins, directions, parameter limits) of the end edges (segments) and lateral edges (rays)."""
    n = len(body.V)
    O = np.concatenate([body.V, body.V])
    D = np.concatenate([body.E, np.repeat(body.d[None], n, axis=0)])
    T = np.concatenate([np.ones(n), np.full(n, np.inf)])
    return O, D, T


def _closest(cands):
    """The (distance, x, y) of smallest distance among candidates (d (k,), x (k, 3), y (k, 3))."""
    best = (np.inf, None, None)
    for d, x, y in cands:
        if len(d) and np.isfinite(d).any():
            k = int(np.nanargmin(d))
            if d[k] < best[0]:
                best = (float(d[k]), x[k], y[k])
    return best


def _edge_edge(A, B):
    """(distance, x, y): the closest pair over all pairs of edges (segment or ray) of A and B."""
    O1, D1, T1 = _edges(A)
    O2, D2, T2 = _edges(B)
    i, j = np.meshgrid(np.arange(len(O1)), np.arange(len(O2)), indexing="ij")
    i, j = i.ravel(), j.ravel()
    best = (np.inf, None, None)
    for lo in range(0, len(i), _SLICE):
        r = _edge_pairs(A, B, (O1, D1, T1), (O2, D2, T2), i[lo : lo + _SLICE], j[lo : lo + _SLICE])
        if r[0] < best[0]:
            best = r
    return best


def _edge_pairs(A, B, edges_a, edges_b, i, j):
    """(distance, x, y) of the closest pair over the edge pairs (i[k] of A, j[k] of B)."""
    O1, D1, T1 = edges_a
    O2, D2, T2 = edges_b
    P0, U, S = O1[i], D1[i], T1[i]
    Q0, W, T = O2[j], D2[j], T2[j]
    r = P0 - Q0
    # Cross product of the directions: for two axes through the exact difference.
    N = np.cross(U, W)
    both_axes = np.isinf(S) & np.isinf(T)
    if both_axes.any():
        N[both_axes] = _axis_cross(A.d, B.d)
    nn = np.einsum("ij,ij->i", N, N)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.einsum("ij,ij->i", N, np.cross(W, r)) / nn
        t = np.einsum("ij,ij->i", N, np.cross(U, r)) / nn
        line = np.abs(np.einsum("ij,ij->i", r, N)) / np.sqrt(nn)
    # Interior critical points only where the cross product has a trustworthy direction: the two
    # axes (formed exactly), or edges more than 1e-10 from parallel; nearer to parallel, the
    # ends below give the minimum to within 1e-10 of the edge length.
    sharp = nn > 1e-20 * np.einsum("ij,ij->i", U, U) * np.einsum("ij,ij->i", W, W)
    interior = (sharp | (both_axes & (nn > 0))) & (s >= 0) & (s <= S) & (t >= 0) & (t <= T)
    s0, t0 = np.where(interior, s, 0.0), np.where(interior, t, 0.0)
    cands = [(np.where(interior, line, np.inf), P0 + s0[:, None] * U, Q0 + t0[:, None] * W)]
    d, f = _point_segment(P0, Q0, W, T)
    cands.append((d, P0, f))
    d, f = _point_segment(Q0, P0, U, S)
    cands.append((d, f, Q0))
    fin_s, fin_t = np.isfinite(S), np.isfinite(T)
    P1 = P0 + np.where(fin_s, S, 0)[:, None] * U
    Q1 = Q0 + np.where(fin_t, T, 0)[:, None] * W
    d, f = _point_segment(P1, Q0, W, T)
    cands.append((np.where(fin_s, d, np.inf), P1, f))
    d, f = _point_segment(Q1, P0, U, S)
    cands.append((np.where(fin_t, d, np.inf), f, Q1))
    return _closest(cands)


def _vertex_faces(P, body):
    """(distance, point, foot): points P (k, 3) to the faces of ``body`` whose plane foot lies in the face."""
    step = max(1, _SLICE // len(body.V))
    best = (np.inf, None, None)
    for lo in range(0, len(P), step):
        r = _vertex_faces_slice(P[lo : lo + step], body)
        if r[0] < best[0]:
            best = r
    return best


def _vertex_faces_slice(P, body):
    """:func:`_vertex_faces` of a few points (memory: points times faces)."""
    loc = body.local(P)
    q, t = loc[:, :2], loc[:, 2]
    cands = []
    # end face: the foot along its world normal m (for a rigid rotation, along d: q stays)
    h = t / body.m_scale
    foot = P - h[:, None] * body.m
    inside = (body.local(foot)[:, :2] @ body.n_loc.T - body.h_loc <= 0).all(axis=1)
    if inside.any():
        k = np.flatnonzero(inside)
        cands.append((np.abs(h[k]), P[k], foot[k]))
    # side faces: the world offset where the foot has t >= 0 and lies on the edge segment
    v = body.xy
    e = np.roll(v, -1, axis=0) - v
    off = (q @ body.n_loc.T - body.h_loc) / body.N_scale
    feet = P[:, None, :] - off[:, :, None] * body.N[None]  # (k, n, 3)
    floc = body.local(feet.reshape(-1, 3)).reshape(feet.shape)
    lam = ((floc[..., :2] - v[None]) * e[None]).sum(axis=2) / (e * e).sum(axis=1)[None]
    ok = (floc[..., 2] >= 0) & (lam >= 0) & (lam <= 1)
    if ok.any():
        k, f = np.nonzero(ok)
        cands.append((np.abs(off[k, f]), P[k], feet[k, f]))
    return _closest(cands)


def gap_features(A, B, points=False):
    """The gap of disjoint bodies by brute force over feature pairs (meaningless if they overlap).

    A float, or with ``points=True`` ``(gap, x, y)``: x on A and y on B at that distance.
    """
    d, x, y = _vertex_faces(A.V, B)
    cands = [(np.array([d]), np.array([x]), np.array([y]))] if x is not None else []
    d, y, x = _vertex_faces(B.V, A)
    if x is not None:
        cands.append((np.array([d]), np.array([x]), np.array([y])))
    d, x, y = _edge_edge(A, B)
    if x is not None:
        cands.append((np.array([d]), np.array([x]), np.array([y])))
    gap, x, y = _closest(cands)
    return (gap, x, y) if points else gap


def gap_qp(A, B, time_limit=30.0):
    """(gap, x, y, lower): the QP ``min |w|^2, w = x - y``, x in A, y in B, by HiGHS, and a lower bound.

    The bodies in vertex form: x = sum_i alpha_i V_a,i + t_a d_a with alpha in the unit
    simplex and t_a >= 0, likewise y; w = x - y are three equality rows, so the Hessian is
    2 I on w alone. The lower bound is the separation along n = (y - x) / |y - x|, nudged
    into the directions of finite support (the certificate: it equals the gap at the optimum).
    """
    highspy = import_highspy()

    na, nb = len(A.V), len(B.V)
    nv = na + nb + 2 + 3  # alpha, beta, t_a, t_b, w
    inf = highspy.kHighsInf
    Am = np.zeros((5, nv))
    Am[0, :na] = 1.0  # sum alpha = 1
    Am[1, na : na + nb] = 1.0  # sum beta = 1
    Am[2:, :na] = -A.V.T  # w - x + y = 0
    Am[2:, na : na + nb] = B.V.T
    Am[2:, na + nb] = -A.d
    Am[2:, na + nb + 1] = B.d
    Am[2:, na + nb + 2 :] = np.eye(3)
    rhs = np.array([1.0, 1.0, 0.0, 0.0, 0.0])
    lp = highspy.HighsLp()
    lp.num_col_ = nv
    lp.num_row_ = 5
    lp.col_cost_ = np.zeros(nv)
    lp.col_lower_ = np.concatenate([np.zeros(na + nb + 2), np.full(3, -inf)])
    lp.col_upper_ = np.full(nv, inf)
    lp.row_lower_ = rhs
    lp.row_upper_ = rhs
    lp.a_matrix_.format_ = highspy.MatrixFormat.kColwise
    cols = [np.flatnonzero(Am[:, j]) for j in range(nv)]
    lp.a_matrix_.start_ = np.concatenate([[0], np.cumsum([len(x) for x in cols])]).astype(np.int32)
    lp.a_matrix_.index_ = np.concatenate(cols).astype(np.int32)
    lp.a_matrix_.value_ = np.concatenate([Am[x, j] for j, x in enumerate(cols)])
    hess = highspy.HighsHessian()
    hess.dim_ = nv
    hess.format_ = highspy.HessianFormat.kTriangular
    hess.start_ = np.concatenate([np.zeros(nv - 2), [1, 2, 3]]).astype(np.int32)
    hess.index_ = np.arange(nv - 3, nv, dtype=np.int32)
    hess.value_ = np.full(3, 2.0)
    model = highspy.HighsModel()
    model.lp_ = lp
    model.hessian_ = hess
    h = new_highs(time_limit)
    h.passModel(model)
    h.run()
    if h.getModelStatus() != highspy.HighsModelStatus.kOptimal:
        raise RuntimeError(f"HiGHS QP: {h.modelStatusToString(h.getModelStatus())}")
    z = np.array(h.getSolution().col_value)
    x = z[:na] @ A.V + z[na + nb] * A.d
    y = z[na : na + nb] @ B.V + z[na + nb + 1] * B.d
    gap = float(np.linalg.norm(y - x))
    n = _into_finite_cone((y - x) / gap, A.d, B.d) if gap > 0 else None
    lower = float(separation_along(A, B, n[None])[0]) if n is not None else -np.inf
    return gap, x, y, lower


def _into_finite_cone(n, da, db):
    """The nearest unit direction u to n with u.d_a <= 0 and u.d_b >= 0 (None if there is none).

    Solver round-off leaves the optimal axis a little outside these directions, where a
    support is infinite and the separation along it is no lower bound.
    """
    fine = lambda u: u @ da <= 1e-14 and u @ db >= -1e-14  # rounding of the projections below
    if fine(n):
        return n
    for u in (n - max(n @ da, 0.0) * da, n - min(n @ db, 0.0) * db):
        if fine(u) and np.linalg.norm(u) > 0:
            return u / np.linalg.norm(u)
    m = _axis_cross(da, db)  # both active: the line across both axes
    if np.linalg.norm(m) == 0:
        return None
    m = m / np.linalg.norm(m)
    return m if n @ m >= 0 else -m


def check_gap(A, B, gap, x, y, tol, scale, sep=-np.inf, qp_rel=1e-6, time_limit=5.0):
    """Confirm a feature gap: "certificate", "qp" or "failed".

    ``gap`` is the distance of x in A and y in B (:func:`gap_features` with ``points=True``),
    so an upper bound. "certificate": x and y lie in their bodies to ``tol`` (plus the rounding
    of their coordinates) and a lower bound
    meets ``gap`` to ``tol``: the SAT value ``sep`` or the separation along
    ``n = (y - x) / |y - x|`` (the optimality (KKT) condition of ``min |x - y|``: x and y are
    the supports of their bodies along n). Otherwise (the direction of a gap of a few rounding
    units is itself rounding) "qp": the second solver agrees to ``qp_rel * scale``, its points
    in their bodies and its value no smaller than the features' (no closer pair missed); HiGHS
    is trusted to about 1e-7 of the scene and sometimes stalls near touching, giving "failed"
    after ``time_limit`` seconds.
    """
    # in their bodies to tol and the rounding of their own coordinates (nearly parallel axes
    # that point the same way pass closest at about gap / tilt from the end faces)
    reach = tol + 8 * np.finfo(float).eps * max(np.abs(x).max(), np.abs(y).max())
    inside = max(residual(A, x[None])[0], residual(B, y[None])[0]) <= reach
    n = _into_finite_cone((y - x) / gap, A.d, B.d) if gap > 0 else None
    lower = max(sep, float(separation_along(A, B, n[None])[0]) if n is not None else -np.inf)
    if inside and gap - lower <= tol:
        return "certificate"
    try:
        qp, xq, yq, lq = gap_qp(A, B, time_limit=time_limit)
    except RuntimeError:
        return "failed"
    eps = qp_rel * scale
    in_q = max(residual(A, xq[None])[0], residual(B, yq[None])[0]) <= eps
    ok = in_q and inside and gap <= qp + eps and gap - max(lower, lq) <= eps
    return "qp" if ok else "failed"


def signed_distance_reference(xy_a, pos_a, rot_a, xy_b, pos_b, rot_b):
    """(signed distance, kind): kind "sat" (overlap: minus the depth) or "features" (the gap)."""
    return signed_distance_of(Body(xy_a, pos_a, rot_a), Body(xy_b, pos_b, rot_b))


def signed_distance_of(A, B):
    """:func:`signed_distance_reference` of two :class:`Body` objects."""
    sep, _ = sat_separation(A, B)
    if sep <= 0.0:
        return sep, "sat"
    return gap_features(A, B), "features"
