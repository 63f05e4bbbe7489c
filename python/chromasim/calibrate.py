"""Fits the simulator to a user's own sensor from a rest image and a few presses of known
force (`chromasim calibrate`; docs/CALIBRATION.md has the method and its validation).

    python3 -m chromasim.calibrate SPEC --rest REST.png \\
        [--press IMAGE OBJECT FORCE_N]... -o FITTED.yaml [--report R.json] [--picture P.png]

SPEC is the user's spec with its nominal values (the sensor's geometry, the spectra, the
image size). Its images are the sensor's PNGs at the spec's render.width_px x height_px, the
rest image unloaded, each press a spec object pressed straight onto the dome with FORCE_N.

Three stages, each a least-squares fit:
1. camera: every marker's blob in the rest image (tracker.blobs) against the rest markers
   projected by the equidistant fisheye posed by half_fov_deg, roll_deg, pitch_deg, yaw_deg;
   matched to the nearest blob, fitted, matched again (three rounds);
2. optics: the rest image against the simulator's at the fitted camera, over the coating's
   albedo scale, the two dyes' absorption scales and the LEDs' relative gains (finite
   differences through the renderer); for each render the sensor's gain and vignetting
   k1, k2 are the linear least-squares answer (the image is linear in g, g k1, g k2);
3. stiffness: the press images against the simulator's at force F / c with the spec's
   moduli: a neo-Hookean dome's forces scale with its moduli at a fixed deformation, so the
   press at F with every layer's E times c is the press at F / c; c by a bounded scalar search.
The fragment holds the fitted values; the report the residuals against the noise the sensor
model predicts. Nothing is written unless every stage converged.
"""

from __future__ import annotations

import argparse
import copy
import json
import math
import os
import sys
import tempfile
import time
from dataclasses import dataclass, field

import numpy as np

from .tracker import LAYERS, background_of, blobs, srgb_to_linear

#: The optics keys stage 2 fits (sensor.optics.*), before the LEDs' gains. The coating's
#: albedo is not among them: auto exposure takes most of it away, and what is left is below
#: the light cache's noise (docs/CALIBRATION.md).
OPTICS = ("inner_marker_absorption_scale", "outer_marker_absorption_scale")
#: The residual (RMS over the noise the sensor model predicts) above which a fit failed.
MAX_NOISE_RATIO = 3.0
#: Fewer markers than this share found in the rest image: not a sensor image of this spec.
MIN_FOUND = 0.5


class CalibrationError(ValueError):
    """Bad input or a fit that did not converge: the message says which and what to do."""


@dataclass
class Press:
    path: str
    image: np.ndarray      # H x W x 3 uint8
    object: str
    force_N: float
    linear: np.ndarray | None = None   # the image's linear values


@dataclass
class Result:
    camera: dict = field(default_factory=dict)       # half_fov_deg, roll/pitch/yaw_deg
    optics: dict = field(default_factory=dict)       # OPTICS
    led_gains: list = field(default_factory=list)
    sensor: dict = field(default_factory=dict)       # gain, k1, k2
    stiffness_scale: float | None = None
    moduli_MPa: dict = field(default_factory=dict)   # layer -> E
    residuals: dict = field(default_factory=dict)    # image -> {rms, noise_rms, ratio}
    markers: dict = field(default_factory=dict)      # found, rms_px
    seconds: dict = field(default_factory=dict)
    images: dict = field(default_factory=dict)       # name -> (user, model) linear


# ---- Reading the spec and the images -------------------------------------------------------

def _resolved(spec_path: str) -> dict:
    import yaml
    from .sim import Sensor
    sensor = Sensor(spec_path)
    spec = yaml.safe_load(sensor.resolved_yaml)
    if not sensor.renders:
        raise CalibrationError(f"{spec_path}: outputs.images is false; allowed: a spec that "
                               f"renders images (calibrate compares them with yours)")
    base = os.path.dirname(os.path.abspath(spec_path))
    for obj in spec["objects"]:
        if obj.get("mesh_file") and not os.path.isabs(obj["mesh_file"]):
            obj["mesh_file"] = os.path.join(base, obj["mesh_file"])
    if spec["sensor"]["optics"].get("spectra_dir") and not os.path.isabs(
            spec["sensor"]["optics"]["spectra_dir"]):
        spec["sensor"]["optics"]["spectra_dir"] = os.path.join(
            base, spec["sensor"]["optics"]["spectra_dir"])
    cam = spec["sensor"]["camera"]
    if cam["model"] != "equidistant":
        raise CalibrationError(f"{spec_path}: sensor.camera.model = {cam['model']}; allowed: "
                               f"equidistant (calibrate fits its field and pose)")
    return spec


