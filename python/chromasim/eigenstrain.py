"""Eigenstrains (seed 001, Willemet, Huloux & Wiertlewski 2022; ../shared/SENSOR.md section 4).

The strain fields eps_xx of a dataset (one row per fingertip frame, the ny x nx grid
flattened) are stacked into the data matrix X (frames x grid points). Its SVD,
X = V S U^T, gives the Eigenstrains u_i(x) (rows of U^T, images on the strain grid), their
singular values sigma_i and the temporal vectors v_i(t); the recruitment of basis i in a
frame is sigma_i v_i(t) = <eps(t), u_i>. As in the paper, X is not centred: eq. 2 rebuilds
eps from sum_i u_i sigma_i v_i(t) alone.

Support-vector classifiers (scikit-learn SVC, RBF kernel, features standardised) predict
the class of the safety margin Gamma of each frame from the first r recruitments:
2 classes (Gamma below 0.5, Gamma at or above 0.5) and k = 3..10 classes (k equal bins of
Gamma over [0, 1], the paper's "quantization of the safety margin"). Three schemes: stratified
k-fold ("10-fold" in the paper), leave-one-friction-out (each friction condition held out in
turn: the factor the classifier must be invariant to) and leave-one-sensor-out (each sensor of
a dataset that varies its sensor, sensors.csv, held out in turn: the paper's cross-subject
test on datasets_spec/seed001_participants.yaml).

Usage:
  python3 -m chromasim.eigenstrain DATASET -o OUTDIR [--bases 10] [--classes 2-10]
                                   [--folds 10] [--seed 0] ...
Outputs (OUTDIR): singular_values.csv, accuracy.csv, timing.csv, recruitments.csv,
bases.npz, and the figures fig4a_bases, fig4a_recruitments, fig4b_accuracy_vs_bases,
fig4c_time_ratio, fig4d_accuracy_vs_classes, accuracy_vs_bases_by_classes,
singular_values (PNG and SVG). docs/PYTHON.md describes them.

This module is the command line and the package's eigenstrain API; the work lives beside
it: eigenstrain_data (the strain rows and their labels), eigenstrain_analysis (SVD,
classes, classifiers, timing) and eigenstrain_plots (the figures).
"""

from __future__ import annotations

import argparse
import csv
import os
import sys
import time

import numpy as np

from .data import DatasetError, open_dataset
# The API of chromasim.eigenstrain, re-exported from the modules that implement it
from .eigenstrain_analysis import (SCHEME_NAMES, SCHEMES, Eigenstrains,  # noqa: F401
                                   confusion, cross_validate, eigenstrains, gamma_classes,
                                   make_classifier, splits, time_classification)
from .eigenstrain_data import StrainSet, grid_axes_mm, load_strain_set  # noqa: F401
from .eigenstrain_plots import (figure_accuracy_by_classes,  # noqa: F401
                                figure_accuracy_vs_bases, figure_accuracy_vs_classes,
                                figure_bases, figure_recruitments, figure_singular_values,
                                figure_time_ratio)

ACCURACY_COLUMNS = ["scheme", "classes", "r", "folds", "accuracy_mean", "accuracy_std",
                    "balanced_accuracy_mean", "balanced_accuracy_std", "chance", "frames",
                    "classes_present", "bases_from"]
TIMING_COLUMNS = ["r", "test_frames", "train_frames", "fit_s", "predict_s_per_frame",
                  "project_predict_s_per_frame", "full_over_r_predict",
                  "full_over_r_project_predict", "accuracy", "support_vectors"]


# ---------------------------------------------------------------------------------------
# Tables
# ---------------------------------------------------------------------------------------

def _write_csv(path: str, rows: list[dict], columns: list[str]):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(columns)
        for row in rows:
            w.writerow([_fmt(row.get(c, "")) for c in columns])


def _fmt(v):
    if isinstance(v, float):
        return f"{v:.6g}"
    return v


