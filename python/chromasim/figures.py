"""The seeds' figures from a dataset, and error-against-run-time plots from benchmark output.

Usage:
  python3 -m chromasim.figures DATASET -o OUTDIR [--trial N] [--frame F] [--finger left]
                               [--bench FILE ...]
  python3 -m chromasim.figures -o OUTDIR --bench FILE ...        (benchmark plots only)

Figures (PNG and SVG, OUTDIR/<name>.png|svg), each written when the dataset has what it
needs, otherwise skipped with the reason printed:
  force_gamma_trialN          forces and Gamma over one trial (seed 000 Fig. 2E)
  safety_margin_by_friction   Gamma against time or travel per friction level, mean +- std
                              (seed 001 Fig. 2E)
  markers_<finger>_trialN_frameF     u_z, u_x, u_y of the 82 markers of each layer over the
                              dome's x-y projection (seed 000 Fig. 3C, 3D)
  markers_quiver_<finger>_trialN_frameF  lateral displacement arrows coloured by u_z (Fig. 3D)
  slip_profile_<finger>       the markers of the meridian along the slip direction, deformed
                              (true scale) and their displacements, for the highest- and
                              lowest-friction trials (seed 000 Fig. 3E)
  stickslip_map               stick ratio of every trial over time, per fingertip; full slip
                              marked
  stickslip_trialN            stick ratio, stick and contact area over one trial
  images_trialN               a grid of the trial's tactile images (both fingertips)
  bench_<file>[_k]            error against run time, one per table of a
                              `chromasim bench mechanics|render --json FILE` file
                              (read_bench_json)
docs/PYTHON.md describes the choices.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import re
import sys
from dataclasses import dataclass

import numpy as np

from .data import Dataset, DatasetError, open_dataset

PHASE_COLOURS = {"grasp": "#dddddd", "hold": "#eeeeee", "load": "#ddeeff", "slip": "#ffdddd",
                 "slide": "#f4f4e0"}
RING_POLAR_DEG = (0.0, 12.5, 25.0, 37.5, 50.0, 62.5)


class Skip(Exception):
    """A figure the dataset cannot support; the message says why."""


# ---------------------------------------------------------------------------------------
# Selection helpers
# ---------------------------------------------------------------------------------------

def trial_rows(ds: Dataset, trial: int) -> np.ndarray:
    rows = np.flatnonzero(ds.labels["trial"] == trial)
    if rows.size == 0:
        raise DatasetError(f"{ds.root}: no trial {trial} in labels.csv "
                           f"(trials {int(ds.labels['trial'].min())} to "
                           f"{int(ds.labels['trial'].max())})")
    return rows[np.argsort(ds.labels["frame"][rows], kind="stable")]


def default_trial(ds: Dataset) -> int:
    """The first trial in which a fingertip slides, else the first trial."""
    lab = ds.labels
    sliding = np.zeros(ds.frames, dtype=bool)
    for f in ds.fingers:
        sliding |= lab[f"{f}_sliding"] > 0
    trials = lab["trial"][sliding] if sliding.any() else lab["trial"]
    return int(trials[0])


def default_frame(ds: Dataset, trial: int, finger: str) -> int:
    """The frame of incipient slip: the non-sliding loaded frame whose Gamma is closest to
    0.5; the trial's last frame when there is none."""
    rows = trial_rows(ds, trial)
    lab = ds.labels
    g = lab[f"{finger}_gamma"][rows]
    ok = (lab[f"{finger}_sliding"][rows] == 0) & (g < 1.0)
    if not ok.any():
        return int(lab["frame"][rows[-1]])
    cand = rows[ok]
    return int(lab["frame"][cand[np.argmin(np.abs(lab[f"{finger}_gamma"][cand] - 0.5))]])


def time_axis(ds: Dataset, rows=None):
    """x values and label: travel (mm) for a slide dataset, time (s) otherwise."""
    lab = ds.labels
    rows = slice(None) if rows is None else rows
    if "travel_mm" in lab and np.all(lab["phase"][rows] == "slide"):
        return lab["travel_mm"][rows], "travel of the object (mm)"
    return lab["time_s"][rows], "time (s)"


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


# ---------------------------------------------------------------------------------------
# Markers
# ---------------------------------------------------------------------------------------

