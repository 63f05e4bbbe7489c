"""chromasim.evaluate: numbers checked against a case computed by hand, and its errors."""

import json

import numpy as np
import pytest

from chromasim import evaluate
from chromasim.data import Dataset


def hand_dataset():
    # Four frames of one fingertip: objects flat/curved x frictions high/low.
    labels = {
        "split": np.array(["v"] * 4, dtype=object),
        "trial": np.array([0.0, 0, 1, 1]), "frame": np.array([0.0, 1, 0, 1]),
        "object": np.array(["flat", "flat", "curved", "curved"], dtype=object),
        "friction": np.array(["high", "low", "high", "low"], dtype=object),
        "left_frictional_strength_N": np.ones(4),
        "left_gamma": np.array([1.0, 0.5, 0.25, 0.0]),
        "left_mu": np.array([1.1, 0.3, 1.1, 0.3]),
    }
    return Dataset(root="/hand", manifest={"fingers": 1}, labels=labels)


def test_hand_computed_case():
    d = hand_dataset()
    pred = {"trial": np.array([1.0, 0, 0, 1]), "frame": np.array([1.0, 0, 1, 0]),
            "gamma_pred": np.array([0.2, 0.9, 0.5, 0.45])}
    rows, est = evaluate.match_predictions(d, pred, "p.csv")
    np.testing.assert_array_equal(rows, [0, 1, 2, 3])
    np.testing.assert_allclose(est, [0.9, 0.5, 0.45, 0.2])
    r = evaluate.evaluate(d, rows, est, seen_mu=(0.5, 1.2))
    # errors: -0.1, 0, 0.2, 0.2 -> MSE (0.01 + 0 + 0.04 + 0.04) / 4 = 0.0225
    assert r["overall"]["mse"] == pytest.approx(0.0225)
    assert r["overall"]["accuracy"] == pytest.approx(0.9775)
    assert r["overall"]["mae"] == pytest.approx(0.125)
    # seen: mu 1.1 frames (0 and 2): (0.01 + 0.04) / 2; unseen: frames 1 and 3: 0.04 / 2
    assert r["seen"]["mse"] == pytest.approx(0.025)
    assert r["unseen"]["mse"] == pytest.approx(0.02)
    t = r["mse_table"]
    assert t[0] == ["object", "high", "low", "all"]
    assert t[1][0] == "flat" and t[1][1] == pytest.approx(0.01) and t[1][2] == pytest.approx(0.0)
    assert t[2][0] == "curved" and t[2][1] == pytest.approx(0.04) and t[2][2] == pytest.approx(0.04)
    assert t[3][3] == pytest.approx(0.0225)
    m = np.array(r["confusion"])
    # truth bins 9 (1.0 lands in the last bin), 5, 2, 0; estimate bins 9, 5, 4, 2
    assert m.sum() == 4 and m[9, 9] == 1 and m[5, 5] == 1 and m[2, 4] == 1 and m[0, 2] == 1


@pytest.mark.parametrize("pred,message", [
    ({"trial": [0], "frame": [0]}, "no column 'gamma_pred'"),
    ({"trial": [0, 0], "frame": [0, 0], "gamma_pred": [0.1, 0.2]}, "predicted twice"),
    ({"trial": [7], "frame": [0], "gamma_pred": [0.1]}, "trial 7 frame 0 is not a frame"),
    ({"trial": [0], "frame": [0], "gamma_pred": [float("nan")]}, "p.csv:2: gamma_pred"),
    ({"trial": [0], "frame": [0], "gamma_pred": [0.5]}, "3 of 4 frames have no prediction"),
])
def test_bad_predictions_are_named(pred, message):
    pred = {k: np.array(v, dtype=float) for k, v in pred.items()}
    with pytest.raises(evaluate.PredictionError, match=message):
        evaluate.match_predictions(hand_dataset(), pred, "p.csv")


def test_report_on_quickstart(quickstart, tmp_path, capsys):
    truth = quickstart.grasp_gamma()
    keys = quickstart.frame_keys()
    path = tmp_path / "pred.csv"
    with open(path, "w") as f:
        f.write("trial,frame,gamma_pred\n")
        for (t, fr), g in zip(keys, truth):
            f.write(f"{t},{fr},{min(1.0, g + 0.1):.6f}\n")
    out = tmp_path / "report"
    assert evaluate.main([str(path), quickstart.root, "-o", str(out),
                          "--seen-mu", "0.0", "0.7"]) == 0
    s = json.load(open(out / "summary.json"))
    expected = np.mean((np.minimum(1.0, truth + 0.1) - truth) ** 2)
    assert s["overall"]["mse"] == pytest.approx(expected, rel=1e-5)
    for name in ("confusion.png", "confusion.svg", "error_vs_gamma.png", "error_vs_mu.png",
                 "mse_table.csv", "per_frame.csv", "confusion.csv"):
        assert (out / name).stat().st_size > 0
    assert "accuracy (1 - MSE)" in capsys.readouterr().out


def test_cli_errors(quickstart, tmp_path, capsys):
    assert evaluate.main([str(tmp_path / "none.csv"), quickstart.root, "-o", str(tmp_path)]) == 2
    assert "none.csv: no such file" in capsys.readouterr().err
    bad = tmp_path / "bad.csv"
    bad.write_text("trial,frame,gamma_pred\n0,zero,0.5\n")
    assert evaluate.main([str(bad), quickstart.root, "-o", str(tmp_path)]) == 2
    assert "bad.csv:2: frame 'zero' is not a number" in capsys.readouterr().err
