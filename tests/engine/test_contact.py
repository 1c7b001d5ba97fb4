"""Contact points of ``prismbatch.collide(..., contact=True)``.

"Every reported contact point lies inside both prisms within tolerance."
Checked with the reference ``point_in_prism_residual`` (max constraint
violation, <= 0 inside) against ``2 * tol`` (tol = the pair tolerance
``rtol * (R_a + R_b + |c_b - c_a|)``) plus a tiny rounding slack, for:

* a few thousand random facing and free pairs (3..3600 vertices);
* pairs brought to touching by bisection (the hardest contacts);
* exactly perpendicular / antiparallel / coplanar configurations;
* float32 (checked against the float32-rounded poses, tol from rtol 1e-5).

Also: NaN rows exactly where there is no hit; a status-only call has the
same hit/case arrays and no contact attribute; serial and parallel kernels
give identical results.
"""

from __future__ import annotations

import numpy as np
import pytest

import prismbatch as pb

from helpers import (
    PairData,
    bisect_to_contact,
    concat_pairs,
    make_pairs,
    overlapping_pairs,
    pair_scale,
    perpendicular_pairs,
    polygon_radius,
    separating_directions,
    vertical_pairs,
)
from reference import point_in_prism_residual

SLACK_REL = 1e-12  # rounding of the residual evaluation itself, relative to S


def residuals(d: PairData, contact, idx):
    """(len(idx), 2) residuals of the contacts w.r.t. prism a and prism b."""
    out = np.empty((len(idx), 2))
    for j, k in enumerate(idx):
        out[j, 0] = point_in_prism_residual(d.polys_a[k], d.pos_a[k], d.rot_a[k], contact[k])
        out[j, 1] = point_in_prism_residual(d.polys_b[k], d.pos_b[k], d.rot_b[k], contact[k])
    return out


def check_contacts(d: PairData, r, label, *, rtol=1e-9, atol=0.0, slack_rel=SLACK_REL, contact=None):
    """Assert NaN/finite rows and residuals <= 2 tol (+ slack) for every hit.

    Returns (number of hits, largest residual / S)."""
    hit = r.hit
    c = r.contact if contact is None else contact
    assert c.shape == (len(d), 3), c.shape
    assert np.all(np.isnan(c[~hit])), f"{label}: rows without a hit must be NaN"
    assert np.all(np.isfinite(c[hit])), f"{label}: rows with a hit must be finite"
    idx = np.flatnonzero(hit)
    scale = pair_scale(d.polys_a, d.pos_a, d.rot_a, d.polys_b, d.pos_b, d.rot_b)
    limit = 2 * (atol + rtol * scale[idx]) + slack_rel * scale[idx]
    res = residuals(d, c, idx)
    worst = np.max(res / limit[:, None], axis=1)
    bad = np.flatnonzero(worst > 1.0)
    assert bad.size == 0, (
        f"{label}: {bad.size} of {idx.size} contacts lie outside a prism by more than 2 tol, e.g. "
        + ", ".join(f"pair {idx[j]}: residuals/S {res[j] / scale[idx[j]]}" for j in bad[:6])
    )
    return idx.size, float(np.max(res / scale[idx, None])) if idx.size else 0.0


@pytest.fixture(scope="module")
def random_pairs():
    rng = np.random.default_rng(31337)
    return concat_pairs(make_pairs(rng, 1500, "facing", "mixed"), make_pairs(rng, 1500, "free", "mixed"))


@pytest.mark.slow
def test_random_pair_contacts_inside_both_prisms(random_pairs):
    d = random_pairs
    r = pb.collide(pb.PrismSet(d.polys_a), pb.PrismSet(d.polys_b), *d.args(), contact=True)
    n_hits, _ = check_contacts(d, r, "random")
    assert n_hits >= 800, n_hits
    assert max(len(p) for p in d.polys_a + d.polys_b) >= 1000


@pytest.fixture(scope="module")
def few_random_pairs():
    # a fifth of random_pairs: the fast set's pairs (random_pairs takes 5 s to make)
    rng = np.random.default_rng(31338)
    return concat_pairs(make_pairs(rng, 300, "facing", "mixed"), make_pairs(rng, 300, "free", "mixed"))