def read_image(path: str, spec: dict) -> np.ndarray:
    """A sensor image as H x W x 3 uint8, or CalibrationError naming the file and the size."""
    try:
        import OpenImageIO as oiio
    except ImportError as e:  # pragma: no cover - install-deps installs it
        raise CalibrationError("python3-openimageio is not installed (scripts/install-deps "
                               "installs it)") from e
    inp = oiio.ImageInput.open(path)
    if inp is None:
        raise CalibrationError(f"{path}: cannot be read as an image ({oiio.geterror()})")
    try:
        pixels = inp.read_image(format="uint8")
    finally:
        inp.close()
    w, h = spec["render"]["width_px"], spec["render"]["height_px"]
    if pixels is None or pixels.ndim != 3 or pixels.shape[2] < 3:
        raise CalibrationError(f"{path}: not an RGB image; allowed: the sensor's {w} x {h} "
                               f"RGB PNG")
    if pixels.shape[:2] != (h, w):
        raise CalibrationError(f"{path}: {pixels.shape[1]} x {pixels.shape[0]} px; allowed: "
                               f"{w} x {h} px (the spec's render.width_px x height_px)")
    return np.ascontiguousarray(pixels[:, :, :3])


# ---- Stage 1: the camera from the rest image's markers ---------------------------------------

def rotation(roll_deg: float, pitch_deg: float, yaw_deg: float) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll): p_dome = R p_camera (scene_data.hpp, CameraParams)."""
    from scipy.spatial.transform import Rotation
    return Rotation.from_euler("xyz", [roll_deg, pitch_deg, yaw_deg], degrees=True).as_matrix()


def project(p_mm: np.ndarray, cam: dict, width: int, height: int) -> np.ndarray:
    """Pixel positions (x, y) of dome points through the posed equidistant fisheye."""
    R = rotation(cam["roll_deg"], cam["pitch_deg"], cam["yaw_deg"])
    q = p_mm @ R   # R^T p per row
    rho = np.hypot(q[:, 0], q[:, 1])
    r_px = np.arctan2(rho, q[:, 2]) / math.radians(cam["half_fov_deg"]) * 0.5 * min(width,
                                                                                     height)
    phi = np.arctan2(q[:, 1], q[:, 0])
    return np.stack([0.5 * width + r_px * np.cos(phi), 0.5 * height + r_px * np.sin(phi)], 1)


def _spacing_px(p_px: np.ndarray) -> float:
    d = np.hypot(*(p_px[:, None, :] - p_px[None, :, :]).transpose(2, 0, 1))
    np.fill_diagonal(d, np.inf)
    return float(np.median(d.min(axis=1)))


def fit_camera(rest_lin: np.ndarray, rest_mm: dict, cam0: dict, path: str) -> tuple[dict, dict]:
    """The camera that projects the rest markers onto their blobs, and the match's quality."""
    from scipy.optimize import least_squares
    h, w = rest_lin.shape[:2]
    keys = ("half_fov_deg", "roll_deg", "pitch_deg", "yaw_deg")
    spacing = min(_spacing_px(project(rest_mm[layer], cam0, w, h)) for layer in LAYERS)
    background = background_of(rest_lin, 0.8 * spacing)
    found = {layer: blobs(rest_lin, background, layer)[0] for layer in LAYERS}
    cam = dict(cam0)
    total = sum(len(rest_mm[layer]) for layer in LAYERS)
    for radius in (0.45, 0.35, 0.25):   # match, fit, match tighter
        pairs = []
        for layer in LAYERS:
            p = project(rest_mm[layer], cam, w, h)
            b = found[layer]
            if not len(b):
                continue
            d = np.hypot(*(p[:, None, :] - b[None, :, :]).transpose(2, 0, 1))
            near = d.argmin(1)
            ok = d[np.arange(len(p)), near] < radius * spacing
            pairs.append((rest_mm[layer][ok], b[near[ok]]))
        matched = sum(len(m) for m, _ in pairs)
        if matched < MIN_FOUND * total:
            raise CalibrationError(
                f"{path}: {matched} of {total} markers found near where the spec's camera puts "
                f"them; allowed: the sensor's rest image, its markers within half a marker "
                f"spacing of the spec's camera model (sensor.camera half_fov_deg and pose)")
        pts = np.concatenate([m for m, _ in pairs])
        obs = np.concatenate([b for _, b in pairs])

        def residual(x):
            c = dict(cam, **dict(zip(keys, x)))
            return (project(pts, c, w, h) - obs).ravel()

        sol = least_squares(residual, [cam[k] for k in keys], x_scale=[5.0, 1.0, 1.0, 1.0])
        if not sol.success:
            raise CalibrationError(f"{path}: the camera fit did not converge ({sol.message})")
        cam.update(zip(keys, (float(v) for v in sol.x)))
    rms = float(np.sqrt(np.mean(np.sum(sol.fun.reshape(-1, 2) ** 2, axis=1))))
    return cam, {"found": int(matched), "of": int(total), "rms_px": rms, "spacing_px": spacing}


