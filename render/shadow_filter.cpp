#include "render/shadow_filter.hpp"

#include "render/scene_data.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace chromasim::render::detail {

namespace {

/// Rows per band (bands): a band's buffer holds 6 floats a group and pixel of its rows and the
/// reach above and below: 7.2 MB at 896 px with 8 groups and 1.5 px.
constexpr int kBandRows = 32;

/// The filter for G groups (a constant, so the sums' loops vectorise): bands of rows in
/// parallel, each summed along x into a buffer of its own (plus the reach above and below),
/// then along y. The sums in floats (7 to 49 terms each), each in a fixed order whatever the
/// band, so the bytes do not depend on the threads.
/// The rim pixels' weights (filter()): (2 radius + 1)^2 of them, row by row, empty without
/// rims.
template <int G>
void bands(int width, int height, int radius, const std::vector<float>& w, std::span<float> rgb,
           std::span<const float> lit, std::span<const float> chosen,
           std::span<const float> shadowed, std::span<const std::uint8_t> rims,
           const std::vector<float>& rim_w) {
    constexpr int per = 3 * G, values = 2 * per; // C_g's (g, c), then S_g's
    const auto at = [width](int x, int y) { return std::size_t(y) * std::size_t(width) + x; };
    // The first and last pixel of row y where a or b holds a value other than zero (first >
    // last: none).
    const auto lit_span = [&](std::span<const float> a, std::span<const float> b, int y) {
        const auto any = [&](int x) {
            const float* pa = a.data() + per * at(x, y);
            const float* pb = b.data() + per * at(x, y);
            for (int v = 0; v < per; ++v)
                if (pa[v] != 0.0f || pb[v] != 0.0f) return true;
            return false;
        };
        int first = 0, last = width - 1;
        while (first < width && !any(first))
            ++first;
        while (last >= first && !any(last))
            --last;
        return std::pair<int, int>{first, last};
    };
    const int count = (height + kBandRows - 1) / kBandRows;
    tbb::parallel_for(tbb::blocked_range<int>(0, count), [&](const auto& range) {
        // Kept by each thread from image to image: no allocation (and no page faults) per band.
        thread_local std::vector<float> rows;
        for (int band = range.begin(); band != range.end(); ++band) {
            const int y0 = band * kBandRows, y1 = std::min(height, y0 + kBandRows);
            const int ya = std::max(0, y0 - radius), yb = std::min(height, y1 + radius);
            rows.resize(std::size_t(yb - ya) * std::size_t(width) * values);
            for (int y = ya; y < yb; ++y) {
                // Only where a pixel within reach has light: outside the image circle the
                // rows hold zeros (about a fifth of a fisheye image).
                const auto [first, last] = lit_span(chosen, shadowed, y);
                const int from = std::max(0, first - radius), to = std::min(width, last + radius + 1);
                float* row = rows.data() + std::size_t(y - ya) * width * values;
                std::fill(row, row + std::size_t(std::max(from, 0)) * values, 0.0f);
                std::fill(row + std::size_t(std::max(to, from)) * values,
                          row + std::size_t(width) * values, 0.0f);
                for (int x = from; x < to; ++x) {
                    float sum[values] = {};
                    const int lo = std::max(0, x - radius), hi = std::min(width - 1, x + radius);
                    for (int qx = lo; qx <= hi; ++qx) {
                        const float wd = w[std::size_t(std::abs(qx - x))];
                        const float* c = chosen.data() + per * at(qx, y);
                        const float* s = shadowed.data() + per * at(qx, y);
                        for (int v = 0; v < per; ++v) {
                            sum[v] += wd * c[v];
                            sum[per + v] += wd * s[v];
                        }
                    }
                    float* out = rows.data() + (std::size_t(y - ya) * width + x) * values;
                    for (int v = 0; v < values; ++v)
                        out[v] = sum[v];
                }
            }
            for (int y = y0; y < y1; ++y) {
                const int lo = std::max(0, y - radius), hi = std::min(height - 1, y + radius);
                // A pixel whose own direct light is zero, lit and shadowed, keeps its value.
                const auto [first, last] = lit_span(lit, shadowed, y);
                for (int x = first; x <= last; ++x) {
                    float sum[values] = {};
                    for (int qy = lo; qy <= hi; ++qy) {
                        const float wd = w[std::size_t(std::abs(qy - y))];
                        const float* r = rows.data() + (std::size_t(qy - ya) * width + x) * values;
                        for (int v = 0; v < values; ++v)
                            sum[v] += wd * r[v];
                    }
                    const std::size_t p = at(x, y);
                    if (!rims.empty() && rims[p]) {
                        // A rim: the same window, the 2-D Gaussian of its own sigma.
                        std::fill(sum, sum + values, 0.0f);
                        const int xl = std::max(0, x - radius),
                                  xh = std::min(width - 1, x + radius);
                        const int side = 2 * radius + 1;
                        for (int qy = lo; qy <= hi; ++qy) {
                            const float* wr =
                                rim_w.data() + std::size_t(qy - y + radius) * std::size_t(side);
                            for (int qx = xl; qx <= xh; ++qx) {
                                const float wd = wr[qx - x + radius];
                                if (wd == 0.0f) continue;
                                const float* cq = chosen.data() + per * at(qx, qy);
                                const float* sq = shadowed.data() + per * at(qx, qy);
                                for (int v = 0; v < per; ++v) {
                                    sum[v] += wd * cq[v];
                                    sum[per + v] += wd * sq[v];
                                }
                            }
                        }
                    }
                    for (int c = 0; c < 3; ++c) {
                        // All groups' ratio, for a group without shadow rays near.
                        float all_c = 0.0f, all_s = 0.0f;
                        for (int g = 0; g < G; ++g)
                            all_c += sum[3 * g + c], all_s += sum[per + 3 * g + c];
                        const std::size_t i = 3 * p + std::size_t(c);
                        double value = rgb[i];
                        bool changed = false;
                        for (int g = 0; g < G; ++g) {
                            const float cg = sum[3 * g + c], sg = sum[per + 3 * g + c];
                            const std::size_t j = per * p + std::size_t(3 * g + c);
                            if (cg > 0.0f)
                                value += lit[j] * double(sg / cg) - shadowed[j];
                            else if (all_c > 0.0f)
                                value += lit[j] * double(all_s / all_c) - shadowed[j];
                            else
                                continue;
                            changed = true;
                        }
                        if (changed) rgb[i] = float(value);
                    }
                }
            }
        }
    });
}

/// Both overloads (one group: `chosen` is `lit`).
void filter(int width, int height, int groups, std::span<float> rgb, std::span<const float> lit,
            std::span<const float> chosen, std::span<const float> shadowed, double sigma_px,
            std::span<const std::uint8_t> rims, double rim_sigma_px) {
    const std::size_t pixels = std::size_t(std::max(width, 0)) * std::size_t(std::max(height, 0));
    const std::size_t per = 3 * std::size_t(std::clamp(groups, 0, kMaxShadowGroups));
    if (width < 1 || height < 1 || groups < 1 || groups > kMaxShadowGroups ||
        rgb.size() != 3 * pixels || lit.size() != per * pixels || chosen.size() != per * pixels ||
        shadowed.size() != per * pixels) {
        throw std::invalid_argument(
            "shadow_filter: a " + std::to_string(width) + " x " + std::to_string(height) +
            " image in " + std::to_string(groups) + " groups with " + std::to_string(rgb.size()) +
            " values, and " + std::to_string(lit.size()) + ", " + std::to_string(chosen.size()) +
            " and " + std::to_string(shadowed.size()) +
            " values of the direct light; allowed: width, height >= 1, 1 to " +
            std::to_string(kMaxShadowGroups) +
            " groups, 3 values a pixel in the image and 3 a group and pixel in the others");
    }
    if (!(sigma_px > 0.0 && sigma_px <= kMaxShadowFilterPx)) {
        throw std::invalid_argument(
            "shadow_filter: sigma = " + std::to_string(sigma_px) +
            " px; allowed: 0 < sigma <= " + std::to_string(kMaxShadowFilterPx));
    }
    if (!rims.empty() && rims.size() != pixels) {
        throw std::invalid_argument("shadow_filter: " + std::to_string(rims.size()) +
                                    " rim flags for " + std::to_string(pixels) +
                                    " pixels; allowed: none or one a pixel");
    }
    if (!(rim_sigma_px >= 0.0 && rim_sigma_px <= kMaxShadowFilterPx)) {
        throw std::invalid_argument(
            "shadow_filter: rim sigma = " + std::to_string(rim_sigma_px) +
            " px; allowed: 0 <= sigma <= " + std::to_string(kMaxShadowFilterPx));
    }
    // The window reaches 3 sigma of the wider of the two (the rims' only where they have one).
    const bool with_rims = std::find(rims.begin(), rims.end(), std::uint8_t(1)) != rims.end();
    const int radius =
        int(std::ceil(3.0 * (with_rims ? std::max(sigma_px, rim_sigma_px) : sigma_px)));
    std::vector<float> w(std::size_t(radius) + 1);
    for (int d = 0; d <= radius; ++d)
        w[std::size_t(d)] = float(std::exp(-0.5 * d * d / (sigma_px * sigma_px)));
    // The rims' 2-D weights: the Gaussian of their sigma (0: the pixel alone).
    std::vector<float> rim_w;
    if (with_rims) {
        const int side = 2 * radius + 1;
        rim_w.assign(std::size_t(side) * std::size_t(side), 0.0f);
        for (int dy = -radius; dy <= radius; ++dy)
            for (int dx = -radius; dx <= radius; ++dx) {
                const double d2 = double(dx * dx + dy * dy);
                rim_w[std::size_t(dy + radius) * std::size_t(side) + std::size_t(dx + radius)] =
                    rim_sigma_px > 0.0 ? float(std::exp(-0.5 * d2 / (rim_sigma_px * rim_sigma_px)))
                    : d2 == 0.0        ? 1.0f
                                       : 0.0f;
            }
    }
    // bands<1> .. bands<kMaxShadowGroups>, by the group count.
    using Kernel = void (*)(int, int, int, const std::vector<float>&, std::span<float>,
                            std::span<const float>, std::span<const float>, std::span<const float>,
                            std::span<const std::uint8_t>, const std::vector<float>&);
    static constexpr auto kernels = []<std::size_t... G>(std::index_sequence<G...>) {
        return std::array<Kernel, sizeof...(G)>{&bands<int(G) + 1>...};
    }
    (std::make_index_sequence<kMaxShadowGroups>{});
    kernels[std::size_t(groups - 1)](width, height, radius, w, rgb, lit, chosen, shadowed,
                                     with_rims ? rims : std::span<const std::uint8_t>{}, rim_w);
}

} // namespace

void shadow_filter(int width, int height, int groups, std::span<float> rgb,
                   std::span<const float> lit, std::span<const float> chosen,
                   std::span<const float> shadowed, double sigma_px,
                   std::span<const std::uint8_t> rims, double rim_sigma_px) {
    filter(width, height, groups, rgb, lit, chosen, shadowed, sigma_px, rims, rim_sigma_px);
}

void shadow_filter(int width, int height, std::span<float> rgb, std::span<const float> lit,
                   std::span<const float> shadowed, double sigma_px) {
    filter(width, height, 1, rgb, lit, lit, shadowed, sigma_px, {}, 0.0);
}

} // namespace chromasim::render::detail
