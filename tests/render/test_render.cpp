// Tests of chromasim::render against analytic answers on a small synthetic sensor: a UV
// hemisphere of radius 12.7 mm as the coating and marker prisms (12-gon discs of radius
// 0.5 mm, closed volumes of thickness kThickness_mm).
#include "render/embree_scene.hpp"
#include "render/fisheye_camera.hpp"
#include "render/renderer.hpp"
#include "render/sampling.hpp"
#include "render/shading.hpp"
#include "test_meshes.hpp"

#include <Eigen/Geometry>
#include <catch2/catch.hpp>
#include <tbb/global_control.h>

#include <cstring>

#include <filesystem>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <vector>

using namespace chromasim::render;
using namespace chromasim::render::test;

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kDeg = kPi / 180.0;
constexpr int kRim = 12;
constexpr int kTrianglesPerMarker = 4 * kRim; // two fans and the side
constexpr double kMarkerRadius_mm = 0.5;
constexpr double kThickness_mm = 0.49;
constexpr double kInnerMarkerZ_mm = 10.75;
constexpr double kOuterMarkerRadius_mm = 12.45;

/// Rim point k of a marker face centred at c with axis n (the 12-gon's frame u, v).
Vec3 rim_point(const Vec3& c, const Vec3& n, int k) {
    const Vec3 u = n.unitOrthogonal(), v = n.cross(u);
    const double phi = 2.0 * kPi * k / kRim;
    return c + kMarkerRadius_mm * (std::cos(phi) * u + std::sin(phi) * v);
}

/// Appends a closed marker prism of `kTrianglesPerMarker` triangles facing outwards: a 12-gon
/// of radius 0.5 mm centred at `centre_mm`, extruded by thickness/2 both ways along `normal`.
void add_disc(MeshBuilder& mesh, const Vec3& centre_mm, const Vec3& normal,
              double thickness_mm = kThickness_mm) {
    const Vec3 n = normal.normalized();
    const Vec3 lo = centre_mm - 0.5 * thickness_mm * n, hi = centre_mm + 0.5 * thickness_mm * n;
    const std::uint32_t bottom = mesh.add_vertex(lo);
    for (int k = 0; k < kRim; ++k)
        mesh.add_vertex(rim_point(lo, n, k));
    const std::uint32_t top = mesh.add_vertex(hi);
    for (int k = 0; k < kRim; ++k)
        mesh.add_vertex(rim_point(hi, n, k));
    for (std::uint32_t k = 0; k < kRim; ++k) {
        const std::uint32_t a = 1 + k, b = 1 + (k + 1) % kRim;
        mesh.triangles.push_back({bottom, bottom + b, bottom + a});
        mesh.triangles.push_back({top, top + a, top + b});
        mesh.triangles.push_back({bottom + a, bottom + b, top + b});
        mesh.triangles.push_back({bottom + a, top + b, top + a});
    }
}

/// Length of the line origin + t w inside a prism of add_disc, by brute force: the share of
/// points 1e-5 mm apart that lie on the inner side of all its 14 planes.
double chord_mm(const Vec3& origin, const Vec3& w, const Vec3& centre, const Vec3& normal,
                double thickness_mm, double t_max_mm) {
    const Vec3 n = normal.normalized();
    std::vector<std::pair<Vec3, double>> planes{{n, 0.5 * thickness_mm}, {-n, 0.5 * thickness_mm}};
    for (int k = 0; k < kRim; ++k) {
        const Vec3 mid = 0.5 * (rim_point(centre, n, k) + rim_point(centre, n, k + 1)) - centre;
        planes.emplace_back(mid.normalized(), mid.norm());
    }
    const double step = 1e-5;
    int inside = 0;
    for (double t = 0.5 * step; t < t_max_mm; t += step) {
        const Vec3 p = origin + t * w - centre;
        bool in = true;
        for (const auto& [m, d] : planes)
            in = in && m.dot(p) <= d;
        inside += in;
    }
    return inside * step;
}

SurfaceMesh discs(const std::vector<std::pair<Vec3, Vec3>>& centres_and_normals) {
    MeshBuilder mesh;
    for (const auto& [centre, normal] : centres_and_normals)
        add_disc(mesh, centre, normal);
    return mesh.build();
}

/// Coating only; markers get added by the tests.
SensorFrame bare_frame() {
    SensorFrame frame;
    frame.coating = hemisphere(12.7, 90, 96);
    frame.triangles_per_marker = kTrianglesPerMarker;
    return frame;
}

const Vec3 kOuterMarkerDirection = unit_from_angles(25.0, 90.0);

/// Inner marker at the apex, outer marker at polar 25 deg, azimuth 90 deg (SensorFrame docs).
SensorFrame marker_frame() {
    SensorFrame frame = bare_frame();
    frame.inner_markers = discs({{Vec3(0.0, 0.0, kInnerMarkerZ_mm), Vec3::UnitZ()}});
    frame.outer_markers =
        discs({{kOuterMarkerRadius_mm * kOuterMarkerDirection, kOuterMarkerDirection}});
    return frame;
}

/// A dome with an inner surface and marker_frame()'s two markers.
SensorFrame dome_with_marker_frame() {
    SensorFrame frame = clear_dome(12, 48, 10, 40);
    const SensorFrame markers = marker_frame();
    frame.inner_markers = markers.inner_markers;
    frame.outer_markers = markers.outer_markers;
    return frame;
}

/// Direct irradiance of the LED ring at p (normal facing the light), written independently
/// of the renderer; `transmission(led, w)` gives the shadow transmittance per LED.
template <class Transmission>
Eigen::Array3d analytic_irradiance(const OpticsParams& o, const Vec3& p, const Vec3& normal,
                                   Transmission transmission) {
    Eigen::Array3d total = Eigen::Array3d::Zero();
    for (int k = 0; k < o.led_count; ++k) {
        const double phi = 2.0 * kPi * k / o.led_count;
        const Vec3 led(o.led_ring_radius_mm * std::cos(phi), o.led_ring_radius_mm * std::sin(phi),
                       o.led_z_mm);
        const Vec3 w = (p - led).normalized();
        const double geometry =
            std::max(0.0, w.z()) * std::max(0.0, -w.dot(normal)) / (p - led).squaredNorm();
        total += o.led_rgb.array() * geometry * transmission(led, w);
    }
    return total;
}

Eigen::Array3d unshadowed(const Vec3&, const Vec3&) {
    return Eigen::Array3d::Ones();
}

Eigen::Array3d pixel(const Image& image, int x, int y) {
    const float* p = image.pixel(x, y);
    return {p[0], p[1], p[2]};
}

/// Pixel containing the projection of p.
Eigen::Array3d pixel_at(const Renderer& renderer, const Image& image, const Vec3& p) {
    const auto xy = renderer.project(p);
    REQUIRE(xy);
    return pixel(image, int(std::floor(xy->x())), int(std::floor(xy->y())));
}

