// Tests of the fast integrator's pixels: runs of pixels traced together, camera samples kept
// between renders, and the pixels that take counts of their own (mirrored LEDs, the markers'
// rims, the LED rays apart).
#include "fast_fixtures.hpp"
#include "render/fisheye_camera.hpp"

#include <catch2/catch.hpp>
#include <tbb/global_control.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <thread>

using namespace chromasim::render;
using namespace chromasim::render::detail;
using namespace chromasim::render::test;

// Below 16 spp a row's pixels of one count are traced in runs whose rays go to Embree
// together; a run ends at a pixel of another count. Rims at a count of their own cut the runs
// elsewhere, so each other pixel traces beside other neighbours: its bytes must not change.
// Checked in RGB and spectral mode, with variance and marker ids.
TEST_CASE("fast integrator: a pixel's bytes do not depend on the neighbours traced with it",
          "[render][fast]") {
    const SensorFrame rest = dome_with_box_markers();
    const SensorFrame pressed = pressed_flat(rest);
    const OpticsParams spectral = spectral_optics();
    for (const OpticsParams& optics : {OpticsParams{}, spectral}) {
        // 23 px wide: runs of 16 / n pixels end part-way along each row.
        Renderer renderer(CameraParams{23, 17, 84.0}, optics);
        small_cache_on(renderer, rest, pressed);
        for (const int spp : {1, 3, 4, 5, 8}) {
            RenderSettings settings{spp, 11};
            settings.integrator = Integrator::fast;
            settings.variance = true;
            settings.marker_ids = true;
            const Image plain = renderer.render(settings);
            settings.rim_samples_per_pixel = spp + 3;
            const Image cut = renderer.render(settings);
            settings.rim_samples_per_pixel = spp + 4;
            const Image cut_again = renderer.render(settings);
            // The rims: their count differs between the last two (the runs do not).
            const std::size_t pixels = plain.rgb.size() / 3;
            int rims = 0, others_changed = 0;
            for (std::size_t p = 0; p < pixels; ++p) {
                bool rim = false, changed = plain.variance[3 * p] != cut.variance[3 * p];
                for (std::size_t c = 3 * p; c < 3 * p + 3; ++c) {
                    rim = rim || cut.rgb[c] != cut_again.rgb[c];
                    changed = changed || plain.rgb[c] != cut.rgb[c];
                }
                rims += rim;
                others_changed += !rim && changed;
            }
            INFO("spectral " << bool(optics.spectra) << ", " << spp << " spp: " << rims
                             << " rim pixels, " << others_changed << " others changed");
            CHECK(rims > 10);
            CHECK(others_changed == 0);
            CHECK(cut.inner_marker_id == plain.inner_marker_id);
            CHECK(cut.outer_marker_id == plain.outer_marker_id);
            // And another seed gives another image: the comparison can fail.
            settings.seed = 12;
            CHECK(renderer.render(settings).rgb != cut_again.rgb);
        }
    }
}

