"""The dataset figures of chromasim.figures: marker maps and slip profiles, forces and
Gamma, stick/slip, tactile images. Each returns the paths it wrote or raises Skip."""

from __future__ import annotations

import numpy as np

from .figures_data import (Skip, _select, friction_extremes, loaded_frames, meridian,
                           read_markers, slip_direction, stick_matrix, time_axis, trial_rows)

PHASE_COLOURS = {"grasp": "#dddddd", "hold": "#eeeeee", "load": "#ddeeff", "slip": "#ffdddd",
                 "slide": "#f4f4e0"}


# ---------------------------------------------------------------------------------------
# Markers
# ---------------------------------------------------------------------------------------

def figure_marker_maps(ds, m, trial, frame, finger, outdir):
    from matplotlib.tri import Triangulation

    from .plots import plt, save, symmetric_limit
    layers = ("inner", "outer")
    comps = (("uz_mm", "u_z"), ("ux_mm", "u_x"), ("uy_mm", "u_y"))
    sel = {ly: _select(m, trial=trial, frame=frame, finger=finger, layer=ly) for ly in layers}
    if not all(s.any() for s in sel.values()):
        raise Skip(f"markers.csv: no rows for trial {trial}, frame {frame}, {finger}")
    fig, axes = plt.subplots(2, 3, figsize=(11, 6.6), layout="constrained")
    for j, (col, name) in enumerate(comps):
        lim = symmetric_limit(np.concatenate([m[col][sel[ly]] for ly in layers]))
        for i, ly in enumerate(layers):
            ax = axes[i, j]
            s = sel[ly]
            x, y, u = m["x0_mm"][s], m["y0_mm"][s], m[col][s]
            tri = Triangulation(x, y)
            cs = ax.tricontourf(tri, u, levels=np.linspace(-lim, lim, 21), cmap="RdBu_r")
            ax.scatter(x, y, s=6, c="k", lw=0)
            ax.set_aspect("equal")
            ax.set_xlabel("x0 (mm)")
            ax.set_ylabel("y0 (mm)")
            ax.set_title(f"{name}, {ly} layer")
            if i == 1:
                fig.colorbar(cs, ax=axes[:, j], shrink=0.7, label=f"{name} (mm)",
                             ticks=np.linspace(-lim, lim, 5))
    fig.suptitle(_frame_title(ds, trial, frame, finger) + "\nmarker displacement over the "
                 "dome (x-y projection of the undeformed centres, interpolated between markers)")
    return save(fig, outdir, f"markers_{finger}_trial{trial}_frame{frame}")


def figure_marker_quiver(ds, m, trial, frame, finger, outdir):
    from .plots import plt, save, symmetric_limit
    layers = ("inner", "outer")
    sel = {ly: _select(m, trial=trial, frame=frame, finger=finger, layer=ly) for ly in layers}
    if not all(s.any() for s in sel.values()):
        raise Skip(f"markers.csv: no rows for trial {trial}, frame {frame}, {finger}")
    lat = np.concatenate([np.hypot(m["ux_mm"][s], m["uy_mm"][s]) for s in sel.values()])
    gain = nice_gain(2.0 / max(float(lat.max()), 1e-9))  # longest arrow about 2 mm
    lim = symmetric_limit(np.concatenate([m["uz_mm"][s] for s in sel.values()]))
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.6), layout="constrained")
    for ax, ly in zip(axes, layers):
        s = sel[ly]
        x, y = m["x0_mm"][s], m["y0_mm"][s]
        q = ax.scatter(x, y, s=28, c=m["uz_mm"][s], cmap="RdBu_r", vmin=-lim, vmax=lim,
                       edgecolors="grey", linewidths=0.3, zorder=1)
        qv = ax.quiver(x, y, m["ux_mm"][s] * gain, m["uy_mm"][s] * gain, angles="xy",
                       scale_units="xy", scale=1, width=0.004, color="k", zorder=2)
        ax.quiverkey(qv, 0.80, 1.02, 1.0, f"{1 / gain:g} mm", labelpos="E",
                     coordinates="axes", fontproperties={"size": 7})
        ax.set_aspect("equal")
        r = float(np.hypot(x, y).max()) + 2.5
        ax.set_xlim(-r, r)
        ax.set_ylim(-r, r)
        ax.set_xlabel("x0 (mm)")
        ax.set_ylabel("y0 (mm)")
        ax.set_title(f"{ly} layer: arrows (u_x, u_y) x {gain:g}; dots: u_z", loc="left")
    fig.colorbar(q, ax=axes, shrink=0.8, label="u_z (mm)")
    fig.suptitle(_frame_title(ds, trial, frame, finger) + ": lateral marker displacement")
    return save(fig, outdir, f"markers_quiver_{finger}_trial{trial}_frame{frame}")


