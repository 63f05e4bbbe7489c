// Tests of the shadow filter (render/shadow_filter.hpp): the ratio estimator keeps an image
// whose shadow fraction is uniform, blurs a step in it by the Gaussian's own sums, takes out
// most of the noise of the shadowed light, and refuses bad input.
#include "render/scene_data.hpp"
#include "render/shadow_filter.hpp"

#include <catch2/catch.hpp>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

using namespace chromasim::render;
using namespace chromasim::render::detail;

namespace {

/// A test image: the rest A, the unshadowed direct light U and the shadowed S, per value.
struct Parts {
    int width, height;
    std::vector<float> rest, lit, shadowed;
    std::vector<float> image() const {
        std::vector<float> rgb(rest.size());
        for (std::size_t i = 0; i < rgb.size(); ++i)
            rgb[i] = rest[i] + shadowed[i];
        return rgb;
    }
};

/// U varies smoothly over the image and by channel, A too; S = U r(x, y, c).
template <typename Fraction> Parts parts(int width, int height, Fraction fraction) {
    Parts p{width, height, {}, {}, {}};
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x)
            for (int c = 0; c < 3; ++c) {
                const float u = 0.3f + 0.01f * float(x) + 0.02f * float(y) + 0.1f * float(c);
                p.rest.push_back(0.2f + 0.005f * float(x + c));
                p.lit.push_back(u);
                p.shadowed.push_back(u * float(fraction(x, y, c)));
            }
    return p;
}

} // namespace

TEST_CASE("shadow filter: a shadow fraction the same everywhere keeps the image up to its edges",
          "[render][shadow_filter]") {
    for (const double sigma : {0.3, 1.0, 2.5}) {
        const Parts p = parts(13, 9, [](int, int, int c) { return 0.25 + 0.2 * c; });
        std::vector<float> rgb = p.image();
        const std::vector<float> before = rgb;
        shadow_filter(p.width, p.height, rgb, p.lit, p.shadowed, sigma);
        double worst = 0.0;
        for (std::size_t i = 0; i < rgb.size(); ++i)
            worst = std::max(worst, double(std::abs(rgb[i] - before[i])));
        INFO("sigma " << sigma);
        CHECK(worst < 2e-6);
    }
}

// The step shows along the row, whatever the unshadowed light.
TEST_CASE("shadow filter: a step in the shadow fraction comes out as the Gaussian's partial sums",
          "[render][shadow_filter]") {
    // r = 1 left of x = 8, 0.2 from there; U the same along each column, so the ratio along a
    // row is sum_{q < 8} w + 0.2 sum_{q >= 8} w over sum w, the weights over the row's
    // pixels within 3 sigma (the column sums cancel).
    const double sigma = 1.3;
    // U must not change along a column for the column sums to cancel: set per column.
    Parts q = parts(16, 7, [](int x, int, int) { return x < 8 ? 1.0 : 0.2; });
    for (int y = 0; y < q.height; ++y)
        for (int x = 0; x < q.width; ++x)
            for (int c = 0; c < 3; ++c) {
                const std::size_t i = 3 * (std::size_t(y) * q.width + x) + c;
                q.lit[i] = 0.4f + 0.03f * float(x) + 0.1f * float(c);
                q.shadowed[i] = q.lit[i] * (x < 8 ? 1.0f : 0.2f);
            }
    std::vector<float> rgb = q.image();
    shadow_filter(q.width, q.height, rgb, q.lit, q.shadowed, sigma);
    const int radius = int(std::ceil(3.0 * sigma));
    double worst = 0.0;
    for (int y = 0; y < q.height; ++y)
        for (int x = 0; x < q.width; ++x)
            for (int c = 0; c < 3; ++c) {
                double num = 0.0, den = 0.0;
                for (int d = -radius; d <= radius; ++d) {
                    const int xq = x + d;
                    if (xq < 0 || xq >= q.width) continue;
                    const std::size_t j = 3 * (std::size_t(y) * q.width + xq) + c;
                    const double w = std::exp(-0.5 * d * d / (sigma * sigma));
                    num += w * q.shadowed[j];
                    den += w * q.lit[j];
                }
                const std::size_t i = 3 * (std::size_t(y) * q.width + x) + c;
                const double expected = q.rest[i] + q.lit[i] * num / den;
                worst = std::max(worst, std::abs(rgb[i] - expected));
            }
    CHECK(worst < 2e-6);
    // Next to the step the light is neither side's: the blur is there.
    const std::size_t left = 3 * (3 * std::size_t(q.width) + 7), right = left + 3;
    CHECK(rgb[left] < q.rest[left] + 0.95f * q.lit[left]);
    CHECK(rgb[right] > q.rest[right] + 0.25f * q.lit[right]);
}

