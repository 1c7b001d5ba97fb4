"""The paper's precision-manipulation experiment (Sec. VI-B), in simulation.

Object a (a square prism of side 3 mm with its diagonals along world x and y,
or a triangular prism of side 2.8 mm) stands with its axis down,
``d_a = [0, 0, -1]``; object b (a glass cylinder of diameter 985 µm, its end
face fitted by a regular ``vertices``-gon, enlarged to 1.5 mm for protection:
the 1.5 mm polygon is b's collision shape) hangs above with its axis nearly up,
``d_b = [-0.0262, -0.0087, 0.9996]``. The state is ``ΔC``, the vector from
a's end-face centre to b's, driven from ``[2551, -2780, -1970]`` µm to
``[0, 0, 1000]`` µm by the paper's PD "attraction" (``kp = 0.3``,
``kd = 0.002``), sampled every 0.02 s for 20 s. Whenever
:meth:`prismbatch.Collider.collide` reports a hit, the detach controller
(:func:`prismbatch.control.detach`, ``ε = 10``) adds its force for that one
step. Postures do not change (the paper's 6-D state reduces to the 3-D
translation).

Units: millimetres and seconds inside; µm (positions) and µm/s or µN (inputs)
in the reports, as the paper reports positions in µm.

The paper gives no plant dynamics. Two documented models (``plant=``):

``"velocity"`` (default)
    The stage follows the commanded velocity: ``x[k+1] = x[k] + dt * u[k]``
    (u in mm/s). This is how a position-controlled micro-stage behaves under a
    velocity command; the PD then gives a first-order approach with time
    constant ``1 / kp`` (3.3 s).
``"force"``
    A mass with viscous friction: ``m dv/dt = u - c v`` with u held over each
    step, integrated exactly (zero-order hold), so it is stable for any m.
    Units: x in mm, m in kg, u in mN, c in mN·s/mm (= N·s/m); defaults
    ``mass = 0.1`` kg, ``damping = 1`` (time constant m/c = 0.1 s = 5
    samples). With ``damping = 1`` the steady speed equals u numerically and
    the model tends to the velocity plant as m -> 0. (A pure mass, c = 0, is
    not offered: with the paper's gains, m x'' + kd x' + kp x = 0 has a damping
    ratio below 1 % for any mass that a 0.02 s sampling can resolve, so the
    goal would never be reached.)

Controller, at every sample k (``e = x - x_d``):

- ``u_pd = -kp e - kd v_meas`` where ``v_meas = (x[k] - x[k-1]) / dt`` is the
  velocity seen by the (camera) measurement, 0 at k = 0;
- optional speed limit ``max_speed`` (mm/s, default off): the PD command's
  norm is clipped to it (force plant: to ``damping * max_speed``, the force
  that sustains that speed). The detach force is never clipped;
- detach: if the pair is in collision at sample k, ``u_d = eps |e| c`` with c
  from the contact class of the contact point (eq. 42), for this step only.
  ``detach`` classifies the contact point against a's features within a
  length tolerance ``detach_tol``; by default (None) it is the distance b
  moved during the last step (at least 1 nm): the previous sample was
  collision-free, so the penetration cannot be deeper than that. A
  simulated contact is a finite overlap, not a touching point, and a tolerance
  of rounding size would classify it as "inside".

Detection cost: the simulation calls ``Collider.collide_pair`` once per
sample (one Python call on one pose pair, as a control loop would; it
returns the contact too) and times each call; compilation (or cache loading)
is done before the loop and reported separately. The same trajectory is then
replayed through one ``collide_pair`` call per sample, one batched call on all the
samples, and python-fcl (:class:`prismbatch.lab.peers.FCLPeer` on finite
stand-ins of length :func:`prismbatch.lab.peers.fcl_standin_length`, maximised
over the trajectory), timing only the query loop.

:func:`run_experiment` returns an :class:`ExperimentResult`;
:func:`write_experiment` writes the trajectory (CSV), metadata (JSON), a
Markdown summary and the figures (PNG and SVG; needs matplotlib).
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .report import new_figure, run_metadata, save_figure, write_csv, write_json
from ..collide import CASES, Collider
from ..control import CONTACT_CLASSES, detach
from ..sampling import rotation_with_axis
from ..shapes import Prism

__all__ = ["run_experiment", "write_experiment", "format_summary", "ExperimentResult", "projected_contour",
           "PRISMS", "PLANTS", "PAPER", "FIG10_TIMES"]

#: Object a: number of end-face vertices and side length (mm).
PRISMS = {"square": (4, 3.0), "triangle": (3, 2.8)}
PLANTS = ("velocity", "force")

#: The instants of the paper's Fig. 10 (projected contours), in s.
FIG10_TIMES = (0.0, 1.0, 2.0, 3.0, 3.5, 4.0, 5.0, 5.9)

#: What the paper reports for the experiment (Sec. VI-B, Figs. 9-11), for comparison only.
PAPER = {
    "case_sequence": [5, 6, 1],
    "fig10_cases": [5, 5, 5, 6, 6, 6, 6, 6],  # "the first three contours correspond to case 5; the rest to case 6"
    "case1_after_s": 6.0,
    "collision_s": 3.5,
    "contact_class": 4,  # "the contact point lies on the side face"
    "collisions": 1,
    "detection_ms": 121.0,
    "swift_ms": 3375.0,
}

_UM = 1e-3  # 1 µm in mm


def _circumradius(n, side):
    return side / (2.0 * math.sin(math.pi / n))


def _runs(values, t):
    """Run-length encoding: [(value, t_start, t_end, n_samples), ...]."""
    out = []
    start = 0
    for i in range(1, len(values) + 1):
        if i == len(values) or values[i] != values[start]:
            out.append((int(values[start]), float(t[start]), float(t[i - 1]), i - start))
            start = i
    return out


def _hull2d(points):
    """Convex hull (counter-clockwise, no repeated end point) of (n, 2) points; monotone chain."""
    p = np.unique(np.round(np.asarray(points, dtype=float), 12), axis=0)
    if len(p) < 3:
        return p

    def half(seq):
        h = []
        for q in seq:
            while len(h) >= 2 and ((h[-1][0] - h[-2][0]) * (q[1] - h[-2][1])
                                   - (h[-1][1] - h[-2][1]) * (q[0] - h[-2][0])) <= 0.0:
                h.pop()
            h.append(q)
        return h

    pts = [tuple(q) for q in p]
    lower = half(pts)
    upper = half(reversed(pts))
    return np.array(lower[:-1] + upper[:-1])


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
    low = pb + xy_b @ Rb[:, :2].T            # b's end face, world
    high = low + length * Rb[:, 2]           # the stand-in's far face
    h_low = (low - pa) @ da                  # height into a's half-space (>= 0: on a's side)
    h_high = (high - pa) @ da
    pts = [low[h_low >= 0.0], high[h_high >= 0.0]]
    for P, h in ((low, h_low), (high, h_high)):  # edges of both faces crossing the plane
        Q, g = np.roll(P, -1, axis=0), np.roll(h, -1)
        m = (h < 0.0) != (g < 0.0)
        f = h[m] / (h[m] - g[m])
        pts.append(P[m] + f[:, None] * (Q[m] - P[m]))
    m = (h_low < 0.0) != (h_high < 0.0)      # lateral edges
    f = h_low[m] / (h_low[m] - h_high[m])
    pts.append(low[m] + f[:, None] * (high[m] - low[m]))
    allp = np.concatenate(pts)
    if len(allp) == 0:
        return np.zeros((0, 2))
    rel = allp - pa
    return _hull2d(np.column_stack([rel @ e1, rel @ e2]))


@dataclass
class ExperimentResult:
    """Everything one run produced. Arrays have one row per sample (``n_steps + 1``).

    Positions are in mm, inputs in mm/s (velocity plant) or mN (force plant);
    :func:`format_summary` and :func:`write_experiment` convert to µm, µm/s, µN.
    """

    params: dict
    t: np.ndarray             # (N,) s
    dc: np.ndarray            # (N, 3) ΔC = b's end-face centre - a's, mm
    case: np.ndarray          # (N,) int8, pb.CASES
    hit: np.ndarray           # (N,) bool
    contact_class: np.ndarray  # (N,) int8, CONTACT_CLASSES (0: no hit)
    contact: np.ndarray       # (N, 3) contact point, world mm (NaN: no hit)
    direction: np.ndarray     # (N, 3) detach direction (NaN: no hit)
    u_pd: np.ndarray          # (N, 3) attraction (PD) input
    u_d: np.ndarray           # (N, 3) detach input (0 where no hit)
    detect_s: np.ndarray      # (N,) time of the per-sample collide call, s
    geometry: dict            # shapes and poses: xy_a, xy_b, xy_b_real, pos_a, rot_a, rot_b
    summary: dict = field(default_factory=dict)
    timing: dict = field(default_factory=dict)

    @property
    def error(self):
        """(N,) |x - x_d| in mm."""
        return np.linalg.norm(self.dc - np.asarray(self.params["xd_um"]) * _UM, axis=1)


def _validate(prism, vertices, plant, duration, dt, kp, kd, eps, max_speed, mass, damping, detach_tol,
              goal_tol_um, b_diameter_mm, b_real_diameter_mm):
    if prism not in PRISMS:
        raise ValueError(f"prism must be one of {sorted(PRISMS)}, got {prism!r}")
    if plant not in PLANTS:
        raise ValueError(f"plant must be one of {list(PLANTS)}, got {plant!r}")
    if int(vertices) != vertices or vertices < 3:
        raise ValueError(f"vertices must be an integer >= 3, got {vertices}")
    for name, v in (("duration", duration), ("dt", dt), ("mass", mass), ("damping", damping),
                    ("goal_tol_um", goal_tol_um), ("b_diameter_mm", b_diameter_mm),
                    ("b_real_diameter_mm", b_real_diameter_mm)):
        if not (np.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be finite and > 0, got {v}")
    for name, v in (("kp", kp), ("kd", kd), ("eps", eps)):
        if not (np.isfinite(v) and v >= 0):
            raise ValueError(f"{name} must be finite and >= 0, got {v}")
    if max_speed is not None and not (np.isfinite(max_speed) and max_speed > 0):
        raise ValueError(f"max_speed must be None or finite and > 0, got {max_speed}")
    if detach_tol is not None and not (np.isfinite(detach_tol) and detach_tol >= 0):
        raise ValueError(f"detach_tol must be None or finite and >= 0, got {detach_tol}")
    if dt > duration:
        raise ValueError(f"dt ({dt}) must not exceed duration ({duration})")


def run_experiment(prism="square", *, vertices=3600, plant="velocity", duration=20.0, dt=0.02,
                   kp=0.3, kd=0.002, eps=10.0, max_speed=None, mass=0.1, damping=1.0, detach_tol=None,
                   goal_tol_um=50.0, b_diameter_mm=1.5, b_real_diameter_mm=0.985, a_phase_deg=0.0,
                   x0_um=(2551.0, -2780.0, -1970.0), xd_um=(0.0, 0.0, 1000.0),
                   d_b=(-0.0262, -0.0087, 0.9996), timing=True, fcl=True, repeats=3):
    """Simulate the paper's experiment; see the module docstring for the model.

    Parameters
    ----------
    prism : {"square", "triangle"}
        Object a: square prism of side 3 mm or triangular prism of side 2.8 mm.
    vertices : int
        Vertices of b's end face (the paper: 3600).
    plant : {"velocity", "force"}
        Plant model (module docstring).
    duration, dt : float
        Simulated time and sampling period, s.
    kp, kd, eps : float
        PD gains and detach gain ε.
    max_speed : float or None
        Optional limit on the PD command (mm/s); default off.
    mass, damping : float
        Force plant only: kg and mN·s/mm.
    detach_tol : float or None
        Feature tolerance (mm) for the contact classification; None: the
        distance moved in the last step.
    goal_tol_um : float
        The goal counts as reached while |x - x_d| <= this (µm). The default
        50 µm is about 1 % of the 4.8 mm move; note kp = 0.3 /s leaves at best
        exp(-6) = 0.25 % (12 µm) of the initial error after 20 s.
    b_diameter_mm, b_real_diameter_mm : float
        b's protective (collision) diameter and its real diameter (drawn only).
    a_phase_deg : float
        World polar angle of a vertex of a's end face (0: a vertex on +x; for
        the square, diagonals along x and y as in the paper; the paper does
        not give the triangle's orientation).
    x0_um, xd_um : (3,) float
        Initial and desired ΔC, µm.
    d_b : (3,) float
        b's axis (normalised here).
    timing : bool
        Replay the trajectory for timing (one call per sample, batched, python-fcl).
    fcl : bool
        Include python-fcl in the replay (skipped with a note if not installed).
    repeats : int
        Replays are repeated this many times and the fastest is kept.

    Returns
    -------
    ExperimentResult
    """
    _validate(prism, vertices, plant, duration, dt, kp, kd, eps, max_speed, mass, damping, detach_tol,
              goal_tol_um, b_diameter_mm, b_real_diameter_mm)
    vertices = int(vertices)
    n_a, side = PRISMS[prism]
    # rot_a = diag(1, -1, -1) maps local (x, y) to world (x, -y): a local phase of -ψ puts a vertex at world angle ψ
    shape_a = Prism.regular(n_a, _circumradius(n_a, side), phase=-math.radians(a_phase_deg))
    shape_b = Prism.regular(vertices, 0.5 * b_diameter_mm)
    xy_b_real = shape_b.xy * (b_real_diameter_mm / b_diameter_mm)
    pos_a = np.zeros(3)
    rot_a = np.diag([1.0, -1.0, -1.0])
    rot_b = rotation_with_axis(d_b)
    x0 = np.asarray(x0_um, float).reshape(3) * _UM
    xd = np.asarray(xd_um, float).reshape(3) * _UM
    n_steps = int(round(duration / dt))
    N = n_steps + 1
    t = np.arange(N) * dt

    col = Collider(shape_a, shape_b)
    pa1 = pos_a.reshape(1, 3)
    ra1 = np.ascontiguousarray(rot_a.reshape(1, 3, 3))
    rb1 = np.ascontiguousarray(rot_b.reshape(1, 3, 3))

    # compile (or load from cache) everything the loop and the replay use, outside the timings
    compile_s = {}
    t0 = time.perf_counter()
    col.collide_pair(pos_a, rot_a, x0, rot_b)
    compile_s["collide_pair"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    col.collide(pa1, ra1, x0.reshape(1, 3), rb1, parallel=False)
    compile_s["collide_batch"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    detach(shape_a, np.zeros((1, 3)), pa1, ra1, rb1, np.ones((1, 3)), eps=eps)
    compile_s["detach"] = time.perf_counter() - t0

    dc = np.zeros((N, 3))
    case = np.zeros(N, np.int8)
    hit = np.zeros(N, bool)
    cls = np.zeros(N, np.int8)
    contact = np.full((N, 3), np.nan)
    direction = np.full((N, 3), np.nan)
    u_pd = np.zeros((N, 3))
    u_d = np.zeros((N, 3))
    detect_s = np.zeros(N)
    detach_s = 0.0
    tol_used = np.full(N, np.nan)

    x = x0.copy()
    x_prev = x0.copy()
    v_true = np.zeros(3)  # force plant state
    perf = time.perf_counter
    for k in range(N):
        dc[k] = x
        t0 = perf()
        r = col.collide_pair(pos_a, rot_a, x, rot_b)
        detect_s[k] = perf() - t0
        case[k] = r.case
        e = x - xd
        v_meas = (x - x_prev) / dt if k > 0 else np.zeros(3)
        u = -kp * e - kd * v_meas
        if max_speed is not None:
            lim = max_speed * (damping if plant == "force" else 1.0)
            s = float(np.linalg.norm(u))
            if s > lim:
                u = u * (lim / s)
        u_pd[k] = u
        if r.hit:
            hit[k] = True
            tol = detach_tol if detach_tol is not None else max(float(np.linalg.norm(x - x_prev)), 1e-6)
            tol_used[k] = tol
            t0 = perf()
            d = detach(shape_a, r.contact[None, :], pa1, ra1, rb1, e.reshape(1, 3), eps=eps, tol=tol)
            detach_s += perf() - t0
            cls[k] = d.contact_class[0]
            contact[k] = r.contact
            direction[k] = d.direction[0]
            u_d[k] = d.force[0]
        if k == n_steps:
            break
        U = u_pd[k] + u_d[k]
        x_prev = x
        if plant == "velocity":
            x = x + dt * U
        else:
            a = math.exp(-damping * dt / mass)
            v_inf = U / damping
            x = x + v_inf * dt + (v_true - v_inf) * (mass / damping) * (1.0 - a)
            v_true = v_inf + (v_true - v_inf) * a

    params = dict(prism=prism, a_vertices=n_a, a_side_mm=side, a_phase_deg=a_phase_deg, vertices=vertices,
                  b_diameter_mm=b_diameter_mm, b_real_diameter_mm=b_real_diameter_mm, plant=plant,
                  duration_s=duration, dt_s=dt, n_samples=N, kp=kp, kd=kd, eps=eps, max_speed_mm_s=max_speed,
                  mass_kg=mass if plant == "force" else None, damping_mN_s_per_mm=damping if plant == "force" else None,
                  detach_tol_mm=detach_tol if detach_tol is not None else "distance moved in the last step (>= 1 nm)",
                  goal_tol_um=goal_tol_um, x0_um=list(map(float, x0_um)), xd_um=list(map(float, xd_um)),
                  d_a=[0.0, 0.0, -1.0], d_b=list(map(float, rot_b[:, 2])), d_b_given=list(map(float, d_b)),
                  collide_rtol=col.rtol)
    geometry = dict(xy_a=shape_a.xy, xy_b=shape_b.xy, xy_b_real=xy_b_real, pos_a=pos_a, rot_a=rot_a, rot_b=rot_b)
    res = ExperimentResult(params, t, dc, case, hit, cls, contact, direction, u_pd, u_d, detect_s, geometry)
    res.summary = _summarise(res, tol_used)
    res.timing = dict(compile_s=compile_s, loop_ms=1e3 * float(detect_s.sum()), detach_ms=1e3 * detach_s,
                      loop_per_call_us=1e6 * float(detect_s.mean()))
    if timing:
        res.timing.update(_replay_timing(res, col, shape_a, shape_b, fcl=fcl, repeats=max(1, int(repeats))))
        if res.timing.get("fcl_ms"):
            res.timing["ratio_loop_vs_fcl"] = res.timing["loop_ms"] / res.timing["fcl_ms"]
    return res


def _summarise(res, tol_used):
    t, hit, case = res.t, res.hit, res.case
    err = res.error
    goal_tol = res.params["goal_tol_um"] * _UM
    dt = res.params["dt_s"]
    runs = _runs(case, t)
    hit_idx = np.flatnonzero(hit)
    episodes = [(int(r_[1] / dt + 0.5), r_[3]) for r_ in _runs(hit.astype(np.int8), t) if r_[0] == 1]
    events = []
    for k in hit_idx:
        nxt = k + 1 < len(t) and not hit[k + 1]
        sep = float(np.dot(res.dc[k + 1] - res.dc[k], res.direction[k])) if k + 1 < len(t) else float("nan")
        events.append(dict(
            t_s=float(t[k]), step=int(k), case=int(case[k]), contact_class=int(res.contact_class[k]),
            contact_class_name=CONTACT_CLASSES[int(res.contact_class[k])],
            contact_um=(res.contact[k] / _UM).tolist(), direction=res.direction[k].tolist(),
            detach_input=float(np.linalg.norm(res.u_d[k])), pd_input=float(np.linalg.norm(res.u_pd[k])),
            error_um=float(err[k] / _UM), feature_tol_um=float(tol_used[k] / _UM),
            next_step_collision_free=bool(nxt), moved_out_um=sep / _UM))
    ok = err <= goal_tol
    reached_at = None
    if ok[-1]:
        bad = np.flatnonzero(~ok)
        reached_at = float(t[bad[-1] + 1]) if len(bad) else float(t[0])
    first = int(hit_idx[0]) if len(hit_idx) else None
    first_ep_end = episodes[0][0] + episodes[0][1] if episodes else None
    later = [float(t[k]) for k in hit_idx if first_ep_end is not None and k >= first_ep_end]
    fig10 = []
    for tt in FIG10_TIMES:
        k = int(round(tt / dt))
        fig10.append(int(case[k]) if k < len(t) else None)
    case1_from = None
    last_non1 = np.flatnonzero(case != 1)
    if case[-1] == 1:
        case1_from = float(t[last_non1[-1] + 1]) if len(last_non1) else float(t[0])
    return dict(
        case_runs=[dict(case=c, t_start_s=a, t_end_s=b, samples=n) for c, a, b, n in runs],
        case_sequence=[r_[0] for r_ in runs],
        case_counts={int(c): int((case == c).sum()) for c in np.unique(case)},
        fig10_times_s=list(FIG10_TIMES), fig10_cases=fig10,
        case1_for_good_from_s=case1_from,
        collision_samples=int(hit.sum()), collision_episodes=len(episodes),
        first_collision_s=float(t[first]) if first is not None else None,
        first_contact_class=int(res.contact_class[first]) if first is not None else None,
        events=events,
        collisions_after_first_detach_s=later,
        every_detach_followed_by_free_step=bool(all(e["next_step_collision_free"] for e in events)),
        goal_reached=bool(ok[-1]), goal_reached_at_s=reached_at,
        goal_reached_without_further_collision=bool(ok[-1]) and not later,
        final_error_um=float(err[-1] / _UM),
        max_speed_mm_s=float(np.max(np.linalg.norm(np.diff(res.dc, axis=0), axis=1)) / dt) if len(t) > 1 else 0.0,
    )


def _replay_timing(res, col, shape_a, shape_b, *, fcl, repeats):
    """Replay the recorded poses: one collide_pair call per sample, one batched call, python-fcl."""
    g = res.geometry
    pa1 = g["pos_a"].reshape(1, 3)
    ra1 = np.ascontiguousarray(g["rot_a"].reshape(1, 3, 3))
    rb1 = np.ascontiguousarray(g["rot_b"].reshape(1, 3, 3))
    poses = [np.ascontiguousarray(p) for p in res.dc]
    pa, ra, rb = g["pos_a"], g["rot_a"], g["rot_b"]
    perf = time.perf_counter
    out = {}
    best = math.inf
    for _ in range(repeats):
        t0 = perf()
        for p in poses:
            col.collide_pair(pa, ra, p, rb)
        best = min(best, perf() - t0)
    out["pair_ms"] = 1e3 * best
    allp = np.ascontiguousarray(res.dc)
    col.collide(pa1, ra1, allp[:2], rb1, parallel=False)  # the same kernel, warm
    best = math.inf
    for _ in range(repeats):
        t0 = perf()
        rb_ = col.collide(pa1, ra1, allp, rb1, parallel=False)
        best = min(best, perf() - t0)
    out["batch_ms"] = 1e3 * best
    out["batch_agrees_with_loop"] = bool(np.array_equal(rb_.hit, res.hit) and np.array_equal(rb_.case, res.case))
    out["fcl_ms"] = None
    if fcl:
        try:
            from .peers import FCLPeer, fcl_standin_length

            L = max(fcl_standin_length(shape_a.xy, shape_b.xy, g["pos_a"], p) for p in res.dc)
            t0 = perf()
            peer = FCLPeer(shape_a.xy, shape_b.xy, L)
            out["fcl_build_s"] = perf() - t0
            items = peer.prepare(g["pos_a"], g["rot_a"], res.dc, g["rot_b"])
            best = math.inf
            for _ in range(repeats):
                t0 = perf()
                h = peer.run(items)
                best = min(best, perf() - t0)
            out["fcl_ms"] = 1e3 * best
            out["fcl_standin_length_mm"] = float(L)
            out["fcl_hits"] = int(h.sum())
            out["fcl_disagreements"] = int((h != res.hit).sum())
            out["fcl_disagreement_s"] = [float(x) for x in res.t[h != res.hit]]
        except ImportError as exc:
            out["fcl_note"] = str(exc)
    return out


# ---------------------------------------------------------------------------
# reporting
# ---------------------------------------------------------------------------


def _fmt_t(x):
    return "-" if x is None else f"{x:.2f} s"


def format_summary(res):
    """The run's summary as text lines (printed by ``prismbatch experiment``)."""
    from .. import __version__

    p, s, tm = res.params, res.summary, res.timing
    lines = []
    lines.append(f"prismbatch {__version__} experiment (paper Sec. VI-B): a = {p['prism']} prism, side "
                 f"{p['a_side_mm']:g} mm; b = {p['vertices']}-gon of diameter {p['b_diameter_mm']:g} mm "
                 f"(real {1e3 * p['b_real_diameter_mm']:.0f} µm); {p['plant']} plant"
                 + (f", speed limit {p['max_speed_mm_s']:g} mm/s" if p["max_speed_mm_s"] else "")
                 + f"; kp {p['kp']:g}, kd {p['kd']:g}, eps {p['eps']:g}; dt {p['dt_s']:g} s, "
                 f"{p['duration_s']:g} s ({p['n_samples']} samples)")
    runs = " -> ".join(f"{r['case']} [{r['t_start_s']:.2f}-{r['t_end_s']:.2f} s]" for r in s["case_runs"])
    lines.append(f"case sequence: {runs}")
    lines.append(f"   paper: 5, then 6, then 1 after about {PAPER['case1_after_s']:g} s; "
                 f"here case 1 for good from {_fmt_t(s['case1_for_good_from_s'])}")
    inst = "  ".join(f"{tt:g}s:{c}" for tt, c in zip(s["fig10_times_s"], s["fig10_cases"]))
    lines.append(f"case at the Fig. 10 instants: {inst}   (paper: "
                 + " ".join(str(c) for c in PAPER["fig10_cases"]) + ")")
    if s["first_collision_s"] is None:
        lines.append("collision: none detected")
    else:
        lines.append(f"collision: first at {s['first_collision_s']:.2f} s (paper: about {PAPER['collision_s']:g} s); "
                     f"{s['collision_samples']} colliding sample(s) in {s['collision_episodes']} episode(s)")
        unit = "µm/s" if p["plant"] == "velocity" else "µN"
        for e in s["events"]:
            lines.append(f"   t={e['t_s']:.2f} s case {e['case']}, contact class {e['contact_class']} "
                         f"({e['contact_class_name']}), contact ({', '.join(f'{c:.0f}' for c in e['contact_um'])}) µm, "
                         f"detach dir ({', '.join(f'{c:+.3f}' for c in e['direction'])}), "
                         f"|u_d| {1e3 * e['detach_input']:.0f} {unit} (classified within {e['feature_tol_um']:.1f} µm); next sample "
                         + ("collision-free" if e["next_step_collision_free"] else "STILL IN COLLISION")
                         + f", moved {e['moved_out_um']:.0f} µm out")
        lines.append(f"   paper: contact on a side face (class {PAPER['contact_class']}); "
                     f"here the first contact is class {s['first_contact_class']} "
                     f"({CONTACT_CLASSES[s['first_contact_class']]})")
    later = s["collisions_after_first_detach_s"]
    lines.append(f"goal: {'reached' if s['goal_reached'] else 'NOT reached'} (|error| <= {p['goal_tol_um']:g} µm"
                 + (f" from {s['goal_reached_at_s']:.2f} s" if s["goal_reached"] else "")
                 + f"; final error {s['final_error_um']:.1f} µm); collisions after the first detach: "
                 + (f"{len(later)} (at " + ", ".join(f"{x:.2f}" for x in later) + " s)" if later else "none")
                 + " (paper: none)")
    if tm:
        line = (f"detection cost over {p['n_samples']} samples: prismbatch {tm['loop_ms']:.1f} ms in the loop "
                f"({tm['loop_per_call_us']:.1f} µs per Python call with contact points)")
        if "pair_ms" in tm:
            line += f", replay {tm['pair_ms']:.1f} ms, one batched call {tm['batch_ms']:.2f} ms"
        lines.append(line)
        if tm.get("fcl_ms") is not None:
            lines.append(f"   python-fcl on the same poses: {tm['fcl_ms']:.1f} ms (finite stand-ins of "
                         f"{tm['fcl_standin_length_mm']:.1f} mm; {tm['fcl_disagreements']} disagreement(s) with "
                         f"prismbatch's hits) -> prismbatch/FCL = {tm['loop_ms'] / tm['fcl_ms']:.2f}; "
                         f"paper: {PAPER['detection_ms']:g} ms vs SWIFT {PAPER['swift_ms']:g} ms "
                         f"= {PAPER['detection_ms'] / PAPER['swift_ms']:.3f}")
        elif tm.get("fcl_note"):
            lines.append(f"   python-fcl: {tm['fcl_note']}")
        c = tm["compile_s"]
        lines.append(f"   compile or cache load (excluded): collide {c['collide_pair'] + c['collide_batch']:.2f} s, "
                     f"detach {c['detach']:.2f} s; detach controller calls {tm['detach_ms']:.2f} ms")
    return lines


