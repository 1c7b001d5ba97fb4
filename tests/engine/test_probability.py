"""prismbatch.probability.collision_probability: known answers, plain against importance sampling,
rare events, interval coverage, extreme magnitudes, reproducibility and bad input; the pieces of
prismbatch.importance (design-point search, Hall's interval) against references written here."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy import integrate, stats
from scipy.spatial.transform import Rotation

import prismbatch as pb
from prismbatch._kernels.probability import poses_usable, sample_serial
from prismbatch._kernels.streams import ZIGGURAT
from prismbatch._kernels.vec3 import rodrigues_coefficients
from prismbatch.geometry import pair_scale_tolerance
from prismbatch.importance import DEFENSIVE, SPREAD, centres, design_points, design_starts, hall_interval
from prismbatch.probability import EXACT, IMPORTANCE, PLAIN, _Run, collision_probability

from reference import StreamReference

SQ = pb.Prism.regular(4, 1.0)  # unit-circumradius squares facing each other
DOWN = np.diag([1.0, -1.0, -1.0])
A5, B6 = pb.Prism.regular(5, 2.0), pb.Prism.regular(6, 2.5)


def phi_tail(x):
    return 0.5 * math.erfc(x / math.sqrt(2))


def facing_cov(sz, sxy=0.05, spin=0.1):
    """Noise of b: height sz, small sideways shifts, spin about the world z axis (through p_b).

    With the squares centred on one axis, sideways shifts below the side (sqrt 2, 28 sigma)
    and spins about z keep the end faces overlapping, so b hits a iff its end face reaches
    z <= 0: p = Phi(-height / sz) exactly (to 1e-100).
    """
    return np.diag([sxy**2, sxy**2, sz**2, 0.0, 0.0, spin**2])


def known(height, sz=0.1, **kw):
    r = collision_probability(SQ, SQ, np.zeros(3), DOWN, [0, 0, height], np.eye(3), facing_cov(sz), **kw)
    return r, phi_tail(height / sz)


def expm_reference(theta):
    """exp([theta]x) by its power series (no closed form shared with the kernel)."""
    K = np.array([[0, -theta[2], theta[1]], [theta[2], 0, -theta[0]], [-theta[1], theta[0], 0]])
    E, term = np.eye(3), np.eye(3)
    for j in range(1, 60):
        term = term @ K / j
        E = E + term
    return E


@pytest.mark.parametrize("k", [6, 12])
def test_sample_kernel_matches_reference(k):
    from prismbatch.sampling import random_rotations

    rng = np.random.default_rng(k)
    m, nq = 40, 3
    pos_a0, pos_b0 = rng.normal(size=(nq, 3)), rng.normal(size=(nq, 3))
    rot_a0, rot_b0 = random_rotations(nq, rng), random_rotations(nq, rng)
    L = 0.4 * rng.normal(size=(nq, k, k))  # angles up to a few radians
    q = rng.integers(0, nq, m)
    z = rng.normal(size=(m, k))
    z[:4] *= 1e-9  # tiny angles: no digits lost
    z[4] = 0.0
    out = np.empty((m, 3)), np.empty((m, 3, 3)), np.empty((m, 3)), np.empty((m, 3, 3))
    sample_serial(q, L, z, pos_a0, rot_a0, pos_b0, rot_b0, *out)
    for s in range(m):
        x = L[q[s]] @ z[s]
        np.testing.assert_allclose(out[2][s], pos_b0[q[s]] + x[:3], atol=1e-14)
        np.testing.assert_allclose(out[3][s], expm_reference(x[3:6]) @ rot_b0[q[s]], atol=1e-12)
        xa = x[6:] if k == 12 else np.zeros(6)
        np.testing.assert_allclose(out[0][s], pos_a0[q[s]] + xa[:3], atol=1e-14)
        np.testing.assert_allclose(out[1][s], expm_reference(xa[3:]) @ rot_a0[q[s]], atol=1e-12)


def test_pose_usable_against_a_plain_rule():
    """The sampling loop's branch-free check of a sampled pose against the rule written out: every
    coordinate within the range (NaN fails), every rotation entry finite."""
    rng = np.random.default_rng(5)
    lim = 1e100
    m = 400
    pos, rot = rng.normal(size=(m, 3)) * 1e99, rng.normal(size=(m, 3, 3))
    for s in range(0, m, 4):  # one odd value in each of three poses out of four
        pos[s, s % 3] = [lim, -lim, np.nextafter(lim, np.inf), np.inf, -np.inf, np.nan][s % 6]
        rot[s + 1, (s // 3) % 3, s % 3] = [np.inf, -np.inf, np.nan, 1e308, -1e308, 0.0][s % 6]
        pos[s + 2, 2], rot[s + 2, 0, 0] = -lim, 1e300
    out = np.empty(m, bool)
    poses_usable(pos, rot, lim, out)
    want = (np.abs(pos) <= lim).all(axis=1) & np.isfinite(rot).all(axis=(1, 2))
    assert np.array_equal(out, want)
    assert 0 < want.sum() < m  # both answers occur


def _series_reference(u, terms=40):
    """sin(t) / t and (1 - cos t) / t^2 of t = sqrt(u) from 40 terms of their series in exact rationals."""
    from fractions import Fraction

    a = b = Fraction(0)
    power = Fraction(1)
    for k in range(terms):
        a += (-1) ** k * power / math.factorial(2 * k + 1)
        b += (-1) ** k * power / math.factorial(2 * k + 2)
        power *= Fraction(u)
    return float(a), float(b)


@pytest.mark.slow  # the full suite; the fast set keeps a lighter test of the same path
def test_rodrigues_coefficients_to_an_ulp_or_two():
    """Both branches (the series up to t = 1, the half-angle sine beyond) against exact sums."""
    rng = np.random.default_rng(3)
    us = [0.0, 1e-300, 1e-20, 1e-8, 0.25, 1.0 - 1e-12, 1.0, np.nextafter(1.0, 2.0), 1.5, 4.0]
    us += list(rng.uniform(0, 1, 300)) + list(rng.uniform(1, 4, 100)) + list(10 ** rng.uniform(-20, 0, 100))
    for u in us:
        got, want = rodrigues_coefficients(float(u)), _series_reference(float(u))
        np.testing.assert_allclose(got, want, rtol=4.5e-16, atol=0)


def _reference_sample(key, u, L, active, mix, poses):
    """One sample of the sampling loop in plain Python: ``(pos_a, rot_a, pos_b, rot_b, log weight)``."""
    k = L.shape[1]
    gen = StreamReference(key, u)
    z = np.array([gen.normal(ZIGGURAT) if active[c] else 0.0 for c in range(k)])
    lw = 0.0
    if mix is not None:
        mu, lpi = mix
        w = gen.uniform()
        if w >= DEFENSIVE:
            j = int(np.searchsorted(DEFENSIVE + (1 - DEFENSIVE) * np.cumsum(np.exp(lpi))[:-1], w, side="right"))
            z = np.where(active, mu[j] + SPREAD * z, z)
        za = z * active
        d2 = ((za[None] - mu) ** 2).sum(1)
        comp = lpi - 0.5 * d2 / SPREAD**2 - active.sum() * math.log(SPREAD)
        lr = np.logaddexp.reduce(comp) + 0.5 * (za @ za)
        lw = -np.logaddexp(math.log(DEFENSIVE), math.log1p(-DEFENSIVE) + lr)
    x = L @ z
    pa, ra, pb, rb = poses
    xa = x[6:] if k == 12 else np.zeros(6)
    return pa + xa[:3], expm_reference(xa[3:]) @ ra, pb + x[:3], expm_reference(x[3:6]) @ rb, lw


@pytest.mark.parametrize("k, far", [(6, 0.0), (12, 0.0), (6, 34.0), (6, 40.0)])
def test_count_kernel_matches_plain_reference(k, far):
    """The compiled sampling loop (draws, mixture, weights, poses, contact) against the same
    draws made in plain Python, posed by the power-series exponential and tested by collide.
    ``far``: query 0 lies out of reach of its nominal noise, and one centre ``far`` standard
    deviations out brings it into contact; those hits' weights straddle exp(-600), where the
    loop leaves linear weights for their logarithms (34), or all lie below it (40)."""
    rng = np.random.default_rng(40 + k)
    A, B = pb.Prism.regular(5, 1.0), pb.Prism.regular(7, 0.8)
    col = pb.Collider(A, B)
    nq = 2
    pos_b = np.array([[0, 0, 0.05 if far else 0.15], [0.3, 0, 0.25]])
    poses = (np.zeros((nq, 3)), np.stack([DOWN] * nq), pos_b, np.stack([np.eye(3)] * nq))
    L = 0.12 * np.eye(k)[None] + 0.02 * rng.normal(size=(nq, k, k))
    if far:  # lowered by some 0.003 a standard deviation
        L[0] *= 0.003 / 0.12
    L[:, :, 4] = 0.0  # a noise component that moves nothing: not drawn
    run = _Run(col, poses, L, 1.96, 0.1, False)
    mu = rng.normal(size=(2, k)) * run.active[0]
    if far:
        mu[0] = -far * np.eye(k)[2]
    lpi = np.log([0.3, 0.7])
    how = np.array([IMPORTANCE, PLAIN])
    mixtures = run._packed({0: (mu, lpi, run.active[0])}, how)
    keys = np.array([2**64 - 5, 12345], dtype=np.uint64)
    query, start, count = np.array([0, 1, 0]), np.array([0, 10, 1000]), np.array([150, 200, 150])
    hits, shift, sums = run._count(query, start, count, keys, mixtures)
    for t in range(3):
        q = query[t]
        lws = []
        for u in range(start[t], start[t] + count[t]):
            mix = (mu, lpi) if q == 0 else None
            *p, lw = _reference_sample(keys[q], u, L[q], run.active[q], mix, [x[q] for x in poses])
            if col.collide(*p).hit[0]:
                lws.append(lw)
        lws = np.array(lws)
        assert hits[t] == len(lws) > 10
        assert len(lws) < count[t]
        np.testing.assert_allclose(shift[t], lws.max(), rtol=1e-13)
        want = [np.exp(p * (lws - shift[t])).sum() for p in (1, 2, 3)]
        np.testing.assert_allclose(sums[t], want, rtol=1e-12)
        if q == 1:
            assert shift[t] == 0.0 and sums[t].tolist() == [len(lws)] * 3
        elif far == 34.0:
            assert (lws < -600).sum() > 3 and (lws > -600).sum() > 3
        elif far == 40.0:
            assert lws.max() < -600


@pytest.mark.parametrize("height, method", [(0.1, PLAIN), (0.3719, IMPORTANCE), (0.47534, IMPORTANCE)])
def test_known_answer(height, method):
    r, p = known(height, seed=5)
    assert r.method[0] == method and r.converged[0]
    half = (r.high[0] - r.low[0]) / 2
    assert half <= 0.1 * r.p[0] * (1 + 1e-12)
    assert abs(r.p[0] - p) < 2 * half  # one seed: a 95 % interval may miss; twice its width may not
    if p < 1e-5:  # p = 1e-6: far fewer than 10^8 samples
        assert r.samples[0] < 20_000


def test_plain_reference_agrees():
    """Plain sampling written here (numpy draws, pb.collide) against the estimator."""
    height, sz = 0.15, 0.1
    rng = np.random.default_rng(1)
    n = 40_000
    x = rng.multivariate_normal(np.zeros(6), facing_cov(sz), size=n)
    pos = np.array([0, 0, height]) + x[:, :3]
    c, s = np.cos(x[:, 5]), np.sin(x[:, 5])
    rot = np.zeros((n, 3, 3))
    rot[:, 0, 0], rot[:, 0, 1], rot[:, 1, 0], rot[:, 1, 1], rot[:, 2, 2] = c, -s, s, c, 1.0
    hits = pb.collide(SQ, SQ, np.zeros(3), DOWN, pos, rot).hit.mean()
    r, p = known(height, seed=2, rel_error=0.03, method="plain")
    se_ref = math.sqrt(p * (1 - p) / n)
    se = (r.high[0] - r.low[0]) / (2 * 1.96)
    assert abs(hits - p) < 4 * se_ref and abs(r.p[0] - hits) < 4 * math.hypot(se, se_ref)


def test_plain_and_importance_agree_with_rotation_noise():
    rng = np.random.default_rng(0)
    from prismbatch.sampling import tilted_up

    R = tilted_up(3, 0.3, rng)[:2]
    pos = np.array([[1.0, 0.5, 0.6], [3.0, 1.0, 0.3]])
    cov = np.diag([0.1, 0.1, 0.1, 0.04, 0.04, 0.04]) ** 2
    kw = dict(cov_a=cov, rel_error=0.05, seed=4, max_samples=400_000)
    plain = collision_probability(A5, B6, np.zeros(3), DOWN, pos, R, cov, method="plain", **kw)
    imp = collision_probability(A5, B6, np.zeros(3), DOWN, pos, R, cov, method="importance", **kw)
    assert (plain.method == PLAIN).all() and (imp.method == IMPORTANCE).all()
    assert plain.converged.all() and imp.converged.all()
    assert (plain.p > 0.005).all()  # moderate: plain sampling is a fair judge
    se = lambda r: (r.high - r.low) / (2 * 1.96)  # noqa: E731
    assert (np.abs(plain.p - imp.p) < 4 * np.hypot(se(plain), se(imp))).all()


def test_interval_coverage_small():
    """20 seeds each of p = 1e-2 (plain) and p = 1e-4 (importance): the 95 % intervals cover."""
    cover = 0
    for height in (0.23263, 0.3719):
        p = phi_tail(height / 0.1)
        for seed in range(20):
            r, _ = known(height, seed=seed, rel_error=0.2)
            cover += r.low[0] <= p <= r.high[0]
    assert cover >= 36


def test_exact_cases_terminate_cheaply():
    # no noise: the nominal answer
    r = collision_probability(SQ, SQ, np.zeros(3), DOWN, [[0, 0, 0.5], [0, 0, -0.5]], np.eye(3), np.zeros((6, 6)))
    assert r.p.tolist() == [0.0, 1.0] and (r.method == EXACT).all() and r.samples.tolist() == [0, 0]
    # far away, translation noise only: provably negligible, no sample drawn
    r = collision_probability(SQ, SQ, np.zeros(3), DOWN, [0, 0, 50.0], np.eye(3), np.diag([0.01] * 3 + [0] * 3))
    assert r.p[0] == 0 and r.method[0] == EXACT and r.samples[0] == 0 and r.converged[0]
    assert 0 < r.high[0] < 1e-300  # Phi(-500) underflows: rounded up, it stays an upper bound
    # far away with rotation noise: importance sampling, p underflows but the relative error is met
    r = collision_probability(SQ, SQ, np.zeros(3), DOWN, [0, 0, 3.0], np.eye(3), np.eye(6) * 1e-2, seed=0)
    assert r.method[0] == IMPORTANCE and r.converged[0] and r.p[0] < 1e-50 and r.samples[0] <= 300_000
    # deep inside: all hits, converged in the first round after the pilot
    r = collision_probability(SQ, SQ, np.zeros(3), DOWN, [0, 0, -5.0], np.eye(3), np.eye(6) * 1e-2, seed=0)
    assert r.p[0] == 1.0 and r.converged[0] and r.samples[0] <= 2048 and r.low[0] > 0.99


def test_singular_covariance_and_budget():
    cov = np.zeros((6, 6))
    cov[2, 2] = 0.01  # height only: rank one
    r = collision_probability(SQ, SQ, np.zeros(3), DOWN, [0, 0, 0.2], np.eye(3), cov, seed=3)
    assert r.converged[0] and abs(r.p[0] - phi_tail(2.0)) < 0.15 * phi_tail(2.0)
    r = collision_probability(SQ, SQ, np.zeros(3), DOWN, [0, 0, 0.3], np.eye(3), cov, seed=3, max_samples=500)
    assert r.samples[0] == 500 and not r.converged[0]


def test_reproducible_and_independent_of_grouping():
    heights = np.array([0.1, 0.3, 0.45, 0.05])
    pos = np.column_stack([np.zeros((4, 2)), heights])
    covs = np.stack([facing_cov(s) for s in (0.1, 0.1, 0.1, 0.2)])
    args = (SQ, SQ, np.zeros(3), DOWN, pos, np.eye(3), covs)
    r1 = collision_probability(*args, seed=11)
    r2 = collision_probability(*args, seed=11)
    for k, v in r1.columns().items():
        np.testing.assert_array_equal(v, r2.columns()[k])
    part = collision_probability(SQ, SQ, np.zeros(3), DOWN, pos[2:], np.eye(3), covs[2:], seed=11, query_index=[2, 3])
    for k, v in part.columns().items():
        np.testing.assert_array_equal(v, r1.columns()[k][2:])
    r3 = collision_probability(*args, seed=12)
    assert not np.array_equal(r1.p, r3.p)
    r4 = collision_probability(*args)
    r5 = collision_probability(*args, seed=r4.seed)
    np.testing.assert_array_equal(r4.p, r5.p)
    threads = collision_probability(*args, seed=11, parallel=True)  # samples shared out over threads
    for k, v in r1.columns().items():
        np.testing.assert_array_equal(v, threads.columns()[k])


@pytest.mark.parametrize(
    "var",
    [[1e220, 1e220, 1e220, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.7e308, 0.0, 0.0]],
    ids=["positions beyond the range", "rotation vector overflowing"],
)
@pytest.mark.parametrize("method", ["plain", "importance", "auto"])
def test_noise_beyond_the_coordinate_range_is_an_error(var, method):
    # the second: |dtheta|^2 overflows for |z| > 1.03, and the turn comes out NaN. Importance sampling
    # meets it in its search for the likeliest collision, before any sample: the same message, no warning.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError, match=r"query 0: a sampled position lies beyond .* pose noise is too large"):
            collision_probability(SQ, SQ, np.zeros(3), DOWN, [0, 0, 0.2], np.eye(3), np.diag(var), method=method)


def test_collider_method_matches_function():
    col = pb.Collider(SQ, SQ)
    a = col.collision_probability(np.zeros(3), DOWN, [0, 0, 0.2], np.eye(3), facing_cov(0.1), seed=1)
    b, _ = known(0.2, seed=1)
    np.testing.assert_array_equal(a.p, b.p)


@pytest.mark.parametrize(
    "kw, err, match",
    [
        (dict(cov_b=np.eye(5)), ValueError, "cov_b has shape"),
        (dict(cov_b=np.eye(6) + np.triu(np.ones((6, 6)), 1)), ValueError, "cov_b is not symmetric"),
        (dict(cov_b=-np.eye(6)), ValueError, "cov_b is not positive semidefinite"),
        (dict(cov_b=np.full((6, 6), np.nan)), ValueError, "cov_b has non-finite"),
        (dict(cov_b=np.eye(6), cov_a=np.diag([1.0, 1, 1, 1, 1, -1])), ValueError, "cov_a is not positive"),
        (dict(cov_b=np.stack([np.eye(6), -np.eye(6)])), ValueError, r"cov_b\[1\]"),
        (dict(cov_b=np.eye(6).astype(bool)), TypeError, "cov_b"),
        (dict(cov_b=np.eye(6), rel_error=0), ValueError, "rel_error"),
        (dict(cov_b=np.eye(6), confidence=1.0), ValueError, "confidence"),
        (dict(cov_b=np.eye(6), max_samples=0), ValueError, "max_samples"),
        (dict(cov_b=np.eye(6), max_samples=1e4), TypeError, "max_samples must be an integer"),
        (dict(cov_b=np.eye(6), method="fast"), ValueError, "method"),
        (dict(cov_b=np.eye(6), seed=-1), ValueError, "seed"),
        (dict(cov_b=np.eye(6), seed=True), TypeError, "seed must be an integer"),
        (dict(cov_b=np.eye(6), query_index=[0, 1, 2]), ValueError, "query_index"),
        (dict(cov_b=np.eye(6), query_index=np.array([0, 2**64 - 1], np.uint64)), ValueError, "query_index"),
        (dict(cov_b=np.eye(6), confidence=1 - 1e-16), ValueError, "confidence must be at most"),
        (dict(cov_b=np.stack([np.eye(6)] * 3)), ValueError, "cov_b has 3"),
    ],
)
def test_bad_input(kw, err, match):
    cov_b = kw.pop("cov_b")
    with pytest.raises(err, match=match):
        collision_probability(SQ, SQ, np.zeros(3), DOWN, [[0, 0, 1.0], [0, 0, 2.0]], np.eye(3), cov_b, **kw)


def test_empty_batch_and_a_tiny_rel_error():
    """No queries give empty results (as collide and distance do); a rel_error far below what any budget
    reaches samples up to max_samples and reports not converged (its sample count overflowed to inf)."""
    r = collision_probability(SQ, SQ, np.zeros((0, 3)), DOWN, [0, 0, 1.0], np.eye(3), np.eye(6) * 1e-4, seed=0)
    assert r.p.shape == r.samples.shape == (0,)
    cov = np.diag([0, 0, 0.01, 0, 0, 0])
    r = collision_probability(SQ, SQ, np.zeros(3), DOWN, [0, 0, 0.2], np.eye(3), cov, seed=1, rel_error=1e-300,
                              max_samples=20000)  # fmt: skip
    assert r.samples[0] == 20000 and not r.converged[0] and 0 < r.p[0] < 0.1


def test_prism_sets_are_rejected():
    s = pb.PrismSet([SQ.xy, SQ.xy])
    with pytest.raises(TypeError, match="PrismSet"):
        collision_probability(s, SQ, np.zeros(3), DOWN, [[0, 0, 1.0], [0, 0, 2.0]], np.eye(3), np.eye(6))


# --- importance sampling's pieces ----------------------------------------------------------------


def test_hall_interval_covers_skewed_means():
    """Means of zero-inflated lognormal samples (like importance weights: few hits, skewed
    weights): the normal interval undercovers, Hall's is near its level; zero skew is normal."""
    rng = np.random.default_rng(0)
    reps, n, q = 2000, 500, 0.05
    y = (rng.random((reps, n)) < q) * rng.lognormal(0.0, 1.0, (reps, n))
    mu = q * math.exp(0.5)
    mean, m2 = y.mean(1), y.var(1)
    se, skew = np.sqrt(m2 / (n - 1)), ((y - mean[:, None]) ** 3).mean(1) / m2**1.5 / math.sqrt(n)
    ends = np.array([hall_interval(*a, 1.96) for a in zip(mean, se, skew)])
    hall = np.mean((ends[:, 0] <= mu) & (mu <= ends[:, 1]))
    normal = np.mean(np.abs(mean - mu) <= 1.96 * se)
    assert normal < 0.91 and 0.935 <= hall <= 0.965
    assert np.all(ends[:, 1] - mean > mean - ends[:, 0])  # right-skewed samples: the upper side is longer
    np.testing.assert_allclose(hall_interval(2.0, 0.5, 0.0, 1.96), (2.0 - 0.98, 2.0 + 0.98))


