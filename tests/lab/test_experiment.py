"""The paper's experiment (Sec. VI-B) in simulation, at reduced resolution (b: 360-gon).

What the simulation robustly gives with the default velocity plant (checked here):
the case sequence is 5 -> 6 -> 1; the first contact comes in case 6 at a's rim
(the edge of its end face next to the side face b approaches: b's axis leans
towards a, so the cylinder reaches the side face first at its top), the detach
pushes b out of a and the next sample is collision-free; the square needs
three such detaches (each return path is straight at the goal and grazes the
same edge), the triangle one; then case 1 for good, and the goal is reached
without further collision.
"""

import json

import numpy as np
import pytest

from prismbatch import Prism, distance
from prismbatch.cli import main
from prismbatch.control import CONTACT_CLASSES
from prismbatch.lab.experiment import FIG10_TIMES, format_summary, projected_contour, run_experiment, write_experiment

pytestmark = [pytest.mark.slow, pytest.mark.needs_fcl]

VERTS = 360


@pytest.fixture(scope="module")
def square():
    return run_experiment("square", vertices=VERTS, timing=True, repeats=1)


@pytest.fixture(scope="module")
def triangle():
    return run_experiment("triangle", vertices=VERTS, timing=False)


def _outward_normal_nearest_edge(xy_local, rot_a, point):
    """Outward unit normal (world) of the side face of a nearest to a world point (a at the origin)."""
    P = xy_local @ rot_a[:, :2].T  # world vertices (z = 0)
    c = P.mean(axis=0)
    best, nbest = np.inf, None
    for i in range(len(P)):
        p0, p1 = P[i], P[(i + 1) % len(P)]
        e = p1 - p0
        f = np.clip((point - p0) @ e / (e @ e), 0, 1)
        d = np.linalg.norm(point[:2] - (p0 + f * e)[:2])
        n = np.array([e[1], -e[0], 0.0])
        n /= np.linalg.norm(n)
        if n @ (p0 - c) < 0:
            n = -n
        if d < best:
            best, nbest = d, n
    return nbest


@pytest.mark.parametrize("name", ["square", "triangle"])
def test_collision_is_detected_and_detached_out_of_a(name, request):
    r = request.getfixturevalue(name)
    s = r.summary
    assert r.hit.any()
    g = r.geometry
    for k in np.flatnonzero(r.hit):
        assert r.contact_class[k] in (2, 4), CONTACT_CLASSES[int(r.contact_class[k])]  # rim / side face
        n = _outward_normal_nearest_edge(g["xy_a"], g["rot_a"], r.contact[k])
        assert r.direction[k] @ n > 0.99  # points out of a, across the side face
        err = np.linalg.norm(r.dc[k] - np.array(r.params["xd_um"]) * 1e-3)
        np.testing.assert_allclose(r.u_d[k], r.params["eps"] * err * r.direction[k], rtol=1e-12)
        assert r.case[k] == 6
    assert s["first_contact_class"] == 2
    # the detach acts for one step only
    assert np.all(r.u_d[~r.hit] == 0.0)


@pytest.mark.parametrize("name", ["square", "triangle"])
def test_detach_separates_the_objects(name, request):
    reference = pytest.importorskip("reference")
    pytest.importorskip("scipy")
    r = request.getfixturevalue(name)
    g = r.geometry
    for k, ev in zip(np.flatnonzero(r.hit), r.summary["events"]):
        assert not r.hit[k + 1] and ev["next_step_collision_free"] and ev["step"] == k
        m_prev, m_hit, m_next = (
            reference.margin_lp(g["xy_a"], g["pos_a"], g["rot_a"], g["xy_b"], r.dc[j], g["rot_b"])
            for j in (k - 1, k, k + 1)
        )
        assert m_prev < 0.0 <= m_hit  # the hit is real and the sample before was free
        assert m_next < -0.1  # a gap of at least 2 * 0.1 mm after the detach (the paper: "substantial margin")
        assert (r.dc[k + 1] - r.dc[k]) @ r.direction[k] > 0.3  # moved out by more than 0.3 mm


def test_case_sequence_and_goal(square, triangle):
    for r in (square, triangle):
        s = r.summary
        assert s["case_sequence"] == [5, 6, 1]
        assert s["goal_reached"] and s["final_error_um"] < r.params["goal_tol_um"]
        assert s["goal_reached_without_further_collision"] is (r is triangle)
        assert s["every_detach_followed_by_free_step"]
        # no collision once b's end face is above a's plane (case 1 for good, to the end)
        assert not r.hit[r.t >= s["case1_for_good_from_s"]].any()
        assert s["fig10_cases"][0] == 5 and s["fig10_cases"][-1] == 1
    assert square.summary["collision_episodes"] == 3 and square.summary["collision_samples"] == 3
    assert triangle.summary["collision_samples"] == 1
    # all detaches of the square happen before it clears a's plane
    assert max(square.summary["collisions_after_first_detach_s"]) < square.summary["case1_for_good_from_s"]


