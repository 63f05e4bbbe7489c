// Tests of the fast integrator (render/fast_integrator.hpp): it agrees with the path integrator
// where its approximations hold (a dome without markers at rest), its images do not depend
// on the thread count, and a frame of another sensor is refused.
#include "render/embree_scene.hpp"
#include "render/fast_integrator.hpp"
#include "render/fisheye_camera.hpp"
#include "render/path_integrator.hpp"
#include "render/renderer.hpp"
#include "render/shading.hpp"
#include "test_meshes.hpp"

#include <Eigen/Geometry>
#include <catch2/catch.hpp>
#include <tbb/global_control.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <thread>

using namespace chromasim::render;
using namespace chromasim::render::detail;
using namespace chromasim::render::test;

namespace {

/// The fast integrator on a frame's scene, with the default optics (no spectra).
struct FastOnFrame {
    explicit FastOnFrame(const SensorFrame& frame) { scene.set_frame(frame); }
    /// And with a small light cache (8 paths, 4 LED points per vertex) built on `rest`.
    FastOnFrame(const SensorFrame& frame, const SensorFrame& rest) : FastOnFrame(frame) {
        LightCacheSettings settings;
        settings.paths_per_vertex = 8;
        settings.direct_samples = 4;
        fast.build_cache(rest, settings, nullptr, 1.0);
        fast.set_frame(frame, scene);
    }
    EmbreeScene scene;
    ShadingModel shading{OpticsParams{}};
    PathIntegrator path{shading};
    FastIntegrator fast{shading, path};
};

/// The light cache's LED vectors, [vertex * leds + k].
std::vector<Vec3> cached_vectors(const FastIntegrator& fast) {
    const std::vector<float>& d = fast.cache().direct;
    std::vector<Vec3> out;
    for (std::size_t i = 0; i + 2 < d.size(); i += 3)
        out.emplace_back(d[i], d[i + 1], d[i + 2]);
    return out;
}

/// The frame's LED vectors (FastIntegrator::frame_direct), in the same order.
std::vector<Vec3> frame_vectors(const FastIntegrator& fast, int vertices, int leds) {
    std::vector<Vec3> out;
    for (int v = 0; v < vertices; ++v)
        for (int k = 0; k < leds; ++k)
            out.push_back(fast.frame_direct(v, k));
    return out;
}

} // namespace

/// The coarse clear dome with a ring of box markers in each layer (12 triangles each).
SensorFrame dome_with_box_markers() {
    SensorFrame rest = clear_dome(16, 64, 24, 96);
    rest.inner_markers = box_markers(10.75, 0.5, 1.0);
    rest.outer_markers = box_markers(12.45, 0.5, 1.0);
    rest.triangles_per_marker = 12;
    return rest;
}

/// `rest` pressed by a plane tilted `degrees` about the y axis, both surfaces cut off beyond
/// it (as pressed_flat does level): the inner surface's cut is a flat facet the camera rays
/// meet far from normal incidence, so they bend there and their reflections cross the cavity
/// to the lit far wall.
SensorFrame pressed_tilted(const SensorFrame& rest, float degrees) {
    SensorFrame pressed = rest;
    const float tilt = degrees * float(std::numbers::pi) / 180.0f;
    const Eigen::Vector3f normal(std::sin(tilt), 0.0f, std::cos(tilt));
    for (auto [mesh, reach] :
         {std::pair{&pressed.inner_surface, 8.5f}, std::pair{&pressed.coating, 10.7f}})
        for (Eigen::Index v = 0; v < mesh->V.rows(); ++v) {
            const Eigen::Vector3f x = mesh->V.row(v).transpose();
            mesh->V.row(v) = (x - std::max(0.0f, normal.dot(x) - reach) * normal).transpose();
        }
    return pressed;
}

/// The default optics with the spectra of assets/spectra (spectral mode).
OpticsParams spectral_optics() {
    OpticsParams spectral;
    spectral.spectra = load_sensor_spectra(SensorSpectraFiles::in_directory(
        std::filesystem::path(CHROMASIM_SOURCE_DIR) / "assets" / "spectra"));
    return spectral;
}

/// The fast integrator at `spp` samples per pixel and `seed`, with the variance channel.
RenderSettings fast_with_variance(int spp, std::uint64_t seed) {
    RenderSettings settings{spp, seed};
    settings.integrator = Integrator::fast;
    settings.variance = true;
    return settings;
}

/// The tests' small light cache: 8 paths, 4 LED points per vertex.
LightCacheSettings small_cache() {
    LightCacheSettings cache;
    cache.paths_per_vertex = 8;
    cache.direct_samples = 4;
    return cache;
}

/// The renderer's light cache (by default the small one) built on `rest`, then `frame` loaded.
void small_cache_on(Renderer& renderer, const SensorFrame& rest, const SensorFrame& frame,
                    const LightCacheSettings& cache = small_cache()) {
    renderer.set_light_cache(rest, cache);
    renderer.set_frame(frame);
}

TEST_CASE("fast integrator: on a dome without markers it agrees with the path integrator",
          "[render][fast]") {
    const SensorFrame frame = clear_dome(16, 64, 24, 96);
    EmbreeScene scene;
    scene.set_frame(frame);
    OpticsParams optics;
    optics.coating_albedo = Vec3(0.85, 0.6, 0.3);
    const ShadingModel shading(optics);
    const PathIntegrator path(shading);
    FastIntegrator fast(shading, path);
    LightCacheSettings settings;
    settings.paths_per_vertex = 256;
    fast.build_cache(frame, settings, nullptr, 1.0);
    fast.set_frame(frame, scene);
    const auto lanes = shading.rgb_lanes();
    for (double polar : {0.0, 40.0, 70.0}) {
        const Vec3 d = unit_from_angles(polar, 15.0);
        constexpr int kPaths = 40000, kFast = 64;
        RgbLanes p = RgbLanes::Zero(), p2 = RgbLanes::Zero(), f = RgbLanes::Zero();
        for (int i = 0; i < kPaths; ++i) {
            PixelRng rng(3, std::uint64_t(i));
            const RgbLanes L = path.radiance(scene, Vec3::Zero(), d, lanes, rng);
            p += L;
            p2 += L.square();
        }
        for (int i = 0; i < kFast; ++i) {
            PixelRng rng(4, std::uint64_t(i));
            f += fast.radiance<kRgbLanes>(scene, Vec3::Zero(), d, lanes, nullptr, rng);
        }
        p /= kPaths;
        f /= kFast;
        const RgbLanes se = ((p2 / kPaths - p.square()).max(0.0) / (kPaths - 1.0)).sqrt();
        for (int c = 0; c < 3; ++c) {
            INFO("polar " << polar << " deg, lane " << c << ": fast " << f[c] << ", path " << p[c]
                          << " +- " << se[c]);
            // Within 8 % plus 4 standard errors of the path estimate: the light cache's own
            // error (interpolation, smoothing, its heavy-tailed noise). Measured: -1.5 to
            // +0.2 % at 0 and 40 deg, +3.2 to +6.3 % at 70 deg (towards the rim). Leaving out
            // the indirect light (more than half of it here) or the refraction would be far
            // outside.
            CHECK(se[c] < 0.01 * p[c]);
            CHECK(std::abs(f[c] - p[c]) < 0.08 * p[c] + 4.0 * se[c]);
        }
    }
}

TEST_CASE("fast integrator: the same image with 1 and 2 threads, a light cache of another "
          "sensor is refused",
          "[render][fast]") {
    const SensorFrame frame = clear_dome(16, 64, 24, 96);
    Renderer renderer(CameraParams{24, 24, 84.0}, OpticsParams{});
    renderer.set_frame(frame);
    RenderSettings settings;
    settings.integrator = Integrator::fast;
    settings.samples_per_pixel = 2;
    CHECK_THROWS_WITH(renderer.render(settings),
                      Catch::Contains("Integrator::fast needs set_light_cache"));
    const LightCacheSettings cache = small_cache();
    Image one, two;
    {
        tbb::global_control threads(tbb::global_control::max_allowed_parallelism, 1);
        renderer.set_light_cache(frame, cache);
        renderer.set_frame(frame);
        one = renderer.render(settings);
    }
    {
        tbb::global_control threads(tbb::global_control::max_allowed_parallelism, 2);
        renderer.set_light_cache(frame, cache);
        renderer.set_frame(frame);
        two = renderer.render(settings);
    }
    REQUIRE(one.rgb.size() == two.rgb.size());
    CHECK(one.rgb == two.rgb);
    double sum = 0.0;
    for (float v : one.rgb)
        sum += v;
    CHECK(sum > 0.0);

    SensorFrame other = frame;
    other.coating = hemisphere(12.7, 12, 48);
    CHECK_THROWS_WITH(renderer.set_frame(other),
                      Catch::Contains("the light cache's") && Catch::Contains("allowed:"));
}