def _csv_rows(res):
    unit = 1e3  # mm -> µm, mm/s -> µm/s, mN -> µN
    header = ["t_s", "dC_x_um", "dC_y_um", "dC_z_um", "error_um", "case", "hit", "contact_class",
              "contact_x_um", "contact_y_um", "contact_z_um", "dir_x", "dir_y", "dir_z",
              "u_pd_x", "u_pd_y", "u_pd_z", "u_d_x", "u_d_y", "u_d_z", "detect_us"]
    err = res.error
    rows = []
    for k in range(len(res.t)):
        rows.append([f"{res.t[k]:.4f}", *(f"{v * unit:.4f}" for v in res.dc[k]), f"{err[k] * unit:.4f}",
                     int(res.case[k]), int(res.hit[k]), int(res.contact_class[k]),
                     *("" if np.isnan(v) else f"{v * unit:.4f}" for v in res.contact[k]),
                     *("" if np.isnan(v) else f"{v:.6f}" for v in res.direction[k]),
                     *(f"{v * unit:.4f}" for v in res.u_pd[k]), *(f"{v * unit:.4f}" for v in res.u_d[k]),
                     f"{res.detect_s[k] * 1e6:.2f}"])
    return header, rows


def _markdown(res, figure_files):
    p, s, tm = res.params, res.summary, res.timing
    unit = "µm/s" if p["plant"] == "velocity" else "µN"
    L = [f"# Experiment (paper Sec. VI-B): {p['prism']} prism, {p['plant']} plant", ""]
    L += ["```", *format_summary(res), "```", ""]
    L += ["| quantity | paper | this run |", "|---|---|---|"]
    L.append(f"| case sequence | 5 → 6 → 1 | {' → '.join(str(c) for c in s['case_sequence'])} |")
    L.append(f"| case at Fig. 10 instants (0,1,2,3,3.5,4,5,5.9 s) | {' '.join(map(str, PAPER['fig10_cases']))} | "
             f"{' '.join(str(c) for c in s['fig10_cases'])} |")
    L.append(f"| case 1 for good from | after about 6 s | {_fmt_t(s['case1_for_good_from_s'])} |")
    L.append(f"| first collision | about 3.5 s | {_fmt_t(s['first_collision_s'])} |")
    fc = s["first_contact_class"]
    L.append(f"| contact class | 4 (side face) | {fc if fc is not None else '-'}"
             + (f" ({CONTACT_CLASSES[fc]})" if fc is not None else "") + " |")
    L.append(f"| colliding samples / episodes | 1 | {s['collision_samples']} / {s['collision_episodes']} |")
    L.append(f"| goal reached without another collision | yes | "
             f"{'yes' if s['goal_reached_without_further_collision'] else 'no'} "
             f"(goal {'reached' if s['goal_reached'] else 'not reached'}, final error {s['final_error_um']:.1f} µm) |")
    if tm.get("fcl_ms") is not None:
        L.append(f"| detection cost of the run | 121 ms (SWIFT 3375 ms) | {tm['loop_ms']:.1f} ms "
                 f"(python-fcl {tm['fcl_ms']:.1f} ms) |")
    L += ["", "## Collisions", "", f"| t (s) | case | class | contact (µm) | detach direction | detach input ({unit}) | "
          "next sample |", "|---|---|---|---|---|---|---|"]
    for e in s["events"]:
        L.append(f"| {e['t_s']:.2f} | {e['case']} | {e['contact_class']} ({e['contact_class_name']}) | "
                 f"{', '.join(f'{c:.0f}' for c in e['contact_um'])} | "
                 f"{', '.join(f'{c:+.4f}' for c in e['direction'])} | {1e3 * e['detach_input']:.0f} | "
                 f"{'free' if e['next_step_collision_free'] else 'collision'} |")
    L += ["", "## Model", "",
          f"- Plant: `{p['plant']}` — " + ("the stage follows the commanded velocity, x[k+1] = x[k] + dt u[k]."
                                          if p["plant"] == "velocity" else
                                          f"m dv/dt = u − c v (m = {p['mass_kg']} kg, c = {p['damping_mN_s_per_mm']} "
                                          "mN·s/mm), exact zero-order-hold update."),
          "- PD attraction u = −kp (x − x_d) − kd v, v the finite-difference velocity of the samples; "
          "detach u_d = ε |x − x_d| c (eq. 42) for the colliding sample only.",
          "- Contact classification tolerance: " + (f"{p['detach_tol_mm']} mm" if not isinstance(p["detach_tol_mm"], str)
                                                      else p["detach_tol_mm"]) + ".",
          "- See `prismbatch/experiment.py` for the full description.", ""]
    if figure_files:
        L += ["## Figures", ""] + [f"- [{Path(f).name}]({Path(f).name})" for f in figure_files if f.endswith(".png")]
    return "\n".join(L) + "\n"


