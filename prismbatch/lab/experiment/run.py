"""Simulating the experiment: PD attraction, detach on collision, one collide call per sample.

See docs/methods/experiment.md for the model (plants, controller, detection cost).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ...checks import check_memory
from ...collide import Collider
from ...control import detach
from ...distance import SEPARATED
from ...sampling import rotation_with_axis
from ...shapes import Prism
from .alarm import collision_alarm
from .model import CONTACT_FROM, PLANTS, PRISMS, UM, ExperimentResult, batch_poses
from .summary import summarise
from .timing import replay_timing

# Peak bytes a sample costs a run (peak RSS over 200,001 samples): ~290 B, its
# arrays (~150 B) and the timing replay's per-sample views; ~900 B with the
# python-fcl replay, which builds a transform per sample.
_SAMPLE_BYTES = 300
_SAMPLE_BYTES_FCL = 900


def _check_samples(duration, dt, replay_fcl):
    """The number of samples of the run, after a ValueError if they cannot fit in memory."""
    samples = duration / dt + 1  # a float: an absurd duration is refused, not overflowed
    check_memory(
        samples * (_SAMPLE_BYTES_FCL if replay_fcl else _SAMPLE_BYTES),
        f"experiment of {samples:,.0f} samples (duration {duration:g} s / dt {dt:g} s)",
    )
    return int(round(duration / dt)) + 1


def _circumradius(n, side):
    return side / (2.0 * math.sin(math.pi / n))


def _validate(
    prism,
    vertices,
    plant,
    duration,
    dt,
    kp,
    kd,
    eps,
    max_speed,
    mass,
    damping,
    detach_tol,
    goal_tol_um,
    b_diameter_mm,
    b_real_diameter_mm,
    contact_from,
    detach_clearance_um,
):
    if contact_from not in CONTACT_FROM:
        raise ValueError(f"contact_from must be one of {list(CONTACT_FROM)}, got {contact_from!r}")
    if prism not in PRISMS:
        raise ValueError(f"prism must be one of {sorted(PRISMS)}, got {prism!r}")
    if plant not in PLANTS:
        raise ValueError(f"plant must be one of {list(PLANTS)}, got {plant!r}")
    if int(vertices) != vertices or vertices < 3:
        raise ValueError(f"vertices must be an integer >= 3, got {vertices}")
    for name, v in (
        ("duration", duration),
        ("dt", dt),
        ("mass", mass),
        ("damping", damping),
        ("goal_tol_um", goal_tol_um),
        ("b_diameter_mm", b_diameter_mm),
        ("b_real_diameter_mm", b_real_diameter_mm),
    ):
        if not (np.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be finite and > 0, got {v}")
    for name, v in (("kp", kp), ("kd", kd), ("eps", eps)):
        if not (np.isfinite(v) and v >= 0):
            raise ValueError(f"{name} must be finite and >= 0, got {v}")
    if max_speed is not None and not (np.isfinite(max_speed) and max_speed > 0):
        raise ValueError(f"max_speed must be None or finite and > 0, got {max_speed}")
    if detach_tol is not None and not (np.isfinite(detach_tol) and detach_tol >= 0):
        raise ValueError(f"detach_tol must be None or finite and >= 0, got {detach_tol}")
    if detach_clearance_um is not None and not (np.isfinite(detach_clearance_um) and detach_clearance_um > 0):
        raise ValueError(f"detach_clearance_um must be None or finite and > 0, got {detach_clearance_um}")
    if dt > duration:
        raise ValueError(f"dt ({dt}) must not exceed duration ({duration})")


def _scene(prism, vertices, a_phase_deg, b_diameter_mm, b_real_diameter_mm, d_b):
    """Shapes and fixed poses of a and b: ``(shape_a, shape_b, geometry)``."""
    n_a, side = PRISMS[prism]
    # rot_a = diag(1, -1, -1) maps local (x, y) to world (x, -y): a local phase of -ψ puts a vertex at world angle ψ
    shape_a = Prism.regular(n_a, _circumradius(n_a, side), phase=-math.radians(a_phase_deg))
    shape_b = Prism.regular(vertices, 0.5 * b_diameter_mm)
    xy_b_real = shape_b.xy * (b_real_diameter_mm / b_diameter_mm)
    pos_a = np.zeros(3)
    rot_a = np.diag([1.0, -1.0, -1.0])
    rot_b = rotation_with_axis(d_b)
    geometry = dict(xy_a=shape_a.xy, xy_b=shape_b.xy, xy_b_real=xy_b_real, pos_a=pos_a, rot_a=rot_a, rot_b=rot_b)
    return shape_a, shape_b, geometry


def _warm_up(col, shape_a, g, x0, eps, contact_from):
    """Compile (or load from cache) everything the loop and the replay use; seconds per part."""
    pa1, ra1, rb1 = batch_poses(g)
    compile_s = {}
    t0 = time.perf_counter()
    col.collide_pair(g["pos_a"], g["rot_a"], x0, g["rot_b"])
    compile_s["collide_pair"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    col.collide(pa1, ra1, x0.reshape(1, 3), rb1, parallel=False)
    compile_s["collide_batch"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    detach(shape_a, np.zeros((1, 3)), pa1, ra1, rb1, np.ones((1, 3)), eps=eps)
    compile_s["detach"] = time.perf_counter() - t0
    if contact_from == "distance":
        t0 = time.perf_counter()
        col.distance(pa1, ra1, x0.reshape(1, 3), rb1, witness=True, parallel=False)
        compile_s["distance"] = time.perf_counter() - t0
    return compile_s


@dataclass(frozen=True)
class _Control:
    """Plant and controller settings of a run (units as in :func:`run_experiment`)."""

    plant: str
    dt: float
    kp: float
    kd: float
    eps: float
    max_speed: float | None
    mass: float
    damping: float
    detach_tol: float | None
    contact_from: str
    detach_clearance: float | None  # mm; None: the fixed gain eps


class _Trace:
    """The per-sample arrays the loop fills (N samples)."""

    def __init__(self, N):
        self.dc = np.zeros((N, 3))
        self.case = np.zeros(N, np.int8)
        self.hit = np.zeros(N, bool)
        self.cls = np.zeros(N, np.int8)
        self.contact = np.full((N, 3), np.nan)
        self.direction = np.full((N, 3), np.nan)
        self.u_pd = np.zeros((N, 3))
        self.u_d = np.zeros((N, 3))
        self.detect_s = np.zeros(N)
        self.tol_used = np.full(N, np.nan)


def _pd_command(ctl, e, x, x_prev, k):
    """The PD attraction at sample k (speed-limited if asked); ``e = x - x_d``."""
    v_meas = (x - x_prev) / ctl.dt if k > 0 else np.zeros(3)
    u = -ctl.kp * e - ctl.kd * v_meas
    if ctl.max_speed is not None:
        lim = ctl.max_speed * (ctl.damping if ctl.plant == "force" else 1.0)
        s = float(np.linalg.norm(u))
        if s > lim:
            u = u * (lim / s)
    return u


def _adapted_push(ctl, v_true, u_pd, direction, depth):
    """The detach input's size that moves b ``depth + clearance`` along ``direction`` in one step.

    The paper's suggested adaptation of the detach parameter to the predicted approach: the
    plant step is affine in its input, so the displacement along the direction under
    ``u_pd + s direction`` is predicted exactly by the plant model (velocity or force), with the
    commanded attraction ``u_pd`` (the approach) included; s is the smallest push that leaves
    the bodies ``clearance`` apart (0 if the attraction alone does).
    """
    zero = np.zeros(3)
    base = float(np.dot(_plant_step(ctl, zero, v_true, u_pd)[0], direction))
    gain = float(
        np.dot(_plant_step(ctl, zero, v_true, direction)[0] - _plant_step(ctl, zero, v_true, zero)[0], direction)
    )
    return max(0.0, (depth + ctl.detach_clearance - base) / gain)


def _detach_step(ctl, col, shape_a, batch, r, e, x, x_prev, v_true, tr, k):
    """Record the hit at sample k and the detach input for it; returns the detach call's seconds."""
    pa1, ra1, rb1 = batch
    tr.hit[k] = True
    tol = ctl.detach_tol if ctl.detach_tol is not None else max(float(np.linalg.norm(x - x_prev)), 1e-6)
    tr.tol_used[k] = tol
    t0 = time.perf_counter()
    contact, point, depth = r.contact[None, :], r.contact, 0.0
    if ctl.contact_from == "distance":
        dist = col.distance(pa1, ra1, x.reshape(1, 3), rb1, witness=True, parallel=False)
        # collide's hit and distance's status agree outside the touching band; inside it a
        # pair may be a hit by one and just apart by the other: then collide's point is used
        if dist.status[0] != SEPARATED:
            contact, point, depth = dist, dist.point_a[0], max(0.0, -float(dist.distance[0]))
    d = detach(shape_a, contact, pa1, ra1, rb1, e.reshape(1, 3), eps=ctl.eps, tol=tol)
    force = d.force[0]
    if ctl.detach_clearance is not None:
        force = _adapted_push(ctl, v_true, tr.u_pd[k], d.direction[0], depth) * d.direction[0]
    elapsed = time.perf_counter() - t0
    tr.cls[k] = d.contact_class[0]
    tr.contact[k] = point
    tr.direction[k] = d.direction[0]
    tr.u_d[k] = force
    return elapsed