def test_contact_flag_serial_parallel_consistency(few_random_pairs):
    d = few_random_pairs
    sa, sb = pb.PrismSet(d.polys_a), pb.PrismSet(d.polys_b)
    full = pb.collide(sa, sb, *d.args(), contact=True)
    status = pb.collide(sa, sb, *d.args(), contact=False)
    np.testing.assert_array_equal(status.hit, full.hit)
    np.testing.assert_array_equal(status.case, full.case)
    assert status.hit.dtype == np.bool_ and status.case.dtype == np.int8
    with pytest.raises(AttributeError):
        status.contact  # noqa: B018
    for contact in (False, True):
        ser = pb.collide(sa, sb, *d.args(), contact=contact, parallel=False)
        par = pb.collide(sa, sb, *d.args(), contact=contact, parallel=True)
        np.testing.assert_array_equal(ser.hit, par.hit)
        np.testing.assert_array_equal(ser.case, par.case)
        if contact:
            np.testing.assert_array_equal(ser.contact, par.contact)  # NaN == NaN here
    assert np.all((full.case >= 1) & (full.case <= 11))


@pytest.mark.parametrize("n", [1, 2, 3, 7, 8, 9, 61])
def test_parallel_blocks_cover_every_pair_once(n):
    # The parallel kernel cuts a batch into blocks (up to 4 a thread, at most n): each pair, once.
    from prismbatch.sampling import free_poses

    col = pb.Collider(pb.Prism.regular(7, 1.0), pb.Prism.regular(5, 0.8))
    P = free_poses(n, np.random.default_rng(n), radius=0.8)
    par = col.collide(*P, contact=True, parallel=True)
    for i in range(n):
        one = col.collide_pair(*(x[i] for x in P))
        assert (one.hit, one.case) == (par.hit[i], par.case[i]), i
        np.testing.assert_array_equal(one.contact, par.contact[i])


@pytest.mark.slow
def test_near_touching_contacts():
    """Contacts of pairs moved to the edge of touching (last hit of a
    bisection on prismbatch's own decision): the gap there is at most
    sqrt(2) tol and the contact must still be within 2 tol of both."""
    rng = np.random.default_rng(99)
    d = concat_pairs(overlapping_pairs(rng, 400, "facing"), overlapping_pairs(rng, 400, "free"))
    sa, sb = pb.PrismSet(d.polys_a), pb.PrismSet(d.polys_b)
    ra = np.array([polygon_radius(p) for p in d.polys_a])
    rb = np.array([polygon_radius(p) for p in d.polys_b])
    far = 4.0 * (ra + rb)
    u, keep = separating_directions(rng, sa, sb, d, far)
    lo, _ = bisect_to_contact(sa, sb, d, u, far)
    touch = PairData(d.polys_a, d.polys_b, d.pos_a, d.rot_a, d.pos_b + lo[:, None] * u, d.rot_b)
    r = pb.collide(sa, sb, *touch.args(), contact=True)
    assert r.hit[keep].all()
    n_hits, _ = check_contacts(touch, r, "near-touching")
    assert n_hits >= 0.95 * len(d)


@pytest.mark.parametrize(
    "mode", [pytest.param("generic", marks=pytest.mark.slow), pytest.param("vertex", marks=pytest.mark.slow), "edge"]
)
def test_perpendicular_contacts(mode):
    rng = np.random.default_rng({"generic": 1, "vertex": 2, "edge": 3}[mode])
    d = perpendicular_pairs(rng, 400, mode)
    r = pb.collide(pb.PrismSet(d.polys_a), pb.PrismSet(d.polys_b), *d.args(), contact=True)
    n_hits, _ = check_contacts(d, r, f"perpendicular/{mode}")
    assert n_hits >= 40