// Where the press deforms it, the sphere model alone is far off.
TEST_CASE("fast integrator: shadow rays follow the deformed inner surface's refraction",
          "[render][fast]") {
    const SensorFrame rest = clear_dome(16, 64, 24, 96);
    FastOnFrame on(rest);
    auto& [scene, shading, path, fast] = on;
    LightCacheSettings settings;
    settings.paths_per_vertex = 8;
    settings.direct_samples = 4;
    fast.build_cache(rest, settings, nullptr, 1.0);
    const SensorFrame pressed = pressed_flat(rest);
    scene.set_frame(pressed);
    fast.set_frame(pressed, scene);

    double sum2_fast = 0.0, sum2_sphere = 0.0, max_fast = 0.0;
    int n = 0;
    const auto& F = pressed.coating.F;
    for (Eigen::Index t = 0; t < F.rows(); ++t) {
        Vec3 p = Vec3::Zero();
        for (int i = 0; i < 3; ++i)
            p += pressed.coating.V.row(F(t, i)).cast<double>().transpose() / 3.0;
        if (p.normalized().z() < std::cos(50.0 * std::numbers::pi / 180.0)) continue;
        const auto radius = path.radius_below(scene, p);
        REQUIRE(radius);
        for (int k = 0; k < path.led_count(); ++k) {
            const Vec3 l = path.led_point(k, 0.2, 0.7); // off the LED's centre
            const auto exact = path.connect(scene, p, l, Chain::refracted, 0.5, *radius);
            if (!exact) continue;
            const auto angle = [&](const Vec3& w) {
                return std::acos(std::clamp(w.dot(exact->direction), -1.0, 1.0));
            };
            const double a_fast =
                angle(fast.shadow_direction(std::uint32_t(t), 1.0 / 3.0, 1.0 / 3.0, p, k, l));
            const double a_sphere = angle(path.refracted_direction(p, l, *radius));
            sum2_fast += a_fast * a_fast;
            sum2_sphere += a_sphere * a_sphere;
            max_fast = std::max(max_fast, a_fast);
            ++n;
        }
    }
    const double rms_fast = std::sqrt(sum2_fast / n), rms_sphere = std::sqrt(sum2_sphere / n);
    INFO(n << " shadow rays: RMS angle to the Newton solve " << rms_fast << " rad (max " << max_fast
           << "), the sphere model alone " << rms_sphere << " rad");
    CHECK(n > 500);
    CHECK(rms_sphere > 0.02);
    CHECK(rms_fast < 0.25 * rms_sphere);
    CHECK(max_fast < 0.05);
}

// The frame re-estimates the LEDs' light there as a cache built on that frame holds it.
TEST_CASE("fast integrator: where a contact bends the coating the LEDs' light matches a cache of "
          "that frame",
          "[render][fast]") {
    const SensorFrame rest = clear_dome(16, 64, 24, 96);
    const SensorFrame pressed = pressed_flat(rest);
    EmbreeScene scene;
    scene.set_frame(pressed);
    const ShadingModel shading(OpticsParams{});
    const PathIntegrator path(shading);
    LightCacheSettings settings;
    settings.paths_per_vertex = 8;
    settings.direct_samples = 16;
    const auto frame_light = [&](const SensorFrame& cache_on, bool refresh) {
        FastIntegrator fast(shading, path);
        LightCacheSettings s = settings;
        s.refresh_direct = refresh;
        s.refresh_threshold = 0.0; // every vertex and LED
        fast.build_cache(cache_on, s, nullptr, 1.0);
        fast.set_frame(pressed, scene);
        return frame_vectors(fast, int(pressed.coating.V.rows()), path.led_count());
    };
    std::vector<Vec3> truth; // the area LEDs' light in a cache built on the frame itself
    {
        FastIntegrator fast(shading, path);
        fast.build_cache(pressed, settings, nullptr, 1.0);
        truth = cached_vectors(fast);
    }
    const std::vector<Vec3> refreshed = frame_light(rest, true);
    const std::vector<Vec3> stale = frame_light(rest, false);
    // Over the flattened cap (the vertices the press moved) and every LED.
    double e_refreshed = 0.0, e_stale = 0.0, norm = 0.0;
    int pairs = 0;
    for (int v = 0; v < int(pressed.coating.V.rows()); ++v) {
        if (!(rest.coating.V(v, 2) > 11.2f)) continue;
        for (int k = 0; k < path.led_count(); ++k) {
            const std::size_t i = std::size_t(v) * path.led_count() + k;
            e_refreshed += (refreshed[i] - truth[i]).squaredNorm();
            e_stale += (stale[i] - truth[i]).squaredNorm();
            norm += truth[i].squaredNorm();
            ++pairs;
        }
    }
    const double rms_refreshed = std::sqrt(e_refreshed / norm),
                 rms_stale = std::sqrt(e_stale / norm);
    INFO(pairs << " vertex-LED pairs on the cap: RMS off the frame's own cache " << rms_refreshed
               << " refreshed, " << rms_stale << " with the rest ratio");
    CHECK(pairs > 100);
    CHECK(rms_stale > 0.05);
    // The same streams on the same geometry: the cache's values to rounding.
    CHECK(rms_refreshed < 1e-5);
}

// Over a coating triangle it is closer to the light than the corners' linear interpolation.
TEST_CASE("fast integrator: the LEDs' light interpolated quadratically over a triangle beats the "
          "linear one",
          "[render][fast]") {
    const SensorFrame rest = clear_dome(8, 32, 24, 96); // coarse triangles, about 2.5 mm
    FastOnFrame on(rest);
    auto& [scene, shading, path, fast] = on;
    LightCacheSettings settings;
    settings.paths_per_vertex = 16;
    settings.direct_samples = 16;
    // The LEDs' unshadowed light alone (the frame's share near the rim is a shadow: its own
    // test below).
    settings.frame_share = false;
    fast.build_cache(rest, settings, nullptr, 1.0);
    fast.set_frame(rest, scene);
    const double nee_ratio = kCacheBsdfPerNee; // the cache's MIS weights
    const auto& V = rest.coating.V;
    const auto& F = rest.coating.F;
    double e_quadratic = 0.0, e_linear = 0.0, norm = 0.0, bias_sum = 0.0, truth_sum = 0.0;
    int points = 0;
    for (Eigen::Index t = 0; t < F.rows(); t += 3) {
        const Vec3 a = V.row(F(t, 0)).cast<double>().transpose();
        const Vec3 b = V.row(F(t, 1)).cast<double>().transpose();
        const Vec3 c = V.row(F(t, 2)).cast<double>().transpose();
        Vec3 n = (b - a).cross(c - a).normalized();
        if (n.dot(a) > 0.0) n = -n;            // towards the dome centre
        const double w[3] = {0.5, 0.25, 0.25}; // off the corners and the midpoints
        const Vec3 p = w[0] * a + w[1] * b + w[2] * c + kHitGap_mm * n;
        for (int k = 0; k < path.led_count(); ++k) {
            // The light itself: 64 stratified LED points, the cache's MIS weights.
            Vec3 g = Vec3::Zero();
            for (int i = 0; i < 64; ++i)
                g += path.led_flux_sample(scene, p, n, k, (i % 8 + 0.5) / 8, (i / 8 + 0.5) / 8,
                                          (i + 0.5) / 64, nee_ratio) /
                     64.0;
            const double truth = std::max(0.0, g.dot(n));
            double linear = 0.0;
            for (int i = 0; i < 3; ++i)
                linear += w[i] * fast.frame_direct(int(F(t, i)), k).dot(n);
            const double quadratic = fast.direct_at(std::uint32_t(t), w[1], w[2], n, k);
            e_quadratic += (quadratic - truth) * (quadratic - truth);
            bias_sum += quadratic - truth;
            truth_sum += truth;
            e_linear += (std::max(0.0, linear) - truth) * (std::max(0.0, linear) - truth);
            norm += truth * truth;
            ++points;
        }
    }
    const double rms_quadratic = std::sqrt(e_quadratic / norm),
                 rms_linear = std::sqrt(e_linear / norm);
    INFO(points << " points: RMS off the light " << rms_quadratic << " quadratic, " << rms_linear
                << " linear");
    CHECK(points > 300);
    CHECK(rms_quadratic < 0.6 * rms_linear);
    // The mean: -1.2 % on these 2.5 mm triangles; -2.3 % when the frame took the point LED's
    // direction with the area LED's length.
    INFO("mean off the light " << bias_sum / truth_sum);
    CHECK(std::abs(bias_sum / truth_sum) < 0.015);
}

