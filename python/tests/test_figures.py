"""chromasim.figures: every figure a dataset supports is written; selections and the
benchmark-table reader against hand-checked values."""

import json
import os

import matplotlib.image as mpimg
import numpy as np
import pytest

from chromasim import figures as F

DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data")
# The tables of `chromasim bench render|mechanics --json FILE`
BENCH_RENDER = os.path.join(DATA, "bench_render.json")
BENCH_MECHANICS = os.path.join(DATA, "bench_mechanics.json")


def _check_figure(out, stem):
    for ext in ("png", "svg"):
        path = os.path.join(out, f"{stem}.{ext}")
        assert os.path.isfile(path) and os.path.getsize(path) > 1000, path
    with open(os.path.join(out, f"{stem}.svg")) as f:
        assert "<svg" in f.read(4000)
    img = mpimg.imread(os.path.join(out, f"{stem}.png"))
    assert img.ndim == 3 and min(img.shape[:2]) > 100
    assert img[..., :3].std() > 0.01  # something is drawn


@pytest.fixture(scope="module")
def quickstart_figures(quickstart, tmp_path_factory):
    out = str(tmp_path_factory.mktemp("fig_qs"))
    assert F.main([quickstart.root, "-o", out, "--bench", BENCH_RENDER, BENCH_MECHANICS]) == 0
    return out


def test_quickstart_every_figure(quickstart, quickstart_figures):
    # trial 0 slides (default trial); Gamma 0.5 at frame 5 for both fingertips
    stems = ["force_gamma_trial0", "safety_margin_by_friction", "stickslip_map",
             "stickslip_trial0", "images_trial0", "bench_render", "bench_mechanics"]
    for finger in ("left", "right"):
        stems += [f"markers_{finger}_trial0_frame5", f"markers_quiver_{finger}_trial0_frame5",
                  f"slip_profile_{finger}"]
    for stem in stems:
        _check_figure(quickstart_figures, stem)
    assert len(os.listdir(quickstart_figures)) == 2 * len(stems)


def test_sliding_skips_images_with_a_reason(sliding, tmp_path, capsys):
    assert F.main([sliding.root, "-o", str(tmp_path), "--finger", "left"]) == 0
    printed = capsys.readouterr().out
    assert "skipped images: no images in this dataset" in printed
    for stem in ("force_gamma_trial0", "safety_margin_by_friction", "stickslip_map",
                 "slip_profile_left"):
        _check_figure(str(tmp_path), stem)
    assert not any(n.startswith("images_") for n in os.listdir(tmp_path))


def test_selections(quickstart, sliding):
    assert F.default_trial(quickstart) == 0
    assert F.default_frame(quickstart, 0, "left") == 5  # Gamma 0.50, not sliding
    assert F.slip_direction(quickstart, 0, "left") == pytest.approx(0.0)
    assert abs(F.slip_direction(quickstart, 0, "right")) == pytest.approx(np.pi)
    # slide set: 7 friction conditions; extremes are the trials of mu 1.1 and 0.5 (jittered)
    hi, lo = F.friction_extremes(sliding, "left")
    mu = {t: sliding.labels["left_mu"][sliding.labels["trial"] == t][0] for t in (hi, lo)}
    assert mu[hi] > 1.05 and mu[lo] < 0.55
    assert F.friction_extremes(quickstart, "left") == [0]  # one mu: one trial
    # load frames 4 to 6, the first slip frame 7; the second slip frame is left out
    np.testing.assert_array_equal(F.loaded_frames(quickstart, 0, "left"), [4, 5, 6, 7])
    slide = F.loaded_frames(sliding, hi, "left")  # mu 1.1: slides from the fourth frame
    assert slide[0] == 0 and sliding.labels["left_sliding"][
        (sliding.labels["trial"] == hi) & (sliding.labels["frame"] == slide[-1])] == 1
    assert len(slide) == 4


def test_meridian_along_the_slip(quickstart):
    m = F.read_markers(quickstart, [0])
    assert set(np.unique(m["trial"])) == {0.0}  # streamed: trial 1 not read
    mask = F._select(m, trial=0, frame=0, finger="left", layer="outer")
    assert mask.sum() == 82
    np.testing.assert_array_equal(np.bincount(F.marker_ring(m, mask)), [1, 6, 12, 17, 21, 25])
    idx = F.meridian(m, mask, 0.0)
    assert len(idx) == 11  # apex + 5 rings x 2 sides
    s = m["x0_mm"][idx]
    assert np.all(np.diff(s) > 0)
    # ring k has n_k markers: the nearest is within half a spacing of the x axis
    assert np.all(np.abs(np.arctan2(m["y0_mm"][idx], np.abs(m["x0_mm"][idx]))) <= np.pi / 17 + 1e-9)


