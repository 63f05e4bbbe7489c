"""chromasim's path-traced image against Blender Cycles' render of the same exported scene
(scripts/crosscheck-cycles): means over the image circle and over the rings of markers, after
one exposure scale that matches the two rest images on the coating near the apex.

Images are (H, W, 3) float arrays of linear RGB, the equidistant fisheye's circle of radius
min(H, W) / 2 about the image centre spanning `half_fov_deg` of polar angle.
"""

import numpy as np

RING_STEP_DEG = 12.5  # the marker rings' polar spacing (docs/SENSOR.md)
RINGS = 6  # the apex and five rings
NORMALISE_DEG = 30.0  # coating pixels within this of the apex set the exposure scale


def polar_angle_deg(shape, half_fov_deg):
    """Polar angle of each pixel centre's ray (deg); NaN outside the image circle."""
    h, w = shape[:2]
    y, x = np.mgrid[0:h, 0:w] + 0.5
    r = np.hypot(x - w / 2, y - h / 2) / (min(h, w) / 2)
    theta = r * half_fov_deg
    theta[r >= 1.0] = np.nan
    return theta


def ring_masks(theta):
    """Annuli of RING_STEP_DEG about each marker ring's polar angle (the apex: a disc)."""
    masks = []
    for k in range(RINGS):
        lo = max(0.0, (k - 0.5) * RING_STEP_DEG)
        hi = (k + 0.5) * RING_STEP_DEG
        masks.append((theta >= lo) & (theta < hi))
    return masks


def coating_mask(theta, marker_ids, grow_px=1):
    """Pixels within NORMALISE_DEG of the apex that show no marker (marker_ids: (H, W) ints,
    -1 for none), `grow_px` away from any marker pixel."""
    marker = marker_ids >= 0
    grown = marker.copy()
    for dy in range(-grow_px, grow_px + 1):
        for dx in range(-grow_px, grow_px + 1):
            grown |= np.roll(np.roll(marker, dy, axis=0), dx, axis=1)
    return (theta < NORMALISE_DEG) & ~grown


def exposure_scale(chromasim_rest, cycles_rest, mask):
    """The one factor that maps Cycles' rest image onto chromasim's on `mask` (sum of RGB)."""
    return chromasim_rest[mask].sum() / cycles_rest[mask].sum()


def means(image, theta):
    """Mean RGB over the image circle and over each ring annulus."""
    inside = np.isfinite(theta)
    return {"circle": image[inside].mean(axis=0),
            "rings": [image[m].mean(axis=0) for m in ring_masks(theta)]}


def compare(chromasim, cycles, theta):
    """Cycles over chromasim, per channel and for the sum of channels, over the circle and
    each ring (both images already on one exposure)."""
    a, b = means(chromasim, theta), means(cycles, theta)

    def ratio(x, y):
        return {"rgb": (y / x).tolist(), "sum": float(y.sum() / x.sum())}

    return {"circle": ratio(a["circle"], b["circle"]),
            "rings": [ratio(x, y) for x, y in zip(a["rings"], b["rings"])],
            "chromasim_circle_mean": a["circle"].tolist(),
            "cycles_circle_mean": b["circle"].tolist()}


def relative_errors(image, variance, theta):
    """Standard error of the sum-of-RGB mean over the circle and each ring, relative to that
    mean, from the per-pixel variance of the mean (chromasim's variance channels; channels and
    pixels taken as independent)."""
    inside = np.isfinite(theta)

    def error(mask):
        return float(np.sqrt(variance[mask].sum()) / image[mask].sum())

    return {"circle": error(inside), "rings": [error(m) for m in ring_masks(theta)]}


def change(rest, pressed, theta):
    """Relative change of the circle mean (sum of channels) from rest to pressed."""
    inside = np.isfinite(theta)
    return float(pressed[inside].sum() / rest[inside].sum() - 1.0)