def _rx(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]])


@pytest.mark.parametrize("tilt", [0.0, 0.15])
def test_design_search_finds_every_corner(tilt):
    """Facing squares with isotropic noise have one likeliest collision per corner (a tilt
    lowering it); the searches reach all four, and on b tilted by 1.5 standard deviations
    the lowest corner and its two neighbours (the far corner is 1e-4 times less likely than
    its neighbours). The distance and its gradient come from pb.distance, scipy's rotations
    and central differences here, not from the estimator."""
    sigma, height, h = 0.1, 0.5, 1e-6

    def dist(z):
        x = sigma * z
        rot = Rotation.from_rotvec(x[:, 3:]).as_matrix() @ _rx(tilt)
        return pb.distance(SQ, SQ, np.zeros(3), DOWN, np.array([0, 0, height]) + x[:, :3], rot).distance

    def linearise(z):
        m = len(z)
        steps = np.concatenate([z] + [z + s * h * e for e in np.eye(6) for s in (1, -1)])
        d = dist(steps).reshape(13, m)
        return d[0], ((d[1::2] - d[2::2]) / (2 * h)).T

    active = np.ones(6, bool)
    d0, g0 = linearise(np.zeros((1, 6)))
    reach = float(np.clip(d0[0] / np.linalg.norm(g0), 1, 5))  # as the estimator starts
    z, miss = design_points(linearise, design_starts(active, np.random.default_rng(3), reach))
    mu, lw = centres(z, miss, active)
    # corners: tilt (z_4, z_5) along an axis; b's corner (0, -1) is the lowest once tilted
    corner = (np.abs(mu[:, 3:5]).max(axis=1) > 1.0) & (np.linalg.norm(mu, axis=1) < 4.5)
    tilts = {tuple(np.sign(np.round(m[3:5], 1)).astype(int)) for m in mu[corner]}
    if tilt == 0:
        # exact: dz + tilt lowering a corner at radius 1: 0.5 = 0.1 (|z_3| + |z_tilt|) at best
        np.testing.assert_allclose(np.linalg.norm(mu[corner], axis=1), 5 / math.sqrt(2), rtol=0.01)
        assert tilts == {(1, 0), (-1, 0), (0, 1), (0, -1)}
        np.testing.assert_allclose(np.exp(lw[corner]), np.exp(lw[corner]).mean(), rtol=0.01)  # equally likely
    else:
        assert len(tilts) == 3 and np.argmax(lw) in np.flatnonzero(corner)