/// `rest`: the fast integrator's light cache is built on it (a quick one: 8 paths per vertex).
Image render_frame(const CameraParams& camera, const OpticsParams& optics, const SensorFrame& frame,
                   int spp = 2, std::uint64_t seed = 1, Integrator integrator = Integrator::direct,
                   const SensorFrame* rest = nullptr) {
    Renderer renderer(camera, optics);
    if (integrator == Integrator::fast) {
        LightCacheSettings cache;
        cache.paths_per_vertex = 8;
        cache.direct_samples = 4;
        renderer.set_light_cache(rest ? *rest : frame, cache);
    }
    renderer.set_frame(frame);
    RenderSettings settings{spp, seed};
    settings.integrator = integrator;
    return renderer.render(settings);
}

/// 33 x 33 px over +-8 deg: the centre pixel sees only the apex region (+-0.25 deg).
const CameraParams kNarrowCamera{33, 33, 8.0};
const CameraParams kWideCamera{128, 128, 84.0};

bool all_finite(const Image& image) {
    return std::all_of(image.rgb.begin(), image.rgb.end(),
                       [](float v) { return std::isfinite(v); });
}

} // namespace

TEST_CASE("fisheye projection is equidistant about the image centre", "[render]") {
    const CameraParams params{80, 60, 84.0}; // min(w, h) = 60: circle radius 30 px
    const Renderer renderer(params, OpticsParams{});
    const Eigen::Vector2d centre(40.0, 30.0);
    for (double polar : {0.0, 10.0, 42.0, 84.0}) {
        for (double azimuth : {0.0, 30.0, 135.0, -100.0}) {
            const Vec3 p = 7.0 * unit_from_angles(polar, azimuth);
            const auto xy = renderer.project(p);
            REQUIRE(xy);
            const Eigen::Vector2d expected =
                centre + polar / 84.0 * 30.0 *
                             Eigen::Vector2d(std::cos(azimuth * kDeg), std::sin(azimuth * kDeg));
            CHECK((*xy - expected).norm() < 1e-9);
        }
    }
    CHECK_FALSE(renderer.project(unit_from_angles(84.5, 10.0)));
    CHECK_FALSE(renderer.project(Vec3::Zero()));

    const FisheyeCamera camera(params);
    for (const Eigen::Vector2d& px : {Eigen::Vector2d(40.0, 30.0), Eigen::Vector2d(22.3, 40.6),
                                      Eigen::Vector2d(55.5, 20.25), Eigen::Vector2d(40.0, 0.5)}) {
        const auto direction = camera.direction(px);
        REQUIRE(direction);
        CHECK(std::abs(direction->norm() - 1.0) < 1e-12);
        const auto back = camera.project(12.7 * *direction);
        REQUIRE(back);
        CHECK((*back - px).norm() < 1e-9);
    }
    CHECK_FALSE(camera.direction(Eigen::Vector2d(0.5, 0.5))); // a corner: outside the circle
    CHECK_THROWS_AS(FisheyeCamera(CameraParams{0, 10, 84.0}), std::invalid_argument);
    CHECK_THROWS_AS(FisheyeCamera(CameraParams{10, 10, 190.0}), std::invalid_argument);
}

TEST_CASE("apex pixels equal analytic products of irradiance and transmittances", "[render]") {
    OpticsParams optics;
    optics.exposure = 1.3;
    const double white = 0.8 * optics.exposure;
    const Eigen::Array3d a_in = optics.inner_marker_absorption_per_mm.array();
    const Eigen::Array3d a_out = optics.outer_marker_absorption_per_mm.array();
    const double s = optics.outer_marker_scatter_fraction;
    const int c = kNarrowCamera.width_px / 2; // the centre pixel looks along +z

    const Image bare = render_frame(kNarrowCamera, optics, bare_frame());
    const Eigen::Array3d background = pixel(bare, c, c);
    SECTION("white coating at the apex: auto exposure and the LED irradiance sum") {
        for (int k = 0; k < 3; ++k)
            CHECK(background[k] == Approx(white).epsilon(1e-3));
    }
    SECTION("inner marker at the apex: one Beer-Lambert factor exp(-a * 0.5 mm)") {
        // The shadow segments LED -> apex cross z = 10.75 mm at 10 * 1.95 / 13.7 = 1.42 mm
        // from the axis, outside the 0.5 mm disc: only the view ray is filtered.
        SensorFrame frame = bare_frame();
        frame.inner_markers = discs({{Vec3(0.0, 0.0, kInnerMarkerZ_mm), Vec3::UnitZ()}});
        const Eigen::Array3d value = pixel(render_frame(kNarrowCamera, optics, frame), c, c);
        const Eigen::Array3d expected = (-a_in * kThickness_mm).exp();
        for (int k = 0; k < 3; ++k) {
            // 1e-4: the pixel's rays tilt up to 0.35 deg, lengthening the path by 2e-5.
            CHECK(value[k] / background[k] == Approx(expected[k]).epsilon(1e-4));
            CHECK(value[k] == Approx(white * expected[k]).epsilon(1e-3));
        }
    }
    SECTION("inner marker just below the apex: filtered on the view and on every LED path") {
        // The prism spans z = 12.155 to 12.645 mm; each LED -> apex segment crosses those
        // planes 10 * 0.545 / 13.7 = 0.40 mm and 0.04 mm from the axis, inside the 12-gon's
        // incircle (0.48 mm), so it enters and leaves through the faces; all six LEDs see the
        // apex at the same angle.
        SensorFrame frame = bare_frame();
        frame.inner_markers = discs({{Vec3(0.0, 0.0, 12.4), Vec3::UnitZ()}});
        const Eigen::Array3d value = pixel(render_frame(kNarrowCamera, optics, frame), c, c);
        const Vec3 led_to_apex = (Vec3(0.0, 0.0, 12.7) - Vec3(10.0, 0.0, -1.0)).normalized();
        const double t = kThickness_mm;
        const Eigen::Array3d expected =
            white * (-a_in * t).exp() * (-a_in * t / led_to_apex.z()).exp();
        for (int k = 0; k < 3; ++k)
            CHECK(value[k] == Approx(expected[k]).epsilon(1e-3));
    }
    SECTION("outer marker at the apex: scattered part plus doubly filtered coating") {
        SensorFrame frame = bare_frame();
        const Vec3 centre(0.0, 0.0, kOuterMarkerRadius_mm);
        frame.outer_markers = discs({{centre, Vec3::UnitZ()}});
        const Eigen::Array3d value = pixel(render_frame(kNarrowCamera, optics, frame), c, c);

        const Vec3 apex(0.0, 0.0, 12.7);
        const Vec3 down(0.0, 0.0, -1.0);
        auto through_disc = [&](const Vec3& led, const Vec3& w) {
            // Every LED -> apex segment crosses the disc plane inside the 12-gon's incircle.
            for (const double z :
                 {centre.z() - 0.5 * kThickness_mm, centre.z() + 0.5 * kThickness_mm}) {
                const Vec3 crossing = led + (z - led.z()) / w.z() * w;
                REQUIRE(crossing.head<2>().norm() < kMarkerRadius_mm * std::cos(kPi / 12.0));
            }
            const double path = kThickness_mm / std::abs(w.z());
            return Eigen::Array3d((1.0 - s) * (-a_out * path).exp());
        };
        const Eigen::Array3d albedo_c = optics.coating_albedo.array();
        const double scale =
            white /
            (albedo_c / kPi * analytic_irradiance(optics, apex, down, unshadowed)).maxCoeff();
        // The view ray enters the cyan volume through its inner face, where it scatters.
        const Vec3 entry = centre - Vec3(0.0, 0.0, 0.5 * kThickness_mm);
        const Eigen::Array3d scattered = s * optics.outer_marker_albedo.array() / kPi *
                                         analytic_irradiance(optics, entry, down, unshadowed);
        const Eigen::Array3d behind = (1.0 - s) * (-a_out * kThickness_mm).exp() * albedo_c / kPi *
                                      analytic_irradiance(optics, apex, down, through_disc);
        const Eigen::Array3d expected = scale * (scattered + behind);
        for (int k = 0; k < 3; ++k)
            CHECK(value[k] == Approx(expected[k]).epsilon(1e-3));
    }
}

