"""The experiment's reports: summary lines, trajectory and Fig. 10 CSV, JSON and Markdown.

See docs/methods/experiment.md.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ...collide import CASES
from ...control import CONTACT_CLASSES
from ..report import fmt, run_metadata, write_csv, write_json, write_text
from .contour import contour_panels
from .model import PAPER
from .plots import plot_experiment


def _seconds(x):
    return fmt(x, ".2f", unit=" s")


def format_summary(res):
    """The run's summary as text lines (printed by ``prismbatch experiment``).

    Parameters
    ----------
    res : ExperimentResult

    Returns
    -------
    list of str
    """
    from ... import __version__

    p, s, tm = res.params, res.summary, res.timing
    lines = []
    lines.append(
        f"prismbatch {__version__} experiment (paper Sec. VI-B): a = {p['prism']} prism, side "
        f"{p['a_side_mm']:g} mm; b = {p['vertices']}-gon of diameter {p['b_diameter_mm']:g} mm "
        f"(real {1e3 * p['b_real_diameter_mm']:.0f} µm); {p['plant']} plant"
        + (f", speed limit {p['max_speed_mm_s']:g} mm/s" if p["max_speed_mm_s"] else "")
        + f"; kp {p['kp']:g}, kd {p['kd']:g}, eps {p['eps']:g}; dt {p['dt_s']:g} s, "
        f"{p['duration_s']:g} s ({p['n_samples']} samples)"
    )
    runs = " -> ".join(f"{r['case']} [{r['t_start_s']:.2f}-{r['t_end_s']:.2f} s]" for r in s["case_runs"])
    lines.append(f"case sequence: {runs}")
    lines.append(
        f"   paper: 5, then 6, then 1 after about {PAPER['case1_after_s']:g} s; "
        f"here case 1 for good from {_seconds(s['case1_for_good_from_s'])}"
    )
    inst = "  ".join(f"{tt:g}s:{c}" for tt, c in zip(s["fig10_times_s"], s["fig10_cases"]))
    lines.append(
        f"case at the Fig. 10 instants: {inst}   (paper: " + " ".join(str(c) for c in PAPER["fig10_cases"]) + ")"
    )
    if s["first_collision_s"] is None:
        lines.append("collision: none detected")
    else:
        lines.append(
            f"collision: first at {s['first_collision_s']:.2f} s (paper: about {PAPER['collision_s']:g} s); "
            f"{s['collision_samples']} colliding sample(s) in {s['collision_episodes']} episode(s)"
        )
        unit = "µm/s" if p["plant"] == "velocity" else "µN"
        for e in s["events"]:
            lines.append(
                f"   t={e['t_s']:.2f} s case {e['case']}, contact class {e['contact_class']} "
                f"({e['contact_class_name']}), contact ({', '.join(f'{c:.0f}' for c in e['contact_um'])}) µm, "
                f"detach dir ({', '.join(f'{c:+.3f}' for c in e['direction'])}), "
                f"|u_d| {1e3 * e['detach_input']:.0f} {unit} (eps {e['eps']:.3g}) "
                f"(classified within {e['feature_tol_um']:.1f} µm); next sample "
                + ("collision-free" if e["next_step_collision_free"] else "STILL IN COLLISION")
                + f", moved {e['moved_out_um']:.0f} µm out"
            )
        lines.append(
            f"   paper: contact on a side face (class {PAPER['contact_class']}); "
            f"here the first contact is class {s['first_contact_class']} "
            f"({CONTACT_CLASSES[s['first_contact_class']]})"
        )
    later = s["collisions_after_first_detach_s"]
    lines.append(
        f"goal: {'reached' if s['goal_reached'] else 'NOT reached'} (|error| <= {p['goal_tol_um']:g} µm"
        + (f" from {s['goal_reached_at_s']:.2f} s" if s["goal_reached"] else "")
        + f"; final error {s['final_error_um']:.1f} µm); collisions after the first detach: "
        + (f"{len(later)} (at " + ", ".join(f"{x:.2f}" for x in later) + " s)" if later else "none")
        + " (paper: none)"
    )
    lines += alarm_lines(res.alarm)
    if tm:
        line = (
            f"detection cost over {p['n_samples']} samples: prismbatch {tm['loop_ms']:.1f} ms in the loop "
            f"({tm['loop_per_call_us']:.1f} µs per Python call with contact points)"
        )
        if "pair_ms" in tm:
            line += f", replay {tm['pair_ms']:.1f} ms, one batched call {tm['batch_ms']:.2f} ms"
        lines.append(line)
        if tm.get("fcl_ms") is not None:
            lines.append(
                f"   python-fcl on the same poses: {tm['fcl_ms']:.1f} ms (finite stand-ins of "
                f"{tm['fcl_standin_length_mm']:.1f} mm; {tm['fcl_disagreements']} disagreement(s) with "
                f"prismbatch's hits) -> prismbatch/FCL = {tm['loop_ms'] / tm['fcl_ms']:.2f}; "
                f"paper: {PAPER['detection_ms']:g} ms vs SWIFT {PAPER['swift_ms']:g} ms "
                f"= {PAPER['detection_ms'] / PAPER['swift_ms']:.3f}"
            )
        elif tm.get("fcl_note"):
            lines.append(f"   python-fcl: {tm['fcl_note']}")
        c = tm["compile_s"]
        lines.append(
            f"   compile or cache load (excluded): collide {c['collide_pair'] + c['collide_batch']:.2f} s, "
            f"detach {c['detach']:.2f} s; detach controller calls {tm['detach_ms']:.2f} ms"
        )
    return lines


def alarm_lines(al):
    """The collision alarm's summary lines (none if it was not computed)."""
    if not al:
        return []
    fin = np.flatnonzero(np.isfinite(al["toi_s"]))
    head = (
        f"collision alarm ({al['horizon_s']:g} s ahead along the commanded motion; camera noise "
        f"{al['sigma_um']:g} µm per axis, {al['samples']} noisy positions every {al['every']} samples; "
        f"fires at p >= {al['threshold']:g}): "
    )
    if al["alarm_s"] is None:
        head += "never fired"
    else:
        head += f"fires at {al['alarm_s']:.2f} s"
        if al["lead_s"] is not None:
            head += f", {al['lead_s']:.2f} s before the first contact ({al['first_contact_s']:.2f} s)"
    lines = [head]
    lines.append(
        "   time to impact from the measured position: "
        + (f"first within the horizon at {al['first_toi_s']:.2f} s" if len(fin) else "never within the horizon")
        + f"; {al['undecided']} noisy motion(s) undecided (counted as collisions); "
        f"{al['seconds']:.2f} s to compute (+{al['compile_s']:.2f} s compile or cache load)"
    )
    return lines


