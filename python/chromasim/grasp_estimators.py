"""Gamma estimators for the closed loop (chromasim.grasp): each is called with an Observation
(one camera frame of the grasp) and returns the grasp's estimated Gamma.

- Oracle: the simulator's true Gamma, optionally with Gaussian noise;
- Checkpoint: a trained network of chromasim.train on both fingertips' images;
- any callable f(left, right) -> Gamma on the two images (H x W x 3 uint8 arrays),
  wrapped by `from_callable` (chromasim.tracker's baseline is one).
"""

from __future__ import annotations

import math
import os

import numpy as np


class EstimatorError(RuntimeError):
    """An estimator raised or returned no finite Gamma: the loop stops (traces are kept)."""


class Observation:
    """One camera frame of the grasp as an estimator sees it. `images()` renders the fingertips'
    images on first use (the PNG's pixels, through the sensor model when the spec enables it);
    `gamma` is the simulator's truth, for the oracle only."""

    def __init__(self, frame, time_s: float):
        self._frame = frame
        self.time_s = time_s
        self.gamma = frame.gamma
        self._images = None

    def images(self) -> tuple[np.ndarray, ...]:
        if self._images is None:
            fingers = self._frame.fingers
            if len(fingers) != 2:
                raise EstimatorError("this estimator needs both fingertips' images: the loop "
                                     "was built with one fingertip (an oracle run)")
            self._images = tuple(self._frame.image(f) for f in fingers)
        return self._images


class Oracle:
    """The true Gamma plus N(0, noise), clamped to [0, 1]."""

    needs_images = False

    def __init__(self, noise: float = 0.0, rng: np.random.Generator | None = None):
        self.noise = float(noise)
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self.name = "oracle" if self.noise == 0 else f"oracle (noise {self.noise:g})"

    def __call__(self, obs: Observation) -> float:
        g = obs.gamma
        if self.noise > 0:
            g += self.rng.normal(0.0, self.noise)
        return min(1.0, max(0.0, g))


class Callable:
    """Any f(left, right) -> Gamma on the fingertips' uint8 images."""

    needs_images = True

    def __init__(self, fn, name: str | None = None):
        self.fn = fn
        self.name = name or getattr(fn, "__name__", type(fn).__name__)

    def __call__(self, obs: Observation) -> float:
        return self.fn(*obs.images())


class Checkpoint:
    """A network trained by chromasim.train (its checkpoint_best.pt or checkpoint_last.pt),
    fed the fingertips' images as GammaImages feeds it in training (resized, stacked left on
    top, in [0, 1])."""

    needs_images = True
    KEYS = ("model", "width", "size", "target")

    def __init__(self, path: str, device: str = "cpu"):
        import torch

        from .model import make_model
        if not os.path.isfile(path):
            raise ValueError(f"{path}: no such checkpoint file")
        try:
            ck = torch.load(path, map_location=device)
        except Exception as e:  # noqa: BLE001 - any unreadable file is the user's to fix
            raise ValueError(f"{path}: not a chromasim.train checkpoint ({e})") from e
        missing = [k for k in self.KEYS if not isinstance(ck, dict) or k not in ck]
        if missing:
            raise ValueError(f"{path}: not a chromasim.train checkpoint: no "
                             f"{', '.join(missing)}")
        if ck["target"] != "grasp":
            raise ValueError(f"{path}: trained on target {ck['target']!r}; the loop needs the "
                             f"grasp's Gamma (chromasim.train --target grasp)")
        model = make_model(ck["width"]).to(device)
        try:
            model.load_state_dict(ck["model"])
        except RuntimeError as e:
            raise ValueError(f"{path}: its weights do not fit a ShuffleNetV2 x{ck['width']} "
                             f"with the Gamma head (another model shape): "
                             f"{str(e).splitlines()[0]}") from e
        self.model = model.eval()
        self.size = int(ck["size"])
        self.device = device
        self.name = f"checkpoint {os.path.basename(path)}"

    def __call__(self, obs: Observation) -> float:
        import torch

        from .torch_data import stack_fingers
        imgs = [torch.from_numpy(np.ascontiguousarray(a)).permute(2, 0, 1)
                for a in obs.images()]
        x = stack_fingers(imgs, self.size).float()[None] / 255.0
        with torch.no_grad():
            return float(self.model(x.to(self.device))[0].clamp(0.0, 1.0))


class Tracked:
    """chromasim.tracker's marker tracking and chromasim.tracker_gamma's force-based Gamma on
    the two images: calibrated once on `calibration_object` of the sensor's spec, tracked
    from the rest image at every trial's start, Gamma at `mu_prior`."""

    needs_images = True

    def __init__(self, sensor, calibration_object, mu_prior: float = 0.8):
        from .tracker import Layout, Tracker
        from .tracker_gamma import FieldGamma, calibrate
        self.layout = Layout.from_sensor(sensor)
        cal = calibrate(sensor, calibration_object)
        rest = sensor.contact(calibration_object, fingers=1).step(grip_N=1e-4).image("left")
        self.trackers = [Tracker(self.layout, rest, size_gain=cal.size_gain) for _ in range(2)]
        self.gamma = FieldGamma(cal, mu_prior)
        self.name = f"tracker (calibrated on {calibration_object}, mu prior {mu_prior:g})"

    def reset(self) -> None:
        for t in self.trackers:
            t.reset()

    def __call__(self, obs: Observation) -> float:
        fields = [t.track(im) for t, im in zip(self.trackers, obs.images())]
        return self.gamma.grasp(fields, self.layout)


def checked_estimate(estimator, obs: Observation) -> float:
    """The estimator's Gamma for `obs`, or EstimatorError naming it and the time."""
    try:
        value = estimator(obs)
        g = float(value)
    except EstimatorError:
        raise
    except Exception as e:  # noqa: BLE001 - any failure stops the loop with its message
        raise EstimatorError(f"estimator {getattr(estimator, 'name', estimator)!s} raised at "
                             f"t = {obs.time_s:.3f} s: {type(e).__name__}: {e}") from e
    if not math.isfinite(g):
        raise EstimatorError(f"estimator {getattr(estimator, 'name', estimator)!s} returned "
                             f"{value!r} at t = {obs.time_s:.3f} s: a finite Gamma is needed")
    return g
