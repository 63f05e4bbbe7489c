"""chromasim's own presses (frictionless unless `mu` is given), run through `chromasim
generate`, for cross-checks against an independent solver (scripts/crosscheck-calculix).

A press is a grasp_load trial with friction `mu` (0 by default): the grip ramps to its value
in `ramp_frames` frames (each frame one step from the previous, as in a dataset), and the last
grasp frame is read: the indentation, the contact area and the displacement of every marker
centre (markers.csv).
"""

import pathlib
import re
import subprocess
import time

import numpy as np

from chromasim.data import open_dataset

SPEC = """name: press
seed: 1
sensor:
  mesh_level: {level}
  element_order: {order}
  material_model: {model}
objects:
  - {{name: obj, shape: {shape}{radius}}}
friction:
  - {{name: press, mu: {mu}}}
fingers: {{count: 1}}
protocol:
  type: grasp_load
  frame_rate_Hz: 1
  grip_N: [{grips}]
  grasp_s: {ramp_frames}
  hold_s: 0
  load_rate_N_per_s: 1000
  target_load_N: 0.001
  slip_frames: 0
splits:
  - {{name: all, fraction: 1.0}}
outputs: {{images: false, labels: true, markers: true}}
"""


def press_spec(shape, level, model, forces, ramp_frames=4, radius_mm=45.0, order=1, mu=0.0):
    """The spec text of presses of `shape` ("flat" or "sphere") at each force (N), on tets
    of `order` (1 linear, 2 quadratic)."""
    return SPEC.format(
        level=level,
        order=order,
        model=model,
        shape=shape,
        radius=f", radius_mm: {radius_mm}" if shape == "sphere" else "",
        grips=", ".join(f"{f:g}" for f in forces),
        ramp_frames=ramp_frames,
        mu=f"{mu:g}",
    )


def run_presses(exe, workdir, shape, level, model, forces, ramp_frames=4, order=1, mu=0.0):
    """Runs the presses; returns {force: {"indentation_mm", "contact_area_mm2", "converged",
    "status", "x0_mm" (164 x 3), "u_mm" (164 x 3)}} and the mechanics seconds per solved frame."""
    workdir = pathlib.Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    spec = workdir / f"press_{shape}_{level}_p{order}_{model}_mu{mu:g}.yaml"
    spec.write_text(press_spec(shape, level, model, forces, ramp_frames, order=order, mu=mu))
    out = workdir / spec.stem
    start = time.monotonic()
    run = subprocess.run(
        [str(exe), "generate", str(spec), "-o", str(out), "--overwrite", "-q"],
        capture_output=True, text=True, check=False)
    if run.returncode != 0:
        raise RuntimeError(f"chromasim generate {spec} failed:\n{run.stdout}{run.stderr}")
    wall_s = time.monotonic() - start
    m = re.search(r"\((?:[^()]*?)(\d+) solves.*?mechanics ([0-9.e+-]+) s", run.stdout + run.stderr)
    per_frame_s = float(m.group(2)) / int(m.group(1)) if m else wall_s
    return _read_presses(out, forces, ramp_frames), per_frame_s


def _read_presses(out, forces, ramp_frames):
    data = open_dataset(str(out))
    labels, markers = data.labels, data.markers()
    result = {}
    for trial in np.unique(labels["trial"]):
        grasp = np.flatnonzero((labels["trial"] == trial) & (labels["phase"] == "grasp"))
        last = grasp[-1]  # the last grasp frame: the press at its grip
        rows = (markers["trial"] == trial) & (markers["frame"] == labels["frame"][last])
        x0 = np.column_stack([markers[k][rows] for k in ("x0_mm", "y0_mm", "z0_mm")])
        u = np.column_stack([markers[k][rows] for k in ("ux_mm", "uy_mm", "uz_mm")])
        result[float(labels["grip_N"][last])] = {
            "indentation_mm": float(labels["left_indentation_mm"][last]),
            "contact_area_mm2": float(labels["left_contact_area_mm2"][last]),
            "converged": bool(labels["left_converged"][last] == 1),
            "status": str(labels["left_status"][last]),
            "x0_mm": x0,
            "u_mm": u,
        }
    missing = [f for f in forces if not any(abs(f - g) < 1e-9 for g in result)]
    if missing:
        raise RuntimeError(f"{out}: no grasp frame for grips {missing}")
    return result