# --- extreme magnitudes -------------------------------------------------------------------------


def within(r, p, i=0):
    """One run's interval against the answer: a 95 % interval may miss; twice its width may not."""
    half = (r.high[i] - r.low[i]) / 2
    return r.converged[i] and abs(r.p[i] - p) < 2 * half


@pytest.mark.parametrize("size, far", [(1e-6, 1e3), (1e-6, 1e6), (1e4, 1e6), (1e4, 0.0), (1e-99, 0.0), (1e98, 0.0)])
@pytest.mark.parametrize("level", [0.1, 0.3719, 0.47534])
def test_known_answer_at_extreme_scales(size, far, level):
    """The facing squares scaled by ``size`` and moved ``far`` from the origin: p = Phi(-height / sz)
    with the height the poses really hold (rounding at 1e6 moves it by ~1e-10)."""
    S = pb.Prism.regular(4, size)
    o = far * np.array([0.6, -0.48, 0.64])
    D = np.diag([size] * 3 + [1.0] * 3)
    pb_ = o + [0, 0, level * size]
    r = collision_probability(S, S, o, DOWN, pb_, np.eye(3), D @ facing_cov(0.1) @ D, seed=4)
    assert r.method[0] == (PLAIN if level < 0.2 else IMPORTANCE)
    assert within(r, phi_tail((pb_[2] - o[2]) / (0.1 * size)))