TEST_CASE("the image has structure, a black surround and coloured markers", "[render]") {
    const OpticsParams optics;
    Renderer renderer(kWideCamera, optics);
    renderer.set_frame(marker_frame());
    const Image image = renderer.render({2, 1});
    REQUIRE(all_finite(image));

    const auto [lo, hi] = std::minmax_element(image.rgb.begin(), image.rgb.end());
    CHECK(*hi - *lo > 0.3f);

    // Pixels whose every corner lies outside the image circle are exactly black.
    const double radius = 64.0;
    int outside = 0;
    for (int y = 0; y < image.height; ++y) {
        for (int x = 0; x < image.width; ++x) {
            const double dx = std::min(std::abs(x - 64.0), std::abs(x + 1 - 64.0));
            const double dy = std::min(std::abs(y - 64.0), std::abs(y + 1 - 64.0));
            if (std::hypot(dx, dy) <= radius) continue;
            ++outside;
            CHECK(pixel(image, x, y).isZero(0.0));
        }
    }
    CHECK(outside > 1000);

    // Inner marker: magenta (green absorbed); outer marker: cyan (red absorbed). The
    // background pixel sits at the outer marker's polar angle, away from both markers.
    const Eigen::Array3d background = pixel_at(renderer, image, unit_from_angles(25.0, 200.0));
    const Eigen::Array3d inner = pixel_at(renderer, image, Vec3(0.0, 0.0, kInnerMarkerZ_mm));
    const Eigen::Array3d outer = pixel_at(renderer, image, kOuterMarkerDirection);
    CHECK(background[0] == Approx(background[1]).epsilon(1e-6)); // white coating, white LEDs
    CHECK(inner[1] / inner[0] < 0.5 * background[1] / background[0]);
    CHECK(inner[2] / inner[1] > 2.0 * background[2] / background[1]);
    CHECK(outer[0] / outer[1] < 0.5 * background[0] / background[1]);
    CHECK(outer[2] / outer[1] == Approx(1.0).margin(0.25));
}

TEST_CASE("a pixel the field's edge crosses is its coverage times its samples inside the field",
          "[render]") {
    // The old estimator (the samples outside the field black) made an edge pixel as noisy as
    // the share of its samples that fell inside: at 1 spp, 0 or all of the light inside, off
    // by about half of it. Now an edge pixel's noise is that of the light inside, as for the
    // pixels just inside the edge. Relative errors against a 256-spp render of the bare dome
    // seen through the narrow camera (the smooth light about the apex), per integrator
    // (sample_pixel, and the fast integrator's batches).
    const FisheyeCamera camera(kNarrowCamera);
    const double radius = camera.circle_radius_px();
    const SensorFrame frame = bare_frame();
    // The pixels compared: the edge's, where the samples split (coverage in (0.25, 0.75)),
    // and those within 4 px inside the edge.
    enum class Ring { none, edge, inside };
    const auto ring = [&](int x, int y) {
        const double c = camera.field_coverage(x, y);
        if (c > 0.25 && c < 0.75) return Ring::edge;
        if (c == 1.0 && std::hypot(x + 0.5 - radius, y + 0.5 - radius) > radius - 4.0)
            return Ring::inside;
        return Ring::none;
    };
    for (const Integrator integrator : {Integrator::direct, Integrator::fast}) {
        INFO("integrator " << int(integrator));
        const Image reference =
            render_frame(kNarrowCamera, OpticsParams{}, frame, 256, 7, integrator);
        double edge2 = 0.0, inner2 = 0.0;
        int edge = 0, inner = 0;
        for (std::uint64_t seed = 1; seed <= 4; ++seed) {
            const Image image =
                render_frame(kNarrowCamera, OpticsParams{}, frame, 1, seed, integrator);
            for (int y = 0; y < image.height; ++y)
                for (int x = 0; x < image.width; ++x) {
                    const double c = camera.field_coverage(x, y);
                    // The light over the part inside the field.
                    const double light = pixel(reference, x, y).sum() / std::max(c, 1e-300);
                    if (!(light > 0.0)) continue;
                    const double e2 =
                        std::pow(pixel(image, x, y).sum() - pixel(reference, x, y).sum(), 2) /
                        (light * light);
                    if (ring(x, y) == Ring::edge) {
                        edge2 += e2;
                        ++edge;
                    } else if (ring(x, y) == Ring::inside) {
                        inner2 += e2;
                        ++inner;
                    }
                }
        }
        REQUIRE(edge > 100);
        REQUIRE(inner > 1000);
        const double edge_rms = std::sqrt(edge2 / edge), inner_rms = std::sqrt(inner2 / inner);
        INFO("relative RMS error: edge " << edge_rms << ", just inside " << inner_rms);
        CHECK(edge_rms < 1.5 * inner_rms);
    }
    // The variance channel at the edge (coverage^2 times the variance of the mean of the
    // samples inside) says as much about the error as inside the field: the ratio of the mean
    // estimated variance to the mean squared error against the reference, at 4 spp with the
    // direct integrator (its LED points: noise in every pixel), within 0.5 to 1.5 times the
    // pixels' just inside the edge (measured: 0.77; without the coverage^2, 2.0).
    Renderer renderer(kNarrowCamera, OpticsParams{});
    renderer.set_frame(frame);
    RenderSettings settings{256, 7};
    const Image reference = renderer.render(settings);
    settings = RenderSettings{4, 3};
    settings.variance = true;
    const Image image = renderer.render(settings);
    double edge_var = 0.0, edge_err2 = 0.0, inner_var = 0.0, inner_err2 = 0.0;
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x) {
            const std::size_t p = 3 * (std::size_t(y) * std::size_t(image.width) + std::size_t(x));
            const double var = image.variance[p] + image.variance[p + 1] + image.variance[p + 2];
            REQUIRE(std::isfinite(var));
            REQUIRE(var >= 0.0);
            const double err2 = (pixel(image, x, y) - pixel(reference, x, y)).square().sum();
            if (ring(x, y) == Ring::edge) {
                edge_var += var;
                edge_err2 += err2;
            } else if (ring(x, y) == Ring::inside) {
                inner_var += var;
                inner_err2 += err2;
            }
        }
    REQUIRE(edge_err2 > 0.0);
    REQUIRE(inner_err2 > 0.0);
    const double ratio = (edge_var / edge_err2) / (inner_var / inner_err2);
    INFO("estimated variance over squared error: edge " << edge_var / edge_err2 << ", just inside "
                                                        << inner_var / inner_err2);
    CHECK(ratio > 0.5);
    CHECK(ratio < 1.5);
}

