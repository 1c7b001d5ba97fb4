"""A collision alarm for the experiment: time to impact and the probability of a collision soon.

At every sample the controller knows where b is (the cameras' measurement)
and the motion it commands. Two predictions along that motion, held constant
for the next ``horizon`` seconds (b's orientation is fixed in the experiment):

- the time to impact, :func:`prismbatch.motion.time_of_impact` from the
  measured position (inf when the motion is clear for the horizon);
- the probability that the motion collides within the horizon when the
  measured position is off by the cameras' noise, Gaussian and isotropic with
  standard deviation ``sigma_um`` per axis: the fraction of ``samples`` noisy
  starting positions whose motion meets a within the horizon (each judged by
  ``time_of_impact``, which cannot step over a contact), with a Wilson
  interval. Evaluated every ``every`` samples.

The alarm fires at the first sample where that probability reaches
``threshold``; its lead is how long before the first contact that is.
``docs/methods/experiment.md`` gives the choice of sigma.
"""

from __future__ import annotations

import time
from statistics import NormalDist

import numpy as np

from ...importance import wilson
from ...motion import CONTACT, UNDECIDED
from .model import UM, batch_poses

#: Seconds ahead the alarm looks.
HORIZON_S = 1.0
#: The cameras' measurement noise, µm per axis (1 sigma); see docs/methods/experiment.md.
SIGMA_UM = 3.0
#: Noisy starting positions per evaluated sample.
SAMPLES = 400
#: Evaluate the probability every this many samples (0.1 s at dt 0.02 s).
EVERY = 5
#: The alarm fires once the probability of a collision within the horizon reaches this.
THRESHOLD = 0.05
#: Confidence of the probability's interval.
CONFIDENCE = 0.95


def commanded_velocity(res):
    """(N, 3) mm/s: the motion the controller commands at each sample (the force plant: its steady speed)."""
    u = res.u_pd + res.u_d
    if res.params["plant"] == "velocity":
        return u
    return u / res.params["damping_mN_s_per_mm"]


def collision_alarm(
    res,
    col,
    *,
    horizon=HORIZON_S,
    sigma_um=SIGMA_UM,
    samples=SAMPLES,
    every=EVERY,
    threshold=THRESHOLD,
    confidence=CONFIDENCE,
    seed=0,
):
    """Time to impact at every sample and the probability of a collision within ``horizon``.

    Parameters
    ----------
    res : ExperimentResult
        A finished run (its states, inputs and geometry).
    col : prismbatch.Collider
        The run's shapes.
    horizon : float
        Seconds ahead.
    sigma_um : float
        Measurement noise, µm per axis (1 sigma).
    samples, every : int
        Noisy positions per evaluated sample, and the stride between evaluated samples.
    threshold : float
        Probability at which the alarm fires.
    confidence : float
        Confidence of the Wilson interval of the probability.
    seed : int
        Seed of the noise (``numpy.random.default_rng``).

    Returns
    -------
    dict
        ``toi_s`` (N,) time to impact from the measured position (inf: clear
        within the horizon); ``t_eval`` (M,) the evaluated times, ``p``,
        ``low``, ``high`` (M,) the probability and its interval; ``undecided``
        the count of noisy motions the advancement left undecided (counted as
        collisions: the alarm errs on the safe side); ``alarm_s`` the first
        alarm time (None if it never fires), ``first_contact_s`` and
        ``lead_s`` (first contact minus alarm, None if either is missing),
        the settings, and the seconds of the first (compiling) call
        ``compile_s`` and of the rest ``seconds``.
    """
    for name, v in (("horizon", horizon), ("sigma_um", sigma_um)):
        if not (np.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be finite and > 0, got {v}")
    if int(samples) != samples or samples < 1 or int(every) != every or every < 1:
        raise ValueError(f"samples and every must be integers >= 1, got {samples} and {every}")
    if not 0.0 < threshold <= 1.0:
        raise ValueError(f"threshold must be in (0, 1], got {threshold}")
    g = res.geometry
    pa1, ra1, rb1 = batch_poses(g)
    vel = np.ascontiguousarray(commanded_velocity(res))
    t0 = time.perf_counter()
    col.time_of_impact(pa1, ra1, res.dc[:1], rb1, velocity=vel[:1], horizon=horizon)  # compile or cache load
    t1 = time.perf_counter()
    toi = col.time_of_impact(pa1, ra1, np.ascontiguousarray(res.dc), rb1, velocity=vel, horizon=horizon).time

    ks = np.arange(0, len(res.t), int(every))
    rng = np.random.default_rng(seed)
    noise = rng.standard_normal((len(ks), int(samples), 3)) * (sigma_um * UM)
    start = (res.dc[ks, None, :] + noise).reshape(-1, 3)
    r = col.time_of_impact(pa1, ra1, start, rb1, velocity=np.repeat(vel[ks], int(samples), axis=0), horizon=horizon)
    meets = ((r.status == CONTACT) | (r.status == UNDECIDED)).reshape(len(ks), int(samples))
    hits = meets.sum(axis=1)
    low, high = wilson(hits, int(samples), NormalDist().inv_cdf(0.5 + confidence / 2))
    p = hits / int(samples)
    t2 = time.perf_counter()

    fired = np.flatnonzero(p >= threshold)
    alarm_s = float(res.t[ks[fired[0]]]) if len(fired) else None
    contacts = np.flatnonzero(res.hit)
    first_contact_s = float(res.t[contacts[0]]) if len(contacts) else None
    lead_s = first_contact_s - alarm_s if alarm_s is not None and first_contact_s is not None else None
    return dict(
        toi_s=toi,
        t_eval=res.t[ks],
        p=p,
        low=low,
        high=high,
        undecided=int(np.count_nonzero(r.status == UNDECIDED)),
        alarm_s=alarm_s,
        first_contact_s=first_contact_s,
        lead_s=lead_s,
        horizon_s=float(horizon),
        sigma_um=float(sigma_um),
        samples=int(samples),
        every=int(every),
        threshold=float(threshold),
        confidence=float(confidence),
        seed=int(seed),
        compile_s=t1 - t0,
        seconds=t2 - t1,
        first_toi_s=float(res.t[np.isfinite(toi)][0]) if np.isfinite(toi).any() else None,
    )
