"""A non-learned Gamma from the tracked markers (chromasim.tracker): Hertz for the normal
force, Mindlin's initial tangential stiffness for the tangential one, and a prior mu.

    cal = calibrate(sensor, "curved")                 # a press and a pull of known force
    est = FieldGamma(cal, mu_prior=0.8)
    gamma = est.grasp([tracker_left.track(l), tracker_right.track(r)])

    python3 -m chromasim.tracker_gamma DATASET -o predictions.csv [--object curved]

Per fingertip, over the outer markers within 20 deg of the apex: their mean inward
displacement d gives f_n = k_n d^alpha (Hertz: alpha 3/2), and their mean tangential
displacement t gives f_t = k_t |t| (the contact's initial tangential stiffness). k_n, alpha
and k_t are fitted on a calibration press and pull of one object with known forces, as the
papers calibrate against a force sensor. The grasp's Gamma = 1 - sum f_t / (mu_prior sum f_n).

Why not the stick ratio: at the markers' depth the displacement field barely changes shape
as the stick zone shrinks (the apex marker's displacement over the second ring's rises about
7 % from stick to full slip, docs/GRASP.md), so the markers carry the forces, not mu; the
estimate is as good as mu_prior is.
"""

from __future__ import annotations

import argparse
import csv
import os
import sys
import time
from dataclasses import dataclass

import numpy as np

from .tracker import Layout, Tracker, calibrate_size

APEX_DEG = 20.0


@dataclass
class Calibration:
    k_n: float        # N per mm^alpha
    alpha: float
    k_t: float        # N per mm
    size_gain: float
    object: str


def _apex(layout: Layout) -> np.ndarray:
    rest = layout.rest_mm["outer"]
    cos = rest[:, 2] / np.linalg.norm(rest, axis=1)
    return cos >= np.cos(np.radians(APEX_DEG))


def field_features(field, layout: Layout) -> tuple[float, float]:
    """(mean inward mm, mean tangential mm) of the outer markers near the apex found."""
    f = field["outer"]
    rest = layout.rest_mm["outer"]
    use = _apex(layout) & f.found
    if not use.any():
        return float("nan"), float("nan")
    n = rest[use] / np.linalg.norm(rest[use], axis=1)[:, None]
    u = f.u_mm[use]
    un = (u * n).sum(axis=1)
    t = (u - un[:, None] * n).mean(axis=0)
    return float(-un.mean()), float(np.linalg.norm(t))


def calibrate(sensor, obj, mu: float = 1.0, grips=(0.5, 1.0, 1.5, 2.0, 2.5)) -> Calibration:
    """Presses `obj` at `grips`, then pulls at each to half its friction limit, and fits the
    size gain and the force laws to the simulator's displacements and forces (the
    calibration rig's indenter and force sensor)."""
    layout = Layout.from_sensor(sensor)
    rest = layout.rest_mm["outer"]
    contact = sensor.contact(obj, mu=mu, fingers=1)
    tracker = Tracker(layout, contact.step(grip_N=1e-4).image("left"))
    shots = []   # (press image, pull image, inward mm per marker, f_n, f_t)
    for grip in grips:
        contact.reset()
        press = contact.step(grip_N=grip)
        pull = contact.step(grip_N=grip, load_N=0.5 * mu * grip)
        inward = -(press.markers("left")["outer"] * rest).sum(1) / np.linalg.norm(rest, axis=1)
        shots.append((press.image("left"), pull.image("left"), inward,
                      press.labels["left_normal_force_N"], pull.labels["left_tangential_force_N"]))

    def tracked():
        for press, pull, *_ in shots:
            tracker.reset()
            yield tracker.track(press), tracker.track(pull)

    tracker.size_gain = calibrate_size([p["outer"] for p, _ in tracked()],
                                       [s[2] for s in shots], rest)
    feats = [(field_features(p, layout)[0], field_features(q, layout)[1]) for p, q in tracked()]
    d, t = np.array(feats).T
    fn, ft = np.array([s[3] for s in shots]), np.array([s[4] for s in shots])
    alpha, log_k = np.polyfit(np.log(d), np.log(fn), 1)
    k_t = float((t * ft).sum() / (t * t).sum())
    return Calibration(float(np.exp(log_k)), float(alpha), k_t, tracker.size_gain, str(obj))


