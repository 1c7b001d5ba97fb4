"""prismbatch.motion.time_of_impact against closed forms and a sampling-and-bisection reference."""

import importlib
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import prismbatch as pb
from prismbatch.geometry import pair_scale_tolerance
from prismbatch.motion import CLEAR, CONTACT, UNDECIDED, time_of_impact
from prismbatch.sampling import free_poses

from helpers import count_pairs_sent, from_hex
from reference import rodrigues

DOWN = np.diag([1.0, -1.0, -1.0])  # a's axis points down: a's body is z <= 0 below its end face at z = 0
SQUARE = pb.Prism.regular(4, math.sqrt(2.0), phase=math.pi / 4)  # the square [-1, 1]^2


def rot_z(phi):
    c, s = math.cos(phi), math.sin(phi)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


# --- closed forms ---------------------------------------------------------------------------------


def test_straight_approach():
    b = pb.Prism.regular(6, 0.5)
    h = np.array([0.5, 1.0, 3.0, 10.0])
    speed = np.array([1.0, 7.0, 0.25, 100.0])
    pos_b = np.column_stack([0.3 * np.ones(4), -0.2 * np.ones(4), h])
    vel = np.column_stack([np.zeros(4), np.zeros(4), -speed])
    r = time_of_impact(SQUARE, b, [0, 0, 0], DOWN, pos_b, np.eye(3), vel, horizon=1e3, pose=True, contact=True)
    assert (r.status == CONTACT).all()
    tol = pb.distance(SQUARE, b, [0, 0, 0], DOWN, r.pos_b, r.rot_b).tol
    exact = h / speed
    # the reported time lies between the first time within tol and the touching time
    assert np.all(r.time <= exact + 1e-12 * exact) and np.all(r.time >= exact - 1.01 * tol / speed)
    assert np.allclose(r.contact[:, 2], 0.0, atol=1e-8) and np.allclose(r.contact[:, :2], [0.3, -0.2], atol=0.5)


def test_fast_pass_across_a_corner_is_not_tunnelled():
    # A diamond (radius 0.1) whose lowest vertex dips 0.05 into a's side y = 1 passes at 400 units/s:
    # it overlaps a for 0.0053 s, between the 0.02 s samples, which see nothing.
    b = pb.Prism.regular(4, 0.1)
    x0, y0, speed = -3.5, 1.05, 400.0
    pos_b, rot_b, vel = [x0, y0, -0.5], np.eye(3), [speed, 0.0, 0.0]
    samples = np.arange(0.0, 0.1, 0.02)
    seen = pb.collide(SQUARE, b, [0, 0, 0], DOWN, np.array(pos_b) + np.outer(samples, vel), rot_b).hit
    assert not seen.any()
    r = time_of_impact(SQUARE, b, [0, 0, 0], DOWN, pos_b, rot_b, vel, horizon=0.1, contact=True)
    # the diamond's lower-right edge reaches a's corner (-1, 1) when its centre is at x = -1 - 0.1 + 0.05
    exact = (-1.05 - x0) / speed
    assert r.status[0] == CONTACT
    assert exact - 1e-8 <= r.time[0] <= exact + 1e-12
    assert np.allclose(r.contact[0], [-1.0, 1.0, -0.25], atol=0.26)  # on a's lateral edge, z in [-0.5, 0]


@pytest.mark.parametrize("omega", [2.0, 50.0, 5000.0])
def test_polygon_spinning_about_its_axis_into_a_side_face(omega):
    # A square of radius 1 spinning about its own (vertical) axis, its centre 0.9 off a's face x = 1:
    # the vertex at 135 degrees reaches x = 1 after turning by arccos(-0.9) - 135 degrees.
    b = pb.Prism.regular(4, 1.0, phase=math.pi / 4)
    g = 0.9
    r = time_of_impact(SQUARE, b, [0, 0, 0], DOWN, [1.0 + g, 0.0, -0.5], np.eye(3), [0, 0, 0], [0, 0, omega],
                       horizon=10.0, pose=True, contact=True)  # fmt: skip
    exact = (math.acos(-g) - 0.75 * math.pi) / omega
    assert r.status[0] == CONTACT
    assert exact * (1 - 1e-6) <= r.time[0] <= exact * (1 + 1e-12)
    assert np.allclose(r.rot_b[0], rot_z(omega * r.time[0]), atol=1e-12)
    assert abs(r.contact[0, 0] - 1.0) < 1e-6 and abs(r.contact[0, 1] - math.sin(math.acos(-g))) < 1e-5


