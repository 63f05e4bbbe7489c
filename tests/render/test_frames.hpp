#pragma once
// The small synthetic sensor of the render tests: a UV hemisphere of radius 12.7 mm as the
// coating and marker prisms (12-gon discs of radius 0.5 mm, closed volumes of thickness
// kThickness_mm), its frames, and a frame rendered in one call.
#include "render/renderer.hpp"
#include "test_meshes.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <utility>
#include <vector>

namespace chromasim::render::test {

inline constexpr double kPi = std::numbers::pi;
inline constexpr int kRim = 12;
inline constexpr int kTrianglesPerMarker = 4 * kRim; // two fans and the side
inline constexpr double kMarkerRadius_mm = 0.5;
inline constexpr double kThickness_mm = 0.49;
inline constexpr double kInnerMarkerZ_mm = 10.75;
inline constexpr double kOuterMarkerRadius_mm = 12.45;

/// Rim point k of a marker face centred at c with axis n (the 12-gon's frame u, v).
inline Vec3 rim_point(const Vec3& c, const Vec3& n, int k) {
    const Vec3 u = n.unitOrthogonal(), v = n.cross(u);
    const double phi = 2.0 * kPi * k / kRim;
    return c + kMarkerRadius_mm * (std::cos(phi) * u + std::sin(phi) * v);
}

/// Appends a closed marker prism of `kTrianglesPerMarker` triangles facing outwards: a 12-gon
/// of radius 0.5 mm centred at `centre_mm`, extruded by thickness/2 both ways along `normal`.
inline void add_disc(MeshBuilder& mesh, const Vec3& centre_mm, const Vec3& normal,
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

/// Marker prisms (add_disc) at the given centres along the given axes, in one mesh.
inline SurfaceMesh discs(const std::vector<std::pair<Vec3, Vec3>>& centres_and_normals) {
    MeshBuilder mesh;
    for (const auto& [centre, normal] : centres_and_normals)
        add_disc(mesh, centre, normal);
    return mesh.build();
}

/// Coating only; markers get added by the tests.
inline SensorFrame bare_frame() {
    SensorFrame frame;
    frame.coating = hemisphere(12.7, 90, 96);
    frame.triangles_per_marker = kTrianglesPerMarker;
    return frame;
}

inline const Vec3 kOuterMarkerDirection = unit_from_angles(25.0, 90.0);

/// Inner marker at the apex, outer marker at polar 25 deg, azimuth 90 deg (SensorFrame docs).
inline SensorFrame marker_frame() {
    SensorFrame frame = bare_frame();
    frame.inner_markers = discs({{Vec3(0.0, 0.0, kInnerMarkerZ_mm), Vec3::UnitZ()}});
    frame.outer_markers =
        discs({{kOuterMarkerRadius_mm * kOuterMarkerDirection, kOuterMarkerDirection}});
    return frame;
}

/// A dome with an inner surface and marker_frame()'s two markers.
inline SensorFrame dome_with_marker_frame() {
    SensorFrame frame = clear_dome(12, 48, 10, 40);
    const SensorFrame markers = marker_frame();
    frame.inner_markers = markers.inner_markers;
    frame.outer_markers = markers.outer_markers;
    return frame;
}

/// `rest`: the fast integrator's light cache is built on it (a quick one: 8 paths per vertex).
inline Image render_frame(const CameraParams& camera, const OpticsParams& optics,
                          const SensorFrame& frame, int spp = 2, std::uint64_t seed = 1,
                          Integrator integrator = Integrator::preview,
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

inline bool all_finite(const Image& image) {
    return std::all_of(image.rgb.begin(), image.rgb.end(),
                       [](float v) { return std::isfinite(v); });
}

} // namespace chromasim::render::test