def nice_gain(g: float) -> float:
    """The largest of 1, 2, 5 times a power of ten not above g."""
    e = np.floor(np.log10(g))
    for k in (5.0, 2.0, 1.0):
        if k * 10 ** e <= g:
            return float(k * 10 ** e)
    return float(10 ** e)


def _frame_title(ds, trial, frame, finger):
    lab = ds.labels
    i = np.flatnonzero((lab["trial"] == trial) & (lab["frame"] == frame))[0]
    return (f"trial {trial} frame {frame} ({lab['phase'][i]}, t = {lab['time_s'][i]:.2f} s, "
            f"{finger} Gamma = {lab[f'{finger}_gamma'][i]:.2f}, mu = {lab[f'{finger}_mu'][i]:.2f})")


def figure_slip_profile(ds, finger, outdir):
    from .plots import plt, save
    trials = friction_extremes(ds, finger)
    m = read_markers(ds, trials)
    fig, axes = plt.subplots(2, len(trials), figsize=(5.4 * len(trials), 6.8), squeeze=False,
                             layout="constrained")
    for c, trial in enumerate(trials):
        theta = slip_direction(ds, trial, finger)
        frames = loaded_frames(ds, trial, finger)
        colours = plt.cm.viridis(np.linspace(0, 0.9, len(frames)))
        ax, bx = axes[0, c], axes[1, c]
        for ly, style in (("inner", "--"), ("outer", "-")):
            base = _select(m, trial=trial, frame=frames[0], finger=finger, layer=ly)
            mid = meridian(m, base, theta)
            s0 = m["x0_mm"][mid] * np.cos(theta) + m["y0_mm"][mid] * np.sin(theta)
            ax.plot(s0, m["z0_mm"][mid], style, color="grey", lw=1,
                    label=f"{ly}, undeformed")
            for col, fr in zip(colours, frames):
                sel = _select(m, trial=trial, frame=fr, finger=finger, layer=ly)
                mk = meridian(m, sel, theta)
                ux, uy, uz = m["ux_mm"][mk], m["uy_mm"][mk], m["uz_mm"][mk]
                us = ux * np.cos(theta) + uy * np.sin(theta)
                ax.plot(s0 + us, m["z0_mm"][mk] + uz, style, marker="o", ms=2.5, color=col,
                        lw=1)
                if ly == "outer":
                    t = _frame_label(ds, trial, fr, finger)
                    bx.plot(s0, us, "-o", ms=2.5, color=col, label=f"u_s, {t}")
                    bx.plot(s0, uz, ":", color=col, lw=1.2)
        mu = ds.labels[f"{finger}_mu"][ds.labels["trial"] == trial][0]
        ax.set_title(f"trial {trial}, mu = {mu:.2f}: meridian along the slip direction "
                     f"({int(round(np.degrees(theta)))} deg), true scale")
        ax.set_xlabel("s, position along the slip direction (mm)")
        ax.set_ylabel("z (mm)")
        ax.set_aspect("equal")
        ax.legend(fontsize=6, loc="lower center")
        bx.axhline(0, color="k", lw=0.5)
        bx.set_xlabel("s0, undeformed position along the slip direction (mm)")
        bx.set_ylabel("displacement (mm)")
        bx.set_title("outer layer: u_s along the slip direction (solid), u_z (dotted)")
        bx.legend(fontsize=6)
    note = "" if len(trials) == 2 else " (one friction condition in this dataset)"
    fig.suptitle(f"{finger} fingertip, marker displacement along the slip direction, highest "
                 f"and lowest friction{note}")
    return save(fig, outdir, f"slip_profile_{finger}")


def _frame_label(ds, trial, frame, finger):
    lab = ds.labels
    i = np.flatnonzero((lab["trial"] == trial) & (lab["frame"] == frame))[0]
    if lab["phase"][i] == "slide":
        return f"{lab['travel_mm'][i]:.2f} mm, Gamma {lab[f'{finger}_gamma'][i]:.2f}"
    return f"{lab['time_s'][i]:.2f} s, Gamma {lab[f'{finger}_gamma'][i]:.2f}"


# ---------------------------------------------------------------------------------------
# Labels
# ---------------------------------------------------------------------------------------

