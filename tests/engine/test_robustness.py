"""Exactness and robustness regressions: identical and nearly identical rotations,
dense nearly collinear polygons, the supported magnitude range, polygons judged
relative to themselves, read-only inputs, and a fork after a parallel call.

The two saved cases in ``tests/data`` were found by an independent exact check
(rational arithmetic on the exact float inputs); their verdicts are stored with
them. Every other expectation here is known in closed form.
"""

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import prismbatch as pb
from prismbatch.config import MAX_MAGNITUDE

from helpers import subdivided

DATA = Path(__file__).resolve().parents[1] / "data"
SQUARE = pb.Prism([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])


def _load_case(name):
    d = json.loads((DATA / f"{name}.json").read_text())
    h = float.fromhex
    arr = lambda key, shape: np.array([h(x) for x in np.ravel(d[key])]).reshape(shape)  # noqa: E731
    case = dict(
        xa=arr("xy_a", (-1, 2)),
        xb=arr("xy_b", (-1, 2)),
        pa=arr("pos_a", (3,)),
        pb=arr("pos_b", (3,)),
        ra=arr("rot_a", (3, 3)),
        rb=arr("rot_b", (3, 3)),
        verdict=d["exact"]["verdict"],
    )
    if d.get("quat_a") is not None:
        case.update(qa=arr("quat_a", (4,)), qb=arr("quat_b", (4,)), order=d["quat_order"])
    return case


@pytest.mark.parametrize("name", ["same_rotation_side_by_side", "dense_nearly_collinear_miss"])
def test_saved_exact_verdicts(name):
    c = _load_case(name)
    A, B = pb.Prism(c["xa"]), pb.Prism(c["xb"])
    want = c["verdict"] == "hit"
    col = pb.Collider(A, B)
    assert col.collide_pair(c["pa"], c["ra"], c["pb"], c["rb"]).hit == want
    assert col.explain(c["pa"], c["ra"], c["pb"], c["rb"])["hit"] == want
    r = pb.collide(A, B, c["pa"][None], c["ra"][None], c["pb"][None], c["rb"][None], contact=True)
    assert r.hit[0] == want
    if "qa" in c:  # the call that was wrong was made with quaternions
        rq = pb.collide(A, B, c["pa"], c["qa"], c["pb"], c["qb"], quat_order=c["order"])
        assert rq.hit[0] == want


@pytest.mark.parametrize("gap", [1e-3, 0.1, 2.0])
def test_identical_rotations_side_by_side_never_hit(gap):
    # Same rotation matrix, a clear lateral gap: parallel axes, a miss whatever
    # the rounding noise of R_a^T R_b (it once swept b along that noise).
    R = Rotation.random(300, random_state=1).as_matrix()
    p = np.random.default_rng(2).normal(size=(300, 3))
    q = p + np.einsum("nij,j->ni", R, [2.0 + gap, 0.0, 0.0])
    r = pb.collide(SQUARE, SQUARE, p, R, q, R)
    assert not r.hit.any()
    # ... and the same pairs moved to touching, or overlapping, all hit.
    for shift in (2.0, 1.5):
        q = p + np.einsum("nij,j->ni", R, [shift, 0.0, 0.0])
        assert pb.collide(SQUARE, SQUARE, p, R, q, R).hit.all()


@pytest.mark.parametrize("theta", [0.0, 1e-16, 1e-15, 1e-12, 1e-9, 1e-6])
def test_tiny_tilts_follow_their_direction(theta):
    # b beside a (gap 0.1 along x), both bodies along +z; b's axis tilted by
    # theta in x. The matrices are exact as written (cos theta rounds to 1), so
    # the exact bodies are known: tilted towards a they meet at t = 0.1 / theta
    # (the prisms are semi-infinite), tilted away or about x they never do.
    def tilt_x(s):  # axis (s, 0, 1)
        return np.array([[1.0, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, 1.0]])

    def tilt_y(s):  # axis (0, s, 1)
        return np.array([[1.0, 0.0, 0.0], [0.0, 1.0, s], [0.0, -s, 1.0]])

    col = pb.Collider(SQUARE, SQUARE)
    pa, pb_ = np.zeros(3), np.array([2.1, 0.0, 0.0])
    towards = col.collide_pair(pa, np.eye(3), pb_, tilt_x(-theta)).hit
    away = col.collide_pair(pa, np.eye(3), pb_, tilt_x(theta)).hit
    sideways = col.collide_pair(pa, np.eye(3), pb_, tilt_y(theta)).hit
    assert towards == (theta > 0.0)
    assert not away
    assert not sideways
    # The same pairs seen from b (a tilted the other way) agree.
    assert col.collide_pair(pb_, tilt_x(-theta), pa, np.eye(3)).hit == (theta > 0.0)