def test_far_part_of_a_turning_body_sweeps_into_a():
    # b's end face is 5 away from a, its body points away; turning about z swings the body round:
    # its far part, not its end face, hits a's corner (-1, 1), moving at |w| * 4.1 there.
    b = pb.Prism.regular(4, 0.01)
    rot_b = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])  # b's axis along +y
    w = 3.0
    r = time_of_impact(SQUARE, b, [0, 0, 0], DOWN, [0, 5.0, -0.5], rot_b, [0, 0, 0], [0, 0, w], horizon=5.0)
    phi = math.atan2(-4.0, -1.0) % (2 * math.pi) - math.pi / 2  # the turn until the axis meets (-1, 1)
    assert r.status[0] == CONTACT
    # b's half-width 0.01 at a lever of sqrt(17) makes it touch up to 0.01 / sqrt(17) rad earlier
    assert (phi - 0.011 / math.sqrt(17)) / w <= r.time[0] <= phi / w + 1e-12


def test_already_touching_is_zero_and_moving_away_is_inf():
    b = pb.Prism.regular(6, 0.5)
    pos_b = [[0, 0, -0.1], [0, 0, 0.0], [0, 0, 0.5], [0, 0, 0.5]]
    vel = [[0, 0, 1.0], [0, 0, 1.0], [0, 0, 1.0], [1.0, 0, 0]]
    r = time_of_impact(SQUARE, b, [0, 0, 0], DOWN, pos_b, np.eye(3), vel, [[0, 0, 0.1]] * 4, horizon=2.0, pose=True)
    assert r.status.tolist() == [CONTACT, CONTACT, CLEAR, CLEAR]
    assert r.time[:2].tolist() == [0.0, 0.0] and np.isinf(r.time[2:]).all()
    assert r.iterations[:2].tolist() == [0, 0] and np.isnan(r.pos_b[2:]).all() and np.isnan(r.distance[2:]).all()


# --- the sampling-and-bisection reference ---------------------------------------------------------


def reference_first(col, pos_a, rot_a, pos_b, rot_b, v, w, horizon, level, bound, grid=256, min_width=1e-9):
    """First time in [0, horizon] with distance <= level (None if there is none), to within min_width:
    the lower end of :func:`reference_bracket`."""
    return reference_bracket(col, pos_a, rot_a, pos_b, rot_b, v, w, horizon, level, bound, min_width, grid)[0]


def random_motions(rng, n, b_radius):
    """Facing poses (b above a, its axis within 0.3 rad of up) and motions that turn it by at most 0.5 rad."""
    pos_b = np.column_stack([rng.uniform(-2, 2, n), rng.uniform(-2, 2, n), rng.uniform(0.2, 3.0, n)])
    tilt = [rodrigues(rng.normal(size=3), rng.uniform(0, 0.3)) for _ in range(n)]
    target = np.column_stack([rng.uniform(-1.5, 1.5, n), rng.uniform(-1.5, 1.5, n), rng.uniform(-1.0, 0.0, n)])
    vel = (target - pos_b) * rng.uniform(0.3, 2.0, (n, 1))  # mostly towards a, some passing by
    vel += rng.normal(scale=0.5, size=(n, 3))
    w = rng.normal(size=(n, 3))
    w *= rng.uniform(0, 0.5, (n, 1)) / np.linalg.norm(w, axis=1, keepdims=True)
    return pos_b, np.array(tilt), vel, w


