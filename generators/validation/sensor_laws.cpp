#include "generators/validation/sensor_laws.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace chromasim::generators {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

double srgb_decode(double c) {
    return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}

/// CIELAB of an sRGB colour (D65).
std::array<double, 3> lab(const std::array<double, 3>& srgb) {
    const double r = srgb_decode(srgb[0]), g = srgb_decode(srgb[1]), b = srgb_decode(srgb[2]);
    const double xyz[3] = {(0.4124 * r + 0.3576 * g + 0.1805 * b) / 0.95047,
                           0.2126 * r + 0.7152 * g + 0.0722 * b,
                           (0.0193 * r + 0.1192 * g + 0.9505 * b) / 1.08883};
    double f[3];
    for (int i = 0; i < 3; ++i)
        f[i] = xyz[i] > 216.0 / 24389.0 ? std::cbrt(xyz[i]) : (24389.0 / 27.0 * xyz[i] + 16) / 116;
    return {116 * f[1] - 16, 500 * (f[0] - f[1]), 200 * (f[1] - f[2])};
}

/// Per-blob sums while its pixels are gathered.
struct BlobSums {
    int pixels = 0;
    Eigen::Vector2d position = Eigen::Vector2d::Zero();
    double hue_cos = 0, hue_sin = 0;
    std::array<double, 3> srgb{0, 0, 0};
};

void add_pixel(BlobSums& s, const Image8& image, int x, int y) {
    const Hsv hsv = rgb_to_hsv(image.at(x, y, 0), image.at(x, y, 1), image.at(x, y, 2));
    const double a = hsv.hue_deg * std::numbers::pi / 180.0;
    ++s.pixels;
    s.position += Eigen::Vector2d(x + 0.5, y + 0.5);
    s.hue_cos += std::cos(a);
    s.hue_sin += std::sin(a);
    for (int c = 0; c < 3; ++c)
        s.srgb[std::size_t(c)] += image.at(x, y, c) / 255.0;
}

Blob finish(const BlobSums& s) {
    Blob b;
    b.pixels = s.pixels;
    b.centroid_px = s.position / s.pixels;
    b.mean_hue_deg = std::atan2(s.hue_sin, s.hue_cos) * 180.0 / std::numbers::pi;
    if (b.mean_hue_deg < 0) b.mean_hue_deg += 360.0;
    for (std::size_t c = 0; c < 3; ++c)
        b.mean_srgb[c] = s.srgb[c] / s.pixels;
    return b;
}

} // namespace

Hsv rgb_to_hsv(std::uint8_t r8, std::uint8_t g8, std::uint8_t b8) {
    const double r = r8 / 255.0, g = g8 / 255.0, b = b8 / 255.0;
    const double max = std::max({r, g, b}), min = std::min({r, g, b}), d = max - min;
    Hsv hsv;
    hsv.value = max;
    hsv.saturation = max > 0 ? d / max : 0.0;
    if (d <= 0) return hsv;
    double h = max == r   ? std::fmod((g - b) / d + 6.0, 6.0)
               : max == g ? (b - r) / d + 2.0
                          : (r - g) / d + 4.0;
    hsv.hue_deg = 60.0 * h;
    return hsv;
}

std::vector<Blob> find_blobs(const Image8& image, double saturation_min, int min_pixels,
                             std::vector<int>* labels) {
    const int w = image.width, h = image.height;
    std::vector<char> saturated(std::size_t(w) * h, 0);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            saturated[std::size_t(y) * w + x] =
                rgb_to_hsv(image.at(x, y, 0), image.at(x, y, 1), image.at(x, y, 2)).saturation >
                saturation_min;
    std::vector<int> label(saturated.size(), -1);
    std::vector<Blob> blobs;
    std::vector<std::size_t> stack, members;
    for (std::size_t start = 0; start < saturated.size(); ++start) {
        if (!saturated[start] || label[start] != -1) continue;
        BlobSums sums;
        members.clear();
        stack.assign(1, start);
        label[start] = -2; // queued
        while (!stack.empty()) {
            const std::size_t i = stack.back();
            stack.pop_back();
            members.push_back(i);
            const int x = int(i % std::size_t(w)), y = int(i / std::size_t(w));
            add_pixel(sums, image, x, y);
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx) {
                    const int nx = x + dx, ny = y + dy;
                    if (nx < 0 || ny < 0 || nx >= w || ny >= h) continue;
                    const std::size_t j = std::size_t(ny) * w + nx;
                    if (saturated[j] && label[j] == -1) {
                        label[j] = -2;
                        stack.push_back(j);
                    }
                }
        }
        const bool kept = sums.pixels >= min_pixels;
        for (std::size_t i : members)
            label[i] = kept ? int(blobs.size()) : -3;
        if (kept) blobs.push_back(finish(sums));
    }
    if (labels) {
        for (int& l : label)
            l = std::max(l, -1);
        *labels = std::move(label);
    }
    return blobs;
}

LineFit fit_line(const std::vector<double>& x, const std::vector<double>& y) {
    LineFit f;
    const std::size_t n = std::min(x.size(), y.size());
    f.points = int(n);
    if (n < 3) return {kNaN, kNaN, kNaN, int(n)};
    double mx = 0, my = 0;
    for (std::size_t i = 0; i < n; ++i) {
        mx += x[i];
        my += y[i];
    }
    mx /= double(n);
    my /= double(n);
    double sxx = 0, sxy = 0, syy = 0;
    for (std::size_t i = 0; i < n; ++i) {
        sxx += (x[i] - mx) * (x[i] - mx);
        sxy += (x[i] - mx) * (y[i] - my);
        syy += (y[i] - my) * (y[i] - my);
    }
    if (!(sxx > 0) || !(syy > 0)) return {kNaN, kNaN, kNaN, int(n)};
    f.slope = sxy / sxx;
    f.intercept = my - f.slope * mx;
    f.r2 = sxy * sxy / (sxx * syy); // = 1 - SS_res / SS_tot for a least-squares line
    return f;
}

double hue_difference_deg(double h, double h0) {
    double d = std::fmod(h - h0, 360.0);
    if (d <= -180.0) d += 360.0;
    if (d > 180.0) d -= 360.0;
    return d;
}

double delta_e76(const std::array<double, 3>& a, const std::array<double, 3>& b) {
    const auto la = lab(a), lb = lab(b);
    return std::hypot(la[0] - lb[0], la[1] - lb[1], la[2] - lb[2]);
}

double percentile(std::vector<double> values, double p) {
    std::erase_if(values, [](double v) { return !std::isfinite(v); });
    if (values.empty()) return kNaN;
    std::sort(values.begin(), values.end());
    const double at = std::clamp(p, 0.0, 100.0) / 100.0 * double(values.size() - 1);
    const std::size_t i = std::size_t(at);
    const double t = at - double(i);
    return i + 1 < values.size() ? values[i] * (1 - t) + values[i + 1] * t : values[i];
}

} // namespace chromasim::generators
