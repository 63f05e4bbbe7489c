"""Frames per second through the Python API against `chromasim generate` on the same spec.

    python3 -m chromasim.bench_api datasets_spec/quickstart.yaml --exe build/release/chromasim

Runs alternate (CLI, then API) `--repeat` times from warm caches; each side does the whole job
from the spec: the CLI writes the dataset, the API builds a Sensor and computes every frame's
labels, markers and images (not written). Prints each run and the medians as a table.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import tempfile
import time

from .sim import Sensor


def _cli(exe: str, spec: str) -> tuple[int, float]:
    out = tempfile.mkdtemp(prefix="chromasim-bench-")
    try:
        t = time.perf_counter()
        subprocess.run([exe, "generate", spec, "-o", os.path.join(out, "d")], check=True,
                       capture_output=True)
        seconds = time.perf_counter() - t
        with open(os.path.join(out, "d", "labels.csv")) as f:
            return sum(1 for _ in f) - 1, seconds
    finally:
        shutil.rmtree(out, ignore_errors=True)


def _api(spec: str) -> tuple[int, float]:
    t = time.perf_counter()
    sensor, frames = Sensor(spec), 0
    for trial in sensor.trials():
        for frame in trial:
            frame.labels
            for finger in frame.fingers:
                frame.markers(finger)
                if sensor.renders:
                    frame.image(finger)
            frames += 1
    return frames, time.perf_counter() - t


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("spec")
    ap.add_argument("--exe", default="build/release/chromasim", help="the chromasim executable")
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args(argv)
    if not os.access(a.exe, os.X_OK):
        ap.error(f"--exe {a.exe}: not an executable (build with cmake --build --preset release)")
    cli, api = [], []
    for r in range(a.repeat):
        n, s = _cli(a.exe, a.spec)
        cli.append(n / s)
        m, u = _api(a.spec)
        api.append(m / u)
        print(f"run {r}: generate {n} frames in {s:.2f} s, API {m} frames in {u:.2f} s", flush=True)
    c, p = statistics.median(cli), statistics.median(api)
    print("| path | frames/s (median) |\n|---|---|")
    print(f"| chromasim generate | {c:.3f} |\n| Python API | {p:.3f} ({100 * (p / c - 1):+.1f} %) |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