# ---- The simulator's images ----------------------------------------------------------------

def field_position(height: int, width: int) -> np.ndarray:
    """t = theta / half_fov of each pixel centre for the equidistant fisheye (1 outside), as the
    sensor model's vignetting takes it (render/sensor_model.hpp)."""
    ys, xs = np.indices((height, width)) + 0.5
    r = np.hypot(xs - 0.5 * width, ys - 0.5 * height) / (0.5 * min(width, height))
    return np.minimum(r, 1.0)


class Simulator:
    """Renders the spec's sensor with trial values: a new Sensor per optics, the mechanics read
    from the user's cache, the light caches kept in a folder of their own (removed at the end)."""

    def __init__(self, spec: dict, cache_dir: str):
        self.spec = spec
        self.cache = cache_dir
        self.renders = 0

    def with_values(self, cam: dict, optics: dict, gains: list) -> dict:
        s = copy.deepcopy(self.spec)
        s["sensor"]["camera"].update(cam)
        s["sensor"]["optics"].update(optics)
        s["sensor"]["led"]["gains"] = [float(g) for g in gains]
        s["sensor"]["led"]["gain_tolerance"] = 0.0
        s["outputs"] = dict(s["outputs"], images=True, exr=False, marker_ids=False,
                            variance=False, strain=False)
        return s

    def sensor(self, spec: dict):
        from .sim import Sensor
        return Sensor(spec, cache_dir=self.cache)

    def image(self, sensor, object_name: str, force_N: float) -> np.ndarray:
        """The noise-free linear image of `object_name` pressed with force_N (1e-4 N: rest)."""
        contact = sensor.contact(object_name, mu=1.0, fingers=1)
        self.renders += 1
        return np.asarray(contact.step(grip_N=force_N).image("left", "linear"), np.float64)


def sensor_gains(render: np.ndarray, user: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, float,
                                                                                 float, float]:
    """The sensor's gain g and vignetting k1, k2 that best map `render` onto `user`:
    user = render (g + g k1 t^2 + g k2 t^4), linear least squares over the unclipped pixels
    inside the field; returns (the model image, g, k1, k2)."""
    use = (t < 0.97)[:, :, None] & (user < 0.98) & (render > 0)
    a = np.stack([render, render * t[:, :, None] ** 2, render * t[:, :, None] ** 4], -1)[use]
    coef, *_ = np.linalg.lstsq(a, user[use], rcond=None)
    g, k1, k2 = float(coef[0]), float(coef[1] / coef[0]), float(coef[2] / coef[0])
    vignette = np.maximum(0.0, 1.0 + k1 * t ** 2 + k2 * t ** 4)[:, :, None]
    return np.clip(g * vignette * render, 0.0, 1.0), g, k1, k2


#: The background's polar bins: rings over t = theta / half_fov, sectors over the azimuth.
RINGS = (0.15, 0.4, 0.6, 0.75, 0.9)
SECTORS = 12