def parse_classes(text: str) -> list[int]:
    """'2-10' or '2,3,5' or '2,4-6' -> sorted unique ints, each at least 2."""
    out = set()
    for part in text.split(","):
        part = part.strip()
        if not part:
            continue
        try:
            if "-" in part:
                a, b = part.split("-", 1)
                out.update(range(int(a), int(b) + 1))
            else:
                out.add(int(part))
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"--classes {text!r}: expected numbers and ranges like 2-10 or 2,3,5") from None
    if not out or min(out) < 2:
        raise argparse.ArgumentTypeError(f"--classes {text!r}: every class count must be >= 2")
    return sorted(out)


# ---------------------------------------------------------------------------------------
# Command line
# ---------------------------------------------------------------------------------------

def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python3 -m chromasim.eigenstrain",
        description="Seed 001's Eigenstrains on a dataset's strain fields: SVD, recruitments, "
                    "SVM classifiers of the safety margin, classification time; CSVs and "
                    "figures in the style of its Fig. 4.")
    p.add_argument("dataset", help="dataset folder written by `chromasim generate` "
                                   "(with outputs.strain: true)")
    p.add_argument("-o", "--out", required=True, help="output folder (created)")
    p.add_argument("--bases", type=int, default=10, help="largest r (classifiers on r = 1..R)")
    p.add_argument("--classes", type=parse_classes, default=parse_classes("2-10"),
                   help="class counts of Gamma: 2 (below / at or above 0.5) and k equal bins "
                        "(default 2-10)")
    p.add_argument("--class-bases", type=int, default=6,
                   help="r of the accuracy-vs-classes figure and the confusion matrix")
    p.add_argument("--grid", choices=("full", "paper"), default="full",
                   help="full: every r for every class count; paper: every r for 2 classes, "
                        "--class-bases only for the others (Fig. 4B and 4D)")
    p.add_argument("--folds", type=int, default=10, help="folds of the stratified k-fold")
    p.add_argument("--seed", type=int, default=0, help="seed of the fold shuffle")
    p.add_argument("--schemes", default="kfold,lofo",
                   help="kfold (stratified k-fold), lofo (leave one friction out) and/or loso "
                        "(leave one sensor out: a dataset whose spec varies its sensor)")
    p.add_argument("--finger", choices=("left", "right"), default=None,
                   help="only this fingertip's strain (default: every fingertip with strain)")
    p.add_argument("--max-travel", type=float, default=0.0, metavar="MM",
                   help="only frames with travel_mm <= MM (the incipient-slip part of a slide; "
                        "0: every frame)")
    p.add_argument("--svd", choices=("auto", "numpy", "gram"), default="auto",
                   help="SVD method (see eigenstrains())")
    p.add_argument("--keep", type=int, default=50,
                   help="singular values and bases kept (table, energy); at least --bases")
    p.add_argument("--C", type=float, default=1.0, help="SVC regularisation C")
    p.add_argument("--kernel", default="rbf", help="SVC kernel")
    p.add_argument("--fold-svd", action="store_true",
                   help="fit the bases on each training fold only (randomized SVD), instead "
                        "of on all fields as the paper does")
    p.add_argument("--full-field", choices=("none", "timing", "cv"), default="timing",
                   help="classifier on the whole strain field: none; timing (one split, the "
                        "first k-fold fold, also gives its accuracy); cv (also its accuracy "
                        "in every fold of every scheme, 2 classes; slow on big sets)")
    p.add_argument("--timing-max-train", type=int, default=0,
                   help="at most this many training rows for the timing classifiers "
                        "(random, same for all; 0: the whole training fold)")
    p.add_argument("--repeats", type=int, default=11, help="timed predictions (median)")
    p.add_argument("--no-figures", action="store_true", help="CSVs only")
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    t_start = time.perf_counter()
    schemes = _check_args(args)
    ds, s = _load(args)
    os.makedirs(args.out, exist_ok=True)
    timings = {"load_s": time.perf_counter() - t_start}
    print(f"eigenstrain: {ds.root}: {s.n} strain fields of {s.fields.shape[1]} points "
          f"({s.grid['nx']} x {s.grid['ny']} grid), fingertips {sorted(set(s.finger))}, "
          f"{len(set(s.friction))} friction conditions"
          + (f", {s.dropped_unconverged} unconverged rows dropped"
             if s.dropped_unconverged else ""))

    # SVD
    R = min(args.bases, s.n, s.fields.shape[1])
    t0 = time.perf_counter()
    es = eigenstrains(s.fields, max(args.keep, R), args.svd)
    timings["svd_s"] = time.perf_counter() - t0
    _write_svd_outputs(args.out, s, es, R)

    # Classifiers
    t0 = time.perf_counter()
    acc_rows, conf, conf_k = _classify_all(args, s, es, R, schemes)
    timings["classifiers_s"] = time.perf_counter() - t0
    _write_csv(os.path.join(args.out, "accuracy.csv"), acc_rows, ACCURACY_COLUMNS)

    # Timing, 2 classes, on the first k-fold split
    t0 = time.perf_counter()
    timing_rows = _timing(args, s, es, R)
    timings["timing_s"] = time.perf_counter() - t0
    _write_csv(os.path.join(args.out, "timing.csv"), timing_rows, TIMING_COLUMNS)

    t0 = time.perf_counter()
    figures = [] if args.no_figures else _draw_figures(args, s, es, R, acc_rows, conf,
                                                       conf_k, timing_rows)
    timings["figures_s"] = time.perf_counter() - t0
    timings["total_s"] = time.perf_counter() - t_start
    _print_summary(args, s, es, acc_rows, timing_rows, timings, figures)
    return 0


