"""The experiment's figures (PNG and SVG; need matplotlib): cf. the paper's Figs. 10 and 11.

See docs/methods/experiment.md.
"""

from __future__ import annotations

import numpy as np

from ...geometry import convex_hull
from ..report import new_figure, save_figure
from .contour import contour_panels
from .model import UM


def plot_experiment(res, out_dir, *, stem="experiment"):
    """Draw the figures (PNG and SVG): cf. the paper's Figs. 10, 11a and 11b-c, and the collision alarm.

    Parameters
    ----------
    res : ExperimentResult
    out_dir : str or pathlib.Path
    stem : str
        File name prefix.

    Returns
    -------
    list of str
        The file paths.
    """
    files = []
    files += _plot_contours(res, out_dir, f"{stem}_fig10_contours")
    files += _plot_trajectory(res, out_dir, f"{stem}_fig11a_trajectory")
    files += _plot_states(res, out_dir, f"{stem}_fig11bc_states_forces")
    if res.alarm:
        files += _plot_alarm(res, out_dir, f"{stem}_alarm")
    return files


def _closed(P):
    return np.vstack([P, P[:1]])


def _plot_contours(res, out, name):
    panels, poly_a = contour_panels(res)
    ncol = 3
    nrow = -(-len(panels) // ncol)
    fig = new_figure(figsize=(10.5, 3.35 * nrow + 0.6), layout="constrained")
    axes = fig.subplots(nrow, ncol, squeeze=False)
    allpts = np.vstack([poly_a, *(P["end_face"] for P in panels)])
    lo, hi = allpts.min(axis=0) - 0.3, allpts.max(axis=0) + 0.3
    for i, P in enumerate(panels):
        ax = axes[i // ncol][i % ncol]
        Q, ef, c = P["projection"], P["end_face"], P["centre"]
        ax.fill(*_closed(poly_a).T, color="tab:red", alpha=0.15, lw=0)
        ax.plot(*_closed(poly_a).T, color="tab:red", lw=1.5, label="a's end face")
        ax.plot(*_closed(ef).T, color="0.45", lw=1.0, ls=":", label="b's end face, projected")
        if len(Q) >= 3:
            ax.fill(*_closed(Q).T, color="tab:blue", alpha=0.25, lw=0)
            ax.plot(*_closed(Q).T, color="tab:blue", lw=1.5, label="b ∩ a's half-space, projected")
        ax.plot([0], [0], "+", color="tab:red", ms=8, label="end-face centres")
        ax.plot([c[0]], [c[1]], "+", color="tab:blue", ms=8)
        if P["hit"]:
            ax.plot([P["contact"][0]], [P["contact"][1]], "x", color="black", ms=8, mew=2, label="contact point")
        hit = ", collision" if P["hit"] else ""
        title = (
            f"t = {P['t']:g} s: case {P['case']}{hit}"
            if P["label"] is None
            else f"{P['label']}, t = {P['t']:.2f} s: case {P['case']}{hit}"
        )
        if not len(Q):
            title += " (no projection)"
        ax.set_title(title, fontsize=10, color="tab:red" if P["hit"] else "black")
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
    for j in range(len(panels), nrow * ncol):
        axes[j // ncol][j % ncol].set_visible(False)
    seen = {}
    for ax in fig.axes:
        for hh, ll in zip(*ax.get_legend_handles_labels()):
            seen.setdefault(ll, hh)
    fig.suptitle(
        f"Projected contours on a's end plane (along d_a, seen from above), {res.params['prism']} prism "
        "— cf. paper Fig. 10",
        fontsize=11,
    )
    fig.legend(list(seen.values()), list(seen.keys()), loc="outside lower center", ncol=5, fontsize=9)
    return save_figure(fig, out, name)


def _silhouette(points_world, s_axis, z_axis):
    return convex_hull(np.column_stack([points_world @ s_axis, points_world @ z_axis]))


def _plot_trajectory(res, out, name):
    g = res.geometry
    Ra, pa, Rb = g["rot_a"], g["pos_a"], g["rot_b"]
    da = Ra[:, 2]
    x0, xd = res.dc[0], np.asarray(res.params["xd_um"]) * UM
    w = np.cross(da, xd - x0)
    w /= np.linalg.norm(w)  # viewing axis, parallel with d_a x (x_d - x_0)
    z_ax = -da  # up on the page
    s_ax = np.cross(z_ax, w)  # completes a right-handed screen frame (s, z) seen along w
    fig = new_figure(figsize=(7.5, 8.0), layout="constrained")
    ax = fig.add_subplot()
    depth = 3.0
    a_face = pa + g["xy_a"] @ Ra[:, :2].T
    A = _silhouette(np.vstack([a_face, a_face + depth * da]), s_ax, z_ax)
    ax.fill(*_closed(A).T, color="tab:red", alpha=0.15, lw=0)
    ax.plot(*_closed(A).T, color="tab:red", lw=1.5, label="a")
    blen = 2.5
    for k, col, lab in ((0, "black", "b, initial"), (len(res.t) - 1, "tab:blue", "b, final")):
        pb_ = pa + res.dc[k]
        for xy, ls, extra in (
            (g["xy_b_real"], "-", f" ({1e3 * res.params['b_real_diameter_mm']:.0f} µm)"),
            (g["xy_b"], ":", f" (protective {res.params['b_diameter_mm']:g} mm)"),
        ):
            face = pb_ + xy @ Rb[:, :2].T
            S = _silhouette(np.vstack([face, face + blen * Rb[:, 2]]), s_ax, z_ax)
            ax.plot(*_closed(S).T, color=col, lw=1.3, ls=ls, label=lab + extra)
    tr = pa + res.dc
    ax.plot(tr @ s_ax, tr @ z_ax, color="magenta", lw=1.5, label="b's end-face centre")
    hk = np.flatnonzero(res.hit)
    if len(hk):
        ax.plot(tr[hk] @ s_ax, tr[hk] @ z_ax, "o", color="magenta", mfc="none", ms=7, label="b at a collision")
        cp = res.contact[hk]
        ax.plot(cp @ s_ax, cp @ z_ax, "x", color="tab:red", ms=8, mew=2, label="contact point")
        sc = 0.4
        for q, d in zip(cp, res.direction[hk]):
            ax.annotate(
                "",
                xy=(q @ s_ax + sc * (d @ s_ax), q @ z_ax + sc * (d @ z_ax)),
                xytext=(q @ s_ax, q @ z_ax),
                arrowprops=dict(arrowstyle="->", color="tab:green", lw=1.5),
            )
        ax.plot([], [], color="tab:green", lw=1.5, label="detach direction (in view)")
    ax.plot([xd @ s_ax], [xd @ z_ax], "*", color="tab:blue", ms=12, label="goal")
    ax.set_aspect("equal")
    ax.grid(alpha=0.3)
    ax.set_xlabel("along the horizontal part of x_d − x_0 (mm)")
    ax.set_ylabel("height, −d_a = z (mm)")
    ax.set_title(
        f"Trajectory of b, {res.params['prism']} prism — cf. paper Fig. 11a\n"
        f"seen along d_a × (x_d − x_0) ∥ ({w[0]:.3f}, {w[1]:.3f}, {w[2]:.3f})",
        fontsize=10,
    )
    fig.legend(loc="outside lower center", ncol=3, fontsize=8.5)
    return save_figure(fig, out, name)


def _plot_states(res, out, name):
    p, t = res.params, res.t
    vel = p["plant"] == "velocity"
    unit = "µm/s" if vel else "µN"
    fig = new_figure(figsize=(9.0, 9.0), layout="constrained")
    axs = fig.subplots(4, 1, sharex=True, height_ratios=[3, 2.2, 2.2, 1.2])
    cols = ("tab:blue", "tab:orange", "tab:green")
    hk = np.flatnonzero(res.hit)
    xd = np.asarray(p["xd_um"])
    for i, c in enumerate("xyz"):
        axs[0].plot(t, res.dc[:, i] / UM, color=cols[i], label=f"ΔC_{c}")
        axs[0].axhline(xd[i], color=cols[i], ls="--", lw=0.8)
    axs[0].plot([], [], color="0.3", ls="--", lw=0.8, label="goal")
    axs[0].set_ylabel("state ΔC (µm)")
    axs[0].set_title(f"(b) state and (c) inputs, {p['prism']} prism, {p['plant']} plant — cf. Fig. 11b, c", fontsize=10)
    for i, c in enumerate("xyz"):
        axs[1].plot(t, 1e3 * res.u_pd[:, i], color=cols[i], label=f"u_pd,{c}")
    axs[1].set_ylabel(f"attraction u_pd ({unit})")
    for i, c in enumerate("xyz"):
        if len(hk):
            m, st, b = axs[2].stem(
                t[hk], 1e3 * res.u_d[hk, i], linefmt=cols[i], markerfmt="o", basefmt=" ", label=f"u_d,{c}"
            )
            m.set_color(cols[i])
    axs[2].axhline(0.0, color="0.5", lw=0.8)
    axs[2].set_ylabel(f"detach u_d ({unit})")
    if not len(hk):
        axs[2].text(0.5, 0.5, "no collision: no detach input", transform=axs[2].transAxes, ha="center")
    axs[3].step(t, res.case, where="post", color="0.2", label="case")
    if len(hk):
        axs[3].plot(t[hk], res.case[hk], "o", color="tab:red", ms=5, label="collision")
    axs[3].set_ylabel("case")
    axs[3].set_yticks(sorted(set(int(c) for c in res.case)))
    axs[3].set_xlabel("time (s)")
    for ax in axs:
        for k in hk:
            ax.axvline(t[k], color="tab:red", lw=0.7, ls=":")
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right", fontsize=8, ncol=4 if ax is not axs[0] else 4)
    return save_figure(fig, out, name)


def _plot_alarm(res, out, name):
    """Time to impact and probability of a collision within the horizon against time, contacts marked."""
    al, t = res.alarm, res.t
    fig = new_figure(figsize=(9.0, 6.0), layout="constrained")
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    toi = np.where(np.isfinite(al["toi_s"]), al["toi_s"], np.nan)  # inf (clear) left out
    ax1.plot(t, toi, color="tab:blue", lw=1.2, label="time to impact (measured position)")
    ax1.axhline(al["horizon_s"], color="0.5", ls="--", lw=0.8, label=f"horizon {al['horizon_s']:g} s")
    ax1.set_ylabel("time to impact (s)")
    ax1.set_ylim(0.0, 1.05 * al["horizon_s"])
    ax1.set_title(
        f"{res.params['prism']} prism: (a) time to impact along the commanded motion,\n(b) probability of a "
        f"collision within {al['horizon_s']:g} s under camera noise of {al['sigma_um']:g} µm per axis",
        fontsize=10,
    )
    te = al["t_eval"]
    ax2.fill_between(
        te,
        al["low"],
        al["high"],
        step="mid",
        color="tab:orange",
        alpha=0.3,
        lw=0,
        label=f"{100 * al['confidence']:g} % interval",
    )
    ax2.step(te, al["p"], where="mid", color="tab:orange", label=f"p ({al['samples']} samples)")
    ax2.axhline(al["threshold"], color="0.3", ls="--", lw=0.8, label=f"alarm threshold {al['threshold']:g}")
    ax2.set_ylabel("P(collision within horizon)")
    ax2.set_ylim(-0.02, 1.02)
    ax2.set_xlabel("time (s)")
    for ax in (ax1, ax2):
        for k in np.flatnonzero(res.hit):
            ax.axvline(t[k], color="tab:red", lw=0.8, ls=":")
        if al["alarm_s"] is not None:
            ax.axvline(al["alarm_s"], color="tab:green", lw=1.0)
        ax.plot([], [], color="tab:red", lw=0.8, ls=":", label="contact (collide)")
        if al["alarm_s"] is not None:
            ax.plot([], [], color="tab:green", lw=1.0, label=f"alarm at {al['alarm_s']:.2f} s")
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
    return save_figure(fig, out, name)
