"""The Cycles cross-check's comparison (scripts/crosscheck-cycles) on images with known
answers: the fisheye's polar angles, the ring annuli, the coating mask, the exposure scale,
and the ratios and changes it reports."""

import numpy as np

from chromasim import cycles_compare as cc

SIZE = 64
HALF_FOV = 84.0


def test_polar_angle_is_equidistant_and_nan_outside_the_circle():
    theta = cc.polar_angle_deg((SIZE, SIZE), HALF_FOV)
    assert theta[SIZE // 2, SIZE // 2] < HALF_FOV / SIZE * 1.5  # the pixel beside the centre
    # A pixel centre at about half the circle's radius: its distance times the field.
    expected = HALF_FOV * np.hypot(SIZE // 4 + 0.5, 0.5) / (SIZE / 2)
    assert abs(theta[SIZE // 2, SIZE // 2 + SIZE // 4] - expected) < 1e-9
    assert np.isnan(theta[0, 0])
    assert np.isfinite(theta[SIZE // 2, SIZE - 1])  # the edge pixel's centre is inside


def test_ring_annuli_are_disjoint_and_cover_the_rings():
    theta = cc.polar_angle_deg((SIZE, SIZE), HALF_FOV)
    masks = cc.ring_masks(theta)
    assert len(masks) == cc.RINGS
    total = np.zeros(theta.shape, int)
    for m in masks:
        total += m
    assert total.max() == 1
    inside = np.isfinite(theta) & (theta < (cc.RINGS - 0.5) * cc.RING_STEP_DEG)
    assert (total[inside] == 1).all()


def test_coating_mask_leaves_out_markers_and_their_border():
    theta = cc.polar_angle_deg((SIZE, SIZE), HALF_FOV)
    ids = -np.ones((SIZE, SIZE), int)
    ids[30:34, 30:34] = 0  # the apex marker
    mask = cc.coating_mask(theta, ids)
    assert not mask[29:35, 29:35].any()
    assert mask[27, 32] and mask[32, 36]
    assert not mask[0:4, :].any()  # beyond 30 deg of polar angle


def test_one_exposure_scale_and_the_ratios_and_changes_it_reports():
    rng = np.random.default_rng(1)
    theta = cc.polar_angle_deg((SIZE, SIZE), HALF_FOV)
    rest = 0.2 + rng.random((SIZE, SIZE, 3))
    mask = np.isfinite(theta) & (theta < cc.NORMALISE_DEG)
    assert abs(cc.exposure_scale(rest, rest / 3.0, mask) - 3.0) < 1e-12
    same = cc.compare(rest, rest.copy(), theta)
    assert abs(same["circle"]["sum"] - 1.0) < 1e-12
    assert all(abs(r["sum"] - 1.0) < 1e-12 for r in same["rings"])
    brighter = rest.copy()
    brighter[cc.ring_masks(theta)[2]] *= 1.05  # one ring 5 % brighter
    r = cc.compare(rest, brighter, theta)
    assert abs(r["rings"][2]["sum"] - 1.05) < 1e-9
    assert abs(r["rings"][1]["sum"] - 1.0) < 1e-12
    assert abs(cc.change(rest, 1.02 * rest, theta) - 0.02) < 1e-12


def test_relative_errors_follow_the_pixel_variances():
    theta = cc.polar_angle_deg((SIZE, SIZE), HALF_FOV)
    image = np.ones((SIZE, SIZE, 3))
    variance = np.full((SIZE, SIZE, 3), 0.04)  # each channel's mean: standard error 0.2
    e = cc.relative_errors(image, variance, theta)
    inside = np.isfinite(theta).sum()
    assert abs(e["circle"] - 0.2 / np.sqrt(3 * inside)) < 1e-12
    ring = cc.ring_masks(theta)[3].sum()
    assert abs(e["rings"][3] - 0.2 / np.sqrt(3 * ring)) < 1e-12
