// The image metrics of `chromasim verify sensor` on synthetic images with known answers, the
// centroid law and the marker association on the default sensor, and bad input refused before
// any work.
#include "generators/spec/spec.hpp"
#include "generators/validation/verify_sensor.hpp"

#include "scratch_dir.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <limits>
#include <sstream>

using namespace chromasim::generators;
using Catch::Matchers::Contains;

namespace {

/// A white image, `size` square.
Image8 white(int size) {
    return Image8{size, size, 3, std::vector<std::uint8_t>(std::size_t(size) * size * 3, 255)};
}

/// Paints pixels whose centres lie within `r` of `c` (and beyond `r_in`) with `rgb`; returns
/// how many and their mean centre.
std::pair<int, Eigen::Vector2d> disc(Image8& img, Eigen::Vector2d c, double r,
                                     std::array<std::uint8_t, 3> rgb, double r_in = -1) {
    int n = 0;
    Eigen::Vector2d sum = Eigen::Vector2d::Zero();
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) {
            const double d = (Eigen::Vector2d(x + 0.5, y + 0.5) - c).norm();
            if (d > r || d <= r_in) continue;
            for (int ch = 0; ch < 3; ++ch)
                img.data[(std::size_t(y) * img.width + x) * 3 + ch] = rgb[std::size_t(ch)];
            ++n;
            sum += Eigen::Vector2d(x + 0.5, y + 0.5);
        }
    return {n, sum / n};
}

} // namespace

TEST_CASE("HSV of 8-bit colours follows the papers' rgb2hsv") {
    CHECK(rgb_to_hsv(255, 0, 0).hue_deg == Approx(0));
    CHECK(rgb_to_hsv(0, 0, 255).hue_deg == Approx(240));
    CHECK(rgb_to_hsv(255, 0, 255).hue_deg == Approx(300));
    CHECK(rgb_to_hsv(255, 0, 255).saturation == Approx(1));
    CHECK(rgb_to_hsv(200, 100, 100).saturation == Approx(0.5));
    CHECK(rgb_to_hsv(128, 128, 128).saturation == 0);
    CHECK(rgb_to_hsv(0, 0, 0).saturation == 0);
}

TEST_CASE("blobs are the saturated discs, with their pixel count, centroid and mean hue") {
    Image8 img = white(80);
    const auto blue = disc(img, {20.3, 22.6}, 6.0, {40, 40, 220});
    // A magenta disc inside a pale ring (saturation 0.3) that the 50 % rule leaves out.
    disc(img, {58, 50}, 9.0, {255, 179, 255}, 5.0);
    const auto magenta = disc(img, {58, 50}, 5.0, {230, 30, 230});
    std::vector<int> labels;
    const std::vector<Blob> blobs = find_blobs(img, 0.5, 3, &labels);
    REQUIRE(blobs.size() == 2);
    const Blob& b = blobs[0].mean_hue_deg > 270 ? blobs[1] : blobs[0];
    const Blob& m = blobs[0].mean_hue_deg > 270 ? blobs[0] : blobs[1];
    CHECK(b.pixels == blue.first);
    CHECK((b.centroid_px - blue.second).norm() < 1e-9);
    CHECK(b.mean_hue_deg == Approx(240));
    CHECK(m.pixels == magenta.first);
    CHECK((m.centroid_px - Eigen::Vector2d(58, 50)).norm() < 1e-9);
    CHECK(m.mean_hue_deg == Approx(300));
    CHECK(std::count(labels.begin(), labels.end(), -1) ==
          long(labels.size()) - blue.first - magenta.first);
}

TEST_CASE("a blob's mean hue is circular: red on both sides of 0 deg averages to red") {
    Image8 img = white(20);
    for (int y = 5; y < 15; ++y)
        for (int x = 5; x < 15; ++x) {
            std::uint8_t* p = &img.data[(std::size_t(y) * 20 + x) * 3];
            p[0] = 240;
            p[1] = x < 10 ? 0 : 42; // hue 10 deg
            p[2] = x < 10 ? 42 : 0; // hue 350 deg
        }
    const auto blobs = find_blobs(img, 0.5, 1);
    REQUIRE(blobs.size() == 1);
    CHECK(std::abs(hue_difference_deg(blobs[0].mean_hue_deg, 0.0)) < 1e-6);
    CHECK(blobs[0].pixels == 100);
}

TEST_CASE("blobs smaller than the minimum are dropped and touching pixels join diagonally") {
    Image8 img = white(10);
    for (int i : {2, 3, 4}) { // a diagonal line of three
        std::uint8_t* p = &img.data[(std::size_t(i) * 10 + i) * 3];
        p[0] = p[1] = 0;
    }
    img.data[(8 * 10 + 1) * 3] = 0; // one cyan pixel alone
    CHECK(find_blobs(img, 0.5, 1).size() == 2);
    CHECK(find_blobs(img, 0.5, 2).size() == 1);
    CHECK(find_blobs(img, 0.5, 2)[0].pixels == 3);
}

