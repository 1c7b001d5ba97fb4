"""The run's summary: case sequence, collisions and their detach steps, goal reached.

See docs/methods/experiment.md.
"""

from __future__ import annotations

import numpy as np

from ...control import CONTACT_CLASSES
from .model import FIG10_TIMES, UM


def _runs(values, t):
    """Run-length encoding: [(value, t_start, t_end, n_samples), ...]."""
    out = []
    start = 0
    for i in range(1, len(values) + 1):
        if i == len(values) or values[i] != values[start]:
            out.append((int(values[start]), float(t[start]), float(t[i - 1]), i - start))
            start = i
    return out


def summarise(res, tol_used):
    """The summary dict of a run (``ExperimentResult.summary``); ``tol_used``: the feature tolerance per sample."""
    t, hit, case = res.t, res.hit, res.case
    err = res.error
    goal_tol = res.params["goal_tol_um"] * UM
    dt = res.params["dt_s"]
    runs = _runs(case, t)
    hit_idx = np.flatnonzero(hit)
    episodes = [(int(r_[1] / dt + 0.5), r_[3]) for r_ in _runs(hit.astype(np.int8), t) if r_[0] == 1]
    events = []
    for k in hit_idx:
        nxt = k + 1 < len(t) and not hit[k + 1]
        sep = float(np.dot(res.dc[k + 1] - res.dc[k], res.direction[k])) if k + 1 < len(t) else float("nan")
        events.append(
            dict(
                t_s=float(t[k]),
                step=int(k),
                case=int(case[k]),
                contact_class=int(res.contact_class[k]),
                contact_class_name=CONTACT_CLASSES[int(res.contact_class[k])],
                contact_um=(res.contact[k] / UM).tolist(),
                direction=res.direction[k].tolist(),
                detach_input=float(np.linalg.norm(res.u_d[k])),
                eps=float(np.linalg.norm(res.u_d[k]) / err[k]) if err[k] > 0 else float("nan"),
                pd_input=float(np.linalg.norm(res.u_pd[k])),
                error_um=float(err[k] / UM),
                feature_tol_um=float(tol_used[k] / UM),
                next_step_collision_free=bool(nxt),
                moved_out_um=sep / UM,
            )
        )
    ok = err <= goal_tol
    reached_at = None
    if ok[-1]:
        bad = np.flatnonzero(~ok)
        reached_at = float(t[bad[-1] + 1]) if len(bad) else float(t[0])
    first = int(hit_idx[0]) if len(hit_idx) else None
    first_ep_end = episodes[0][0] + episodes[0][1] if episodes else None
    later = [float(t[k]) for k in hit_idx if first_ep_end is not None and k >= first_ep_end]
    fig10 = []
    for tt in FIG10_TIMES:
        k = int(round(tt / dt))
        fig10.append(int(case[k]) if k < len(t) else None)
    case1_from = None
    last_non1 = np.flatnonzero(case != 1)
    if case[-1] == 1:
        case1_from = float(t[last_non1[-1] + 1]) if len(last_non1) else float(t[0])
    return dict(
        case_runs=[dict(case=c, t_start_s=a, t_end_s=b, samples=n) for c, a, b, n in runs],
        case_sequence=[r_[0] for r_ in runs],
        case_counts={int(c): int((case == c).sum()) for c in np.unique(case)},
        fig10_times_s=list(FIG10_TIMES),
        fig10_cases=fig10,
        case1_for_good_from_s=case1_from,
        collision_samples=int(hit.sum()),
        collision_episodes=len(episodes),
        first_collision_s=float(t[first]) if first is not None else None,
        first_contact_class=int(res.contact_class[first]) if first is not None else None,
        events=events,
        collisions_after_first_detach_s=later,
        every_detach_followed_by_free_step=bool(all(e["next_step_collision_free"] for e in events)),
        goal_reached=bool(ok[-1]),
        goal_reached_at_s=reached_at,
        goal_reached_without_further_collision=bool(ok[-1]) and not later,
        final_error_um=float(err[-1] / UM),
        max_speed_mm_s=float(np.max(np.linalg.norm(np.diff(res.dc, axis=0), axis=1)) / dt) if len(t) > 1 else 0.0,
    )