def _iso(size):
    D = np.diag([size] * 3 + [1.0] * 3)
    return D @ (np.eye(6) * 1e-2) @ D


_UNIT = {}


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(log_size=st.floats(-6, 4), log_far=st.floats(3, 6), seed=st.integers(0, 3))
def test_scale_and_offset_invariance_with_rotation_noise(log_size, log_far, seed):
    """Scaling the bodies, their distance and the translation noise by one factor, and moving
    them far from the origin, leaves p alone (rotations are about each body's position)."""
    if seed not in _UNIT:
        _UNIT[seed] = collision_probability(SQ, SQ, np.zeros(3), DOWN, [0, 0, 0.45], np.eye(3), _iso(1.0), seed=seed)
    ref, s = _UNIT[seed], 10.0**log_size
    S, o = pb.Prism.regular(4, s), 10.0**log_far * np.array([-0.36, 0.48, 0.8])
    r = collision_probability(S, S, o, DOWN, o + [0, 0, 0.45 * s], np.eye(3), _iso(s), seed=seed)
    se = lambda r: (r.high[0] - r.low[0]) / (2 * 1.96)  # noqa: E731
    assert r.method[0] == ref.method[0] == IMPORTANCE and r.converged[0]
    assert abs(r.p[0] - ref.p[0]) < 4 * math.hypot(se(r), se(ref))