def test_force_plant_and_speed_limit_run():
    r = run_experiment("triangle", vertices=36, plant="force", timing=False)
    assert r.summary["case_sequence"] == [5, 6, 1] and r.hit.any() and r.summary["goal_reached"]
    slow = run_experiment("triangle", vertices=36, max_speed=0.5, timing=False)
    assert (
        slow.summary["first_collision_s"]
        > run_experiment("triangle", vertices=36, timing=False).summary["first_collision_s"]
    )
    steady = np.linalg.norm(np.diff(slow.dc, axis=0), axis=1)[~slow.hit[:-1]] / slow.params["dt_s"]
    assert steady.max() <= 0.5 + 1e-9


def _distance_to_rim(xy_local, rot_a, point):
    """Distance from a world point to the boundary of a's end face (a at the origin)."""
    P = (xy_local @ rot_a[:, :2].T)[:, :2]
    edge = np.inf
    for i in range(len(P)):
        p0, e = P[i], P[(i + 1) % len(P)] - P[i]
        f = np.clip((point[:2] - p0) @ e / (e @ e), 0, 1)
        edge = min(edge, np.linalg.norm(point[:2] - (p0 + f * e)))
    return float(np.hypot(point[2], edge))


def test_contact_from_distance_is_the_witness_point_on_a(triangle):
    """The default takes the contact from the penetration's witness point on a (on a's rim here, as
    collide's point, which contact_from="collide" uses, but elsewhere along the rim)."""
    old = run_experiment("triangle", vertices=VERTS, timing=False, contact_from="collide")
    g = triangle.geometry
    assert triangle.params["contact_from"] == "distance" and old.params["contact_from"] == "collide"
    hits = np.flatnonzero(triangle.hit)
    assert len(hits) and np.array_equal(hits, np.flatnonzero(old.hit))
    b = Prism.regular(VERTS, 0.5 * triangle.params["b_diameter_mm"])
    a = Prism(g["xy_a"])
    for k in hits:
        d = distance(a, b, g["pos_a"], g["rot_a"], triangle.dc[k], g["rot_b"], witness=True)
        np.testing.assert_allclose(triangle.contact[k], d.point_a[0], rtol=0, atol=1e-12)
        np.testing.assert_allclose(triangle.direction[k], d.normal[0], rtol=0, atol=1e-12)
        assert _distance_to_rim(g["xy_a"], g["rot_a"], triangle.contact[k]) < 1e-9
        assert _distance_to_rim(g["xy_a"], g["rot_a"], old.contact[k]) < 1e-6
        assert np.linalg.norm(triangle.contact[k] - old.contact[k]) > 1e-3  # mm: not the same point
    with pytest.raises(ValueError, match="contact_from"):
        run_experiment(contact_from="witness", vertices=36, timing=False)


def test_alarm_fires_before_the_first_contact(triangle, square):
    for r in (triangle, square):
        al = r.alarm
        assert al["alarm_s"] is not None and al["first_contact_s"] == r.summary["first_collision_s"]
        assert 0.0 < al["lead_s"] == pytest.approx(al["first_contact_s"] - al["alarm_s"])
        assert np.all((al["low"] <= al["p"]) & (al["p"] <= al["high"]))


def _meets_within(col, g, start, velocity, horizon, steps=4000):
    """Plain reference: does b, moving from ``start`` at ``velocity``, hit a at any of ``steps`` + 1 instants?"""
    s = np.linspace(0.0, horizon, steps + 1)[:, None]
    pos = np.ascontiguousarray(start + s * velocity)
    return col.collide(g["pos_a"], g["rot_a"], pos, g["rot_b"]).hit.any()


def test_alarm_against_sampled_motions(triangle):
    """Time to impact and the alarm's probability against motions sampled densely with collide."""
    from prismbatch import Collider
    from prismbatch.lab.experiment.alarm import collision_alarm, commanded_velocity

    g = triangle.geometry
    a, b = Prism(g["xy_a"]), Prism.regular(VERTS, 0.5 * triangle.params["b_diameter_mm"])
    col = Collider(a, b)
    al = collision_alarm(triangle, col, samples=40, every=25, seed=3)
    vel = commanded_velocity(triangle)
    for k in range(0, len(triangle.t), 50):  # the nominal time to impact
        toi = al["toi_s"][k]
        if np.isfinite(toi):
            assert not _meets_within(col, g, triangle.dc[k], vel[k], toi * (1 - 1e-6))
            d = distance(a, b, g["pos_a"], g["rot_a"], triangle.dc[k] + toi * vel[k], g["rot_b"])
            assert d.distance[0] <= d.tol[0]
        else:
            assert not _meets_within(col, g, triangle.dc[k], vel[k], 1.0)
    # the probability: the same noise draws, each motion judged by dense sampling
    rng = np.random.default_rng(3)
    ks = np.arange(0, len(triangle.t), 25)
    noise = rng.standard_normal((len(ks), 40, 3)) * (al["sigma_um"] * 1e-3)
    mixed = [j for j in range(len(ks)) if 0 < al["p"][j] < 1]
    for j in [*mixed[:2], int(np.argmax(al["p"])), 0]:
        k = ks[j]
        hits = sum(_meets_within(col, g, triangle.dc[k] + noise[j, i], vel[k], 1.0) for i in range(40))
        assert abs(hits - 40 * al["p"][j]) <= 1, (triangle.t[k], hits, al["p"][j])  # sampling may miss a graze