def densities(lin: np.ndarray, background: np.ndarray) -> np.ndarray:
    """Each layer's median optical density per channel at its markers' centres (6 values):
    a median over about 80 markers, which the light cache's blotches hardly move."""
    h, w = lin.shape[:2]
    out = []
    for layer in LAYERS:
        at, _ = blobs(lin, background, layer)
        ix = np.clip(at.astype(int), 0, [w - 1, h - 1])
        d = -np.log(np.clip(lin[ix[:, 1], ix[:, 0]], 1e-4, None) / background[ix[:, 1], ix[:, 0]])
        out.append(np.median(d, axis=0) if len(d) else np.zeros(3))
    return np.concatenate(out)


def azimuthal_profile(background: np.ndarray) -> np.ndarray:
    """The background's brightness per sector over its ring's mean (rings x sectors x 3): how
    the LEDs' light varies round the dome, whatever the gain, vignetting and albedo."""
    h, w = background.shape[:2]
    t = field_position(h, w)
    ys, xs = np.indices((h, w)) + 0.5
    sector = (((np.arctan2(ys - 0.5 * h, xs - 0.5 * w) % (2 * np.pi)) / (2 * np.pi) * SECTORS)
              .astype(int) % SECTORS)
    out = []
    for lo, hi in zip(RINGS[:-1], RINGS[1:]):
        ring = (t >= lo) & (t < hi)
        means = np.array([background[ring & (sector == k)].mean(axis=0) for k in range(SECTORS)])
        out.append(means / means.mean(axis=0))
    return np.concatenate(out).ravel()


def _gains(g: np.ndarray) -> np.ndarray:
    """LED gains of mean 1 from all but the first (auto exposure leaves their scale free)."""
    return np.concatenate([[len(g) + 1 - g.sum()], g])


def _least_squares(fun, x0, lower, upper, step: float, what: str):
    """scipy's trust-region least squares with forward differences `step` times each value
    (every value starts at 1), wide enough to stand above the renders' noise."""
    from scipy.optimize import least_squares
    sol = least_squares(fun, x0, bounds=(lower, upper), diff_step=step,
                        x_scale=0.1, max_nfev=10, xtol=2e-3, ftol=1e-4)
    if sol.status < 0 or not np.all(np.isfinite(sol.x)):
        raise CalibrationError(f"the {what} fit did not converge ({sol.message})")
    at_bound = np.isclose(sol.x, lower, atol=1e-3) | np.isclose(sol.x, upper, atol=1e-3)
    if at_bound.any():
        raise CalibrationError(f"the {what} fit did not converge: it ran into the end of its "
                               f"range; check that the images are this spec's sensor")
    return sol


def fit_optics(sim: Simulator, cam: dict, rest: np.ndarray, obj: str, leds: int,
               spacing_px: float) -> dict:
    """The dye scales that give the markers their optical densities (six medians), then the
    LEDs' gains that give the background its azimuthal profile; the sensor gain and
    vignetting by linear least squares on each render."""
    t = field_position(*rest.shape[:2])
    user_bg = background_of(rest, 0.8 * spacing_px)
    user_dens, user_profile = densities(rest, user_bg), azimuthal_profile(user_bg)
    state = {"optics": np.ones(len(OPTICS)), "gains": np.ones(leds - 1)}

    def render(x_optics, x_gains):
        optics = dict(zip(OPTICS, (float(v) for v in x_optics)))
        s = sim.sensor(sim.with_values(cam, optics, _gains(x_gains)))
        image = sensor_gains(sim.image(s, obj, 1e-4), rest, t)
        return image, background_of(image[0], 0.8 * spacing_px)

    def dens_residual(x):
        image, bg = render(x, state["gains"])
        return densities(image[0], bg) - user_dens

    def profile_residual(x):
        image, bg = render(state["optics"], x)
        return azimuthal_profile(bg) - user_profile

    state["optics"] = _least_squares(dens_residual, state["optics"], np.full(len(OPTICS), 0.25),
                                     np.full(len(OPTICS), 4.0), 0.04, "optics").x
    state["gains"] = _least_squares(profile_residual, state["gains"], np.full(leds - 1, 0.3),
                                    np.full(leds - 1, 2.0), 0.05, "LED gain").x
    (image, g, k1, k2), _ = render(state["optics"], state["gains"])
    gains = _gains(state["gains"])
    return {"optics": dict(zip(OPTICS, (float(v) for v in state["optics"]))),
            "led_gains": [float(v) for v in gains / gains.mean()],
            "sensor": {"gain": g, "k1": k1, "k2": k2}, "image": image}