TEST_CASE("rendering is deterministic and refitting equals a fresh build", "[render]") {
    const OpticsParams optics;
    const CameraParams camera{64, 64, 84.0};
    const SensorFrame frame = marker_frame();

    Renderer renderer(camera, optics);
    renderer.set_frame(frame);
    const Image first = renderer.render({2, 7});
    CHECK(renderer.render({2, 7}).rgb == first.rgb);
    CHECK(renderer.render({2, 8}).rgb != first.rgb); // the seed drives the jitter

    // Press the apex region in by up to 1 mm and shift the markers: same topology.
    SensorFrame moved = frame;
    for (Eigen::Index i = 0; i < moved.coating.V.rows(); ++i) {
        const Eigen::Vector3f v = moved.coating.V.row(i);
        const float weight = std::max(0.0f, v.z() / 12.7f - 0.9f) * 10.0f;
        moved.coating.V.row(i) = v * (1.0f - weight / 12.7f);
    }
    moved.inner_markers.V.rowwise() += Eigen::RowVector3f(0.3f, -0.2f, 0.1f);
    moved.outer_markers.V.rowwise() += Eigen::RowVector3f(-0.1f, 0.4f, 0.0f);

    renderer.set_frame(moved); // refit
    const Image refitted = renderer.render({2, 7});
    CHECK(refitted.rgb != first.rgb);
    CHECK(render_frame(camera, optics, moved, 2, 7).rgb == refitted.rgb);
}

TEST_CASE("EmbreeScene refits in place when the topology is unchanged", "[render]") {
    detail::EmbreeScene scene;
    CHECK_FALSE(scene.closest_hit(Vec3::Zero(), Vec3::UnitZ(), 0.0, 100.0).hit());

    SensorFrame frame = marker_frame();
    CHECK(scene.set_frame(frame) == detail::SceneUpdate::built);
    const Vec3 axis = Vec3(0.01, 0.02, 1.0).normalized(); // off the fan's centre vertex
    auto first = scene.closest_hit(Vec3::Zero(), axis, 0.0, 100.0);
    const double bottom_mm = kInnerMarkerZ_mm - 0.5 * kThickness_mm;
    CHECK(first.kind == detail::SurfaceKind::inner_marker);
    CHECK(first.t_mm == Approx(bottom_mm / axis.z()).epsilon(1e-6));
    CHECK(first.normal.z() == Approx(-1.0).epsilon(1e-6)); // the inner face looks down

    frame.inner_markers.V.col(2).array() += 0.5f;
    CHECK(scene.set_frame(frame) == detail::SceneUpdate::refitted);
    const auto moved = scene.closest_hit(Vec3::Zero(), axis, 0.0, 100.0);
    CHECK(moved.t_mm == Approx((bottom_mm + 0.5) / axis.z()).epsilon(1e-6));
    const auto top = scene.closest_hit(Vec3::Zero(), axis, moved.t_mm + 1e-3, 100.0);
    CHECK(top.kind == detail::SurfaceKind::inner_marker);
    CHECK(top.t_mm == Approx((bottom_mm + 0.5 + kThickness_mm) / axis.z()).epsilon(1e-6));
    CHECK(top.normal.z() == Approx(1.0).epsilon(1e-6));
    const auto behind = scene.closest_hit(Vec3::Zero(), axis, top.t_mm + 1e-3, 100.0);
    CHECK(behind.kind == detail::SurfaceKind::coating);

    frame.inner_markers = SurfaceMesh{}; // topology change: rebuild
    CHECK(scene.set_frame(frame) == detail::SceneUpdate::built);
    CHECK(scene.closest_hit(Vec3::Zero(), axis, 0.0, 100.0).kind == detail::SurfaceKind::coating);
}

TEST_CASE("EmbreeScene leaves out the surface kinds a query does not ask for", "[render]") {
    // The dome's inner surface, then the markers on the axis, then the coating.
    detail::EmbreeScene scene;
    scene.set_frame(dome_with_marker_frame());
    const Vec3 axis = Vec3(0.01, 0.02, 1.0).normalized();
    using detail::kind_bit;
    using detail::SurfaceKind;
    const auto first = [&](unsigned kinds) {
        return scene.closest_hit(Vec3::Zero(), axis, 0.0, 100.0, kinds);
    };
    const detail::RayHit all = first(detail::kAllKinds);
    CHECK(all.kind == SurfaceKind::inner_surface);
    const detail::RayHit no_surface =
        first(detail::kAllKinds & ~kind_bit(SurfaceKind::inner_surface));
    CHECK(no_surface.kind == SurfaceKind::inner_marker);
    CHECK(no_surface.t_mm > all.t_mm);
    // The same hit as the full query's past the surface.
    const detail::RayHit past = scene.closest_hit(Vec3::Zero(), axis, all.t_mm + 1e-4, 100.0);
    CHECK(past.kind == SurfaceKind::inner_marker);
    CHECK(no_surface.t_mm == Approx(past.t_mm).epsilon(1e-6));
    CHECK(no_surface.prim_id == past.prim_id);
    CHECK(first(kind_bit(SurfaceKind::coating)).kind == SurfaceKind::coating);
    CHECK(first(kind_bit(SurfaceKind::coating) | kind_bit(SurfaceKind::inner_marker)).kind ==
          SurfaceKind::inner_marker);
    CHECK_FALSE(first(kind_bit(SurfaceKind::none)).hit());
}

