#pragma once
/// The fast integrator's internals shared by its four files: fast_light_cache.cpp (the
/// light cache, built once per sensor, and the frame's share near the rim),
/// fast_frame.cpp (a frame's update and its shadow-ray culling), fast_integrator.cpp (a
/// sample's walk, shading and shadow rays) and fast_camera.cpp (the camera packets).
/// Include only from those.
#include "render/fast_integrator.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <numbers>
#include <optional>
#include <utility>
#include <vector>

namespace chromasim::render::detail {

namespace {

constexpr double kInvPi = 1.0 / std::numbers::pi;
/// Most LEDs a sample's lookup holds (the spec allows 64).
constexpr int kMaxLeds = 64;
/// A coating hit this close behind an outer marker's face lies below that marker (the faces
/// sit 1 % of the layer, 5 um, off the coating).
constexpr double kUnderMarker_mm = 0.05;
/// The shadow ray's refraction: the sphere model's mismatch (a difference of sines) at which
/// to stop, about 1e-9 rad and 1e-8 mm across the layers.
constexpr double kShadowTolerance = 1e-9;
/// ... or after a Newton step that turns the direction by less than this (rad): what is left
/// is about its square, and it saves the evaluations that would confirm it. 1e-2 leaves
/// 8e-6 rad on average and at most 3.4e-3 rad (in the contact at 5 N + 2 N), below the
/// frame correction's own 8e-3 rad against the refracted solve, in about 1.3 evaluations a
/// shadow ray.
constexpr double kShadowStepTolerance = 1e-2;
/// Shadow-ray culling: the margin of each triangle's ball over its corners' paths (mm).
constexpr double kCullMargin_mm = 0.1;
/// An edge of the coating folds inwards where its neighbour's far corner rises more than this
/// above a triangle's plane, seen from the cavity: ten times the vertices' float round-off at
/// the dome's radius (coplanar triangles of a tessellated sphere are no fold), a hundredth of
/// the rays' kHitGap_mm.
constexpr double kFoldHeight_mm = 1e-5;
/// The frame's share near the rim (FastIntegrator::tabulate_frame_share): the LED points a
/// side (their cells' centres) over which the share of an LED's light is taken at a coating
/// vertex or edge midpoint.
constexpr int kFrameShareGrid = 8;
/// A shade's draws: none (ShadowDraw::rays 0), and one shadow ray from the stream (both
/// referred to, not copied, per sample).
constexpr ShadowDraw kNoShadowRays{.rays = 0};
constexpr ShadowDraw kStreamShadowRay{};
/// radiance16 sends a bounce's rays to Embree as one packet from this many on, else one by one.
constexpr std::size_t kMinPacket = 4;

/// Where the ray from p (outside the sphere of radius R about the origin) along the unit w
/// first meets the sphere; none if it misses it or meets it behind p.
[[maybe_unused]] std::optional<Vec3> sphere_exit(const Vec3& p, const Vec3& w, double R) {
    const double b = p.dot(w), c = p.squaredNorm() - R * R;
    const double disc = b * b - c;
    if (!(disc >= 0.0)) return std::nullopt;
    const double t = -b - std::sqrt(disc);
    if (!(t > 0.0)) return std::nullopt;
    return p + t * w;
}

/// Squared distance from x to the segment [a, b].
[[maybe_unused]] double distance2_to_segment(const Vec3& x, const Vec3& a, const Vec3& b) {
    const Vec3 ab = b - a;
    const double length2 = ab.squaredNorm();
    const double t = length2 > 0.0 ? std::clamp((x - a).dot(ab) / length2, 0.0, 1.0) : 0.0;
    return (a + t * ab - x).squaredNorm();
}

/// Transmittance of a slab of optical thickness tau (per lane) for light arriving with a
/// Lambertian (cosine) distribution: 2 E_3(tau) = 2 int_0^1 mu exp(-tau / mu) dmu, by 8-point
/// Gauss-Legendre quadrature in mu (error below 1e-4 for the thicknesses of the markers).
template <int N> LanesN<N> diffuse_transmittance(const LanesN<N>& tau) {
    static constexpr double x[8] = {0.0198550717512319, 0.1016667612931866, 0.2372337950418355,
                                    0.4082826787521751, 0.5917173212478249, 0.7627662049581645,
                                    0.8983332387068134, 0.9801449282487681};
    static constexpr double w[8] = {0.0506142681451881, 0.1111905172266872, 0.1568533229389436,
                                    0.1813418916891810, 0.1813418916891810, 0.1568533229389436,
                                    0.1111905172266872, 0.0506142681451881};
    LanesN<N> sum = LanesN<N>::Zero();
    for (int i = 0; i < 8; ++i)
        sum += (2.0 * w[i] * x[i]) * (-tau / x[i]).exp();
    return sum;
}

/// The frame's coating and inner surface alone (no markers): the scene on which the light
/// cache finds the LEDs' light at rest.
[[maybe_unused]] SensorFrame coating_and_interface(const SensorFrame& frame) {
    SensorFrame bare;
    bare.coating = frame.coating;
    bare.inner_surface = frame.inner_surface;
    return bare;
}

/// Area-weighted vertex normals of the coating, turned to face the dome centre.
[[maybe_unused]] std::vector<Vec3> coating_normals(const SurfaceMesh& mesh) {
    std::vector<Vec3> n(std::size_t(mesh.V.rows()), Vec3::Zero());
    for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
        const Vec3 a = mesh.V.row(mesh.F(f, 0)).cast<double>().transpose();
        const Vec3 b = mesh.V.row(mesh.F(f, 1)).cast<double>().transpose();
        const Vec3 c = mesh.V.row(mesh.F(f, 2)).cast<double>().transpose();
        const Vec3 area = (b - a).cross(c - a); // twice the area, along the normal
        for (int k = 0; k < 3; ++k)
            n[mesh.F(f, k)] += area;
    }
    for (std::size_t v = 0; v < n.size(); ++v) {
        const Vec3 p = mesh.V.row(Eigen::Index(v)).cast<double>().transpose();
        if (n[v].norm() > 0.0) n[v].normalize();
        if (n[v].dot(p) > 0.0) n[v] = -n[v];
    }
    return n;
}

/// Each coating vertex's tributary area (a third of its triangles'), mm^2.
[[maybe_unused]] std::vector<double> vertex_areas(const SurfaceMesh& mesh) {
    std::vector<double> area(std::size_t(mesh.V.rows()), 0.0);
    for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
        const Vec3 a = mesh.V.row(mesh.F(f, 0)).cast<double>().transpose();
        const Vec3 b = mesh.V.row(mesh.F(f, 1)).cast<double>().transpose();
        const Vec3 c = mesh.V.row(mesh.F(f, 2)).cast<double>().transpose();
        const double third = (b - a).cross(c - a).norm() / 6.0;
        for (int k = 0; k < 3; ++k)
            area[std::size_t(mesh.F(f, k))] += third;
    }
    return area;
}