def write_experiment(res, out_dir, *, figures=True):
    """Write the run to ``out_dir``: CSV, JSON, Markdown and (optionally) figures.

    Returns a dict of the written paths: ``csv`` (trajectory), ``contours_csv``
    (the Fig. 10 curves), ``json``, ``markdown`` and
    ``figures`` (list; PNG and SVG of each figure).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    stem = f"experiment_{res.params['prism']}"
    paths = {"csv": str(out / f"{stem}_trajectory.csv"), "contours_csv": str(out / f"{stem}_fig10_contours.csv"),
             "json": str(out / f"{stem}.json"),
             "markdown": str(out / f"{stem}.md"), "figures": []}
    write_csv(paths["csv"], *_csv_rows(res))
    write_csv(paths["contours_csv"], *_contour_csv_rows(res))
    if figures:
        paths["figures"] = plot_experiment(res, out, stem=stem)
    meta = run_metadata(description="prismbatch simulation of the paper's Sec. VI-B experiment",
                        parameters=res.params, summary=res.summary, timing=res.timing, paper=PAPER,
                        cases={int(k): v for k, v in CASES.items()}, contact_classes=CONTACT_CLASSES,
                        files={k: (os.path.basename(v) if isinstance(v, str) else [os.path.basename(x) for x in v])
                               for k, v in paths.items()})
    write_json(paths["json"], meta)
    with open(paths["markdown"], "w") as f:
        f.write(_markdown(res, paths["figures"]))
    return paths


# ---------------------------------------------------------------------------
# figures
# ---------------------------------------------------------------------------

def plot_experiment(res, out_dir, *, stem="experiment"):
    """Draw the three figures (PNG and SVG); returns the file paths."""
    files = []
    files += _plot_contours(res, out_dir, f"{stem}_fig10_contours")
    files += _plot_trajectory(res, out_dir, f"{stem}_fig11a_trajectory")
    files += _plot_states(res, out_dir, f"{stem}_fig11bc_states_forces")
    return files


def _closed(P):
    return np.vstack([P, P[:1]])


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
        panels.append(dict(t=float(tt), k=k, label=label, case=int(res.case[k]), hit=bool(res.hit[k]),
                           end_face=plane(g["xy_b"] @ g["rot_b"][:, :2].T + res.dc[k]),
                           projection=np.asarray(Q).reshape(-1, 2), centre=plane(res.dc[k][None])[0],
                           contact=plane((res.contact[k] - pa)[None])[0] if res.hit[k] else None))
    return panels, poly_a


def _contour_csv_rows(res):
    """Fig. 10's curves as CSV rows (µm), so the figure can be redrawn from files."""
    panels, poly_a = contour_panels(res)
    header = ["panel", "t_s", "label", "case", "hit", "curve", "vertex", "x_um", "y_um"]
    rows = []
    for i, P in enumerate(panels):
        curves = [("a_end_face", poly_a), ("b_end_face_projected", P["end_face"]),
                  ("b_projection", P["projection"]), ("b_centre", P["centre"][None])]
        if P["contact"] is not None:
            curves.append(("contact", P["contact"][None]))
        for name, pts in curves:
            for j, (x, y) in enumerate(pts):
                rows.append([i, f"{P['t']:.4f}", P["label"] or "", P["case"], int(P["hit"]), name, j,
                             f"{1e3 * x:.4f}", f"{1e3 * y:.4f}"])
    return header, rows


