// Each LED's own intensity (OpticsParams::led_gain): light is linear in the LEDs' emission, so
// with the same random draws an image under gains g is the sum of the images of each LED alone
// times its gain; the fast integrator takes the gains in its cached direct light, its indirect
// light and the LEDs it sees by reflection, and agrees with the path integrator under them.
#include "fast_fixtures.hpp"
#include "render/fisheye_camera.hpp"

#include <catch2/catch.hpp>

#include <array>
#include <cmath>
#include <stdexcept>
#include <vector>

using namespace chromasim::render;
using namespace chromasim::render::detail;
using namespace chromasim::render::test;

namespace {

constexpr std::array<double, 6> kGains{1.6, 0.4, 1.0, 0.7, 1.3, 0.9};

/// `optics` with gains `g` (all six LEDs).
OpticsParams with_gains(OpticsParams optics, std::vector<double> g) {
    optics.led_gain = std::move(g);
    return optics;
}

/// Only LED k lit.
std::vector<double> alone(int k) {
    std::vector<double> g(6, 0.0);
    g[std::size_t(k)] = 1.0;
    return g;
}

} // namespace

TEST_CASE("LED gains: the preview's irradiance is the gains' sum of each LED's alone",
          "[render][leds]") {
    EmbreeScene scene;
    scene.set_frame(dome_with_box_markers());
    const OpticsParams base; // LEDs 1 mm under the rim, no lens barrel: straight light
    const ShadingModel lit(with_gains(base, {kGains.begin(), kGains.end()}));
    for (const double polar : {0.0, 30.0, 60.0}) {
        const Vec3 p = 11.6 * unit_from_angles(polar, 20.0), n = -p.normalized();
        Rgb sum = Rgb::Zero();
        for (int k = 0; k < 6; ++k)
            sum += kGains[std::size_t(k)] *
                   ShadingModel(with_gains(base, alone(k))).irradiance(scene, p, n);
        const Rgb E = lit.irradiance(scene, p, n);
        INFO("polar " << polar);
        REQUIRE(E.maxCoeff() > 0.0);
        for (int c = 0; c < 3; ++c)
            CHECK(E[c] == Approx(sum[c]).epsilon(1e-12));
        CHECK(ShadingModel(base)
                  .irradiance(scene, p, n)
                  .isApprox(ShadingModel(with_gains(base, std::vector<double>(6, 1.0)))
                                .irradiance(scene, p, n),
                            0.0));
    }
}

// With and without next-event estimation, the same draws.
TEST_CASE("LED gains: a path's light is the gains' sum of each LED's alone, NEE on and off",
          "[render][leds][path]") {
    EmbreeScene scene;
    scene.set_frame(dome_with_box_markers());
    const OpticsParams base = fuse_optics();
    std::vector<ShadingModel> single;
    for (int k = 0; k < 6; ++k)
        single.emplace_back(with_gains(base, alone(k)));
    const ShadingModel lit(with_gains(base, {kGains.begin(), kGains.end()}));
    const auto lanes = lit.rgb_lanes();
    for (const bool next_event : {false, true}) {
        const PathIntegrator path(lit, next_event);
        RgbLanes total = RgbLanes::Zero(), expected = RgbLanes::Zero();
        for (int i = 0; i < 400; ++i) {
            const Vec3 d = unit_from_angles(5.0 + 0.17 * i, 7.0 * i);
            PixelRng rng(11, std::uint64_t(i));
            total += path.radiance(scene, Vec3::Zero(), d, lanes, rng);
            for (int k = 0; k < 6; ++k) {
                const PathIntegrator one(single[std::size_t(k)], next_event);
                PixelRng same(11, std::uint64_t(i));
                expected +=
                    kGains[std::size_t(k)] * one.radiance(scene, Vec3::Zero(), d, lanes, same);
            }
        }
        INFO("next-event estimation " << next_event);
        REQUIRE(total[1] > 0.0);
        for (int c = 0; c < 3; ++c)
            CHECK(total[c] == Approx(expected[c]).epsilon(1e-9));
    }
}

TEST_CASE("LED gains: an LED seen directly or in the inner surface shines with its own gain",
          "[render][leds][path]") {
    EmbreeScene scene;
    scene.set_frame(clear_dome(48, 192, 48, 192));
    const ShadingModel shading(with_gains(fuse_optics(), {kGains.begin(), kGains.end()}));
    const PathIntegrator path(shading, false);
    const auto lanes = shading.rgb_lanes();
    for (int k = 0; k < 6; ++k) {
        // From the cavity beside the inner surface straight to the middle of LED k.
        const Vec3 l = path.led_point(k, 0.5, 0.5);
        const Vec3 from = Vec3(l.x(), l.y(), 0.0) * 1.03 + Vec3(0.0, 0.0, 0.5);
        const auto hit = path.led_hit(from, (l - from).normalized(), 0.0, 100.0);
        REQUIRE(hit);
        CHECK(hit->k == k);
        CHECK(hit->front);
        PixelRng rng(1, 0);
        const RgbLanes L = path.radiance(scene, from, (l - from).normalized(), lanes, rng);
        CHECK(L[0] == Approx(kGains[std::size_t(k)] / path.led_area_mm2()).epsilon(1e-12));
    }
}

TEST_CASE("LED gains: the fast integrator agrees with the path integrator under unequal LEDs",
          "[render][leds][fast]") {
    const SensorFrame frame = clear_dome(16, 64, 24, 96);
    EmbreeScene scene;
    scene.set_frame(frame);
    OpticsParams optics; // as test_fast.cpp's equal LEDs
    optics.coating_albedo = Vec3(0.85, 0.6, 0.3);
    optics.led_gain = {2.0, 0.25, 1.0, 0.5, 1.5, 0.75};
    const ShadingModel shading(optics);
    const PathIntegrator path(shading);
    FastIntegrator fast(shading, path);
    LightCacheSettings settings;
    settings.paths_per_vertex = 256;
    fast.build_cache(frame, settings, nullptr, 1.0);
    fast.set_frame(frame, scene);
    const auto lanes = shading.rgb_lanes();
    // Towards LED 0 (gain 2) and LED 1 (gain 0.25), near the apex and near the rim.
    for (const auto& [polar, azimuth] : {std::pair{30.0, 0.0}, std::pair{30.0, 60.0},
                                         std::pair{65.0, 0.0}, std::pair{65.0, 60.0}}) {
        const auto [p, se, f] =
            along_ray(path, fast, scene, lanes, unit_from_angles(polar, azimuth));
        for (int c = 0; c < 3; ++c) {
            INFO("polar " << polar << " deg, azimuth " << azimuth << " deg, lane " << c << ": fast "
                          << f[c] << ", path " << p[c] << " +- " << se[c]);
            // The tolerance of the equal-LED comparison (test_fast.cpp); the LEDs' light in
            // these directions differs by a factor of up to 2.6 between the two azimuths.
            CHECK(se[c] < 0.01 * p[c]);
            CHECK(std::abs(f[c] - p[c]) < 0.08 * p[c] + 4.0 * se[c]);
        }
    }
}

TEST_CASE("LED gains: a list of the wrong length or a negative gain is refused", "[render][leds]") {
    OpticsParams o;
    o.led_gain = {1.0, 1.0};
    CHECK_THROWS_AS(ShadingModel(o), std::invalid_argument);
    o.led_gain = {1.0, 1.0, 1.0, -0.1, 1.0, 1.0};
    CHECK_THROWS_AS(ShadingModel(o), std::invalid_argument);
}