def read_markers(ds: Dataset, trials) -> dict[str, np.ndarray]:
    """The rows of markers.csv of the given trials, as columns (numeric ones float64).
    Streams the file and stops after the last wanted trial (the file is in trial order)."""
    path = ds.path("markers.csv")
    if not os.path.isfile(path):
        raise Skip(f"{path}: no such file (outputs.markers is off)")
    wanted = {int(t) for t in trials}
    last = max(wanted)
    rows = []
    with open(path, newline="") as f:
        reader = csv.reader(f)
        header = next(reader)
        it = header.index("trial")
        for row in reader:
            t = int(row[it])
            if t in wanted:
                rows.append(row)
            elif t > last:
                break
    if not rows:
        raise Skip(f"{path}: no rows of trial(s) {sorted(wanted)}")
    cols = {}
    for j, name in enumerate(header):
        vals = [r[j] for r in rows]
        try:
            cols[name] = np.array(vals, dtype=np.float64)
        except ValueError:
            cols[name] = np.array(vals, dtype=object)
    return cols


def _select(m: dict, **eq) -> np.ndarray:
    mask = np.ones(len(m["trial"]), dtype=bool)
    for k, v in eq.items():
        mask &= m[k] == v
    return mask


def marker_ring(m: dict, mask) -> np.ndarray:
    """Ring of each selected marker (0 = apex, 1..5), from its undeformed polar angle."""
    x, y, z = m["x0_mm"][mask], m["y0_mm"][mask], m["z0_mm"][mask]
    polar = np.degrees(np.arctan2(np.hypot(x, y), z))
    return np.rint(polar / 12.5).astype(int)


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


def slip_direction(ds, trial, finger) -> float:
    """Angle (rad, from +x in the fingertip's frame) of the tangential force at the trial's
    frame where it is largest; 0 when the trial has none."""
    rows = trial_rows(ds, trial)
    fx = ds.labels[f"{finger}_tangential_force_x_N"][rows]
    fy = ds.labels[f"{finger}_tangential_force_y_N"][rows]
    k = int(np.argmax(np.hypot(fx, fy)))
    return float(np.arctan2(fy[k], fx[k])) if np.hypot(fx[k], fy[k]) > 0 else 0.0


def meridian(m, mask, theta) -> np.ndarray:
    """Indices (into m) of the markers of the meridian through the slip direction theta:
    the apex and, per ring, the marker closest in azimuth to theta and to theta + pi;
    sorted by position along the slip direction."""
    idx = np.flatnonzero(mask)
    ring = marker_ring(m, mask)
    az = np.arctan2(m["y0_mm"][idx], m["x0_mm"][idx])
    chosen = list(idx[ring == 0])
    for k in range(1, ring.max() + 1):
        on = ring == k
        for target in (theta, theta + np.pi):
            d = np.abs(np.angle(np.exp(1j * (az[on] - target))))
            chosen.append(idx[on][np.argmin(d)])
    chosen = np.array(sorted(set(chosen)))
    s = m["x0_mm"][chosen] * np.cos(theta) + m["y0_mm"][chosen] * np.sin(theta)
    return chosen[np.argsort(s)]


def friction_extremes(ds, finger) -> list[int]:
    """The trial of highest and of lowest mean mu (one trial when every trial has the same
    mu). Among equal mu, the first trial that slides, else the first."""
    lab = ds.labels
    trials = np.unique(lab["trial"]).astype(int)
    mu = np.array([lab[f"{finger}_mu"][lab["trial"] == t].mean() for t in trials])
    slides = np.array([(lab[f"{finger}_sliding"][lab["trial"] == t] > 0).any() for t in trials])

    def pick(target):
        cand = np.flatnonzero(np.isclose(mu, target, rtol=1e-6, atol=1e-9))
        sl = cand[slides[cand]]
        return int(trials[(sl if sl.size else cand)[0]])
    hi, lo = pick(mu.max()), pick(mu.min())
    return [hi] if hi == lo or np.isclose(mu.max(), mu.min()) else [hi, lo]


def loaded_frames(ds, trial, finger, count=5) -> np.ndarray:
    """Up to `count` frames of the trial under tangential load (load, slip or slide) up to
    the first frame in which the fingertip slides (the transition from stick to slip),
    evenly spaced, first and last included."""
    rows = trial_rows(ds, trial)
    lab = ds.labels
    loaded = rows[np.isin(lab["phase"][rows], ("load", "slip", "slide"))]
    if loaded.size == 0:
        loaded = rows
    sliding = np.flatnonzero(lab[f"{finger}_sliding"][loaded] > 0)
    if sliding.size:
        loaded = loaded[: sliding[0] + 1]
    pick = np.unique(np.round(np.linspace(0, loaded.size - 1, min(count, loaded.size))).astype(int))
    return lab["frame"][loaded[pick]].astype(int)


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
    note = "" if len(trials) == 2 else " (one friction level in this dataset)"
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
    ax.set_title("Safety margin per friction level (mean +- std over trials)")
    ax.legend(fontsize=7)
    return save(fig, outdir, "safety_margin_by_friction")