@pytest.mark.parametrize("nb", [6, 36])
def test_random_motions_against_sampling_and_bisection(nb):
    rng = np.random.default_rng(nb)
    b = pb.Prism.regular(nb, 0.7)
    a = pb.Prism.regular(5, 2.0)
    n, horizon = 24, 1.0
    pos_b, rot_b, vel, w = random_motions(rng, n, 0.7)
    col = pb.Collider(a, b)
    r = col.time_of_impact([0, 0, 0], DOWN, pos_b, rot_b, vel, w, horizon=horizon, pose=True)
    assert (r.status != UNDECIDED).all()
    assert 4 <= np.count_nonzero(r.status == CONTACT) <= n - 4  # both kinds are exercised
    for i in range(n):
        # b stays within 0.8 rad of up, so its contact witnesses lie within S / sigma of its end face
        # (sigma = 1: the axes face each other), S at most s_max over the motion
        s_max = 2.0 + 0.7 + np.linalg.norm(pos_b[i]) + np.linalg.norm(vel[i]) * horizon + 0.1
        bound = 1.5 * (np.linalg.norm(vel[i]) + np.linalg.norm(w[i]) * (0.7 + s_max))
        args = (col, np.zeros(3), DOWN, pos_b[i], rot_b[i], vel[i], w[i], horizon)
        touch = reference_first(*args, 0.0, bound)
        tol = col.distance(np.zeros(3), DOWN, pos_b[i], rot_b[i]).tol[0]
        near = reference_first(*args, tol, bound)
        if r.status[i] == CLEAR:
            assert touch is None, (i, touch)
        else:
            assert near is not None and near - 1e-8 <= r.time[i], (i, near, r.time[i])
            assert touch is None or r.time[i] <= touch + 1e-8, (i, touch, r.time[i])
    hit = r.status == CONTACT
    again = col.distance(np.zeros(3), DOWN, r.pos_b[hit], r.rot_b[hit])
    assert (again.distance <= again.tol).all()  # a reported contact is one


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), n_a=st.integers(3, 40), n_b=st.integers(3, 40))
def test_free_poses_no_sampled_contact_before_the_time_and_touching_at_it(seed, n_a, n_b):
    # Any poses (the axes need not face each other) and fast turns: the samples before the reported
    # time never touch, and b's pose at it does (per distance).
    rng = np.random.default_rng(seed)
    a, b = pb.Prism.regular(n_a, rng.uniform(0.5, 2)), pb.Prism.regular(n_b, rng.uniform(0.5, 2))
    pos_b = rng.uniform(-4, 4, 3)
    rot_b = rodrigues(rng.normal(size=3), rng.uniform(0, math.pi))
    rot_a = rodrigues(rng.normal(size=3), rng.uniform(0, math.pi))
    vel, w = rng.normal(size=3) * 4, rng.normal(size=3) * 2
    col = pb.Collider(a, b)
    r = col.time_of_impact([0, 0, 0], rot_a, pos_b, rot_b, vel, w, horizon=2.0, pose=True)
    end = 2.0 if r.status[0] == CLEAR else r.time[0]
    ts = np.linspace(0.0, end, 101)[: 101 if r.status[0] == CLEAR else 100]
    P = pos_b + np.outer(ts, vel)
    R = np.array([rodrigues(w, t) @ rot_b for t in ts])
    before = col.distance([0, 0, 0], rot_a, P, R, parallel=False)
    assert (before.distance > 0).all() or r.time[0] == 0.0
    if r.status[0] == CONTACT:
        at = col.distance([0, 0, 0], rot_a, r.pos_b, r.rot_b)
        assert at.distance[0] <= at.tol[0]


def test_pose_at_time_and_serial_equals_parallel():
    rng = np.random.default_rng(7)
    b = pb.Prism.regular(36, 0.7)
    n = 300
    pos_b, rot_b, vel, w = random_motions(rng, n, 0.7)
    col = pb.Collider(pb.Prism.regular(5, 2.0), b)
    kw = dict(horizon=2.0, pose=True, contact=True)
    rs = col.time_of_impact([0, 0, 0], DOWN, pos_b, rot_b, vel, w, parallel=False, **kw)
    rp = col.time_of_impact([0, 0, 0], DOWN, pos_b, rot_b, vel, w, parallel=True, **kw)
    for x, y in ((rs.time, rp.time), (rs.status, rp.status), (rs.pos_b, rp.pos_b), (rs.contact, rp.contact)):
        np.testing.assert_array_equal(x, y)
    hit = rs.status == CONTACT
    t = rs.time[hit]
    np.testing.assert_allclose(rs.pos_b[hit], pos_b[hit] + vel[hit] * t[:, None], rtol=0, atol=1e-12)
    R = np.array([rodrigues(wi, ti) @ Ri for wi, ti, Ri in zip(w[hit], t, rot_b[hit])])
    np.testing.assert_allclose(rs.rot_b[hit], R, rtol=0, atol=1e-12)
    # the contact is the midpoint of the witnesses at that time (pairs that start inside: half the depth)
    again = col.distance([0, 0, 0], DOWN, rs.pos_b[hit], rs.rot_b[hit], witness=True)
    assert np.all(np.linalg.norm(rs.contact[hit] - again.point_a, axis=1) <= 0.5 * abs(again.distance) + again.tol)
    assert np.isnan(rs.contact[~hit]).all()
    assert len(rs[hit]) == hit.sum() and set(rs.columns()) >= {"time", "status", "pos_b_x", "rot_b_22", "contact_z"}


def test_float32_poses_touch_at_the_time_to_their_tolerance():
    """dtype=float32, as collide and distance take it. The moving pose is formed in float64 while a's
    stays in float32: that mix once failed to compile (a TypingError, not a result)."""
    rng = np.random.default_rng(8)
    a, b = pb.Prism.regular(5, 2.0), pb.Prism.regular(36, 0.7)
    pos_b, rot_b, vel, w = random_motions(rng, 200, 0.7)
    kw = dict(horizon=2.0, pose=True)
    r64 = time_of_impact(a, b, [0, 0, 0], DOWN, pos_b, rot_b, vel, w, **kw)
    r32 = time_of_impact(a, b, [0, 0, 0], DOWN, pos_b, rot_b, vel, w, dtype=np.float32, **kw)
    moved = (r32.status == CONTACT) & (r32.time > 0)
    assert moved.sum() >= 20 and (r32.status == r64.status).mean() >= 0.95
    again = pb.distance(a, b, [0, 0, 0], DOWN, r32.pos_b[moved], r32.rot_b[moved], dtype=np.float32)
    assert np.all(np.abs(again.distance) <= 2 * again.tol)