TEST_CASE("fast integrator: at rest the frame's LED light is the cache's own, vector for vector",
          "[render][fast]") {
    const SensorFrame rest = clear_dome(8, 32, 24, 96);
    FastOnFrame on(rest);
    auto& [scene, shading, path, fast] = on;
    LightCacheSettings settings;
    settings.paths_per_vertex = 4;
    settings.direct_samples = 16;
    settings.refresh_direct = false;
    fast.build_cache(rest, settings, nullptr, 1.0);
    fast.set_frame(rest, scene);
    const std::vector<Vec3> cached = cached_vectors(fast);
    const std::vector<Vec3> frame =
        frame_vectors(fast, int(rest.coating.V.rows()), path.led_count());
    double e2 = 0.0, norm2 = 0.0;
    int lit = 0;
    for (std::size_t i = 0; i < cached.size(); ++i) {
        e2 += (frame[i] - cached[i]).squaredNorm();
        norm2 += cached[i].squaredNorm();
        lit += cached[i].squaredNorm() > 0.0;
    }
    INFO(lit << " lit vertex-LED pairs, RMS off the cache " << std::sqrt(e2 / norm2));
    CHECK(lit > 300);
    CHECK(std::sqrt(e2 / norm2) < 1e-5);
    // And the indirect light is the cache's.
    CHECK(fast.indirect_scale() == Approx(1.0).margin(1e-6));
}

// It gives the same bits at rest, the sphere model's values where the press leaves the
// connections, each connection once, the reflections from the given starts alone.
TEST_CASE("fast integrator: a frame's point-LED light is solved from the connections found at rest",
          "[render][fast]") {
    const SensorFrame rest = clear_dome(16, 64, 24, 96);
    const SensorFrame pressed = pressed_flat(rest);
    EmbreeScene at_rest, at_press;
    at_rest.set_frame(rest);
    at_press.set_frame(pressed);
    const ShadingModel shading(OpticsParams{});
    const PathIntegrator path(shading);
    // A coating vertex's point a hair off it towards the cavity, and the normal there.
    const auto normal_at = [](const SensorFrame& f, int v) -> Vec3 {
        return -f.coating.V.row(v).cast<double>().transpose().normalized();
    };
    const auto point_at = [&](const SensorFrame& f, int v) -> Vec3 {
        return f.coating.V.row(v).cast<double>().transpose() + kHitGap_mm * normal_at(f, v);
    };
    int reflected = 0, compared = 0, agree = 0, pairs = 0;
    double without_reflections = 0.0, with_reflections = 0.0;
    for (int v = 0; v < int(rest.coating.V.rows()); v += 7)
        for (int k = 0; k < path.led_count(); ++k) {
            const Vec3 p = point_at(rest, v), n = normal_at(rest, v);
            PointLedPaths found;
            const Vec3 sphere =
                path.led_flux_point(at_rest, p, n, k, std::nullopt, nullptr, nullptr, &found);
            ++pairs;
            reflected += int(found.reflected.size());
            // At rest every solve starts at its own answer.
            CHECK(path.led_flux_point(at_rest, p, n, k, std::nullopt, nullptr, &found) == sphere);
            if (!found.reflected.empty()) {
                // A start given twice finds one connection, counted once.
                PointLedPaths twice = found;
                twice.reflected.push_back(found.reflected.front());
                CHECK(path.led_flux_point(at_rest, p, n, k, std::nullopt, nullptr, &twice) ==
                      sphere);
                // The reflections come from the given starts alone.
                PointLedPaths none = found;
                none.reflected.clear();
                without_reflections +=
                    path.led_flux_point(at_rest, p, n, k, std::nullopt, nullptr, &none).norm();
                with_reflections += sphere.norm();
            }
            // Off the flattened cap the rest's starts and the sphere model's find the same
            // connections.
            if (rest.coating.V(v, 2) > 10.0f) continue;
            const Vec3 q = point_at(pressed, v), m = normal_at(pressed, v);
            const Vec3 a = path.led_flux_point(at_press, q, m, k);
            const Vec3 b = path.led_flux_point(at_press, q, m, k, std::nullopt, nullptr, &found);
            ++compared;
            agree += (a - b).norm() <= 1e-6 * std::max(a.norm(), 1e-12);
        }
    INFO(pairs << " vertex-LED pairs, " << reflected << " reflections at rest; " << agree << " of "
               << compared << " pairs off the cap agree under the press; light with "
               << with_reflections << " and without " << without_reflections << " the reflections");
    CHECK(reflected > pairs / 4);
    CHECK(without_reflections < 0.99 * with_reflections);
    CHECK(compared > 100);
    // Measured: 544 of 552 (a reflection off the flattened cap, or a start in another
    // basin, can differ).
    CHECK(agree >= compared - compared / 20);
}

// The optional scale follows the coating's LED light.
TEST_CASE("fast integrator: under a press the rest cache's indirect light matches a pressed "
          "frame's cache",
          "[render][fast]") {
    const SensorFrame rest = clear_dome(16, 64, 24, 96);
    const SensorFrame pressed = pressed_flat(rest);
    FastOnFrame on(pressed);
    auto& [scene, shading, path, fast] = on;
    LightCacheSettings settings;
    settings.paths_per_vertex = 128;
    settings.direct_samples = 16;
    settings.scale_indirect = true;
    fast.build_cache(rest, settings, nullptr, 1.0);
    fast.set_frame(pressed, scene);
    const double scale = fast.indirect_scale();
    // The truth: the indirect light path-traced on the pressed frame (a cache built there,
    // the same streams per vertex), averaged over the coating, over the rest cache's.
    FastIntegrator own(shading, path);
    own.build_cache(pressed, settings, nullptr, 1.0);
    const auto mean_indirect = [](const LightCache& c, const SurfaceMesh& coating) {
        double sum = 0.0, area = 0.0;
        for (Eigen::Index f = 0; f < coating.F.rows(); ++f) {
            const Vec3 a = coating.V.row(coating.F(f, 0)).cast<double>().transpose();
            const Vec3 b = coating.V.row(coating.F(f, 1)).cast<double>().transpose();
            const Vec3 d = coating.V.row(coating.F(f, 2)).cast<double>().transpose();
            const double third = (b - a).cross(d - a).norm() / 6.0;
            for (int k = 0; k < 3; ++k)
                for (int j = 0; j < 3; ++j) // the RGB lanes
                    sum += third * c.indirect[std::size_t(coating.F(f, k)) * c.lanes + j];
            area += 3.0 * third;
        }
        return sum / area;
    };
    const double truth =
        mean_indirect(own.cache(), pressed.coating) / mean_indirect(fast.cache(), rest.coating);
    INFO("indirect light pressed / rest: " << truth << " path-traced, " << scale << " scaled");
    // The path integrator finds a press's indirect light unchanged to 1 %: the default keeps
    // the rest value. The scale (render.fast.scale_indirect) follows the cache's point-LED
    // flux onto the coating, which the press lowers.
    CHECK(std::abs(truth - 1.0) < 0.01);
    CHECK(scale < 1.0);
    CHECK(scale > 0.95);
    const FastOnFrame plain(pressed, rest); // the default settings: no scale
    CHECK(plain.fast.indirect_scale() == 1.0);
}

TEST_CASE("fast integrator: the light cache's LED light does not depend on how many indirect "
          "paths it traces",
          "[render][fast]") {
    // The cache splits the LEDs' light between its direct term (updated vertex by vertex per
    // frame) and its indirect term (only scaled) by MIS weights; with weights from the actual
    // sample counts, more paths moved light into the indirect term.
    const SensorFrame rest = clear_dome(8, 32, 24, 96);
    const auto direct_with = [&](int paths) {
        FastOnFrame on(rest);
        LightCacheSettings settings;
        settings.paths_per_vertex = paths;
        settings.direct_samples = 16;
        on.fast.build_cache(rest, settings, nullptr, 1.0);
        return on.fast.cache().direct;
    };
    const std::vector<float> few = direct_with(4), more = direct_with(64);
    REQUIRE(few.size() == more.size());
    double lit = 0.0;
    for (float g : few)
        lit += std::abs(g);
    CHECK(lit > 0.0);
    CHECK(few == more); // the same streams per vertex and LED: the same bytes
}