def stick_matrix(ds, finger):
    """(trials, x values, stick ratio matrix, sliding matrix, x label): one row per trial
    (sorted by mu, then trial), one column per distinct time (or travel) of the dataset;
    NaN where a trial has no frame at that time."""
    lab = ds.labels
    t, tlabel = time_axis(ds)
    t = np.round(t, 6)
    xs = np.unique(t)
    trials = np.unique(lab["trial"]).astype(int)
    mu = np.array([lab[f"{finger}_mu"][lab["trial"] == k].mean() for k in trials])
    order = np.lexsort((trials, mu))
    trials = trials[order]
    row_of = {k: i for i, k in enumerate(trials)}
    S = np.full((len(trials), len(xs)), np.nan)
    L = np.full_like(S, np.nan)
    ri = np.array([row_of[int(k)] for k in lab["trial"]])
    ci = np.searchsorted(xs, t)
    S[ri, ci] = lab[f"{finger}_stick_ratio"]
    L[ri, ci] = lab[f"{finger}_sliding"]
    return trials, xs, S, L, tlabel, mu[order]


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


# ---------------------------------------------------------------------------------------
# Benchmark tables
# ---------------------------------------------------------------------------------------

@dataclass
class BenchTable:
    """One table of a `chromasim bench mechanics|render --json FILE` file."""

    caption: str            # the line the Markdown prints before the table ('' if none)
    header: list[str]
    rows: list[list[str]]   # each cell the text the Markdown shows ('' when empty)

    def column(self, j: int) -> np.ndarray:
        return np.array([_number(r[j]) if j < len(r) else np.nan for r in self.rows])


def _number(cell: str) -> float:
    m = re.fullmatch(r"\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*%?\s*", cell)
    return float(m.group(1)) if m else np.nan


BENCH_JSON = ("written by `chromasim bench mechanics|render --json FILE`: {command, "
              "chromasim_version, tables: [{caption, header, rows}]}")


def read_bench_json(path: str) -> list[BenchTable]:
    """The tables of a bench's JSON file (BENCH_JSON); a cell that is a number is read as
    its text, null as ''. Raises DatasetError naming the path."""
    try:
        with open(path, encoding="utf-8") as f:
            doc = json.load(f)
    except OSError as e:
        raise DatasetError(f"{path}: {e.strerror}") from None
    except ValueError as e:
        raise DatasetError(f"{path}: not JSON ({e}); allowed: a file {BENCH_JSON}") from None
    try:
        tables = doc["tables"]
        if isinstance(tables, list):
            return [_bench_table(t) for t in tables]
    except (KeyError, TypeError, AttributeError):
        pass  # told below
    raise DatasetError(f"{path}: not a bench table file; allowed: a file {BENCH_JSON}")


def _bench_table(t: dict) -> BenchTable:
    header, rows = t["header"], t["rows"]
    if not (isinstance(header, list) and isinstance(rows, list)
            and all(isinstance(r, list) for r in rows)):
        raise TypeError("header and rows are lists")
    return BenchTable(_text(t.get("caption")), [_text(h) for h in header],
                      [[_text(c) for c in r] for r in rows])


def _text(cell) -> str:
    if isinstance(cell, (list, dict)):
        raise TypeError("a cell is text or a number")
    return "" if cell is None else str(cell)


TIME_COLUMNS = ("trial frame ms", "render ms", "frame from rest ms", "frame ms", "time ms",
                "time s", "wall s")
ERROR_COLUMNS = ("rms error", "vs ref", "vs medium", "error")
SERIES_COLUMNS = ("integrator", "mode", "material", "volumetric", "interior")
POINT_COLUMNS = ("spp", "level", "light cache paths per vertex", "size")


def bench_columns(table: BenchTable):
    """(time column, error column, series columns, point-label column) of a table, by
    header names: the time column is the first header starting with one of TIME_COLUMNS
    (in that order of preference), the error column the first containing one of
    ERROR_COLUMNS ('vs ref' is named after the column before it, e.g. indentation mm);
    None when the table has no such pair."""
    low = [h.lower() for h in table.header]

    def first(keys, test):
        for k in keys:
            for j, h in enumerate(low):
                if test(h, k):
                    return j
        return None
    jt = first(TIME_COLUMNS, lambda h, k: h.startswith(k))
    je = first(ERROR_COLUMNS, lambda h, k: k in h and "volume" not in h)
    if jt is None or je is None:
        return None
    series = [j for j, h in enumerate(low) if h in SERIES_COLUMNS]
    point = first(POINT_COLUMNS, lambda h, k: h == k)
    return jt, je, series, point