TEST_CASE("line fits, hue differences, colour differences and percentiles") {
    const LineFit exact = fit_line({0, 1, 2, 3}, {1, 3, 5, 7});
    CHECK(exact.slope == Approx(2));
    CHECK(exact.intercept == Approx(1));
    CHECK(exact.r2 == Approx(1));
    const LineFit noisy = fit_line({0, 1, 2, 3}, {0, 1, 0, 1});
    CHECK(noisy.slope == Approx(0.2));
    CHECK(noisy.r2 == Approx(0.2));
    CHECK(std::isnan(fit_line({0, 1, 2}, {4, 4, 4}).r2));
    CHECK(std::isnan(fit_line({0, 1}, {0, 1}).r2));
    CHECK(hue_difference_deg(10, 350) == Approx(20));
    CHECK(hue_difference_deg(350, 10) == Approx(-20));
    CHECK(hue_difference_deg(180, 0) == Approx(180));
    CHECK(delta_e76({0.3, 0.5, 0.7}, {0.3, 0.5, 0.7}) == 0);
    CHECK(delta_e76({1, 1, 1}, {0, 0, 0}) == Approx(100).margin(0.01));
    const double nan = std::numeric_limits<double>::quiet_NaN();
    CHECK(percentile({5, 1, nan, 3, 2, 4}, 50) == Approx(3));
    CHECK(percentile({5, 1, 3, 2, 4}, 10) == Approx(1.4));
    CHECK(std::isnan(percentile({nan}, 50)));
}

TEST_CASE("verify sensor refuses an image too small for the metrics and invisible markers") {
    ScratchDir dir("verify_sensor_bad");
    SensorVerifyOptions o;
    o.size_px = 224;
    o.json = dir.path / "out.json";
    o.picture = dir.path / "apex.png";
    std::ostringstream log;
    CHECK_THROWS_WITH(verify_sensor(o, log),
                      Contains("--size-px 224: a marker spans") && Contains("at least 10"));
    o.size_px = 5000;
    CHECK_THROWS_WITH(verify_sensor(o, log), Contains("--size-px 5000: out of range"));
    o.size_px = 448;
    o.spec_file = dir.write("clear.yaml", "name: clear\nrender: {spectral: false}\n"
                                          "sensor:\n  optics:\n"
                                          "    inner_marker_absorption_per_mm: [0, 0, 0]\n"
                                          "    outer_marker_absorption_per_mm: [0, 0, 0]\n");
    CHECK_THROWS_WITH(verify_sensor(o, log), Contains("clear.yaml") && Contains("invisible"));
    // Markers so pale that no pixel passes the 50 % saturation rule: found on the rest image.
    o.spec_file = dir.write("pale.yaml", "name: pale\nrender: {spectral: false}\n"
                                         "sensor:\n  optics:\n"
                                         "    inner_marker_absorption_per_mm: [0, 0.05, 0]\n"
                                         "    outer_marker_absorption_per_mm: [0.05, 0, 0]\n");
    CHECK_THROWS_WITH(verify_sensor(o, log), Contains("pale.yaml") && Contains("too pale"));
    o.spec_file.clear();
    o.json = dir.path / "missing" / "out.json";
    CHECK_THROWS_WITH(verify_sensor(o, log), Contains("no folder"));
    CHECK(log.str().empty());
    CHECK(std::distance(std::filesystem::directory_iterator(dir.path),
                        std::filesystem::directory_iterator{}) == 2); // the two specs only
}

TEST_CASE("a hollow dome is held to the size cue, a supported one to the hue cue") {
    CHECK(normal_cue("hollow") == NormalCue::size);
    CHECK(normal_cue("rigid_core") == NormalCue::hue);
    CHECK(normal_cue("soft_fill") == NormalCue::hue);
    SensorVerifyReport r;
    r.marker_span_px = 12.0; // 6 px at 224 px: one more pixel across is (7/6)^2 - 1 = 36 % area
    ObjectLaws o;
    o.object = "flat";
    o.area.r2_median = 0.97;
    o.area.r2_p10 = 0.92;
    o.apex_area_change = 0.37;
    o.centroid.r2_median = 0.995;
    r.objects = {o};
    add_sensor_targets(r, 448);
    CHECK(r.targets.size() == 5);
    CHECK(r.all_met());
    CHECK(r.targets[2].bound == Approx(13.0 / 36.0));
    r.objects[0].apex_area_change = 0.35;
    r.targets.clear();
    add_sensor_targets(r, 448);
    CHECK_FALSE(r.all_met());
    r.cue = NormalCue::hue; // the same laws against the hue targets: R^2 0 fails
    r.objects[0].apex_area_change = 0.37;
    r.targets.clear();
    add_sensor_targets(r, 448);
    CHECK(r.targets[0].what == "flat: hue vs normal displacement, R2 median");
    CHECK_FALSE(r.all_met());
}

TEST_CASE("the default sensor meets its targets: centroid and size laws, each blob its own "
          "marker") {
    SensorVerifyOptions o;
    std::ostringstream log;
    const SensorVerifyReport r = verify_sensor(o, log);
    REQUIRE(r.objects.size() == 2);
    for (const ObjectLaws& laws : r.objects) {
        INFO(laws.object);
        CHECK(laws.flagged_frames == 0);
        CHECK(laws.tracked >= 70);
        CHECK(laws.id_checks > 1500);
        CHECK(laws.id_mismatches == 0);
        CHECK(laws.centroid.markers >= 60);
        CHECK(laws.centroid.r2_median >= 0.99);
        // A marker pressed towards the camera looks larger (docs/SENSOR.md).
        CHECK(laws.area.r2_median >= 0.95);
        CHECK(laws.area.slope_median > 0);
    }
    CHECK(r.cue == NormalCue::size);
    for (const auto& t : r.targets) {
        INFO(t.what << ": " << t.measured << " against " << t.bound);
        CHECK(t.met());
    }
}
