"""The simulator from Python: a spec's sensor, stepped contacts and a spec's trials.

    sensor = Sensor("datasets_spec/quickstart.yaml")        # or Sensor({...}) from a dict
    grasp = sensor.contact("curved", mu=0.8)                 # both fingertips, facing
    for t in range(50):
        frame = grasp.step(grip_N=1.0, load_N=0.02 * t)      # friction history kept
        frame.gamma, frame.labels["left_sliding"]            # labels: no image is rendered
    left = frame.image("left")                               # H x W x 3 uint8, the PNG's pixels
    for frame in sensor.trial(0):                            # a spec's trial, frame by frame
        ...

A Sensor shares the command line's caches (mesh, factorization, light cache: `--cache-dir`,
default ~/.cache/chromasim). The mechanics solve when you step; an image is rendered only
when you ask for one, and the light cache is built (or read) on the first. Long calls release
the GIL. The same spec and seed give the bytes `chromasim generate` writes: labels at
labels.csv's precision, markers, and the PNGs' pixels (python/tests/test_api.py).

Errors: a bad spec raises SpecError (a ValueError) whose message names the file, line:column,
key, value and what is allowed; a bad argument raises TypeError or ValueError naming it.
"""

from __future__ import annotations

import json
import numbers
import os
from collections.abc import Iterator, Mapping, Sequence

import numpy

try:
    from . import _core
except ImportError as e:  # pragma: no cover - the message is the test
    raise ImportError(
        "chromasim's compiled module (chromasim._core) was not found: build it with "
        "`cmake --preset release && cmake --build --preset release` (scripts/test or "
        "scripts/quickstart do), or set CHROMASIM_BUILD_DIR to a build folder. It is built for "
        "Debian's /usr/bin/python3. (" + str(e) + ")") from e

SpecError = _core.SpecError

__all__ = ["Sensor", "Contact", "Trial", "Frame", "SpecError"]

Frame = _core.Frame