def test_stick_matrix(quickstart):
    trials, xs, S, L, label, mu = F.stick_matrix(quickstart, "left")
    assert label == "time (s)" and S.shape == (2, 9)
    np.testing.assert_allclose(xs, np.arange(1, 10) / 10)
    # trial 0: stick ratio 0 and sliding in its last two frames (slip phase)
    row = list(trials).index(0)
    np.testing.assert_array_equal(L[row, -2:], [1, 1])
    np.testing.assert_array_equal(S[row, -2:], [0, 0])


def test_bench_tables_by_header():
    (t,) = F.read_bench_json(BENCH_RENDER)
    assert t.caption.startswith("render 32 x 32, coarse dome at 1.5 N + 0.6 N pull")
    jt, je, series, point = F.bench_columns(t)
    assert t.header[jt] == "render ms" and t.header[je] == "RMS error %"
    assert [t.header[j] for j in series] == ["integrator", "mode"] and t.header[point] == "spp"
    times, errors = t.column(jt), t.column(je)
    assert times[0] == 5.0 and errors[0] == pytest.approx(22.346)
    # the fast integrator's "light cache" rows are not measurements: NaN, not drawn
    cache = [i for i, r in enumerate(t.rows) if r[2] == "light cache"]
    assert len(cache) == 2 and np.isnan(errors[cache]).all()
    assert np.isfinite(times).sum() == len(t.rows) - 2

    (m,) = F.read_bench_json(BENCH_MECHANICS)
    jt, je, series, point = F.bench_columns(m)
    assert m.header[jt] == "trial frame ms"
    assert m.header[je] == "vs ref" and m.header[je - 1] == "indentation mm"
    assert m.header[point] == "level" and series == []
    assert m.column(je)[-1] == 0.0  # the reference level


def _write_json(path, doc):
    path.write_text(json.dumps(doc))
    return str(path)


def test_bench_json_by_hand(tmp_path):
    doc = {"command": "bench render", "chromasim_version": "0.0.0",
           "tables": [{"caption": "caption line", "header": ["a", "render ms", "RMS error %"],
                       "rows": [["x", "1.5", "2 %"], ["y", "n/a", 3], ["z", "", None]]}]}
    (t,) = F.read_bench_json(_write_json(tmp_path / "b.json", doc))
    assert t.caption == "caption line" and t.header == ["a", "render ms", "RMS error %"]
    np.testing.assert_array_equal(t.column(1), [1.5, np.nan, np.nan])
    np.testing.assert_array_equal(t.column(2), [2.0, 3.0, np.nan])
    assert F.bench_columns(F.BenchTable("", ["level", "nodes"], [])) is None
    # not JSON (a saved Markdown stdout) and not the bench's shape: named, with what is allowed
    md = tmp_path / "b.md"
    md.write_text("| a | render ms |\n|---|---|\n| x | 1 |\n")
    for path in (str(md), _write_json(tmp_path / "c.json", {"tables": [{"header": "a"}]}),
                 _write_json(tmp_path / "d.json", [1, 2])):
        with pytest.raises(F.DatasetError, match="allowed: a file written by") as e:
            F.read_bench_json(path)
        assert path in str(e.value)


def test_cli_errors(quickstart, tmp_path):
    with pytest.raises(SystemExit) as e:
        F.main([str(tmp_path / "nowhere"), "-o", str(tmp_path / "o")])
    assert "nowhere" in str(e.value) and "not a folder" in str(e.value)
    with pytest.raises(SystemExit) as e:
        F.main([quickstart.root, "-o", str(tmp_path / "o"), "--trial", "99"])
    assert "no trial 99" in str(e.value)
    with pytest.raises(SystemExit) as e:
        F.main(["-o", str(tmp_path / "o"), "--bench", str(tmp_path / "missing.json")])
    assert "missing.json" in str(e.value)
    with pytest.raises(SystemExit):
        F.main(["-o", str(tmp_path / "o")])