// It also walks past more markers than it keeps.
TEST_CASE("RayHits walks a ray's hits as successive closest_hit calls do in fewer traversals",
          "[render]") {
    // The dome with both marker layers, the inner one replaced by the apex marker plus a stack
    // of six more at x = 3 mm (twelve faces, more than RayHits keeps).
    SensorFrame frame = dome_with_marker_frame();
    std::vector<std::pair<Vec3, Vec3>> stack = {{Vec3(0.0, 0.0, kInnerMarkerZ_mm), Vec3::UnitZ()}};
    for (int i = 1; i < 7; ++i)
        stack.push_back({Vec3(3.0, 0.0, 10.6 + 0.25 * i), Vec3::UnitZ()});
    frame.inner_markers = discs(stack);
    detail::EmbreeScene scene;
    scene.set_frame(frame);
    Eigen::Matrix<double, 3, Eigen::Dynamic> random = Eigen::MatrixXd::Random(3, 400);
    std::vector<std::pair<Vec3, Vec3>> rays = {
        {Vec3::Zero(), Vec3(0.01, 0.02, 1.0).normalized()},            // the apex marker
        {Vec3(3.0, 0.0, 10.55), Vec3(0.001, 0.002, 1.0).normalized()}, // up the stack
        {Vec3(3.0, 0.0, 13.0), Vec3(0.001, 0.002, -1.0).normalized()}, // down it
        // The outer marker, off its fan's centre (a vertex many triangles share, where either
        // may answer).
        {Vec3::Zero(), (kOuterMarkerDirection + Vec3(0.003, 0.0, 0.0)).normalized()}};
    for (Eigen::Index i = 0; i < random.cols(); i += 2)
        rays.push_back({Vec3(random(0, i), random(1, i), 11.0 + random(2, i)),
                        Vec3(random.col(i + 1)).normalized()});
    std::size_t walked = 0, long_walks = 0, ties = 0;
    std::uint64_t traversals[2] = {0, 0};
    for (const unsigned kinds :
         {detail::kAllKinds,
          detail::kAllKinds & ~detail::kind_bit(detail::SurfaceKind::inner_surface)}) {
        for (const auto& [origin, direction] : rays) {
            std::vector<detail::RayHit> one_by_one, walk;
            scene.count_rays(true);
            for (double tnear = 0.0; one_by_one.size() < 20;) {
                const detail::RayHit hit = scene.closest_hit(origin, direction, tnear, 30.0, kinds);
                if (!hit.hit()) break;
                one_by_one.push_back(hit);
                tnear = hit.t_mm + detail::kHitGap_mm;
            }
            traversals[0] += scene.rays_counted();
            scene.count_rays(true);
            detail::RayHits hits(scene, origin, direction, 0.0, 30.0, kinds);
            for (double tnear = 0.0; walk.size() < 20;) {
                const detail::RayHit hit = hits.next(tnear);
                if (!hit.hit()) break;
                walk.push_back(hit);
                tnear = hit.t_mm + detail::kHitGap_mm;
            }
            traversals[1] += scene.rays_counted();
            INFO("ray from " << origin.transpose() << " along " << direction.transpose());
            // Through the apex marker into the coating, the inner surface left out: its two
            // faces and the coating in one traversal (and one more past the coating), against
            // four.
            if (origin == Vec3::Zero() && direction.x() == rays[0].second.x() &&
                !(kinds & detail::kind_bit(detail::SurfaceKind::inner_surface))) {
                CHECK(walk.size() == 3);
                CHECK(scene.rays_counted() == 2);
            }
            REQUIRE(walk.size() == one_by_one.size());
            for (std::size_t k = 0; k < walk.size(); ++k) {
                CHECK(walk[k].kind == one_by_one[k].kind);
                CHECK(walk[k].t_mm == Approx(one_by_one[k].t_mm).epsilon(1e-6));
                CHECK((walk[k].normal - one_by_one[k].normal).norm() < 1e-6);
                // The same triangle, or, where two triangles tie (the same distance and
                // normal, checked above: the stack's discs share their side walls, so a ray
                // through a wall where two discs overlap meets both at once), either of them:
                // which one answers a tie is Embree's order of candidates, which differs
                // between machines (seen on an AMD EPYC in session 23, not on session 22's).
                ties += walk[k].prim_id != one_by_one[k].prim_id;
            }
            walked += walk.size();
            long_walks += walk.size() > detail::RayHits::kMarkers + 1;
        }
    }
    scene.count_rays(false);
    INFO(walked << " hits, " << ties << " ties, " << long_walks
                << " walks past more markers than kept; traversals " << traversals[1] << " against "
                << traversals[0]);
    CHECK(walked > 600);
    CHECK(ties <= 2); // of the 600 and more hits (2 seen: one ray, both kinds of query)
    CHECK(long_walks >= 2);
    CHECK(traversals[1] < traversals[0]);
}

TEST_CASE("EmbreeScene packets of 16 rays answer as the rays one by one", "[render]") {
    // A dome with an inner surface and both marker layers; rays from the camera point and from
    // points in the layers, in random directions (a full packet and a partial one of 11),
    // with a near limit that skips the first surface for some rays.
    detail::EmbreeScene scene;
    scene.set_frame(dome_with_marker_frame());
    Eigen::Matrix<double, 3, Eigen::Dynamic> random = Eigen::MatrixXd::Random(3, 27 * 2);
    int compared = 0, hits = 0;
    for (const int count : {16, 11}) {
        for (const double tnear : {0.0, 1.0}) {
            std::vector<Vec3> origins, directions;
            for (int i = 0; i < count; ++i) {
                const Vec3 r = random.col(compared % random.cols());
                origins.push_back(i % 2 ? Vec3(0.0, 0.0, 0.0)
                                        : Vec3(0.3 * r.x(), 0.3 * r.y(), 11.5));
                Vec3 w = random.col((compared + 7) % random.cols());
                if (i == 0) w = Vec3(0.01, 0.02, 1.0); // through the markers on the axis
                directions.push_back(w.normalized());
                ++compared;
            }
            std::vector<detail::RayHit> packed(std::size_t(count), detail::RayHit{});
            scene.closest_hits16(origins, directions, tnear, 100.0, packed);
            for (int i = 0; i < count; ++i) {
                const detail::RayHit one = scene.closest_hit(
                    origins[std::size_t(i)], directions[std::size_t(i)], tnear, 100.0);
                const detail::RayHit& two = packed[std::size_t(i)];
                INFO("count " << count << ", tnear " << tnear << ", ray " << i);
                CHECK(two.kind == one.kind);
                CHECK(two.prim_id == one.prim_id);
                CHECK(two.t_mm == Approx(one.t_mm).epsilon(1e-5));
                CHECK(two.u == Approx(one.u).margin(1e-5));
                CHECK(two.v == Approx(one.v).margin(1e-5));
                CHECK((two.normal - one.normal).norm() < 1e-6);
                hits += one.hit();
            }
        }
    }
    CHECK(hits > 40); // most rays hit something: the comparison is not of empty answers
    std::vector<detail::RayHit> out(17);
    const std::vector<Vec3> seventeen(17, Vec3::UnitZ());
    CHECK_THROWS_AS(scene.closest_hits16(seventeen, seventeen, 0.0, 1.0, out),
                    std::invalid_argument);
    CHECK_THROWS_AS(scene.closest_hits16(std::span(seventeen).first(3),
                                         std::span(seventeen).first(2), 0.0, 1.0,
                                         std::span(out).first(3)),
                    std::invalid_argument);
}