def test_noise_large_against_the_bodies():
    """Sideways noise 3 to 10 times the squares' size: p = Phi(-height / sz) P(|dx| + |dy| <= 2)
    (the footprints, diamonds of circumradius 1, overlap iff the shift is in their Minkowski sum)."""

    def overlap(s):
        f = lambda x: stats.norm.pdf(x, scale=s) * (2 * stats.norm.cdf((2 - abs(x)) / s) - 1)  # noqa: E731
        return integrate.quad(f, -2, 2, points=[0.0])[0]

    for sxy, sz, height, method in [(3.0, 1.0, 2.5, IMPORTANCE), (10.0, 10.0, 5.0, PLAIN)]:
        cov = np.diag([sxy**2, sxy**2, sz**2, 0, 0, 0])
        r = collision_probability(SQ, SQ, np.zeros(3), DOWN, [0, 0, height], np.eye(3), cov, seed=1)
        assert r.method[0] == method and within(r, phi_tail(height / sz) * overlap(sxy))


def test_large_rotation_noise_against_plain_reference():
    """Rotations of a radian or more (the body may turn over): plain sampling written here."""
    cov = np.diag([0.3**2] * 3 + [1.5**2] * 3)
    rng = np.random.default_rng(7)
    n = 40_000
    x = rng.multivariate_normal(np.zeros(6), cov, size=n)
    rot = Rotation.from_rotvec(x[:, 3:]).as_matrix()
    hits = pb.collide(A5, B6, np.zeros(3), DOWN, np.array([0.5, 0, 3.0]) + x[:, :3], rot).hit.mean()
    r = collision_probability(A5, B6, np.zeros(3), DOWN, [0.5, 0, 3.0], np.eye(3), cov, seed=3, rel_error=0.03)
    se_ref, se = math.sqrt(hits * (1 - hits) / n), (r.high[0] - r.low[0]) / (2 * 1.96)
    assert 0.2 < hits < 0.5 and abs(r.p[0] - hits) < 4 * math.hypot(se, se_ref)