def _csv_rows(res):
    unit = 1e3  # mm -> µm, mm/s -> µm/s, mN -> µN
    header = [
        "t_s",
        "dC_x_um",
        "dC_y_um",
        "dC_z_um",
        "error_um",
        "case",
        "hit",
        "contact_class",
        "contact_x_um",
        "contact_y_um",
        "contact_z_um",
        "dir_x",
        "dir_y",
        "dir_z",
        "u_pd_x",
        "u_pd_y",
        "u_pd_z",
        "u_d_x",
        "u_d_y",
        "u_d_z",
        "detect_us",
        "time_to_impact_s",
    ]
    err = res.error
    toi = res.alarm["toi_s"] if res.alarm else np.full(len(res.t), np.nan)
    rows = []
    for k in range(len(res.t)):
        rows.append(
            [
                f"{res.t[k]:.4f}",
                *(f"{v * unit:.4f}" for v in res.dc[k]),
                f"{err[k] * unit:.4f}",
                int(res.case[k]),
                int(res.hit[k]),
                int(res.contact_class[k]),
                *("" if np.isnan(v) else f"{v * unit:.4f}" for v in res.contact[k]),
                *("" if np.isnan(v) else f"{v:.6f}" for v in res.direction[k]),
                *(f"{v * unit:.4f}" for v in res.u_pd[k]),
                *(f"{v * unit:.4f}" for v in res.u_d[k]),
                f"{res.detect_s[k] * 1e6:.2f}",
                "" if np.isnan(toi[k]) else f"{toi[k]:.6g}",  # inf: clear for the alarm's horizon
            ]
        )
    return header, rows


