"""The compiled loops' random numbers (``prismbatch._kernels.streams``): bit for bit against a
plain-Python generator, the ziggurat's tables against their defining areas, and the draws'
distribution against the exact normal law; the stream keys against NumPy's SeedSequence."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import integrate, stats

from prismbatch._kernels.streams import ZIGGURAT, spawned_keys, standard_normals

from reference import StreamReference


@pytest.mark.parametrize("key, start", [(0, 0), (2**64 - 1, 7), (0x1234_5678_9ABC_DEF0, 2**40), (99, 2**63 - 300)])
def test_draws_match_the_plain_generator(key, start):
    got = standard_normals(key, start, 300, 6)
    for s in range(300):
        ref = StreamReference(key, start + s)
        want = [ref.normal(ZIGGURAT) for _ in range(6)]
        assert got[s].tolist() == want, f"sample {start + s}"


def test_ziggurat_tables_have_equal_areas():
    """Layer i (1..255) is the box [0, x_i] x [f(x_i), f(x_{i-1})], f(x_0) = 1, of area v; the base
    strip is r f(r) plus the tail beyond r, also v; the acceptance bounds are x_{i-1} / x_i."""
    k, w, f, r = ZIGGURAT
    x = w * 2.0**52
    g = lambda t: math.exp(-0.5 * t * t)  # noqa: E731
    np.testing.assert_allclose(f, [g(t) for t in x[:1] * 0] + [g(t) for t in x[1:]], rtol=1e-15)
    tail = integrate.quad(g, r, np.inf, epsabs=0, epsrel=1e-13)[0]
    v = r * g(r) + tail
    areas = [x[1] * (1.0 - f[1])] + [x[i] * (f[i - 1] - f[i]) for i in range(2, 256)]
    np.testing.assert_allclose(areas, v, rtol=1e-9)
    assert x[255] == r and x[0] * g(r) == pytest.approx(v, rel=1e-9)
    assert np.all(np.diff(x[1:]) > 0)
    want_k = [int(r / x[0] * 2.0**52), 0] + [int(x[i - 1] / x[i] * 2.0**52) for i in range(2, 256)]
    assert np.abs(k.astype(np.int64) - np.array(want_k, dtype=np.int64)).max() <= 1


def test_normal_distribution():
    z = standard_normals(2024, 0, 500_000, 8)
    x = z.ravel()
    # 200 equiprobable bins and the tail beyond the ziggurat's base (|x| > r), which has its own code
    edges = stats.norm.ppf(np.linspace(0, 1, 201))
    counts = np.histogram(x, edges)[0]
    assert stats.chisquare(counts).pvalue > 1e-4
    r = ZIGGURAT[3]
    for c in (r, 4.0, 4.5):
        expect = 2 * stats.norm.sf(c) * x.size
        seen = np.sum(np.abs(x) > c)
        assert abs(seen - expect) < 5 * math.sqrt(expect), (c, seen, expect)
    assert stats.kstest(x, "norm").pvalue > 1e-4
    # components of a sample and consecutive samples uncorrelated
    se = 1 / math.sqrt(len(z))
    c = np.corrcoef(z.T)
    assert np.abs(c - np.eye(8)).max() < 5 * se
    assert abs(np.corrcoef(z[:-1, 0], z[1:, 0])[0, 1]) < 5 * se
    # streams of neighbouring keys are unrelated
    y = standard_normals(2025, 0, 500_000, 8)
    assert abs(np.corrcoef(x, y.ravel())[0, 1]) < 5 / math.sqrt(x.size)


_KEY = st.one_of(st.integers(0, 2**32 - 1), st.integers(2**32 - 2, 2**32 + 2), st.integers(0, 2**63 - 1))


@settings(max_examples=60, deadline=None)
@given(
    seed=st.one_of(st.integers(0, 2**32), st.integers(0, 2**128 + 1), st.integers(2**127, 2**300)),
    keys=st.lists(_KEY, min_size=0, max_size=12),
    child=st.sampled_from([0, 1, 2, 2**32 - 1]),
)
def test_spawned_keys_are_seedsequences(seed, keys, child):
    """One key or two 32-bit words, seeds of one to ten words (the pool holds four)."""
    want = [np.random.SeedSequence(seed, spawn_key=(k, child)).generate_state(1, np.uint64)[0] for k in keys]
    got = spawned_keys(seed, np.array(keys, dtype=np.int64), child)
    assert got.dtype == np.uint64 and got.tolist() == [int(w) for w in want]