def test_magnitudes_inside_the_range_are_scale_free():
    # The same scene at scales 1e-12 ... 1e12 and shifted far from the origin
    # gives the same answers (the scene is exact at every power of two scale).
    rng = np.random.default_rng(3)
    R = Rotation.random(400, random_state=4).as_matrix()
    q = rng.uniform(-3, 3, size=(400, 3))
    base = pb.collide(SQUARE, SQUARE, np.zeros(3), np.eye(3), q, R).hit
    for e in (-40, -20, 20, 40):
        s = 2.0**e
        sq = pb.Prism(SQUARE.xy * s)
        assert (pb.collide(sq, sq, np.zeros(3), np.eye(3), q * s, R).hit == base).all()


@pytest.mark.parametrize("scale", [1e-11, 1e-6, 1.0, 1e6, 1e11])
def test_float32_answers_inside_its_range_match_float64(scale):
    # float32 compute has its own supported range (config.SUPPORTED_RANGE):
    # inside it, answers away from the touching band are those of float64.
    rng = np.random.default_rng(5)
    a, b = pb.Prism.regular(7, 2.0 * scale), pb.Prism.regular(4, 1.5 * scale)
    R = Rotation.random(2000, random_state=6).as_matrix()
    q = rng.uniform(-3, 3, size=(2000, 3)) * scale
    r64 = pb.collide(a, b, np.zeros(3), np.eye(3), q, R)
    r32 = pb.collide(a, b, np.zeros(3), np.eye(3), q, R, dtype=np.float32)
    assert 200 < r64.hit.sum() < 1800
    assert (r32.hit != r64.hit).sum() <= 4  # only pairs within float32's 1e-5 tolerance band


@pytest.mark.parametrize("pos", [[1e20, 0, -1], [0, 0, -1e39], [2e12, 0, 0]])
def test_float32_positions_beyond_its_range_raise(pos):
    sq = pb.Prism.regular(4, 1.0)
    down = np.diag([1.0, -1.0, -1.0])
    with pytest.raises(
        ValueError, match=r"pos_b\[0\] has a coordinate .* outside the supported range \|x\| <= 1e\+12 for float32"
    ):
        pb.collide(sq, sq, [0, 0, 0], down, np.array([pos, pos]), np.eye(3), dtype=np.float32)
    # (1e39 is inf once the caller has rounded it to float32.)
    with np.errstate(over="ignore"):
        pos32 = np.array(pos, np.float32)
    with pytest.raises(
        ValueError, match=r"pos_b (has a coordinate .* outside the supported range \|x\| <= 1e\+12|contains non-finite)"
    ):
        pb.Collider(sq, sq, dtype=np.float32).collide_pair(
            np.zeros(3, np.float32), down.astype(np.float32), pos32, np.eye(3, dtype=np.float32)
        )
    assert pb.collide(sq, sq, [0, 0, 0], down, [1e20, 0, -1], np.eye(3)).hit.tolist() == [False]  # float64: fine


@pytest.mark.parametrize("r", [1e13, 1e-13])
def test_float32_polygons_beyond_its_range_raise(r):
    p = pb.Prism.regular(5, r)
    with pytest.raises(ValueError, match="outside the supported range for float32"):
        pb.collide(p, p, np.zeros(3), np.eye(3), np.zeros(3), np.eye(3), dtype=np.float32)
    pb.collide(p, p, np.zeros(3), np.eye(3), np.zeros(3), np.eye(3))  # float64 takes it