// This holds through changes of frame, seed, count and shadow rays, in RGB and spectral
// mode; none is kept beyond the budget, and two renders may run at once.
TEST_CASE("fast integrator: the camera samples kept from render to render give the bytes of "
          "samples drawn anew",
          "[render][fast]") {
    const SensorFrame rest = dome_with_box_markers();
    const SensorFrame pressed = pressed_flat(rest);
    const OpticsParams spectral = spectral_optics();
    struct Step {
        const SensorFrame* frame;
        int spp;
        std::uint64_t seed;
        int shadow_rays;
    };
    // Each step changes one thing the kept samples depend on, or the frame alone.
    const std::array<Step, 6> steps{{{&rest, 2, 11, 0},
                                     {&pressed, 2, 11, 0},
                                     {&pressed, 2, 12, 0},
                                     {&pressed, 3, 12, 0},
                                     {&pressed, 3, 12, 7},
                                     {&rest, 2, 11, 0}}};
    for (const OpticsParams& optics : {OpticsParams{}, spectral}) {
        // 23 px wide: batches of 16 / n pixels end part-way along each row.
        Renderer kept(CameraParams{23, 17, 84.0}, optics), anew(CameraParams{23, 17, 84.0}, optics);
        small_cache_on(kept, rest, rest);
        small_cache_on(anew, rest, rest);
        CHECK(kept.camera_samples_bytes() == 0);
        std::vector<float> previous;
        for (const Step& step : steps) {
            kept.set_frame(*step.frame);
            anew.set_frame(*step.frame);
            RenderSettings settings = fast_with_variance(step.spp, step.seed);
            settings.shadow_rays_per_pixel = step.shadow_rays;
            // With the rims, the mirrored pixels, the LED rays and the filter: each count's
            // samples kept apart.
            settings.rim_samples_per_pixel = 5;
            settings.reflection_samples_per_pixel = 8;
            settings.reflected_led_samples_per_pixel = 16;
            settings.shadow_filter_px = 1.0;
            const Image with = kept.render(settings);
            // The kept samples: at least each pixel's samples and shadow rays at the main
            // count (17 x 23 pixels, most in the field: 4 doubles a sample, 3 a ray).
            const std::size_t bytes = kept.camera_samples_bytes();
            CHECK(bytes > 200 * (4 * std::size_t(step.spp) + 3) * sizeof(double));
            // Drawn anew, by a renderer that keeps none: the same bytes.
            settings.camera_cache_mb = 0.0;
            const Image without = anew.render(settings);
            CHECK(anew.camera_samples_bytes() == 0);
            INFO("spectral " << bool(optics.spectra) << ", " << step.spp << " spp, seed "
                             << step.seed << ", " << step.shadow_rays << " shadow rays");
            double lit = 0.0;
            for (const float v : with.rgb)
                lit += v;
            CHECK(lit > 0.0);
            CHECK(with.rgb == without.rgb);
            CHECK(with.variance == without.variance);
            CHECK(with.rgb != previous); // each step changes the image: the check can fail
            previous = with.rgb;
        }
        // A budget below what they take: none kept, the same bytes.
        Renderer small(CameraParams{23, 17, 84.0}, optics);
        small_cache_on(small, rest, rest);
        RenderSettings settings = fast_with_variance(2, 11);
        settings.camera_cache_mb = 1e-3; // 1 kB
        CHECK(small.render(settings).rgb == anew.render(settings).rgb);
        CHECK(small.camera_samples_bytes() == 0);
    }
    // Two threads rendering with one renderer at once: one keeps the samples, the other draws
    // them anew without waiting for the store; both give the bytes of a render alone.
    {
        Renderer shared(CameraParams{23, 17, 84.0}, OpticsParams{});
        small_cache_on(shared, rest, pressed);
        RenderSettings settings = fast_with_variance(2, 11);
        settings.reflected_led_samples_per_pixel = 16;
        const Image alone = shared.render(settings);
        std::array<Image, 2> together;
        std::thread other([&] { together[1] = shared.render(settings); });
        together[0] = shared.render(settings);
        other.join();
        CHECK(together[0].rgb == alone.rgb);
        CHECK(together[1].rgb == alone.rgb);
    }
    Renderer renderer(CameraParams{8, 8, 84.0}, OpticsParams{});
    small_cache_on(renderer, rest, rest);
    RenderSettings settings = fast_with_variance(2, 11);
    settings.camera_cache_mb = -1.0;
    CHECK_THROWS_WITH(renderer.render(settings),
                      Catch::Contains("camera_cache_mb = -1") && Catch::Contains("allowed: >= 0"));
}