def _alarm_csv_rows(al):
    """The alarm's probability at its evaluated samples, with the interval."""
    header = ["t_s", "p_collision_within_horizon", "low", "high", "samples"]
    rows = [
        [f"{t:.4f}", f"{p:.6g}", f"{lo:.6g}", f"{hi:.6g}", al["samples"]]
        for t, p, lo, hi in zip(al["t_eval"], al["p"], al["low"], al["high"])
    ]
    return header, rows


def _contour_csv_rows(res):
    """Fig. 10's curves as CSV rows (µm), so the figure can be redrawn from files."""
    panels, poly_a = contour_panels(res)
    header = ["panel", "t_s", "label", "case", "hit", "curve", "vertex", "x_um", "y_um"]
    rows = []
    for i, P in enumerate(panels):
        curves = [
            ("a_end_face", poly_a),
            ("b_end_face_projected", P["end_face"]),
            ("b_projection", P["projection"]),
            ("b_centre", P["centre"][None]),
        ]
        if P["contact"] is not None:
            curves.append(("contact", P["contact"][None]))
        for name, pts in curves:
            for j, (x, y) in enumerate(pts):
                rows.append(
                    [
                        i,
                        f"{P['t']:.4f}",
                        P["label"] or "",
                        P["case"],
                        int(P["hit"]),
                        name,
                        j,
                        f"{1e3 * x:.4f}",
                        f"{1e3 * y:.4f}",
                    ]
                )
    return header, rows