// They see nothing but the inner surface, and tell which points are in the cavity.
TEST_CASE("EmbreeScene's inner-surface packets answer rays in the cavity as closest_hit does",
          "[render]") {
    // Rays in the cavity: from the camera point, and from points on the inner surface back
    // into the cavity (as the fast integrator's reflections). Their first surface in the whole
    // scene is the inner surface or nothing, and the inner surface's own BVH gives the same.
    detail::EmbreeScene scene;
    scene.set_frame(dome_with_marker_frame());
    Eigen::Matrix<double, 3, Eigen::Dynamic> random = Eigen::MatrixXd::Random(3, 64);
    int compared = 0, hits = 0;
    for (const int count : {16, 11, 2}) {
        std::vector<Vec3> origins, directions;
        for (int i = 0; i < count; ++i, ++compared) {
            Vec3 w = random.col(compared % random.cols()).normalized();
            if (i % 2 == 0) {
                // Mostly up into the dome; every fourth ray may leave through the base.
                origins.push_back(Vec3::Zero());
                w = Vec3(w.x(), w.y(), std::abs(w.z()) + (i % 4 == 0 ? -0.3 : 0.1)).normalized();
            } else {
                // A point of the inner surface, and a direction back into the cavity.
                const detail::RayHit out = scene.closest_hit(
                    Vec3::Zero(), Vec3(w.x(), w.y(), std::abs(w.z()) + 0.1).normalized(), 0.0,
                    100.0);
                REQUIRE(out.kind == detail::SurfaceKind::inner_surface);
                const Vec3 dir = Vec3(w.x(), w.y(), std::abs(w.z()) + 0.1).normalized();
                origins.push_back(out.t_mm * dir);
                w = (random.col((compared + 5) % random.cols()).normalized() - 1.5 * dir)
                        .normalized();
            }
            directions.push_back(w);
        }
        std::vector<detail::RayHit> packed(std::size_t(count), detail::RayHit{});
        const double tnear = detail::kHitGap_mm;
        scene.closest_interface_hits16(origins, directions, tnear, 100.0, packed);
        for (int i = 0; i < count; ++i) {
            const auto k = std::size_t(i);
            const detail::RayHit one = scene.closest_hit(origins[k], directions[k], tnear, 100.0);
            const detail::RayHit& two = packed[k];
            INFO("count " << count << ", ray " << i);
            CHECK(two.kind == one.kind);
            CHECK(two.prim_id == one.prim_id);
            CHECK(two.t_mm == Approx(one.t_mm).epsilon(1e-5));
            CHECK(two.u == Approx(one.u).margin(1e-5));
            CHECK(two.v == Approx(one.v).margin(1e-5));
            CHECK((two.normal - one.normal).norm() < 1e-6);
            CHECK((two.shading_normal - one.shading_normal).norm() < 1e-6);
            hits += one.kind == detail::SurfaceKind::inner_surface;
        }
    }
    CHECK(hits > 10);
    // From inside the layers the whole scene meets markers and the coating; the inner surface's
    // BVH does not.
    const std::vector<Vec3> in_layers(4, Vec3(0.0, 0.0, 11.5));
    const std::vector<Vec3> up(4, Vec3(0.01, 0.02, 1.0).normalized());
    std::vector<detail::RayHit> packed(4);
    scene.closest_interface_hits16(in_layers, up, 0.0, 100.0, packed);
    const detail::RayHit whole = scene.closest_hit(in_layers[0], up[0], 0.0, 100.0);
    CHECK(whole.kind != detail::SurfaceKind::none);
    CHECK(whole.kind != detail::SurfaceKind::inner_surface);
    for (const detail::RayHit& hit : packed)
        CHECK(hit.kind == detail::SurfaceKind::none);
    // Which points count as in the cavity: the centre and points well inside the inner
    // surface, on or above the rim plane; not in the layers, below the rim plane or outside.
    CHECK(scene.in_cavity(Vec3::Zero()));
    CHECK(scene.in_cavity(Vec3(3.0, -2.0, 5.0)));
    CHECK_FALSE(scene.in_cavity(Vec3(0.0, 0.0, 11.5)));
    CHECK_FALSE(scene.in_cavity(Vec3(0.0, 0.0, -1.0)));
    CHECK_FALSE(scene.in_cavity(Vec3(10.0, 10.0, 10.0)));
    SensorFrame bare = dome_with_marker_frame();
    bare.inner_surface = SurfaceMesh{};
    detail::EmbreeScene without;
    without.set_frame(bare);
    CHECK_FALSE(without.in_cavity(Vec3::Zero()));
}

TEST_CASE("shadow transmittance multiplies marker transmissions, the coating blocks", "[render]") {
    const OpticsParams optics;
    const detail::ShadingModel shading(optics);
    SensorFrame frame = marker_frame();
    frame.outer_markers = discs({{Vec3(0.0, 0.0, 12.4), Vec3::UnitZ()}}); // z 12.155..12.645
    detail::EmbreeScene scene;
    scene.set_frame(frame);
    const Vec3 from(0.0, 0.0, 1.0);
    const Eigen::Array3d a_in = optics.inner_marker_absorption_per_mm.array();
    const detail::Rgb inner = (-a_in * kThickness_mm).exp();
    const detail::Rgb outer =
        (1.0 - optics.outer_marker_scatter_fraction) *
        (-optics.outer_marker_absorption_per_mm.array() * kThickness_mm).exp();
    const detail::Rgb clear = shading.transmittance(scene, from, Vec3(0.0, 0.0, 10.0));
    const detail::Rgb one = shading.transmittance(scene, from, Vec3(0.0, 0.0, 12.0));
    const detail::Rgb two = shading.transmittance(scene, from, Vec3(0.0, 0.0, 12.68));
    const detail::Rgb blocked = shading.transmittance(scene, from, Vec3(0.0, 0.0, 14.0));
    // Segments that start or end inside the inner volume (z 10.505..10.995) count only the
    // part inside.
    const detail::Rgb from_inside =
        shading.transmittance(scene, Vec3(0.0, 0.0, 10.75), Vec3(0.0, 0.0, 12.0));
    const detail::Rgb into = shading.transmittance(scene, from, Vec3(0.0, 0.0, 10.801));
    for (int k = 0; k < 3; ++k) {
        CHECK(clear[k] == 1.0);
        CHECK(one[k] == Approx(inner[k]).epsilon(1e-6));
        CHECK(two[k] == Approx(inner[k] * outer[k]).epsilon(1e-5));
        CHECK(blocked[k] == 0.0);
        CHECK(from_inside[k] == Approx(std::exp(-a_in[k] * 0.245)).epsilon(1e-6));
        CHECK(into[k] == Approx(std::exp(-a_in[k] * (0.8 - 0.505))).epsilon(1e-5));
    }
}