// The same bytes come out on 1 and 2 threads.
TEST_CASE("shadow filter: noise in the shadowed light falls by about the neighbourhood's effective "
          "count",
          "[render][shadow_filter]") {
    // Each pixel's S a binary shadow ray's estimate: U (with probability 0.7) or 0, so the
    // fraction is 0.7 everywhere with the noise of one shadow ray.
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> uniform(0.0, 1.0);
    const Parts p = parts(64, 48, [&](int, int, int) { return uniform(rng) < 0.7 ? 1.0 : 0.0; });
    const Parts truth = parts(64, 48, [](int, int, int) { return 0.7; });
    const auto rms = [&](const std::vector<float>& rgb) {
        const std::vector<float> exact = truth.image();
        double sum = 0.0;
        for (std::size_t i = 0; i < rgb.size(); ++i)
            sum += (double(rgb[i]) - exact[i]) * (double(rgb[i]) - exact[i]);
        return std::sqrt(sum / double(rgb.size()));
    };
    const std::vector<float> noisy = p.image();
    const double sigma = 1.5;
    std::vector<float> one = noisy, two = noisy;
    {
        tbb::global_control threads(tbb::global_control::max_allowed_parallelism, 1);
        shadow_filter(p.width, p.height, one, p.lit, p.shadowed, sigma);
    }
    {
        tbb::global_control threads(tbb::global_control::max_allowed_parallelism, 2);
        shadow_filter(p.width, p.height, two, p.lit, p.shadowed, sigma);
    }
    CHECK(one == two);
    // A Gaussian of sigma 1.5 px averages about 4 pi sigma^2 = 28 pixels: the noise's
    // standard deviation should fall about 5-fold; at least 3.5-fold.
    INFO("noise " << rms(noisy) << " -> " << rms(one));
    CHECK(rms(one) < rms(noisy) / 3.5);
    CHECK(rms(one) > rms(noisy) / 8.0); // and no more than averaging can give
}

TEST_CASE("shadow filter: a channel without unshadowed light is kept, bad sizes and widths "
          "are refused",
          "[render][shadow_filter]") {
    Parts p = parts(5, 4, [](int x, int, int) { return x % 2 ? 0.5 : 1.0; });
    for (std::size_t i = 2; i < p.lit.size(); i += 3)
        p.lit[i] = p.shadowed[i] = 0.0f; // blue: no direct light
    std::vector<float> rgb = p.image();
    const std::vector<float> before = rgb;
    shadow_filter(p.width, p.height, rgb, p.lit, p.shadowed, 1.0);
    for (std::size_t i = 2; i < rgb.size(); i += 3)
        CHECK(rgb[i] == before[i]);
    CHECK(rgb[0] != before[0]); // red is filtered
    CHECK_THROWS_WITH(shadow_filter(5, 4, rgb, std::vector<float>(3), p.shadowed, 1.0),
                      Catch::Contains("allowed: width, height >= 1, 1 to 8 groups, 3 values a "
                                      "pixel in the image and 3 a group and pixel"));
    for (const int groups : {0, kMaxShadowGroups + 1})
        CHECK_THROWS_WITH(shadow_filter(5, 4, groups, rgb, p.lit, p.lit, p.shadowed, 1.0),
                          Catch::Contains("1 to 8 groups"));
    for (const double bad : {0.0, -1.0, kMaxShadowFilterPx + 0.5, std::nan("")})
        CHECK_THROWS_WITH(shadow_filter(5, 4, rgb, p.lit, p.shadowed, bad),
                          Catch::Contains("allowed: 0 < sigma <= "));
}

