"""Seed 000's closed-loop grasp in simulation (its Fig. 5): a P-controller on an estimated
Gamma holds fruit through a weight drop, and a cup while it is filled with rice.

    python3 -m chromasim.grasp --out out/grasp                       # the oracle
    python3 -m chromasim.grasp --out out/grasp_cnn --estimator checkpoint:out/cnn/checkpoint_best.pt
    python3 -m chromasim.grasp --out out/grasp_trk --estimator tracker      # chromasim.tracker
    python3 -m chromasim.grasp --out out/grasp_fn --estimator mypackage.mymodule:estimate
    python3 -m chromasim.grasp_report out/grasp                       # Fig. 5 A, B, C

Writes into --out: traces/<scene>_<fruit>_<target>_<trial>.csv (grip, load, true and estimated
Gamma per camera frame), events.csv (every slide), trials.csv (one row per trial), summary.csv
(per scene, fruit and target: slip probability, grip, reaction time) and run.json. Each file is
written whole when its trial ends. An estimator that raises or returns no finite Gamma stops
the run with exit status 1; the traces of the trials so far, the failing one's included, are
kept. The dynamics and every assumption: docs/GRASP.md.
"""

from __future__ import annotations

import argparse
import importlib
import math
import os
import sys
import time

from . import grasp_config, grasp_estimators
from .grasp_io import RunWriter
from .grasp_loop import run_trial
from .grasp_scenes import rice_cup_scene, summarize, trial_rng, weight_drop_scene

DEFAULT_CONFIG = os.path.normpath(os.path.join(os.path.dirname(__file__), "..", "..",
                                              "datasets_spec", "grasp", "seed000.yaml"))


def make_estimator(text: str, noise: float, rng, sensor=None, mu_prior: float = 0.8):
    """oracle | tracker[:OBJECT] | checkpoint:PATH | module:function (a callable
    f(left, right) -> Gamma)."""
    if text == "oracle":
        return grasp_estimators.Oracle(noise, rng)
    if text == "tracker" or text.startswith("tracker:"):
        obj = text.split(":", 1)[1] if ":" in text else sensor.objects[-1]
        if obj not in sensor.objects:
            raise ValueError(f"--estimator {text}: allowed objects: {', '.join(sensor.objects)}")
        return grasp_estimators.Tracked(sensor, obj, mu_prior)
    if text.startswith("checkpoint:"):
        return grasp_estimators.Checkpoint(text.split(":", 1)[1])
    if ":" in text:
        mod, fn = text.rsplit(":", 1)
        try:
            target = getattr(importlib.import_module(mod), fn)
        except (ImportError, AttributeError) as e:
            raise ValueError(f"--estimator {text}: cannot import {fn} from {mod}: {e}") from e
        if not callable(target):
            raise ValueError(f"--estimator {text}: {fn} is not callable")
        return grasp_estimators.Callable(target, name=text)
    raise ValueError(f"--estimator {text}: allowed: oracle, tracker[:OBJECT], checkpoint:PATH, "
                     f"module:function")


def plan(cfg, scenes: list[str], fruits: list[str] | None, targets: list[float] | None):
    """(scene kind, fruit, target, trial) for every trial to run, in run order."""
    out = []
    if "weight_drop" in scenes:
        for fruit in cfg.weight_drop.fruits:
            if fruits and fruit not in fruits:
                continue
            for target in cfg.weight_drop.targets:
                if targets and not any(abs(target - t) < 1e-9 for t in targets):
                    continue
                out += [("weight_drop", fruit, target, k) for k in range(cfg.trials)]
    if "rice_cup" in scenes:
        for target in cfg.rice_cup.targets:
            if not targets or any(abs(target - t) < 1e-9 for t in targets):
                out.append(("rice_cup", "cup", target, 0))
    return out