def test_iteration_cap_is_reported_not_a_contact():
    # Turning towards a's own direction needs ever smaller steps: with a cap of 3 the pair is undecided.
    b = pb.Prism.regular(4, 0.5)
    r = time_of_impact(SQUARE, b, [0, 0, 0], DOWN, [5.0, 0, 0.5], np.eye(3), [0, 0, 0], [0, 2.0, 0],
                       horizon=10.0, max_iter=3, contact=True)  # fmt: skip
    assert r.status[0] == UNDECIDED and r.iterations[0] == 3 and 0 < r.time[0] < 10 and np.isnan(r.contact[0]).all()
    assert not r.hit[0]


def test_bad_input():
    b = pb.Prism.regular(4, 0.5)
    call = lambda **kw: time_of_impact(SQUARE, b, [0, 0, 0], DOWN, [0, 0, 1.0], np.eye(3), **kw)
    with pytest.raises(TypeError, match="velocity"):
        call(horizon=1.0)
    with pytest.raises(ValueError, match="velocity"):
        call(velocity=[1.0, 2.0], horizon=1.0)
    with pytest.raises(ValueError, match=r"velocity\[1\]"):
        call(velocity=[[0, 0, 1.0], [0, np.nan, 0]], horizon=1.0)
    with pytest.raises(TypeError, match="angular_velocity"):
        call(velocity=[0, 0, 1.0], angular_velocity="fast", horizon=1.0)
    with pytest.raises(ValueError, match="angular_velocity"):
        call(velocity=[0, 0, 1.0], angular_velocity=[0, 0, np.inf], horizon=1.0)
    for h in (0.0, -1.0, np.inf, np.nan):
        with pytest.raises(ValueError, match="horizon"):
            call(velocity=[0, 0, 1.0], horizon=h)
    with pytest.raises(TypeError, match="horizon"):
        call(velocity=[0, 0, 1.0], horizon="1")
    with pytest.raises(ValueError, match="batch sizes"):
        call(velocity=np.zeros((3, 3)), angular_velocity=np.zeros((2, 3)), horizon=1.0)
    with pytest.raises(TypeError, match="max_iter"):
        call(velocity=[0, 0, 1.0], horizon=1.0, max_iter=2.5)
    with pytest.raises(ValueError, match="max_iter"):
        call(velocity=[0, 0, 1.0], horizon=1.0, max_iter=0)
    with pytest.raises(TypeError, match="pose"):
        call(velocity=[0, 0, 1.0], horizon=1.0, pose="yes")
    with pytest.raises(ValueError, match="rot_b"):
        time_of_impact(SQUARE, b, [0, 0, 0], DOWN, [0, 0, 1.0], 2 * np.eye(3), [0, 0, 1.0], horizon=1.0)


def test_motion_widens_a_single_pose_and_horizons_per_pair():
    b = pb.Prism.regular(4, 0.5)
    vel = [[0, 0, -1.0], [0, 0, -2.0], [0, 0, 1.0]]
    r = time_of_impact(SQUARE, b, [0, 0, 0], DOWN, [0, 0, 1.0], np.eye(3), vel, horizon=[2.0, 0.4, 2.0])
    assert r.status.tolist() == [CONTACT, CLEAR, CLEAR]
    assert abs(r.time[0] - 1.0) < 1e-8


# --- adversarial motions for the directional bounds -------------------------------------------------


def unit(x):
    x = np.asarray(x, float)
    return x / np.linalg.norm(x)


def rodrigues_many(w, ts):
    """exp(t [w]x) for every t of ``ts``, (m, 3, 3): :func:`rodrigues` at once."""
    th = np.linalg.norm(w) * np.asarray(ts, float)
    if not np.linalg.norm(w):
        return np.broadcast_to(np.eye(3), (len(th), 3, 3))
    k = np.asarray(w, float) / np.linalg.norm(w)
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(th)[:, None, None] * K + (1.0 - np.cos(th))[:, None, None] * (K @ K)


def reference_bracket(col, pos_a, rot_a, pos_b, rot_b, v, w, horizon, level, bound, min_width, grid=256):
    """(lo, hi) around the first time in [0, horizon] with distance <= level.

    d(t) sampled on a grid; an interval [t0, t1] is clear when d(t0) + d(t1) - 2 level > bound (t1 - t0),
    ``bound`` a speed no point of b that can come within ``level`` of a exceeds on these motions;
    otherwise it is split in 16, in order, down to ``min_width``. An interval still not cleared then only
    sets ``lo`` (the first time that may reach ``level``) and the scan goes on: ``hi`` is the first sampled
    time that does reach it. So lo <= t(level) <= hi whenever hi is found; (None, None) proves the level
    never reached.
    """
    lo = [None]

    def d(ts):
        P = pos_b + np.outer(ts, v)
        return col.distance(pos_a, rot_a, P, rodrigues_many(w, ts) @ rot_b, parallel=False).distance

    def first(t0, t1, n):
        ts = np.linspace(t0, t1, n + 1)
        ds = d(ts)
        for j in range(n):
            if ds[j] <= level:
                return ts[j]
            if ds[j] + ds[j + 1] - 2 * level > bound * (ts[j + 1] - ts[j]):
                continue
            if ts[j + 1] - ts[j] < min_width:
                lo[0] = ts[j] if lo[0] is None else lo[0]
                continue
            found = first(ts[j], ts[j + 1], 16)
            if found is not None:
                return found
        return ts[n] if ds[n] <= level else None

    hi = first(0.0, horizon, grid)
    return (hi if lo[0] is None else lo[0]), hi


