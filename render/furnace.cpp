#include "render/furnace.hpp"

#include "render/embree_scene.hpp"
#include "render/path_integrator.hpp"

#include <Eigen/Geometry>

#include <chrono>
#include <cmath>
#include <numbers>

namespace chromasim::render {

SurfaceMesh uv_sphere(double radius_mm, int rings, int segments, double max_polar_deg) {
    constexpr double kPi = std::numbers::pi;
    SurfaceMesh mesh;
    mesh.V.resize(1 + Eigen::Index(rings) * segments, 3);
    mesh.V.row(0) << 0.0f, 0.0f, float(radius_mm);
    for (int i = 1; i <= rings; ++i)
        for (int j = 0; j < segments; ++j) {
            const double theta = max_polar_deg * kPi / 180.0 * i / rings;
            const double phi = 2.0 * kPi * j / segments;
            mesh.V.row(1 + Eigen::Index(i - 1) * segments + j) =
                (radius_mm * Eigen::Vector3d(std::sin(theta) * std::cos(phi),
                                             std::sin(theta) * std::sin(phi), std::cos(theta)))
                    .cast<float>()
                    .transpose();
        }
    auto ring = [&](int i, int j) { return std::uint32_t(1 + (i - 1) * segments + j % segments); };
    mesh.F.resize(Eigen::Index(segments) * (2 * rings - 1), 3);
    Eigen::Index f = 0;
    for (int j = 0; j < segments; ++j)
        mesh.F.row(f++) << 0u, ring(1, j + 1), ring(1, j);
    for (int i = 1; i < rings; ++i)
        for (int j = 0; j < segments; ++j) {
            mesh.F.row(f++) << ring(i, j), ring(i, j + 1), ring(i + 1, j);
            mesh.F.row(f++) << ring(i, j + 1), ring(i + 1, j + 1), ring(i + 1, j);
        }
    return mesh;
}

FurnaceResult run_furnace(const FurnaceSettings& s) {
    using namespace detail;
    const auto t0 = std::chrono::steady_clock::now();
    SensorFrame frame;
    frame.coating = uv_sphere(s.radius_mm, s.rings, s.segments);
    EmbreeScene scene;
    scene.set_frame(frame);
    OpticsParams optics;
    optics.led_ring_radius_mm = 0.4 * s.radius_mm;
    optics.led_width_mm = optics.led_height_mm = 0.05;
    optics.frame_inner_radius_mm = 1e9; // no clamping frame: the sphere is closed
    const ShadingModel shading(optics);
    const PathIntegrator integrator(shading);
    LaneOptics<kRgbLanes> lanes;
    lanes.coating_albedo = RgbLanes(s.albedo[0], s.albedo[1], s.albedo[2], 0.0);
    lanes.inner_absorption_per_mm = lanes.outer_absorption_per_mm = RgbLanes::Zero();
    lanes.outer_albedo = RgbLanes::Zero();
    lanes.led = RgbLanes(1.0, 1.0, 1.0, 0.0);

    const double theta = s.polar_deg * std::numbers::pi / 180.0;
    const Vec3 direction(std::sin(theta), 0.0, std::cos(theta));
    PixelRng rng(s.seed, 0);
    RgbLanes sum = RgbLanes::Zero(), sum2 = RgbLanes::Zero();
    for (int i = 0; i < s.paths; ++i) {
        const RgbLanes L = integrator.radiance(scene, Vec3::Zero(), direction, lanes, rng);
        sum += L;
        sum2 += L.square();
    }
    FurnaceResult r;
    const RgbLanes mean = sum / s.paths;
    const RgbLanes se = ((sum2 / s.paths - mean.square()).max(0.0) / (s.paths - 1.0)).sqrt();
    r.measured = mean.head<3>();
    r.standard_error = se.head<3>();
    double area = 0.0;
    for (Eigen::Index f = 0; f < frame.coating.F.rows(); ++f) {
        const Vec3 a = frame.coating.V.row(frame.coating.F(f, 0)).cast<double>(),
                   b = frame.coating.V.row(frame.coating.F(f, 1)).cast<double>(),
                   c = frame.coating.V.row(frame.coating.F(f, 2)).cast<double>();
        area += 0.5 * (b - a).cross(c - a).norm();
    }
    const double power = optics.led_count * std::numbers::pi; // pi L_e A_led, L_e A_led = 1
    r.expected = s.albedo.square() * power / (std::numbers::pi * area * (1.0 - s.albedo));
    r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return r;
}

} // namespace chromasim::render
