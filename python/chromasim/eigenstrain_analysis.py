"""The analysis of chromasim.eigenstrain: the SVD of the strain data matrix (the
Eigenstrains and their recruitments), the classes of Gamma, cross-validated SVM
classifiers on the recruitments and their prediction time."""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass

import numpy as np

# Cross-validation schemes of splits(), and their names in the tables and figures
SCHEMES = ("kfold", "lofo", "loso")
SCHEME_NAMES = {"kfold": "stratified k-fold", "lofo": "leave one friction out",
                "loso": "leave one sensor out"}


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
    lofo and loso: LeaveOneGroupOut on `groups` (the friction names, or the sensors of a
    dataset whose spec varies its sensor: seed 001's participants)."""
    from sklearn.model_selection import KFold, LeaveOneGroupOut, StratifiedKFold
    if scheme == "kfold":
        counts = np.bincount(y)
        counts = counts[counts > 0]
        if counts.min() >= folds:
            cv = StratifiedKFold(n_splits=folds, shuffle=True, random_state=seed)
            return list(cv.split(np.zeros(len(y)), y))
        return list(KFold(n_splits=folds, shuffle=True, random_state=seed).split(y))
    if scheme in ("lofo", "loso"):
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
