"""Probability of collision under Gaussian pose noise: :func:`collision_probability`.

Noise model (world frame): ``p = p0 + dp``, ``R = exp([dtheta]x) R0`` with ``x = (dp, dtheta)``
drawn from ``N(0, cov)`` (6x6) for b and, independently, for a when ``cov_a`` is given. Each
covariance is factored as ``cov = L L^T`` through the eigen-decomposition of its correlation
matrix (eigenvalues below 1e-12 of the largest dropped; translation and rotation have different
units, and a cut relative to the largest variance would drop a 1e-6 body's translations), so
singular and rotation-free covariances need no special case; samples are ``x = L z`` with ``z``
standard normal (6 or 12 components). Contact does not change when both bodies move together,
so poses are sampled about a's nominal position: far from the world origin (1e6) collide's
rounding band (4 eps ``|position|``) would otherwise count as contact for tiny bodies. What
collide counts as contact, touching within its tolerance ``atol + rtol S`` (S the pair's scale)
included, is what ``p`` is the probability of: where the noise is within a few orders of that
tolerance, pass a smaller ``rtol``.

Estimators, per query:

- **plain** Monte Carlo: the fraction of sampled poses that :meth:`Collider.collide` reports as
  hits, with a Wilson score interval.
- **importance** sampling for rare events (:mod:`prismbatch.importance`). The signed distance is
  linearised in ``z`` through the witness points (moving b by ``dp`` changes it by ``n . dp``,
  turning b by ``dtheta`` about ``p_b`` by ``dtheta . ((point_b - p_b) x n)``, taken through the
  left Jacobian of SO(3); a's noise enters with the opposite sign), and damped Hasofer-Lind
  steps with fresh distance calls move to the most likely colliding points ``mu_j`` of the
  noise, searched from the nominal pose, from both directions of every noise axis (as far out as
  the linear estimate of the distance to the boundary) and from two random antithetic pairs:
  facing parallel faces have one per corner that a tilt lowers, and random starts alone missed
  one of a square's four in 45 % of runs. The proposal is the defensive mixture
  ``0.1 N(0, I) + 0.9 sum_j pi_j N(mu_j, 1.2^2 I)`` (components of ``z`` that move nothing drawn
  from ``N(0, 1)`` throughout): its weights ``phi(z) / q(z) <= 10`` are bounded, so a poor
  centre costs samples, never correctness, and the spread reaches the parts of a curved
  collision region between the centres. The weighted mean is skewed (low estimates come with
  low variance estimates), so the interval is Hall's skewness-corrected one
  (:func:`~prismbatch.importance.hall_interval`), not the normal one. Weights are kept as
  logarithms with a running shift, so probabilities far below 1e-300 still stop on their
  relative error (and are then reported as 0.0, their float64 value, with ``high`` rounded up
  to the smallest float64 where it underflows).
- **exact**: no noise at all (the nominal answer, 0 or 1), or noise in translation only that
  provably cannot reach contact: the signed distance is convex in a translation of either body,
  so ``p <= Phi(-(d - tol) / |g|)`` with ``d`` the nominal distance, ``tol`` collide's
  tolerance and ``g`` the distance's gradient in ``z``; when that bound is below
  :data:`NEGLIGIBLE`, ``p`` is reported as 0 with ``high`` the bound.

``method="auto"`` uses importance sampling where the nominal pose is separated and the linear
estimate ``Phi(-|mu|)`` is below :data:`IMPORTANCE_BELOW`, plain Monte Carlo elsewhere.

Samples are drawn in rounds, every round of every query drawn, posed and tested for contact
together in one compiled loop that stores nothing per sample (it runs at about the rate of
``collide`` on ready-made poses; the draws are SplitMix64 streams and a ziggurat,
:mod:`prismbatch._kernels.streams`). A pilot (:data:`FIRST_ROUND` samples, doubled
until one collides) sizes the estimate with its normal interval, and the estimate is then formed
from fresh samples only: :data:`PILOT_MARGIN` times as many as the pilot's relative error says
are needed, then more rounds (at most doubling) until the relative error is met, the interval's
upper end falls below :data:`NEGLIGIBLE` (p is then reported as 0, its float64 value, and counts
as converged) or the budget is spent. Stopping on the very samples that are averaged favours low
estimates with low variances; fresh samples after the pilot avoid most of it. Coverage of the
95 % intervals over 20 000 runs per case (``docs/methods/probability.md``): 94.9-95.3 % on twelve
cases (the known answers at p = 1e-2, 1e-4, 1e-6, isotropic rotation and translation noise on
facing squares, triangles and 12-gons, tilted poses, noise on both bodies), 95.10 % +- 0.09 %
pooled; with random starts, spread 1.5 and the normal interval it was 92.9-95.2 % (2000 runs per
case), mean 94.3 %, with 2.2-4.1 times the samples. Query ``i`` draws from its own streams, keyed by
``SeedSequence(seed, spawn_key=(query_index[i],))`` (sample ``u`` of a query from its own
generator, seeded by the query's key and ``u``), so its result does not depend on the other
queries, on how they are grouped, chunked or spread over threads, or on where they run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from statistics import NormalDist

import numpy as np

from ._kernels.batch import use_parallel
from ._kernels.jit import first_call
from ._kernels.probability import count_parallel, count_serial, poses_usable, sample_parallel, sample_serial
from ._kernels.streams import ZIGGURAT, spawned_keys
from .checks import check_flag, integer, real_scalar
from .config import SUPPORTED_RANGE
from .covariance import noise_factor, rotation_free
from .importance import DEFENSIVE, SPREAD, Tally, centres, design_points, design_starts, plain_intervals
from .poses import as_pose, broadcast_poses
from .results import BatchResult
from .shapes import Prism, as_prism_set

__all__ = ["collision_probability", "ProbabilityResult", "METHODS", "EXACT", "PLAIN", "IMPORTANCE"]

EXACT, PLAIN, IMPORTANCE = 0, 1, 2

#: Meaning of :attr:`ProbabilityResult.method`.
METHODS = {
    EXACT: "exact: no noise, or translation noise that provably cannot reach contact (p = 0, high = bound)",
    PLAIN: "plain Monte Carlo, Wilson score interval",
    IMPORTANCE: "importance sampling about the most likely colliding poses, skewness-corrected (Hall) interval",
}

#: ``method="auto"`` samples by importance where the linear estimate of p is below this.
IMPORTANCE_BELOW = 0.05
#: Samples in a query's first round; later rounds are sized from the relative error reached.
FIRST_ROUND = 1024
#: The estimate's first draw is this many times what the pilot says it needs (fewer estimates then
#: go on in further rounds, whose stopping biases the interval).
PILOT_MARGIN = 1.5
#: Samples per task of the compiled sampling loop (a query's round is cut into tasks of this size,
#: which threads share; each sample's draws depend only on its query and its index, so results
#: do not depend on the cut or on how queries are grouped).
TASK_SAMPLES = 4096
#: Tasks per call of the sampling loop at most (bounds its scratch memory).
MAX_TASKS = 1 << 14
#: Default budget of samples per query.
DEFAULT_MAX_SAMPLES = 1_000_000
#: A provable upper bound of p below this is reported as p = 0 (method EXACT).
NEGLIGIBLE = 1e-300
LOG_NEGLIGIBLE = math.log(NEGLIGIBLE)
# Tolerances on the correlation matrix D^-1 C D^-1 (D the standard deviations; units drop out):
_METHOD_NAMES = ("auto", "plain", "importance")


@dataclass(frozen=True)
class ProbabilityResult(BatchResult):
    """Result of :func:`collision_probability` for ``N`` queries.

    Attributes
    ----------
    p : numpy.ndarray, shape (N,)
        Estimated probability of collision.
    low, high : numpy.ndarray, shape (N,)
        Confidence interval at ``confidence``.
    samples : numpy.ndarray of int64, shape (N,)
        Samples drawn (poses evaluated by ``collide``) per query, the pilot's included.
    converged : numpy.ndarray of bool, shape (N,)
        True where the interval's half-width reached ``rel_error * p`` (or the answer is exact);
        False where the sample budget ran out first.
    method : numpy.ndarray of int8, shape (N,)
        :data:`EXACT`, :data:`PLAIN` or :data:`IMPORTANCE` (see :data:`METHODS`).
    hits : numpy.ndarray of int64, shape (N,)
        Samples of the estimate (the pilot's not counted) that collided.
    beta : numpy.ndarray, shape (N,)
        Distance of the most likely colliding noise from the nominal pose in standard
        deviations (``Phi(-beta)`` is the linear estimate of p); NaN where not computed.
    seed : int
        Root entropy of the random streams (given, or drawn when ``seed`` was None).
    confidence, rel_error : float
        As requested.
    """

    p: np.ndarray
    low: np.ndarray
    high: np.ndarray
    samples: np.ndarray
    converged: np.ndarray
    method: np.ndarray
    hits: np.ndarray
    beta: np.ndarray
    seed: int
    confidence: float
    rel_error: float

    def __repr__(self):
        n = len(self)
        return (
            f"ProbabilityResult({n} quer{'ies' if n != 1 else 'y'}, {int(np.count_nonzero(self.converged))} "
            f"converged, {int(self.samples.sum())} samples)"
        )

    def columns(self) -> dict:
        """The result as named 1-D columns (``pandas.DataFrame(result.columns())`` takes them)."""
        names = ("p", "low", "high", "samples", "converged", "method", "hits", "beta")
        return {k: getattr(self, k) for k in names}

    @staticmethod
    def concatenate(parts, seed, confidence, rel_error):
        """The results of consecutive query ranges as one (for chunked runs)."""
        columns = [r.columns() for r in parts]
        arrays = {k: np.concatenate([c[k] for c in columns]) for k in columns[0]}
        return ProbabilityResult(**arrays, seed=seed, confidence=confidence, rel_error=rel_error)


def collision_probability(
    shape_a,
    shape_b,
    pos_a,
    rot_a,
    pos_b,
    rot_b,
    cov_b,
    *,
    cov_a=None,
    rel_error=0.1,
    confidence=0.95,
    max_samples=DEFAULT_MAX_SAMPLES,
    seed=None,
    method="auto",
    query_index=None,
    quat_order=None,
    rtol=None,
    atol=0.0,
    dtype=np.float64,
    parallel=None,
):
    """Probability that two prisms collide when their poses are uncertain (Gaussian noise).

    Parameters
    ----------
    shape_a, shape_b : Prism
        Single prisms (a :class:`~prismbatch.PrismSet` is not supported here).
    pos_a, rot_a, pos_b, rot_b : array_like
        Nominal poses, single or ``N`` queries, in any form :func:`~prismbatch.collide` takes
        (for 4x4 transforms pass them as ``pos_a`` and ``pos_b`` with ``rot_a = rot_b = None``).
    cov_b : array_like, shape (6, 6) or (N, 6, 6)
        Covariance of b's noise ``(dp, dtheta)`` in the world frame: ``p = p0 + dp``,
        ``R = exp([dtheta]x) R0``. Symmetric and positive semidefinite; singular is fine.
    cov_a : array_like, optional
        The same for a (independent of b's); None: a's pose is exact.
    rel_error : float, optional
        Sampling stops once the interval's half-width is at most ``rel_error * p``.
    confidence : float, optional
        Level of the interval ``[low, high]``.
    max_samples : int, optional
        Budget of samples per query (default :data:`DEFAULT_MAX_SAMPLES`, 10^6).
    seed : int, optional
        Root seed; query ``i`` uses ``SeedSequence(seed, spawn_key=(query_index[i],))``.
        None draws fresh entropy (kept in the result's ``seed``).
    method : {"auto", "plain", "importance"}, optional
        Estimator; "auto" chooses per query (see the module notes).
    query_index : array_like of int, shape (N,), optional
        Keys of the queries' random streams (default ``0 .. N-1``); a chunk of a larger
        query set passes its global indices to get the same answers as the whole run.
    quat_order, rtol, atol, dtype, parallel
        As for :func:`~prismbatch.collide`.

    Returns
    -------
    ProbabilityResult
        ``p``, ``low``, ``high``, ``samples``, ``converged``, ``method``, ``hits``, ``beta``.

    Raises
    ------
    TypeError, ValueError
        Bad shapes, poses, covariances (wrong shape, not symmetric, not positive
        semidefinite, not finite) or options; the message names the argument.

    Examples
    --------
    >>> import numpy as np, prismbatch as pb
    >>> from prismbatch.probability import collision_probability
    >>> a, b = pb.Prism.regular(4, 1.0), pb.Prism.regular(4, 1.0)
    >>> down = np.diag([1.0, -1.0, -1.0])
    >>> cov = np.diag([0, 0, 0.1**2, 0, 0, 0])      # b's height is uncertain by 0.1
    >>> r = collision_probability(a, b, [0, 0, 0], down, [0, 0, 0.2], np.eye(3), cov, seed=1)
    >>> bool(abs(r.p[0] - 0.02275) < 0.003), r.method.tolist()  # Phi(-2)
    (True, [2])
    """
    from .collide import collider_for

    col = collider_for(shape_a, shape_b, rtol, atol, dtype)  # checks and packs the shapes (kept for repeat calls)
    return col.collision_probability(
        pos_a,
        rot_a,
        pos_b,
        rot_b,
        cov_b,
        cov_a=cov_a,
        rel_error=rel_error,
        confidence=confidence,
        max_samples=max_samples,
        seed=seed,
        method=method,
        query_index=query_index,
        quat_order=quat_order,
        parallel=parallel,
    )


def estimate(col, pos_a, rot_a, pos_b, rot_b, cov_b, *, cov_a, rel_error, confidence, max_samples, seed, method,
             query_index, quat_order, parallel):  # fmt: skip
    """:func:`collision_probability` on a :class:`~prismbatch.Collider` (its method calls this)."""
    if not (isinstance(col.shape_a, Prism) and isinstance(col.shape_b, Prism)):
        raise TypeError("collision_probability needs single Prism shapes, not PrismSets")
    rel_error = real_scalar(rel_error, "rel_error", 0.0, 1e6)
    if rel_error <= 0:
        raise ValueError(f"rel_error must be > 0, got {rel_error!r}")
    confidence = real_scalar(confidence, "confidence", 0.0, 1.0)
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be in (0, 1), got {confidence!r}")
    if not 0.5 + 0.5 * confidence < 1.0:  # its normal quantile would be infinite
        raise ValueError(f"confidence must be at most {1.0 - 2.0**-52!r}, got {confidence!r}")
    max_samples = integer(DEFAULT_MAX_SAMPLES if max_samples is None else max_samples, "max_samples", 1)
    if method not in _METHOD_NAMES:
        raise ValueError(f"method must be one of {_METHOD_NAMES}, got {method!r}")
    check_flag(parallel, "parallel", allow_none=True)
    seed = int(np.random.SeedSequence().entropy) if seed is None else integer(seed, "seed", 0)
    pa, ra = as_pose(pos_a, rot_a, quat_order=quat_order, name="a")
    pb, rb = as_pose(pos_b, rot_b, quat_order=quat_order, name="b")
    n, (pa, ra, pb, rb) = broadcast_queries(pa, ra, pb, rb, cov_b, cov_a)
    # Contact is invariant under a shift of both bodies: sampling about a's nominal position keeps
    # collide's rounding band (4 eps |position|) from counting as contact far from the origin.
    pa, pb = np.zeros_like(pa), pb - pa
    L = noise_factor(cov_b, "cov_b", n)
    translation_only = rotation_free(cov_b)
    if cov_a is not None:
        La = noise_factor(cov_a, "cov_a", n)
        L = np.concatenate((np.concatenate((L, np.zeros_like(L)), 2), np.concatenate((np.zeros_like(La), La), 2)), 1)
        translation_only &= rotation_free(cov_a)
    keys = _query_keys(query_index, n)
    run = _Run(col, (pa, ra, pb, rb), L, NormalDist().inv_cdf(0.5 + 0.5 * confidence), rel_error, parallel)
    return run.estimate(method, translation_only, max_samples, seed, keys, confidence)


def broadcast_queries(pos_a, rot_a, pos_b, rot_b, cov_b, cov_a):
    """``(n, (pos_a, rot_a, pos_b, rot_b))``: parsed poses broadcast to the queries' count, which a batch
    of covariances (N, 6, 6) takes part in (:func:`~prismbatch.poses.broadcast_poses`, naming it)."""
    batched = [
        (np.shape(c)[0], nm) for c, nm in ((cov_b, "cov_b"), (cov_a, "cov_a")) if c is not None and np.ndim(c) == 3
    ]
    n, name = batched[0] if batched else (None, "")
    return broadcast_poses(pos_a, rot_a, pos_b, rot_b, n_shapes=n, shapes_name=name)


def _query_keys(query_index, n):
    if query_index is None:
        return np.arange(n)
    q = np.asarray(query_index)
    if q.dtype.kind not in "iu" or q.shape != (n,) or (q < 0).any() or (q > np.iinfo(np.int64).max).any():
        raise ValueError(f"query_index must be {n} integers >= 0 (one per query), got shape {q.shape} {q.dtype}")
    return q.astype(np.int64)


class _Run:
    """One call's queries: nominal poses, noise factors and the sampling loop."""

    def __init__(self, col, poses, L, z, rel_error, parallel):
        self.col, self.poses, self.L, self.z, self.rel, self.parallel = col, poses, L, z, rel_error, parallel
        self.n, self.k = L.shape[0], L.shape[1]
        self.active = np.abs(L).max(axis=1) > 0  # (n, k): the noise components that move something
        dt = col.dtype  # what the sampling loop takes of the shapes and the tolerances, once per call
        a, b = (
            as_prism_set(s, name, dt)[0].kernel_arrays(dt)
            for s, name in ((col.shape_a, "shape_a"), (col.shape_b, "shape_b"))
        )
        self.shapes = (a.floats, a.ints, b.floats, b.ints)
        self.limits = (col.rtol, col.atol, float(np.finfo(dt).eps), SUPPORTED_RANGE[dt.name][1])

    def sample_poses(self, query, z):
        """Poses of the standard-normal noise ``z`` (m, k) of queries ``query`` (m,): (pos_a, rot_a, pos_b, rot_b)."""
        m = len(query)
        kern = sample_parallel if use_parallel(self.parallel, m) else sample_serial
        out = np.empty((m, 3)), np.empty((m, 3, 3)), np.empty((m, 3)), np.empty((m, 3, 3))
        kern(np.ascontiguousarray(query, dtype=np.int64), self.L, np.ascontiguousarray(z), *self.poses, *out)
        lim = self.limits[3]
        ok, ok_b = np.empty(m, bool), np.empty(m, bool)
        poses_usable(out[0], out[1], lim, ok)
        poses_usable(out[2], out[3], lim, ok_b)
        ok &= ok_b
        if not ok.all():
            where = "in the search for the likeliest collision"
            raise ValueError(self._noise_too_large(int(query[np.argmin(ok)]), where))
        return out

    def _noise_too_large(self, q, where):
        """The message for noise that moves a sampled pose out of the coordinates' range."""
        return (
            f"query {q}: a sampled position lies beyond {self.limits[3]:g} from the origin or a sampled rotation "
            f"is not finite ({where}); the pose noise is too large for {self.col.dtype.name} coordinates"
        )

    def proposals(self, qs, rngs, reach):
        """The importance-sampling mixtures of queries ``qs``: ``{query: (mu (J, k), log weights (J,), active)}``.

        Every query's searches (:func:`~prismbatch.importance.design_starts`, axis starts
        ``reach[query]`` standard deviations out, random parts from its own stream
        ``rngs[query]``) run together, one batch distance call a step.
        """
        if not len(qs):
            return {}
        starts = [design_starts(self.active[i], rngs[i], reach[i]) for i in qs]
        count = np.array([len(s) for s in starts], dtype=np.int64)
        query = np.repeat(qs, count)

        def linearise(z):
            r, g = self._linearise(query, z)
            return r.distance, g

        z, miss = design_points(linearise, np.concatenate(starts))
        out, ends = {}, np.cumsum(count)
        for j, i in enumerate(qs):
            part = slice(ends[j] - count[j], ends[j])
            out[i] = (*centres(z[part], miss[part], self.active[i]), self.active[i])
        return out

    def _linearise(self, qs, z):
        """``(DistanceResult with witnesses, gradient of the distance in z)`` at the noise ``z`` of queries ``qs``."""
        L = self.L[qs]
        x = np.einsum("nij,nj->ni", L, z)
        poses = self.sample_poses(qs, z)
        r = self.col.distance(*poses, witness=True, parallel=self.parallel)
        nrm = r.normal
        g = [nrm, _through_exp(x[:, 3:6], np.cross(r.point_b - poses[2], nrm))]
        if self.k == 12:
            g += [-nrm, -_through_exp(x[:, 9:12], np.cross(r.point_a - poses[0], nrm))]
        gz = np.einsum("nij,ni->nj", L, np.concatenate(g, axis=1))  # L^T g
        return r, gz

    def estimate(self, method, translation_only, max_samples, seed, keys, confidence):
        """Every query's estimate: exact cases, then the search for centres, then the rounds."""
        n = self.n
        p, low, high = np.zeros(n), np.zeros(n), np.zeros(n)
        samples, hits = np.zeros(n, np.int64), np.zeros(n, np.int64)
        converged, how, beta = np.zeros(n, bool), np.full(n, PLAIN, np.int8), np.full(n, np.nan)
        noisy = np.abs(self.L).max(axis=(1, 2)) > 0
        exact = np.flatnonzero(~noisy)
        if len(exact):  # no noise at all: the nominal answer
            hit = self.col.collide(
                *self.sample_poses(exact, np.zeros((len(exact), self.k))), parallel=self.parallel
            ).hit
            p[exact] = low[exact] = high[exact] = hit
            converged[exact], how[exact] = True, EXACT
        qs = np.flatnonzero(noisy)
        # Query i's two streams are the children of SeedSequence(seed, spawn_key=(keys[i],)): spawn_key
        # (keys[i], 0) for the search, (keys[i], 1) for the sampling loop (see _kernels.streams).
        child = lambda i, j: np.random.SeedSequence(seed, spawn_key=(int(keys[i]), j))  # noqa: E731
        stream_keys = np.zeros(n, np.uint64)
        stream_keys[qs] = spawned_keys(seed, keys[qs], 1)
        mix = {}
        if len(qs) and method != "plain":
            r0, g0 = self._linearise(qs, np.zeros((len(qs), self.k)))
            g0 = np.linalg.norm(g0, axis=1)
            apart = r0.status > 0
            with np.errstate(divide="ignore", invalid="ignore"):  # within tol counts as contact
                bound = 0.5 * np.array([math.erfc(v / math.sqrt(2)) for v in (r0.distance - r0.tol) / g0])
            proven = translation_only & apart & (bound < NEGLIGIBLE)
            e = qs[proven]
            top = np.maximum(bound[proven], math.ulp(0.0))  # rounded up where it underflows: still a bound
            p[e], low[e], high[e], converged[e], how[e] = 0.0, 0.0, top, True, EXACT
            qs, apart, g0 = qs[~proven], apart[~proven], g0[~proven]
            with np.errstate(divide="ignore", invalid="ignore"):  # the linear estimate of beta, where to start
                reach = np.clip(np.nan_to_num(r0.distance[~proven] / g0, nan=1.0), 1.0, 5.0)
            reach = dict(zip(qs.tolist(), reach))
            mix = self.proposals(qs[g0 > 0], {i: np.random.default_rng(child(i, 0)) for i in qs}, reach)
            for i, (mu, _, _) in mix.items():
                beta[i] = np.linalg.norm(mu, axis=1).min()
            beta[qs[g0 == 0]] = np.inf
            beta[qs[~apart]] = 0.0  # colliding (or touching) as it is: the likeliest noise collides
            linear = 0.5 * np.array([math.erfc(v / math.sqrt(2)) for v in beta[qs]])
            use = (apart & (linear < IMPORTANCE_BELOW)) if method == "auto" else np.ones(len(qs), bool)
            how[qs[use & (g0 > 0)]] = IMPORTANCE
        state = {int(i): Tally() for i in qs}
        pilot = {i: None for i in state}  # samples of the pilot, once it is over
        drawn = dict.fromkeys(state, 0)  # samples drawn so far: where each query's next round starts
        todo = {i: min(FIRST_ROUND, max_samples) for i in state}
        mixtures = self._packed(mix, how)
        while todo:
            self._round(todo, stream_keys, drawn, state, mixtures)
            nxt = {}
            plain = [i for i in todo if how[i] != IMPORTANCE]
            rho_plain = dict(zip(plain, plain_intervals([state[i] for i in plain], self.z)[3].tolist()))
            for i in todo:
                st = state[i]
                rho = rho_plain[i] if i in rho_plain else st.relative_half_width(self.z)
                left = max_samples - st.n - (pilot[i] or 0)
                if how[i] == IMPORTANCE and st.log_high(self.z) < LOG_NEGLIGIBLE:
                    converged[i] = True  # p is below 1e-300 at the interval's upper end: reported as 0
                    continue
                if pilot[i] is None and left > 0:
                    if np.isfinite(rho):
                        # The pilot sizes the estimate, which then gets fresh samples (coverage;
                        # see the module notes).
                        pilot[i], state[i] = st.n, Tally()
                        if i not in rho_plain:  # (a plain interval has no normal form of its own)
                            rho = st.relative_half_width(self.z, normal=True)
                        ratio = rho / self.rel  # (squared by a product: a tiny rel_error overflows it to inf)
                        nxt[i] = int(
                            min(max(math.ceil(min(PILOT_MARGIN * st.n * ratio * ratio, left)), FIRST_ROUND), left)
                        )
                    else:  # no hit yet
                        nxt[i] = int(min(st.n, left))
                    continue
                if rho <= self.rel:
                    converged[i] = True
                    continue
                if left <= 0:
                    continue
                ratio = rho / self.rel
                need = st.n * ratio * ratio if np.isfinite(rho) else 2 * st.n
                # (capped before the ceiling, which cannot take inf; the cap changes no min below)
                nxt[i] = int(min(max(math.ceil(min(1.1 * need, 2 * st.n + left)) - st.n, FIRST_ROUND), st.n, left))
            todo = nxt
        for i, st in state.items():
            samples[i], hits[i] = st.n + (pilot[i] or 0), st.hits
            if how[i] == IMPORTANCE:
                p[i], low[i], high[i] = st.interval(self.z)
        plain = [i for i in state if how[i] != IMPORTANCE]
        if plain:
            p[plain], low[plain], high[plain] = plain_intervals([state[i] for i in plain], self.z)[:3]
        return ProbabilityResult(p, low, high, samples, converged, how, hits, beta, int(seed), confidence, self.rel)

    def _packed(self, mix, how):
        """The mixtures of the queries sampled by importance as the sampling loop takes them:
        ``(start (n + 1,), mu (J, k), log pi (J,), cum (J,))``, query i's centres at
        ``start[i]:start[i + 1]`` (none for the others, which draw from the nominal distribution);
        ``cum`` is the mixture's cumulative weight up to and including each centre, after the
        defensive part (the loop picks a centre by it)."""
        chosen = [i for i in range(self.n) if how[i] == IMPORTANCE and i in mix]
        count = np.zeros(self.n + 1, np.int64)
        for i in chosen:
            count[i + 1] = len(mix[i][1])
        mu = np.zeros((int(count.sum()), self.k))
        lpi = np.zeros(len(mu))
        start = np.cumsum(count)
        cum = np.zeros(len(mu))
        for i in chosen:
            mu[start[i] : start[i + 1]], lpi[start[i] : start[i + 1]] = mix[i][0], mix[i][1]
            cum[start[i] : start[i + 1]] = DEFENSIVE + (1.0 - DEFENSIVE) * np.cumsum(np.exp(mix[i][1]))
        return start, mu, lpi, cum

    def _round(self, todo, keys, drawn, state, mixtures):
        """Draw and test one round of every query in ``todo`` (``{query: samples}``), adding it to
        the query's tally; ``drawn[query]`` (its samples so far) moves on."""
        tasks = [
            (i, drawn[i] + s, min(TASK_SAMPLES, m - s))
            for i, m in sorted(todo.items())
            for s in range(0, m, TASK_SAMPLES)
        ]
        for i, m in todo.items():
            drawn[i] += m
        for g in range(0, len(tasks), MAX_TASKS):
            part = tasks[g : g + MAX_TASKS]
            query, start, count = (np.array(c, dtype=np.int64) for c in zip(*part))
            hits, shift, sums = self._count(query, start, count, keys, mixtures)
            for (i, _, m), h, sh, su in zip(part, hits.tolist(), shift.tolist(), sums.tolist()):
                state[i].add_sums(m, h, sh, *su)

    def _count(self, query, start, count, keys, mixtures):
        """The sampling loop on tasks ``(query, start, count)``: ``(hits, shift, sums)`` per task."""
        T, dt = len(query), self.col.dtype
        scratch = np.empty((T, self.k)), np.empty((T, 3), dt), np.empty((T, 3, 3), dt), np.empty((T, 3), dt)
        scratch += (np.empty((T, 3, 3), dt),)
        hits, shift, sums, bad = np.empty(T, np.int64), np.empty(T), np.empty((T, 3)), np.empty(T, np.int64)
        parallel = use_parallel(self.parallel, int(count.sum()))
        kern = count_parallel if parallel else count_serial
        # fmt: off
        first_call((kern, dt), kern, *self.shapes, query, start, count, keys, self.L, *self.poses, *mixtures,
                   self.active, DEFENSIVE, SPREAD, *ZIGGURAT, *self.limits, *scratch, hits, shift, sums, bad)
        # fmt: on
        if (bad >= 0).any():
            t = int(np.argmax(bad >= 0))
            raise ValueError(self._noise_too_large(int(query[t]), f"sample {int(start[t] + bad[t])}"))
        return hits, shift, sums


def _through_exp(theta, v):
    """``J(theta)^T v``: the gradient ``v`` of a turn applied on the left, taken back to the
    exponential coordinates ``theta`` (J is the left Jacobian of SO(3))."""
    t = np.linalg.norm(theta, axis=1)[:, None]
    safe = np.where(t > 1e-4, t, 1.0)
    b = np.where(t > 1e-4, 2 * (np.sin(0.5 * safe) / safe) ** 2, 0.5 - t * t / 24)
    c = np.where(t > 1e-4, (1.0 - np.sin(safe) / safe) / safe / safe, 1 / 6 - t * t / 120)  # (t - sin t) / t^3
    w = np.cross(theta, v)
    return v - b * w + c * np.cross(theta, w)