def adversarial_case(kind, rng):
    """(a, b, pos_b, rot_b, v, w, horizon) of one family, built so that a directional bound missing one of
    its terms passes a contact: spins about axes across the normal, fast spins, levers, sliding, side and
    far contacts."""
    a = pb.Prism.regular(5, 2.0, phase=rng.uniform(0, 1))
    tilt = rodrigues(rng.normal(size=3), rng.uniform(0, 0.3))
    horizon = float(10.0 ** rng.uniform(-2, 0))
    if kind == "spin across n":  # b just above a's face, tipping fast about a horizontal axis
        b = pb.Prism.regular(int(rng.integers(3, 9)), rng.uniform(0.3, 1.5))
        pos_b = np.array([*rng.uniform(-2.5, 2.5, 2), b.radius * 0.3 + rng.uniform(0.01, 0.6)])
        w = unit([*rng.normal(size=2), 0.05 * rng.normal()]) * rng.uniform(0.3, 1.2) / horizon
        v = np.array([*rng.normal(scale=0.3, size=2), -rng.uniform(0, 1)]) * pos_b[2] / horizon
        return a, b, pos_b, tilt, v, w, horizon
    if kind == "fast spin about b's axis":  # a polygon whirling about its own axis near a's rim
        b = pb.Prism.regular(int(rng.integers(3, 6)), rng.uniform(0.3, 1.0), centre=rng.uniform(-0.3, 0.3, 2))
        ang = rng.uniform(0, 2 * math.pi)
        reach = 2.0 + b.radius + np.linalg.norm(b.centre) + rng.uniform(0.02, 0.5)
        pos_b = np.array([reach * math.cos(ang), reach * math.sin(ang), rng.uniform(-0.8, 0.3)])
        horizon = 0.1 * horizon
        w = tilt[:, 2] * rng.uniform(5, 30) / horizon + rng.normal(size=3) * 0.3 / horizon
        v = -pos_b * rng.uniform(0, 0.3) / horizon
        return a, b, pos_b, tilt, v, w, horizon
    if kind == "lever":  # b's face far from p_b: the rotation about p_b swings it along a wide arc
        b = pb.Prism.regular(int(rng.integers(3, 8)), rng.uniform(0.2, 0.6), centre=(rng.uniform(1.5, 3.0), 0.0))
        pos_b = np.array([*rng.uniform(-2, 2, 2), rng.uniform(0.3, 1.2)])
        w = unit(rng.normal(size=3)) * rng.uniform(0.2, 0.9) / horizon
        target = np.array([*rng.uniform(-1.5, 1.5, 2), 0.0])
        v = (target - pos_b) * rng.uniform(0.3, 1.5) / horizon
        return a, b, pos_b, tilt, v, w, horizon
    if kind == "slide":  # b's tilted face just over a's corner, sliding along itself fast while it tips:
        # in b's frame the corner's lever and the turning normal make the gap close at 2 |v| |w| t
        b = pb.Prism.regular(int(rng.integers(5, 9)), 3.0)
        phase = rng.uniform(0, 1)
        a = pb.Prism.regular(5, 2.0, phase=phase)
        k = rng.integers(5)
        e = DOWN @ np.array([math.cos(phase + 0.4 * math.pi * k), math.sin(phase + 0.4 * math.pi * k), 0.0])
        db = math.cos(0.4) * np.array([0.0, 0.0, 1.0]) + math.sin(0.4) * e  # leaning out over the corner 2 e
        pos_b = 2.0 * e + db * rng.uniform(0.005, 0.05)
        f = unit(np.cross(db, rng.normal(size=3)))  # along b's face
        turn = rng.uniform(0.5, 1.0) / horizon
        v = f * rng.uniform(30, 60) * turn
        w = np.cross(db, f) * turn * rng.choice([-1.0, 1.0])
        rot_b = np.column_stack([f, np.cross(db, f), db])
        return a, b, pos_b, rot_b, v, w, horizon
    if kind == "side":  # b beside a's lateral face, its axis pointing away; a's axis across n
        b = pb.Prism.regular(int(rng.integers(3, 9)), rng.uniform(0.2, 0.8))
        out = rodrigues([0.0, 1.0, 0.0], math.pi / 2) @ tilt  # b's axis along +x (away from a)
        ang = rng.uniform(-0.5, 0.5)
        pos_b = np.array([2.0 + b.radius + rng.uniform(0, 0.5), 0.0, rng.uniform(-3.0, -0.5)])
        pos_b[:2] = rot_z(ang)[:2, :2] @ pos_b[:2]
        w = unit(rng.normal(size=3)) * rng.uniform(0.2, 0.8) / horizon
        v = np.array([-rng.uniform(0, 0.8), rng.normal(scale=0.2), rng.normal(scale=0.2)]) / horizon
        v[:2] = rot_z(ang)[:2, :2] @ v[:2]
        return a, b, pos_b, out @ rot_z(rng.uniform(0, 6)), v, w, horizon
    # "nearly parallel": both axes point down, b beside a leaning away (leaning towards, they would meet
    # far down), turning towards a by up to half its lean: the contact is far along a's axis
    b = pb.Prism.regular(int(rng.integers(3, 9)), rng.uniform(0.2, 0.6))
    theta = rng.uniform(0.1, 0.4)
    rot_b = rodrigues([0.0, 1.0, 0.0], -theta) @ DOWN
    pos_b = np.array([2.0 + b.radius + rng.uniform(0.05, 0.8), rng.uniform(-1.0, 1.0), rng.uniform(-3.0, 0.5)])
    w = np.array([0.2 * rng.normal(), rng.uniform(0.1, 0.5), 0.2 * rng.normal()]) * theta / horizon
    v = np.array([-pos_b[0] * rng.uniform(0.2, 1.0), rng.normal(scale=0.2), rng.normal(scale=0.3)]) / horizon
    return a, b, pos_b, rot_b, v, w, horizon