@pytest.mark.parametrize("bad", [1e308, -1.7e308, 2 * MAX_MAGNITUDE, np.inf, np.nan])
def test_positions_outside_the_range_raise(bad):
    a, b = pb.Prism.regular(5, 2.0), pb.Prism.regular(6, 2.5)
    down = np.diag([1.0, -1.0, -1.0])
    col = pb.Collider(a, b)
    for call in (
        lambda: pb.collide(a, b, [bad, 0, 0], down, [-1e308, 0, 0], np.eye(3)),
        lambda: pb.collide(a, b, np.array([[0, 0, bad]] * 5), down, np.zeros(3), np.eye(3)),
        lambda: col.collide_pair(np.array([bad, 0, 0]), down, np.zeros(3), np.eye(3)),
        lambda: col.explain(np.zeros(3), down, np.array([0, 0, bad]), np.eye(3)),
    ):
        with pytest.raises(ValueError, match="pos_"):
            call()


def test_polygons_outside_the_range_raise_at_collide():
    for r in (1e200, 1e-200):
        p = pb.Prism.regular(5, r)  # a valid polygon ...
        with pytest.raises(ValueError, match="supported range"):  # ... that the kernels cannot take
            pb.collide(p, p, np.zeros(3), np.eye(3), np.zeros(3), np.eye(3))


def test_valid_polygons_far_away_or_of_any_size_are_accepted():
    tri = pb.Prism([[1e12, 1e12], [1e12 + 5, 1e12], [1e12, 1e12 + 5]])
    assert np.allclose(tri.centre - 1e12, [5 / 3, 5 / 3], atol=1e-3)
    far = pb.Prism.regular(27, 1, centre=(1e10, 1e10))
    assert far.n_vertices == 27 and abs(far.radius - 1) < 1e-5
    for r in (1e200, 1e-200, 1e-300):
        p = pb.Prism.regular(5, r)
        assert abs(p.radius / r - 1) < 1e-12 and np.all(np.abs(p.centre) < 1e-12 * r)
    # Real defects are still rejected at every scale.
    for s in (1e-200, 1.0, 1e200):
        with pytest.raises(ValueError, match="not convex"):
            pb.Prism(np.array([[0, 0], [2, 0], [1, 0.2], [2, 2], [0, 2]]) * s)
        with pytest.raises(ValueError, match="zero area"):
            pb.Prism(np.array([[0, 0], [1, 1], [2, 2]]) * s + 1e10 * s)


def _sampled_square(per_side, corner, angle):
    """A unit square with corner ``(corner, corner)``, ``per_side`` vertices on each side (np.linspace, as a
    tessellation writes them), turned by ``angle``: straight sides, up to the rounding of the coordinates."""
    xy = subdivided(np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float) + corner, per_side)
    c, s = np.cos(angle), np.sin(angle)
    return xy @ np.array([[c, -s], [s, c]]).T


@pytest.mark.parametrize("per_side, corner", [(100, 100.0), (10_000, 0.0), (10_000, 1e4), (100_000, 1.0)])
def test_sides_sampled_then_turned_are_refused_with_the_remedy(per_side, corner):
    """Vertices along straight sides that rounding turns back and forth by more than 1e-12 rad are refused
    (accepting turns up to 1e-6 let the extreme-vertex search land anywhere on a side and missed contacts 2.6
    tol deep), with a message that names the turn and the remedy; the corners alone are accepted."""
    for angle in (0.3, 2.2):
        xy = _sampled_square(per_side, corner, angle)
        with pytest.raises(ValueError, match=r"reflex turn of [0-9.e-]+ rad\): .*drop the vertices inside straight"):
            pb.Prism(xy)
        np.testing.assert_array_equal(pb.Prism(xy[::per_side]).xy, xy[::per_side])
    with pytest.raises(ValueError, match=r"reflex turn of 1.9 rad\)$"):  # a real dent: no such hint
        pb.Prism([[0, 0], [2, 0], [1, 0.2], [2, 2], [0, 2]])
    assert pb.Prism(_sampled_square(per_side, corner, 0.0)).n_vertices == 4 * per_side  # exactly straight sides