def _check_args(args) -> list[str]:
    """The --schemes as a list; exits on a bad scheme, --bases or --folds."""
    schemes = [x.strip() for x in args.schemes.split(",") if x.strip()]
    bad = [x for x in schemes if x not in SCHEMES]
    if bad or not schemes:
        sys.exit(f"eigenstrain: --schemes {args.schemes!r}; allowed: kfold, lofo, loso")
    if args.bases < 1 or args.folds < 2:
        sys.exit("eigenstrain: --bases must be >= 1 and --folds >= 2")
    return schemes


def _load(args):
    """The dataset and its strain set; exits with a message naming the dataset."""
    try:
        ds = open_dataset(args.dataset)
        s = load_strain_set(ds, args.finger, max_travel_mm=args.max_travel)
        if s.n < 2:
            raise DatasetError(f"{s.n} strain rows left (--max-travel {args.max_travel})")
    except DatasetError as e:
        sys.exit(f"eigenstrain: {_named(e, args.dataset)}")
    return ds, s


def _write_svd_outputs(out: str, s: StrainSet, es: Eigenstrains, R: int):
    """singular_values.csv, bases.npz (the first R bases as images) and recruitments.csv."""
    frac = es.energy_fraction()
    _write_csv(os.path.join(out, "singular_values.csv"),
               [{"i": i + 1, "sigma": float(es.sigma[i]), "energy_fraction": float(frac[i]),
                 "cumulative_energy": float(np.cumsum(frac)[i])} for i in range(len(es.sigma))],
               ["i", "sigma", "energy_fraction", "cumulative_energy"])
    x, y = grid_axes_mm(s.grid)
    np.savez_compressed(os.path.join(out, "bases.npz"), sigma=es.sigma,
                        bases=es.bases[:R].reshape(R, int(s.grid["ny"]), int(s.grid["nx"])),
                        x_mm=x, y_mm=y, total_energy=es.total_energy)
    rec = es.recruitments(R)
    rec_rows = [{"trial": int(s.trial[j]), "frame": int(s.frame[j]), "finger": s.finger[j],
                 "friction": s.friction[j], "mu": float(s.mu[j]), "gamma": float(s.gamma[j]),
                 "travel_mm": float(s.travel_mm[j]), "time_s": float(s.time_s[j]),
                 **{f"r{i + 1}": float(rec[j, i]) for i in range(R)}} for j in range(s.n)]
    _write_csv(os.path.join(out, "recruitments.csv"), rec_rows,
               ["trial", "frame", "finger", "friction", "mu", "gamma", "travel_mm", "time_s"]
               + [f"r{i + 1}" for i in range(R)])