def _number(name: str, value, unit: str) -> float:
    """`value` as a float, or TypeError naming the argument and what it takes."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name}: expected a number ({unit}), got {type(value).__name__} "
                        f"{value!r}")
    return float(value)


class Sensor:
    """A spec's sensor, built once: the dome's mesh and factorization now (or read from the
    cache), the renderer on the first image asked for.

    spec: a spec file's path, or a dict with a spec's contents (relative file paths in it start
    at the working directory). cache_dir: the cache folder (None: the command line's default,
    $CHROMASIM_CACHE_DIR or ~/.cache/chromasim; False: no cache). seed: replaces the spec's seed
    (its trials' draws). variant: for a spec that varies its sensor (`varied` keys written as
    lists or ranges), which of the sensors `generate` draws (0 to sampling.sensor_variants - 1;
    sensors.csv names each trial's)."""

    def __init__(self, spec: str | os.PathLike | Mapping, *, cache_dir=None,
                 seed: int | None = None, variant: int | None = None):
        if cache_dir is None:
            cache = _core.default_cache_dir()
        elif cache_dir is False:
            cache = ""
        else:
            cache = os.fspath(cache_dir)
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, numbers.Integral)
                                 or seed < 0):
            raise ValueError(f"seed = {seed!r}: allowed: an integer >= 0")
        if variant is not None and (isinstance(variant, bool)
                                    or not isinstance(variant, numbers.Integral)):
            raise ValueError(f"variant = {variant!r}: allowed: an integer")
        if isinstance(spec, Mapping):
            text = json.dumps(spec, indent=2)  # JSON is YAML: errors point into this text
            self._core = _core.Sensor(text=text, name="<dict>", cache_dir=cache, seed=seed,
                                      variant=variant)
        elif isinstance(spec, (str, os.PathLike)):
            self._core = _core.Sensor(path=os.fspath(spec), cache_dir=cache, seed=seed,
                                      variant=variant)
        else:
            raise TypeError(f"spec: expected a spec file's path or a dict, got "
                            f"{type(spec).__name__}")
        self._trials = None

    name = property(lambda self: self._core.name)
    seed = property(lambda self: self._core.seed)
    objects = property(lambda self: self._core.objects, doc="the spec's object names")
    fingers = property(lambda self: self._core.fingers, doc="fingertips per grasp (1 or 2)")
    image_size = property(lambda self: self._core.image_size, doc="(height, width) in px")
    renders = property(lambda self: self._core.renders, doc="the spec asks for images")
    mesh = property(lambda self: self._core.mesh, doc="the dome mesh's size and cache state")
    precompute_s = property(lambda self: self._core.precompute_s,
                            doc="seconds the mesh, factorization and responses took (or their read)")
    resolved_yaml = property(lambda self: self._core.resolved_yaml)

    def marker_rest_positions(self, layer: str) -> numpy.ndarray:
        """Rest positions (mm) of a layer's marker centres, inner or outer: markers x 3."""
        return self._core.marker_rest_positions(layer)

    def prepare_images(self) -> dict:
        """Builds the renderer now (exposure, light cache) rather than at the first image."""
        return self._core.prepare_images()

    def contact(self, object: str | int = 0, mu: float | Sequence[float] = 0.8, *,
                fingers: int | None = None, direction_deg: float | None = None) -> "Contact":
        """A grasp of spec object `object` (its name or index) at friction `mu` (one value, or
        one per fingertip), by `fingers` fingertips (default: the spec's fingers.count), its
        load along `direction_deg` in the left fingertip's plane (default: the spec's
        protocol.load_direction_deg; the right fingertip's is opposite)."""
        count = self.fingers if fingers is None else fingers
        if isinstance(count, bool) or count not in (1, 2):
            raise ValueError(f"fingers = {count!r}: allowed: 1 or 2")
        if isinstance(mu, Sequence):
            mus = [_number("mu", m, "Coulomb coefficient") for m in mu]
        else:
            mus = [_number("mu", mu, "Coulomb coefficient")] * count
        if isinstance(object, bool) or not isinstance(object, (str, numbers.Integral)):
            raise TypeError(f"object: expected a spec object's name or index, got "
                            f"{type(object).__name__}")
        if direction_deg is not None:
            direction_deg = _number("direction_deg", direction_deg, "deg")
        return Contact(_core.Contact(self._core, object, mus, direction_deg))

    def _plan(self):
        if self._trials is None:
            self._trials = _core.Trials(self._core)
        return self._trials

    def __len__(self) -> int:
        """The number of trials in the spec's plan."""
        return len(self._plan())

    def trial(self, index: int) -> "Trial":
        """Trial `index` of the spec's plan, to iterate frame by frame."""
        if isinstance(index, bool) or not isinstance(index, numbers.Integral):
            raise TypeError(f"trial index: expected an integer, got {type(index).__name__}")
        return Trial(self._plan(), int(index))

    def trials(self, start: int = 0, stop: int | None = None, step: int = 1) -> Iterator["Trial"]:
        """The plan's trials start, start + step, ... before stop (default: all)."""
        n = len(self)
        for k in range(start, n if stop is None else min(stop, n), step):
            yield self.trial(k)


class Trial:
    """One trial of a spec's plan: its factors (`info`) and its frames, solved as you iterate
    (each fingertip from its previous frame, as `chromasim generate` does)."""

    def __init__(self, trials, index: int):
        self.info = trials.info(index)
        self._trials = trials
        self.index = index

    def __len__(self) -> int:
        return self.info["frames"]

    def __iter__(self) -> Iterator[Frame]:
        return iter(self._trials.run(self.index))


class Contact:
    """One fingertip, or two facing each other, pressed by one rigid object. Each step solves
    every fingertip's quasi-static contact from its last converged frame (its stick/slip
    history kept); a step with the last step's loads reuses its result."""

    def __init__(self, core):
        self._core = core

    object = property(lambda self: self._core.object)
    fingers = property(lambda self: self._core.fingers, doc="the fingertips' names")
    mu = property(lambda self: self._core.mu, doc="each fingertip's Coulomb coefficient")
    steps = property(lambda self: self._core.steps, doc="steps taken since the last reset")

    def step(self, grip_N: float, load_N: float = 0.0, *, travel_mm: float | None = None,
             time_s: float = 0.0) -> Frame:
        """Grip force `grip_N` (> 0) on each fingertip; `load_N` (>= 0), the total tangential
        load shared equally by the fingertips, each along its direction (force control), or,
        with `travel_mm`, the object's travel along it (displacement control). `time_s` is
        only a label. Returns the frame: labels now, images when asked for."""
        grip = _number("grip_N", grip_N, "N")
        load = _number("load_N", load_N, "N")
        travel = None if travel_mm is None else _number("travel_mm", travel_mm, "mm")
        return self._core.step(grip, load, travel, _number("time_s", time_s, "s"))

    def reset(self) -> None:
        """Forgets the friction history: the next step starts from rest."""
        self._core.reset()
