"""`chromasim calibrate` recovers hidden values: "your sensor" is the small calibration spec
rendered with a hidden camera, dye strengths, LED gains, sensor gain, vignetting and stiffness,
with the sensor's noise (its own seed); the fit starts from the spec's nominal values
(docs/CALIBRATION.md). The coating's albedo is not fitted, so it stays nominal here."""

from __future__ import annotations

import copy
import json
import os
import subprocess

import numpy as np
import pytest
import yaml

from chromasim import calibrate as cal

SPEC = os.path.join(os.path.dirname(__file__), "specs", "calibration.yaml")
HIDDEN_CAMERA = {"half_fov_deg": 80.0, "roll_deg": -1.0, "pitch_deg": 1.5, "yaw_deg": 2.0}
HIDDEN_OPTICS = {"inner_marker_absorption_scale": 1.2, "outer_marker_absorption_scale": 0.85}
HIDDEN_GAINS = [1.12, 0.9, 1.05, 0.94, 1.0, 0.99]
HIDDEN_SENSOR = {"gain": 1.15, "k1": -0.25, "k2": -0.05}
HIDDEN_STIFFNESS = 1.3
PRESSES = [("flat", 1.5), ("ball", 1.5), ("flat", 3.0)]


def _png(path: str, pixels: np.ndarray) -> None:
    import OpenImageIO as oiio
    out = oiio.ImageOutput.create(path)
    out.open(path, oiio.ImageSpec(pixels.shape[1], pixels.shape[0], 3, "uint8"))
    out.write_image(pixels)
    out.close()


@pytest.fixture(scope="module")
def your_sensor(tmp_path_factory):
    """The hidden sensor's rest image and presses, as PNG files."""
    from chromasim.sim import Sensor
    folder = tmp_path_factory.mktemp("your_sensor")
    spec = yaml.safe_load(Sensor(SPEC).resolved_yaml)
    hidden = copy.deepcopy(spec)
    hidden["sensor"]["camera"].update(HIDDEN_CAMERA)
    hidden["sensor"]["optics"].update(HIDDEN_OPTICS)
    hidden["sensor"]["led"]["gains"] = HIDDEN_GAINS
    hidden["render"]["sensor"]["gain"] = HIDDEN_SENSOR["gain"]
    hidden["render"]["sensor"]["vignetting"].update(k1=HIDDEN_SENSOR["k1"],
                                                    k2=HIDDEN_SENSOR["k2"])
    hidden["render"]["sensor"]["seed"] = 77   # noise the fit's own renders never share
    for layer in hidden["sensor"]["materials"].values():
        layer["E_MPa"] *= HIDDEN_STIFFNESS
    sensor = Sensor(hidden)
    rest = str(folder / "rest.png")
    _png(rest, sensor.contact("flat", fingers=1).step(grip_N=1e-4).image("left"))
    presses = []
    for i, (obj, force) in enumerate(PRESSES):
        path = str(folder / f"press{i}.png")
        _png(path, sensor.contact(obj, fingers=1).step(grip_N=force).image("left"))
        presses.append((path, obj, force))
    return {"folder": folder, "rest": rest, "presses": presses, "spec": spec}


def _calibrate(exe: str, args: list[str]) -> subprocess.CompletedProcess:
    return subprocess.run([exe, "calibrate", *args], capture_output=True, text=True,
                          timeout=1800)


def test_calibrate_recovers_hidden_optics_camera_and_stiffness(your_sensor, chromasim_exe):
    d = your_sensor
    out, rep, pic = (str(d["folder"] / n) for n in ("fit.yaml", "fit.json", "fit.png"))
    args = [SPEC, "--rest", d["rest"], "-o", out, "--report", rep, "--picture", pic]
    for path, obj, force in d["presses"]:
        args += ["--press", path, obj, str(force)]
    r = _calibrate(chromasim_exe, args)
    assert r.returncode == 0, r.stderr
    report = json.load(open(rep))
    fitted = yaml.safe_load(open(out))
    print(json.dumps(report, indent=1))

    def within(got, want, tol, what):
        assert abs(got - want) <= tol * abs(want), f"{what}: {got} against {want}"

    for k, v in HIDDEN_CAMERA.items():
        within(fitted["sensor"]["camera"][k], v, 0.05, k)
    for k, v in HIDDEN_OPTICS.items():
        within(fitted["sensor"]["optics"][k], v, 0.05, k)
    hidden_gains = np.array(HIDDEN_GAINS) / np.mean(HIDDEN_GAINS)
    for k, (got, want) in enumerate(zip(fitted["sensor"]["led"]["gains"], hidden_gains)):
        within(got, want, 0.05, f"LED {k}'s gain")
    s = fitted["render"]["sensor"]
    within(s["gain"], HIDDEN_SENSOR["gain"], 0.05, "sensor gain")
    within(s["vignetting"]["k1"], HIDDEN_SENSOR["k1"], 0.05, "vignetting k1")
    # k2 is small: the relative illumination it and k1 give at the field's middle and edge
    for t in (0.5, 1.0):
        within(1 + s["vignetting"]["k1"] * t ** 2 + s["vignetting"]["k2"] * t ** 4,
               1 + HIDDEN_SENSOR["k1"] * t ** 2 + HIDDEN_SENSOR["k2"] * t ** 4, 0.05,
               f"relative illumination at t = {t}")
    for layer, m in fitted["sensor"]["materials"].items():
        want = d["spec"]["sensor"]["materials"][layer]["E_MPa"] * HIDDEN_STIFFNESS
        within(m["E_MPa"], want, 0.10, f"{layer} E_MPa")
    for name, res in report["residuals"].items():
        # the sensor's noise and the light cache's own (256 paths a vertex)
        assert res["ratio"] < 2.0, f"{name}: residual {res['ratio']} x the noise"
    assert os.path.getsize(pic) > 0


def test_calibrate_refuses_bad_images_and_writes_nothing(your_sensor, chromasim_exe, tmp_path):
    d = your_sensor
    out = str(tmp_path / "fit.yaml")
    small = str(tmp_path / "small.png")
    _png(small, np.zeros((32, 48, 3), np.uint8))
    r = _calibrate(chromasim_exe, [SPEC, "--rest", small, "-o", out])
    assert r.returncode == 1
    assert f"{small}: 48 x 32 px; allowed: 96 x 96 px" in r.stderr
    blank = str(tmp_path / "blank.png")
    _png(blank, np.full((96, 96, 3), 180, np.uint8))
    r = _calibrate(chromasim_exe, [SPEC, "--rest", blank, "-o", out])
    assert r.returncode == 1
    assert "0 of 164 markers found" in r.stderr
    r = _calibrate(chromasim_exe, [SPEC, "--rest", d["rest"], "-o", out,
                                   "--press", d["rest"], "cube", "1.0"])
    assert r.returncode == 1
    assert "object 'cube'; allowed: an object of" in r.stderr
    assert not os.path.exists(out)
    assert sorted(os.listdir(tmp_path)) == ["blank.png", "small.png"]