// Each such pixel is as a render at that count would have it, among them every pixel that
// sees an LED in the inner surface; the other pixels keep their bytes.
TEST_CASE("fast integrator: the pixels that mirror an LED take reflection_samples_per_pixel",
          "[render][fast]") {
    const SensorFrame rest = dome_with_box_markers();
    const SensorFrame pressed = pressed_flat(rest);
    Renderer renderer(CameraParams{96, 96, 84.0}, OpticsParams{});
    small_cache_on(renderer, rest, pressed);
    RenderSettings settings = fast_with_variance(4, 5);
    const Image four = renderer.render(settings);
    settings.samples_per_pixel = 16;
    const Image sixteen = renderer.render(settings);
    settings.samples_per_pixel = 4;
    settings.reflection_samples_per_pixel = 16;
    const Image both = renderer.render(settings);
    // Each pixel is to the bit the 4-spp render's or the 16-spp render's (value and variance).
    const auto same = [](const Image& a, const Image& b, std::size_t p) {
        for (std::size_t c = 3 * p; c < 3 * p + 3; ++c)
            if (a.rgb[c] != b.rgb[c] || a.variance[c] != b.variance[c]) return false;
        return true;
    };
    const std::size_t pixels = std::size_t(both.width) * std::size_t(both.height);
    int more = 0, neither = 0;
    for (std::size_t p = 0; p < pixels; ++p) {
        if (same(both, four, p)) continue;
        ++more;
        neither += !same(both, sixteen, p);
    }
    // Every pixel some part of which sees an LED in the inner surface (found on an 8 x 8 grid
    // of points per pixel, independently of the renderer's choice) took 16 samples.
    const CameraParams params{96, 96, 84.0};
    const FisheyeCamera camera(params);
    FastOnFrame on(pressed);
    int bright = 0, missed = 0;
    for (int y = 0; y < params.height_px; ++y)
        for (int x = 0; x < params.width_px; ++x) {
            bool mirrors = false;
            for (int i = 0; i < 64 && !mirrors; ++i) {
                const auto d =
                    camera.direction(Eigen::Vector2d(x + (i % 8 + 0.5) / 8, y + (i / 8 + 0.5) / 8));
                if (!d) continue;
                const RayHit hit =
                    on.scene.closest_hit(Vec3::Zero(), *d, 0.0, std::numeric_limits<double>::max());
                if (!hit.hit() || hit.kind != SurfaceKind::inner_surface) continue;
                const Vec3 n = hit.shading_normal.dot(*d) > 0.0 ? Vec3(-hit.shading_normal)
                                                                : hit.shading_normal;
                const Vec3 reflected = (*d - 2.0 * d->dot(n) * n).normalized();
                mirrors =
                    on.path
                        .led_hit(hit.t_mm * *d, reflected, 1e-6, std::numeric_limits<double>::max())
                        .has_value();
            }
            if (!mirrors) continue;
            ++bright;
            missed += same(both, four, std::size_t(y) * std::size_t(params.width_px) + x);
        }
    INFO(more << " of " << pixels << " pixels with 16 samples; " << bright
              << " see an LED in the inner surface, " << missed << " of them with 4");
    CHECK(neither == 0);
    CHECK(more > 0);
    CHECK(more < int(pixels / 5));
    CHECK(bright > 0);
    CHECK(missed == 0);
    // At most samples_per_pixel (0 included): none take more, the same bytes.
    for (const int n : {0, 4}) {
        settings.reflection_samples_per_pixel = n;
        CHECK(renderer.render(settings).rgb == four.rgb);
    }
    settings.reflection_samples_per_pixel = -1;
    CHECK_THROWS_WITH(renderer.render(settings),
                      Catch::Contains("reflection_samples_per_pixel = -1 is invalid"));
}

