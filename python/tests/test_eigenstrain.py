"""chromasim.eigenstrain: the SVD against exact identities, classes, classifiers, the CLI."""

import csv
import os

import matplotlib.image as mpimg
import numpy as np
import pytest

from chromasim import eigenstrain as E


@pytest.fixture(scope="module")
def strain_set(sliding):
    return E.load_strain_set(sliding)


def test_svd_by_hand():
    # X = 3 a f^T + 1 b g^T with orthonormal a, b (frames) and f, g (grid points):
    # sigma = (3, 1); one basis leaves a residual of Frobenius norm 1.
    a, b = np.array([1.0, 1.0, 0.0]) / np.sqrt(2), np.array([1.0, -1.0, 0.0]) / np.sqrt(2)
    f, g = np.eye(4)[0], np.eye(4)[2]
    X = 3 * np.outer(a, f) + np.outer(b, g)
    for method in ("numpy", "gram"):
        es = E.eigenstrains(X, 2, method)
        np.testing.assert_allclose(es.sigma, [3.0, 1.0], rtol=1e-12)
        np.testing.assert_allclose(np.abs(es.bases[0]), f, atol=1e-12)
        np.testing.assert_allclose(np.linalg.norm(X - es.reconstruct(1)), 1.0, rtol=1e-12)
        np.testing.assert_allclose(es.reconstruct(2), X, atol=1e-12)
        np.testing.assert_allclose(es.energy_fraction(), [0.9, 0.1], rtol=1e-12)


def test_svd_reconstruction_of_the_strain_fields(strain_set):
    X = strain_set.fields
    es = E.eigenstrains(X, method="numpy")
    norm = np.linalg.norm(X)
    # all bases: the data back to rounding
    assert np.linalg.norm(X - es.reconstruct(len(es.sigma))) <= 1e-10 * norm
    # r bases: residual = sqrt(sum of the dropped sigma^2) (Eckart-Young), and it shrinks
    previous = np.inf
    for r in (1, 2, 6, 10):
        residual = np.linalg.norm(X - es.reconstruct(r))
        np.testing.assert_allclose(residual, np.sqrt(np.sum(es.sigma[r:] ** 2)), rtol=1e-8)
        assert residual < previous
        previous = residual
    # orthonormal bases and temporal vectors; recruitments = projections on the bases
    k = 10
    np.testing.assert_allclose(es.bases[:k] @ es.bases[:k].T, np.eye(k), atol=1e-10)
    np.testing.assert_allclose(es.v[:, :k].T @ es.v[:, :k], np.eye(k), atol=1e-10)
    np.testing.assert_allclose(es.project(X, k), es.recruitments(k), atol=1e-10 * es.sigma[0])
    np.testing.assert_allclose(es.energy_fraction().sum(), 1.0, rtol=1e-12)
    assert es.total_energy == pytest.approx(norm ** 2, rel=1e-12)
    assert (es.recruitments(k).sum(axis=0) >= 0).all()  # the sign convention


def test_gram_method_matches_numpy(strain_set):
    X = strain_set.fields
    ref = E.eigenstrains(X, 10, "numpy")
    gram = E.eigenstrains(X, 10, "gram")
    np.testing.assert_allclose(gram.sigma[:6], ref.sigma[:6], rtol=1e-9)
    np.testing.assert_allclose(gram.bases[:6], ref.bases[:6], atol=1e-6)
    np.testing.assert_allclose(gram.recruitments(6), ref.recruitments(6), atol=1e-7 * ref.sigma[0])
    assert gram.total_energy == pytest.approx(ref.total_energy, rel=1e-12)


def test_gamma_classes():
    g = np.array([0.0, 0.1, 0.49, 0.5, 0.95, 1.0])
    np.testing.assert_array_equal(E.gamma_classes(g, 2), [0, 0, 0, 1, 1, 1])
    np.testing.assert_array_equal(E.gamma_classes(g, 10), [0, 1, 4, 5, 9, 9])
    np.testing.assert_array_equal(E.gamma_classes(g, 3), [0, 0, 1, 1, 2, 2])
    with pytest.raises(ValueError):
        E.gamma_classes(g, 1)


def test_classifier_on_a_separable_case():
    # two classes far apart along the first feature, noise on the others: every fold right
    rng = np.random.default_rng(3)
    y = np.repeat([0, 1], 60)
    F = rng.normal(size=(120, 4))
    F[:, 0] += 8.0 * y
    folds = E.splits("kfold", y, np.zeros(120), 10, 0)
    res = E.cross_validate(F, y, folds, rs=[1, 4])
    assert res[1][0].min() == 1.0 and res[4][0].min() == 1.0
    # the same features with the labels shuffled: no better than a coin
    y_shuffled = rng.permutation(y)
    folds = E.splits("kfold", y_shuffled, np.zeros(120), 10, 0)
    res = E.cross_validate(F, y_shuffled, folds, rs=[4])
    assert res[4][0].mean() < 0.75


def test_leave_one_friction_out_splits(strain_set):
    y = E.gamma_classes(strain_set.gamma, 2)
    folds = E.splits("lofo", y, strain_set.friction, 10, 0)
    assert len(folds) == 7
    for train, test in folds:
        assert len(set(strain_set.friction[test])) == 1
        assert strain_set.friction[test][0] not in set(strain_set.friction[train])