def speed_bound(a, b, rot_a, pos_b, rot_b, v, w, horizon):
    """A speed no witness point of b exceeds over the motion (for the reference): its lever from p_b is at
    most |c_b| + R_b + 4 S / sigma (the distance's cut, ``docs/methods/distance.md``), sigma at its least."""
    da, db = rot_a[:, 2], rot_b[:, 2]
    theta = math.acos(np.clip(da @ db, -1, 1))
    low = theta - np.linalg.norm(np.cross(w, db)) * horizon
    assert low > 0.0, "the reference needs the axes kept apart"
    sigma = 1.0 if low >= math.pi / 2 else math.sin(low)
    cb = np.linalg.norm(b.centre)
    spread = np.linalg.norm(v) + np.linalg.norm(w) * cb
    s_max = 2 * a.radius + b.radius + np.linalg.norm(pos_b) + cb + spread * horizon
    return 1.5 * (np.linalg.norm(v) + np.linalg.norm(w) * (cb + b.radius + 4.0 * s_max / sigma))


@pytest.mark.parametrize(
    "kind",
    [
        "spin across n",
        pytest.param("fast spin about b's axis", marks=pytest.mark.slow),  # (2 s each: sampling and bisection)
        "lever",
        pytest.param("slide", marks=pytest.mark.slow),
        "side",
        "nearly parallel",
    ],
)
def test_adversarial_motions_against_sampling_and_bisection(kind):
    # Each family is built so that the directional bounds are tight: a term left out of them (the turn of u
    # over the step, the drift in b's frame, the polygon's other supports, the far points, the lever's
    # turn) passes a contact in at least one of them. The reference cannot tunnel (see reference_bracket).
    rng = np.random.default_rng(sum(map(ord, kind)))
    n, hits = 10, 0
    for _ in range(n):
        a, b, pos_b, rot_b, v, w, horizon = adversarial_case(kind, rng)
        col = pb.Collider(a, b)
        r = col.time_of_impact([0, 0, 0], DOWN, pos_b, rot_b, v, w, horizon=horizon, pose=True)
        args = (col, np.zeros(3), DOWN, pos_b, rot_b, v, w, horizon)
        bound = speed_bound(a, b, DOWN, pos_b, rot_b, v, w, horizon)
        width = 1e-11 * horizon
        _, touch = reference_bracket(*args, 0.0, bound, width)  # the first sampled touching
        if r.status[0] == CLEAR:
            assert touch is None, (kind, touch)
            continue
        assert touch is None or r.time[0] <= touch, (kind, touch, r.time[0])  # no contact passed
        if r.status[0] == CONTACT:
            hits += 1
            at = col.distance(np.zeros(3), DOWN, r.pos_b, r.rot_b)
            assert at.distance[0] <= at.tol[0]
            near, _ = reference_bracket(*args, at.tol[0], bound, width)  # nothing within tol before it
            assert near is not None and near <= r.time[0], (kind, near, r.time[0])
    assert 3 <= hits < n  # contacts and clear pairs both