def _plant_step(ctl, x, v_true, U):
    """Advance the plant one sample under input U: the new position and (force plant) velocity."""
    if ctl.plant == "velocity":
        return x + ctl.dt * U, v_true
    a = math.exp(-ctl.damping * ctl.dt / ctl.mass)
    v_inf = U / ctl.damping
    x = x + v_inf * ctl.dt + (v_true - v_inf) * (ctl.mass / ctl.damping) * (1.0 - a)
    v_true = v_inf + (v_true - v_inf) * a
    return x, v_true


def _simulate(col, shape_a, g, x0, xd, N, ctl):
    """The control loop over N samples: returns the filled :class:`_Trace` and the detach seconds."""
    pos_a, rot_a, rot_b = g["pos_a"], g["rot_a"], g["rot_b"]
    batch = batch_poses(g)
    tr = _Trace(N)
    detach_s = 0.0
    x = x0.copy()
    x_prev = x0.copy()
    v_true = np.zeros(3)  # force plant state
    perf = time.perf_counter
    for k in range(N):
        tr.dc[k] = x
        t0 = perf()
        r = col.collide_pair(pos_a, rot_a, x, rot_b)
        tr.detect_s[k] = perf() - t0
        tr.case[k] = r.case
        e = x - xd
        tr.u_pd[k] = _pd_command(ctl, e, x, x_prev, k)
        if r.hit:
            detach_s += _detach_step(ctl, col, shape_a, batch, r, e, x, x_prev, v_true, tr, k)
        if k == N - 1:
            break
        U = tr.u_pd[k] + tr.u_d[k]
        x_prev = x
        x, v_true = _plant_step(ctl, x, v_true, U)
    return tr, detach_s


