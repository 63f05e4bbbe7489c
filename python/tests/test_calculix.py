"""The CalculiX cross-check's own pieces (scripts/crosscheck-calculix): the quadratic tet's
shape functions and their inverse, the turn into the sector, and the presses' spec."""

import math
import os
import subprocess

import numpy as np
import pytest

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


def test_face_rule_derivatives_match_finite_differences():
    N, Ns, Nt, w = calculix.face_rule(4)
    h = 1e-6
    grid = 4
    # The rule's points, recovered from N's linear part: s = N1 + (N3 + N4) / 2.
    s = N[:, 1] + 0.5 * (N[:, 3] + N[:, 4])
    t = N[:, 2] + 0.5 * (N[:, 4] + N[:, 5])

    def shape(s, t):
        l1 = 1 - s - t
        return np.stack([l1 * (2 * l1 - 1), s * (2 * s - 1), t * (2 * t - 1), 4 * l1 * s,
                         4 * s * t, 4 * t * l1], -1)

    assert np.allclose(shape(s, t), N, atol=1e-14)
    assert np.allclose((shape(s + h, t) - shape(s - h, t)) / (2 * h), Ns, atol=1e-8)
    assert np.allclose((shape(s, t + h) - shape(s, t - h)) / (2 * h), Nt, atol=1e-8)
    assert len(s) == grid * grid and abs(w * len(s) - 0.5) < 1e-15


def spherical_cap_faces(R, max_polar_deg=40.0, rings=12, sectors=24):
    """6-node faces tiling a cap of the sphere of radius R about +z, every node on the sphere."""
    def on_sphere(polar, azimuth):
        return R * np.array([math.sin(polar) * math.cos(azimuth),
                             math.sin(polar) * math.sin(azimuth), math.cos(polar)])
    nodes, index = [], {}

    def node(p):
        key = tuple(np.round(p, 9))
        if key not in index:
            index[key] = len(nodes)
            nodes.append(p)
        return index[key]

    def mid(a, b):  # the edge node: the chord's midpoint pushed onto the sphere
        m = (nodes[a] + nodes[b]) / 2
        return node(R * m / np.linalg.norm(m))

    top = math.radians(max_polar_deg)
    faces = []
    for i in range(rings):
        p0, p1 = top * i / rings, top * (i + 1) / rings
        for k in range(sectors):
            a0, a1 = 2 * math.pi * k / sectors, 2 * math.pi * (k + 1) / sectors
            c = [node(on_sphere(p0, a0)), node(on_sphere(p1, a0)), node(on_sphere(p1, a1)),
                 node(on_sphere(p0, a1))]
            for tri in ((c[0], c[1], c[2]), (c[0], c[2], c[3])):
                if len(set(tri)) == 3:
                    faces.append([*tri, mid(tri[0], tri[1]), mid(tri[1], tri[2]),
                                  mid(tri[2], tri[0])])
    return np.array(nodes), np.array(faces)


def test_contact_area_of_a_flat_on_the_undeformed_dome_is_the_cap():
    # A flat lowered by d onto the dome, nothing deformed: the overlap is the spherical cap of
    # height d, 2 pi R d (Archimedes).
    X, faces = spherical_cap_faces(calculix.R_OUT)
    case = calculix.Case(object="flat", wedge_deg=360.0)
    depths = [0.5, 1.0, 2.0]
    areas = calculix.contact_areas(case, X, faces, [np.zeros_like(X)] * 3, depths)
    for d, a in zip(depths, areas):
        assert a == pytest.approx(2 * math.pi * calculix.R_OUT * d, rel=0.01)
    # A displacement that lifts every node by 0.25 mm is the same as a deeper flat.
    lifted = np.zeros_like(X)
    lifted[:, 2] = 0.25
    assert calculix.contact_areas(case, X, faces, [lifted], [0.75])[0] == pytest.approx(areas[1], rel=1e-12)
