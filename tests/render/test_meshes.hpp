#pragma once
// Small triangle meshes for the render tests: a growable triangle soup and a UV hemisphere.
#include "render/furnace.hpp"
#include "render/scene_data.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <vector>

namespace chromasim::render::test {

inline Vec3 unit_from_angles(double polar_deg, double azimuth_deg) {
    const double theta = polar_deg * std::numbers::pi / 180.0;
    const double phi = azimuth_deg * std::numbers::pi / 180.0;
    return {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
}

/// Growable triangle soup that becomes a SurfaceMesh.
struct MeshBuilder {
    std::vector<Vec3> vertices;
    std::vector<std::array<std::uint32_t, 3>> triangles;

    std::uint32_t add_vertex(const Vec3& v) {
        vertices.push_back(v);
        return std::uint32_t(vertices.size() - 1);
    }
    SurfaceMesh build() const {
        SurfaceMesh mesh;
        mesh.V.resize(Eigen::Index(vertices.size()), 3);
        mesh.F.resize(Eigen::Index(triangles.size()), 3);
        for (std::size_t i = 0; i < vertices.size(); ++i)
            mesh.V.row(i) = vertices[i].cast<float>();
        for (std::size_t i = 0; i < triangles.size(); ++i) {
            for (int k = 0; k < 3; ++k)
                mesh.F(Eigen::Index(i), k) = triangles[i][k];
        }
        return mesh;
    }
};

/// UV hemisphere z >= 0 with its pole on +z, rings every 90/rings degrees, normals inwards.
inline SurfaceMesh hemisphere(double radius_mm, int rings, int segments) {
    return uv_sphere(radius_mm, rings, segments, 90.0);
}

/// The dome's optics without markers: coating hemisphere r = 12.7 mm and inner surface
/// r = 10.5 mm, each with its rings and segments.
inline SensorFrame clear_dome(int coating_rings, int coating_segments, int inner_rings,
                              int inner_segments) {
    SensorFrame frame;
    frame.coating = hemisphere(12.7, coating_rings, coating_segments);
    frame.inner_surface = hemisphere(10.5, inner_rings, inner_segments);
    return frame;
}

/// A contact: both surfaces of `rest` pressed flat at the apex (z <= 9 mm inside, 11.2 mm
/// outside), where the sphere through the point below has the wrong normal.
inline SensorFrame pressed_flat(const SensorFrame& rest) {
    SensorFrame pressed = rest;
    for (Eigen::Index v = 0; v < pressed.inner_surface.V.rows(); ++v)
        pressed.inner_surface.V(v, 2) = std::min(pressed.inner_surface.V(v, 2), 9.0f);
    for (Eigen::Index v = 0; v < pressed.coating.V.rows(); ++v)
        pressed.coating.V(v, 2) = std::min(pressed.coating.V(v, 2), 11.2f);
    return pressed;
}

} // namespace chromasim::render::test
