"""The papers' classical marker tracking on tactile images alone (seed 000 Sec. III, RA-L
2019): every marker's 3D displacement from a fingertip's image and its rest image.

    layout = Layout.from_sensor(sensor)                 # marker layout, fisheye intrinsics
    tracker = Tracker(layout, rest_image)               # the unloaded fingertip's image
    field = tracker.track(image)                        # {"inner", "outer"}: u (82 x 3 mm)

    python3 -m chromasim.tracker SPEC [--object NAME]   # accuracy against the simulator, fps

- Blobs: each layer's markers absorb their own channel (the outer cyan markers red, the
  inner magenta ones green). The optical density -ln(I / background) of that channel, the
  background being the rest image with its markers closed away (a grey closing), is
  thresholded and labelled (scipy.ndimage); a blob must absorb its own channel at least half
  as strongly as the other, so the overlap of the two layers counts for the outer one.
- Matching: every marker takes the blob nearest to where it was last (the rest image: where
  the layout projects it) within 0.45 of the marker spacing; none there leaves it NaN.
- u_x, u_y: the centroid's ray (equidistant fisheye at the dome's centre) met with the
  marker's sphere, less its rest position.
- u_z: the size cue docs/SENSOR.md holds the hollow dome to. A marker moved inward by d from
  radius r looks (r / (r - d))^2 larger, so d = g r (1 - 1 / sqrt(A / A_rest)) from its area
  A above half its peak density. The gain g is 1 for that geometric law; a press of known
  depth calibrates it (`calibrate_size`), as the papers calibrate u_z with a Hertz press.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

LAYERS = ("inner", "outer")
CHANNEL = {"inner": 1, "outer": 0}   # magenta absorbs green, cyan absorbs red


@dataclass
class Layout:
    """Where each layer's markers rest (mm, camera at the origin looking along +z) and the
    equidistant fisheye that sees them."""
    rest_mm: dict[str, np.ndarray]
    half_fov_rad: float
    width_px: int
    height_px: int

    @classmethod
    def from_sensor(cls, sensor) -> "Layout":
        import yaml
        cam = yaml.safe_load(sensor.resolved_yaml)["sensor"]["camera"]
        if cam.get("model", "equidistant") != "equidistant" or any(
                cam.get(k, 0) for k in ("roll_deg", "pitch_deg", "yaw_deg")):
            raise ValueError("chromasim.tracker: only the centred equidistant fisheye "
                             "(sensor.camera.model: equidistant, no rotation) is supported")
        h, w = sensor.image_size
        return cls({layer: np.asarray(sensor.marker_rest_positions(layer), float)
                    for layer in LAYERS}, math.radians(cam["half_fov_deg"]), w, h)

    @property
    def circle_px(self) -> float:
        return 0.5 * min(self.width_px, self.height_px)

    def project(self, p_mm: np.ndarray) -> np.ndarray:
        """Pixel positions (x, y; pixel i spans [i, i + 1]) of points, n x 3 -> n x 2."""
        rho = np.hypot(p_mm[:, 0], p_mm[:, 1])
        r_px = np.arctan2(rho, p_mm[:, 2]) / self.half_fov_rad * self.circle_px
        phi = np.arctan2(p_mm[:, 1], p_mm[:, 0])
        return np.stack([0.5 * self.width_px + r_px * np.cos(phi),
                         0.5 * self.height_px + r_px * np.sin(phi)], axis=1)

    def rays(self, px: np.ndarray) -> np.ndarray:
        """Unit directions through pixel positions, n x 2 -> n x 3."""
        off = px - np.array([0.5 * self.width_px, 0.5 * self.height_px])
        r = np.hypot(off[:, 0], off[:, 1])
        theta = r / self.circle_px * self.half_fov_rad
        s = np.where(r > 0, np.sin(theta) / np.maximum(r, 1e-300), 0.0)
        return np.stack([s * off[:, 0], s * off[:, 1], np.cos(theta)], axis=1)

    def spacing_px(self, layer: str) -> float:
        """The median distance in the image between a marker and its nearest neighbour."""
        p = self.project(self.rest_mm[layer])
        d = np.hypot(*(p[:, None, :] - p[None, :, :]).transpose(2, 0, 1))
        np.fill_diagonal(d, np.inf)
        return float(np.median(d.min(axis=1)))


@dataclass
class LayerField:
    """One layer's markers in one image."""
    u_mm: np.ndarray          # markers x 3 displacement, NaN where not found
    found: np.ndarray         # markers, bool
    centroid_px: np.ndarray   # markers x 2
    size_ratio: np.ndarray    # apparent area over the rest image's

    def normal_mm(self, rest_mm: np.ndarray) -> np.ndarray:
        """The inward displacement along each marker's rest direction."""
        return -(self.u_mm * rest_mm).sum(axis=1) / np.linalg.norm(rest_mm, axis=1)


