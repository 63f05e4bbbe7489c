"""The Python API (chromasim.sim, chromasim.stream) against `chromasim generate` and the
physics of a stepped contact."""

import csv
import os
import threading
import time

import numpy as np
import pytest

from make_datasets import ROOT, SPECS

sim = pytest.importorskip(
    "chromasim.sim", reason="chromasim._core is not built here (a sanitizer build has none)")

QUICKSTART = SPECS["quickstart"]


@pytest.fixture(scope="module")
def sensor():
    return sim.Sensor(QUICKSTART)


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _text(value) -> str:
    """A value as labels.csv and markers.csv write it (C++ streams at 9 significant digits)."""
    if isinstance(value, float):
        return format(value, ".9g")
    return str(value)


def test_api_gives_the_bytes_generate_writes_on_the_quickstart(sensor, datasets):
    from PIL import Image
    root = datasets["quickstart"]
    labels = _rows(os.path.join(root, "labels.csv"))
    markers = _rows(os.path.join(root, "markers.csv"))
    marker_rows = {(r["trial"], r["frame"], r["finger"], r["layer"], r["marker"]): r
                   for r in markers}
    assert len(sensor) == 2
    row = 0
    for trial in sensor.trials():
        for frame in trial:
            expected = labels[row]
            row += 1
            got = frame.labels
            compared = [k for k in expected if not k.endswith(("_image", "_exr"))]
            assert set(compared) == set(got)
            for key in compared:
                assert _text(got[key]) == expected[key], (row, key)
            for finger in frame.fingers:
                png = np.asarray(Image.open(os.path.join(root, expected[f"{finger}_image"])))
                img = frame.image(finger)
                assert img.dtype == np.uint8 and img.shape == png.shape
                assert np.array_equal(img, png), (row, finger)
                for layer, u in frame.markers(finger).items():
                    for m in (0, 17, 81):
                        r = marker_rows[(str(frame.trial), str(frame.index), finger, layer, str(m))]
                        assert [_text(v) for v in u[m]] == [r["ux_mm"], r["uy_mm"], r["uz_mm"]]
    assert row == len(labels)


def test_marker_rest_positions_are_the_csv_x0(sensor, datasets):
    markers = _rows(os.path.join(datasets["quickstart"], "markers.csv"))
    x0 = sensor.marker_rest_positions("outer")
    assert x0.shape == (82, 3)
    first = [r for r in markers if r["layer"] == "outer" and r["frame"] == "0"
             and r["finger"] == "left" and r["trial"] == "0"]
    for r in first[:5]:
        assert [_text(v) for v in x0[int(r["marker"])]] == [r["x0_mm"], r["y0_mm"], r["z0_mm"]]


def test_stepped_grasp_follows_coulomb_and_keeps_its_history(sensor):
    grasp = sensor.contact("curved", mu=0.8)
    assert grasp.fingers == ["left", "right"]
    grip = 1.0
    for load in (0.0, 0.4, 0.8, 1.2):
        f = grasp.step(grip_N=grip, load_N=load)
        for side in f.fingers:
            assert f.labels[f"{side}_converged"] == 1
            assert f.labels[f"{side}_normal_force_N"] == pytest.approx(grip, rel=1e-6)
            # Stuck: the fingertip carries its share, and Gamma = 1 - f_t / (mu f_n).
            assert f.labels[f"{side}_tangential_force_N"] == pytest.approx(load / 2, abs=1e-6)
            assert f.labels[f"{side}_gamma"] == pytest.approx(1 - load / 2 / (0.8 * grip), abs=1e-6)
        assert f.gamma == pytest.approx(1 - load / 2 / (0.8 * grip), abs=1e-6)
    stuck_travel = f.labels["left_object_travel_x_mm"]
    assert stuck_travel > 0
    # The same loads again reuse the result; a pull past mu f_n slides (Gamma 0).
    assert grasp.step(grip_N=grip, load_N=1.2).labels["left_reused"] == 1
    slid = grasp.step(grip_N=grip, load_N=1.7)
    assert slid.labels["left_sliding"] == 1 and slid.gamma == 0.0
    # Without the history the same load from rest is a different path: reset gives the first
    # step's result again, bit for bit.
    grasp.reset()
    again = grasp.step(grip_N=grip, load_N=0.0)
    fresh = sensor.contact("curved", mu=0.8).step(grip_N=grip, load_N=0.0)
    assert again.labels == fresh.labels


def test_a_labels_only_loop_builds_no_renderer():
    s = sim.Sensor(QUICKSTART)
    f = s.contact("flat", mu=0.8, fingers=1).step(grip_N=0.5, load_N=0.1)
    assert f.fingers == ["left"] and "right_gamma" not in f.labels
    assert not s._core.images_ready
    img = f.image("left", kind="linear")
    assert s._core.images_ready
    assert img.dtype == np.float32 and img.shape == (128, 128, 3) and img.max() > 0