def _markdown(res, figure_files):
    p, s, tm = res.params, res.summary, res.timing
    unit = "µm/s" if p["plant"] == "velocity" else "µN"
    L = [f"# Experiment (paper Sec. VI-B): {p['prism']} prism, {p['plant']} plant", ""]
    L += ["```", *format_summary(res), "```", ""]
    L += ["| quantity | paper | this run |", "|---|---|---|"]
    L.append(f"| case sequence | 5 → 6 → 1 | {' → '.join(str(c) for c in s['case_sequence'])} |")
    L.append(
        f"| case at Fig. 10 instants (0,1,2,3,3.5,4,5,5.9 s) | {' '.join(map(str, PAPER['fig10_cases']))} | "
        f"{' '.join(str(c) for c in s['fig10_cases'])} |"
    )
    L.append(f"| case 1 for good from | after about 6 s | {_seconds(s['case1_for_good_from_s'])} |")
    L.append(f"| first collision | about 3.5 s | {_seconds(s['first_collision_s'])} |")
    fc = s["first_contact_class"]
    L.append(
        f"| contact class | 4 (side face) | {fc if fc is not None else '-'}"
        + (f" ({CONTACT_CLASSES[fc]})" if fc is not None else "")
        + " |"
    )
    L.append(f"| colliding samples / episodes | 1 | {s['collision_samples']} / {s['collision_episodes']} |")
    L.append(
        f"| goal reached without another collision | yes | "
        f"{'yes' if s['goal_reached_without_further_collision'] else 'no'} "
        f"(goal {'reached' if s['goal_reached'] else 'not reached'}, final error {s['final_error_um']:.1f} µm) |"
    )
    if tm.get("fcl_ms") is not None:
        L.append(
            f"| detection cost of the run | 121 ms (SWIFT 3375 ms) | {tm['loop_ms']:.1f} ms "
            f"(python-fcl {tm['fcl_ms']:.1f} ms) |"
        )
    L += [
        "",
        "## Collisions",
        "",
        f"| t (s) | case | class | contact (µm) | detach direction | detach input ({unit}) | ε | moved out (µm) "
        "| next sample |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for e in s["events"]:
        L.append(
            f"| {e['t_s']:.2f} | {e['case']} | {e['contact_class']} ({e['contact_class_name']}) | "
            f"{', '.join(f'{c:.0f}' for c in e['contact_um'])} | "
            f"{', '.join(f'{c:+.4f}' for c in e['direction'])} | {1e3 * e['detach_input']:.0f} | {e['eps']:.3g} | "
            f"{e['moved_out_um']:.1f} | {'free' if e['next_step_collision_free'] else 'collision'} |"
        )
    L += [
        "",
        "## Model",
        "",
        f"- Plant: `{p['plant']}` — "
        + (
            "the stage follows the commanded velocity, x[k+1] = x[k] + dt u[k]."
            if p["plant"] == "velocity"
            else f"m dv/dt = u − c v (m = {p['mass_kg']} kg, c = {p['damping_mN_s_per_mm']} "
            "mN·s/mm), exact zero-order-hold update."
        ),
        "- PD attraction u = −kp (x − x_d) − kd v, v the finite-difference velocity of the samples; "
        "detach u_d = ε |x − x_d| c (eq. 42) for the colliding sample only, "
        + (
            f"ε = {p['eps']:g} (the paper's fixed gain)."
            if p.get("detach_clearance_um") is None
            else f"ε adapted at each contact to the predicted approach: the smallest push that the plant model "
            f"predicts leaves b {p['detach_clearance_um']:g} µm out of contact after the step."
        ),
        "- Contact classification tolerance: "
        + (f"{p['detach_tol_mm']} mm" if not isinstance(p["detach_tol_mm"], str) else p["detach_tol_mm"])
        + ".",
        "- See `docs/methods/experiment.md` for the full description.",
        "",
    ]
    if res.alarm:
        al = res.alarm
        L += [
            "## Collision alarm",
            "",
            f"At every sample: the time to impact along the commanded motion held for {al['horizon_s']:g} s "
            f"(`prismbatch.motion.time_of_impact`), and every {al['every']} samples the probability that the "
            f"motion collides within that time when the measured position is off by the cameras' noise "
            f"({al['sigma_um']:g} µm per axis, {al['samples']} noisy positions, Wilson interval at "
            f"{al['confidence']:g}). The alarm fires at p >= {al['threshold']:g}.",
            "",
            *(f"- {line.strip()}" for line in alarm_lines(al)),
            "",
        ]
    if figure_files:
        L += ["## Figures", ""] + [f"- [{Path(f).name}]({Path(f).name})" for f in figure_files if f.endswith(".png")]
    return "\n".join(L) + "\n"


def write_experiment(res, out_dir, *, figures=True):
    """Write the run to ``out_dir``: CSV, JSON, Markdown and (optionally) figures.

    Parameters
    ----------
    res : ExperimentResult
    out_dir : str or pathlib.Path
        Created if missing; files are named ``experiment_<prism>_*``.
    figures : bool
        Also draw the figures (needs matplotlib).

    Returns
    -------
    dict
        The written paths: ``csv`` (trajectory), ``contours_csv`` (the Fig. 10
        curves), ``json``, ``markdown`` and ``figures`` (list; PNG and SVG of
        each figure).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    stem = f"experiment_{res.params['prism']}"
    paths = {
        "csv": str(out / f"{stem}_trajectory.csv"),
        "contours_csv": str(out / f"{stem}_fig10_contours.csv"),
        "json": str(out / f"{stem}.json"),
        "markdown": str(out / f"{stem}.md"),
        "figures": [],
    }
    write_csv(paths["csv"], *_csv_rows(res))
    write_csv(paths["contours_csv"], *_contour_csv_rows(res))
    if res.alarm:
        paths["alarm_csv"] = str(out / f"{stem}_alarm.csv")
        write_csv(paths["alarm_csv"], *_alarm_csv_rows(res.alarm))
    if figures:
        paths["figures"] = plot_experiment(res, out, stem=stem)
    meta = run_metadata(
        description="prismbatch simulation of the paper's Sec. VI-B experiment",
        parameters=res.params,
        summary=res.summary,
        timing=res.timing,
        alarm={k: v for k, v in res.alarm.items() if not isinstance(v, np.ndarray)},
        paper=PAPER,
        cases={int(k): v for k, v in CASES.items()},
        contact_classes=CONTACT_CLASSES,
        files={
            k: (os.path.basename(v) if isinstance(v, str) else [os.path.basename(x) for x in v])
            for k, v in paths.items()
        },
    )
    write_json(paths["json"], meta)
    write_text(paths["markdown"], _markdown(res, paths["figures"]))
    return paths
