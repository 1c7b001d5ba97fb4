"""The paper's Fig. 10 geometry: b's part on a's side of a's end plane, projected onto it.

:func:`projected_contour` computes one contour; :func:`contour_panels` the
panels of a run at the Fig. 10 instants (used by the CSV and the figure).
See docs/methods/experiment.md.
"""

from __future__ import annotations

import numpy as np

from ...geometry import convex_hull
from .model import FIG10_TIMES


def projected_contour(xy_b, pos_b, rot_b, pos_a, rot_a, *, length=None):
    """Contour of b's projection on a's end plane (the paper's Fig. 10).

    The part of b on a's side of a's end plane, projected along d_a onto that
    plane, in plane coordinates ``(e1, e2) = (R_a[:, 0], R_a[:, 0] x d_a)``
    about a's position (for ``d_a = -z`` and ``R_a[:, 0] = x`` these are world
    x and y, seen from above). Exact for facing axes; when b's body runs into
    a's half-space without end it is cut at ``length`` along d_b (default:
    4 (|p_b - p_a| + 2 radius of b's polygon), like the python-fcl stand-in).
    Returns the hull as (k, 2), empty (0, 2) when nothing of b is on a's side
    (case 1).
    """
    xy_b = np.asarray(xy_b, float)
    pa, pb = np.asarray(pos_a, float).reshape(3), np.asarray(pos_b, float).reshape(3)
    Ra, Rb = np.asarray(rot_a, float).reshape(3, 3), np.asarray(rot_b, float).reshape(3, 3)
    if length is None:
        length = 4.0 * (np.linalg.norm(pb - pa) + 2.0 * float(np.max(np.hypot(*xy_b.T))))
    da = Ra[:, 2]
    e1 = Ra[:, 0]
    e2 = np.cross(e1, da)
    low = pb + xy_b @ Rb[:, :2].T  # b's end face, world
    high = low + length * Rb[:, 2]  # the stand-in's far face
    h_low = (low - pa) @ da  # height into a's half-space (>= 0: on a's side)
    h_high = (high - pa) @ da
    pts = [low[h_low >= 0.0], high[h_high >= 0.0]]
    for P, h in ((low, h_low), (high, h_high)):  # edges of both faces crossing the plane
        Q, g = np.roll(P, -1, axis=0), np.roll(h, -1)
        m = (h < 0.0) != (g < 0.0)
        f = h[m] / (h[m] - g[m])
        pts.append(P[m] + f[:, None] * (Q[m] - P[m]))
    m = (h_low < 0.0) != (h_high < 0.0)  # lateral edges
    f = h_low[m] / (h_low[m] - h_high[m])
    pts.append(low[m] + f[:, None] * (high[m] - low[m]))
    allp = np.concatenate(pts)
    if len(allp) == 0:
        return np.zeros((0, 2))
    rel = allp - pa
    return convex_hull(np.column_stack([rel @ e1, rel @ e2]))


def contour_panels(res):
    """The Fig. 10 panels as data, in a's end plane (world x, y for the paper's a), mm.

    Returns ``(panels, poly_a)``: ``poly_a`` is a's end face (n, 2); each panel
    is a dict with ``t``, ``k`` (sample), ``label`` (None or "first contact"),
    ``case``, ``hit``, ``end_face`` (b's end face projected), ``projection``
    (b ∩ a's half-space projected; empty when there is none), ``centre``
    (b's end-face centre) and ``contact`` (None or a point).
    """
    g, s = res.geometry, res.summary
    dt = res.params["dt_s"]
    times = [tt for tt in FIG10_TIMES if int(round(tt / dt)) < len(res.t)]
    marks = [(tt, int(round(tt / dt)), None) for tt in times]
    if s["first_collision_s"] is not None:
        k = int(round(s["first_collision_s"] / dt))
        marks.append((res.t[k], k, "first contact"))
    Ra, pa = g["rot_a"], g["pos_a"]
    # the plane basis of projected_contour: e1 = R_a[:, 0], e2 = e1 x d_a; for the paper's a these are world x, y
    e1, e2 = Ra[:, 0], np.cross(Ra[:, 0], Ra[:, 2])
    plane = lambda P: np.column_stack([P @ e1, P @ e2])  # noqa: E731
    poly_a = plane(g["xy_a"] @ Ra[:, :2].T)
    panels = []
    for tt, k, label in marks:
        Q = projected_contour(g["xy_b"], res.dc[k] + pa, g["rot_b"], pa, Ra)
        panels.append(
            dict(
                t=float(tt),
                k=k,
                label=label,
                case=int(res.case[k]),
                hit=bool(res.hit[k]),
                end_face=plane(g["xy_b"] @ g["rot_b"][:, :2].T + res.dc[k]),
                projection=np.asarray(Q).reshape(-1, 2),
                centre=plane(res.dc[k][None])[0],
                contact=plane((res.contact[k] - pa)[None])[0] if res.hit[k] else None,
            )
        )
    return panels, poly_a