def _square_bent_inwards(m, tau):
    """A unit square whose bottom side is m edges, each turning back by tau rad from the last (a side bent
    inwards by m tau in all, each step below the per-vertex limit of 1e-12)."""
    ang = m * tau / 2 - tau * np.arange(m)
    e = np.stack([np.cos(ang), np.sin(ang)], axis=1) / np.cos(ang).sum()
    side = np.concatenate([[[0.0, 0.0]], np.cumsum(e, axis=0)])
    return np.concatenate([side, side[-1] + [[0.0, 1.0]], [[0.0, 1.0]]])


@pytest.mark.parametrize("m, tau", [(100_000, 9e-13), (10_000, 5e-13), (10, 9e-13)])
def test_a_side_bent_inwards_in_steps_below_the_limit_is_refused(m, tau):
    """Each backward turn passes the per-vertex test, their sum may not (above 4e-12 rad): a bend of 9e-8
    rad leaves the side's middle 1.1e-8 inside (the tolerance of a pair of size 2 is 2e-9), which the
    kernels' search, taking the polygon as convex, would not see. 3 steps of 9e-13 (1.8e-12 from the
    first edge's direction) are rounding: kept."""
    xy = _square_bent_inwards(m, tau)
    with pytest.raises(ValueError, match=f"turns back by {(m - 1) * tau:.2g} rad in all"):
        pb.Prism(xy)
    with pytest.raises(ValueError, match="polygon 1: .*turns back"):
        pb.PrismSet([[[0, 0], [1, 0], [1, 1], [0, 1]], xy])
    assert pb.Prism(_square_bent_inwards(3, tau)).n_vertices == 6


def test_read_only_inputs_are_accepted_everywhere():
    a, b = pb.Prism.regular(5, 2.0), pb.Prism.regular(6, 2.5)
    pos = np.array([0.3, 0.1, 0.0])
    pos.flags.writeable = False
    rot = np.broadcast_to(np.diag([1.0, -1.0, -1.0]), (3, 3))
    pb_ = np.array([0.0, 0.0, -0.5])  # b pushed up into a
    col = pb.Collider(a, b)
    want = col.collide_pair(pos.copy(), rot.copy(), pb_, np.eye(3))
    assert want.hit
    assert col.collide_pair(pos, rot, pb_, np.eye(3)).hit == want.hit
    assert col.explain(pos, rot, pb_, np.eye(3))["hit"] == want.hit
    assert pb.collide(a, b, pos, rot, pb_, np.eye(3)).hit[0] == want.hit
    many = np.broadcast_to(pos, (10, 3))
    assert pb.collide(a, b, many, rot, pb_, np.eye(3)).hit.all()


@pytest.mark.slow
@pytest.mark.parametrize("parent, child", [("collide", "collide"), ("collide", "detach"), ("detach", "collide")])
def test_fork_after_a_parallel_call_gives_working_children(tmp_path, parent, child):
    # detach chooses its kernel through the same fork guard as collide.
    script = tmp_path / "fork_pool.py"
    script.write_text(
        textwrap.dedent(f"""
        import multiprocessing as mp
        import numpy as np
        import prismbatch as pb
        from prismbatch.control import detach
        a, b = pb.Prism.regular(5, 2.0), pb.Prism.regular(6, 2.5)
        down = np.diag([1.0, -1.0, -1.0])
        P = np.random.default_rng(0).normal(size=(5000, 3))
        def collide(_):
            return int(pb.collide(a, b, np.zeros(3), np.eye(3), P, np.eye(3), parallel=True).hit.sum())
        def detach_(_):
            inside = np.column_stack([0.1 * P[:, :2], -np.abs(P[:, 2])])
            d = detach(a, inside, np.zeros(3), down, np.eye(3), np.ones(len(P)), parallel=True)
            return int(d.contact_class.sum())
        work = {{"collide": collide, "detach": detach_}}
        if __name__ == "__main__":
            work["{parent}"](0)  # threads started in the parent
            with mp.get_context("fork").Pool(2) as pool:
                in_children = pool.map(work["{child}"], range(3))
            print(work["{child}"](0), in_children)
    """)
    )
    out = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=600, env=dict(os.environ)
    )
    assert out.returncode == 0, out.stderr
    first, rest = out.stdout.split(" ", 1)
    assert json.loads(rest) == [int(first)] * 3
