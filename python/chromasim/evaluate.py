"""Stress-test any safety-margin estimator against a chromasim dataset.

  python3 -m chromasim.evaluate PREDICTIONS.csv DATASET -o OUT_DIR
        [--seen-mu LO HI | --train-dataset TRAIN_DIR] [--target grasp|left|right]

PREDICTIONS.csv: a header row and one row per frame with columns `trial`, `frame` (the
frame's key in the dataset's labels.csv) and `gamma_pred` (the estimate; other columns are
ignored). Every prediction must name a frame of the dataset, once; frames without a
prediction are an error unless `--allow-missing` (then they are left out and counted).
The truth is the grasp's Gamma (chromasim.data.Dataset.grasp_gamma) or one fingertip's.

OUT_DIR gets:
  summary.json         overall and per-group (seen / unseen friction) numbers
  mse_table.csv        MSE per object x friction, seed 000's Table I layout, plus `all`
  confusion.csv/.png   counts of (true, estimated) Gamma in 10 % bins (estimates clamped to
                       [0, 1] for binning; 1.0 falls in the last bin)
  error_vs_gamma.png, error_vs_mu.png (and .svg): signed error, binned mean and std
  per_frame.csv        trial, frame, object, friction, mu, gamma, gamma_pred, error, seen
"accuracy" is seed 000's: 1 - MSE. A frame is "seen" when its mu (the mean over the
fingertips) lies within the training set's mu range (from --train-dataset, or --seen-mu),
widened by 1e-9; without either, every frame counts as seen.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import sys

import numpy as np

from .data import Dataset, DatasetError, open_dataset, read_csv

BINS = 10


class PredictionError(ValueError):
    pass


def match_predictions(d: Dataset, pred: dict[str, np.ndarray], path: str,
                      allow_missing: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Rows of the dataset that have a prediction, and the predictions in that order."""
    for column in ("trial", "frame", "gamma_pred"):
        if column not in pred:
            raise PredictionError(f"{path}: no column '{column}' (need trial, frame, gamma_pred)")
    for column in ("trial", "frame", "gamma_pred"):
        values = pred[column]
        if values.dtype == object:
            bad = next(i for i, v in enumerate(values) if not _is_number(v))
            raise PredictionError(f"{path}:{bad + 2}: {column} '{values[bad]}' is not a number")
    gamma = pred["gamma_pred"]
    if not np.isfinite(gamma).all():
        bad = int(np.flatnonzero(~np.isfinite(gamma))[0])
        raise PredictionError(f"{path}:{bad + 2}: gamma_pred is not a finite number")
    index = {(int(t), int(f)): i for i, (t, f) in enumerate(d.frame_keys())}
    rows = np.empty(len(gamma), dtype=np.int64)
    seen = set()
    for i, (t, f) in enumerate(zip(pred["trial"], pred["frame"])):
        key = (int(t), int(f))
        if key not in index:
            raise PredictionError(f"{path}:{i + 2}: trial {key[0]} frame {key[1]} is not a frame"
                                  f" of {d.root}")
        if key in seen:
            raise PredictionError(f"{path}:{i + 2}: trial {key[0]} frame {key[1]} predicted twice")
        seen.add(key)
        rows[i] = index[key]
    missing = d.frames - len(seen)
    if missing and not allow_missing:
        first = next(k for k in index if k not in seen)
        raise PredictionError(f"{path}: {missing} of {d.frames} frames have no prediction (first:"
                              f" trial {first[0]} frame {first[1]}); --allow-missing evaluates"
                              " the others")
    order = np.argsort(rows)
    return rows[order], gamma[order]


def _is_number(v) -> bool:
    try:
        float(v)
        return True
    except (TypeError, ValueError):
        return False


def confusion(truth: np.ndarray, estimate: np.ndarray, bins: int = BINS) -> np.ndarray:
    """counts[i, j]: frames with true Gamma in bin i and estimate in bin j (10 % bins)."""
    def b(x):
        return np.clip((np.clip(x, 0.0, 1.0) * bins).astype(np.int64), 0, bins - 1)
    m = np.zeros((bins, bins), dtype=np.int64)
    np.add.at(m, (b(truth), b(estimate)), 1)
    return m


def summarize(truth, estimate) -> dict:
    e = estimate - truth
    mse = float(np.mean(e ** 2)) if len(e) else float("nan")
    return {"frames": int(len(e)), "mse": mse, "accuracy": 1.0 - mse,
            "rmse": float(np.sqrt(mse)), "mae": float(np.mean(np.abs(e))) if len(e) else float("nan"),
            "bias": float(np.mean(e)) if len(e) else float("nan")}