def _shade_phases(ax, t, phases):
    """Background spans per phase, from midpoint to midpoint between frames."""
    if len(t) == 0:
        return
    edges = np.concatenate([[t[0] - (t[1] - t[0]) / 2 if len(t) > 1 else t[0] - 0.5],
                            (t[1:] + t[:-1]) / 2,
                            [t[-1] + (t[-1] - t[-2]) / 2 if len(t) > 1 else t[0] + 0.5]])
    seen = set()
    for i, ph in enumerate(phases):
        label = ph if ph not in seen else None
        seen.add(ph)
        ax.axvspan(edges[i], edges[i + 1], color=PHASE_COLOURS.get(ph, "#f0f0f0"), lw=0,
                   label=label, zorder=0)


def figure_force_gamma(ds, trial, outdir):
    from .plots import plt, save
    rows = trial_rows(ds, trial)
    lab = ds.labels
    t, tlabel = time_axis(ds, rows)
    fig, (ax, bx) = plt.subplots(2, 1, figsize=(7, 5.6), sharex=True, layout="constrained")
    _shade_phases(ax, t, lab["phase"][rows])
    colours = {"left": "tab:blue", "right": "tab:orange"}
    widths = {"left": 2.6, "right": 1.2}  # the right fingertip's lines on top, thinner
    for f in ds.fingers:
        c, w = colours[f], widths[f]
        ax.plot(t, lab[f"{f}_normal_force_N"][rows], "-", color=c, lw=w, label=f"{f}: grip f_n")
        ax.plot(t, lab[f"{f}_tangential_force_N"][rows], "--", color=c, lw=w,
                label=f"{f}: f_t")
        ax.plot(t, lab[f"{f}_frictional_strength_N"][rows], ":", color=c, lw=w,
                label=f"{f}: strength mu f_n")
        bx.plot(t, lab[f"{f}_gamma"][rows], "-o", ms=2 + w, lw=w, color=c, label=f"{f} Gamma")
    if "load_N" in lab and np.ptp(lab["load_N"][rows]) > 0:
        ax.plot(t, lab["load_N"][rows], "-", color="k", lw=1.5, label="load (total)")
    if len(ds.fingers) > 1:
        bx.plot(t, ds.grasp_gamma()[rows], "-", color="k", lw=1.5, label="grasp Gamma")
    ax.set_ylabel("force (N)")
    ax.legend(fontsize=7, ncol=2, loc="best")
    bx.set_ylabel("safety margin Gamma (-)")
    bx.set_ylim(-0.05, 1.05)
    bx.set_xlabel(tlabel)
    bx.legend(fontsize=7)
    ax.set_title(f"trial {trial} ({lab['object'][rows[0]]}, {lab['friction'][rows[0]]}, grip "
                 f"{lab['grip_N'][rows[0]]:.2f} N): forces and safety margin")
    return save(fig, outdir, f"force_gamma_trial{trial}")


def figure_safety_margin_by_friction(ds, finger, outdir):
    from .plots import plt, save
    lab = ds.labels
    t, tlabel = time_axis(ds)
    t = np.round(t, 9)
    names = list(dict.fromkeys(lab["friction"]))
    mean_mu = {f: float(lab[f"{finger}_mu"][lab["friction"] == f].mean()) for f in names}
    names.sort(key=lambda f: mean_mu[f])
    colours = plt.cm.viridis(np.linspace(0, 0.95, max(len(names), 2)))
    fig, ax = plt.subplots(figsize=(6, 3.8), layout="constrained")
    g = lab[f"{finger}_gamma"]
    for c, f in zip(colours, names):
        m = lab["friction"] == f
        ts = np.unique(t[m])
        mean = np.array([g[m & (t == v)].mean() for v in ts])
        std = np.array([g[m & (t == v)].std() for v in ts])
        n = len(np.unique(lab["trial"][m]))
        ax.plot(ts, mean, "-", color=c, label=f"{f} (mu {mean_mu[f]:.2f}, {n} trials)")
        ax.fill_between(ts, mean - std, mean + std, color=c, alpha=0.2, lw=0)
    ax.set_xlabel(tlabel)
    ax.set_ylabel(f"{finger} safety margin Gamma (-)")
    ax.set_ylim(-0.05, 1.05)
    ax.set_title("Safety margin per friction condition (mean +- std over trials)")
    ax.legend(fontsize=7)
    return save(fig, outdir, "safety_margin_by_friction")