# --- extreme magnitudes against closed forms --------------------------------------------------------


@pytest.mark.parametrize("size, far", [(1e-6, 1e3), (1e-6, 1e6), (1.0, 0.0), (1e6, 0.0), (1e6, 1e9)])
def test_extreme_magnitudes_against_closed_forms(size, far):
    # Tiny objects far from the world origin, huge ones, and motions from 1e-9 to 1e9 time units (speeds
    # and turn rates over 18 decades, horizons to match): a straight approach onto a face and a square
    # spinning into a side face, each reported between the first time within tol and the touching time.
    s, P0 = size, far * np.array([0.8, -0.6, 0.3])
    a = pb.Prism.regular(4, math.sqrt(2.0) * s, phase=math.pi / 4)  # the square [-s, s]^2
    scales = np.array([1e-9, 1e-3, 1.0, 1e3, 1e9])  # the time each motion takes to touch
    m = len(scales)
    # straight down onto a's end face from h s above it: touching at h s / speed
    b = pb.Prism.regular(6, 0.5 * s)
    h = 0.7
    speed = h * s / scales
    pos_b = P0 + s * np.array([0.3, -0.2, h])
    vel = np.column_stack([np.zeros(m), np.zeros(m), -speed])
    col = pb.Collider(a, b)
    assert (col.time_of_impact(P0, DOWN, pos_b, np.eye(3), vel, horizon=0.5 * scales).status == CLEAR).all()
    r = col.time_of_impact(P0, DOWN, pos_b, np.eye(3), vel, horizon=2.0 * scales)
    assert (r.status == CONTACT).all(), r.status
    tol = col.distance(P0, DOWN, pos_b, np.eye(3)).tol[0]  # (the same at the touching pose: b moves by h s)
    exact = h * s / speed
    assert np.all(r.time >= exact - 1.01 * tol / speed) and np.all(r.time <= exact + 0.01 * tol / speed), r.time / exact
    # a square of radius s spinning about its own axis at 0.335 rad per time scale, its centre g s outside
    # a's side face x = s: the gap is s (g - cos(pi/4 - phi)) after a turn phi, touching at
    # phi* = pi/4 - arccos(g)
    g = 0.9
    b = pb.Prism.regular(4, s, phase=math.pi / 4)
    col = pb.Collider(a, b)
    omega = (math.pi / 4 - math.acos(g)) / scales
    pos_b = P0 + s * np.array([1.0 + g, 0.0, -0.5])
    w = np.column_stack([np.zeros(m), np.zeros(m), omega])
    r = col.time_of_impact(P0, DOWN, pos_b, np.eye(3), np.zeros(3), w, horizon=10.0 * scales, pose=True)
    assert (r.status == CONTACT).all(), r.status
    tol = col.distance(P0, DOWN, r.pos_b, r.rot_b).tol
    assert np.all(tol < 0.01 * s)  # the test means something: the window is a small part of the turn
    first = (math.pi / 4 - np.arccos(g - tol / s)) / omega  # the gap is tol here
    assert np.all(r.time >= first * (1 - 1e-9)) and np.all(r.time <= scales * (1 + 1e-9)), (
        r.time / scales,
        first / scales,
    )
    np.testing.assert_allclose(r.pos_b, np.broadcast_to(pos_b, (m, 3)), rtol=0, atol=0)
    for i in range(m):
        np.testing.assert_allclose(r.rot_b[i], rot_z(omega[i] * r.time[i]), rtol=0, atol=1e-12)


def hexes(*xs):
    return from_hex(xs)