AXIS_LABELS = {"render ms": "render time per image (ms)",
               "trial frame ms": "time per trial frame (ms)",
               "frame from rest ms (labels)": "time per frame from rest (ms)",
               "rms error %": "RMS error (% of the white level)",
               "less ref noise %": "RMS error less the reference's noise (% of the white level)"}


def _axis_label(header: str, table: BenchTable, j: int) -> str:
    h = header.strip()
    low = h.lower()
    if low in AXIS_LABELS:
        return AXIS_LABELS[low]
    if low.startswith("vs ") and j > 0:
        base = re.sub(r"\s+mm$", "", table.header[j - 1])
        return f"|{base} error {h}| (%)"
    if low.endswith(" ms"):
        return f"{h[:-3]} (ms)"
    if low.endswith(" s"):
        return f"{h[:-2]} (s)"
    if low.endswith("%"):
        return f"{h[:-1].strip()} (% of the white level)" if "error" in low else f"{h[:-1]} (%)"
    return h


def figure_bench(table: BenchTable, stem: str, outdir: str):
    """Error (absolute value, log scale) against time (log scale): one line per series
    (the categorical columns: integrator and mode); with 'vs ref' columns (bench
    mechanics) one line per such column (indentation, apex u_z). Rows of zero error (the
    reference level) are a vertical line at their time."""
    import textwrap

    from .plots import plt, save
    cols = bench_columns(table)
    if cols is None:
        raise Skip("no time and error columns")
    jt, je, series, point = cols
    t = table.column(jt)
    err_cols = [je]
    if table.header[je].lower().startswith("vs "):
        err_cols = [j for j, h in enumerate(table.header) if h == table.header[je]]
    if not any((np.isfinite(t) & np.isfinite(table.column(j))).any() for j in err_cols):
        raise Skip("no row with a number in both the time and the error column")
    fig, ax = plt.subplots(figsize=(6, 4.2), layout="constrained")
    keys = [" ".join(r[j] for j in series if j < len(r)) for r in table.rows]
    refs = set()
    for j in err_cols:
        e = np.abs(table.column(j))
        ok = np.isfinite(t) & np.isfinite(e)
        refs.update(int(i) for i in np.flatnonzero(ok & (e == 0)))
        name = re.sub(r"\s+mm$", "", table.header[j - 1]) if len(err_cols) > 1 else ""
        for key in dict.fromkeys(k for k, o in zip(keys, ok) if o):
            idx = sorted((i for i, (k, o) in enumerate(zip(keys, ok)) if o and k == key
                          and e[i] > 0), key=lambda i: t[i])
            if not idx:
                continue
            ax.plot(t[idx], e[idx], "o-", label=" ".join(x for x in (key, name) if x) or None)
            if point is not None:
                for i in idx:
                    ax.annotate(table.rows[i][point], (t[i], e[i]), textcoords="offset points",
                                xytext=(3, 3), fontsize=7)
    for i in sorted(refs):
        what = table.rows[i][point] if point is not None else f"row {i + 1}"
        ax.axvline(t[i], color="grey", ls=":", lw=1, label=f"reference {what} (0 error)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    _decade_limits(ax)
    ax.set_xlabel(_axis_label(table.header[jt], table, jt))
    ylabel = _axis_label(table.header[je], table, je)
    if len(err_cols) > 1:
        ylabel = f"|error {table.header[je]}| (%)"
    ax.set_ylabel(ylabel)
    cap = textwrap.shorten(table.caption, 300, placeholder=" ...")
    labels = f" (point labels: {table.header[point]})" if point is not None else ""
    ax.set_title("\n".join([f"error against run time{labels}"] + textwrap.wrap(cap, 110)),
                 fontsize=7)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7)
    ax.grid(True, which="both", lw=0.3, alpha=0.5)
    return save(fig, outdir, stem)


def _decade_limits(ax):
    """Log axes spanning whole decades, tick labels as plain numbers."""
    from matplotlib.ticker import FuncFormatter, NullFormatter
    for axis, get, set_ in ((ax.xaxis, ax.get_xlim, ax.set_xlim),
                            (ax.yaxis, ax.get_ylim, ax.set_ylim)):
        lo, hi = get()
        if lo > 0 and hi > lo:
            set_(10 ** np.floor(np.log10(lo)), 10 ** np.ceil(np.log10(hi)))
        axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        axis.set_minor_formatter(NullFormatter())


