"""chromasim.train / predict on the quickstart dataset: real images, real gradient steps."""

import copy
import csv
import os

import numpy as np
import pytest
import torch

from chromasim import predict, train
from chromasim.model import make_model
from chromasim.torch_data import GammaImages


def test_dataset_stacks_both_fingertips(quickstart):
    ds = GammaImages(quickstart, size=224)
    assert len(ds) == quickstart.frames
    x, gamma, i = ds[4]
    assert x.shape == (3, 448, 224) and x.dtype == torch.float32
    assert 0.0 <= float(x.min()) and float(x.max()) <= 1.0 and float(x.std()) > 0.01
    assert float(gamma) == pytest.approx(quickstart.grasp_gamma()[ds.rows[4]])
    # The top half is the left image, the bottom the right one: they differ.
    assert not torch.equal(x[:, :224], x[:, 224:])


def test_unknown_split_is_named(quickstart):
    with pytest.raises(ValueError, match="no split 'nope'"):
        GammaImages(quickstart, ["nope"])


def test_two_training_steps_change_the_weights(quickstart, tmp_path):
    args = train.parser().parse_args([
        quickstart.root, "-o", str(tmp_path), "--epochs", "1", "--batch-size", "4",
        "--width", "0.5", "--max-steps", "2", "--size", "96", "-q", "--seed", "3"])
    torch.manual_seed(3)
    initial = copy.deepcopy(make_model("0.5").state_dict())
    model, history = train.train(args)
    assert history[0]["step"] == 2 and np.isfinite(history[0]["train_loss"])
    changed = [k for k, v in model.state_dict().items()
               if v.dtype.is_floating_point and not torch.equal(v, initial[k])]
    conv_weights = [k for k in initial if k.endswith("weight") and initial[k].dim() == 4]
    assert set(conv_weights) <= set(changed)  # every convolution moved
    assert os.path.exists(tmp_path / "checkpoint_last.pt")
    rows = list(csv.DictReader(open(tmp_path / "history.csv")))
    assert rows[0]["step"] == "2"

    out = tmp_path / "pred.csv"
    assert predict.main([str(tmp_path / "checkpoint_last.pt"), quickstart.root,
                         "-o", str(out)]) == 0
    pred = list(csv.DictReader(open(out)))
    assert len(pred) == quickstart.frames
    assert all(0.0 <= float(r["gamma_pred"]) <= 1.0 for r in pred)


def test_resume_continues_the_run(quickstart, tmp_path):
    common = [quickstart.root, "-o", str(tmp_path), "--batch-size", "4", "--width", "0.5",
              "--size", "64", "-q", "--no-augment"]
    train.train(train.parser().parse_args(common + ["--epochs", "1"]))
    _, history = train.train(train.parser().parse_args(common + ["--epochs", "2", "--resume"]))
    assert [h["epoch"] for h in history] == [1, 2]
    assert history[1]["step"] == 2 * history[0]["step"]