def _draw_figures(args, s, es, R, acc_rows, conf, conf_k, timing_rows) -> list[str]:
    """Every figure; returns the paths written."""
    figures = []
    figures += figure_bases(es, s.grid, args.out)
    figures += figure_recruitments(es, s, args.out)
    figures += figure_singular_values(es, args.out)
    figures += figure_accuracy_vs_bases(acc_rows, args.out)
    figures += figure_accuracy_by_classes(acc_rows, args.out)
    figures += figure_accuracy_vs_classes(acc_rows, min(args.class_bases, R), conf, conf_k,
                                          args.out)
    figures += figure_time_ratio(timing_rows, args.out)
    return figures


def _classify_all(args, s: StrainSet, es: Eigenstrains, R: int, schemes):
    rs_all = list(range(1, R + 1))
    r_class = min(args.class_bases, R)
    F = es.recruitments(R)
    fold_features = None
    if args.fold_svd:
        from sklearn.utils.extmath import randomized_svd

        def fold_features(train, test):
            _, _, Vt = randomized_svd(s.fields[train], n_components=R, n_iter=7,
                                      random_state=args.seed)
            return s.fields @ Vt.T
    acc_rows = []
    conf, conf_k = None, None
    for k in args.classes:
        y = gamma_classes(s.gamma, k)
        rs = rs_all if (args.grid == "full" or k == 2) else [r_class]
        chance = float(np.bincount(y).max() / len(y))
        for scheme in schemes:
            groups = s.sensor if scheme == "loso" else s.friction
            folds_list = splits(scheme, y, groups, args.folds, args.seed)
            if not folds_list:
                print(f"eigenstrain: {scheme}: skipped (one "
                      f"{'sensor' if scheme == 'loso' else 'friction condition'} only)")
                continue
            res = cross_validate(F, y, folds_list, args.C, args.kernel, rs, fold_features)
            if k == 2 and args.full_field == "cv":
                res["full"] = cross_validate(s.fields, y, folds_list, args.C, args.kernel,
                                             [s.fields.shape[1]])[s.fields.shape[1]]
            for r, (a, b) in res.items():
                acc_rows.append({
                    "scheme": scheme, "classes": k, "r": r, "folds": len(folds_list),
                    "accuracy_mean": float(a.mean()), "accuracy_std": float(a.std()),
                    "balanced_accuracy_mean": float(b.mean()),
                    "balanced_accuracy_std": float(b.std()), "chance": chance,
                    "frames": s.n, "classes_present": int(len(np.unique(y))),
                    "bases_from": "training fold" if args.fold_svd else "all fields"})
            if scheme == "kfold" and k == (5 if 5 in args.classes else max(args.classes)):
                conf_k = k
                conf = confusion(F[:, :r_class], y, folds_list, k, args.C, args.kernel,
                                 fold_features)
    return acc_rows, conf, conf_k


def _timing(args, s: StrainSet, es: Eigenstrains, R: int):
    y = gamma_classes(s.gamma, 2)
    train, test = splits("kfold", y, s.friction, args.folds, args.seed)[0]
    if args.timing_max_train and len(train) > args.timing_max_train:
        rng = np.random.default_rng(args.seed)
        train = np.sort(rng.choice(train, args.timing_max_train, replace=False))
    rows = time_classification(s.fields, es, y, train, test, range(1, R + 1), args.repeats,
                               args.C, args.kernel, full=args.full_field != "none")
    for row in rows:
        row["train_frames"] = len(train)
    return rows