def mse_table(objects, frictions, truth, estimate) -> list[list]:
    """Rows per object (then `all`), columns per friction (then `all`), MSE (empty: no frame)."""
    obj_names = list(dict.fromkeys(objects))
    fr_names = list(dict.fromkeys(frictions))
    table = [["object"] + fr_names + ["all"]]
    for o in obj_names + ["all"]:
        row = [o]
        for f in fr_names + ["all"]:
            sel = np.ones(len(truth), dtype=bool)
            if o != "all":
                sel &= objects == o
            if f != "all":
                sel &= frictions == f
            row.append(float(np.mean((estimate[sel] - truth[sel]) ** 2)) if sel.any() else "")
        table.append(row)
    return table


def evaluate(d: Dataset, rows: np.ndarray, estimate: np.ndarray, target: str = "grasp",
             seen_mu: tuple[float, float] | None = None) -> dict:
    """Every number of the report, as plain data (the writer and the tests share it)."""
    truth_all = d.grasp_gamma() if target == "grasp" else d.labels[f"{target}_gamma"]
    truth = truth_all[rows]
    mu = d.frame_mu()[rows]
    objects = d.labels["object"][rows]
    frictions = d.labels["friction"][rows]
    if seen_mu is None:
        seen = np.ones(len(rows), dtype=bool)
    else:
        seen = (mu >= seen_mu[0] - 1e-9) & (mu <= seen_mu[1] + 1e-9)
    result = {"target": target, "seen_mu": list(seen_mu) if seen_mu else None,
              "frames_in_dataset": d.frames, "frames_evaluated": int(len(rows)),
              "overall": summarize(truth, estimate),
              "seen": summarize(truth[seen], estimate[seen]),
              "unseen": summarize(truth[~seen], estimate[~seen]),
              "mse_table": mse_table(objects, frictions, truth, estimate),
              "confusion": confusion(truth, estimate).tolist(),
              "confusion_seen": confusion(truth[seen], estimate[seen]).tolist(),
              "confusion_unseen": confusion(truth[~seen], estimate[~seen]).tolist()}
    result["_per_frame"] = {"truth": truth, "estimate": estimate, "mu": mu, "objects": objects,
                            "frictions": frictions, "seen": seen}
    return result


def seen_range_of(train_dir: str) -> tuple[float, float]:
    t = open_dataset(train_dir)
    mu = t.frame_mu()
    return float(mu.min()), float(mu.max())


def _write_csv(path: str, rows: list[list]) -> None:
    with open(path, "w", newline="") as f:
        csv.writer(f).writerows(rows)


def _binned(x, err, edges):
    centres, mean, std, count = [], [], [], []
    for lo, hi in zip(edges[:-1], edges[1:]):
        sel = (x >= lo) & ((x < hi) | ((hi == edges[-1]) & (x <= hi)))
        if sel.any():
            centres.append(0.5 * (lo + hi))
            mean.append(err[sel].mean())
            std.append(err[sel].std())
            count.append(int(sel.sum()))
    return np.array(centres), np.array(mean), np.array(std), count


