"""Reference peers (python-fcl, optionally coal) used by the benchmarks.

General-purpose collision libraries have no semi-infinite prism, so each
prism is stood in for by a FINITE convex extrusion of its polygon from the
end face (local z = 0) to local z = L along +z; see ``fcl_standin_length``
for the old rule (kept for the benchmarks) and ``standin_lengths`` for the
sound per-pair rule used by :func:`prismbatch.lab.validate`.

The optional dependencies are imported lazily inside the functions, so
importing this module never requires them.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..geometry import centroid_radius, max_radius

__all__ = [
    "fcl_standin_length",
    "standin_lengths",
    "StandinLengths",
    "fcl_prism",
    "coal_prism",
    "FCLPeer",
    "FCLCylinderPeer",
    "CoalPeer",
]

_FCL_MISSING = "python-fcl is not installed: pip install 'prismbatch[fcl]'"
_COAL_MISSING = "coal is not installed: pip install 'prismbatch[coal]' (or pip install coal)"


def import_fcl():
    """The ``fcl`` module (python-fcl); ImportError naming the ``[fcl]`` extra when it is missing."""
    try:
        import fcl  # noqa: PLC0415
    except ImportError as exc:  # pragma: no cover - depends on environment
        raise ImportError(_FCL_MISSING) from exc
    return fcl


def _import_coal():
    try:
        import coal  # noqa: PLC0415
    except ImportError as exc:  # pragma: no cover - depends on environment
        raise ImportError(_COAL_MISSING) from exc
    return coal


def _polygon_ccw(xy) -> np.ndarray:
    poly = np.asarray(xy, dtype=float).reshape(-1, 2)
    if len(poly) < 3:
        raise ValueError("polygon needs at least 3 vertices")
    x, y = poly[:, 0], poly[:, 1]
    area2 = float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
    if area2 == 0.0:
        raise ValueError("polygon has zero area")
    return poly[::-1].copy() if area2 < 0.0 else poly.copy()


def fcl_standin_length(xy_a, xy_b, pos_a, pos_b) -> float:
    """Finite length L standing in for a semi-infinite prism.

    Rule::

        L = 4 * (|p_a - p_b| + R_a + R_b)

    where ``p_a``, ``p_b`` are the prisms' positions (end-face origins) and
    ``R_a``, ``R_b`` the polygons' maximum vertex radii about their local
    origin.  This is long enough that, for poses whose intersection (if any)
    lies within that distance of the end faces, the far caps cannot matter.
    It is NOT a guarantee for every pose: two nearly parallel axes that
    converge slowly can first meet arbitrarily far from both end faces, and
    then the truncated stand-ins report "no collision". :func:`standin_lengths`
    gives a per-pair length with a proof that the status cannot change.
    """
    pa = np.asarray(pos_a, dtype=float).reshape(3)
    pb = np.asarray(pos_b, dtype=float).reshape(3)
    return 4.0 * (float(np.linalg.norm(pa - pb)) + max_radius(xy_a) + max_radius(xy_b))


def standin_length(xy_a, xy_b, pos_a, rot_a, pos_b, rot_b):
    """One stand-in length for a whole pose set: the largest :func:`standin_lengths` over its pairs.

    Finite stand-ins of this length have the collision status of the
    semi-infinite prisms for every pair of the set (pairs whose bound was
    capped, axes parallel within about 1e-6 rad, excepted; see
    :func:`standin_lengths`). For a peer built once and queried at many poses.
    """
    return float(np.max(standin_lengths(xy_a, xy_b, pos_a, rot_a, pos_b, rot_b).length))


class StandinLengths(NamedTuple):
    """Result of :func:`standin_lengths` (all arrays of shape (N,))."""

    length: np.ndarray
    bound: np.ndarray
    sound: np.ndarray


def standin_lengths(xy_a, xy_b, pos_a, rot_a, pos_b, rot_b, *, factor=2.0, max_ratio=1e6):
    """Per-pair stand-in length L that provably cannot change the collision status.

    Rule (``S = |c_b - c_a| + R_a + R_b``: world end-face centroids, radii
    about them; ``d = R[:, 2]`` the axes; ``c = d_a . d_b``)::

        bound = S                               if c <= 0 or d_a == d_b exactly
              = S / sqrt(1 - c)                 otherwise
                (computed as sqrt(2) S / |d_a - d_b|, accurate for small angles)
        L     = factor * bound                  (factor 2 by default)

    Why: a common point ``x = x_a + s d_a = x_b + t d_b`` (``x_a, x_b`` in the
    end faces, ``s, t >= 0``: the depths along each axis) gives
    ``s d_a - t d_b = x_b - x_a``, of length at most S, while
    ``|s d_a - t d_b|^2 = s^2 + t^2 - 2 s t c`` is at least ``max(s, t)^2``
    when ``c <= 0`` and at least ``(1 - c) (s^2 + t^2)`` when ``c > 0``.
    So EVERY common point lies within ``bound`` of both end faces, and
    truncating both prisms at ``L >= bound`` leaves the intersection, hence the
    status, unchanged (a separated pair stays separated: the stand-ins are
    subsets). With ``factor >= 2`` the far cap is also at least ``bound >= S``
    away from the whole intersection, so the LP margin of the stand-ins equals
    the semi-infinite one whenever the bodies meet. For exactly parallel axes
    pointing the same way the intersection is unbounded, but sliding a common
    point back along the shared axis gives one with ``max(s, t) <= S``.
    Facing axes (``c <= 0``) need no more than ``S``; nearly parallel axes
    pointing the same way need about ``1.4 S / angle`` (they can first meet
    that far out), which the old rule (:func:`fcl_standin_length`) misses.

    Parameters
    ----------
    xy_a, xy_b : array_like, shape (n, 2)
        End-face polygons (local frames).
    pos_a, pos_b : array_like, shape (3,) or (N, 3)
        Positions of the local origins.
    rot_a, rot_b : array_like, shape (3, 3) or (N, 3, 3)
        Rotations (columns: local axes in world coordinates).
    factor : float, optional
        Safety factor >= 1 applied to the bound (default 2, see above).
    max_ratio : float, optional
        Lengths are capped at ``factor * max_ratio * S``; capped pairs are
        flagged ``sound = False`` (axes within about ``1.4 / max_ratio`` rad of
        parallel, same direction: finite stand-ins that long are numerically
        useless anyway).

    Returns
    -------
    StandinLengths
        ``length`` (N,) the lengths L to use, ``bound`` (N,) the uncapped
        bound (inf for caps), ``sound`` (N,) bool: ``length >= bound``.
    """
    factor = float(factor)
    max_ratio = float(max_ratio)
    if not (np.isfinite(factor) and factor >= 1.0):
        raise ValueError(f"factor must be a finite number >= 1, got {factor}")
    if not (np.isfinite(max_ratio) and max_ratio >= 1.0):
        raise ValueError(f"max_ratio must be a finite number >= 1, got {max_ratio}")
    N, pa, ra, pb, rb = _batch_poses(pos_a, rot_a, pos_b, rot_b)
    ca2, Ra = centroid_radius(xy_a)
    cb2, Rb = centroid_radius(xy_b)
    ca = pa + ra[:, :, :2] @ ca2
    cb = pb + rb[:, :, :2] @ cb2
    S = np.linalg.norm(cb - ca, axis=1) + Ra + Rb
    da, db = ra[:, :, 2], rb[:, :, 2]
    c = np.einsum("ij,ij->i", da, db)
    diff = np.linalg.norm(da - db, axis=1)
    with np.errstate(divide="ignore"):
        inv = np.where(c > 0.0, np.sqrt(2.0) / diff, 1.0)
    inv = np.where(diff == 0.0, 1.0, inv)  # exactly parallel, same direction
    bound = S * inv
    cap = max_ratio * S
    sound = bound <= cap
    length = factor * np.minimum(bound, cap)
    return StandinLengths(length, bound, sound)


def _prism_mesh(xy, length):
    """Vertices (2n, 3) and outward-oriented faces of the extruded polygon.

    Vertices 0..n-1 are the polygon at z = 0, n..2n-1 at z = length.
    Faces (vertex index lists, CCW seen from outside): the bottom cap
    (normal -z), the top cap (normal +z), and n side quads.
    """
    poly = _polygon_ccw(xy)
    length = float(length)
    if not length > 0.0:
        raise ValueError("length must be positive")
    n = len(poly)
    verts = np.zeros((2 * n, 3))
    verts[:n, :2] = poly
    verts[n:, :2] = poly
    verts[n:, 2] = length
    faces = [list(range(n - 1, -1, -1)), list(range(n, 2 * n))]
    for i in range(n):
        j = (i + 1) % n
        # (v_j - v_i) x (+z) = outward normal for a CCW polygon
        faces.append([i, j, n + j, n + i])
    return verts, faces


def fcl_prism(xy, length):
    """``fcl.Convex`` of the polygon extruded from z = 0 to z = ``length``.

    python-fcl's constructor is ``fcl.Convex(verts, num_faces, faces)``
    with ``verts`` (V, 3) float and ``faces`` a flat int array
    ``[k, i0, ..., i_{k-1}, k, ...]``; faces are listed CCW seen from
    outside (outward normals).
    """
    fcl = import_fcl()
    verts, faces = _prism_mesh(xy, length)
    flat = []
    for f in faces:
        flat.append(len(f))
        flat.extend(f)
    return fcl.Convex(verts, len(faces), np.asarray(flat, dtype=np.int64))


def _cap_strip(n):
    """Triangles (i, j, k) covering the CCW polygon 0..n-1 as a zig-zag strip.

    Unlike a fan, no vertex gets more than a few neighbours: coal refuses
    convex meshes whose vertices have too many (a 254-gon fan fails).
    """
    tris = []
    i, j = 0, n - 1
    while j - i >= 2:
        tris.append((i, i + 1, j))
        i += 1
        if j - i >= 2:
            tris.append((i, j - 1, j))
            j -= 1
    return tris


def coal_prism(xy, length):
    """``coal.Convex`` of the extruded polygon (triangulated, outward facing)."""
    coal = _import_coal()
    verts, faces = _prism_mesh(xy, length)
    n = len(verts) // 2
    pts = coal.StdVec_Vec3s()
    for v in verts:
        pts.append(np.asarray(v, dtype=float))
    tris = coal.StdVec_Triangle()
    for a, b, c in _cap_strip(n):
        tris.append(coal.Triangle(a, c, b))  # bottom cap, normal -z
        tris.append(coal.Triangle(n + a, n + b, n + c))  # top cap, normal +z
    for f in faces[2:]:  # side quads, outward
        tris.append(coal.Triangle(int(f[0]), int(f[1]), int(f[2])))
        tris.append(coal.Triangle(int(f[0]), int(f[2]), int(f[3])))
    return coal.Convex(pts, tris)


def _batch_poses(pos_a, rot_a, pos_b, rot_b):
    pos_a = np.asarray(pos_a, dtype=float)
    pos_b = np.asarray(pos_b, dtype=float)
    rot_a = np.asarray(rot_a, dtype=float)
    rot_b = np.asarray(rot_b, dtype=float)
    N = max(
        pos_a.reshape(-1, 3).shape[0],
        pos_b.reshape(-1, 3).shape[0],
        rot_a.reshape(-1, 3, 3).shape[0],
        rot_b.reshape(-1, 3, 3).shape[0],
    )
    pos_a = np.broadcast_to(pos_a.reshape(-1, 3), (N, 3))
    pos_b = np.broadcast_to(pos_b.reshape(-1, 3), (N, 3))
    rot_a = np.broadcast_to(rot_a.reshape(-1, 3, 3), (N, 3, 3))
    rot_b = np.broadcast_to(rot_b.reshape(-1, 3, 3), (N, 3, 3))
    return N, pos_a, rot_a, pos_b, rot_b


class _Peer:
    """Boolean collision of two finite prism stand-ins in a library like FCL.

    Built once from the two polygons and the stand-in ``length`` (see
    ``fcl_standin_length``); the collision objects are reused and only their
    transforms change per query. A fresh request and result are created per
    query (python-fcl accumulates contacts into a reused result).
    Subclasses name the library's module, geometry builder and result test.
    """

    def __init__(self, xy_a, xy_b, length):
        self._setup(self._geometry(xy_a, float(length)), self._geometry(xy_b, float(length)), length)

    def _setup(self, geom_a, geom_b, length):
        lib = self._import()
        self._lib = lib
        self._Transform = getattr(lib, self._transform_name)
        self.length = float(length)
        self.geom_a, self.geom_b = geom_a, geom_b
        self.obj_a = lib.CollisionObject(self.geom_a, self._Transform())
        self.obj_b = lib.CollisionObject(self.geom_b, self._Transform())

    @staticmethod
    def prepare(pos_a, rot_a, pos_b, rot_b):
        """Per-pair contiguous float64 (R_a, p_a, R_b, p_b) tuples (outside timed loops)."""
        N, pos_a, rot_a, pos_b, rot_b = _batch_poses(pos_a, rot_a, pos_b, rot_b)
        f = np.ascontiguousarray
        return [(f(rot_a[k]), f(pos_a[k]), f(rot_b[k]), f(pos_b[k])) for k in range(N)]

    def run(self, items) -> np.ndarray:
        """Collide prepared pairs: per query two transforms, a fresh request/result."""
        lib = self._lib
        oa, ob = self.obj_a, self.obj_b
        Transform, Request, Result, collide = (self._Transform, lib.CollisionRequest, lib.CollisionResult, lib.collide)
        hit = self._is_collision
        out = np.empty(len(items), dtype=bool)
        for k, (ra, pa, rb, pb) in enumerate(items):
            oa.setTransform(Transform(ra, pa))
            ob.setTransform(Transform(rb, pb))
            res = Result()
            collide(oa, ob, Request(), res)
            out[k] = hit(res)
        return out

    def collide(self, pos_a, rot_a, pos_b, rot_b) -> bool:
        """One pair: poses (3,) and (3, 3)."""
        return bool(self.run(self.prepare(pos_a, rot_a, pos_b, rot_b))[0])

    def collide_batch(self, pos_a, rot_a, pos_b, rot_b) -> np.ndarray:
        """(N,) bool for per-pair poses pos (N, 3), rot (N, 3, 3) (broadcasts)."""
        return self.run(self.prepare(pos_a, rot_a, pos_b, rot_b))


class FCLPeer(_Peer):
    """python-fcl (GJK/MPR on ``fcl.Convex``) on finite stand-ins."""

    _import = staticmethod(import_fcl)
    _geometry = staticmethod(fcl_prism)
    _transform_name = "Transform"

    @staticmethod
    def _is_collision(res):
        return res.is_collision


class FCLCylinderPeer(FCLPeer):
    """python-fcl's own ``Cylinder(radius, length)`` as a, against b's finite prism stand-in.

    The exact-shape peer of the work-precision study. FCL's cylinder is
    centred on its origin along its local z, so a's pose is shifted by
    ``length / 2`` along a's axis: its end face is then a's end face and it
    extends along d_a, like a prism stand-in.
    """

    def __init__(self, radius, xy_b, length):
        fcl = import_fcl()
        self._setup(fcl.Cylinder(float(radius), float(length)), fcl_prism(xy_b, float(length)), length)

    def prepare(self, pos_a, rot_a, pos_b, rot_b):
        """As :meth:`FCLPeer.prepare`, with a's position moved to the cylinder's centre."""
        _, pos_a, rot_a, pos_b, rot_b = _batch_poses(pos_a, rot_a, pos_b, rot_b)
        return _Peer.prepare(pos_a + 0.5 * self.length * rot_a[:, :, 2], rot_a, pos_b, rot_b)


class CoalPeer(_Peer):
    """coal (the maintained hpp-fcl successor) on finite stand-ins."""

    _import = staticmethod(_import_coal)
    _geometry = staticmethod(coal_prism)
    _transform_name = "Transform3s"

    @staticmethod
    def _is_collision(res):
        return res.isCollision()


class _DistancePeer(_Peer):
    """Signed distance of two finite prism stand-ins: ``run`` returns (distance (N,), point_a (N, 3), point_b (N, 3)).

    The library's signed distance (negative: minus its penetration depth, by EPA) with its
    nearest points; a fresh request and result per query, as for collisions.
    """

    def run(self, items):
        lib = self._lib
        oa, ob = self.obj_a, self.obj_b
        Transform = self._Transform
        n = len(items)
        dist, pa_out, pb_out = np.empty(n), np.empty((n, 3)), np.empty((n, 3))
        for k, (ra, pa, rb, pb) in enumerate(items):
            oa.setTransform(Transform(ra, pa))
            ob.setTransform(Transform(rb, pb))
            dist[k], pa_out[k], pb_out[k] = self._query(lib, oa, ob, self.tolerance)
        return dist, pa_out, pb_out


class CoalDistancePeer(_DistancePeer):
    """coal's ``distance`` (GJK, EPA when penetrating) on ``coal.Convex`` stand-ins.

    ``tolerance`` (default: coal's own, what users get) sets its EPA tolerance: with its
    default coal's depth was off by up to about 1e-4 of a size-4 scene here, so an accuracy
    comparison of depths needs a tight one (1e-12).
    """

    _import = staticmethod(_import_coal)
    _geometry = staticmethod(coal_prism)
    _transform_name = "Transform3s"

    def __init__(self, xy_a, xy_b, length, tolerance=None):
        super().__init__(xy_a, xy_b, length)
        self.tolerance = tolerance

    @staticmethod
    def _query(lib, oa, ob, tolerance):
        req, res = lib.DistanceRequest(), lib.DistanceResult()
        req.enable_signed_distance = True
        if tolerance is not None:
            req.epa_tolerance = tolerance  # the depth only: a tight GJK tolerance gave gaps of 0.0 here
            req.epa_max_iterations = 10_000
        d = lib.distance(oa, ob, req, res)
        return d, res.getNearestPoint1(), res.getNearestPoint2()


class FCLDistancePeer(_DistancePeer):
    """python-fcl's signed ``distance`` on ``fcl.Convex`` stand-ins."""

    _import = staticmethod(import_fcl)
    _geometry = staticmethod(fcl_prism)
    _transform_name = "Transform"

    tolerance = None  # python-fcl's request has no tolerance to set

    @staticmethod
    def _query(lib, oa, ob, tolerance):
        req = lib.DistanceRequest(enable_nearest_points=True, enable_signed_distance=True)
        res = lib.DistanceResult()
        d = lib.distance(oa, ob, req, res)
        return d, res.nearest_points[0], res.nearest_points[1]