def test_thin_body_tumbling_fast_needs_the_turn_of_its_face():
    # Found by an adversarial review's mutation of the kernel: a 1000:1 triangle and pentagon, b tumbling
    # at 23.7 rad/s (5.6 rad over the horizon).
    # Without the face term R_b |w| delta of the world-frame bound the step lands 4.5e-4 s past the contact
    # (b 1.4e-3 deep in a, 1.4e6 tol); with it the reported time lies before the first sampled touching.
    a_xy = hexes(
        "-0x1.9d440f5989e64p-2",
        "-0x1.1e29cff65b6c0p-3",
        "-0x1.4b7704e211b7ep-2",
        "-0x1.cc572db22bf23p-4",
        "-0x1.5eecb254480c2p+0",
        "-0x1.e0a06807b087bp-2",
    )
    b_xy = hexes(
        "0x1.0433afe1d2e26p-1",
        "-0x1.5432730afd524p+0",
        "-0x1.976aea12f6d45p-2",
        "0x1.0b049bad3a8a4p+0",
        "-0x1.02a1ff5beefdfp-1",
        "0x1.5253fd7710114p+0",
        "-0x1.c3bd37ad5d743p-2",
        "0x1.26d98eb699dd3p+0",
        "-0x1.2e1d0d69dacd6p-8",
        "0x1.084d91f6018c6p-7",
    )
    pos_a = hexes(
        "0x1.22f26f69f5973p-1",
        "-0x1.88c5d300867fbp-2",
        "-0x1.1bf6f8aa1aed0p-2",
    )
    rot_a = hexes(
        "0x1.b3f77cb221793p-1",
        "-0x1.d00c49ac3ff9cp-4",
        "-0x1.06215c1043da2p-1",
        "-0x1.bb7b0b07d63d6p-3",
        "-0x1.ee2feeb14db45p-1",
        "-0x1.2c27790f8cb22p-3",
        "-0x1.e904c492a18d7p-2",
        "0x1.e2a17b5104f02p-3",
        "-0x1.b15c2afc61a6fp-1",
    )
    pos_b = hexes(
        "-0x1.9e04aa8006344p-1",
        "0x1.0d736196d01b4p-1",
        "0x1.3b635ac639590p-1",
    )
    rot_b = hexes(
        "0x1.64ca7d4000ca0p-4",
        "0x1.fdf41de8718a7p-1",
        "0x1.43a2da410d640p-6",
        "-0x1.7871c3fae2f7dp-1",
        "0x1.a0f38fc1b4af0p-5",
        "0x1.5a0e3fce977d2p-1",
        "0x1.5828624d34eefp-1",
        "-0x1.2ca3a50b120e4p-4",
        "0x1.7935b209c0ce6p-1",
    )
    v = hexes(
        "0x1.f1530a0ca523fp-11",
        "0x1.38f2df61665a3p-5",
        "-0x1.1109d2799f5bep-5",
    )
    w = hexes(
        "0x1.4353cdc58a314p+4",
        "-0x1.c09166e2a72c4p+1",
        "-0x1.698f10fe4e47dp+3",
    )
    horizon = float.fromhex("0x1.ea60de6f7a56ap-3")
    a, b = pb.Prism(a_xy.reshape(-1, 2)), pb.Prism(b_xy.reshape(-1, 2))
    rot_a, rot_b = rot_a.reshape(3, 3), rot_b.reshape(3, 3)
    r = time_of_impact(a, b, pos_a, rot_a, pos_b, rot_b, v, w, horizon=horizon)
    assert r.status[0] == CONTACT
    ts = np.linspace(0.0, r.time[0], 2001)[:-1]
    m = len(ts)
    rots = rodrigues_many(w, ts) @ rot_b
    d = pb.distance(
        a, b, np.broadcast_to(pos_a, (m, 3)), np.broadcast_to(rot_a, (m, 3, 3)), pos_b + np.outer(ts, v), rots
    )
    assert (d.distance > 0.0).all(), ts[np.argmax(d.distance <= 0.0)]


@pytest.mark.parametrize("parallel", [False, True])
def test_pairs_out_of_the_batch_room_are_rerun(monkeypatch, parallel):
    """The batch loop runs the distance's EPA in a fixed room and reruns the pairs that run out of
    it with the largest: with the batch's room cut to 6 vertices, the motions that start in
    contact take the rerun, and every output is the same to the bit; except that where the axes
    point the same way the depth comes from the separating-axis theorem where EPA stops (both
    exact): the initial depth and the contact then agree within the tolerance."""
    motion_mod = importlib.import_module("prismbatch.motion")
    rng = np.random.default_rng(47)
    col = pb.Collider(pb.Prism.regular(36, 2.0), pb.Prism.regular(37, 2.5))
    pa, ra, pbb, rb = free_poses(300, rng, radius=2.5)
    pbb = pa + 0.3 * (pbb - pa)  # many start in contact
    v, w = rng.normal(size=(300, 3)), rng.normal(size=(300, 3))
    kw = dict(horizon=1.0, pose=True, contact=True, parallel=parallel)
    want = col.time_of_impact(pa, ra, pbb, rb, v, w, **kw)
    monkeypatch.setattr(motion_mod, "EPA_ROOM", (6,))
    rerun = count_pairs_sent(monkeypatch, motion_mod, "toi_rerun_parallel" if parallel else "toi_rerun_serial", 10)
    got = col.time_of_impact(pa, ra, pbb, rb, v, w, **kw)
    assert rerun and rerun[0] > 50 and (want.time == 0).sum() > 50
    same_way = np.einsum("ij,ij->i", ra[:, :, 2], rb[:, :, 2]) > 0
    tol = pair_scale_tolerance(col.shape_a, col.shape_b, pa, ra, pbb, rb)[1]
    for name, value in want.columns().items():
        np.testing.assert_array_equal(got.columns()[name][~same_way], value[~same_way])
        if name.startswith(("distance", "contact")):  # NaN where there is none, in both
            g = got.columns()[name]
            assert ((np.abs(g - value) <= tol) | (np.isnan(g) & np.isnan(value)))[same_way].all()
        else:
            np.testing.assert_array_equal(got.columns()[name], value)
