"""chromasim.data against a generated dataset and hand-made cases."""

import numpy as np
import pytest

from chromasim.data import Dataset, DatasetError, open_dataset


def test_quickstart_labels_and_checksums(quickstart):
    d = quickstart
    assert d.fingers == ("left", "right")
    assert d.frames == d.manifest["counts"]["label_rows"]
    assert d.verify() == []
    keys = d.frame_keys()
    assert len({tuple(k) for k in keys}) == d.frames  # (trial, frame) is unique


def test_grasp_gamma_by_hand():
    labels = {
        "trial": np.zeros(3), "frame": np.arange(3.0),
        "left_frictional_strength_N": np.array([1.0, 1.0, 0.0]),
        "right_frictional_strength_N": np.array([3.0, 1.0, 0.0]),
        "left_gamma": np.array([0.5, 0.0, 1.0]),
        "right_gamma": np.array([5.0 / 6.0, 0.0, 1.0]),
    }
    d = Dataset(root="/x", manifest={"fingers": 2}, labels=labels)
    # f_t = 0.5 and 0.5 of strengths 1 and 3: (4 - 1) / 4; both sliding: 0; no strength: 0
    np.testing.assert_allclose(d.grasp_gamma(), [0.75, 0.0, 0.0])


def test_grasp_gamma_one_finger_equals_its_gamma(sliding):
    np.testing.assert_allclose(sliding.grasp_gamma(), sliding.labels["left_gamma"], atol=1e-6)


def test_strain_stack_matches_grid(sliding):
    fields, keys = sliding.strain()
    grid = sliding.strain_grid()
    assert fields.shape == (sliding.frames, grid["nx"] * grid["ny"])
    assert np.isfinite(fields).all() and np.abs(fields).max() > 0
    np.testing.assert_array_equal(keys, sliding.frame_keys())


def test_errors_name_the_path(tmp_path):
    with pytest.raises(DatasetError, match="manifest.json: no such file"):
        open_dataset(str(tmp_path))
    (tmp_path / "manifest.json").write_text("{ nope")
    with pytest.raises(DatasetError, match=r"manifest.json:1:3"):
        open_dataset(str(tmp_path))


def test_package_version_is_the_project_version():
    import pathlib
    import re

    import chromasim

    cmake = pathlib.Path(__file__).resolve().parents[2] / "CMakeLists.txt"
    version = re.search(r"project\(chromasim VERSION (\S+)", cmake.read_text()).group(1)
    assert chromasim.__version__ == version


def test_frame_sensor_names_each_rows_sensor(datasets, quickstart):
    d = open_dataset(datasets["tiny_participants"])
    sensor = d.frame_sensor()
    assert sensor.shape == (d.frames,)
    # Crossed: every friction condition on every sensor, twice; one sensor per trial.
    trials = d.labels["trial"].astype(int)
    assert set(sensor) == {0, 1, 2}
    for t in set(trials):
        assert len(set(sensor[trials == t])) == 1
    by_sensor = {s: sorted(set(d.labels["friction"][sensor == s])) for s in (0, 1, 2)}
    assert all(v == ["mu050", "mu100"] for v in by_sensor.values())
    assert (quickstart.frame_sensor() == -1).all()  # nothing varies