TEST_CASE("grazing rays through markers take the real chord, squeezed markers stay finite",
          "[render]") {
    // A ray along (almost) +z through an inner prism tilted 85 deg: thickness / |cos| would
    // be 5.6 mm; the volume's real chord is about a disc diameter.
    const OpticsParams optics;
    const detail::ShadingModel shading(optics);
    SensorFrame frame = bare_frame();
    const Vec3 tilted_normal = unit_from_angles(85.0, 0.0);
    frame.inner_markers = discs({{Vec3(0.0, 0.0, kInnerMarkerZ_mm), tilted_normal}});
    detail::EmbreeScene with_disc, without_disc;
    with_disc.set_frame(frame);
    without_disc.set_frame(bare_frame());
    const Vec3 ray = Vec3(0.0, 0.001, 1.0).normalized();
    const detail::Rgb seen = shading.radiance(with_disc, Vec3::Zero(), ray);
    const detail::Rgb reference = shading.radiance(without_disc, Vec3::Zero(), ray);
    const double chord = chord_mm(Vec3::Zero(), ray, Vec3(0.0, 0.0, kInnerMarkerZ_mm),
                                  tilted_normal, kThickness_mm, 12.0);
    CHECK(chord > 0.9);
    CHECK(chord < 1.1);
    const detail::Rgb expected = (-optics.inner_marker_absorption_per_mm.array() * chord).exp();
    for (int k = 0; k < 3; ++k)
        CHECK(seen[k] / reference[k] == Approx(expected[k]).epsilon(1e-4));

    // A marker squeezed to zero thickness: its faces coincide; the ray enters and leaves at
    // once (path 0), nothing is absorbed, and nothing turns NaN.
    MeshBuilder flat;
    add_disc(flat, Vec3(0.0, 0.0, kInnerMarkerZ_mm), Vec3::UnitZ(), 0.0);
    frame.inner_markers = flat.build();
    with_disc.set_frame(frame);
    const detail::Rgb squeezed = shading.radiance(with_disc, Vec3::Zero(), ray);
    for (int k = 0; k < 3; ++k)
        CHECK(squeezed[k] == Approx(reference[k]).epsilon(1e-9));

    // Whole images with discs seen edge-on and nearly edge-on, one absorption channel zero
    // (an infinite path would turn 0 * inf into NaN).
    OpticsParams clear_red = optics;
    clear_red.inner_marker_absorption_per_mm.x() = 0.0;
    frame.inner_markers = discs({{Vec3(0.0, 0.0, kInnerMarkerZ_mm), Vec3::UnitX()},
                                 {Vec3(2.0, 0.0, 10.5), unit_from_angles(89.99, 180.0)},
                                 {Vec3(0.0, 3.0, 10.3), unit_from_angles(90.0, 90.0)}});
    frame.outer_markers = discs({{Vec3(-3.0, 0.0, 12.0), Vec3::UnitX()}});
    CHECK(all_finite(render_frame(CameraParams{64, 64, 84.0}, clear_red, frame)));
}

TEST_CASE("bad input is reported, not rendered", "[render]") {
    OpticsParams optics;
    optics.outer_marker_scatter_fraction = 1.5;
    CHECK_THROWS_AS(Renderer(CameraParams{}, optics), std::invalid_argument);
    optics = OpticsParams{};
    optics.led_z_mm = 20.0; // above the dome: the apex is dark, no auto exposure
    CHECK_THROWS_AS(Renderer(CameraParams{}, optics), std::invalid_argument);

    Renderer renderer(CameraParams{16, 16, 84.0}, OpticsParams{});
    CHECK_THROWS_AS(renderer.render({1, 1}), std::logic_error);
    SensorFrame frame = marker_frame();
    frame.triangles_per_marker = 5;
    CHECK_THROWS_AS(renderer.set_frame(frame), std::invalid_argument);
    frame = marker_frame();
    frame.coating.F(0, 1) = std::uint32_t(frame.coating.V.rows());
    CHECK_THROWS_AS(renderer.set_frame(frame), std::invalid_argument);
    renderer.set_frame(marker_frame());
    CHECK_THROWS_AS(renderer.render({0, 1}), std::invalid_argument);

    CHECK_THROWS_WITH(detail::EmbreeScene("threads=abc"),
                      Catch::Contains("Embree error in rtcNewDevice"));
}

// The filters lie over the white coating.
TEST_CASE("filter_product: through two filters a pixel is the spectral product of their "
          "transmittances",
          "[render][spectral]") {
    OpticsParams optics;
    optics.spectra = load_sensor_spectra(SensorSpectraFiles::in_directory(
        std::filesystem::path(CHROMASIM_SOURCE_DIR) / "assets" / "spectra"));
    optics.outer_marker_scatter_fraction = 0.0; // the cyan dye as a pure filter here
    const SensorSpectra& sp = *optics.spectra;
    // A magenta prism (z 10.505..10.995) and below it a cyan one (z 9.505..9.995) on the axis:
    // the view ray crosses both; every LED -> apex segment passes them more than 1.2 mm off
    // the axis, outside their 0.5 mm radius, so only the view is filtered.
    SensorFrame frame = bare_frame();
    frame.inner_markers = discs({{Vec3(0.0, 0.0, kInnerMarkerZ_mm), Vec3::UnitZ()}});
    frame.outer_markers = discs({{Vec3(0.0, 0.0, 9.75), Vec3::UnitZ()}});
    const CameraParams camera{3, 3, 1.0}; // the centre pixel within 0.33 deg of the axis
    const int spp = 4096;
    const Eigen::Array3d seen = pixel(render_frame(camera, optics, frame, spp, 3), 1, 1);
    const Eigen::Array3d white = pixel(render_frame(camera, optics, bare_frame(), spp, 3), 1, 1);

    const Spectrum lit = sp.camera.led_emission() * sp.coating_albedo;
    const Spectrum filtered = lit *
                              transmittance(sp.inner_marker_absorption_per_mm, kThickness_mm) *
                              transmittance(sp.outer_marker_absorption_per_mm, kThickness_mm);
    const Eigen::Array3d expected =
        sp.camera.rgb_of_radiance(filtered) / sp.camera.rgb_of_radiance(lit);
    // The RGB approximation: the product of each filter's own camera-RGB transmittance.
    const FilterPairRgb pair =
        rgb_of_filter_pair(sp.camera, sp.inner_marker_absorption_per_mm, kThickness_mm,
                           sp.outer_marker_absorption_per_mm, kThickness_mm);
    for (int k = 0; k < 3; ++k) {
        INFO("channel " << k << ": rendered " << seen[k] / white[k] << ", spectral product "
                        << expected[k] << ", RGB product " << pair.rgb_product[k]);
        CHECK(seen[k] / white[k] == Approx(expected[k]).epsilon(0.01));
    }
    // The difference the spectral mode exists for (SENSOR.md: mixing is per wavelength).
    CHECK((pair.rgb_product - pair.spectral).abs().maxCoeff() > 0.02);
}

