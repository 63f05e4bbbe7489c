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
Gamma over [0, 1], the paper's "quantization of the safety margin"). Two schemes: stratified
k-fold ("10-fold" in the paper) and leave-one-friction-out (each friction level of the
dataset held out in turn; the paper's cross-subject test holds out a participant, this
dataset has no participants and friction is the factor the classifier must be invariant to).

Usage:
  python3 -m chromasim.eigenstrain DATASET -o OUTDIR [--bases 10] [--classes 2-10]
                                   [--folds 10] [--seed 0] ...
Outputs (OUTDIR): singular_values.csv, accuracy.csv, timing.csv, recruitments.csv,
bases.npz, and the figures fig4a_bases, fig4a_recruitments, fig4b_accuracy_vs_bases,
fig4c_time_ratio, fig4d_accuracy_vs_classes, accuracy_vs_bases_by_classes,
singular_values (PNG and SVG). docs/PYTHON.md describes them.
"""

from __future__ import annotations

import argparse
import csv
import os
import sys
import time
import warnings
from dataclasses import dataclass

import numpy as np

from .data import Dataset, DatasetError, open_dataset

SCHEMES = ("kfold", "lofo")
SCHEME_NAMES = {"kfold": "stratified k-fold", "lofo": "leave one friction out"}


# ---------------------------------------------------------------------------------------
# Data
# ---------------------------------------------------------------------------------------

@dataclass
class StrainSet:
    """The strain rows of a dataset with the labels of their frame and fingertip.

    fields: (n, ny * nx) eps_xx, row-major on the grid (index iy * nx + ix).
    Every other array has n entries."""

    fields: np.ndarray
    trial: np.ndarray
    frame: np.ndarray
    finger: np.ndarray
    friction: np.ndarray
    mu: np.ndarray
    gamma: np.ndarray
    travel_mm: np.ndarray
    time_s: np.ndarray
    grid: dict
    dropped_unconverged: int = 0

    @property
    def n(self) -> int:
        return len(self.fields)


def load_strain_set(ds: Dataset, finger: str | None = None,
                    drop_unconverged: bool = True, max_travel_mm: float = 0.0) -> StrainSet:
    """Every strain row of `ds` (of one fingertip, or of all that have strain files) with
    its frame's labels. Rows of frames whose fingertip has `converged` 0 are dropped, and
    with max_travel_mm > 0 the rows of frames with travel_mm above it."""
    fingers = [finger] if finger else list(ds.fingers)
    files = {f for _, _, f, _ in ds.strain_files()}
    fingers = [f for f in fingers if f in files]
    if not fingers:
        raise DatasetError(
            f"{ds.root}: no strain files{' for fingertip ' + finger if finger else ''} "
            "(strain/<split>/trial_*/<finger>.csv; generate with outputs.strain: true)")
    grid = ds.strain_grid()
    lab = ds.labels
    row_of = {(int(t), int(f)): i for i, (t, f) in enumerate(ds.frame_keys())}
    parts: dict[str, list] = {k: [] for k in ("fields", "idx", "finger")}
    for fg in fingers:
        fields, keys = ds.strain(fg)
        try:
            idx = np.array([row_of[(int(t), int(f))] for t, f in keys], dtype=np.int64)
        except KeyError as e:
            raise DatasetError(f"{ds.root}: strain row {e.args[0]} (trial, frame) of "
                               f"fingertip {fg} has no labels.csv row") from None
        parts["fields"].append(fields)
        parts["idx"].append(idx)
        parts["finger"].append(np.full(len(idx), fg, dtype=object))
    fields = np.concatenate(parts["fields"])
    idx = np.concatenate(parts["idx"])
    fg = np.concatenate(parts["finger"])
    per_finger = lambda name: np.array(  # noqa: E731
        [lab[f"{f}_{name}"][i] for f, i in zip(fg, idx)], dtype=float)
    keep = np.ones(len(idx), dtype=bool)
    if drop_unconverged and all(f"{f}_converged" in lab for f in fingers):
        keep = per_finger("converged") != 0
    if fields.shape[1] != grid["nx"] * grid["ny"]:
        raise DatasetError(f"{ds.root}: strain rows hold {fields.shape[1]} values, the grid "
                           f"{grid['nx']} x {grid['ny']} needs {grid['nx'] * grid['ny']}")
    if max_travel_mm > 0 and "travel_mm" in lab:
        keep &= lab["travel_mm"][idx] <= max_travel_mm + 1e-9
    s = StrainSet(
        fields=fields, trial=lab["trial"][idx].astype(np.int64),
        frame=lab["frame"][idx].astype(np.int64), finger=fg,
        friction=lab["friction"][idx], mu=per_finger("mu"), gamma=per_finger("gamma"),
        travel_mm=lab["travel_mm"][idx] if "travel_mm" in lab else np.zeros(len(idx)),
        time_s=lab["time_s"][idx], grid=grid)
    if not keep.all():
        for name in ("fields", "trial", "frame", "finger", "friction", "mu", "gamma",
                     "travel_mm", "time_s"):
            setattr(s, name, getattr(s, name)[keep])
        s.dropped_unconverged = int((per_finger("converged") == 0).sum()) \
            if drop_unconverged and all(f"{f}_converged" in lab for f in fingers) else 0
    return s


def grid_axes_mm(grid: dict) -> tuple[np.ndarray, np.ndarray]:
    """x (nx) and y (ny) coordinates of the strain grid, mm (docs/DATASET_FORMAT.md)."""
    x = np.linspace(-grid["half_width_x_mm"], grid["half_width_x_mm"], int(grid["nx"]))
    y = np.linspace(-grid["half_width_y_mm"], grid["half_width_y_mm"], int(grid["ny"]))
    return x, y


# ---------------------------------------------------------------------------------------
# SVD
# ---------------------------------------------------------------------------------------

@dataclass
class Eigenstrains:
    """Truncated SVD X ~ v diag(sigma) bases of the data matrix X (n frames x m points).

    sigma: (k,) descending; bases: (k, m), the Eigenstrains u_i(x) as orthonormal rows;
    v: (n, k), orthonormal columns v_i(t); total_energy: ||X||_F^2 (all singular values
    squared, also those not kept)."""

    sigma: np.ndarray
    bases: np.ndarray
    v: np.ndarray
    total_energy: float
    method: str

    def recruitments(self, r: int | None = None) -> np.ndarray:
        """sigma_i v_i(t) for i < r: (n, r), the projections <eps(t), u_i>."""
        return self.v[:, :r] * self.sigma[:r]

    def project(self, fields: np.ndarray, r: int | None = None) -> np.ndarray:
        """Recruitments of new fields (rows) on the first r bases: fields @ u_i."""
        return fields @ self.bases[:r].T

    def reconstruct(self, r: int) -> np.ndarray:
        """eq. 2: sum over i < r of u_i(x) sigma_i v_i(t), shape (n, m)."""
        return self.recruitments(r) @ self.bases[:r]

    def energy_fraction(self) -> np.ndarray:
        """sigma_i^2 / ||X||_F^2 for the kept i."""
        return self.sigma ** 2 / self.total_energy if self.total_energy > 0 else self.sigma * 0


def eigenstrains(X: np.ndarray, k: int | None = None, method: str = "auto") -> Eigenstrains:
    """SVD of X (rows = frames), not centred. `k` bases are kept (all when None).

    method "numpy": np.linalg.svd(X, full_matrices=False) (exact, all singular values);
    "gram": the eigen-decomposition of the smaller Gram matrix (X X^T or X^T X) with
    scipy.linalg.eigh, only the top k eigenpairs (much cheaper for 10,080 x 7,676; accurate
    for the leading bases, its relative error grows as sigma_i falls towards
    sqrt(eps_machine) sigma_1); "auto": numpy when min(n, m) <= 3000, else gram.
    Signs: each basis is oriented so that its recruitments sum to a non-negative value."""
    X = np.asarray(X, dtype=np.float64)
    n, m = X.shape
    kmax = min(n, m)
    k = kmax if k is None else max(1, min(int(k), kmax))
    if method == "auto":
        method = "numpy" if kmax <= 3000 else "gram"
    total = float(np.einsum("ij,ij->", X, X))
    if method == "numpy":
        A, s, Bt = np.linalg.svd(X, full_matrices=False)
        v, sigma, bases = A[:, :k], s[:k], Bt[:k]
    elif method == "gram":
        v, sigma, bases = _gram_svd(X, k)
    else:
        raise ValueError(f"eigenstrains: method {method!r}; allowed: auto, numpy, gram")
    signs = np.where((v * sigma).sum(axis=0) < 0, -1.0, 1.0)
    return Eigenstrains(sigma=sigma.copy(), bases=bases * signs[:, None], v=v * signs,
                        total_energy=total, method=method)


def _gram_svd(X: np.ndarray, k: int):
    from scipy.linalg import eigh
    n, m = X.shape
    small = X @ X.T if n <= m else X.T @ X
    d = small.shape[0]
    w, Q = eigh(small, subset_by_index=[d - k, d - 1]) if k < d else eigh(small)
    order = np.argsort(w)[::-1][:k]
    w, Q = w[order], Q[:, order]
    sigma = np.sqrt(np.clip(w, 0.0, None))
    safe = np.where(sigma > 0, sigma, 1.0)
    if n <= m:  # Q holds v; u = X^T v / sigma
        v = Q
        bases = (X.T @ Q / safe).T
    else:       # Q holds u; v = X u / sigma
        bases = Q.T
        v = X @ Q / safe
    return v, sigma, bases


# ---------------------------------------------------------------------------------------
# Classes and classifiers
# ---------------------------------------------------------------------------------------

def gamma_classes(gamma: np.ndarray, k: int) -> np.ndarray:
    """Class of each Gamma in k equal bins of [0, 1]: bin j holds j/k <= Gamma < (j+1)/k
    (Gamma = 1 in the top bin). k = 2: 0 below 0.5, 1 at or above 0.5."""
    if k < 2:
        raise ValueError(f"classes: {k}; allowed: 2 or more")
    g = np.clip(np.asarray(gamma, dtype=float), 0.0, 1.0)
    return np.minimum(np.floor(g * k + 1e-12), k - 1).astype(np.int64)


def make_classifier(C: float = 1.0, kernel: str = "rbf"):
    """Standardise the features, then an SVC (gamma='scale')."""
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler
    from sklearn.svm import SVC
    return make_pipeline(StandardScaler(), SVC(C=C, kernel=kernel, gamma="scale",
                                               cache_size=500))


def _fit(F, y, C, kernel):
    if len(np.unique(y)) < 2:  # a training fold with one class: predict it
        from sklearn.dummy import DummyClassifier
        return DummyClassifier(strategy="most_frequent").fit(F, y)
    return make_classifier(C, kernel).fit(F, y)


def splits(scheme: str, y: np.ndarray, groups: np.ndarray, folds: int, seed: int):
    """(train, test) index pairs. kfold: StratifiedKFold(folds, shuffled with `seed`) on
    the classes y (plain shuffled KFold when a class has fewer than `folds` members);
    lofo: LeaveOneGroupOut on `groups` (the friction names)."""
    from sklearn.model_selection import KFold, LeaveOneGroupOut, StratifiedKFold
    if scheme == "kfold":
        counts = np.bincount(y)
        counts = counts[counts > 0]
        if counts.min() >= folds:
            cv = StratifiedKFold(n_splits=folds, shuffle=True, random_state=seed)
            return list(cv.split(np.zeros(len(y)), y))
        return list(KFold(n_splits=folds, shuffle=True, random_state=seed).split(y))
    if scheme == "lofo":
        if len(np.unique(groups)) < 2:
            return []
        return list(LeaveOneGroupOut().split(np.zeros(len(y)), y, groups))
    raise ValueError(f"scheme {scheme!r}; allowed: {', '.join(SCHEMES)}")


def cross_validate(features: np.ndarray, y: np.ndarray, folds_list, C=1.0, kernel="rbf",
                   rs=None, fold_features=None):
    """Accuracy and balanced accuracy per fold for each r in `rs` (first r columns of the
    features). `fold_features(train, test)` may return per-fold features (bases fitted on
    the training rows only). Returns {r: (acc array, balanced acc array)}."""
    from sklearn.metrics import balanced_accuracy_score
    rs = rs or [features.shape[1]]
    out = {r: ([], []) for r in rs}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a class absent from a test fold
        for train, test in folds_list:
            F = fold_features(train, test) if fold_features else features
            for r in rs:
                clf = _fit(F[train, :r], y[train], C, kernel)
                pred = clf.predict(F[test, :r])
                out[r][0].append(float(np.mean(pred == y[test])))
                out[r][1].append(float(balanced_accuracy_score(y[test], pred)))
    return {r: (np.array(a), np.array(b)) for r, (a, b) in out.items()}


def confusion(features, y, folds_list, k, C=1.0, kernel="rbf", fold_features=None):
    """k x k confusion matrix (rows true, columns predicted) pooled over the test folds,
    on all columns of the features (or of fold_features(train, test))."""
    M = np.zeros((k, k), dtype=np.int64)
    r = features.shape[1]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for train, test in folds_list:
            Fk = fold_features(train, test)[:, :r] if fold_features else features
            pred = _fit(Fk[train], y[train], C, kernel).predict(Fk[test])
            np.add.at(M, (y[test], pred), 1)
    return M


def _median_time(fn, repeats: int) -> float:
    times = []
    for _ in range(max(1, repeats)):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def time_classification(X, es: Eigenstrains, y, train, test, rs, repeats=5, C=1.0,
                        kernel="rbf", full=True):
    """Prediction time on the test rows of classifiers trained on the train rows, with the
    first r recruitments and with the whole strain field. Rows of dicts: r ('full' for the
    field), seconds per frame for predict alone and for projection + predict (the
    projection fields @ u_i is what computing the recruitments of a new frame costs),
    accuracy on the test rows, number of support vectors, fit seconds. Timed with one BLAS
    thread (threadpoolctl); libsvm's prediction is single-threaded anyway."""
    from threadpoolctl import threadpool_limits
    rows = []
    Xte = X[test]
    # one BLAS thread: on a shared machine, threads only add noise to the ratios
    with warnings.catch_warnings(), threadpool_limits(limits=1):
        warnings.simplefilter("ignore")
        for r in list(rs) + (["full"] if full else []):
            if r == "full":
                Ftr, Fte = X[train], Xte
                project = lambda: Xte  # noqa: E731
            else:
                F = es.recruitments(r)
                Ftr, Fte = F[train], F[test]
                P = np.ascontiguousarray(es.bases[:r].T)  # prepared once, as deployed
                project = lambda P=P: Xte @ P  # noqa: E731
            t0 = time.perf_counter()
            clf = _fit(Ftr, y[train], C, kernel)
            fit_s = time.perf_counter() - t0
            pred = clf.predict(Fte)
            t_pred = _median_time(lambda: clf.predict(Fte), repeats)
            t_all = _median_time(lambda: clf.predict(project()), repeats)
            svc = clf[-1] if hasattr(clf, "__getitem__") else None
            rows.append({
                "r": r, "test_frames": len(test), "fit_s": fit_s,
                "predict_s_per_frame": t_pred / len(test),
                "project_predict_s_per_frame": t_all / len(test),
                "accuracy": float(np.mean(pred == y[test])),
                "support_vectors": int(svc.n_support_.sum()) if svc is not None else 0,
            })
    if full:
        full_row = rows[-1]
        for row in rows:
            row["full_over_r_predict"] = (full_row["predict_s_per_frame"]
                                          / row["predict_s_per_frame"])
            row["full_over_r_project_predict"] = (full_row["project_predict_s_per_frame"]
                                                  / row["project_predict_s_per_frame"])
    return rows


