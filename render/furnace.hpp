#pragma once
/// The furnace test of the path integrator: an integrating sphere. A closed Lambertian sphere
/// of albedo rho with LEDs inside facing +z; below the LED plane there is no direct light, and
/// the indirect irradiance in a Lambertian sphere is uniform (every pair of points on a sphere
/// exchanges light with cos cos / d^2 = 1 / (4 R^2)), so the radiance seen there is
///     L = rho^2 Phi / (pi A (1 - rho)),   Phi = led_count pi L_e A_led (Lambertian LEDs),
/// with A the sphere's (tessellated) area. Used by tests/render and `chromasim verify render`.
#include "render/scene_data.hpp"

#include <Eigen/Core>

#include <cstdint>

namespace chromasim::render {

struct FurnaceSettings {
    double radius_mm = 12.7;
    int rings = 128, segments = 256; ///< UV tessellation of the sphere
    Eigen::Array3d albedo{0.3, 0.6, 0.8};
    int paths = 1000000;      ///< along one camera ray from the centre
    double polar_deg = 130.0; ///< of that ray (below the LED plane)
    std::uint64_t seed = 7;
};

struct FurnaceResult {
    Eigen::Array3d measured, standard_error, expected; ///< per RGB lane
    double seconds = 0.0;
};

/// Path-traces the integrating sphere (RGB lanes, tiny LEDs so their own shadow is negligible,
/// no clamping frame) and returns the radiance estimate with its standard error beside the
/// analytic value.
FurnaceResult run_furnace(const FurnaceSettings& settings);

/// UV sphere cap (pole on +z) from the pole down to `max_polar_deg` (90: the hemisphere
/// z >= 0; 180: the closed sphere, its last ring collapsed onto the south pole), rings every
/// max_polar_deg / rings degrees, normals inwards.
SurfaceMesh uv_sphere(double radius_mm, int rings, int segments, double max_polar_deg = 180.0);

} // namespace chromasim::render