TEST_CASE("a pixel's samples take every hero-wavelength stratum once, whatever their count",
          "[render]") {
    // (3 k + 1) mod n, the renderer's up to 0.6.0, took one stratum in three three times when
    // 3 divided n (24 spp was noisier than 16: 1.46 against 1.27 % at 224 px).
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

TEST_CASE("determinism: the same bytes with 1 and 2 threads, spectral and RGB", "[render]") {
    OpticsParams spectral;
    spectral.spectra = load_sensor_spectra(SensorSpectraFiles::in_directory(
        std::filesystem::path(CHROMASIM_SOURCE_DIR) / "assets" / "spectra"));
    for (const OpticsParams& optics : {OpticsParams{}, spectral}) {
        auto render_with = [&](int threads) {
            const tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                                            std::size_t(threads));
            return render_frame(CameraParams{48, 48, 84.0}, optics, marker_frame(), 3, 5);
        };
        const Image one = render_with(1), two = render_with(2);
        REQUIRE(one.rgb.size() == two.rgb.size());
        CHECK(std::memcmp(one.rgb.data(), two.rgb.data(), one.rgb.size() * sizeof(float)) == 0);
    }
}

TEST_CASE("extra channels: marker ids per layer and a variance estimate, only when asked",
          "[render]") {
    const OpticsParams optics;
    Renderer renderer(kWideCamera, optics);
    renderer.set_frame(marker_frame());
    const Image plain = renderer.render({4, 1});
    CHECK(plain.inner_marker_id.empty());
    CHECK(plain.variance.empty());
    RenderSettings settings{4, 1};
    settings.marker_ids = settings.variance = true;
    const Image image = renderer.render(settings);
    CHECK(image.rgb == plain.rgb); // the extra channels do not disturb the samples
    const std::size_t pixels = std::size_t(image.width) * image.height;
    REQUIRE(image.inner_marker_id.size() == pixels);
    REQUIRE(image.outer_marker_id.size() == pixels);
    REQUIRE(image.variance.size() == 3 * pixels);
    // The inner marker's centre pixel sees marker 0 of the inner layer and no outer marker;
    // the outer marker's sees marker 0 of the outer layer; a plain coating pixel sees none.
    auto at = [&](const Vec3& p) {
        const auto xy = renderer.project(p);
        REQUIRE(xy);
        return std::size_t(std::floor(xy->y())) * image.width + std::size_t(std::floor(xy->x()));
    };
    const std::size_t inner = at(Vec3(0.0, 0.0, kInnerMarkerZ_mm));
    const std::size_t outer = at(kOuterMarkerDirection);
    const std::size_t plain_px = at(unit_from_angles(25.0, 200.0));
    CHECK(image.inner_marker_id[inner] == 0);
    CHECK(image.outer_marker_id[inner] == -1);
    CHECK(image.outer_marker_id[outer] == 0);
    CHECK(image.inner_marker_id[outer] == -1);
    CHECK(image.inner_marker_id[plain_px] == -1);
    CHECK(image.outer_marker_id[plain_px] == -1);
    // Variance: finite and >= 0 everywhere; at a marker's edge (samples on both sides) far
    // above the smooth coating's.
    double edge = 0.0;
    for (std::size_t p = 0; p < pixels; ++p)
        for (int c = 0; c < 3; ++c) {
            const float v = image.variance[3 * p + std::size_t(c)];
            REQUIRE(std::isfinite(v));
            REQUIRE(v >= 0.0f);
        }
    for (std::size_t p = 0; p < pixels; ++p)
        if (image.inner_marker_id[p] == 0)
            for (const std::size_t q : {p - 1, p + 1})
                if (image.inner_marker_id[q] == -1)
                    edge = std::max(edge, double(image.variance[3 * p + 1]));
    CHECK(edge > 100.0 * image.variance[3 * plain_px + 1]);
}

TEST_CASE("degenerate deformation: zero-area triangles and rays at the image circle's rim stay "
          "finite",
          "[render][extreme]") {
    SensorFrame frame = marker_frame();
    frame.inner_surface = hemisphere(10.5, 24, 48);
    const SensorFrame rest = frame; // the fast integrator's light cache is built at rest
    // Collapse the first coating triangle and a whole marker face onto a point, and flatten
    // the outer marker onto a line: zero-area triangles with zero normals.
    const Eigen::RowVector3f p = frame.coating.V.row(frame.coating.F(0, 0));
    for (int k = 0; k < 3; ++k)
        frame.coating.V.row(frame.coating.F(0, k)) = p;
    for (int t = 0; t < kRim; ++t) // the inner marker's inner face (triangles 4 t)
        for (int k = 0; k < 3; ++k)
            frame.inner_markers.V.row(frame.inner_markers.F(4 * t, k)) =
                frame.inner_markers.V.row(0);
    frame.outer_markers.V.col(1).setZero();
    frame.outer_markers.V.col(2).setConstant(12.45f);
    OpticsParams spectral;
    spectral.spectra = load_sensor_spectra(SensorSpectraFiles::in_directory(
        std::filesystem::path(CHROMASIM_SOURCE_DIR) / "assets" / "spectra"));
    // The path and fast integrators also refract at an inner surface with a collapsed triangle.
    const Eigen::RowVector3f q = frame.inner_surface.V.row(frame.inner_surface.F(7, 0));
    for (int k = 0; k < 3; ++k)
        frame.inner_surface.V.row(frame.inner_surface.F(7, k)) = q;
    for (const Integrator integrator : {Integrator::direct, Integrator::path, Integrator::fast})
        for (const OpticsParams& optics : {OpticsParams{}, spectral}) {
            INFO("integrator " << int(integrator) << ", spectral " << bool(optics.spectra));
            // 84 deg: the rim pixels' rays run almost along the rim plane, grazing the coating.
            const Image image =
                render_frame(CameraParams{96, 96, 84.0}, optics, frame, 4, 9, integrator, &rest);
            CHECK(all_finite(image));
            CHECK(*std::max_element(image.rgb.begin(), image.rgb.end()) < 100.0f);
            // A camera wider than the dome (100 deg): rays below the rim plane see nothing.
            CHECK(all_finite(
                render_frame(CameraParams{64, 64, 100.0}, optics, frame, 2, 9, integrator, &rest)));
        }
}
