// Tests of the renderer's sample sequences (render/sampling.hpp): hero-wavelength strata,
// multi-jittered pixel positions, and the shadow rays' scrambled Sobol points.
#include "render/sampling.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cstdint>
#include <utility>
#include <vector>

TEST_CASE("a pixel's samples take every hero-wavelength stratum once, whatever their count",
          "[render]") {
    // (3 k + 1) mod n would take one stratum in three three times when 3 divides n (24 spp
    // noisier than 16: 1.46 against 1.27 % at 224 px).
    for (int n = 1; n <= 100; ++n)
        for (const std::uint64_t pixel : {0ull, 17ull, 50175ull}) {
            const std::uint32_t seed =
                chromasim::render::detail::wavelength_permutation_seed(0x5EEDull, pixel);
            std::vector<int> taken(std::size_t(n), 0);
            for (int k = 0; k < n; ++k) {
                const int stratum = chromasim::render::detail::wavelength_stratum(k, n, seed);
                REQUIRE(stratum >= 0);
                REQUIRE(stratum < n);
                ++taken[std::size_t(stratum)];
            }
            INFO(n << " samples, pixel " << pixel);
            CHECK(std::all_of(taken.begin(), taken.end(), [](int t) { return t == 1; }));
        }
    // Not the shadow rays' seed: the two draws of a sample are not paired.
    CHECK(chromasim::render::detail::wavelength_permutation_seed(1, 2) !=
          chromasim::render::detail::shadow_seed(1, 2));
}

TEST_CASE("a pixel's positions are multi-jittered: one per cell, one per column and row",
          "[render]") {
    using chromasim::render::detail::multi_jittered;
    using chromasim::render::detail::position_seed;
    chromasim::render::detail::PixelRng rng(3, 4);
    for (const auto& [nx, ny] : {std::pair{4, 4}, {4, 6}, {1, 7}, {3, 3}, {5, 5}})
        for (const std::uint64_t pixel : {0ull, 17ull, 50175ull}) {
            const int n = nx * ny;
            std::vector<int> cell(std::size_t(n), 0), column(std::size_t(n), 0),
                row(std::size_t(n), 0);
            for (int k = 0; k < n; ++k) {
                const auto [u, v] = multi_jittered(k, nx, ny, position_seed(0x5EEDull, pixel),
                                                   rng.uniform(), rng.uniform());
                REQUIRE(u >= 0.0);
                REQUIRE(u < 1.0);
                REQUIRE(v >= 0.0);
                REQUIRE(v < 1.0);
                CHECK(int(u * nx) == k % nx); // sample k in cell k of the jittered grid
                CHECK(int(v * ny) == k / nx);
                ++cell[std::size_t(int(v * ny) * nx + int(u * nx))];
                ++column[std::size_t(int(u * n))];
                ++row[std::size_t(int(v * n))];
            }
            INFO(nx << " x " << ny << ", pixel " << pixel);
            const auto once = [](const std::vector<int>& c) {
                return std::all_of(c.begin(), c.end(), [](int t) { return t == 1; });
            };
            CHECK(once(cell));
            CHECK(once(column));
            CHECK(once(row));
        }
}