// No noise where each group's fraction is uniform (the one-group ratio keeps that noise);
// a group without shadow rays near takes all groups' ratio.
TEST_CASE("shadow filter in groups of LEDs: the group each shadow ray went to adds no noise",
          "[render][shadow_filter]") {
    // Three groups of LEDs with their own unshadowed light U_g (smooth) and fractions r_g
    // (per channel). Each pixel's one shadow ray goes to group g with probability U_g / U:
    // C_g = U and S_g = U r_g for that group, 0 for the others (so E[C_g] = U_g, E[S_g] =
    // U_g r_g). The image is A + sum_g S_g; converged, A + sum_g U_g r_g.
    constexpr int groups = 3, width = 40, height = 30;
    const double r[groups] = {1.0, 0.3, 0.6};
    const std::size_t n = std::size_t(width) * height;
    std::vector<float> rest(3 * n), lit(3 * groups * n), chosen(3 * groups * n, 0.0f),
        shadowed(3 * groups * n, 0.0f), image(3 * n), exact(3 * n);
    std::vector<float> lit_all(3 * n), shadowed_all(3 * n);
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> uniform(0.0, 1.0);
    const auto fraction = [&](int g, int c) { return r[g] * (1.0 - 0.1 * c); };
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            const std::size_t p = std::size_t(y) * width + x;
            double u[groups], total = 0.0;
            for (int g = 0; g < groups; ++g)
                total += u[g] = (0.2 + 0.1 * g) * (1.0 + 0.01 * x + 0.02 * y);
            int pick = 0;
            for (double at = uniform(rng) * total - u[0]; at > 0.0 && pick + 1 < groups;)
                at -= u[++pick];
            for (int c = 0; c < 3; ++c) {
                const double scale = 1.0 + 0.1 * c;
                rest[3 * p + c] = float(0.1 + 0.002 * x);
                double sum = 0.0, truth = rest[3 * p + c];
                for (int g = 0; g < groups; ++g) {
                    const std::size_t i = 3 * (groups * p + g) + c;
                    lit[i] = float(u[g] * scale);
                    truth += u[g] * scale * fraction(g, c);
                    if (g == pick) {
                        chosen[i] = float(total * scale);
                        shadowed[i] = float(total * scale * fraction(g, c));
                        sum += shadowed[i];
                    }
                }
                image[3 * p + c] = float(rest[3 * p + c] + sum);
                exact[3 * p + c] = float(truth);
                lit_all[3 * p + c] = float(total * scale);
                shadowed_all[3 * p + c] = float(sum);
            }
        }
    const auto worst = [&](const std::vector<float>& a) {
        double w = 0.0;
        for (std::size_t i = 0; i < a.size(); ++i)
            w = std::max(w, std::abs(double(a[i]) - exact[i]) / exact[i]);
        return w;
    };
    const double sigma = 1.5;
    std::vector<float> grouped = image, one = image;
    shadow_filter(width, height, groups, grouped, lit, chosen, shadowed, sigma);
    shadow_filter(width, height, one, lit_all, shadowed_all, sigma);
    INFO("worst relative error: " << worst(grouped) << " in groups, " << worst(one) << " in one, "
                                  << worst(image) << " unfiltered");
    CHECK(worst(grouped) < 1e-5);
    CHECK(worst(one) > 0.02); // the draws' noise, smoothed but there
    // One group with C = U: the one-group overload's bytes.
    std::vector<float> again = image;
    shadow_filter(width, height, 1, again, lit_all, lit_all, shadowed_all, sigma);
    CHECK(again == one);

    // No shadow ray went to group 2 within the Gaussian's reach (3 sigma = 5 px) of the
    // columns x < 4: there it takes all groups' ratio, sum S / sum C over the same weights.
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < 9; ++x)
            for (int c = 0; c < 3; ++c) {
                const std::size_t p = std::size_t(y) * width + x, i = 3 * (groups * p + 2) + c;
                image[3 * p + c] -= shadowed[i];
                shadowed_all[3 * p + c] -= shadowed[i];
                lit_all[3 * p + c] -= chosen[i];
                chosen[i] = shadowed[i] = 0.0f;
            }
    grouped = image;
    shadow_filter(width, height, groups, grouped, lit, chosen, shadowed, sigma);
    const int radius = int(std::ceil(3.0 * sigma));
    double off = 0.0;
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < 4; ++x)
            for (int c = 0; c < 3; ++c) {
                double all_s = 0.0, all_c = 0.0;
                for (int qy = std::max(0, y - radius); qy <= std::min(height - 1, y + radius); ++qy)
                    for (int qx = 0; qx <= x + radius; ++qx) {
                        const double w = std::exp(
                            -0.5 * ((qx - x) * (qx - x) + (qy - y) * (qy - y)) / (sigma * sigma));
                        const std::size_t q = std::size_t(qy) * width + qx;
                        all_s += w * shadowed_all[3 * q + c];
                        all_c += w * lit_all[3 * q + c];
                    }
                const std::size_t p = std::size_t(y) * width + x;
                double expected = rest[3 * p + c];
                for (int g = 0; g < 2; ++g)
                    expected += lit[3 * (groups * p + g) + c] * fraction(g, c);
                expected += lit[3 * (groups * p + 2) + c] * all_s / all_c;
                off = std::max(off, std::abs(grouped[3 * p + c] - expected) / expected);
            }
    CHECK(off < 1e-5);
}