def test_spec_errors_name_the_place_and_write_nothing(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\nrender:\n  width_px: -3\n")
    with pytest.raises(sim.SpecError, match=r"bad\.yaml:3:13: render\.width_px.*-3.*allowed"):
        sim.Sensor(bad)
    with pytest.raises(ValueError, match=r"<dict>:\d+:\d+: sensor\.mesh_levl"):
        sim.Sensor({"sensor": {"mesh_levl": "coarse"}})
    with pytest.raises(sim.SpecError, match="cannot open|No such file|not found"):
        sim.Sensor(tmp_path / "missing.yaml")
    assert sorted(os.listdir(tmp_path)) == ["bad.yaml"]


def test_a_varied_spec_gives_one_sensor_per_variant(tmp_path):
    spec = {"seed": 5,
            "sensor": {"mesh_level": "very_coarse", "element_order": 1,
                       "material_model": "linear",
                       "materials": {"clear_layer": {"E_MPa": [0.2, 0.4]}}},
            "sampling": {"sensor_variants": 2}, "outputs": {"images": False}}
    with pytest.raises(sim.SpecError, match=r"varies its sensor .*give variant = 0 to 1"):
        sim.Sensor(spec, cache_dir=tmp_path)
    with pytest.raises(IndexError, match=r"variant 2: the spec draws 2 sensors"):
        sim.Sensor(spec, cache_dir=tmp_path, variant=2)
    depth = {}
    for k in (0, 1):
        s = sim.Sensor(spec, cache_dir=tmp_path, variant=k)
        e = float(s.resolved_yaml.split("clear_layer:")[1].split("E_MPa:")[1].split()[0])
        f = s.contact("flat", mu=0.8, fingers=1).step(grip_N=1.0, load_N=0.0)
        depth[e] = f.labels["left_indentation_mm"]
    assert sorted(depth) == [0.2, 0.4]  # seed 5's two sensors draw both moduli
    assert depth[0.2] > depth[0.4]


def test_bad_arguments_raise_clear_python_errors(sensor):
    grasp = sensor.contact(0, mu=0.8)
    with pytest.raises(ValueError, match=r"grip_N = -1\.0: allowed: a finite number > 0"):
        grasp.step(grip_N=-1.0)
    with pytest.raises(ValueError, match=r"grip_N = nan"):
        grasp.step(grip_N=float("nan"))
    with pytest.raises(ValueError, match=r"load_N = -0\.5"):
        grasp.step(grip_N=1.0, load_N=-0.5)
    with pytest.raises(TypeError, match=r"grip_N: expected a number \(N\), got str"):
        grasp.step(grip_N="1 N")
    with pytest.raises(ValueError, match=r"object 'apple': the spec's objects are flat, curved"):
        sensor.contact("apple")
    with pytest.raises(ValueError, match=r"mu = 0\.0"):
        sensor.contact("flat", mu=0.0)
    with pytest.raises(ValueError, match=r"fingers = 3"):
        sensor.contact("flat", fingers=3)
    frame = grasp.step(grip_N=1.0)
    with pytest.raises(ValueError, match=r"finger 'middle': this frame's fingertips are left, right"):
        frame.image("middle")
    with pytest.raises(ValueError, match=r"kind 'hdr': allowed: png"):
        frame.image("left", kind="hdr")
    with pytest.raises(ValueError, match=r"outputs\.strain: true"):
        frame.strain("left")
    assert grasp.steps == 1  # the refused steps did nothing


def test_steps_release_the_gil(sensor):
    grasp = sensor.contact("curved", mu=0.8)
    ticks = []
    stop = threading.Event()

    def tick():
        while not stop.is_set():
            ticks.append(1)
            time.sleep(0.001)

    t = threading.Thread(target=tick)
    t.start()
    try:
        before = len(ticks)
        for k in range(3):
            grasp.step(grip_N=1.0 + 0.1 * k, load_N=0.2)
        during = len(ticks) - before
    finally:
        stop.set()
        t.join()
    assert during > 0


def test_simulated_frames_match_the_dataset_class(datasets):
    torch = pytest.importorskip("torch")
    from chromasim.stream import SimulatedFrames
    from chromasim.torch_data import GammaImages
    stream = SimulatedFrames(QUICKSTART, size=64, max_trials=1)
    items = list(stream)
    ds = GammaImages(datasets["quickstart"], size=64)
    keys = [tuple(k) for k in ds.keys()]
    assert len(items) == sum(1 for k in keys if k[0] == 0)
    for x, gamma, key in items:
        i = keys.index(tuple(key.tolist()))
        x_ds, gamma_ds, _ = ds[i]
        assert x.shape == (3, 128, 64)
        assert torch.equal(x, x_ds)
        assert float(gamma) == pytest.approx(float(gamma_ds), abs=1e-6)
    again = list(SimulatedFrames(QUICKSTART, size=64, max_trials=1))
    assert all(torch.equal(a[0], b[0]) for a, b in zip(items, again))


def test_simulated_frames_split_trials_over_workers():
    torch = pytest.importorskip("torch")
    from chromasim.stream import SimulatedFrames
    import yaml
    sensor = yaml.safe_load(open(QUICKSTART))["sensor"]  # its cached very_coarse mesh
    spec = {"sensor": sensor, "objects": [{"name": "flat", "shape": "flat"}], "protocol": {
        "frame_rate_Hz": 10, "grasp_s": 0.2, "hold_s": 0.1, "load_rate_N_per_s": 4,
        "target_load_N": 0.8}, "sampling": {"method": "random", "trials": 3},
        "friction": [{"name": "f", "mu": {"min": 0.5, "max": 1.0}}],
        "outputs": {"images": True}, "render": {"width_px": 32, "height_px": 32,
                                                "fast": {"paths_per_vertex": 64}}}
    one = list(torch.utils.data.DataLoader(SimulatedFrames(spec, seed=3, size=32),
                                           batch_size=None, num_workers=0))
    two = list(torch.utils.data.DataLoader(SimulatedFrames(spec, seed=3, size=32),
                                           batch_size=None, num_workers=2,
                                           multiprocessing_context="spawn"))
    key = lambda item: tuple(item[2].tolist())  # noqa: E731
    assert sorted(map(key, one)) == sorted(map(key, two))
    by_key = {key(i): i for i in two}
    for x, gamma, k in one:
        assert torch.equal(x, by_key[key((x, gamma, k))][0])
    other = list(SimulatedFrames(spec, seed=4, size=32))
    assert [float(i[1]) for i in other] != [float(i[1]) for i in one]