def fit_stiffness(sim: Simulator, spec: dict, presses: list, rest_model: np.ndarray,
                  sensor_fit: dict) -> tuple[float, dict]:
    """The scale c of every layer's E whose presses look most like the user's: the press at
    F / c with the spec's moduli, through the fitted sensor gain and vignetting (a bounded
    scalar search over log c)."""
    from scipy.optimize import minimize_scalar
    t = field_position(*rest_model.shape[:2])
    vignette = np.maximum(0.0, 1.0 + sensor_fit["k1"] * t ** 2 + sensor_fit["k2"] * t ** 4)
    gain = sensor_fit["gain"] * vignette[:, :, None]
    sensor = sim.sensor(spec)
    images = {}

    def cost(log_c):
        total = 0.0
        for p in presses:
            model = np.clip(gain * sim.image(sensor, p.object, p.force_N / math.exp(log_c)),
                            0, 1)
            images[p.path] = model
            total += float(np.mean((model - p.linear) ** 2))
        return total

    sol = minimize_scalar(cost, bounds=(math.log(0.25), math.log(4.0)), method="bounded",
                          options={"xatol": 0.01})
    c = math.exp(sol.x)
    if not sol.success or abs(sol.x) > math.log(4.0) - 0.02:
        raise CalibrationError(f"the stiffness fit did not converge: the presses ask for moduli "
                               f"{c:.3g} times the spec's, outside 0.25 to 4; check the forces "
                               f"and objects given with the presses")
    cost(sol.x)   # the images at the answer
    return c, images


def noise_rms(model: np.ndarray, spec: dict) -> float:
    """The RMS noise the sensor model and the 8-bit sRGB PNG add to a linear image."""
    s = spec["render"]["sensor"]
    full_well = s["full_well_e"]
    var = ((model * full_well if s["shot_noise"] else 0.0) + s["read_noise_e"] ** 2) / full_well ** 2
    var = var + (1.0 / (2 ** s["adc_bits"] - 1)) ** 2 / 12.0
    # the PNG's step in sRGB, in linear terms: d lin / d srgb over 255, uniform
    srgb = np.where(model <= 0.0031308, model * 12.92, 1.055 * model ** (1 / 2.4) - 0.055)
    slope = np.where(srgb <= 0.04045, 1 / 12.92, 2.4 / 1.055 * ((srgb + 0.055) / 1.055) ** 1.4)
    var = var + (slope / 255.0) ** 2 / 12.0
    return float(np.sqrt(np.mean(var)))


# ---- The whole fit ---------------------------------------------------------------------------