# ---------------------------------------------------------------------------------------
# Figures
# ---------------------------------------------------------------------------------------

def _friction_order(s: StrainSet):
    names = list(dict.fromkeys(s.friction))
    mean_mu = {f: float(np.mean(s.mu[s.friction == f])) for f in names}
    return sorted(names, key=lambda f: mean_mu[f]), mean_mu


def _time_axis(s: StrainSet):
    if np.ptp(s.travel_mm) > 0:
        return s.travel_mm, "relative displacement (travel) (mm)"
    return s.time_s, "time (s)"


def figure_bases(es: Eigenstrains, grid: dict, outdir: str, count: int = 6):
    from .plots import plt, save, symmetric_limit
    x, y = grid_axes_mm(grid)
    count = min(count, len(es.sigma))
    cols = 3 if count > 2 else count
    rows = int(np.ceil(count / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(3.6 * cols, 2.6 * rows), squeeze=False,
                             layout="constrained")
    frac = es.energy_fraction()
    for i, ax in enumerate(axes.flat):
        if i >= count:
            ax.axis("off")
            continue
        img = es.bases[i].reshape(int(grid["ny"]), int(grid["nx"]))
        lim = symmetric_limit(img)
        im = ax.imshow(img, origin="lower", extent=[x[0], x[-1], y[0], y[-1]],
                       cmap="RdBu_r", vmin=-lim, vmax=lim, aspect="equal")
        ax.set_title(f"u_{i + 1}: sigma^2 {100 * frac[i]:.2f} % of energy")
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
        fig.colorbar(im, ax=ax, shrink=0.8, label=f"u_{i + 1} (-)")
    fig.suptitle("Eigenstrains: first bases of eps_xx on the strain grid, unit norm "
                 "(red: tension, blue: compression, for a positive recruitment)")
    return save(fig, outdir, "fig4a_bases")


def figure_recruitments(es: Eigenstrains, s: StrainSet, outdir: str, count: int = 6):
    from .plots import plt, save
    t, tlabel = _time_axis(s)
    order, mean_mu = _friction_order(s)
    count = min(count, len(es.sigma))
    cols = 3 if count > 2 else count
    rows = int(np.ceil(count / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(3.4 * cols, 2.6 * rows), squeeze=False)
    colours = plt.cm.viridis(np.linspace(0, 1, max(len(order), 2)))
    R = es.recruitments(count)
    tk = np.round(t, 9)
    for i, ax in enumerate(axes.flat):
        if i >= count:
            ax.axis("off")
            continue
        for c, f in zip(colours, order):
            m = s.friction == f
            ts = np.unique(tk[m])
            mean = np.array([R[m & (tk == v), i].mean() for v in ts])
            std = np.array([R[m & (tk == v), i].std() for v in ts])
            ax.plot(ts, mean, color=c, lw=1.2, label=f"{f} (mu {mean_mu[f]:.2f})")
            ax.fill_between(ts, mean - std, mean + std, color=c, alpha=0.2, lw=0)
        ax.set_title(f"sigma_{i + 1} v_{i + 1}(t)")
        ax.set_xlabel(tlabel)
        ax.set_ylabel(f"sigma_{i + 1} v_{i + 1} (-)")
    axes.flat[0].legend(fontsize=7, loc="best")
    fig.suptitle("Recruitment of the first bases per friction level (mean +- std over trials)")
    fig.tight_layout()
    return save(fig, outdir, "fig4a_recruitments")


def _accuracy_band(ax, rows, x_key: str, colour, label: str) -> np.ndarray:
    """Mean accuracy (%) of `rows` against rows[x_key], with a +- std band; returns x."""
    x = np.array([a[x_key] for a in rows])
    m = np.array([a["accuracy_mean"] for a in rows]) * 100
    sd = np.array([a["accuracy_std"] for a in rows]) * 100
    ax.plot(x, m, "o-", color=colour, label=label)
    ax.fill_between(x, m - sd, m + sd, color=colour, alpha=0.2, lw=0)
    return x


def figure_accuracy_vs_bases(acc_rows, outdir: str, classes: int = 2):
    from .plots import plt, save
    fig, ax = plt.subplots(figsize=(5, 3.4))
    chance = None
    for scheme, colour in zip(SCHEMES, ("darkgreen", "yellowgreen")):
        rows = [a for a in acc_rows if a["scheme"] == scheme and a["classes"] == classes]
        rb = sorted((a for a in rows if a["r"] != "full"), key=lambda a: a["r"])
        if not rb:
            continue
        r = _accuracy_band(ax, rb, "r", colour, SCHEME_NAMES[scheme])
        ax.plot(r, [100 * a["balanced_accuracy_mean"] for a in rb], "--", color=colour, lw=1,
                label=f"{SCHEME_NAMES[scheme]}, balanced accuracy")
        full = [a for a in rows if a["r"] == "full"]
        if full:
            ax.errorbar([r.max() + 1.5], [full[0]["accuracy_mean"] * 100],
                        [full[0]["accuracy_std"] * 100], fmt="s", color=colour, capsize=3)
            ax.plot([r.max() + 1.5], [full[0]["balanced_accuracy_mean"] * 100], "x",
                    color=colour)
        chance = rb[0]["chance"]
    if chance is not None:
        ax.axhline(chance * 100, color="grey", ls=":", lw=1, label="majority class")
    ax.set_xlabel("number of bases r")
    ax.set_ylabel("classification rate (%)")
    ax.set_title(f"Gamma in {classes} classes from the first r recruitments "
                 "(square, right: whole strain field)")
    ax.legend(fontsize=7)
    return save(fig, outdir, "fig4b_accuracy_vs_bases")


def figure_accuracy_by_classes(acc_rows, outdir: str, scheme: str = "kfold"):
    from .plots import plt, save
    fig, ax = plt.subplots(figsize=(5, 3.4))
    ks = sorted({a["classes"] for a in acc_rows if a["scheme"] == scheme})
    colours = plt.cm.plasma(np.linspace(0, 0.9, max(len(ks), 2)))
    for k, c in zip(ks, colours):
        rb = sorted((a for a in acc_rows if a["scheme"] == scheme and a["classes"] == k
                     and a["r"] != "full"), key=lambda a: a["r"])
        if rb:
            ax.plot([a["r"] for a in rb], [100 * a["accuracy_mean"] for a in rb], "o-",
                    color=c, ms=3, label=f"{k} classes")
    ax.set_xlabel("number of bases r")
    ax.set_ylabel("classification rate (%)")
    ax.set_title(f"Gamma classes against bases ({SCHEME_NAMES[scheme]})")
    ax.legend(fontsize=7, ncol=2)
    return save(fig, outdir, "accuracy_vs_bases_by_classes")


def figure_accuracy_vs_classes(acc_rows, r: int, conf, conf_k: int, outdir: str):
    from .plots import plt, save
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.6))
    ax = axes[0]
    for scheme, colour in zip(SCHEMES, ("darkgreen", "yellowgreen")):
        rb = sorted((a for a in acc_rows if a["scheme"] == scheme and a["r"] == r),
                    key=lambda a: a["classes"])
        if not rb:
            continue
        k = _accuracy_band(ax, rb, "classes", colour, SCHEME_NAMES[scheme])
        ax.plot(k, [100 * a["chance"] for a in rb], ":", color="grey", lw=1)
    ax.set_xlabel("number of classes of Gamma")
    ax.set_ylabel("classification rate (%)")
    ax.set_title(f"{r} bases (dotted: majority class)")
    ax.legend(fontsize=7)
    ax = axes[1]
    if conf is not None:
        rowsum = conf.sum(axis=1, keepdims=True)
        P = np.where(rowsum > 0, conf / np.maximum(rowsum, 1), np.nan) * 100
        im = ax.imshow(P, cmap="Greens", vmin=0, vmax=100, origin="upper")
        edges = np.linspace(0, 1, conf_k + 1)
        ticks = [f"{edges[j]:.1f}-{edges[j + 1]:.1f}" for j in range(conf_k)]
        ax.set_xticks(range(conf_k), ticks, rotation=45, fontsize=7)
        ax.set_yticks(range(conf_k), ticks, fontsize=7)
        for (i, j), n in np.ndenumerate(conf):
            ax.text(j, i, str(n), ha="center", va="center", fontsize=6)
        ax.set_xlabel("predicted Gamma class")
        ax.set_ylabel("true Gamma class")
        ax.set_title(f"confusion, {conf_k} classes, {r} bases, k-fold (% of row; counts)")
        fig.colorbar(im, ax=ax, label="% of the true class")
    else:
        ax.axis("off")
    fig.tight_layout()
    return save(fig, outdir, "fig4d_accuracy_vs_classes")


