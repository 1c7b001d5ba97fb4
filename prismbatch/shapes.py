"""Convex prisms and their structure-of-arrays storage.

A prism is a semi-infinite convex right prism: its end face is a convex polygon
given as ``(n, 2)`` vertices in the prism's local frame (at ``z = 0``) and its
body extends from the end face along local ``+z`` without end.

Kernels never see Python objects: a :class:`PrismSet` flattens every polygon
into one vertex array plus offsets, and precomputes what the kernels need
(vertices about an internal centre, unwrapped edge and polar angles for the
binary searches, inverse edge lengths, bounding radii).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ._kernels.batch import pack, unpack
from ._kernels.planar import edge_search_tables_each
from .checks import check_memory, format_bytes, real_scalar, refuse_masked
from .config import MAX_VERTICES, SUPPORTED_RANGE
from .outline import binary_exponent, check_polygons, next_rows, prev_rows, raise_first_failure, read_polygon
from .outline import validate_polygon as validate_polygon

__all__ = ["Prism", "PrismSet", "validate_polygon"]

# Peak bytes a vertex costs from building a prism to a Collider's tables of it
# (tracemalloc on a 10^6-gon: a peak of 163 B to build and check the polygon, of
# 216 B to its PrismSet and one packed copy, 112 B kept; float32 packs a second copy).
_BYTES_PER_VERTEX = 240


def _vertex_count(xy):
    """Vertices of a polygon argument, read without copying it (0 if it has no length)."""
    if isinstance(xy, Prism):
        return xy.n_vertices
    try:
        return len(xy)
    except TypeError:  # not a sequence: validate_polygon says what is wrong with it
        return 0


def _centroids(ccw):
    """Area centroids (m, 2) of convex CCW polygons (m, n, 2) (strictly interior), at any size and offset."""
    e0 = binary_exponent(ccw)[:, None, None]
    u = np.ldexp(ccw, -e0)
    u0 = u[:, :1].copy()
    u = u - u0
    e1 = binary_exponent(u)[:, None]
    xs, ys = np.ldexp(u[..., 0], -e1), np.ldexp(u[..., 1], -e1)
    # Shift to the mean too: keeps the shoelace sums well conditioned.
    x0, y0 = xs.mean(axis=1, keepdims=True), ys.mean(axis=1, keepdims=True)
    xs, ys = xs - x0, ys - y0
    xn, yn = next_rows(xs), next_rows(ys)
    cr = xs * yn - xn * ys
    a = cr.sum(axis=1, keepdims=True) / 2.0
    c = np.concatenate(
        (
            ((xs + xn) * cr).sum(axis=1, keepdims=True) / (6.0 * a) + x0,
            ((ys + yn) * cr).sum(axis=1, keepdims=True) / (6.0 * a) + y0,
        ),
        axis=1,
    )
    return np.ldexp(np.ldexp(c, e1) + u0[:, 0], e0[:, 0])


def _kernel_data(ccw, centre):
    """Per-vertex arrays the kernels use (see PrismSet attributes) of polygons (m, n, 2) about centres (m, 2).

    Returns ``(v (m, n, 2), edge_angle (m, n), edge_table (m, n), vertex_angle (m, n),
    inv_edge_len (m, n))``.
    """
    m, n = ccw.shape[:2]
    v = ccw - centre[:, None, :]
    e = next_rows(v) - v
    elen = np.hypot(e[..., 0], e[..., 1])
    eang = np.empty((m, n))
    etab = np.empty((m, n), dtype=np.int64)
    exact_edges = next_rows(ccw) - ccw
    edge_search_tables_each(
        np.ascontiguousarray(exact_edges[..., 0]), np.ascontiguousarray(exact_edges[..., 1]), eang, etab
    )
    # Polar angle of each vertex about the centre, unwrapped to increase
    # (from unit-scaled copies: angles do not depend on size, products might overflow).
    u = np.ldexp(v, -binary_exponent(v)[:, None, None])
    ux, uy, px, py = u[..., 0], u[..., 1], prev_rows(u[..., 0]), prev_rows(u[..., 1])
    step = np.arctan2(px * uy - py * ux, px * ux + py * uy)
    vang = np.arctan2(v[:, :1, 1], v[:, :1, 0]) + np.concatenate(
        (np.zeros((m, 1)), np.cumsum(step[:, 1:], axis=1)), axis=1
    )
    return v, eang, etab, vang, 1.0 / elen


def _radii(ccw, centres, names):
    """Bounding radii (m,) of polygons (m, n, 2) about their centres (m, 2).

    ValueError naming the first polygon (``names(j)``) whose extent overflows float64 (coordinates
    near its limit, 1.8e308): its edges, and the kernels' tables of them, would be infinite.
    """
    with np.errstate(over="ignore", invalid="ignore"):
        extent = np.ptp(ccw, axis=1)
        span = np.hypot(extent[:, 0], extent[:, 1])  # bounds every edge and twice every radius
    if not np.isfinite(span).all():
        j = int(np.argmin(np.isfinite(span)))
        raise ValueError(
            f"{names(j)}: its extent overflows float64 (vertices up to {np.abs(ccw[j]).max():.3g} from the "
            "origin: its bounding box's diagonal is beyond 1.8e308); rescale the units"
        )
    return np.hypot(ccw[..., 0] - centres[:, :1], ccw[..., 1] - centres[:, 1:]).max(axis=1)


class Prism:
    """One semi-infinite convex right prism.

    Parameters
    ----------
    xy : array_like, shape (n, 2)
        End-face polygon in the prism's local frame (``z = 0``), clockwise or
        counter-clockwise. The local origin need not lie inside it.

    Attributes
    ----------
    xy : numpy.ndarray, shape (n, 2)
        Vertices, counter-clockwise, in the local frame.
    centre : numpy.ndarray, shape (2,)
        Area centroid of the end face (the internal centre the kernels use).
    radius : float
        Largest distance from ``centre`` to a vertex.

    Examples
    --------
    >>> import prismbatch as pb
    >>> pb.Prism.regular(5, 2.0).n_vertices
    5
    """

    def __init__(self, xy, *, name="prism"):
        n = _vertex_count(xy)
        check_memory(n * _BYTES_PER_VERTEX, f"{name} of {n:,} vertices")
        ccw = validate_polygon(xy, name=name)
        centre = _centroids(ccw[None])[0]
        self._set(ccw, centre, float(_radii(ccw[None], centre[None], lambda j: name)[0]))

    @classmethod
    def _checked(cls, ccw, centre, radius):
        """A prism of a polygon that has passed :func:`check_polygons` (PrismSet's bulk build)."""
        prism = cls.__new__(cls)
        prism._set(ccw, centre, radius)
        return prism

    def _set(self, ccw, centre, radius):
        self.xy = ccw
        self.xy.flags.writeable = False
        self.centre = centre
        self.radius = radius

    @classmethod
    def regular(cls, n, radius, *, phase=0.0, centre=(0.0, 0.0)):
        """Regular ``n``-gon with circumradius ``radius``.

        Parameters
        ----------
        n : int
            Number of vertices (>= 3).
        radius : float
            Circumradius (> 0).
        phase : float, optional
            Polar angle of vertex 0 in radians.
        centre : (2,) array_like, optional
            Centre in the local frame.

        Raises
        ------
        ValueError
            ``n`` outside [3, :data:`~prismbatch.config.MAX_VERTICES`], or more
            vertices than the memory available holds (about 240 bytes a vertex
            once a Collider has built its tables).
        """
        if isinstance(n, (bool, np.bool_)) or not isinstance(n, (int, np.integer)):
            raise TypeError(f"Prism.regular: n must be an integer, got {type(n).__name__} {n!r}")
        n = int(n)  # (a small NumPy integer would overflow in the memory estimate below)
        if not 3 <= n <= MAX_VERTICES:
            big = n > MAX_VERTICES  # say why the limit is there
            need = f" (it would need about {format_bytes(n * _BYTES_PER_VERTEX)} of memory)" if big else ""
            raise ValueError(f"Prism.regular: n must be in [3, {MAX_VERTICES:,}], got {n}{need}")
        check_memory(n * _BYTES_PER_VERTEX, f"Prism.regular({n})")
        radius = real_scalar(radius, "Prism.regular: radius", 5e-324, 1.7976931348623157e308)
        phase = real_scalar(phase, "Prism.regular: phase", -1e6, 1e6)
        refuse_masked(centre, "Prism.regular: centre")
        c = np.asarray(centre)
        if c.dtype.kind not in "iuf" or c.shape != (2,) or not np.isfinite(c).all():
            raise ValueError(f"Prism.regular: centre must be 2 finite numbers, got {centre!r}")
        ang = phase + 2.0 * np.pi * np.arange(n) / n
        xy = np.column_stack([radius * np.cos(ang), radius * np.sin(ang)]) + c.astype(float)
        return cls(xy)

    @property
    def n_vertices(self):
        """Number of end-face vertices."""
        return self.xy.shape[0]

    def __repr__(self):
        return f"Prism(n_vertices={self.n_vertices}, radius={self.radius:.6g})"


class PrismSet:
    """Many prisms in structure-of-arrays storage, one per pose pair.

    Parameters
    ----------
    polygons : sequence of array_like or Prism
        End-face polygons (each ``(n_k, 2)``) or :class:`Prism` objects. A
        ValueError, before anything is built, if their vertices together need
        more memory than is available (about 240 bytes a vertex).

    Attributes
    ----------
    offsets : numpy.ndarray of int64, shape (m + 1,)
        Polygon ``k`` owns rows ``offsets[k]:offsets[k + 1]`` of the flat arrays.
    vx, vy : numpy.ndarray, shape (total,)
        Vertex coordinates about each polygon's centre, counter-clockwise.
    edge_angle : numpy.ndarray, shape (total,)
        Pseudo-angle (see ``_planar.pseudo_angle``) of edge ``v_k -> v_{k+1}``,
        unwrapped so that it increases along each polygon.
    edge_table : numpy.ndarray of int64, shape (total,)
        Per polygon, a bucket table over those angles: with ``edge_angle`` it
        finds the extreme vertex in a direction in O(1) for evenly spread
        edges, O(log n) at worst.
    vertex_angle : numpy.ndarray, shape (total,)
        Polar angle of each vertex about the centre, unwrapped increasing
        (binary search of the wedge holding a point, the paper's eq. 1).
    inv_edge_len : numpy.ndarray, shape (total,)
        ``1 / |v_{k+1} - v_k|`` for signed distances to edges.
    centre : numpy.ndarray, shape (m, 2)
        Internal centre (area centroid) of each polygon in its local frame.
    radius : numpy.ndarray, shape (m,)
        Bounding radius about the centre (the paper's ``L_0`` / ``L_a``).
    """

    def __init__(self, polygons):
        if isinstance(polygons, np.ndarray) and polygons.ndim == 2:
            raise TypeError("PrismSet takes a sequence of polygons; wrap a single polygon as [xy] or use Prism")
        polygons = [polygons] if isinstance(polygons, Prism) else list(polygons)
        if not polygons:
            raise ValueError("PrismSet needs at least one polygon")
        total = sum(_vertex_count(p) for p in polygons)
        check_memory(total * _BYTES_PER_VERTEX, f"PrismSet of {len(polygons):,} polygons, {total:,} vertices")
        groups, self._prisms = _build_groups(polygons)
        m = len(polygons)
        counts = np.empty(m, dtype=np.int64)
        self._row = np.empty(m, dtype=np.int64)  # polygon k is row _row[k] of its vertex count's group
        self.centre, self.radius = np.empty((m, 2)), np.empty(m)
        for n, (ks, ccw, centres, radii) in groups.items():
            counts[ks], self._row[ks] = n, np.arange(len(ks))
            self.centre[ks], self.radius[ks] = centres, radii
        self._groups = groups
        self.offsets = np.concatenate(([0], np.cumsum(counts))).astype(np.int64)
        # The kernel tables of the polygons of each vertex count at once, then put in set order.
        n_total = int(self.offsets[-1])
        v = np.empty((n_total, 2))
        self.edge_angle, self.vertex_angle, self.inv_edge_len = np.empty(n_total), np.empty(n_total), np.empty(n_total)
        self.edge_table = np.empty(n_total, dtype=np.int64)
        for n, (ks, ccw, centres, _) in groups.items():
            rows = (self.offsets[ks][:, None] + np.arange(n)).ravel()
            parts = _kernel_data(ccw, centres)
            v[rows] = parts[0].reshape(-1, 2)
            for dest, part in zip((self.edge_angle, self.edge_table, self.vertex_angle, self.inv_edge_len), parts[1:]):
                dest[rows] = part.ravel()
        self.vx = np.ascontiguousarray(v[:, 0])
        self.vy = np.ascontiguousarray(v[:, 1])
        for arr in (
            self.offsets,
            self.vx,
            self.vy,
            self.edge_angle,
            self.edge_table,
            self.vertex_angle,
            self.inv_edge_len,
            self.radius,
            self.centre,
        ):
            arr.flags.writeable = False
        self._kernel_arrays = {}

    def __len__(self):
        return len(self._row)

    def __getitem__(self, k):
        """The :class:`Prism` of polygon ``k`` (a list of them for a slice), made on first access."""
        if isinstance(k, slice):
            return [self[j] for j in range(len(self))[k]]
        j = range(len(self))[k]  # (the int and IndexError rules of a sequence)
        prism = self._prisms.get(j)
        if prism is None:
            ks, ccw, centres, radii = self._groups[int(self.offsets[j + 1] - self.offsets[j])]
            row = self._row[j]
            prism = self._prisms[j] = Prism._checked(ccw[row], centres[row], float(radii[row]))
        return prism

    @property
    def prisms(self):
        """Every polygon's :class:`Prism`, in set order (made on first access: a set of many polygons is
        built without them)."""
        return self[:]

    def __repr__(self):
        n = np.diff(self.offsets)
        return f"PrismSet({len(self)} prisms, {int(n.min())}..{int(n.max())} vertices)"

    def kernel_arrays(self, dtype=np.float64):
        """The arrays the kernels read, cast once to ``dtype``, as a :class:`PrismArrays` (kept per dtype).

        All floats of the set live in one array and all integers in another
        (:func:`prismbatch._kernels.batch.pack`); the nine fields are views into them.
        """
        dt = np.dtype(dtype)
        cached = self._kernel_arrays.get(dt)
        if cached is not None:
            return cached
        # Left writeable: Numba's dispatcher types read-only arrays on a slow path (~1 µs each per call).
        floats, ints = pack(
            self.vx,
            self.vy,
            self.edge_angle,
            self.edge_table,
            self.vertex_angle,
            self.inv_edge_len,
            self.offsets,
            self.radius,
            self.centre,
            dt,
        )
        out = PrismArrays(*unpack.py_func(floats, ints), floats, ints)
        self._kernel_arrays[dt] = out
        return out


def _build_groups(polygons):
    """``(groups, given)``: ``polygons`` (arrays or Prisms) checked in stacks of equal vertex count.

    ``groups`` maps a vertex count n to ``(ks, ccw, centres, radii)``: the polygons' indices, their
    vertices counter-clockwise (m, n, 2, read-only), area centroids (m, 2) and bounding radii (m,);
    ``given`` maps the index of each Prism in ``polygons`` to it. The outcome is that of
    ``Prism(p, name=f"polygon {k}")`` for each in turn (the same checks, :func:`check_polygons`, and
    the first failing polygon's error), at a fraction of the cost: no Prism object is made.
    """
    given = {k: p for k, p in enumerate(polygons) if isinstance(p, Prism)}
    by_count, stacks, errors = {}, [], {}  # errors: k -> the exception, or the failed checks, of polygon k
    for k, p in enumerate(polygons):
        if k not in given:
            try:
                plain = isinstance(p, (np.ndarray, list, tuple)) and not isinstance(p, np.ma.MaskedArray)
                arr = np.asarray(p) if plain else None  # (others, masked arrays too, are read one by one)
            except ValueError:  # ragged: read_polygon words the error
                arr = None
            if (
                arr is not None
                and arr.dtype.kind in "iuf"
                and arr.ndim == 2
                and arr.shape[0] >= 3
                and arr.shape[1] == 2
            ):
                by_count.setdefault(arr.shape[0], ([], []))
                by_count[arr.shape[0]][0].append(k)
                by_count[arr.shape[0]][1].append(arr)
            else:
                stacks.append(_read_one(p, k, errors))
    for n, (ks, arrays) in by_count.items():
        stack = np.array(arrays, dtype=np.float64)
        # closed rings and non-finite vertices are read one by one (dropping the repeat, or naming the vertex)
        odd = ~np.isfinite(stack).all(axis=(1, 2)) | ((stack[:, 0] == stack[:, -1]).all(axis=1) & (n >= 4))
        for j in np.flatnonzero(odd):
            stacks.append(_read_one(stack[j], ks[j], errors))
        keep = np.flatnonzero(~odd)
        stacks.append(([ks[j] for j in keep], stack[keep]))
    parts = {}  # n -> [(ks, ccw, centres, radii)] of each stack
    for ks, stack in stacks:
        if not ks:
            continue
        checks = check_polygons(stack)
        ok = np.flatnonzero(checks.ok)
        if len(ok):
            ccw = checks.ccw[ok]
            centres = _centroids(ccw)
            kept = np.asarray(ks)[ok]
            radii = _radii(ccw, centres, lambda j: f"polygon {kept[j]}")
            parts.setdefault(ccw.shape[1], []).append((kept, ccw, centres, radii))
        for j in np.flatnonzero(~checks.ok):
            errors[ks[j]] = (checks, j, stack[j])
    if errors:
        k = min(errors)
        if isinstance(errors[k], Exception):
            raise errors[k]
        raise_first_failure(*errors[k], f"polygon {k}")
    for k, p in given.items():
        parts.setdefault(p.n_vertices, []).append((np.array([k]), p.xy[None], p.centre[None], np.array([p.radius])))
    groups = {}
    for n, group in parts.items():
        ks, ccw, centres, radii = (np.concatenate(f) for f in zip(*group))
        ccw.flags.writeable = False
        groups[n] = (ks, ccw, centres, radii)
    return groups, given


def _read_one(p, k, errors):
    """``([k], (1, n, 2) array)`` of polygon ``k`` read by :func:`read_polygon`, or ``([], None)``
    with its error kept in ``errors``."""
    try:
        return [k], read_polygon(p, f"polygon {k}")[None]
    except (TypeError, ValueError) as exc:
        errors[k] = exc
        return [], None


class PrismArrays(NamedTuple):
    """A :class:`PrismSet`'s arrays as the kernels take them (one dtype, C-contiguous).

    Vertices of prism k are rows ``offsets[k]:offsets[k + 1]`` of the
    per-vertex arrays, relative to the polygon's centre. The nine fields are
    views into ``floats`` and ``ints``, the two arrays the batch kernels take.
    """

    vx: np.ndarray
    vy: np.ndarray
    edge_angle: np.ndarray
    edge_table: np.ndarray
    vertex_angle: np.ndarray
    inv_edge_len: np.ndarray
    offsets: np.ndarray
    radius: np.ndarray
    centre: np.ndarray
    floats: np.ndarray
    ints: np.ndarray


def as_prism_set(shape, name, dtype=np.float64):
    """Return ``(PrismSet, per_pair)`` for a Prism or PrismSet argument.

    Raises ValueError if a polygon is outside the range the kernels support
    in ``dtype`` (:data:`~prismbatch.config.SUPPORTED_RANGE`).
    """
    if isinstance(shape, PrismSet):
        pset, per_pair = shape, True
    elif isinstance(shape, Prism):
        pset = getattr(shape, "_as_set", None)
        if pset is None:
            pset = PrismSet([shape])
            shape._as_set = pset
        per_pair = False
    else:
        raise TypeError(f"{name} must be a prismbatch.Prism or PrismSet, got {type(shape).__name__}")
    _check_kernel_range(pset, name if not per_pair else f"{name} (PrismSet)", np.dtype(dtype).name)
    return pset, per_pair


def _check_kernel_range(pset, name, dtype_name):
    """Raise ValueError if a polygon's size or offset is outside the range the kernels support."""
    min_radius, max_magnitude = SUPPORTED_RANGE[dtype_name]
    small = pset.radius < min_radius
    large = (pset.radius > max_magnitude) | (np.abs(pset.centre).max(axis=1) > max_magnitude)
    if small.any() or large.any():
        k = int(np.argmax(small | large))
        raise ValueError(
            f"{name}: polygon {k} (radius {float(pset.radius[k])!r}, centre {pset.centre[k].tolist()}) is outside "
            f"the supported range for {dtype_name}: radius in [{min_radius:g}, {max_magnitude:g}] and |centre| <= "
            f"{max_magnitude:g}; rescale the units"
        )
