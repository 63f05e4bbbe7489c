"""Run a trained checkpoint (chromasim.train) over a dataset and write a predictions CSV.

  python3 -m chromasim.predict CHECKPOINT DATASET -o predictions.csv [--splits ...]

The CSV has one row per frame: `trial`, `frame`, `gamma_pred` (clamped to [0, 1], the range
of Gamma), the format chromasim.evaluate reads from any estimator.
"""

from __future__ import annotations

import argparse
import csv
import os
import sys
import time

import torch

from .data import DatasetError
from .model import make_model
from .torch_data import GammaImages


@torch.no_grad()
def predict(checkpoint: str, dataset: str, splits=None, batch_size: int = 64,
            device: str = "cpu", keep_flagged: bool = False):
    ck = torch.load(checkpoint, map_location=device)
    model = make_model(ck["width"]).to(device)
    model.load_state_dict(ck["model"])
    model.eval()
    data = GammaImages(dataset, splits, size=ck["size"], target=ck["target"],
                       keep_flagged=keep_flagged)
    loader = torch.utils.data.DataLoader(data, batch_size=batch_size, shuffle=False)
    preds = []
    t0 = time.perf_counter()
    for x, _, _ in loader:
        preds.append(model(x.to(device)).clamp(0.0, 1.0).cpu())
    seconds = time.perf_counter() - t0
    return data.keys(), torch.cat(preds).numpy(), seconds


def write_predictions(path: str, keys, preds) -> None:
    tmp = path + ".tmp"
    with open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["trial", "frame", "gamma_pred"])
        for (trial, frame), g in zip(keys, preds):
            w.writerow([int(trial), int(frame), f"{float(g):.6f}"])
    os.replace(tmp, path)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python3 -m chromasim.predict", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("checkpoint")
    p.add_argument("dataset")
    p.add_argument("-o", "--out", required=True, help="predictions CSV")
    p.add_argument("--splits", nargs="+")
    p.add_argument("--batch-size", type=int, default=64)
    p.add_argument("--device", default="cuda" if torch.cuda.is_available() else "cpu")
    p.add_argument("--keep-flagged", action="store_true",
                   help="also frames whose solve did not converge")
    args = p.parse_args(argv)
    if not os.path.isfile(args.checkpoint):
        print(f"predict: {args.checkpoint}: no such file", file=sys.stderr)
        return 2
    try:
        keys, preds, seconds = predict(args.checkpoint, args.dataset, args.splits,
                                       args.batch_size, args.device, args.keep_flagged)
    except DatasetError as e:
        print(f"predict: {e}", file=sys.stderr)
        return 2
    write_predictions(args.out, keys, preds)
    print(f"predict: {len(preds)} frames in {seconds:.1f} s "
          f"({len(preds) / max(seconds, 1e-9):.1f} frames/s, {args.device}, batch {args.batch_size})"
          f" -> {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