def _plot_contours(res, out, name):
    panels, poly_a = contour_panels(res)
    ncol = 3
    nrow = -(-len(panels) // ncol)
    fig = new_figure(figsize=(10.5, 3.35 * nrow + 0.6), layout="constrained")
    axes = fig.subplots(nrow, ncol, squeeze=False)
    allpts = np.vstack([poly_a, *(P["end_face"] for P in panels)])
    lo, hi = allpts.min(axis=0) - 0.3, allpts.max(axis=0) + 0.3
    for i, P in enumerate(panels):
        ax = axes[i // ncol][i % ncol]
        Q, ef, c = P["projection"], P["end_face"], P["centre"]
        ax.fill(*_closed(poly_a).T, color="tab:red", alpha=0.15, lw=0)
        ax.plot(*_closed(poly_a).T, color="tab:red", lw=1.5, label="a's end face")
        ax.plot(*_closed(ef).T, color="0.45", lw=1.0, ls=":", label="b's end face, projected")
        if len(Q) >= 3:
            ax.fill(*_closed(Q).T, color="tab:blue", alpha=0.25, lw=0)
            ax.plot(*_closed(Q).T, color="tab:blue", lw=1.5, label="b ∩ a's half-space, projected")
        ax.plot([0], [0], "+", color="tab:red", ms=8, label="end-face centres")
        ax.plot([c[0]], [c[1]], "+", color="tab:blue", ms=8)
        if P["hit"]:
            ax.plot([P["contact"][0]], [P["contact"][1]], "x", color="black", ms=8, mew=2, label="contact point")
        hit = ", collision" if P["hit"] else ""
        title = (f"t = {P['t']:g} s: case {P['case']}{hit}" if P["label"] is None
                 else f"{P['label']}, t = {P['t']:.2f} s: case {P['case']}{hit}")
        if not len(Q):
            title += " (no projection)"
        ax.set_title(title, fontsize=10, color="tab:red" if P["hit"] else "black")
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
    for j in range(len(panels), nrow * ncol):
        axes[j // ncol][j % ncol].set_visible(False)
    seen = {}
    for ax in fig.axes:
        for hh, ll in zip(*ax.get_legend_handles_labels()):
            seen.setdefault(ll, hh)
    fig.suptitle(f"Projected contours on a's end plane (along d_a, seen from above), {res.params['prism']} prism "
                 "— cf. paper Fig. 10", fontsize=11)
    fig.legend(list(seen.values()), list(seen.keys()), loc="outside lower center", ncol=5, fontsize=9)
    return save_figure(fig, out, name)


def _silhouette(points_world, s_axis, z_axis):
    return _hull2d(np.column_stack([points_world @ s_axis, points_world @ z_axis]))


def _plot_trajectory(res, out, name):
    g = res.geometry
    Ra, pa, Rb = g["rot_a"], g["pos_a"], g["rot_b"]
    da = Ra[:, 2]
    x0, xd = res.dc[0], np.asarray(res.params["xd_um"]) * _UM
    w = np.cross(da, xd - x0)
    w /= np.linalg.norm(w)          # viewing axis, parallel with d_a x (x_d - x_0)
    z_ax = -da                      # up on the page
    s_ax = np.cross(z_ax, w)        # completes a right-handed screen frame (s, z) seen along w
    fig = new_figure(figsize=(7.5, 8.0), layout="constrained")
    ax = fig.add_subplot()
    depth = 3.0
    a_face = pa + g["xy_a"] @ Ra[:, :2].T
    A = _silhouette(np.vstack([a_face, a_face + depth * da]), s_ax, z_ax)
    ax.fill(*_closed(A).T, color="tab:red", alpha=0.15, lw=0)
    ax.plot(*_closed(A).T, color="tab:red", lw=1.5, label="a")
    blen = 2.5
    for k, col, lab in ((0, "black", "b, initial"), (len(res.t) - 1, "tab:blue", "b, final")):
        pb_ = pa + res.dc[k]
        for xy, ls, extra in ((g["xy_b_real"], "-", f" ({1e3 * res.params['b_real_diameter_mm']:.0f} µm)"),
                              (g["xy_b"], ":", f" (protective {res.params['b_diameter_mm']:g} mm)")):
            face = pb_ + xy @ Rb[:, :2].T
            S = _silhouette(np.vstack([face, face + blen * Rb[:, 2]]), s_ax, z_ax)
            ax.plot(*_closed(S).T, color=col, lw=1.3, ls=ls, label=lab + extra)
    tr = pa + res.dc
    ax.plot(tr @ s_ax, tr @ z_ax, color="magenta", lw=1.5, label="b's end-face centre")
    hk = np.flatnonzero(res.hit)
    if len(hk):
        ax.plot(tr[hk] @ s_ax, tr[hk] @ z_ax, "o", color="magenta", mfc="none", ms=7, label="b at a collision")
        cp = res.contact[hk]
        ax.plot(cp @ s_ax, cp @ z_ax, "x", color="tab:red", ms=8, mew=2, label="contact point")
        sc = 0.4
        for q, d in zip(cp, res.direction[hk]):
            ax.annotate("", xy=(q @ s_ax + sc * (d @ s_ax), q @ z_ax + sc * (d @ z_ax)), xytext=(q @ s_ax, q @ z_ax),
                        arrowprops=dict(arrowstyle="->", color="tab:green", lw=1.5))
        ax.plot([], [], color="tab:green", lw=1.5, label="detach direction (in view)")
    ax.plot([xd @ s_ax], [xd @ z_ax], "*", color="tab:blue", ms=12, label="goal")
    ax.set_aspect("equal")
    ax.grid(alpha=0.3)
    ax.set_xlabel("along the horizontal part of x_d − x_0 (mm)")
    ax.set_ylabel("height, −d_a = z (mm)")
    ax.set_title(f"Trajectory of b, {res.params['prism']} prism — cf. paper Fig. 11a\n"
                 f"seen along d_a × (x_d − x_0) ∥ ({w[0]:.3f}, {w[1]:.3f}, {w[2]:.3f})", fontsize=10)
    fig.legend(loc="outside lower center", ncol=3, fontsize=8.5)
    return save_figure(fig, out, name)


def _plot_states(res, out, name):
    p, t = res.params, res.t
    vel = p["plant"] == "velocity"
    unit = "µm/s" if vel else "µN"
    fig = new_figure(figsize=(9.0, 9.0), layout="constrained")
    axs = fig.subplots(4, 1, sharex=True, height_ratios=[3, 2.2, 2.2, 1.2])
    cols = ("tab:blue", "tab:orange", "tab:green")
    hk = np.flatnonzero(res.hit)
    xd = np.asarray(p["xd_um"])
    for i, c in enumerate("xyz"):
        axs[0].plot(t, res.dc[:, i] / _UM, color=cols[i], label=f"ΔC_{c}")
        axs[0].axhline(xd[i], color=cols[i], ls="--", lw=0.8)
    axs[0].plot([], [], color="0.3", ls="--", lw=0.8, label="goal")
    axs[0].set_ylabel("state ΔC (µm)")
    axs[0].set_title(f"(b) state and (c) inputs, {p['prism']} prism, {p['plant']} plant — cf. Fig. 11b, c",
                     fontsize=10)
    for i, c in enumerate("xyz"):
        axs[1].plot(t, 1e3 * res.u_pd[:, i], color=cols[i], label=f"u_pd,{c}")
    axs[1].set_ylabel(f"attraction u_pd ({unit})")
    for i, c in enumerate("xyz"):
        if len(hk):
            m, st, b = axs[2].stem(t[hk], 1e3 * res.u_d[hk, i], linefmt=cols[i], markerfmt="o", basefmt=" ",
                                   label=f"u_d,{c}")
            m.set_color(cols[i])
    axs[2].axhline(0.0, color="0.5", lw=0.8)
    axs[2].set_ylabel(f"detach u_d ({unit})")
    if not len(hk):
        axs[2].text(0.5, 0.5, "no collision: no detach input", transform=axs[2].transAxes, ha="center")
    axs[3].step(t, res.case, where="post", color="0.2", label="case")
    if len(hk):
        axs[3].plot(t[hk], res.case[hk], "o", color="tab:red", ms=5, label="collision")
    axs[3].set_ylabel("case")
    axs[3].set_yticks(sorted(set(int(c) for c in res.case)))
    axs[3].set_xlabel("time (s)")
    for ax in axs:
        for k in hk:
            ax.axvline(t[k], color="tab:red", lw=0.7, ls=":")
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right", fontsize=8, ncol=4 if ax is not axs[0] else 4)
    return save_figure(fig, out, name)