def calibrate(spec_path: str, rest_path: str, presses: list[tuple[str, str, float]],
              cache_dir: str | None = None) -> tuple[Result, dict]:
    """Fits `spec_path`'s sensor to the user's images; returns the result and the fitted spec."""
    from .sim import Sensor
    t0 = time.perf_counter()
    spec = _resolved(spec_path)
    if not spec["render"]["sensor"]["enabled"]:
        raise CalibrationError(f"{spec_path}: render.sensor.enabled is false; allowed: true, "
                               f"with the noise of your camera (calibrate fits its gain and "
                               f"vignetting, and judges the residual against its noise)")
    names = [o["name"] for o in spec["objects"]]
    rest = srgb_to_linear(read_image(rest_path, spec))
    items = _presses(spec, spec_path, presses)
    nominal = Sensor(spec, cache_dir=cache_dir)   # the mechanics into the user's cache
    rest_mm = {layer: np.asarray(nominal.marker_rest_positions(layer)) for layer in LAYERS}
    res = Result()
    cam0 = {k: spec["sensor"]["camera"][k] for k in ("half_fov_deg", "roll_deg", "pitch_deg",
                                                     "yaw_deg")}
    res.camera, res.markers = fit_camera(rest, rest_mm, cam0, rest_path)
    res.seconds["camera"] = time.perf_counter() - t0
    user_cache = cache_dir or _default_cache()
    with tempfile.TemporaryDirectory(prefix="chromasim-calibrate-") as tmp:
        for name in os.listdir(user_cache) if os.path.isdir(user_cache) else []:
            if name.startswith("model-"):
                os.symlink(os.path.join(user_cache, name), os.path.join(tmp, name))
        sim = Simulator(spec, tmp)
        fit = fit_optics(sim, res.camera, rest, names[0], spec["sensor"]["led"]["count"],
                         res.markers["spacing_px"])
        res.optics, res.led_gains, res.sensor = fit["optics"], fit["led_gains"], fit["sensor"]
        res.images["rest"] = (rest, fit["image"])
        res.seconds["optics"] = time.perf_counter() - t0 - res.seconds["camera"]
        fitted = sim.with_values(res.camera, res.optics, res.led_gains)
        if items:
            c, images = fit_stiffness(sim, fitted, items, fit["image"], res.sensor)
            res.stiffness_scale = c
            for layer, m in fitted["sensor"]["materials"].items():
                if layer != "fill" or spec["sensor"]["interior"] == "soft_fill":
                    res.moduli_MPa[layer] = m["E_MPa"] * c
            for p in items:
                res.images[p.path] = (p.linear, images[p.path])
        res.seconds["stiffness"] = (time.perf_counter() - t0 - res.seconds["camera"]
                                    - res.seconds["optics"])
        res.seconds["renders"] = sim.renders
    inside = field_position(*rest.shape[:2]) < 0.97
    for name, (user, model) in res.images.items():
        rms = float(np.sqrt(np.mean((user - model)[inside] ** 2)))
        noise = noise_rms(model[inside], spec)
        res.residuals[name] = {"rms": rms, "noise_rms": noise, "ratio": rms / noise}
    worst = max(r["ratio"] for r in res.residuals.values())
    if worst > MAX_NOISE_RATIO:
        raise CalibrationError(f"the fit did not converge: an image residual is {worst:.1f} "
                               f"times the sensor's noise (allowed: up to {MAX_NOISE_RATIO}); "
                               f"check that the images are this spec's sensor, unloaded at rest "
                               f"and pressed with the forces given")
    return res, spec


def _presses(spec: dict, spec_path: str, presses: list) -> list[Press]:
    """The presses' images read and checked against the spec's objects, before any work."""
    names = [o["name"] for o in spec["objects"]]
    out = []
    for path, obj, force in presses:
        if obj not in names:
            raise CalibrationError(f"--press {path} {obj} {force}: object '{obj}'; allowed: "
                                   f"an object of {spec_path}: {', '.join(names)}")
        if not (math.isfinite(force) and 0.05 <= force <= 10.0):
            raise CalibrationError(f"--press {path} {obj} {force}: force {force} N; allowed: "
                                   f"0.05 to 10 N")
        image = read_image(path, spec)
        out.append(Press(path, image, obj, force, srgb_to_linear(image)))
    return out


def _default_cache() -> str:
    from . import sim
    return sim._core.default_cache_dir()


# ---- Output ---------------------------------------------------------------------------------

def _num(x: float) -> str:
    return f"{x:.6g}"


def fragment(res: Result, spec_path: str, rest_path: str, presses: list) -> str:
    """The fitted values as a spec fragment (YAML), to merge into the user's spec."""
    cam = ", ".join(f"{k}: {_num(v)}" for k, v in res.camera.items())
    optics = ", ".join(f"{k}: {_num(v)}" for k, v in res.optics.items())
    gains = ", ".join(_num(g) for g in res.led_gains)
    lines = [f"# chromasim calibrate: {spec_path} fitted to {rest_path}"
             + (f" and {len(presses)} presses" if presses else "") + ".",
             "# Merge these keys into the spec (docs/CALIBRATION.md).",
             "sensor:",
             f"  camera: {{{cam}}}",
             f"  led: {{gains: [{gains}]}}",
             f"  optics: {{{optics}}}"]
    if res.moduli_MPa:
        lines.append("  materials:")
        lines += [f"    {layer}: {{E_MPa: {_num(e)}}}" for layer, e in res.moduli_MPa.items()]
    s = res.sensor
    lines += ["render:",
              f"  sensor: {{gain: {_num(s['gain'])}, vignetting: {{model: polynomial, "
              f"k1: {_num(s['k1'])}, k2: {_num(s['k2'])}}}}}", ""]
    return "\n".join(lines)