@pytest.mark.parametrize("plant", ["velocity", "force"])
def test_adapted_detach_leaves_the_asked_clearance(plant):
    clearance_um = 40.0
    r = run_experiment("square", vertices=36, plant=plant, detach_clearance_um=clearance_um, timing=False, alarm=False)
    g = r.geometry
    a, b = Prism(g["xy_a"]), Prism(g["xy_b"])
    hits = np.flatnonzero(r.hit)
    assert len(hits) >= 2
    gaps = distance(a, b, g["pos_a"], g["rot_a"], r.dc[hits + 1], g["rot_b"]).distance
    depth = -distance(a, b, g["pos_a"], g["rot_a"], r.dc[hits], g["rot_b"]).distance
    moved = np.einsum("ij,ij->i", r.dc[hits + 1] - r.dc[hits], r.direction[hits])
    # the plant model predicts the step exactly: out of the penetration and the clearance beyond, along the normal
    np.testing.assert_allclose(moved, np.maximum(depth, 0) + clearance_um * 1e-3, rtol=1e-9)
    assert np.all(gaps >= clearance_um * 1e-3 * (1 - 1e-9))
    eps = np.array([e["eps"] for e in r.summary["events"]])
    assert np.all(eps > 0) and np.ptp(eps) > 0  # adapted per contact, not the fixed 10
    with pytest.raises(ValueError, match="detach_clearance_um"):
        run_experiment(vertices=36, detach_clearance_um=-1.0, timing=False)


def test_bad_parameters():
    with pytest.raises(ValueError, match="plant"):
        run_experiment(plant="mass", vertices=36, timing=False)
    with pytest.raises(ValueError, match="prism"):
        run_experiment("pentagon", vertices=36, timing=False)
    with pytest.raises(ValueError, match="dt"):
        run_experiment(dt=0.0, vertices=36, timing=False)


def test_projected_contour():
    xy = np.array([[1.0, 0], [0, 1], [-1, 0], [0, -1]])
    down = np.diag([1.0, -1.0, -1.0])
    # b facing a (axis up), end face above a's plane: nothing on a's side
    assert projected_contour(xy, [0, 0, 0.5], np.eye(3), [0, 0, 0], down).shape == (0, 2)
    # end face below the plane, axis exactly up: the projection is the end face itself
    Q = projected_contour(xy, [3, 0, -0.5], np.eye(3), [0, 0, 0], down)
    assert len(Q) == 4 and np.allclose(sorted(map(tuple, np.round(Q, 12))), sorted(map(tuple, xy + [3, 0])))


def test_timing_and_fcl_agree(square):
    tm = square.timing
    assert tm["loop_ms"] > 0 and tm["pair_ms"] > 0 and tm["batch_ms"] > 0
    assert tm["batch_agrees_with_loop"]
    if tm.get("fcl_ms") is not None:
        assert tm["fcl_disagreements"] == 0
    assert any("detection cost" in line for line in format_summary(square))


def test_writer(square, tmp_path):
    paths = write_experiment(square, tmp_path, figures=False)
    rows = open(paths["csv"]).read().splitlines()
    assert len(rows) == 1 + len(square.t) and rows[0].startswith("t_s,dC_x_um")
    meta = json.load(open(paths["json"]))
    assert meta["parameters"]["vertices"] == VERTS and meta["versions"]["prismbatch"]
    assert meta["summary"]["case_sequence"] == [5, 6, 1]
    assert "| case sequence |" in open(paths["markdown"]).read()


def test_writer_figures(square, tmp_path):
    pytest.importorskip("matplotlib")
    paths = write_experiment(square, tmp_path, figures=True)
    assert len(paths["figures"]) == 8  # Figs. 10, 11a, 11b-c and the alarm, PNG and SVG each
    assert any(f.endswith("_alarm.png") for f in paths["figures"])
    alarm = open(paths["alarm_csv"]).read().splitlines()
    assert alarm[0].startswith("t_s,p_collision_within_horizon") and len(alarm) == 1 + len(square.alarm["p"])
    for f in paths["figures"]:
        data = open(f, "rb").read()
        assert len(data) > 5000
        assert data[:4] == b"\x89PNG" if f.endswith(".png") else b"<svg" in data[:2000]
    assert len(FIG10_TIMES) == 8


def test_cli_experiment(capsys, tmp_path):
    assert (
        main(
            [
                "experiment",
                "--prism",
                "triangle",
                "--vertices",
                "36",
                "--duration",
                "6",
                "--no-fcl",
                "--out",
                str(tmp_path),
                "--no-figures",
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "case sequence: 5" in out and "collision: first at" in out and "wrote" in out
    assert (tmp_path / "experiment_triangle_trajectory.csv").exists()
    assert main(["experiment", "--dt", "-1"]) == 2
