"""The time a closed-loop grasp trial takes (chromasim.grasp), with images and with labels only.

    python3 -m chromasim.bench_grasp [--config datasets_spec/grasp/seed000.yaml] [--repeat 3]

One weight-drop trial (the fruit and target below, 351 camera frames at 100 Hz) three ways,
alternated `--repeat` times from warm caches, all on the same trajectory (each estimator
returns the true Gamma):
- labels only, one fingertip: what `--estimator oracle` solves;
- labels only, both fingertips;
- both fingertips and their images at the estimator's rate: what an image estimator costs
  before its own inference (the renderer is built before the first run).
Prints each run and the medians as a table: seconds per trial and per simulated second.
"""

from __future__ import annotations

import argparse
import statistics

from . import grasp, grasp_config, grasp_estimators
from .grasp_loop import run_trial
from .grasp_scenes import trial_rng, weight_drop_scene
from .sim import Sensor


class _TruthWithImages:
    """The true Gamma, after rendering both fingertips' images as an image estimator would."""
    needs_images = True
    name = "truth after images"

    def __call__(self, obs):
        obs.images()
        return obs.gamma


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default=grasp.DEFAULT_CONFIG)
    ap.add_argument("--fruit", default="mandarin")
    ap.add_argument("--target", type=float, default=0.6)
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args(argv)
    cfg = grasp_config.load(a.config)
    sensor = Sensor(cfg.sensor_spec)
    sensor.prepare_images()
    ways = [("labels only, one fingertip", 1, grasp_estimators.Oracle(0.0)),
            ("labels only, both fingertips", 2, grasp_estimators.Oracle(0.0)),
            ("both fingertips and their images", 2, _TruthWithImages())]
    times: dict[str, list[float]] = {name: [] for name, _, _ in ways}
    frames = 0
    for r in range(a.repeat):
        for name, fingers, estimator in ways:
            scene = weight_drop_scene(cfg, a.fruit, a.target, 0, trial_rng(cfg.seed, "bench"))
            res = run_trial(sensor.contact(scene.object, mu=scene.mu, fingers=fingers), scene,
                            estimator, cfg)
            frames = res.frames
            times[name].append(res.seconds)
            print(f"run {r}: {name}: {res.seconds:.2f} s ({res.frames} frames, "
                  f"{res.estimates} estimates)", flush=True)
    sim_s = (frames - 1) / cfg.camera_Hz
    print(f"| {a.fruit} at {a.target:.0%}, {frames} frames | s per trial (median) | "
          f"s per simulated s |\n|---|---|---|")
    for name, t in times.items():
        m = statistics.median(t)
        print(f"| {name} | {m:.1f} | {m / sim_s:.1f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