def test_leave_one_sensor_out_splits_and_cli(datasets, tmp_path):
    s = E.load_strain_set(E.open_dataset(datasets["tiny_participants"]))
    assert sorted(set(s.sensor)) == [0, 1, 2]
    y = E.gamma_classes(s.gamma, 2)
    folds = E.splits("loso", y, s.sensor, 10, 0)
    assert len(folds) == 3
    for train, test in folds:
        assert len(set(s.sensor[test])) == 1
        assert s.sensor[test][0] not in set(s.sensor[train])
    out = tmp_path / "loso"
    assert E.main([datasets["tiny_participants"], "-o", str(out), "--schemes", "loso",
                   "--bases", "3", "--classes", "2", "--repeats", "1"]) == 0
    with open(out / "accuracy.csv") as f:
        rows = list(csv.DictReader(f))
    assert {r["scheme"] for r in rows} == {"loso"}
    assert {r["folds"] for r in rows} == {"3"}
    # a dataset that varies no sensor has one group, -1: loso skips it
    assert set(E.load_strain_set(E.open_dataset(datasets["tiny_sliding"])).sensor) == {-1}


def test_two_classes_on_the_tiny_slide(strain_set):
    # 21 slides: 8 % of the frames have Gamma >= 0.5; 6 bases must beat the majority class
    # and find most of the minority class (balanced accuracy)
    es = E.eigenstrains(strain_set.fields, 6)
    y = E.gamma_classes(strain_set.gamma, 2)
    chance = np.bincount(y).max() / len(y)
    folds = E.splits("kfold", y, strain_set.friction, 10, 0)
    acc, balanced = E.cross_validate(es.recruitments(6), y, folds, rs=[6])[6]
    assert acc.mean() > chance
    assert balanced.mean() > 0.9


def _read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_cli_writes_tables_and_figures(sliding, tmp_path, capsys):
    out = tmp_path / "eig"
    rc = E.main([sliding.root, "-o", str(out), "--bases", "4", "--classes", "2,3",
                 "--folds", "5", "--repeats", "1", "--keep", "12"])
    assert rc == 0
    acc = _read_csv(out / "accuracy.csv")
    # 2 schemes x 2 class counts x 4 r
    assert len(acc) == 16
    assert {(a["scheme"], a["classes"]) for a in acc} == {
        (s, k) for s in ("kfold", "lofo") for k in ("2", "3")}
    assert all(0.0 <= float(a["accuracy_mean"]) <= 1.0 for a in acc)
    assert {a["folds"] for a in acc if a["scheme"] == "lofo"} == {"7"}
    timing = _read_csv(out / "timing.csv")
    assert [t["r"] for t in timing] == ["1", "2", "3", "4", "full"]
    assert all(float(t["predict_s_per_frame"]) > 0 for t in timing)
    sv = _read_csv(out / "singular_values.csv")
    assert len(sv) == 12
    sigma = [float(r["sigma"]) for r in sv]
    assert sigma == sorted(sigma, reverse=True)
    rec = _read_csv(out / "recruitments.csv")
    assert len(rec) == sliding.frames and "r4" in rec[0]
    with np.load(out / "bases.npz") as z:
        assert z["bases"].shape == (4, 76, 101)
    for stem in ("fig4a_bases", "fig4a_recruitments", "fig4b_accuracy_vs_bases",
                 "fig4c_time_ratio", "fig4d_accuracy_vs_classes",
                 "accuracy_vs_bases_by_classes", "singular_values"):
        for ext in ("png", "svg"):
            path = out / f"{stem}.{ext}"
            assert path.is_file() and path.stat().st_size > 1000, path
        img = mpimg.imread(out / f"{stem}.png")
        assert img.ndim == 3 and img.shape[0] > 100 and img.shape[1] > 100
        assert img[..., :3].std() > 0.01  # not a blank canvas
    printed = capsys.readouterr().out
    assert "stratified k-fold" in printed and "leave one friction out" in printed


def test_cli_errors_name_the_dataset(quickstart, tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        E.main([str(tmp_path / "nowhere"), "-o", str(tmp_path / "o")])
    assert "nowhere" in str(e.value) and "not a folder" in str(e.value)
    with pytest.raises(SystemExit) as e:  # quickstart has images and markers, no strain
        E.main([quickstart.root, "-o", str(tmp_path / "o")])
    assert quickstart.root in str(e.value) and "no strain files" in str(e.value)
    with pytest.raises(SystemExit):
        E.main([quickstart.root, "-o", str(tmp_path / "o"), "--classes", "1-3"])
    assert not os.path.exists(tmp_path / "o" / "accuracy.csv")


def test_cli_bases_per_training_fold(sliding, tmp_path):
    out = tmp_path / "fold"
    assert E.main([sliding.root, "-o", str(out), "--bases", "3", "--classes", "2",
                   "--schemes", "lofo", "--fold-svd", "--full-field", "none", "--no-figures",
                   "--repeats", "1"]) == 0
    acc = _read_csv(out / "accuracy.csv")
    assert [a["r"] for a in acc] == ["1", "2", "3"]
    assert {a["bases_from"] for a in acc} == {"training fold"}
    assert all(float(a["balanced_accuracy_mean"]) > 0.5 for a in acc)
    assert [t["r"] for t in _read_csv(out / "timing.csv")] == ["1", "2", "3"]
    assert not list(out.glob("*.png"))
