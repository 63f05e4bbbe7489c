"""chromasim from Python: simulate the sensor in your own code (chromasim.sim), or read a
dataset written by `chromasim generate`, train and evaluate safety-margin estimators on it,
compute eigenstrains and draw figures.

    import chromasim
    sensor = chromasim.Sensor("datasets_spec/quickstart.yaml")
    grasp = sensor.contact("curved", mu=0.8)
    frame = grasp.step(grip_N=1.0, load_N=0.6)
    frame.labels["left_gamma"], frame.image("left")

Entry points (run with `python3 -m`):
  chromasim.train       pretrain the seed-000 CNN (ShuffleNetV2) on a dataset
  chromasim.evaluate    stress-test any estimator's predictions CSV against a dataset
  chromasim.eigenstrain seed 001's SVD of strain fields and SVM classifiers
  chromasim.figures     the seeds' figures from a dataset and benchmark outputs
  chromasim.bench_api   frames per second through the API against `chromasim generate`
  chromasim.grasp       seed 000's closed-loop grasp (chromasim.grasp_report: its Fig. 5)

The simulator (Sensor, Contact, SimulatedFrames) needs the compiled module chromasim._core,
which the CMake build writes to <build>/python/chromasim/: this package looks for it there
($CHROMASIM_BUILD_DIR, else the repository's build/release). The readers (chromasim.data)
need only numpy; torch is imported by train and the Dataset classes only.
"""

import os as _os

__version__ = "0.47.0"  # the CMake project version (python/tests/test_data.py checks it)


def _build_dirs() -> list[str]:
    """Folders that may hold the compiled module: $CHROMASIM_BUILD_DIR's, then build/release's."""
    root = _os.path.dirname(_os.path.dirname(_os.path.dirname(_os.path.abspath(__file__))))
    builds = [_os.environ.get("CHROMASIM_BUILD_DIR", ""), _os.path.join(root, "build", "release")]
    return [_os.path.join(b, "python", "chromasim") for b in builds if b]


__path__ = list(__path__) + [d for d in _build_dirs() if _os.path.isdir(d)]

_LAZY = {"Sensor": "sim", "Contact": "sim", "Trial": "sim", "SpecError": "sim",
         "SimulatedFrames": "stream"}


def __getattr__(name: str):
    """Sensor, Contact, Trial, SpecError (chromasim.sim) and SimulatedFrames (chromasim.stream),
    imported on first use so that the dataset tools work without the compiled module."""
    if name not in _LAZY:
        raise AttributeError(f"module 'chromasim' has no attribute {name!r}")
    import importlib
    return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