def _print_summary(args, s, es, acc_rows, timing_rows, timings, figures):
    frac = np.cumsum(es.energy_fraction())
    print(f"\nSVD ({es.method}): sigma_1 = {es.sigma[0]:.4g}; energy in the first "
          + ", ".join(f"{r}: {100 * frac[r - 1]:.2f} %" for r in (1, 2, 6, 10) if r <= len(frac)))
    look = {(a["scheme"], a["classes"], a["r"]): a for a in acc_rows}
    schemes = [sc for sc in SCHEMES if any(a["scheme"] == sc for a in acc_rows)]
    chance = {a["classes"]: a["chance"] for a in acc_rows}

    def cells(k, r):
        out = []
        for sc in schemes:
            a = look.get((sc, k, r))
            out += [f"{100 * a['accuracy_mean']:.1f} +- {100 * a['accuracy_std']:.1f}",
                    f"{100 * a['balanced_accuracy_mean']:.1f} +- "
                    f"{100 * a['balanced_accuracy_std']:.1f}"] if a else ["", ""]
        return out
    head = " | ".join(f"{SCHEME_NAMES[sc]}: {w}" for sc in schemes
                      for w in ("accuracy", "balanced"))
    if 2 in chance:
        rs = sorted(a["r"] for a in acc_rows if a["classes"] == 2 and a["r"] != "full"
                    and a["scheme"] == schemes[0])
        rs += ["full"] if (schemes[0], 2, "full") in look else []
        print(f"\n2 classes (Gamma < 0.5, >= 0.5; majority class {100 * chance[2]:.1f} % of "
              f"the frames), % over folds (mean +- std); balanced: mean recall of the classes")
        print(f"| r | {head} |")
        print("|---" * (1 + 2 * len(schemes)) + "|")
        for r in rs:
            print(f"| {r} | " + " | ".join(cells(2, r)) + " |")
    r6 = min(args.class_bases, max(a["r"] for a in acc_rows if a["r"] != "full"))
    ks = sorted({a["classes"] for a in acc_rows if a["r"] == r6})
    print(f"\nclasses of Gamma (k equal bins of [0, 1]) with r = {r6} bases, %; "
          "all r in accuracy.csv")
    print(f"| classes | majority class | {head} |")
    print("|---" * (2 + 2 * len(schemes)) + "|")
    for k in ks:
        print(f"| {k} | {100 * chance[k]:.1f} | " + " | ".join(cells(k, r6)) + " |")
    if timing_rows and "full_over_r_predict" in timing_rows[0]:
        full = timing_rows[-1]
        print(f"\nclassification time, 2 classes, {full['test_frames']} test frames, "
              f"{timing_rows[0]['train_frames']} training frames; whole field: "
              f"{1e6 * full['predict_s_per_frame']:.1f} us/frame, accuracy "
              f"{100 * full['accuracy']:.1f} %")
        print("| r | us/frame (predict) | field / r | us/frame (project + predict) | field / r |"
              " accuracy % |")
        print("|---|---|---|---|---|---|")
        for t in timing_rows[:-1]:
            print(f"| {t['r']} | {1e6 * t['predict_s_per_frame']:.2f} | "
                  f"{t['full_over_r_predict']:.0f} | "
                  f"{1e6 * t['project_predict_s_per_frame']:.2f} | "
                  f"{t['full_over_r_project_predict']:.0f} | {100 * t['accuracy']:.1f} |")
    print("\nrun time: " + ", ".join(f"{k[:-2]} {v:.1f} s" for k, v in timings.items()))
    print(f"wrote {args.out}: singular_values.csv, accuracy.csv, timing.csv, recruitments.csv, "
          f"bases.npz and {len(figures)} figure files")


def _named(error: Exception, path: str) -> str:
    """The error's message, prefixed with the path unless it names the folder already."""
    text = str(error)
    return text if (path in text or os.path.abspath(path) in text) else f"{path}: {text}"


if __name__ == "__main__":
    sys.exit(main())
