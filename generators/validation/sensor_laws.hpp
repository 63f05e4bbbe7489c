#pragma once
/// The ChromaTouch cues measured from an 8-bit image as the papers do (docs/SENSOR.md): a
/// marker is a blob of pixels whose HSV saturation exceeds 50 %; its mean hue encodes the
/// normal displacement, its pixel count the apparent size, its centroid the lateral
/// displacement. Pure functions on images and numbers, for `chromasim verify sensor`.
#include "generators/io/image_io.hpp"

#include <Eigen/Core>

#include <array>
#include <vector>

namespace chromasim::generators {

struct Hsv {
    double hue_deg = 0;    ///< [0, 360); 0 for a grey pixel
    double saturation = 0; ///< (max - min) / max of the 8-bit channels, [0, 1]
    double value = 0;      ///< max / 255
};
Hsv rgb_to_hsv(std::uint8_t r, std::uint8_t g, std::uint8_t b);

/// One connected group of saturated pixels.
struct Blob {
    int pixels = 0;
    Eigen::Vector2d centroid_px = Eigen::Vector2d::Zero(); ///< mean of its pixel centres
    double mean_hue_deg = 0;                  ///< circular mean of its pixels' hue, [0, 360)
    std::array<double, 3> mean_srgb{0, 0, 0}; ///< mean 8-bit colour / 255
};

/// The blobs of `image` (3 or more channels, the first three RGB): 8-connected groups of
/// pixels with saturation above `saturation_min`, those of at least `min_pixels`. With
/// `labels`, also each pixel's blob index (-1: none), row-major.
std::vector<Blob> find_blobs(const Image8& image, double saturation_min, int min_pixels,
                             std::vector<int>* labels = nullptr);

/// Least-squares line y = slope x + intercept; r2 = 1 - SS_res / SS_tot (NaN when y does not
/// vary or fewer than 3 points).
struct LineFit {
    double slope = 0, intercept = 0, r2 = 0;
    int points = 0;
};
LineFit fit_line(const std::vector<double>& x, const std::vector<double>& y);

/// h - h0 wrapped to (-180, 180] degrees.
double hue_difference_deg(double h_deg, double h0_deg);

/// CIE 1976 colour difference of two sRGB colours in [0, 1] (D65 white); about 2.3 is a just
/// noticeable difference, above 10 two colours read as different.
double delta_e76(const std::array<double, 3>& srgb_a, const std::array<double, 3>& srgb_b);

/// The p-th percentile (p in [0, 100], linear interpolation) of the finite values; NaN if none.
double percentile(std::vector<double> values, double p);

} // namespace chromasim::generators