// Checked in RGB and spectral mode, with variance and marker ids.
TEST_CASE("fast integrator: neighbouring pixels traced together give each pixel the bytes it gets "
          "alone",
          "[render][fast]") {
    const SensorFrame rest = dome_with_box_markers();
    const SensorFrame pressed = pressed_flat(rest);
    const OpticsParams spectral = spectral_optics();
    for (const OpticsParams& optics : {OpticsParams{}, spectral}) {
        // 23 px wide: batches of 16 / n pixels end part-way along each row.
        Renderer renderer(CameraParams{23, 17, 84.0}, optics);
        small_cache_on(renderer, rest, pressed);
        for (const int spp : {1, 3, 4, 5, 8, 16, 20}) {
            RenderSettings settings{spp, 11};
            settings.integrator = Integrator::fast;
            settings.variance = true;
            settings.marker_ids = true;
            settings.batch_pixels = true;
            const Image together = renderer.render(settings);
            settings.batch_pixels = false;
            const Image alone = renderer.render(settings);
            INFO("spectral " << bool(optics.spectra) << ", " << spp << " spp");
            double lit = 0.0;
            for (const float v : alone.rgb)
                lit += v;
            CHECK(lit > 0.0);
            CHECK(together.rgb == alone.rgb);
            CHECK(together.variance == alone.variance);
            CHECK(together.inner_marker_id == alone.inner_marker_id);
            CHECK(together.outer_marker_id == alone.outer_marker_id);
            // And another seed gives another image: the comparison can fail.
            settings.seed = 12;
            CHECK(renderer.render(settings).rgb != alone.rgb);
        }
        // The pixels at counts of their own, where an LED is mirrored (8: runs of 2) and on
        // the markers' rims (5: runs of 3), with and without the runs.
        RenderSettings settings{2, 11};
        settings.integrator = Integrator::fast;
        settings.variance = true;
        const Image plain = renderer.render(settings);
        settings.reflection_samples_per_pixel = 8;
        const Image mirrored = renderer.render(settings);
        settings.edge_samples_per_pixel = 5;
        settings.batch_pixels = true;
        const Image together = renderer.render(settings);
        settings.batch_pixels = false;
        const Image alone = renderer.render(settings);
        INFO("spectral " << bool(optics.spectra) << ", 2 spp, 8 where mirrored, 5 on the rims");
        CHECK(mirrored.rgb != plain.rgb);    // some pixels mirror an LED
        CHECK(together.rgb != mirrored.rgb); // some lie on a rim
        CHECK(together.rgb == alone.rgb);
        CHECK(together.variance == alone.variance);
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
            settings.edge_samples_per_pixel = 5;
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

// The same bytes as tracing them all (256 a pixel), at rest and pressed, in fewer rays.
TEST_CASE("fast integrator: the LED rays are skipped only in pixels that provably mirror no LED",
          "[render][fast]") {
    const SensorFrame rest = dome_with_box_markers();
    for (const auto& [name, frame] : {std::pair<const char*, SensorFrame>{"at rest", rest},
                                      {"pressed flat", pressed_flat(rest)}}) {
        Renderer renderer(CameraParams{48, 48, 84.0}, OpticsParams{});
        small_cache_on(renderer, rest, frame);
        RenderSettings settings = fast_with_variance(1, 3);
        settings.reflection_samples_per_pixel = 1;
        settings.reflected_led_samples_per_pixel = 256;
        Image images[2];
        std::uint64_t rays[2] = {0, 0};
        for (const bool cull : {false, true}) {
            settings.cull_reflected_leds = cull;
            renderer.count_rays(true);
            images[cull] = renderer.render(settings);
            rays[cull] = renderer.rays_counted();
            renderer.count_rays(false);
        }
        INFO(name << ": rays " << rays[1] << " with the skipped pixels, " << rays[0]
                  << " tracing all");
        // A skipped pixel's 256 rays would all have missed: not one byte changes.
        CHECK(images[1].rgb == images[0].rgb);
        CHECK(images[1].variance == images[0].variance);
        // Some pixels were skipped (each saves 256 rays, less its 4 corners').
        CHECK(rays[1] + 1000 < rays[0]);
    }
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
TEST_CASE("fast integrator: the pixels on a marker's rim take edge_samples_per_pixel",
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
    settings.edge_samples_per_pixel = 6;
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
            // The rule up to 0.22.0: the centre's ids differ from one of its 8 neighbours'.
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
        settings.edge_samples_per_pixel = n;
        CHECK(renderer.render(settings).rgb == two.rgb);
    }
    settings.edge_samples_per_pixel = -1;
    CHECK_THROWS_WITH(renderer.render(settings),
                      Catch::Contains("edge_samples_per_pixel = -1 is invalid"));
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
    settings.edge_samples_per_pixel = 6;
    settings.shadow_filter_px = 1.0;
    const Image plain = renderer.render(settings);
    // The rims' pixels: those that take 6 (their bytes differ from a 2-spp render's without
    // the filter; the filter spreads nothing here as both renders have none).
    RenderSettings unfiltered = settings;
    unfiltered.shadow_filter_px = 0.0;
    const Image rims_at_six = renderer.render(unfiltered);
    unfiltered.edge_samples_per_pixel = 0;
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
    settings.edge_samples_per_pixel = 0;
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

// The field's outer ring is as bright on average with less noise; the pixels away from the
// rim keep their bytes.
TEST_CASE("fast integrator: the frame's share of the LEDs' light taken apart near the rim lowers "
          "the noise",
          "[render][fast]") {
    const SensorFrame rest = dome_with_box_markers();
    const SensorFrame pressed = pressed_flat(rest);
    Image images[2];
    for (const bool share : {false, true}) {
        Renderer renderer(CameraParams{96, 96, 84.0}, OpticsParams{});
        LightCacheSettings cache = small_cache();
        cache.frame_share = share;
        small_cache_on(renderer, rest, pressed, cache);
        images[share] = renderer.render(fast_with_variance(8, 5));
    }
    // The field's outer ring (polar angles above 78 degrees), and the rest.
    double sums[2] = {0.0, 0.0}, variances[2] = {0.0, 0.0};
    int ring = 0, changed_inside = 0, changed_ring = 0;
    double innermost_change = 1.0;
    for (int y = 0; y < 96; ++y)
        for (int x = 0; x < 96; ++x) {
            const double r = std::hypot(x + 0.5 - 48.0, y + 0.5 - 48.0) / 48.0;
            const std::size_t p = std::size_t(y) * 96 + std::size_t(x);
            bool changed = false;
            for (std::size_t c = 3 * p; c < 3 * p + 3; ++c)
                changed = changed || images[0].rgb[c] != images[1].rgb[c];
            if (changed) innermost_change = std::min(innermost_change, r);
            if (r > 1.0) continue;
            if (r < 78.0 / 84.0) {
                changed_inside += changed;
                continue;
            }
            ++ring;
            changed_ring += changed;
            for (const int share : {0, 1})
                for (std::size_t c = 3 * p; c < 3 * p + 3; ++c) {
                    sums[share] += images[share].rgb[c];
                    variances[share] += images[share].variance[c];
                }
        }
    INFO(ring << " pixels in the ring, " << changed_ring << " changed; " << changed_inside
              << " changed inside it, the innermost at r " << innermost_change
              << "; ring sums " << sums[0] << " (plane tested) and " << sums[1]
              << " (share apart), summed variances " << variances[0] << " and " << variances[1]);
    CHECK(changed_ring > ring / 2);
    CHECK(changed_inside == 0);
    // The same mean within 4 standard deviations of the difference.
    CHECK(std::abs(sums[1] - sums[0]) < 4.0 * std::sqrt(variances[0] + variances[1]));
    CHECK(variances[1] < 0.5 * variances[0]);
}

// Checked at rest, pressed and where the coating folds inwards.
TEST_CASE("fast integrator: shadow rays culled where they provably meet nothing leave the image as "
          "it was",
          "[render][fast]") {
    const SensorFrame rest = dome_with_box_markers();
    // A groove 1.8 mm deep on the coating's ring at 61.9 degrees: shadow rays from above it
    // meet its wall (the culling that leaves out the folds fails here, 0.08 off).
    const SensorFrame groove = grooved(rest, 60.0, 63.0, 1.8);
    RenderSettings settings;
    settings.integrator = Integrator::fast;
    settings.samples_per_pixel = 4;
    for (const auto& [name, frame] : {std::pair<const char*, SensorFrame>{"at rest", rest},
                                      {"pressed flat", pressed_flat(rest)},
                                      {"grooved", groove}}) {
        std::vector<float> images[2];
        std::uint64_t rays[2] = {0, 0};
        for (const bool cull : {false, true}) {
            Renderer renderer(CameraParams{32, 32, 84.0}, OpticsParams{});
            LightCacheSettings cache = small_cache();
            cache.cull_shadows = cull;
            small_cache_on(renderer, rest, frame, cache);
            renderer.count_rays(true);
            images[cull] = renderer.render(settings).rgb;
            rays[cull] = renderer.rays_counted();
        }
        double worst = 0.0, mean = 0.0;
        for (std::size_t i = 0; i < images[0].size(); ++i) {
            worst = std::max(worst, double(std::abs(images[1][i] - images[0][i])));
            mean += images[0][i] / double(images[0].size());
        }
        INFO(name << ": largest difference " << worst << " (image mean " << mean << "), rays "
                  << rays[1] << " culled against " << rays[0] << " traced");
        CHECK(mean > 0.05);
        // The culling's shadow rays take their direction by Newton from the frame's guess,
        // to 3.4e-3 rad at most (kShadowStepTolerance); without it, over the whole bracket to
        // 1e-9: their shadows' edges move by microns (9.5e-5 here at most). A ray culled that
        // meets a marker would leave its shadow out (0.08 off in the groove).
        CHECK(worst < 5e-4);
        CHECK(double(rays[1]) < 0.95 * double(rays[0]));
    }
}

TEST_CASE("fast integrator: a pixel's samples traced in Embree packets of 16 match one by one to "
          "the bit",
          "[render][fast]") {
    const SensorFrame rest = dome_with_box_markers();
    const SensorFrame pressed = pressed_flat(rest);
    FastOnFrame on(pressed, rest);
    auto& [scene, shading, path, fast] = on;
    const LaneOptics<kRgbLanes> lanes = shading.rgb_lanes();
    // Bundles of 16 (and fewer) directions 1 degree across, from the apex to past the rim
    // (grazing, where the inner surface reflects most and the reflected ray meets the far
    // wall), over markers and bare coating. Not through the UV spheres' poles: a ray through
    // a vertex that many triangles share may take another of them in a packet than alone.
    int compared = 0, reflected = 0;
    for (const double polar : {0.1, 12.5, 25.0, 40.0, 62.5, 75.0, 83.0, 88.0}) {
        for (const double azimuth : {0.0, 33.0, 190.0}) {
            for (const std::size_t n : {std::size_t(16), std::size_t(5)}) {
                std::vector<Vec3> directions;
                std::vector<ShadowDraw> shadow;
                for (std::size_t i = 0; i < n; ++i) {
                    directions.push_back(unit_from_angles(polar + 0.25 * double(i % 4),
                                                          azimuth + 0.25 * double(i / 4)));
                    // Half the samples with their shadow uniforms given, half drawing them.
                    shadow.push_back(i % 2 ? ShadowDraw{}
                                           : ShadowDraw{(double(i) + 0.5) / double(n), 0.3, 0.8});
                }
                const std::vector<const LaneOptics<kRgbLanes>*> lane_sets(n, &lanes);
                const std::vector<const CacheLambdas<kRgbLanes>*> lambdas(n, nullptr);
                std::vector<RgbLanes> packed(n);
                // Two pixels' streams: the first half of the samples draws from one, the
                // rest from the other (a packet of two neighbouring pixels' samples).
                PixelRng a(7, std::uint64_t(polar * 1000 + azimuth)), b = a;
                PixelRng a2(8, std::uint64_t(polar * 1000 + azimuth)), b2 = a2;
                std::vector<PixelRng*> streams(n, &a);
                for (std::size_t i = n / 2; i < n; ++i)
                    streams[i] = &a2;
                fast.radiance16<kRgbLanes>(scene, Vec3::Zero(), directions, lane_sets, lambdas,
                                           shadow, streams, packed);
                for (std::size_t i = 0; i < n; ++i) {
                    const RgbLanes one =
                        fast.radiance<kRgbLanes>(scene, Vec3::Zero(), directions[i], lanes, nullptr,
                                                 i < n / 2 ? b : b2, shadow[i]);
                    INFO("polar " << polar << ", azimuth " << azimuth << ", sample " << i << " of "
                                  << n);
                    CHECK((packed[i] == one).all());
                    ++compared;
                    reflected += polar >= 75.0 && one.maxCoeff() > 0.0;
                }
                CHECK(a.uniform() == b.uniform()); // the same draws, in the same order
                CHECK(a2.uniform() == b2.uniform());
            }
        }
    }
    CHECK(compared == 8 * 3 * 21);
    CHECK(reflected > 0);
    CHECK_THROWS_WITH(fast.radiance16<kRgbLanes>(scene, Vec3::Zero(),
                                                 std::vector<Vec3>(17, Vec3::UnitZ()), {}, {}, {},
                                                 {}, std::span<RgbLanes>{}),
                      Catch::Contains("allowed: at most 16"));
}

// The direct light given apart adds up and changes no sample.
TEST_CASE("fast integrator: the shadow filter brings a noisy image nearer the converged one",
          "[render][fast]") {
    const SensorFrame rest = dome_with_box_markers();
    const SensorFrame pressed = pressed_flat(rest);
    // The parts of a sample (radiance16 with and without `direct`): the same radiance to the
    // bit, the shadowed light within the unshadowed, the rest (indirect light) not negative.
    {
        FastOnFrame on(pressed, rest);
        auto& [scene, shading, path, fast] = on;
        const LaneOptics<kRgbLanes> lanes = shading.rgb_lanes();
        int shadowed = 0, lit = 0, parts = 0, clear = 0;
        for (const double polar : {5.0, 30.0, 55.0, 70.0, 80.0}) {
            for (const double azimuth : {0.0, 20.0, 45.0, 100.0}) {
                constexpr std::size_t n = 16;
                std::vector<Vec3> directions;
                std::vector<ShadowDraw> shadow;
                for (std::size_t i = 0; i < n; ++i) {
                    directions.push_back(unit_from_angles(polar + 0.4 * double(i % 4),
                                                          azimuth + 0.4 * double(i / 4)));
                    shadow.push_back({(double(i) + 0.5) / double(n), 0.3, 0.7});
                }
                const std::vector<const LaneOptics<kRgbLanes>*> lane_sets(n, &lanes);
                const std::vector<const CacheLambdas<kRgbLanes>*> lambdas(n, nullptr);
                std::vector<RgbLanes> plain(n), split(n);
                std::vector<DirectLight<kRgbLanes>> direct(n);
                PixelRng a(3, 9), b = a;
                std::vector<PixelRng*> sa(n, &a), sb(n, &b);
                fast.radiance16<kRgbLanes>(scene, Vec3::Zero(), directions, lane_sets, lambdas,
                                           shadow, sa, plain);
                fast.radiance16<kRgbLanes>(scene, Vec3::Zero(), directions, lane_sets, lambdas,
                                           shadow, sb, split, direct);
                for (std::size_t i = 0; i < n; ++i) {
                    INFO("polar " << polar << ", azimuth " << azimuth << ", sample " << i);
                    CHECK((plain[i] == split[i]).all());
                    const DirectLight<kRgbLanes>& d = direct[i];
                    CHECK((d.shadowed() <= d.lit() * (1 + 1e-12)).all());
                    CHECK((d.shadowed() >= 0.0).all());
                    CHECK((split[i] - d.shadowed() >= -1e-12).all());
                    shadowed += (d.shadowed().head<3>() < 0.99 * d.lit().head<3>()).any();
                    lit += (d.lit().head<3>() > 0.0).all();
                    // Each part: its LED's group among the 6 (one per LED), its groups'
                    // shares of the unshadowed light adding up to 1 where there is any,
                    // and `clear` only where nothing was in the shadow ray's way.
                    CHECK((d.parts >= 0 && d.parts <= kMaxDirectParts));
                    for (int q = 0; q < d.parts; ++q) {
                        const DirectPart<kRgbLanes>& part = d.part[std::size_t(q)];
                        CHECK((part.group >= 0 && part.group < fast.shadow_groups()));
                        double share = 0.0;
                        for (const double s : part.share)
                            share += s;
                        if ((part.lit > 0.0).any()) {
                            CHECK(share == Approx(1.0).margin(1e-12));
                            for (int g = fast.shadow_groups(); g < kMaxShadowGroups; ++g)
                                CHECK(part.share[std::size_t(g)] == 0.0);
                        }
                        if (part.clear) CHECK((part.shadowed == part.lit).all());
                        parts += 1, clear += part.clear;
                    }
                }
            }
        }
        CHECK(lit > 200);     // most samples see LED light on the coating
        CHECK(shadowed > 10); // and some of them through a marker's shadow
        CHECK(fast.shadow_groups() == 6);
        INFO(parts << " parts, " << clear << " clear");
        CHECK(parts >= lit); // a part for every sample that meets the coating
        CHECK(clear > 0);
        CHECK(clear < parts);
    }
    // The image: a 1-spp render, filtered and not, against a 256-spp one (unfiltered). On
    // these box markers, most of the noise is the camera's samples across their sharp
    // edges, so the filter takes off about an eighth (on the shipped dome, at 896 px and
    // 4 spp, three fifths: docs/VALIDATION.md); with the direct light's parts mixed up
    // between pixels or swapped, it adds error.
    Renderer renderer(CameraParams{96, 96, 84.0}, OpticsParams{});
    small_cache_on(renderer, rest, pressed);
    RenderSettings settings{256, 3};
    settings.integrator = Integrator::fast;
    const Image converged = renderer.render(settings);
    settings.samples_per_pixel = 1;
    settings.seed = 4;
    const Image noisy = renderer.render(settings);
    settings.shadow_filter_px = 0.0;
    CHECK(renderer.render(settings).rgb == noisy.rgb); // 0: no filter, the same bytes
    const auto rms = [&](const Image& image) {
        double sum = 0.0;
        for (std::size_t i = 0; i < image.rgb.size(); ++i)
            sum += std::pow(double(image.rgb[i]) - converged.rgb[i], 2);
        return std::sqrt(sum / double(image.rgb.size()));
    };
    settings.shadow_filter_px = 1.0;
    const Image filtered = renderer.render(settings);
    INFO("RMS against 256 spp: " << rms(noisy) << " unfiltered, " << rms(filtered) << " filtered");
    CHECK(rms(filtered) < 0.92 * rms(noisy));
    // The variance channel stays the unfiltered pixel's.
    settings.variance = true;
    const Image with_variance = renderer.render(settings);
    CHECK(with_variance.rgb == filtered.rgb);
    settings.shadow_filter_px = 0.0;
    CHECK(renderer.render(settings).variance == with_variance.variance);
    for (const double bad : {-0.5, kMaxShadowFilterPx + 1.0, std::nan("")}) {
        settings.shadow_filter_px = bad;
        CHECK_THROWS_WITH(renderer.render(settings), Catch::Contains("shadow_filter_px"));
    }
}

// shadow_rays_per_pixel: up to the sample count the same bytes; their parts add up to the same
// unshadowed light; the same bytes on 1 and 2 threads.
TEST_CASE("fast integrator: more shadow rays a pixel give the same image on average with less "
          "noise",
          "[render][fast]") {
    const SensorFrame rest = dome_with_box_markers();
    const SensorFrame pressed = pressed_flat(rest);
    // A sample's parts: with 3 shadow rays, 3 parts at the coating hit, their unshadowed
    // light adding up to the one-ray sample's, the radiance the mean of the rays' (its
    // shadowed light within the unshadowed).
    {
        FastOnFrame on(pressed, rest);
        auto& [scene, shading, path, fast] = on;
        const LaneOptics<kRgbLanes> lanes = shading.rgb_lanes();
        constexpr std::size_t n = 16;
        std::vector<Vec3> directions;
        std::vector<ShadowDraw> one, three;
        for (std::size_t i = 0; i < n; ++i) {
            directions.push_back(unit_from_angles(10.0 + 4.0 * double(i), 15.0 * double(i)));
            one.push_back({(double(i) + 0.5) / double(n), 0.3, 0.7});
            ShadowDraw d = one.back();
            d.rays = 3;
            d.further[0] = {0.9 - 0.05 * double(i), 0.6, 0.2};
            d.further[1] = {0.05 * double(i), 0.1, 0.9};
            three.push_back(d);
        }
        const std::vector<const LaneOptics<kRgbLanes>*> lane_sets(n, &lanes);
        const std::vector<const CacheLambdas<kRgbLanes>*> lambdas(n, nullptr);
        std::vector<RgbLanes> r1(n), r3(n);
        std::vector<DirectLight<kRgbLanes>> d1(n), d3(n);
        PixelRng a(3, 9), b = a;
        std::vector<PixelRng*> sa(n, &a), sb(n, &b);
        fast.radiance16<kRgbLanes>(scene, Vec3::Zero(), directions, lane_sets, lambdas, one, sa, r1,
                                   d1);
        fast.radiance16<kRgbLanes>(scene, Vec3::Zero(), directions, lane_sets, lambdas, three, sb,
                                   r3, d3);
        int lit = 0, differ = 0;
        for (std::size_t i = 0; i < n; ++i) {
            INFO("sample " << i << ": " << d1[i].parts << " and " << d3[i].parts << " parts");
            CHECK((d3[i].lit() - d1[i].lit()).abs().maxCoeff() <=
                  1e-12 * (1.0 + d1[i].lit().abs().maxCoeff()));
            CHECK((d3[i].shadowed() <= d3[i].lit() * (1 + 1e-12)).all());
            // The indirect light is the same: the radiances differ by the shadowed light's.
            CHECK(((r3[i] - d3[i].shadowed()) - (r1[i] - d1[i].shadowed())).abs().maxCoeff() <=
                  1e-12);
            if ((d1[i].lit() > 0.0).any()) {
                ++lit;
                CHECK(d3[i].parts == d1[i].parts + 2);
                differ += (d3[i].shadowed() != d1[i].shadowed()).any();
            }
        }
        CHECK(lit > 8);
        CHECK(differ > 0); // the other rays found other shadows somewhere
    }
    Renderer renderer(CameraParams{96, 96, 84.0}, OpticsParams{});
    small_cache_on(renderer, rest, pressed);
    RenderSettings settings{256, 3};
    settings.integrator = Integrator::fast;
    const Image converged = renderer.render(settings);
    settings = fast_with_variance(2, 4);
    const Image plain = renderer.render(settings);
    // Up to the pixel's sample count: one a sample, the same bytes.
    for (const int rays : {1, 2}) {
        settings.shadow_rays_per_pixel = rays;
        CHECK(renderer.render(settings).rgb == plain.rgb);
    }
    // 8 (4 a sample at 2 spp) and more: the same, at most 4 a sample.
    settings.shadow_rays_per_pixel = 8;
    const Image more = renderer.render(settings);
    settings.shadow_rays_per_pixel = 50;
    CHECK(renderer.render(settings).rgb == more.rgb);
    // The error against 256 spp, and the sums over the image against the converged one's
    // (both unbiased: within 4 standard deviations of the sum, from the variance channel).
    const auto compare = [&](const Image& image, double& rms, double& sum, double& var,
                             double& converged_sum) {
        rms = sum = var = converged_sum = 0.0;
        for (std::size_t i = 0; i < image.rgb.size(); ++i) {
            rms += std::pow(double(image.rgb[i]) - converged.rgb[i], 2);
            sum += image.rgb[i], var += image.variance[i], converged_sum += converged.rgb[i];
        }
        rms = std::sqrt(rms / double(image.rgb.size()));
    };
    double rms_plain, sum_plain, var_plain, rms_more, sum_more, var_more, sum_converged;
    compare(plain, rms_plain, sum_plain, var_plain, sum_converged);
    compare(more, rms_more, sum_more, var_more, sum_converged);
    INFO("RMS against 256 spp: " << rms_plain << " with one shadow ray a sample, " << rms_more
                                 << " with 4; sums " << sum_plain << ", " << sum_more
                                 << ", converged " << sum_converged << "; summed variances "
                                 << var_plain << ", " << var_more);
    CHECK(more.rgb != plain.rgb);
    CHECK(std::abs(sum_more - sum_converged) < 4.0 * std::sqrt(var_more));
    CHECK(std::abs(sum_plain - sum_converged) < 4.0 * std::sqrt(var_plain));
    // The shadow rays' noise is part of each sample's: less of it, with the filter too.
    CHECK(rms_more < 0.97 * rms_plain);
    CHECK(var_more < 0.97 * var_plain);
    settings.shadow_filter_px = 1.0;
    settings.shadow_rays_per_pixel = 0;
    const Image filtered_plain = renderer.render(settings);
    settings.shadow_rays_per_pixel = 8;
    const Image filtered_more = renderer.render(settings);
    double rms_fp, rms_fm, unused;
    compare(filtered_plain, rms_fp, unused, unused, unused);
    compare(filtered_more, rms_fm, unused, unused, unused);
    INFO("filtered: " << rms_fp << " with one a sample, " << rms_fm << " with 4");
    CHECK(rms_fm < rms_fp);
    // The same bytes on 1 and 2 threads.
    Image threads_one, threads_two;
    {
        tbb::global_control threads(tbb::global_control::max_allowed_parallelism, 1);
        threads_one = renderer.render(settings);
    }
    {
        tbb::global_control threads(tbb::global_control::max_allowed_parallelism, 2);
        threads_two = renderer.render(settings);
    }
    CHECK(threads_one.rgb == filtered_more.rgb);
    CHECK(threads_two.rgb == filtered_more.rgb);
    CHECK(threads_one.variance == threads_two.variance);
    settings.shadow_rays_per_pixel = -1;
    CHECK_THROWS_WITH(renderer.render(settings),
                      Catch::Contains("shadow_rays_per_pixel = -1 is invalid") &&
                          Catch::Contains("allowed: integer >= 0"));
}

// The reflection is below a tenth of the sample: the refracted ray's parts stay the same,
// the sample's radiance rises by at most the reflection's share of its LED light.
TEST_CASE("fast integrator: the camera ray's faint reflection off the inner surface is shaded "
          "unshadowed",
          "[render][fast]") {
    const SensorFrame rest = dome_with_box_markers();
    // The camera rays' reflections off the tilted cut go across the cavity to the lit far wall
    // and its markers, where off a level cut they would leave by the rim.
    const SensorFrame pressed = pressed_tilted(rest, 35.0f);
    EmbreeScene scene;
    scene.set_frame(pressed);
    const ShadingModel shading{OpticsParams{}};
    const PathIntegrator path{shading};
    // The same light cache, with and without the reflections' shadow rays.
    std::array<FastIntegrator, 2> fast{FastIntegrator{shading, path},
                                       FastIntegrator{shading, path}};
    for (const bool unshadowed : {false, true}) {
        LightCacheSettings cache = small_cache();
        cache.unshadowed_reflections = unshadowed;
        fast[unshadowed].build_cache(rest, cache, nullptr, 1.0);
        fast[unshadowed].set_frame(pressed, scene);
    }
    const LaneOptics<kRgbLanes> lanes = shading.rgb_lanes();
    constexpr std::size_t n = 16;
    const std::vector<const LaneOptics<kRgbLanes>*> lane_sets(n, &lanes);
    const std::vector<const CacheLambdas<kRgbLanes>*> lambdas(n, nullptr);
    int fewer = 0, brighter = 0, samples = 0;
    for (int batch = 0; batch < 8; ++batch) {
        std::vector<Vec3> directions;
        std::vector<ShadowDraw> draws;
        for (std::size_t i = 0; i < n; ++i) {
            const double polar = 2.0 + 5.0 * double(batch) + 0.3 * double(i);
            directions.push_back(unit_from_angles(polar, 22.5 * double(i)));
            draws.push_back({(double(i) + 0.5) / double(n), 0.3, 0.7});
        }
        std::array<std::vector<RgbLanes>, 2> radiance{std::vector<RgbLanes>(n),
                                                      std::vector<RgbLanes>(n)};
        std::array<std::vector<DirectLight<kRgbLanes>>, 2> direct{
            std::vector<DirectLight<kRgbLanes>>(n), std::vector<DirectLight<kRgbLanes>>(n)};
        for (const bool unshadowed : {false, true}) {
            std::vector<PixelRng> rngs;
            for (std::size_t i = 0; i < n; ++i)
                rngs.emplace_back(7, std::uint64_t(batch) * n + i);
            std::vector<PixelRng*> streams;
            for (PixelRng& r : rngs)
                streams.push_back(&r);
            fast[unshadowed].radiance16<kRgbLanes>(scene, Vec3::Zero(), directions, lane_sets,
                                                   lambdas, draws, streams, radiance[unshadowed],
                                                   direct[unshadowed]);
        }
        for (std::size_t i = 0; i < n; ++i, ++samples) {
            const DirectLight<kRgbLanes>&traced = direct[0][i], &open = direct[1][i];
            INFO("batch " << batch << ", sample " << i << ": " << traced.parts << " and "
                          << open.parts << " parts");
            // The refracted ray's parts come first and are the same; the reflection's are gone.
            REQUIRE(open.parts <= traced.parts);
            for (int q = 0; q < open.parts; ++q) {
                CHECK((open.part[std::size_t(q)].lit == traced.part[std::size_t(q)].lit).all());
                CHECK((open.part[std::size_t(q)].shadowed ==
                       traced.part[std::size_t(q)].shadowed)
                          .all());
            }
            // What the reflection's parts carried: at most a tenth of the sample's LED light
            // each, shadowed; unshadowed now, so the radiance is up by at most their
            // unshadowed light.
            RgbLanes gone_lit = RgbLanes::Zero(), gone_shadowed = RgbLanes::Zero();
            for (int q = open.parts; q < traced.parts; ++q) {
                gone_lit += traced.part[std::size_t(q)].lit;
                gone_shadowed += traced.part[std::size_t(q)].shadowed;
            }
            const RgbLanes up = radiance[1][i] - radiance[0][i];
            const double tol = 1e-12 * (1.0 + radiance[0][i].abs().maxCoeff());
            CHECK((up >= -tol).all());
            CHECK(((up - (gone_lit - gone_shadowed)).abs() <= tol).all());
            fewer += open.parts < traced.parts;
            brighter += (up > tol).any();
        }
    }
    INFO(fewer << " of " << samples << " samples shaded their reflection without shadow rays, "
               << brighter << " of them brighter for it");
    // The fan reaches reflections that are lit, and some that a marker shadows.
    CHECK(fewer > 8);
    CHECK(brighter > 0);
}

// The ids follow the markers as the samples see them; the direct integrator's ids go
// straight through the inner surface.
TEST_CASE("fast integrator: marker ids and rim pixels follow the camera ray refracted at the inner "
          "surface",
          "[render][fast]") {
    // A press tilted 35 degrees: the camera rays meet its flat cut well off normal incidence
    // and bend by several degrees on their way to the markers.
    const SensorFrame rest = dome_with_box_markers();
    const SensorFrame pressed = pressed_tilted(rest, 35.0f);
    const CameraParams camera{96, 96, 84.0};
    Renderer renderer(camera, OpticsParams{});
    small_cache_on(renderer, rest, pressed);
    RenderSettings settings{1, 5};
    settings.marker_ids = true;
    settings.integrator = Integrator::fast;
    const Image fast = renderer.render(settings);
    settings.integrator = Integrator::direct;
    const Image direct = renderer.render(settings);
    // The ids by hand: Snell's law at the inner surface's interpolated normal written out, then
    // closest_hit after closest_hit to the coating, the first marker face of each layer.
    EmbreeScene scene;
    scene.set_frame(pressed);
    const FisheyeCamera lens(camera);
    const double eta = 1.0 / OpticsParams{}.refractive_index;
    const double inf = std::numeric_limits<double>::infinity();
    const auto walk = [&](const Vec3& from, const Vec3& d, double tnear, unsigned kinds) {
        std::pair<std::int32_t, std::int32_t> ids{-1, -1};
        for (int i = 0; i < 32; ++i) {
            const RayHit hit = scene.closest_hit(from, d, tnear, inf, kinds);
            if (hit.kind != SurfaceKind::inner_marker && hit.kind != SurfaceKind::outer_marker)
                break;
            tnear = hit.t_mm + kHitGap_mm;
            std::int32_t& id = hit.kind == SurfaceKind::inner_marker ? ids.first : ids.second;
            if (id < 0) id = std::int32_t(hit.prim_id / 12);
        }
        return ids;
    };
    const unsigned no_interface = kAllKinds & ~kind_bit(SurfaceKind::inner_surface);
    int refracted_differs = 0, straight_differs = 0, with_marker = 0, bent = 0, wrong = 0;
    for (int y = 0; y < camera.height_px; ++y)
        for (int x = 0; x < camera.width_px; ++x) {
            const std::size_t p = std::size_t(y) * std::size_t(camera.width_px) + std::size_t(x);
            const auto d = lens.direction(Eigen::Vector2d(x + 0.5, y + 0.5));
            std::pair<std::int32_t, std::int32_t> seen{-1, -1}, straight{-1, -1};
            if (d) {
                straight = walk(lens.origin_mm(), *d, 0.0, no_interface);
                const RayHit in = scene.closest_hit(lens.origin_mm(), *d, 0.0, inf);
                if (in.kind == SurfaceKind::inner_surface && in.normal.dot(*d) < 0.0) {
                    const Vec3 n = in.shading_normal.dot(*d) < 0.0 ? in.shading_normal
                                                                   : Vec3(-in.shading_normal);
                    const double cos_i = -n.dot(*d);
                    const double k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
                    const Vec3 r = (eta * *d + (eta * cos_i - std::sqrt(k)) * n).normalized();
                    bent += std::acos(std::clamp(r.dot(*d), -1.0, 1.0)) >
                            2.0 * std::numbers::pi / 180.0;
                    seen = walk(lens.origin_mm() + in.t_mm * *d, r, kHitGap_mm, kAllKinds);
                }
            }
            with_marker += seen.first >= 0 || seen.second >= 0;
            wrong +=
                fast.inner_marker_id[p] != seen.first || fast.outer_marker_id[p] != seen.second;
            refracted_differs += seen != straight;
            straight_differs += direct.inner_marker_id[p] != straight.first ||
                                direct.outer_marker_id[p] != straight.second;
        }
    INFO(with_marker << " pixels show a marker, " << bent << " rays bend by more than 2 degrees, "
                     << refracted_differs << " pixels' ids change with the bend");
    CHECK(wrong == 0);
    CHECK(straight_differs == 0);
    // The bend matters here: without it the ids (and the rims) would be off.
    CHECK(bent > 500);
    CHECK(refracted_differs > 50);
    CHECK(with_marker > 500);
}

// fast_wavelengths 8 has a little more noise; 0 picks by the samples per pixel, other
// counts are refused.
TEST_CASE("fast integrator: 8 hero wavelengths a sample estimate the same colours as 16",
          "[render][fast]") {
    const SensorFrame rest = dome_with_box_markers();
    const SensorFrame pressed = pressed_flat(rest);
    Renderer renderer(CameraParams{48, 48, 84.0}, spectral_optics());
    small_cache_on(renderer, rest, pressed);
    // 8 wavelengths with seeds 21 and 22, 16 with seed 22 (the same camera samples as the
    // second 8, other wavelengths).
    RenderSettings settings = fast_with_variance(16, 21);
    settings.fast_wavelengths = 8;
    const Image eight = renderer.render(settings);
    settings.seed = 22;
    const Image eight_again = renderer.render(settings);
    settings.fast_wavelengths = 16;
    const Image sixteen = renderer.render(settings);
    REQUIRE(eight.rgb.size() == sixteen.rgb.size());
    CHECK(eight_again.rgb != sixteen.rgb); // the setting is the render's
    // Per channel: the image's mean (the wavelengths' colours: a wrong table or white balance
    // moves it everywhere), and the pixels' differences against their variance channels (a
    // chi-square per value, below 1 where the strata beat independent samples): 8 against 16
    // as far apart as 8 against 8 with other samples.
    std::array<double, 3> mean8{}, mean16{}, mean8b{};
    double chi2 = 0.0, chi2_same = 0.0, var8 = 0.0, var16 = 0.0;
    std::size_t counted = 0;
    for (std::size_t i = 0; i < eight.rgb.size(); ++i) {
        mean8[i % 3] += eight.rgb[i], mean16[i % 3] += sixteen.rgb[i];
        mean8b[i % 3] += eight_again.rgb[i];
        const double v8 = eight.variance[i], v8b = eight_again.variance[i],
                     v16 = sixteen.variance[i];
        if (v8 + v16 <= 0.0 || v8 + v8b <= 0.0) continue;
        chi2 += std::pow(double(eight.rgb[i]) - sixteen.rgb[i], 2) / (v8 + v16);
        chi2_same += std::pow(double(eight.rgb[i]) - eight_again.rgb[i], 2) / (v8 + v8b);
        var8 += v8, var16 += v16;
        ++counted;
    }
    REQUIRE(counted > 3000);
    chi2 /= double(counted), chi2_same /= double(counted);
    INFO("chi-square per value: 8 against 16 " << chi2 << ", 8 against 8 (another seed) "
                                               << chi2_same << "; variance 8 / 16 "
                                               << var8 / var16);
    for (int c = 0; c < 3; ++c) {
        INFO("channel " << c << ": mean " << mean8[std::size_t(c)] << " (8), "
                        << mean8b[std::size_t(c)] << " (8, another seed), "
                        << mean16[std::size_t(c)] << " (16)");
        CHECK(mean8b[std::size_t(c)] == Approx(mean16[std::size_t(c)]).epsilon(0.001));
        CHECK(mean8[std::size_t(c)] == Approx(mean16[std::size_t(c)]).epsilon(0.002));
    }
    // The two counts differ by no more than two draws of one count do.
    CHECK(chi2 < 1.15 * chi2_same);
    CHECK(chi2 > 0.85 * chi2_same);
    CHECK(chi2 < 1.0);
    // Fewer wavelengths, no more than a little more noise (here the camera samples' positions
    // on the markers' sharp edges hold most of it).
    CHECK(var8 < 1.2 * var16);
    // 0 (the default): 16 at one sample per pixel, 8 from 2 on.
    for (const int spp : {1, 2}) {
        settings.samples_per_pixel = spp;
        settings.fast_wavelengths = spp == 1 ? 16 : 8;
        const Image chosen = renderer.render(settings);
        settings.fast_wavelengths = 0;
        CHECK(renderer.render(settings).rgb == chosen.rgb);
        CHECK(fast_wavelengths_of(settings) == (spp == 1 ? 16 : 8));
    }
    for (const int bad : {-1, 4, 12, 32}) {
        settings.fast_wavelengths = bad;
        CHECK_THROWS_WITH(renderer.render(settings),
                          Catch::Contains("fast_wavelengths = " + std::to_string(bad)) &&
                              Catch::Contains("8 or 16"));
    }
}

// Hence 2 samples of 8 wavelengths are about as noisy in colour as 1 of 16.
TEST_CASE("fast integrator: a pixel's samples split the hero wavelengths' strata between them",
          "[render][fast]") {
    // A narrow camera that sees the coating through one wide inner (magenta) marker at the
    // apex: every pixel's colour is the filter's product with the LEDs' spectrum, so the
    // wavelengths drawn make much of its noise.
    SensorFrame rest = clear_dome(16, 64, 24, 96);
    rest.inner_markers = box_markers(10.75, 0.5, 3.0);
    rest.triangles_per_marker = 12;
    Renderer renderer(CameraParams{48, 48, 5.0}, spectral_optics());
    small_cache_on(renderer, rest, rest);
    // The noise: half the mean squared difference of two seeds' images, over the values.
    const auto noise = [&](int spp, int wavelengths) {
        RenderSettings settings{spp, 31};
        settings.integrator = Integrator::fast;
        settings.fast_wavelengths = wavelengths;
        const Image a = renderer.render(settings);
        settings.seed = 32;
        const Image b = renderer.render(settings);
        double sum = 0.0;
        for (std::size_t i = 0; i < a.rgb.size(); ++i)
            sum += std::pow(double(a.rgb[i]) - b.rgb[i], 2);
        return sum / 2.0 / double(a.rgb.size());
    };
    const double eight_2 = noise(2, 8), sixteen_1 = noise(1, 16), eight_1 = noise(1, 8);
    INFO("variance: 2 spp x 8 wavelengths " << eight_2 << ", 1 x 16 " << sixteen_1 << ", 1 x 8 "
                                            << eight_1);
    // Measured 1.74e-4, 1.59e-4 and 4.56e-4. With each sample's 8 drawn over the whole
    // strata (0.26.0's draw, where sets i and i + 128 hold the same wavelengths) 2 x 8 gave
    // 2.11e-4: 1.32 times 1 x 16 and 0.47 times 1 x 8.
    CHECK(eight_2 < 1.2 * sixteen_1);
    CHECK(eight_2 < 0.42 * eight_1);
}