class FieldGamma:
    """The grasp's Gamma from its fingertips' tracked fields."""

    def __init__(self, cal: Calibration, mu_prior: float = 0.8):
        self.cal, self.mu_prior = cal, mu_prior

    def forces(self, field, layout: Layout) -> tuple[float, float]:
        d, t = field_features(field, layout)
        fn = self.cal.k_n * max(d, 0.0) ** self.cal.alpha if np.isfinite(d) else 0.0
        return fn, self.cal.k_t * t if np.isfinite(t) else 0.0

    def grasp(self, fields, layout: Layout) -> float:
        fn, ft = np.sum([self.forces(f, layout) for f in fields], axis=0)
        if fn <= 0:
            return 1.0
        return float(np.clip(1.0 - ft / (self.mu_prior * fn), 0.0, 1.0))


def predict_dataset(root: str, obj: str | None, mu_prior: float, out_csv: str) -> dict:
    """Tracks every frame of a dataset, trial by trial from the rest image, and writes the
    grasp's Gamma per frame (chromasim.evaluate's predictions CSV). Returns timings."""
    from PIL import Image

    from .data import open_dataset
    from .sim import Sensor
    ds = open_dataset(root)
    sensor = Sensor(ds.path("spec.resolved.yaml"))
    layout = Layout.from_sensor(sensor)
    obj = obj if obj is not None else sensor.objects[-1]
    t0 = time.perf_counter()
    cal = calibrate(sensor, obj)
    calib_s = time.perf_counter() - t0
    rest = sensor.contact(obj, fingers=1).step(grip_N=1e-4).image("left")
    trackers = {f: Tracker(layout, rest, size_gain=cal.size_gain) for f in ds.fingers}
    est = FieldGamma(cal, mu_prior)
    lab = ds.labels
    rows, track_s, last_trial = [], 0.0, None
    for i in range(ds.frames):
        if lab["trial"][i] != last_trial:
            last_trial = lab["trial"][i]
            for t in trackers.values():
                t.reset()
        images = [np.asarray(Image.open(ds.path(str(lab[f"{f}_image"][i]))).convert("RGB"))
                  for f in ds.fingers]
        t1 = time.perf_counter()
        fields = [trackers[f].track(im) for f, im in zip(ds.fingers, images)]
        gamma = est.grasp(fields, layout)
        track_s += time.perf_counter() - t1
        rows.append((int(lab["trial"][i]), int(lab["frame"][i]), gamma))
    tmp = out_csv + ".tmp"
    with open(tmp, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["trial", "frame", "gamma_pred"])
        w.writerows((t, k, f"{g:.6f}") for t, k, g in rows)
    os.replace(tmp, out_csv)
    return {"frames": ds.frames, "calibration_s": calib_s, "track_s": track_s,
            "frames_per_s": ds.frames / track_s if track_s > 0 else float("nan"),
            "calibration": cal}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python3 -m chromasim.tracker_gamma",
                                 description=__doc__.splitlines()[0])
    ap.add_argument("dataset", help="a dataset folder written by chromasim generate")
    ap.add_argument("-o", "--out", required=True, help="the predictions CSV")
    ap.add_argument("--object", help="the spec object to calibrate on (default: the last)")
    ap.add_argument("--mu-prior", type=float, default=0.8,
                    help="the friction the estimate assumes (default 0.8)")
    a = ap.parse_args(argv)
    if not 0 < a.mu_prior <= 5:
        ap.error(f"--mu-prior {a.mu_prior}: allowed: a number in (0, 5]")
    r = predict_dataset(a.dataset, a.object, a.mu_prior, a.out)
    c = r["calibration"]
    print(f"calibration on {c.object}: f_n = {c.k_n:.3f} d^{c.alpha:.2f} N, f_t = {c.k_t:.3f} "
          f"|t| N, size gain {c.size_gain:.3f} ({r['calibration_s']:.1f} s)")
    print(f"{r['frames']} frames, tracking and estimate {r['frames_per_s']:.1f} frames/s "
          f"(both fingertips); wrote {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
