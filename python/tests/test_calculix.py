"""The CalculiX cross-check's own pieces (scripts/crosscheck-calculix): the quadratic tet's
shape functions and their inverse, the turn into the sector, and the presses' spec."""

import math
import os
import subprocess

import numpy as np

from chromasim import calculix, presses

CORNERS = np.array([[0.0, 0, 0], [2, 0, 0], [0, 3, 0], [0, 0, 1.5]])
EDGES = [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]  # CalculiX's C3D10 midside order


def curved_tet():
    """A 10-node tet whose midside nodes are bent off their edges' midpoints."""
    mids = [(CORNERS[i] + CORNERS[j]) / 2 + 0.1 * np.array([math.sin(k), math.cos(k), 0.3])
            for k, (i, j) in enumerate(EDGES)]
    return np.vstack([CORNERS, mids])


def test_shape_functions_interpolate_nodes_and_sum_to_one():
    for node in range(10):
        L = np.zeros(4)
        if node < 4:
            L[node] = 1
        else:
            i, j = EDGES[node - 4]
            L[i] = L[j] = 0.5
        N = calculix.shape10(L)
        assert abs(N.sum() - 1) < 1e-15
        assert np.allclose(N, np.eye(10)[node], atol=1e-15)


def test_derivatives_match_finite_differences():
    L = np.array([0.1, 0.2, 0.3, 0.4])
    D = calculix.dshape10(L)
    for k in range(4):
        e = np.zeros(4)
        e[k] = 1e-6
        fd = (calculix.shape10(L + e) - calculix.shape10(L - e)) / 2e-6
        assert np.allclose(D[:, k], fd, atol=1e-8)


def test_natural_coordinates_invert_the_curved_map():
    Xe = curved_tet()
    rng = np.random.default_rng(1)
    for _ in range(20):
        L = rng.dirichlet(np.ones(4))
        p = Xe.T @ calculix.shape10(L)
        guess = np.array([0.25, 0.25, 0.25, 0.25])
        assert np.allclose(calculix.natural_coordinates(Xe, p, guess), L, atol=1e-10)


def test_points_turn_onto_the_sector_mid_plane():
    pts = np.array([[1.0, 2.0, 3.0], [-4.0, 0.5, 1.0], [0.3, -7.0, 2.0]])
    inside, turn = calculix.into_sector(pts, 30.0)
    assert np.allclose(np.arctan2(inside[:, 1], inside[:, 0]), math.radians(15))
    assert np.allclose(np.hypot(inside[:, 0], inside[:, 1]), np.hypot(pts[:, 0], pts[:, 1]))
    assert np.allclose(inside[:, 2], pts[:, 2])
    back = np.column_stack([np.cos(turn) * inside[:, 0] - np.sin(turn) * inside[:, 1],
                            np.sin(turn) * inside[:, 0] + np.cos(turn) * inside[:, 1]])
    assert np.allclose(back, pts[:, :2])


def test_press_spec_validates(tmp_path):
    exe = os.environ.get("CHROMASIM_EXE", "build/release/chromasim")
    spec = tmp_path / "press.yaml"
    spec.write_text(
        presses.press_spec("sphere", "very_coarse", "neo_hookean", [0.5, 3.2], order=2))
    run = subprocess.run([exe, "validate", str(spec)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert "ok (2 trials" in run.stdout