def test_noise_small_against_the_bodies_and_the_touching_band():
    """Height noise 1e-8 of the squares' size: collide's touching band (rtol 1e-9 of the scene
    size) counts as contact and moves the boundary by a fifth of sz; with rtol 1e-15 the answer
    is Phi(-height / sz) again."""
    sz = 1e-8
    height = 3.719 * sz
    cov = np.diag([(0.5 * sz) ** 2, (0.5 * sz) ** 2, sz**2, 0, 0, 0.1**2])
    args = (SQ, SQ, np.zeros(3), DOWN, [0, 0, height], np.eye(3), cov)
    r = collision_probability(*args, seed=1, rtol=1e-15)
    assert r.method[0] == IMPORTANCE and within(r, phi_tail(height / sz))
    _, tol = pair_scale_tolerance(SQ, SQ, np.zeros((1, 3)), DOWN[None], np.array([[0, 0, height]]), np.eye(3)[None])
    assert tol[0] > 0.1 * sz
    r = collision_probability(*args, seed=1)
    assert r.low[0] <= phi_tail((height - tol[0]) / sz) * 1.2 and r.high[0] >= phi_tail(height / sz)


def test_probabilities_near_zero_and_one():
    # far below the smallest float64 with rotation noise: reported 0, converged, a positive high
    r, _ = known(5.0, seed=1)  # Phi(-50) ~ 1e-545
    assert r.method[0] == IMPORTANCE and r.converged[0] and r.p[0] == 0.0 and 0 < r.high[0] < 1e-300
    r, p = known(3.0, seed=1)  # Phi(-30) ~ 5e-198: still a float, and estimated to rel_error
    assert r.method[0] == IMPORTANCE and within(r, p) and r.samples[0] < 100_000
    r, p = known(-0.3, seed=1)  # Phi(3) ~ 0.99865
    assert r.method[0] == PLAIN and within(r, p) and r.high[0] <= 1.0
    r, p = known(-0.65, seed=1)  # 1 - 1e-10: every sample collides
    assert r.p[0] == 1.0 and r.high[0] == 1.0 and r.low[0] > 0.99 and r.converged[0]


def test_float32_collider_samples_the_same_streams():
    """A float32 Collider draws the same samples (its poses rounded to float32): its hits differ
    from float64's only for samples within float32 rounding of contact."""
    cov = np.diag([0.05**2, 0.05**2, 0.1**2, 0.01, 0.01, 0.1**2])
    kw = dict(cov_a=0.5 * cov, seed=3, method="plain", rel_error=0.02)
    r64, r32 = (
        pb.Collider(SQ, SQ, dtype=dt).collision_probability(np.zeros(3), DOWN, [0, 0, 0.1], np.eye(3), cov, **kw)
        for dt in (np.float64, np.float32)
    )
    assert r64.samples[0] == r32.samples[0] > 1000
    assert r32.hits[0] != 0 and abs(int(r32.hits[0]) - int(r64.hits[0])) <= 2