def write_report(result: dict, d: Dataset, rows: np.ndarray, out: str) -> list[str]:
    from .plots import plt, save

    os.makedirs(out, exist_ok=True)
    pf = result["_per_frame"]
    written = []

    def path(name):
        written.append(os.path.join(out, name))
        return written[-1]

    summary = {k: v for k, v in result.items() if not k.startswith("_")}
    summary["dataset"] = d.root
    with open(path("summary.json"), "w") as f:
        json.dump(summary, f, indent=2)
    _write_csv(path("mse_table.csv"), result["mse_table"])
    for name, key in (("confusion", "confusion"), ("confusion_seen", "confusion_seen"),
                      ("confusion_unseen", "confusion_unseen")):
        m = result[key]
        header = ["true \\ estimated"] + [f"{10 * j}-{10 * (j + 1)}%" for j in range(BINS)]
        _write_csv(path(f"{name}.csv"),
                   [header] + [[f"{10 * i}-{10 * (i + 1)}%"] + m[i] for i in range(BINS)])
    keys = d.frame_keys()[rows]
    per = [["trial", "frame", "object", "friction", "mu", "gamma", "gamma_pred", "error", "seen"]]
    for k, (t, f) in enumerate(keys):
        per.append([int(t), int(f), pf["objects"][k], pf["frictions"][k], f"{pf['mu'][k]:.6g}",
                    f"{pf['truth'][k]:.6g}", f"{pf['estimate'][k]:.6g}",
                    f"{pf['estimate'][k] - pf['truth'][k]:.6g}", int(pf["seen"][k])])
    _write_csv(path("per_frame.csv"), per)

    groups = [("all", np.ones(len(rows), dtype=bool))]
    if result["seen_mu"] is not None:
        groups += [("seen", pf["seen"]), ("unseen", ~pf["seen"])]

    # Confusion matrices, row-normalised, one panel per group.
    fig, axes = plt.subplots(1, len(groups), figsize=(4.6 * len(groups), 4.2), squeeze=False)
    for ax, (name, sel) in zip(axes[0], groups):
        m = confusion(pf["truth"][sel], pf["estimate"][sel]).astype(float)
        norm = m / np.maximum(m.sum(axis=1, keepdims=True), 1)
        im = ax.imshow(norm, origin="lower", extent=(0, 100, 0, 100), vmin=0, vmax=1,
                       cmap="viridis")
        ax.set_xlabel("estimated Gamma (%)")
        ax.set_ylabel("true Gamma (%)")
        ax.set_title(f"{name} ({int(sel.sum())} frames)")
        fig.colorbar(im, ax=ax, label="share of the true bin")
    fig.tight_layout()
    written += save(fig, out, "confusion")

    err = pf["estimate"] - pf["truth"]
    for xname, x, edges, xlabel in (
            ("gamma", pf["truth"], np.linspace(0, 1, BINS + 1), "true Gamma"),
            ("mu", pf["mu"], np.unique(np.round(np.linspace(pf["mu"].min(), pf["mu"].max() + 1e-9,
                                                            11), 9)), "friction coefficient mu")):
        fig, ax = plt.subplots(figsize=(6, 4))
        for name, sel in groups:
            if not sel.any():
                continue
            ax.scatter(x[sel], err[sel], s=3, alpha=0.25, label=f"{name} frames")
            if len(edges) > 1:
                c, mean, std, _ = _binned(x[sel], err[sel], edges)
                ax.errorbar(c, mean, yerr=std, marker="o", capsize=3, label=f"{name}: mean +- std")
        ax.axhline(0, color="k", lw=0.8)
        ax.set_xlabel(xlabel)
        ax.set_ylabel("estimate - truth (Gamma)")
        ax.set_title(f"Gamma error against {xname}")
        ax.legend(fontsize=8)
        fig.tight_layout()
        written += save(fig, out, f"error_vs_{xname}")
    return written


def format_summary(result: dict) -> str:
    lines = []
    t = result["mse_table"]
    lines.append("MSE per object x friction:")
    lines.append("| " + " | ".join(str(c) for c in t[0]) + " |")
    lines.append("|" + "---|" * len(t[0]))
    for row in t[1:]:
        lines.append("| " + " | ".join(row[:1] + [f"{v:.5f}" if v != "" else "" for v in row[1:]])
                     + " |")
    for group in ("overall", "seen", "unseen"):
        s = result[group]
        if s["frames"]:
            lines.append(f"{group}: {s['frames']} frames, MSE {s['mse']:.5f}, accuracy (1 - MSE) "
                         f"{100 * s['accuracy']:.2f} %, RMSE {s['rmse']:.4f}, MAE {s['mae']:.4f},"
                         f" bias {s['bias']:+.4f}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python3 -m chromasim.evaluate", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("predictions", help="CSV with trial, frame, gamma_pred")
    p.add_argument("dataset", help="dataset folder (chromasim generate)")
    p.add_argument("-o", "--out", required=True, help="report folder")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--seen-mu", nargs=2, type=float, metavar=("LO", "HI"),
                   help="mu range the estimator was trained on")
    g.add_argument("--train-dataset", help="take the seen mu range from this dataset")
    p.add_argument("--target", default="grasp", help="grasp (default), left or right")
    p.add_argument("--allow-missing", action="store_true",
                   help="evaluate the predicted frames when some have none")
    args = p.parse_args(argv)
    try:
        d = open_dataset(args.dataset)
        if args.target not in ("grasp",) + d.fingers:
            raise PredictionError(f"--target {args.target}: allowed grasp, {', '.join(d.fingers)}")
        if not os.path.isfile(args.predictions):
            raise PredictionError(f"{args.predictions}: no such file")
        pred = read_csv(args.predictions)
        rows, estimate = match_predictions(d, pred, args.predictions, args.allow_missing)
        if args.seen_mu and args.seen_mu[0] > args.seen_mu[1]:
            raise PredictionError(f"--seen-mu {args.seen_mu[0]} {args.seen_mu[1]}: LO > HI")
        seen = tuple(args.seen_mu) if args.seen_mu else (
            seen_range_of(args.train_dataset) if args.train_dataset else None)
    except (DatasetError, PredictionError) as e:
        print(f"evaluate: {e}", file=sys.stderr)
        return 2
    result = evaluate(d, rows, estimate, args.target, seen)
    write_report(result, d, rows, args.out)
    print(format_summary(result))
    print(f"evaluate: report in {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
