#pragma once
// Small triangle meshes for the render tests: a growable triangle soup and UV spheres.
#include "render/scene_data.hpp"

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

/// UV sphere cap from the pole on +z down to `max_polar_deg` (90: a hemisphere z >= 0, 180:
/// the closed sphere, its last ring collapsed onto the south pole), rings every max_polar_deg/rings
/// degrees, normals inwards.
inline SurfaceMesh sphere_cap(double radius_mm, int rings, int segments, double max_polar_deg) {
    MeshBuilder mesh;
    const std::uint32_t pole = mesh.add_vertex(Vec3(0.0, 0.0, radius_mm));
    for (int i = 1; i <= rings; ++i) {
        for (int j = 0; j < segments; ++j) {
            mesh.add_vertex(radius_mm *
                            unit_from_angles(max_polar_deg * i / rings, 360.0 * j / segments));
        }
    }
    auto ring_vertex = [&](int i, int j) {
        return std::uint32_t(1 + (i - 1) * segments + j % segments);
    };
    for (int j = 0; j < segments; ++j)
        mesh.triangles.push_back({pole, ring_vertex(1, j + 1), ring_vertex(1, j)});
    for (int i = 1; i < rings; ++i) {
        for (int j = 0; j < segments; ++j) {
            const std::uint32_t a = ring_vertex(i, j), b = ring_vertex(i, j + 1);
            const std::uint32_t c = ring_vertex(i + 1, j), d = ring_vertex(i + 1, j + 1);
            mesh.triangles.push_back({a, b, c});
            mesh.triangles.push_back({b, d, c});
        }
    }
    return mesh.build();
}

/// UV hemisphere z >= 0 with its pole on +z, rings every 90/rings degrees, normals inwards.
inline SurfaceMesh hemisphere(double radius_mm, int rings, int segments) {
    return sphere_cap(radius_mm, rings, segments, 90.0);
}

} // namespace chromasim::render::test
