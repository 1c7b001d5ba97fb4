"""prismbatch.probability.collision_probability: known answers, plain against importance sampling,
rare events, interval coverage, reproducibility and bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest

import prismbatch as pb
from prismbatch._kernels.probability import sample_serial
from prismbatch.probability import EXACT, IMPORTANCE, PLAIN, collision_probability

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
    assert r.p[0] == 0 and r.method[0] == EXACT and r.samples[0] == 0 and r.converged[0] and r.high[0] < 1e-300
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
        (dict(cov_b=np.eye(6), method="fast"), ValueError, "method"),
        (dict(cov_b=np.eye(6), seed=-1), ValueError, "seed"),
        (dict(cov_b=np.eye(6), query_index=[0, 1, 2]), ValueError, "query_index"),
    ],
)
def test_bad_input(kw, err, match):
    cov_b = kw.pop("cov_b")
    with pytest.raises(err, match=match):
        collision_probability(SQ, SQ, np.zeros(3), DOWN, [[0, 0, 1.0], [0, 0, 2.0]], np.eye(3), cov_b, **kw)


def test_prism_sets_are_rejected():
    s = pb.PrismSet([SQ.xy, SQ.xy])
    with pytest.raises(TypeError, match="PrismSet"):
        collision_probability(s, SQ, np.zeros(3), DOWN, [[0, 0, 1.0], [0, 0, 2.0]], np.eye(3), np.eye(6))
