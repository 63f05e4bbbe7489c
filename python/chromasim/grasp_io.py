"""The closed-loop grasp's files (chromasim.grasp): each is written to a temporary name and
renamed, so a file in the run's folder is always whole; traces, events and trials are
written after every trial, summary.csv and run.json when the run ends."""

from __future__ import annotations

import csv
import json
import math
import os
from dataclasses import asdict

import numpy as np

from . import __version__
from .grasp_loop import TRACE_COLUMNS, TrialResult
from .grasp_scenes import TrialSummary

EVENT_COLUMNS = ("scene", "fruit", "target", "trial", "start_s", "end_s", "distance_mm",
                 "slip")
TRIAL_COLUMNS = ("scene", "fruit", "target", "trial", "mu", "mass_g", "event_s", "trace",
                 "slips", "slid_mm", "lost", "grip_hold_N", "grip_after_N", "grip_max_N",
                 "reaction_ms", "gamma_hold", "gamma_hold_sd", "frames", "estimates",
                 "seconds", "error")


def _write_csv(path: str, columns, rows) -> None:
    tmp = path + ".tmp"
    with open(tmp, "w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=columns, lineterminator="\n")
        w.writeheader()
        for r in rows:
            w.writerow({k: _cell(r.get(k)) for k in columns})
    os.replace(tmp, path)


def _cell(v):
    if isinstance(v, float):
        return "nan" if math.isnan(v) else f"{v:.6g}"
    return "" if v is None else v


class RunWriter:
    def __init__(self, out: str, cfg, estimator_arg: str, estimator_name: str, fingers: int):
        os.makedirs(os.path.join(out, "traces"), exist_ok=True)
        self.out, self.cfg = out, cfg
        self.estimator = {"argument": estimator_arg, "name": estimator_name,
                          "fingers_solved": fingers}
        self.events: list[dict] = []
        self.trials: list[dict] = []

    def trial(self, res: TrialResult, s: TrialSummary) -> None:
        sc = res.scene
        name = f"{sc.kind}_{sc.fruit}_{round(sc.target * 100):02d}_{sc.trial}.csv"
        _write_csv(os.path.join(self.out, "traces", name), TRACE_COLUMNS, res.rows)
        key = {"scene": sc.kind, "fruit": sc.fruit, "target": sc.target, "trial": sc.trial}
        for sl in res.slides:
            self.events.append({**key, "start_s": sl.start_s, "end_s": sl.end_s,
                                "distance_mm": sl.distance_mm,
                                "slip": int(sl.distance_mm >= self.cfg.slip_mm)})
        self.trials.append({**key, "mu": sc.mu, "mass_g": sc.mass_g(0.0),
                            "event_s": sc.event_s, "trace": f"traces/{name}", **asdict(s),
                            "lost": int(s.lost), "frames": res.frames,
                            "estimates": res.estimates, "seconds": res.seconds,
                            "error": res.error or ""})
        _write_csv(os.path.join(self.out, "events.csv"), EVENT_COLUMNS, self.events)
        _write_csv(os.path.join(self.out, "trials.csv"), TRIAL_COLUMNS, self.trials)

    def finish(self, seconds: float, error: str | None) -> list[dict]:
        rows = summary_rows(self.trials)
        _write_csv(os.path.join(self.out, "summary.csv"), SUMMARY_COLUMNS, rows)
        c = self.cfg
        run = {"chromasim": __version__, "config": os.path.abspath(c.path),
               "sensor_spec": c.sensor_spec, "estimator": self.estimator,
               "camera_Hz": c.camera_Hz, "estimator_Hz": c.estimator_Hz,
               "latency_ms": c.latency_ms, "noise": c.noise, "seed": c.seed,
               "trials_per_condition": c.trials, "slip_mm": c.slip_mm, "lost_mm": c.lost_mm,
               "controller": asdict(c.controller), "seconds": seconds, "error": error,
               "complete": error is None}
        tmp = os.path.join(self.out, "run.json.tmp")
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump(run, f, indent=2)
        os.replace(tmp, os.path.join(self.out, "run.json"))
        return rows


SUMMARY_COLUMNS = ("scene", "fruit", "target", "trials", "slips", "slip_probability",
                   "grip_hold_N_mean", "grip_hold_N_sd", "grip_after_N_mean", "grip_max_N_mean",
                   "reaction_ms_mean", "reaction_ms_sd", "gamma_hold_mean", "gamma_hold_sd",
                   "seconds_per_trial")


def summary_rows(trials: list[dict]) -> list[dict]:
    """One row per (scene, fruit, target): slip probability = trials with a slip / trials."""
    groups: dict[tuple, list[dict]] = {}
    for t in trials:
        groups.setdefault((t["scene"], t["fruit"], t["target"]), []).append(t)
    rows = []
    for (scene, fruit, target), ts in groups.items():
        def col(k):
            return np.array([t[k] for t in ts], dtype=float)

        def mean(k):
            v = col(k)
            v = v[np.isfinite(v)]
            return float(v.mean()) if v.size else math.nan

        def sd(k):
            v = col(k)
            v = v[np.isfinite(v)]
            return float(v.std()) if v.size else math.nan

        slipped = int(sum(t["slips"] > 0 for t in ts))
        rows.append({"scene": scene, "fruit": fruit, "target": target, "trials": len(ts),
                     "slips": slipped, "slip_probability": slipped / len(ts),
                     "grip_hold_N_mean": mean("grip_hold_N"), "grip_hold_N_sd": sd("grip_hold_N"),
                     "grip_after_N_mean": mean("grip_after_N"),
                     "grip_max_N_mean": mean("grip_max_N"),
                     "reaction_ms_mean": mean("reaction_ms"), "reaction_ms_sd": sd("reaction_ms"),
                     "gamma_hold_mean": mean("gamma_hold"), "gamma_hold_sd": mean("gamma_hold_sd"),
                     "seconds_per_trial": mean("seconds")})
    return rows