def _args(argv):
    p = argparse.ArgumentParser(prog="python3 -m chromasim.grasp", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--config", default=DEFAULT_CONFIG, help="the grasp configuration")
    p.add_argument("--out", required=True, help="a new folder for the run's files")
    p.add_argument("--estimator", default="oracle",
                   help="oracle | tracker[:OBJECT] | checkpoint:PATH | module:function "
                        "(default: oracle)")
    p.add_argument("--noise", type=float, help="the oracle's noise (default: the config's)")
    p.add_argument("--mu-prior", type=float, default=0.8,
                   help="the friction the tracker's Gamma assumes (default 0.8)")
    p.add_argument("--scenes", default="weight_drop,rice_cup",
                   help="weight_drop, rice_cup or both, comma-separated")
    p.add_argument("--fruits", help="only these fruits, comma-separated")
    p.add_argument("--targets", help="only these targets, comma-separated (0.2,0.6)")
    p.add_argument("--trials", type=int, help="trials per fruit and target (default: config)")
    p.add_argument("--cache-dir", help="chromasim's cache folder (default: the CLI's)")
    return p.parse_args(argv)


def _check_args(a, cfg, sensor_objects):
    scenes = [s for s in a.scenes.split(",") if s]
    bad = [s for s in scenes if s not in ("weight_drop", "rice_cup")]
    if bad or not scenes:
        raise ValueError(f"--scenes {a.scenes}: allowed: weight_drop, rice_cup")
    fruits = a.fruits.split(",") if a.fruits else None
    for f in fruits or []:
        if f not in cfg.weight_drop.fruits:
            raise ValueError(f"--fruits {f}: allowed: {', '.join(cfg.weight_drop.fruits)}")
    try:
        targets = [float(t) for t in a.targets.split(",")] if a.targets else None
    except ValueError:
        raise ValueError(f"--targets {a.targets}: allowed: numbers such as 0.2,0.6") from None
    if a.trials is not None:
        if a.trials < 1:
            raise ValueError(f"--trials {a.trials}: allowed: an integer >= 1")
        cfg.trials = a.trials
    if a.noise is not None:
        if not (0.0 <= a.noise <= 1.0):
            raise ValueError(f"--noise {a.noise}: allowed: a number in [0, 1]")
        cfg.noise = a.noise
    for name, where in cfg.marks.items():
        if name not in sensor_objects:
            raise grasp_config.ConfigError(
                f"{where} = {name}: allowed: an object of {cfg.sensor_spec}: "
                f"{', '.join(sensor_objects)}")
    return scenes, fruits, targets


def main(argv=None) -> int:
    a = _args(argv)
    from .sim import Sensor, SpecError
    try:
        cfg = grasp_config.load(a.config)
        if os.path.exists(os.path.join(a.out, "run.json")):
            raise ValueError(f"--out {a.out}: holds a run already (run.json): choose another "
                             f"folder or delete it")
        sensor = Sensor(cfg.sensor_spec, cache_dir=a.cache_dir)
        scenes, fruits, targets = _check_args(a, cfg, sensor.objects)
        estimator = make_estimator(a.estimator, cfg.noise, None, sensor, a.mu_prior)
    except (ValueError, SpecError) as e:
        print(f"chromasim.grasp: error: {e}", file=sys.stderr)
        return 2
    todo = plan(cfg, scenes, fruits, targets)
    if not todo:
        print("chromasim.grasp: error: --fruits/--targets leave no trial", file=sys.stderr)
        return 2
    fingers = 1 if isinstance(estimator, grasp_estimators.Oracle) else 2
    writer = RunWriter(a.out, cfg, a.estimator, estimator.name, fingers)
    t0 = time.perf_counter()
    for kind, fruit, target, trial in todo:
        rng = trial_rng(cfg.seed, kind, fruit, target, trial)
        scene = (weight_drop_scene(cfg, fruit, target, trial, rng) if kind == "weight_drop"
                 else rice_cup_scene(cfg, target))
        if isinstance(estimator, grasp_estimators.Oracle):
            estimator.rng = rng
        contact = sensor.contact(scene.object, mu=scene.mu, fingers=fingers)
        res = run_trial(contact, scene, estimator, cfg)
        s = summarize(res, cfg.slip_mm)
        writer.trial(res, s)
        print(f"{kind:11s} {fruit:10s} target {target:.0%} trial {trial}: grip "
              f"{s.grip_hold_N:.2f} N, Gamma {s.gamma_hold:.3f}, slid {s.slid_mm:.1f} mm, "
              f"reaction {s.reaction_ms:.0f} ms ({res.seconds:.1f} s, {res.frames} frames)",
              flush=True)
        if res.error:
            writer.finish(time.perf_counter() - t0, res.error)
            print(f"chromasim.grasp: error: {res.error} (traces so far kept in {a.out})",
                  file=sys.stderr)
            return 1
    rows = writer.finish(time.perf_counter() - t0, None)
    _print_summary(rows)
    return 0


def _print_summary(rows) -> None:
    print(f"{'scene':11s} {'fruit':10s} target trials P(slip) grip_N  after_N reaction_ms "
          f"s/trial")
    for r in rows:
        rt = r["reaction_ms_mean"]
        print(f"{r['scene']:11s} {r['fruit']:10s} {r['target']:6.0%} {r['trials']:6d} "
              f"{r['slip_probability']:8.2f} {r['grip_hold_N_mean']:6.2f} "
              f"{r['grip_after_N_mean']:7.2f} {'-' if math.isnan(rt) else f'{rt:.0f}':>11s} "
              f"{r['seconds_per_trial']:7.1f}")


if __name__ == "__main__":
    sys.exit(main())