def bench_figures(path: str, outdir: str, report) -> list[str]:
    tables = read_bench_json(path)
    if not tables:
        report(f"bench {path}", "no table in the file")
        return []
    base = re.sub(r"[^A-Za-z0-9_-]+", "_", os.path.splitext(os.path.basename(path))[0])
    stem = base if base.startswith("bench") else f"bench_{base}"
    out = []
    for k, table in enumerate(tables):
        name = stem if len(tables) == 1 else f"{stem}_{k + 1}"
        try:
            out += figure_bench(table, name, outdir)
        except Skip as e:
            report(name, f"table {k + 1} ({' | '.join(table.header[:4])} ...): {e}")
    return out


# ---------------------------------------------------------------------------------------
# Command line
# ---------------------------------------------------------------------------------------

def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python3 -m chromasim.figures",
        description="The seeds' figures from a dataset (seed 000 Fig. 2E, 3C-3E; seed 001 "
                    "Fig. 2E; stick/slip; sample images) and error-against-run-time plots "
                    "from `chromasim bench mechanics|render --json FILE` files. PNG and SVG.")
    p.add_argument("dataset", nargs="?", help="dataset folder written by `chromasim generate`")
    p.add_argument("-o", "--out", required=True, help="output folder (created)")
    p.add_argument("--trial", type=int, default=None,
                   help="trial of the per-trial figures (default: the first that slides)")
    p.add_argument("--frame", type=int, default=None,
                   help="frame of the marker maps (default: per fingertip, the non-sliding "
                        "frame with Gamma closest to 0.5)")
    p.add_argument("--finger", choices=("left", "right"), default=None,
                   help="fingertip of the marker figures (default: every fingertip)")
    p.add_argument("--bench", nargs="+", default=[], metavar="FILE",
                   help="JSON written by `chromasim bench mechanics|render --json FILE`")
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if not args.dataset and not args.bench:
        sys.exit("figures: give a DATASET and/or --bench FILE ...")
    written, skipped = [], []

    def report(name, why):
        skipped.append(name)
        print(f"figures: skipped {name}: {why}")

    def attempt(name, fn, *a):
        try:
            written.extend(fn(*a))
        except Skip as e:
            report(name, str(e))

    os.makedirs(args.out, exist_ok=True)
    if args.dataset:
        try:
            ds = open_dataset(args.dataset)
            trial = default_trial(ds) if args.trial is None else args.trial
            trial_rows(ds, trial)
        except DatasetError as e:
            sys.exit(f"figures: {_named(e, args.dataset)}")
        _dataset_figures(ds, trial, args, attempt, report)
    for path in args.bench:
        try:
            written.extend(bench_figures(path, args.out, report))
        except DatasetError as e:
            sys.exit(f"figures: --bench {e}")
    for p in written:
        print(f"figures: wrote {p}")
    print(f"figures: {len(written)} files in {args.out}, {len(skipped)} figures skipped")
    return 0 if written else 1


def _dataset_figures(ds, trial, args, attempt, report):
    out = args.out
    fingers = [args.finger] if args.finger else list(ds.fingers)
    attempt("force_gamma", figure_force_gamma, ds, trial, out)
    attempt("safety_margin_by_friction", figure_safety_margin_by_friction, ds, fingers[0], out)
    attempt("stickslip_map", figure_stickslip_map, ds, out)
    attempt("stickslip_trial", figure_stickslip_trial, ds, trial, out)
    attempt("images", figure_images, ds, trial, out)
    try:
        m = read_markers(ds, [trial])
    except Skip as e:
        for f in fingers:
            report(f"markers_{f}", str(e))
            report(f"slip_profile_{f}", str(e))
        return
    for f in fingers:
        frame = default_frame(ds, trial, f) if args.frame is None else args.frame
        attempt(f"markers_{f}", figure_marker_maps, ds, m, trial, frame, f, out)
        attempt(f"markers_quiver_{f}", figure_marker_quiver, ds, m, trial, frame, f, out)
        attempt(f"slip_profile_{f}", figure_slip_profile, ds, f, out)


def _named(error: Exception, path: str) -> str:
    """The error's message, prefixed with the path unless it names the folder already."""
    text = str(error)
    return text if (path in text or os.path.abspath(path) in text) else f"{path}: {text}"


if __name__ == "__main__":
    sys.exit(main())