// The Gaussian is taken over the window; the other pixels keep their bytes, bad rims are
// refused.
TEST_CASE("shadow filter on the markers' rims: a rim pixel's ratio takes the 2-D Gaussian of its "
          "own sigma",
          "[render][shadow_filter]") {
    // A random shadow fraction per pixel and channel (so every weight shows), two groups,
    // rims on a diagonal band and one corner pixel.
    constexpr int groups = 2, width = 17, height = 12;
    const std::size_t n = std::size_t(width) * height;
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> uniform(0.1, 1.0);
    std::vector<float> rest(3 * n), lit(3 * groups * n), chosen(3 * groups * n),
        shadowed(3 * groups * n), image(3 * n);
    for (std::size_t p = 0; p < n; ++p)
        for (int c = 0; c < 3; ++c) {
            rest[3 * p + c] = float(0.1 * uniform(rng));
            double sum = 0.0;
            for (int g = 0; g < groups; ++g) {
                const std::size_t i = 3 * (groups * p + g) + c;
                lit[i] = float(uniform(rng));
                chosen[i] = float(uniform(rng));
                shadowed[i] = float(chosen[i] * uniform(rng));
                sum += shadowed[i];
            }
            image[3 * p + c] = float(rest[3 * p + c] + sum);
        }
    std::vector<std::uint8_t> rims(n, 0);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x)
            rims[std::size_t(y) * width + x] = std::abs(x - y - 2) <= 1 || (x == 0 && y == 0);
    const double sigma = 1.2;
    std::vector<float> plain = image;
    shadow_filter(width, height, groups, plain, lit, chosen, shadowed, sigma);
    for (const double rim_sigma : {0.0, 0.5, 1.2, 2.0}) {
        INFO("rim sigma " << rim_sigma);
        std::vector<float> out = image;
        shadow_filter(width, height, groups, out, lit, chosen, shadowed, sigma, rims, rim_sigma);
        // The window: 3 sigma of the wider.
        const int radius = int(std::ceil(3.0 * std::max(sigma, rim_sigma)));
        double worst = 0.0;
        int kept = 0, differ = 0;
        for (int y = 0; y < height; ++y)
            for (int x = 0; x < width; ++x) {
                const std::size_t p = std::size_t(y) * width + x;
                if (!rims[p]) {
                    // Bit for bit as without rims, where the window is the same.
                    if (rim_sigma <= sigma) {
                        for (int c = 0; c < 3; ++c)
                            kept += out[3 * p + c] == plain[3 * p + c];
                    }
                    continue;
                }
                for (int c = 0; c < 3; ++c) {
                    double expected = rest[3 * p + c];
                    for (int g = 0; g < groups; ++g) {
                        double sc = 0.0, ss = 0.0;
                        for (int qy = std::max(0, y - radius);
                             qy <= std::min(height - 1, y + radius); ++qy)
                            for (int qx = std::max(0, x - radius);
                                 qx <= std::min(width - 1, x + radius); ++qx) {
                                const double d2 = double((qx - x) * (qx - x) + (qy - y) * (qy - y));
                                const double w = rim_sigma > 0.0
                                                     ? std::exp(-0.5 * d2 / (rim_sigma * rim_sigma))
                                                     : (d2 == 0.0 ? 1.0 : 0.0);
                                const std::size_t j =
                                    3 * (groups * (std::size_t(qy) * width + qx) + g) + c;
                                sc += w * chosen[j];
                                ss += w * shadowed[j];
                            }
                        expected += lit[3 * (groups * p + g) + c] * ss / sc;
                    }
                    worst = std::max(worst, std::abs(out[3 * p + c] - expected) / expected);
                    differ += out[3 * p + c] != plain[3 * p + c];
                }
            }
        CHECK(worst < 1e-5);
        if (rim_sigma <= sigma)
            CHECK(kept == 3 * int(n - std::size_t(std::count(rims.begin(), rims.end(), 1))));
        // The rims' own sigma shows (at the filter's own sigma only by round-off).
        if (rim_sigma != sigma) CHECK(differ > 40);
    }
    // No rim flagged: the bytes without rims.
    std::vector<float> none = image;
    shadow_filter(width, height, groups, none, lit, chosen, shadowed, sigma,
                  std::vector<std::uint8_t>(n, 0), 0.3);
    CHECK(none == plain);
    CHECK_THROWS_WITH(shadow_filter(width, height, groups, none, lit, chosen, shadowed, sigma,
                                    std::vector<std::uint8_t>(n - 1, 0), 0.3),
                      Catch::Contains("allowed: none or one a pixel"));
    for (const double bad : {-0.1, kMaxShadowFilterPx + 0.5, std::nan("")})
        CHECK_THROWS_WITH(
            shadow_filter(width, height, groups, none, lit, chosen, shadowed, sigma, rims, bad),
            Catch::Contains("allowed: 0 <= sigma <= "));
}