class Tracker:
    """Follows every marker of both layers from the rest image, frame after frame."""

    def __init__(self, layout: Layout, rest_image: np.ndarray, threshold: float = 0.4,
                 size_gain: float = 1.0):
        self.layout, self.threshold, self.size_gain = layout, threshold, size_gain
        rest = self._checked(rest_image)
        self.spacing = {layer: layout.spacing_px(layer) for layer in LAYERS}
        self.background = background_of(rest, 0.8 * min(self.spacing.values()))
        self.rest = {layer: self._match(layer, rest, layout.project(layout.rest_mm[layer]))
                     for layer in LAYERS}
        self.reset()

    def _checked(self, image) -> np.ndarray:
        a = np.asarray(image)
        want = (self.layout.height_px, self.layout.width_px, 3)
        if a.shape != want or a.dtype != np.uint8:
            raise ValueError(f"chromasim.tracker: an image of {a.shape} {a.dtype}; allowed: "
                             f"{want} uint8 (the sensor's PNG pixels)")
        return srgb_to_linear(a)

    def reset(self) -> None:
        """Starts a new sequence: markers are looked for near their rest positions."""
        self.last = {layer: self.rest[layer][0].copy() for layer in LAYERS}

    def _blobs(self, lin: np.ndarray, layer: str) -> tuple[np.ndarray, np.ndarray]:
        """(centroids n x 2, areas n) of the layer's blobs."""
        return blobs(lin, self.background, layer, self.threshold)

    def _match(self, layer: str, lin: np.ndarray, guess_px: np.ndarray):
        """(centroid_px, area, found) per marker: the nearest blob to its guess."""
        centroid, area = self._blobs(lin, layer)
        n = len(guess_px)
        at, size = np.full((n, 2), np.nan), np.full(n, np.nan)
        if len(area):
            d = np.hypot(*(guess_px[:, None, :] - centroid[None, :, :]).transpose(2, 0, 1))
            nearest = d.argmin(axis=1)
            ok = d[np.arange(n), nearest] < 0.45 * self.spacing[layer]
            at[ok], size[ok] = centroid[nearest[ok]], area[nearest[ok]]
        return at, size, np.isfinite(size)

    def track(self, image: np.ndarray) -> dict[str, LayerField]:
        """Every marker's displacement (mm) in `image` (H x W x 3 uint8, the PNG's pixels)."""
        lin = self._checked(image)
        out = {}
        for layer in LAYERS:
            at, size, found = self._match(layer, lin, self.last[layer])
            # a blob a third or three times its rest size is two merged markers or a fragment
            with np.errstate(invalid="ignore"):
                plausible = np.abs(np.log(size / self.rest[layer][1])) < np.log(3.0)
            found &= self.rest[layer][2] & plausible
            self.last[layer] = np.where(found[:, None], at, self.last[layer])
            ratio = np.where(found, size / self.rest[layer][1], np.nan)
            out[layer] = LayerField(self._displacement(layer, at, ratio, found), found, at,
                                    ratio)
        return out

    def _displacement(self, layer, at, ratio, found) -> np.ndarray:
        rest_mm = self.layout.rest_mm[layer]
        r = np.linalg.norm(rest_mm, axis=1)
        inward = self.size_gain * r * (1.0 - 1.0 / np.sqrt(np.where(found, ratio, 1.0)))
        u = self.layout.rays(np.where(found[:, None], at, 0.0)) * (r - inward)[:, None] - rest_mm
        u[~found] = np.nan
        return u


def srgb_to_linear(image: np.ndarray) -> np.ndarray:
    """A PNG's 8-bit sRGB pixels as linear values in [0, 1]."""
    x = np.asarray(image, np.float64) / 255.0
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def background_of(lin: np.ndarray, size_px: float) -> np.ndarray:
    """The image with its markers closed away (a grey closing `size_px` across)."""
    size = max(3, int(round(size_px)))
    return np.maximum(ndimage.grey_closing(lin, size=(size, size, 1)), 1e-3)


def blobs(lin: np.ndarray, background: np.ndarray, layer: str,
          threshold: float = 0.4) -> tuple[np.ndarray, np.ndarray]:
    """(centroids n x 2 px, areas n px) of one layer's markers in a linear image: its channel's
    optical density against `background` above `threshold`, at least half the other's."""
    c = CHANNEL[layer]
    dens = -np.log(np.clip(lin[:, :, c], 1e-4, None) / background[:, :, c])
    other = -np.log(np.clip(lin[:, :, 1 - c], 1e-4, None) / background[:, :, 1 - c])
    mask = (dens > threshold) & (dens > 0.5 * other)
    labels, n = ndimage.label(mask)
    if n == 0:
        return np.zeros((0, 2)), np.zeros(0)
    index = np.arange(1, n + 1)
    w = np.where(mask, dens, 0.0)
    mass = ndimage.sum(w, labels, index)
    ys, xs = np.indices(mask.shape)
    centroid = np.stack([ndimage.sum(w * (xs + 0.5), labels, index) / mass,
                         ndimage.sum(w * (ys + 0.5), labels, index) / mass], axis=1)
    peak = ndimage.maximum(dens, labels, index)
    upper = mask & (dens >= 0.5 * peak[np.maximum(labels - 1, 0)])
    return centroid, np.asarray(ndimage.sum(upper.astype(float), labels, index))