def figure_time_ratio(timing_rows, outdir: str):
    from .plots import plt, save
    rb = [t for t in timing_rows if t["r"] != "full" and "full_over_r_predict" in t]
    if not rb:
        return []
    fig, ax = plt.subplots(figsize=(5, 3.4))
    r = [t["r"] for t in rb]
    ax.semilogy(r, [1 / t["full_over_r_predict"] for t in rb], "o-",
                label="predict (recruitments given)")
    ax.semilogy(r, [1 / t["full_over_r_project_predict"] for t in rb], "s--",
                label="project on u_i + predict")
    ax.set_xlabel("number of bases r")
    ax.set_ylabel("time with r bases / time with the field (-)")
    ax.set_title("Classification time, 2 classes, against the whole strain field")
    ax.legend(fontsize=7)
    return save(fig, outdir, "fig4c_time_ratio")


def figure_singular_values(es: Eigenstrains, outdir: str):
    from .plots import plt, save
    fig, ax = plt.subplots(figsize=(5, 3.4))
    i = np.arange(1, len(es.sigma) + 1)
    frac = es.energy_fraction()
    ax.semilogy(i, es.sigma, "o-", ms=3, label="sigma_i")
    ax.set_xlabel("basis index i")
    ax.set_ylabel("singular value sigma_i (-)")
    ax2 = ax.twinx()
    ax2.plot(i, 100 * np.cumsum(frac), "r.-", ms=3, label="cumulative energy")
    ax2.set_ylabel("cumulative sum of sigma^2 / ||X||_F^2 (%)", color="r")
    ax.set_title("Singular values of the strain data matrix")
    return save(fig, outdir, "singular_values")


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
                   help="kfold (stratified k-fold) and/or lofo (leave one friction out)")
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
    schemes = [x.strip() for x in args.schemes.split(",") if x.strip()]
    bad = [x for x in schemes if x not in SCHEMES]
    if bad or not schemes:
        sys.exit(f"eigenstrain: --schemes {args.schemes!r}; allowed: kfold, lofo")
    if args.bases < 1 or args.folds < 2:
        sys.exit("eigenstrain: --bases must be >= 1 and --folds >= 2")
    try:
        ds = open_dataset(args.dataset)
        s = load_strain_set(ds, args.finger, max_travel_mm=args.max_travel)
        if s.n < 2:
            raise DatasetError(f"{s.n} strain rows left (--max-travel {args.max_travel})")
    except DatasetError as e:
        sys.exit(f"eigenstrain: {_named(e, args.dataset)}")
    os.makedirs(args.out, exist_ok=True)
    timings = {"load_s": time.perf_counter() - t_start}
    print(f"eigenstrain: {ds.root}: {s.n} strain fields of {s.fields.shape[1]} points "
          f"({s.grid['nx']} x {s.grid['ny']} grid), fingertips {sorted(set(s.finger))}, "
          f"{len(set(s.friction))} friction levels"
          + (f", {s.dropped_unconverged} unconverged rows dropped"
             if s.dropped_unconverged else ""))

    # SVD
    R = min(args.bases, s.n, s.fields.shape[1])
    t0 = time.perf_counter()
    es = eigenstrains(s.fields, max(args.keep, R), args.svd)
    timings["svd_s"] = time.perf_counter() - t0
    frac = es.energy_fraction()
    _write_csv(os.path.join(args.out, "singular_values.csv"),
               [{"i": i + 1, "sigma": float(es.sigma[i]), "energy_fraction": float(frac[i]),
                 "cumulative_energy": float(np.cumsum(frac)[i])} for i in range(len(es.sigma))],
               ["i", "sigma", "energy_fraction", "cumulative_energy"])
    x, y = grid_axes_mm(s.grid)
    np.savez_compressed(os.path.join(args.out, "bases.npz"), sigma=es.sigma,
                        bases=es.bases[:R].reshape(R, int(s.grid["ny"]), int(s.grid["nx"])),
                        x_mm=x, y_mm=y, total_energy=es.total_energy)
    rec = es.recruitments(R)
    rec_rows = [{"trial": int(s.trial[j]), "frame": int(s.frame[j]), "finger": s.finger[j],
                 "friction": s.friction[j], "mu": float(s.mu[j]), "gamma": float(s.gamma[j]),
                 "travel_mm": float(s.travel_mm[j]), "time_s": float(s.time_s[j]),
                 **{f"r{i + 1}": float(rec[j, i]) for i in range(R)}} for j in range(s.n)]
    _write_csv(os.path.join(args.out, "recruitments.csv"), rec_rows,
               ["trial", "frame", "finger", "friction", "mu", "gamma", "travel_mm", "time_s"]
               + [f"r{i + 1}" for i in range(R)])

    # Classifiers
    t0 = time.perf_counter()
    acc_rows, conf, conf_k = _classify_all(args, s, es, R, schemes)
    timings["classifiers_s"] = time.perf_counter() - t0
    _write_csv(os.path.join(args.out, "accuracy.csv"), acc_rows,
               ["scheme", "classes", "r", "folds", "accuracy_mean", "accuracy_std",
                "balanced_accuracy_mean", "balanced_accuracy_std", "chance", "frames",
                "classes_present", "bases_from"])

    # Timing, 2 classes, on the first k-fold split
    t0 = time.perf_counter()
    timing_rows = _timing(args, s, es, R)
    timings["timing_s"] = time.perf_counter() - t0
    _write_csv(os.path.join(args.out, "timing.csv"), timing_rows,
               ["r", "test_frames", "train_frames", "fit_s", "predict_s_per_frame",
                "project_predict_s_per_frame", "full_over_r_predict",
                "full_over_r_project_predict", "accuracy", "support_vectors"])

    t0 = time.perf_counter()
    figures = []
    if not args.no_figures:
        figures += figure_bases(es, s.grid, args.out)
        figures += figure_recruitments(es, s, args.out)
        figures += figure_singular_values(es, args.out)
        figures += figure_accuracy_vs_bases(acc_rows, args.out)
        figures += figure_accuracy_by_classes(acc_rows, args.out)
        figures += figure_accuracy_vs_classes(acc_rows, min(args.class_bases, R), conf, conf_k,
                                              args.out)
        figures += figure_time_ratio(timing_rows, args.out)
    timings["figures_s"] = time.perf_counter() - t0
    timings["total_s"] = time.perf_counter() - t_start
    _print_summary(args, s, es, acc_rows, timing_rows, timings, figures)
    return 0


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
            folds_list = splits(scheme, y, s.friction, args.folds, args.seed)
            if not folds_list:
                print(f"eigenstrain: {scheme}: skipped (one friction level only)")
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