def figure_stickslip_map(ds, outdir):
    from matplotlib.colors import ListedColormap

    from .plots import plt, save
    fingers = ds.fingers
    fig, axes = plt.subplots(1, len(fingers), figsize=(5.5 * len(fingers), 4.8), squeeze=False,
                             layout="constrained")
    for ax, f in zip(axes[0], fingers):
        trials, xs, S, L, tlabel, mu = stick_matrix(ds, f)
        if len(xs) > 1:
            mids = (xs[1:] + xs[:-1]) / 2
            xe = np.concatenate([[xs[0] - (mids[0] - xs[0])], mids, [xs[-1] + (xs[-1] - mids[-1])]])
        else:
            xe = np.array([xs[0] - 0.5, xs[0] + 0.5])
        ye = np.arange(len(trials) + 1) - 0.5
        pm = ax.pcolormesh(xe, ye, np.ma.masked_invalid(S), cmap="viridis", vmin=0, vmax=1,
                           rasterized=True)  # a raster in the SVG: thousands of cells
        slide = np.ma.masked_where(~(L > 0), np.ones_like(S))
        ax.pcolormesh(xe, ye, slide, cmap=ListedColormap(["#d62728"]), vmin=0, vmax=1,
                      rasterized=True)
        ax.set_xlabel(tlabel)
        ax.set_ylabel("trial (sorted by mu)")
        step = max(1, len(trials) // 12)
        ax.set_yticks(np.arange(0, len(trials), step),
                      [f"{trials[i]} ({mu[i]:.2f})" for i in range(0, len(trials), step)],
                      fontsize=6)
        ax.set_title(f"{f}: stick area / contact area; red: whole contact slips")
    fig.colorbar(pm, ax=axes[0], shrink=0.8, label="stick ratio (-)")
    fig.suptitle("Stick/slip over time, every trial (tick labels: trial (mu)); blank: no frame")
    return save(fig, outdir, "stickslip_map")


def figure_stickslip_trial(ds, trial, outdir):
    from .plots import plt, save
    rows = trial_rows(ds, trial)
    lab = ds.labels
    t, tlabel = time_axis(ds, rows)
    fig, (ax, bx) = plt.subplots(2, 1, figsize=(7, 5.2), sharex=True, layout="constrained")
    colours = {"left": "tab:blue", "right": "tab:orange"}
    for f in ds.fingers:
        c = colours[f]
        ax.plot(t, lab[f"{f}_stick_ratio"][rows], "-o", ms=3, color=c, label=f"{f} stick ratio")
        sl = lab[f"{f}_sliding"][rows] > 0
        if sl.any():
            ax.plot(t[sl], np.zeros(sl.sum()) - 0.04 * (1 + ds.fingers.index(f)), "x",
                    color=c, label=f"{f}: whole contact slips")
        w = 2.6 if f == "left" else 1.2  # the right fingertip's lines on top, thinner
        bx.plot(t, lab[f"{f}_contact_area_mm2"][rows], "-", color=c, lw=w,
                label=f"{f} contact area")
        bx.plot(t, lab[f"{f}_stick_area_mm2"][rows], "--", color=c, lw=w,
                label=f"{f} stick area")
    ax.set_ylabel("stick ratio (-)")
    ax.set_ylim(-0.12, 1.05)
    ax.legend(fontsize=7)
    ax.set_title(f"trial {trial}: stick/slip over the trial")
    bx.set_ylabel("area (mm^2)")
    bx.set_xlabel(tlabel)
    bx.legend(fontsize=7)
    return save(fig, outdir, f"stickslip_trial{trial}")


def figure_images(ds, trial, outdir, count=6):
    import matplotlib.image as mpimg

    from .plots import plt, save
    rows = trial_rows(ds, trial)
    lab = ds.labels
    cols = [f"{f}_image" for f in ds.fingers]
    if any(c not in lab for c in cols) or all(
            not isinstance(v, str) or not v for c in cols for v in lab[c][rows]):
        raise Skip("no images in this dataset (outputs.images is off)")
    pick = rows[np.unique(np.round(np.linspace(0, len(rows) - 1, min(count, len(rows))))
                          .astype(int))]
    fig, axes = plt.subplots(len(ds.fingers), len(pick),
                             figsize=(1.9 * len(pick), 2.1 * len(ds.fingers)), squeeze=False,
                             layout="constrained")
    for i, f in enumerate(ds.fingers):
        for j, r in enumerate(pick):
            ax = axes[i, j]
            rel = lab[f"{f}_image"][r]
            ax.imshow(mpimg.imread(ds.path(rel)))
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(f"{f} t={lab['time_s'][r]:.2f} s\nGamma {lab[f'{f}_gamma'][r]:.2f} "
                         f"({lab['phase'][r]})", fontsize=7)
    h, w = mpimg.imread(ds.path(lab[f"{ds.fingers[0]}_image"][pick[0]])).shape[:2]
    fig.suptitle(f"trial {trial}: tactile images ({w} x {h} px, image x right = camera +x, "
                 "image y down = camera +y)")
    return save(fig, outdir, f"images_trial{trial}")