def calibrate_size(fields: list[LayerField], inward_mm: list[np.ndarray],
                   rest_mm: np.ndarray, min_mm: float = 0.2) -> float:
    """The size gain g that maps the geometric law to known inward displacements (a press of
    known depth): the median ratio over the markers found pressed in at least `min_mm`."""
    r = np.linalg.norm(rest_mm, axis=1)
    x = np.concatenate([r * (1.0 - 1.0 / np.sqrt(f.size_ratio)) for f in fields])
    y = np.concatenate(inward_mm)
    ok = np.isfinite(x) & (y >= min_mm) & (x > 0)
    if not ok.any():
        raise ValueError(f"chromasim.tracker: no marker found pressed in by {min_mm} mm: "
                         f"press deeper to calibrate the size cue")
    return float(np.median(y[ok] / x[ok]))


def _errors(field: LayerField, truth: np.ndarray, rest_mm: np.ndarray) -> dict:
    """RMS and max errors (mm) of the tangential and normal displacements, markers found."""
    ok = field.found
    n = rest_mm[ok] / np.linalg.norm(rest_mm[ok], axis=1)[:, None]

    def split(u):
        un = (u * n).sum(axis=1)
        return u - un[:, None] * n, un

    (ut_e, un_e), (ut_t, un_t) = split(field.u_mm[ok]), split(truth[ok])
    et, en = np.linalg.norm(ut_e - ut_t, axis=1), un_e - un_t
    return {"found": int(ok.sum()), "tangential_rms": float(np.sqrt((et ** 2).mean())),
            "tangential_max": float(et.max()), "normal_rms": float(np.sqrt((en ** 2).mean())),
            "normal_max": float(np.abs(en).max()),
            "u_t_max": float(np.linalg.norm(ut_t, axis=1).max()),
            "u_n_max": float(np.abs(un_t).max())}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python3 -m chromasim.tracker",
                                 description="Marker tracking against the simulator's truth.")
    ap.add_argument("spec", help="a chromasim spec (its first object unless --object)")
    ap.add_argument("--object", default=0, help="the spec object pressed")
    ap.add_argument("--mu", type=float, default=1.0)
    ap.add_argument("--grip", type=float, default=1.5, help="the pull's grip (N)")
    a = ap.parse_args(argv)
    from .sim import Sensor
    sensor = Sensor(a.spec)
    layout = Layout.from_sensor(sensor)
    contact = sensor.contact(a.object, mu=a.mu, fingers=1)
    tracker = Tracker(layout, contact.step(grip_N=1e-4).image("left"))
    fields, inward = [], []
    for grip in (0.5, 1.0, 2.0):   # the calibration press
        frame = contact.step(grip_N=grip)
        fields.append(tracker.track(frame.image("left"))["outer"])
        inward.append(-(frame.markers("left")["outer"] * layout.rest_mm["outer"]).sum(1)
                      / np.linalg.norm(layout.rest_mm["outer"], axis=1))
    tracker.size_gain = calibrate_size(fields, inward, layout.rest_mm["outer"])
    print(f"size gain from the press: {tracker.size_gain:.3f}")
    contact.reset()
    tracker.reset()
    print("| grip N | load N | Gamma | layer | found | u_t max | u_t err rms / max | u_n max "
          "| u_n err rms / max |\n|---|---|---|---|---|---|---|---|---|")
    seconds = []
    for load in np.linspace(0.0, 0.9 * a.mu * a.grip, 5):
        frame = contact.step(grip_N=a.grip, load_N=float(load))
        image = frame.image("left")
        t = time.perf_counter()
        field = tracker.track(image)
        seconds.append(time.perf_counter() - t)
        truth = frame.markers("left")
        for layer in LAYERS:
            e = _errors(field[layer], truth[layer], layout.rest_mm[layer])
            print(f"| {a.grip:g} | {load:.2f} | {frame.gamma:.2f} | {layer} | {e['found']} | "
                  f"{e['u_t_max']:.2f} | {e['tangential_rms']:.3f} / {e['tangential_max']:.3f} "
                  f"| {e['u_n_max']:.2f} | {e['normal_rms']:.3f} / {e['normal_max']:.3f} |")
    print(f"tracking: {1.0 / float(np.median(seconds)):.0f} images/s "
          f"({sensor.image_size[1]} x {sensor.image_size[0]} px, median of {len(seconds)})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
