// What `bench render` reports as an image's error against a noisy reference
// (generators/validation/bench.hpp): the mean of independent reference renders with the variance of that
// mean from their spread, and the RMS error less the reference's noise in quadrature.
#include "generators/validation/bench.hpp"
#include "generators/io/image_io.hpp"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

using chromasim::generators::error_against;
using chromasim::generators::mean_of_renders;

TEST_CASE("bench error: the mean of renders and the variance of that mean, by hand",
          "[generators][bench]") {
    // Values 1, 3 and 2, 2: means 2 and 2; sample variances 2 and 0, over 2 renders: 1 and 0.
    const auto m = mean_of_renders({{1.0f, 2.0f}, {3.0f, 2.0f}});
    REQUIRE(m.mean.size() == 2);
    CHECK(m.mean[0] == Approx(2.0));
    CHECK(m.mean[1] == Approx(2.0));
    CHECK(m.variance_of_mean[0] == Approx(1.0));
    CHECK(m.variance_of_mean[1] == Approx(0.0).margin(1e-12));
    CHECK_THROWS_AS(mean_of_renders({{1.0f}}), std::invalid_argument);
    CHECK_THROWS_AS(mean_of_renders({{1.0f}, {1.0f, 2.0f}}), std::invalid_argument);
    CHECK_THROWS_AS(error_against({1.0f}, {1.0f, 2.0f}, {}), std::invalid_argument);
}

TEST_CASE("bench error: a known bias recovered through noisy references", "[generators][bench]") {
    // A converged image that is off the truth by 0.03 everywhere, against references with
    // Gaussian noise of 0.1 per value: three independent references, their mean's noise from
    // their spread. The RMS error is dominated by the noise (about 0.064); less the noise it
    // is the bias, within a few per cent (40,000 values).
    constexpr std::size_t n = 40'000;
    constexpr double bias = 0.03, sigma = 0.1;
    std::mt19937_64 rng(12345);
    std::normal_distribution<double> noise(0.0, sigma);
    std::vector<float> truth(n), image(n);
    for (std::size_t i = 0; i < n; ++i) {
        truth[i] = float(0.5 + 0.3 * std::sin(0.001 * double(i)));
        image[i] = float(truth[i] + bias);
    }
    std::vector<std::vector<float>> refs(3, std::vector<float>(n));
    for (auto& r : refs)
        for (std::size_t i = 0; i < n; ++i)
            r[i] = float(truth[i] + noise(rng));
    const auto m = mean_of_renders(refs);
    const std::vector<float> mean(m.mean.begin(), m.mean.end());
    const std::vector<float> var(m.variance_of_mean.begin(), m.variance_of_mean.end());
    const auto e = error_against(image, mean, var);
    CHECK(e.rms == Approx(std::sqrt(bias * bias + sigma * sigma / 3.0)).epsilon(0.02));
    CHECK(e.less_reference_noise == Approx(bias).epsilon(0.06));
    // Without the noise estimate, the noise passes for error: more than twice the bias.
    const auto raw = error_against(image, mean, {});
    CHECK(raw.less_reference_noise == Approx(raw.rms));
    CHECK(raw.rms > 2.0 * bias);
    // Every pixel lit: the circle is the whole image (less the one value of 40,000 that makes
    // no pixel).
    CHECK(e.in_circle == Approx(e.less_reference_noise).epsilon(1e-4));
    // A reference identical to the image: no error at all.
    const auto none = error_against(image, image, {});
    CHECK(none.rms == 0.0);
    CHECK(none.max == 0.0);
}

TEST_CASE("bench error: 'in the circle' leaves out the pixels the reference leaves black",
          "[generators][bench]") {
    // Two pixels lit, off by 0.1 in every channel; two black in both images. The image's RMS
    // is 0.1 / sqrt(2); the circle's 0.1; with a reference variance of 0.0019 on the lit values
    // (and none on the black ones), sqrt(0.01 - 0.0019) = 0.09.
    const std::vector<float> reference = {0.5f, 0.5f, 0.5f, 0.0f, 0.0f, 0.0f,
                                          0.0f, 0.2f, 0.0f, 0.0f, 0.0f, 0.0f};
    std::vector<float> image = reference, variance(12, 0.0f);
    for (const std::size_t i : {0, 1, 2, 6, 7, 8}) {
        image[i] += 0.1f;
        variance[i] = 0.0019f;
    }
    const auto e = error_against(image, reference, variance);
    CHECK(e.rms == Approx(0.1 / std::sqrt(2.0)).epsilon(1e-5));
    CHECK(e.in_circle == Approx(0.09).epsilon(1e-4));
}