// The LEDs in the inner surface, left out of a sample and given apart (reflected_leds16),
// add up to it to round-off.
TEST_CASE("fast integrator: the LEDs seen by reflection and given apart add up to the sample",
          "[render][fast]") {
    const SensorFrame rest = dome_with_box_markers();
    const SensorFrame pressed = pressed_flat(rest);
    FastOnFrame on(pressed, rest);
    auto& [scene, shading, path, fast] = on;
    const LaneOptics<kRgbLanes> lanes = shading.rgb_lanes();
    const RgbLanes led = lanes.led / path.led_area_mm2();
    // Packets of 16 directions over the grazing band, where the LEDs are mirrored.
    int samples = 0, mirrored = 0, unchanged = 0;
    for (double polar = 55.0; polar < 90.0; polar += 0.5) {
        for (double azimuth0 = 0.0; azimuth0 < 360.0; azimuth0 += 16.0) {
            std::vector<Vec3> directions;
            for (int i = 0; i < 16; ++i)
                directions.push_back(unit_from_angles(polar, azimuth0 + i));
            const std::size_t n = directions.size();
            const std::vector<ShadowDraw> shadow(n, ShadowDraw{0.4, 0.3, 0.8});
            const std::vector<const LaneOptics<kRgbLanes>*> lane_sets(n, &lanes);
            const std::vector<const CacheLambdas<kRgbLanes>*> lambdas(n, nullptr);
            std::vector<RgbLanes> with(n), without(n);
            std::vector<double> fresnel(n, -1.0);
            PixelRng a(3, std::uint64_t(polar * 1000 + azimuth0)), b = a;
            std::vector<PixelRng*> streams_a(n, &a), streams_b(n, &b);
            fast.radiance16<kRgbLanes>(scene, Vec3::Zero(), directions, lane_sets, lambdas, shadow,
                                       streams_a, with);
            fast.radiance16<kRgbLanes>(scene, Vec3::Zero(), directions, lane_sets, lambdas, shadow,
                                       streams_b, without, {}, false);
            fast.reflected_leds16(scene, Vec3::Zero(), directions, fresnel);
            for (std::size_t i = 0; i < n; ++i) {
                INFO("polar " << polar << ", azimuth " << azimuth0 + double(i));
                CHECK(fresnel[i] >= 0.0);
                CHECK(fresnel[i] < 1.0);
                const RgbLanes sum = without[i] + fresnel[i] * led;
                CHECK(((sum - with[i]).abs() <= 1e-12 * with[i].abs().max(1.0)).all());
                ++samples;
                mirrored += fresnel[i] > 0.0;
                unchanged += fresnel[i] == 0.0 && (with[i] == without[i]).all();
            }
        }
    }
    INFO(samples << " samples, " << mirrored << " see an LED by reflection");
    CHECK(mirrored > 20);
    CHECK(samples - mirrored == unchanged); // elsewhere the same bits
    CHECK_THROWS_WITH(
        fast.reflected_leds16(scene, Vec3::Zero(), std::vector<Vec3>(17, Vec3::UnitZ()), {}),
        Catch::Contains("allowed: at most 16"));
}