@pytest.mark.parametrize(
    "relation, height",
    [
        ("parallel", "coplanar"),
        pytest.param("antiparallel", "coplanar", marks=pytest.mark.slow),
        pytest.param("parallel", "random", marks=pytest.mark.slow),
        pytest.param("antiparallel", "random", marks=pytest.mark.slow),
    ],
)
def test_parallel_contacts(relation, height):
    rng = np.random.default_rng({"parallel": 10, "antiparallel": 20}[relation] + (height == "random"))
    d, _ = vertical_pairs(rng, 400, relation, height, with_gap=False)
    r = pb.collide(pb.PrismSet(d.polys_a), pb.PrismSet(d.polys_b), *d.args(), contact=True)
    n_hits, _ = check_contacts(d, r, f"{relation}/{height}")
    assert n_hits >= 40


@pytest.mark.slow
def test_float32_contacts(random_pairs):
    d = random_pairs
    r = pb.collide(pb.PrismSet(d.polys_a), pb.PrismSet(d.polys_b), *d.args(), contact=True, dtype=np.float32)
    assert r.contact.dtype in (np.float32, np.float64)
    # the reference sees the poses the kernel saw (rounded to float32); the
    # polygons are rounded too (about 1e-7 R), well inside tol = 1e-5 S
    d32 = PairData(d.polys_a, d.polys_b, *(np.asarray(a, np.float32).astype(np.float64) for a in d.args()))
    n_hits, _ = check_contacts(d32, r, "float32", rtol=1e-5, slack_rel=1e-6, contact=np.asarray(r.contact, np.float64))
    assert n_hits >= 800


@pytest.mark.slow
@pytest.mark.parametrize("rtol,atol", [(0.0, 0.02), (1e-2, 0.0)])
def test_contacts_with_large_tolerance(random_pairs, rtol, atol):
    """With a large tolerance, hits include pairs up to sqrt(2) tol apart;
    their contacts must still be within 2 tol of both prisms."""
    d = random_pairs
    r = pb.collide(pb.PrismSet(d.polys_a), pb.PrismSet(d.polys_b), *d.args(), contact=True, rtol=rtol, atol=atol)
    base = pb.collide(pb.PrismSet(d.polys_a), pb.PrismSet(d.polys_b), *d.args())
    assert np.all(r.hit[base.hit]), "a larger tolerance cannot lose hits"
    n_hits, _ = check_contacts(d, r, f"rtol={rtol},atol={atol}", rtol=rtol, atol=atol)
    assert n_hits > base.hit.sum()  # the tolerance adds near misses


def test_serial_and_parallel_kernels_have_separate_cache_entries():
    # Numba keys its disk cache by function name and line, not by the
    # parallel flag: one shared name made one kernel silently run as the other.
    from prismbatch._kernels import batch as _batch

    assert _batch.collide_serial.targetoptions.get("parallel") is False
    assert _batch.collide_parallel.targetoptions.get("parallel") is True
    names = {_batch.collide_serial.py_func.__qualname__, _batch.collide_parallel.py_func.__qualname__}
    assert len(names) == 2
    idx = {d._cache._cache_file._index_name for d in (_batch.collide_serial, _batch.collide_parallel)}
    assert len(idx) == 2


def test_single_plain_pair_takes_the_one_pair_path_with_identical_results():
    import prismbatch as pb
    from prismbatch.sampling import free_poses

    a, b = pb.Prism.regular(7, 1.0), pb.Prism.regular(5, 0.8)
    P = free_poses(300, np.random.default_rng(4), radius=0.8)
    col = pb.Collider(a, b)
    batch = col.collide(*P, contact=True, parallel=False)
    assert batch.hit.any() and not batch.hit.all()
    for i in range(300):
        one = col.collide(P[0][i], P[1][i], P[2][i], P[3][i], contact=True)
        pair = col.collide_pair(P[0][i], P[1][i], P[2][i], P[3][i])
        assert one.hit.shape == (1,) and one.contact.shape == (1, 3)
        assert one.hit[0] == batch.hit[i] == pair.hit and one.case[0] == batch.case[i] == pair.case
        np.testing.assert_array_equal(one.contact[0], batch.contact[i])
    bad = P[1][0] * 1.01
    with pytest.raises(ValueError, match="rot_a is not orthonormal"):
        col.collide(P[0][0], bad, P[2][0], P[3][0])
