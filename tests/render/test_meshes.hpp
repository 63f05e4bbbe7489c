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

/// A smooth press: every vertex of both surfaces of `rest` moved towards the centre by
/// depth_mm exp(-theta^2 / (2 sigma^2)) at polar angle theta, so that the inner surface's
/// normals tilt by up to about 10 deg on the dent's flank (a 45 mm sphere at 2 N).
inline SensorFrame pressed_smooth(const SensorFrame& rest, double depth_mm = 2.0,
                                  double sigma_deg = 15.0) {
    SensorFrame pressed = rest;
    const double sigma = sigma_deg * std::numbers::pi / 180.0;
    for (SurfaceMesh* mesh : {&pressed.inner_surface, &pressed.coating})
        for (Eigen::Index v = 0; v < mesh->V.rows(); ++v) {
            const Vec3 x = mesh->V.row(v).cast<double>();
            const double theta = std::acos(std::clamp(x.z() / x.norm(), -1.0, 1.0));
            const double r = x.norm() - depth_mm * std::exp(-theta * theta / (2 * sigma * sigma));
            mesh->V.row(v) = (r * x.normalized()).cast<float>().transpose();
        }
    return pressed;
}

/// Box markers (12 triangles each, normals outwards) on ChromaTouch's pattern (SENSOR.md 1: an
/// apex marker and rings every 12.5 degrees of polar angle up to 62.5, round(6 sin(k 12.5) /
/// sin(12.5)) markers on ring k), centred on the sphere of radius_mm, thickness_mm along the
/// radius and width_mm across.
inline SurfaceMesh box_markers(double radius_mm, double thickness_mm, double width_mm) {
    MeshBuilder mesh;
    const double step = 12.5 * std::numbers::pi / 180.0;
    for (int ring = 0; ring <= 5; ++ring) {
        const int count =
            ring == 0 ? 1 : int(std::lround(6.0 * std::sin(ring * step) / std::sin(step)));
        for (int m = 0; m < count; ++m) {
            const Vec3 u = unit_from_angles(12.5 * ring, 360.0 * m / count);
            const Vec3 a = (std::abs(u.z()) < 0.9 ? Vec3::UnitZ() : Vec3::UnitX()).cross(u);
            const Vec3 e1 = a.normalized(), e2 = u.cross(e1);
            const Vec3 centre = radius_mm * u;
            std::uint32_t corner[8];
            for (int c = 0; c < 8; ++c)
                corner[c] = mesh.add_vertex(centre + ((c & 1) ? 0.5 : -0.5) * thickness_mm * u +
                                            ((c & 2) ? 0.5 : -0.5) * width_mm * e1 +
                                            ((c & 4) ? 0.5 : -0.5) * width_mm * e2);
            // Each face as two triangles, wound so that the normal points out of the box.
            static constexpr int faces[6][4] = {{0, 2, 6, 4}, {1, 3, 7, 5}, {0, 1, 5, 4},
                                                {2, 3, 7, 6}, {0, 1, 3, 2}, {4, 5, 7, 6}};
            for (const auto& f : faces) {
                const Vec3 p0 = mesh.vertices[corner[f[0]]], p1 = mesh.vertices[corner[f[1]]],
                           p2 = mesh.vertices[corner[f[2]]];
                const bool out = (p1 - p0).cross(p2 - p0).dot((p0 + p2) / 2.0 - centre) > 0.0;
                const std::uint32_t q[4] = {corner[f[0]], corner[f[1]], corner[f[2]], corner[f[3]]};
                if (out) {
                    mesh.triangles.push_back({q[0], q[1], q[2]});
                    mesh.triangles.push_back({q[0], q[2], q[3]});
                } else {
                    mesh.triangles.push_back({q[0], q[2], q[1]});
                    mesh.triangles.push_back({q[0], q[3], q[2]});
                }
            }
        }
    }
    return mesh.build();
}

/// `rest`'s coating with a groove: the vertices between the polar angles lo_deg and hi_deg
/// pushed in towards the centre by depth_mm, so that its walls fold the coating inwards.
inline SensorFrame grooved(const SensorFrame& rest, double lo_deg, double hi_deg, double depth_mm) {
    SensorFrame out = rest;
    for (Eigen::Index v = 0; v < out.coating.V.rows(); ++v) {
        const Vec3 p = out.coating.V.row(v).cast<double>().transpose();
        const double polar = std::acos(p.normalized().z()) * 180.0 / std::numbers::pi;
        if (polar > lo_deg && polar < hi_deg)
            out.coating.V.row(v) = (p * (1.0 - depth_mm / p.norm())).cast<float>().transpose();
    }
    return out;
}

/// The FUSE sensor's LEDs (13.8 mm under the rim) and lens barrel (docs/SENSOR.md).
inline OpticsParams fuse_optics() {
    OpticsParams o;
    o.led_z_mm = -13.8;
    o.lens_radius_mm = 8.0;
    return o;
}

} // namespace chromasim::render::test
