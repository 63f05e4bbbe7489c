"""What chromasim.figures selects from a dataset: trials, frames, the markers of a trial
(streamed from markers.csv), a meridian of markers along the slip direction, the stick
matrix. Skip is raised for a figure the dataset cannot support."""

from __future__ import annotations

import csv
import os

import numpy as np

from .data import Dataset, DatasetError

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


# ---------------------------------------------------------------------------------------
# Stick/slip
# ---------------------------------------------------------------------------------------

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