// reflected_led_samples_per_pixel: the pixels that mirror an LED are as bright on average, in
// RGB and spectral mode; the other pixels keep their bytes.
TEST_CASE("fast integrator: reflected LEDs from rays of their own keep the brightness with less "
          "noise",
          "[render][fast]") {
    const SensorFrame rest = dome_with_box_markers();
    const SensorFrame pressed = pressed_flat(rest);
    const OpticsParams spectral = spectral_optics();
    for (const OpticsParams& optics : {OpticsParams{}, spectral}) {
        INFO("spectral " << bool(optics.spectra));
        Renderer renderer(CameraParams{96, 96, 84.0}, optics);
        small_cache_on(renderer, rest, pressed);
        RenderSettings settings = fast_with_variance(4, 5);
        const Image plain = renderer.render(settings);
        settings.reflected_led_samples_per_pixel = 64;
        const Image apart = renderer.render(settings);
        // Another stream than the samples' own: a converged image of each kind to compare with.
        settings.reflected_led_samples_per_pixel = 0;
        settings.samples_per_pixel = 256;
        settings.seed = 9;
        const Image converged = renderer.render(settings);
        const std::size_t pixels = std::size_t(plain.width) * std::size_t(plain.height);
        int changed = 0;
        double sum_plain = 0.0, sum_apart = 0.0, sum_converged = 0.0, var_plain = 0.0,
               var_apart = 0.0, err2_plain = 0.0, err2_apart = 0.0;
        for (std::size_t p = 0; p < pixels; ++p) {
            bool same = true;
            for (std::size_t c = 3 * p; c < 3 * p + 3; ++c)
                same =
                    same && plain.rgb[c] == apart.rgb[c] && plain.variance[c] == apart.variance[c];
            if (same) continue;
            ++changed;
            for (std::size_t c = 3 * p; c < 3 * p + 3; ++c) {
                sum_plain += plain.rgb[c], sum_apart += apart.rgb[c];
                sum_converged += converged.rgb[c];
                var_plain += plain.variance[c], var_apart += apart.variance[c];
                err2_plain += std::pow(plain.rgb[c] - converged.rgb[c], 2.0);
                err2_apart += std::pow(apart.rgb[c] - converged.rgb[c], 2.0);
            }
        }
        INFO(changed << " pixels changed; sums " << sum_plain << ", " << sum_apart << ", converged "
                     << sum_converged << "; summed variances " << var_plain << ", " << var_apart
                     << "; squared errors " << err2_plain << ", " << err2_apart);
        // Only the pixels where an LED is mirrored (fewer than a fifth) change.
        CHECK(changed > 0);
        CHECK(changed < int(pixels / 5));
        // Both unbiased: the sums over those pixels agree within 4 standard deviations of
        // their difference (the variances of the sums, each pixel's channels independent).
        CHECK(std::abs(sum_apart - sum_plain) < 4.0 * std::sqrt(var_plain + var_apart));
        CHECK(std::abs(sum_apart - sum_converged) < 4.0 * std::sqrt(var_apart) + 1e-3);
        // The LEDs' images were most of those pixels' noise.
        CHECK(var_apart < 0.6 * var_plain);
        CHECK(err2_apart < 0.6 * err2_plain);
        // And the variance channel says how much is left: the samples' variance about their
        // own mean plus the LED rays' (0.21.0 took it about the pixel's mean with the LEDs
        // in, a third too low here), of the order of the squared error against the converged
        // image (above it: the channel takes the stratified samples as independent; 3.7 times
        // here since the frame's share took the frame's binary shadows out of these pixels,
        // 1.8 to 2.1 times before).
        CHECK(var_apart > 0.3 * err2_apart);
        CHECK(var_apart < 5.0 * err2_apart);
        CHECK(var_plain > 0.3 * err2_plain);
        CHECK(var_plain < 5.0 * err2_plain);
    }
    Renderer renderer(CameraParams{16, 16, 84.0}, OpticsParams{});
    small_cache_on(renderer, rest, pressed);
    RenderSettings settings{4, 5};
    settings.integrator = Integrator::fast;
    settings.reflected_led_samples_per_pixel = -1;
    CHECK_THROWS_WITH(renderer.render(settings),
                      Catch::Contains("reflected_led_samples_per_pixel = -1 is invalid"));
}

// Cases: clear of the LEDs, overlapping, within the margin, enclosing one, and folded (no
// proof, so near).
TEST_CASE("the LED culling's quadrilateral test tells a quadrilateral clear of an LED from one "
          "near it",
          "[render][fast]") {
    const ShadingModel shading{OpticsParams{}};
    const PathIntegrator path{shading};
    const OpticsParams& o = shading.optics();
    const Vec3 c = path.led_point(0, 0.5, 0.5);
    const Vec3 t = (path.led_point(0, 1.0, 0.5) - c).normalized(),
               r = (path.led_point(0, 0.5, 1.0) - c).normalized();
    // A square of half-size h about centre m (in the LEDs' plane), in order round it.
    const auto square = [&](const Vec3& m, double h) {
        return std::array<Vec3, 4>{m - h * t - h * r, m + h * t - h * r, m + h * t + h * r,
                                   m - h * t + h * r};
    };
    const double half_w = 0.5 * o.led_width_mm;
    // Beside the LED along its width, 0.3 mm clear of it.
    const Vec3 beside = c + (half_w + 0.3 + 0.2) * t;
    CHECK_FALSE(path.quad_near_led(square(beside, 0.2), 0.25));
    CHECK(path.quad_near_led(square(beside, 0.2), 0.35));        // within the margin
    CHECK(path.quad_near_led(square(c + half_w * t, 0.2), 0.0)); // over its edge
    CHECK(path.quad_near_led(square(c, 5.0), 0.0));              // around the whole LED
    // A diamond off the LED's corner, its side facing the corner 0.28 mm away: the LED's own
    // axes overlap it, only the diamond's side separates them; grown by 0.25 mm, they meet.
    const Vec3 corner = c + half_w * t + 0.5 * o.led_height_mm * r;
    const Vec3 m = corner + 0.7 * t + 0.7 * r;
    const std::array<Vec3, 4> diamond = {m - 1.0 * t, m - 1.0 * r, m + 1.0 * t, m + 1.0 * r};
    CHECK_FALSE(path.quad_near_led(diamond, 0.0));
    CHECK(path.quad_near_led(diamond, 0.25));
    // Folded (a bow tie) or flat: no proof.
    std::array<Vec3, 4> bow = square(beside, 0.2);
    std::swap(bow[2], bow[3]);
    CHECK(path.quad_near_led(bow, 0.0));
    CHECK(path.quad_near_led({beside, beside, beside, beside}, 0.0));
}

