#include "render/shadow_filter.hpp"

#include "render/scene_data.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

namespace chromasim::render::detail {

void shadow_filter(int width, int height, std::span<float> rgb, std::span<const float> lit,
                   std::span<const float> shadowed, double sigma_px) {
    const std::size_t pixels = std::size_t(std::max(width, 0)) * std::size_t(std::max(height, 0));
    if (width < 1 || height < 1 || rgb.size() != 3 * pixels || lit.size() != 3 * pixels ||
        shadowed.size() != 3 * pixels) {
        throw std::invalid_argument(
            "shadow_filter: a " + std::to_string(width) + " x " + std::to_string(height) +
            " image with " + std::to_string(rgb.size()) + ", " + std::to_string(lit.size()) +
            " and " + std::to_string(shadowed.size()) +
            " values; allowed: width, height >= 1 and 3 values a pixel in each");
    }
    if (!(sigma_px > 0.0 && sigma_px <= kMaxShadowFilterPx)) {
        throw std::invalid_argument(
            "shadow_filter: sigma = " + std::to_string(sigma_px) +
            " px; allowed: 0 < sigma <= " + std::to_string(kMaxShadowFilterPx));
    }
    const int radius = int(std::ceil(3.0 * sigma_px));
    std::vector<double> w(std::size_t(radius) + 1);
    for (int d = 0; d <= radius; ++d)
        w[std::size_t(d)] = std::exp(-0.5 * d * d / (sigma_px * sigma_px));
    // One separable pass along x (step (1, 0)) or y (step (0, 1)): around each pixel p, the
    // weighted sums of value(q, c) for U (c < 3) and S (c >= 3), handed to done(p, sums);
    // pixels off the image count for nothing. Each sum in a fixed order, so threads do not
    // change it.
    const auto at = [width](int x, int y) { return std::size_t(y) * std::size_t(width) + x; };
    const auto pass = [&](auto&& value, int dx, int dy, auto&& done) {
        tbb::parallel_for(0, height, [&](int y) {
            for (int x = 0; x < width; ++x) {
                double sum[6] = {};
                for (int d = -radius; d <= radius; ++d) {
                    const int qx = x + d * dx, qy = y + d * dy;
                    if (qx < 0 || qx >= width || qy < 0 || qy >= height) continue;
                    const double wd = w[std::size_t(std::abs(d))];
                    const std::size_t q = at(qx, qy);
                    for (int c = 0; c < 6; ++c)
                        sum[c] += wd * value(q, c);
                }
                done(at(x, y), sum);
            }
        });
    };
    // Along the rows, into [pixel * 6 + c] (floats: 24 bytes a pixel, 19 MB at 896 px).
    std::vector<float> rows(6 * pixels);
    pass([&](std::size_t q, int c) { return c < 3 ? lit[3 * q + c] : shadowed[3 * q + c - 3]; }, 1,
         0,
         [&](std::size_t p, const double* sum) {
             for (int c = 0; c < 6; ++c)
                 rows[6 * p + c] = float(sum[c]);
         });
    // Along the columns, then A + U R in place of A + S.
    pass([&](std::size_t q, int c) { return rows[6 * q + c]; }, 0, 1,
         [&](std::size_t p, const double* sum) {
             for (std::size_t c = 0; c < 3; ++c) {
                 if (!(sum[c] > 0.0)) continue;
                 const std::size_t i = 3 * p + c;
                 rgb[i] = float(double(rgb[i]) - shadowed[i] + lit[i] * (sum[3 + c] / sum[c]));
             }
         });
}

} // namespace chromasim::render::detail