def report(res: Result) -> dict:
    return {"camera": res.camera, "optics": res.optics, "led_gains": res.led_gains,
            "sensor": res.sensor, "stiffness_scale": res.stiffness_scale,
            "moduli_MPa": res.moduli_MPa, "markers": res.markers, "residuals": res.residuals,
            "seconds": res.seconds}


def picture(res: Result) -> np.ndarray:
    """One row per image: the user's, the fitted simulator's, and 4 x |difference|; sRGB."""
    rows = []
    for user, model in res.images.values():
        diff = np.clip(4.0 * np.abs(user - model), 0, 1)
        rows.append(np.concatenate([user, model, diff], axis=1))
    lin = np.clip(np.concatenate(rows, axis=0), 0, 1)
    srgb = np.where(lin <= 0.0031308, lin * 12.92, 1.055 * lin ** (1 / 2.4) - 0.055)
    return (srgb * 255 + 0.5).astype(np.uint8)


def _write(path: str, data: bytes) -> None:
    """Writes `path` whole or not at all."""
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=".calibrate-")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise


def _png_bytes(pixels: np.ndarray) -> bytes:
    import OpenImageIO as oiio
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "p.png")
        out = oiio.ImageOutput.create(path)
        out.open(path, oiio.ImageSpec(pixels.shape[1], pixels.shape[0], 3, "uint8"))
        out.write_image(pixels)
        out.close()
        with open(path, "rb") as f:
            return f.read()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="chromasim calibrate", description=(
        "Fits a spec's camera, optics, LED gains, sensor gain and vignetting to a rest image "
        "of your sensor, and its layers' stiffness to presses of known force."))
    ap.add_argument("spec", help="your sensor's spec, with its nominal values")
    ap.add_argument("--rest", required=True, help="a PNG of the unloaded sensor")
    ap.add_argument("--press", nargs=3, action="append", default=[],
                    metavar=("IMAGE", "OBJECT", "FORCE_N"),
                    help="a PNG of a spec object pressed onto the dome with FORCE_N newtons")
    ap.add_argument("-o", "--output", required=True, help="the fitted spec fragment (YAML)")
    ap.add_argument("--report", help="residuals and fitted values (JSON)")
    ap.add_argument("--picture", help="yours, the fit's and 4 x their difference (PNG)")
    ap.add_argument("--cache-dir", help="chromasim's cache (default: as generate's)")
    a = ap.parse_args(argv)
    presses = []
    for image, obj, force in a.press:
        try:
            presses.append((image, obj, float(force)))
        except ValueError:
            ap.error(f"--press {image} {obj} {force}: FORCE_N '{force}' is not a number")
    for path in [a.output] + [p for p in (a.report, a.picture) if p]:
        if not os.path.isdir(os.path.dirname(os.path.abspath(path))):
            ap.error(f"{path}: its folder does not exist")
    try:
        res, _ = calibrate(a.spec, a.rest, presses, a.cache_dir)
    except CalibrationError as e:
        print(f"chromasim calibrate: {e}; nothing written", file=sys.stderr)
        return 1
    outputs = [(a.output, fragment(res, a.spec, a.rest, presses).encode())]
    if a.report:
        outputs.append((a.report, (json.dumps(report(res), indent=2) + "\n").encode()))
    if a.picture:
        outputs.append((a.picture, _png_bytes(picture(res))))
    for path, data in outputs:
        _write(path, data)
    for name, r in res.residuals.items():
        print(f"{name}: residual {r['rms']:.4f}, {r['ratio']:.2f} x the sensor's noise")
    print(f"wrote {', '.join(p for p, _ in outputs)} ({sum(v for k, v in res.seconds.items() if k != 'renders'):.0f} s, "
          f"{res.seconds['renders']} renders)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