// Each is as a render at that count would have it, exactly those whose corners' markers
// differ; the other pixels keep their bytes.
TEST_CASE("fast integrator: the pixels on a marker's rim take rim_samples_per_pixel",
          "[render][fast]") {
    const SensorFrame rest = dome_with_box_markers();
    const SensorFrame pressed = pressed_flat(rest);
    const CameraParams camera{96, 96, 84.0};
    Renderer renderer(camera, OpticsParams{});
    small_cache_on(renderer, rest, pressed);
    RenderSettings settings{2, 5};
    settings.integrator = Integrator::fast;
    settings.variance = true;
    settings.marker_ids = true;
    const Image two = renderer.render(settings);
    settings.samples_per_pixel = 6;
    const Image six = renderer.render(settings);
    settings.samples_per_pixel = 2;
    settings.rim_samples_per_pixel = 6;
    const Image both = renderer.render(settings);
    const auto same = [](const Image& a, const Image& b, std::size_t p) {
        for (std::size_t c = 3 * p; c < 3 * p + 3; ++c)
            if (a.rgb[c] != b.rgb[c] || a.variance[c] != b.variance[c]) return false;
        return true;
    };
    // Which pixels should take 6: those whose 4 corners' pairs of ids are not all the same.
    // The corners' ids from the id channels of another camera (written by another code path)
    // whose pixel centres are this one's corners: the same lens as Kannala-Brandt, one pixel
    // wider, its principal point half a pixel on.
    CameraParams corners = with_equidistant_intrinsics(camera);
    corners.model = CameraModel::kannala_brandt;
    corners.width_px = corners.height_px = 97;
    corners.cx_px = corners.cy_px = 48.0;
    Renderer at_corners(corners, OpticsParams{});
    small_cache_on(at_corners, rest, pressed);
    RenderSettings ids{1, 5};
    ids.integrator = Integrator::fast;
    ids.marker_ids = true;
    const Image corner_ids = at_corners.render(ids);
    const int w = both.width, h = both.height;
    const auto at = [w](int x, int y) { return std::size_t(y) * std::size_t(w) + x; };
    const auto corner = [&](int x, int y) {
        const std::size_t i = std::size_t(y) * 97 + std::size_t(x);
        return std::pair{corner_ids.inner_marker_id[i], corner_ids.outer_marker_id[i]};
    };
    int rims = 0, wrong = 0, neither = 0, centre_rule = 0;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const auto c = corner(x, y);
            const bool rim =
                corner(x + 1, y) != c || corner(x, y + 1) != c || corner(x + 1, y + 1) != c;
            rims += rim;
            // The centres' rule, for comparison: the centre's ids differ from one of its 8
            // neighbours'.
            bool wide = false;
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx) {
                    const int qx = x + dx, qy = y + dy;
                    if (qx < 0 || qy < 0 || qx >= w || qy >= h) continue;
                    wide = wide ||
                           two.inner_marker_id[at(qx, qy)] != two.inner_marker_id[at(x, y)] ||
                           two.outer_marker_id[at(qx, qy)] != two.outer_marker_id[at(x, y)];
                }
            centre_rule += wide;
            const std::size_t p = at(x, y);
            // Pixels outside the field are black at any count: either will do.
            const bool as_two = same(both, two, p), as_six = same(both, six, p);
            neither += !as_two && !as_six;
            wrong += rim ? !as_six : !as_two;
        }
    INFO(rims << " of " << w * h << " pixels on a rim (" << centre_rule
              << " by the centres' rule); " << wrong << " at the wrong count");
    CHECK(neither == 0);
    CHECK(wrong == 0);
    CHECK(rims > 50);
    // A band about half as wide as the centres' rule's.
    CHECK(rims < 0.7 * centre_rule);
    // At most samples_per_pixel (0 included): none take more, the same bytes.
    for (const int n : {0, 2}) {
        settings.rim_samples_per_pixel = n;
        CHECK(renderer.render(settings).rgb == two.rgb);
    }
    settings.rim_samples_per_pixel = -1;
    CHECK_THROWS_WITH(renderer.render(settings),
                      Catch::Contains("rim_samples_per_pixel = -1 is invalid"));
}