namespace {
// A bench of the preview integrator on the dome at rest at 16 px: a second's work.
chromasim::generators::RenderBenchOptions small_bench() {
    chromasim::generators::RenderBenchOptions o;
    o.samples_per_pixel = {1, 2};
    o.reference_spp = 1;
    o.size_px = 16;
    o.repeats = 1;
    o.modes = {"rgb"};
    o.integrators = {"preview"};
    o.normal_N = 0.0;
    return o;
}
} // namespace

TEST_CASE("bench render --images-out writes each timed setting's image, or refuses before any "
          "work",
          "[generators][bench]") {
    namespace fs = std::filesystem;
    const fs::path dir =
        fs::temp_directory_path() / ("chromasim_bench_images_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    chromasim::generators::RenderBenchOptions o = small_bench(); // the dome at rest: no solve
    SECTION("a file in the way: refused, nothing printed") {
        fs::create_directories(dir);
        const fs::path file = dir / "taken";
        std::ofstream(file) << "x";
        o.images_out = file / "sub";
        std::ostringstream out;
        CHECK_THROWS_WITH(chromasim::generators::bench_render(o, out),
                          Catch::Contains("--images-out") && Catch::Contains("cannot make"));
        CHECK(out.str().empty());
    }
    SECTION("one EXR per setting, with variance and marker ids, at the bench's size") {
        o.images_out = dir / "made" / "here"; // made, parents too
        std::ostringstream out;
        chromasim::generators::bench_render(o, out);
        for (int spp : {1, 2}) {
            const fs::path path = o.images_out / ("preview_rgb_spp" + std::to_string(spp) +
                                                  "_filter0_mirror0_rim0_led0.exr");
            INFO(path.string());
            REQUIRE(fs::exists(path));
            const auto image = chromasim::generators::read_image_float(path);
            CHECK(image.width == 16);
            CHECK(image.height == 16);
            for (const char* channel : {"R", "G", "B", "variance.R", "inner_marker_id"})
                CHECK(std::find(image.channels.begin(), image.channels.end(), channel) !=
                      image.channels.end());
            // Lit somewhere: the render, not a blank file.
            float brightest = 0.0f;
            for (int y = 0; y < 16; ++y)
                for (int x = 0; x < 16; ++x)
                    brightest = std::max(brightest, image.at(x, y, "G"));
            CHECK(brightest > 0.1f);
        }
    }
    fs::remove_all(dir);
}

// The JSON holds the tables as printed: figures.py reads it instead of the Markdown.
TEST_CASE("bench render --json writes the printed table or refuses a bad path first",
          "[generators][bench]") {
    namespace fs = std::filesystem;
    const fs::path dir =
        fs::temp_directory_path() / ("chromasim_bench_json_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    chromasim::generators::RenderBenchOptions o = small_bench();
    SECTION("a folder that does not exist: refused, nothing printed") {
        o.json_out = dir / "missing" / "r.json";
        std::ostringstream out;
        CHECK_THROWS_WITH(chromasim::generators::bench_render(o, out),
                          Catch::Contains("--json") && Catch::Contains("does not exist"));
        CHECK(out.str().empty());
        CHECK_FALSE(fs::exists(o.json_out));
    }
    SECTION("the rows of the Markdown table, cell by cell") {
        o.json_out = dir / "r.json";
        std::ostringstream out;
        chromasim::generators::bench_render(o, out);
        const auto json = nlohmann::json::parse(std::ifstream(o.json_out));
        CHECK(json["command"] == "bench render");
        REQUIRE(json["tables"].size() == 1);
        const auto& table = json["tables"][0];
        CHECK(table["header"][0] == "integrator");
        REQUIRE(table["rows"].size() == 2); // one a spp
        for (const auto& row : table["rows"]) {
            std::string line = "|";
            for (const auto& cell : row)
                line.append(" ").append(cell.get<std::string>()).append(" |");
            INFO(line);
            CHECK(out.str().find(line + "\n") != std::string::npos);
        }
    }
    fs::remove_all(dir);
}