def run_experiment(
    prism="square",
    *,
    vertices=3600,
    plant="velocity",
    duration=20.0,
    dt=0.02,
    kp=0.3,
    kd=0.002,
    eps=10.0,
    max_speed=None,
    mass=0.1,
    damping=1.0,
    detach_tol=None,
    contact_from="distance",
    detach_clearance_um=None,
    goal_tol_um=50.0,
    b_diameter_mm=1.5,
    b_real_diameter_mm=0.985,
    a_phase_deg=0.0,
    x0_um=(2551.0, -2780.0, -1970.0),
    xd_um=(0.0, 0.0, 1000.0),
    d_b=(-0.0262, -0.0087, 0.9996),
    timing=True,
    fcl=True,
    repeats=3,
    alarm=True,
):
    """Simulate the paper's experiment; docs/methods/experiment.md describes the model.

    Parameters
    ----------
    prism : {"square", "triangle"}
        Object a: square prism of side 3 mm or triangular prism of side 2.8 mm.
    vertices : int
        Vertices of b's end face (the paper: 3600).
    plant : {"velocity", "force"}
        Plant model (docs/methods/experiment.md).
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
    contact_from : {"distance", "collide"}
        Where detach takes the contact from: ``"distance"`` (default) the
        penetration's witness point on a and its normal
        (:func:`prismbatch.distance`), so the class says where the bodies
        really touch; ``"collide"`` the contact point of
        :func:`prismbatch.collide`, a point within tol of both bodies that
        lies inside both for deep contacts (class 6 "inside"), as the paper.
    detach_clearance_um : float or None
        None (default): the detach input is ``eps |x - x_d|`` along the detach
        direction, as the paper. A clearance in µm: the detach parameter is
        adapted at every contact to the predicted approach, the smallest push
        that the plant model predicts moves b out of the contact (its
        penetration depth, with ``contact_from="distance"``) and this far
        beyond within the step, the commanded attraction included (the
        paper's future work: "adaptation of the detach parameter").
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
    alarm : bool
        Also compute the collision alarm along the run
        (:func:`prismbatch.lab.experiment.alarm.collision_alarm`, default
        settings): time to impact and the probability of a collision within
        the next second at every sample.

    Returns
    -------
    ExperimentResult

    Raises
    ------
    ValueError
        A bad argument, or more samples (``duration / dt``) than the memory
        available holds, before anything is built.
    """
    _validate(
        prism,
        vertices,
        plant,
        duration,
        dt,
        kp,
        kd,
        eps,
        max_speed,
        mass,
        damping,
        detach_tol,
        goal_tol_um,
        b_diameter_mm,
        b_real_diameter_mm,
        contact_from,
        detach_clearance_um,
    )
    vertices = int(vertices)
    N = _check_samples(duration, dt, timing and fcl)
    n_a, side = PRISMS[prism]
    shape_a, shape_b, geometry = _scene(prism, vertices, a_phase_deg, b_diameter_mm, b_real_diameter_mm, d_b)
    rot_b = geometry["rot_b"]
    x0 = np.asarray(x0_um, float).reshape(3) * UM
    xd = np.asarray(xd_um, float).reshape(3) * UM
    t = np.arange(N) * dt

    col = Collider(shape_a, shape_b)
    compile_s = _warm_up(col, shape_a, geometry, x0, eps, contact_from)
    clearance = None if detach_clearance_um is None else detach_clearance_um * UM
    ctl = _Control(plant, dt, kp, kd, eps, max_speed, mass, damping, detach_tol, contact_from, clearance)
    tr, detach_s = _simulate(col, shape_a, geometry, x0, xd, N, ctl)

    params = dict(
        prism=prism,
        a_vertices=n_a,
        a_side_mm=side,
        a_phase_deg=a_phase_deg,
        vertices=vertices,
        b_diameter_mm=b_diameter_mm,
        b_real_diameter_mm=b_real_diameter_mm,
        plant=plant,
        duration_s=duration,
        dt_s=dt,
        n_samples=N,
        kp=kp,
        kd=kd,
        eps=eps,
        max_speed_mm_s=max_speed,
        mass_kg=mass if plant == "force" else None,
        damping_mN_s_per_mm=damping if plant == "force" else None,
        detach_tol_mm=detach_tol if detach_tol is not None else "distance moved in the last step (>= 1 nm)",
        contact_from=contact_from,
        detach_clearance_um=detach_clearance_um,
        goal_tol_um=goal_tol_um,
        x0_um=list(map(float, x0_um)),
        xd_um=list(map(float, xd_um)),
        d_a=[0.0, 0.0, -1.0],
        d_b=list(map(float, rot_b[:, 2])),
        d_b_given=list(map(float, d_b)),
        collide_rtol=col.rtol,
    )
    res = ExperimentResult(
        params, t, tr.dc, tr.case, tr.hit, tr.cls, tr.contact, tr.direction, tr.u_pd, tr.u_d, tr.detect_s, geometry
    )
    res.summary = summarise(res, tr.tol_used)
    if alarm:
        res.alarm = collision_alarm(res, col)
    res.timing = dict(
        compile_s=compile_s,
        loop_ms=1e3 * float(tr.detect_s.sum()),
        detach_ms=1e3 * detach_s,
        loop_per_call_us=1e6 * float(tr.detect_s.mean()),
    )
    if timing:
        res.timing.update(replay_timing(res, col, shape_a, shape_b, fcl=fcl, repeats=max(1, int(repeats))))
        if res.timing.get("fcl_ms"):
            res.timing["ratio_loop_vs_fcl"] = res.timing["loop_ms"] / res.timing["fcl_ms"]
    return res