// It changes them only where the rims are found.
TEST_CASE("fast integrator: the shadow filter's own width on the markers' rims changes only the "
          "rims' pixels",
          "[render][fast]") {
    const SensorFrame rest = dome_with_box_markers();
    const SensorFrame pressed = pressed_flat(rest);
    Renderer renderer(CameraParams{96, 96, 84.0}, OpticsParams{});
    small_cache_on(renderer, rest, pressed);
    RenderSettings settings{2, 5};
    settings.integrator = Integrator::fast;
    settings.rim_samples_per_pixel = 6;
    settings.shadow_filter_px = 1.0;
    const Image plain = renderer.render(settings);
    // The rims' pixels: those that take 6 (their bytes differ from a 2-spp render's without
    // the filter; the filter spreads nothing here as both renders have none).
    RenderSettings unfiltered = settings;
    unfiltered.shadow_filter_px = 0.0;
    const Image rims_at_six = renderer.render(unfiltered);
    unfiltered.rim_samples_per_pixel = 0;
    const Image at_two = renderer.render(unfiltered);
    const std::size_t pixels = plain.rgb.size() / 3;
    std::vector<bool> rim(pixels);
    int rim_count = 0;
    for (std::size_t p = 0; p < pixels; ++p) {
        for (std::size_t c = 3 * p; c < 3 * p + 3; ++c)
            rim[p] = rim[p] || rims_at_six.rgb[c] != at_two.rgb[c];
        rim_count += rim[p];
    }
    REQUIRE(rim_count > 50);
    for (const double rim_sigma : {0.0, 0.4}) {
        INFO("rim sigma " << rim_sigma);
        settings.shadow_filter_rim_px = rim_sigma;
        const Image own = renderer.render(settings);
        int other_changed = 0, rims_changed = 0;
        for (std::size_t p = 0; p < pixels; ++p) {
            bool changed = false;
            for (std::size_t c = 3 * p; c < 3 * p + 3; ++c)
                changed = changed || own.rgb[c] != plain.rgb[c];
            (rim[p] ? rims_changed : other_changed) += changed;
        }
        CHECK(other_changed == 0);
        CHECK(rims_changed > rim_count / 4);
    }
    // Without the rims found (none take more samples) it changes nothing.
    settings.rim_samples_per_pixel = 0;
    settings.shadow_filter_rim_px.reset();
    const Image without = renderer.render(settings);
    settings.shadow_filter_rim_px = 0.4;
    CHECK(renderer.render(settings).rgb == without.rgb);
    for (const double bad : {-0.5, kMaxShadowFilterPx + 1.0}) {
        settings.shadow_filter_rim_px = bad;
        CHECK_THROWS_WITH(renderer.render(settings), Catch::Contains("shadow_filter_rim_px = ") &&
                                                         Catch::Contains("is invalid; allowed: 0"));
    }
}