/// The coating's edges, each once, in the order the triangles first name them, and each
/// triangle's three (edge i from corner i to corner i + 1 mod 3).
[[maybe_unused]] void coating_edges(const std::vector<std::uint32_t>& triangles,
                                    std::vector<std::array<std::uint32_t, 2>>& edges,
                                    std::vector<std::uint32_t>& triangle_edges) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> index;
    edges.clear();
    triangle_edges.assign(triangles.size(), 0);
    for (std::size_t t = 0; t + 2 < triangles.size(); t += 3)
        for (int i = 0; i < 3; ++i) {
            const std::uint32_t a = triangles[t + std::size_t(i)],
                                b = triangles[t + std::size_t((i + 1) % 3)];
            const auto [it, added] =
                index.try_emplace({std::min(a, b), std::max(a, b)}, std::uint32_t(edges.size()));
            if (added) edges.push_back({a, b});
            triangle_edges[t + std::size_t(i)] = it->second;
        }
}

} // namespace

template <int N> struct FastIntegrator::Lookup {
    std::array<double, kMaxLeds> direct;     ///< G_k
    double radius_mm = 0.0;                  ///< the sphere model's inner radius below (0: none)
    const std::uint32_t* triangle = nullptr; ///< the hit triangle's vertices
    double weights[3] = {0.0, 0.0, 0.0};     ///< and their barycentric weights
    std::uint32_t prim = 0;                  ///< the hit triangle
    /// Bit k: the frame's share of LED k's light is off `direct` here (m_frame_triangle), and
    /// shadow rays to it leave the frame's plane out.
    std::uint64_t frame_share = 0;
};

} // namespace chromasim::render::detail