TEST_CASE("a pixel's shadow-ray uniforms are stratified jointly and uniform over pixels",
          "[render]") {
    using chromasim::render::detail::PixelSeeds;
    using chromasim::render::detail::shadow_uniforms;
    // 16 samples, after the per-pixel scrambling: (u1, u2), the point on the LED, one point in
    // each of the 16 boxes of 2^a x 2^(4 - a) (a (0, 4, 2)-net); with u_led, two in each box
    // of 2^a x 2^(3 - a) (a (1, 4, 2)-net).
    for (const std::uint64_t pixel : {0ull, 17ull, 50175ull}) {
        std::vector<std::array<double, 3>> u;
        for (int k = 0; k < 16; ++k)
            u.push_back(shadow_uniforms(k, 16, PixelSeeds(0x5EEDull, pixel)));
        for (int d0 = 0; d0 < 3; ++d0)
            for (int d1 = d0 + 1; d1 < 3; ++d1) {
                const int t = d0 == 0 ? 1 : 0, m = 4 - t; // u_led is dimension 0 here
                for (int a = 0; a <= m; ++a) {
                    const int nx = 1 << a, ny = (1 << m) >> a;
                    std::vector<int> in_box(std::size_t(1 << m), 0);
                    for (const auto& p : u)
                        ++in_box[std::size_t(int(p[std::size_t(d0)] * nx) * ny +
                                             int(p[std::size_t(d1)] * ny))];
                    INFO("pixel " << pixel << ", dimensions " << d0 << ", " << d1 << ", boxes "
                                  << nx << " x " << ny);
                    CHECK(std::all_of(in_box.begin(), in_box.end(),
                                      [t](int count) { return count == 1 << t; }));
                }
            }
    }
    // A 2 x 2 block of pixels sharing one scrambled sequence (the renderer's), 4 samples
    // each: in (u1, u2) every pixel's 4 points are a (0, 2, 2)-net, the block's first two
    // pixels' 8 a (0, 3, 2)-net and all 16 a (0, 4, 2)-net; u_led alone takes each sixteenth
    // once. Pixels of another block are scrambled otherwise.
    const auto boxes_once = [](const std::vector<std::array<double, 3>>& points, int m) {
        for (int a = 0; a <= m; ++a) {
            const int nx = 1 << a, ny = (1 << m) >> a;
            std::vector<int> in_box(std::size_t(1 << m), 0);
            for (const auto& p : points)
                ++in_box[std::size_t(int(p[1] * nx) * ny + int(p[2] * ny))];
            if (!std::all_of(in_box.begin(), in_box.end(), [](int c) { return c == 1; }))
                return false;
        }
        return true;
    };
    for (const std::uint64_t block : {0ull, 12345ull}) {
        INFO("block " << block);
        std::vector<std::array<double, 3>> all;
        std::vector<double> led;
        for (std::uint32_t quad = 0; quad < 4; ++quad) {
            std::vector<std::array<double, 3>> mine;
            for (int k = 0; k < 4; ++k) {
                // The pixels' own indices (and permutations) differ; the block is shared.
                mine.push_back(
                    shadow_uniforms(k, 4, PixelSeeds(0x5EEDull, 4 * block + quad, block, quad)));
                led.push_back(mine.back()[0]);
            }
            CHECK(boxes_once(mine, 2));
            all.insert(all.end(), mine.begin(), mine.end());
            if (quad == 1) CHECK(boxes_once(all, 3));
        }
        CHECK(boxes_once(all, 4));
        std::vector<int> strata(16, 0);
        for (const double u : led)
            ++strata[std::size_t(u * 16)];
        CHECK(std::all_of(strata.begin(), strata.end(), [](int c) { return c == 1; }));
    }
    CHECK(shadow_uniforms(0, 4, PixelSeeds(0x5EEDull, 0, 0, 0)) !=
          shadow_uniforms(0, 4, PixelSeeds(0x5EEDull, 0, 1, 0)));
    // The unscrambled points, by hand from the direction numbers (1/2; 1/2, 1/4, ...; and
    // 1/2, 3/4, 3/8 for x^2 + x + 1), in the natural order; and an index with its top bit set.
    const double by_hand[8][3] = {{0, 0, 0},
                                  {0.5, 0.5, 0.5},
                                  {0.25, 0.75, 0.75},
                                  {0.75, 0.25, 0.25},
                                  {0.125, 0.625, 0.375},
                                  {0.625, 0.125, 0.875},
                                  {0.375, 0.375, 0.625},
                                  {0.875, 0.875, 0.125}};
    for (std::uint32_t i = 0; i < 8; ++i)
        for (std::size_t d = 0; d < 3; ++d)
            CHECK(chromasim::render::detail::sobol3(i)[d] * 0x1.0p-32 == by_hand[i][d]);
    CHECK(chromasim::render::detail::sobol3(1u << 31)[0] == 1u);
    // Any count: in [0, 1); over many pixels each sample's uniforms are uniform (the
    // scrambling is what makes the estimate unbiased): the means of 20000 pixels within 4.5
    // standard errors (0.0092) of 1/2, and a quarter of them below 1/4.
    for (const int n : {1, 5, 24}) {
        for (int k = 0; k < n; k += 2) {
            std::array<double, 3> mean{}, below{};
            const int pixels = 20000;
            for (int pixel = 0; pixel < pixels; ++pixel) {
                const auto u = shadow_uniforms(k, n, PixelSeeds(9, std::uint64_t(pixel)));
                for (std::size_t d = 0; d < 3; ++d) {
                    REQUIRE(u[d] >= 0.0);
                    REQUIRE(u[d] < 1.0);
                    mean[d] += u[d] / pixels;
                    below[d] += (u[d] < 0.25) / double(pixels);
                }
            }
            for (std::size_t d = 0; d < 3; ++d) {
                INFO(n << " samples, sample " << k << ", dimension " << d);
                CHECK(mean[d] == Approx(0.5).margin(0.0092));
                CHECK(below[d] == Approx(0.25).margin(0.0138));
            }
        }
    }
}
