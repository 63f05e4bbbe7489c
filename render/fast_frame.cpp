// The fast integrator's frame update: the LEDs' light carried from rest onto a deformed
// frame, and the shadow-ray culling of that frame.
#include "render/fast_common.hpp"

#include "render/sampling.hpp"
#include "render/spectrum.hpp"
#include "render/sphere_refraction.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <map>
#include <new>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>
#include <type_traits>

namespace chromasim::render::detail {

void FastIntegrator::check_topology(const SensorFrame& frame) const {
    if (!m_cache) throw std::logic_error("FastIntegrator: no light cache built");
    const LightCache& c = *m_cache;
    const auto& F = frame.coating.F;
    if (frame.coating.V.rows() != c.vertices ||
        std::size_t(F.size()) != c.coating_triangles.size() ||
        !std::equal(F.data(), F.data() + F.size(), c.coating_triangles.begin())) {
        throw std::invalid_argument(
            "FastIntegrator: the frame's coating has " + std::to_string(frame.coating.V.rows()) +
            " vertices and " + std::to_string(F.rows()) + " triangles, the light cache's " +
            std::to_string(c.vertices) + " and " + std::to_string(c.coating_triangles.size() / 3) +
            " (other triangles); allowed: the coating of the sensor the cache was built for");
    }
}

void FastIntegrator::set_frame(const SensorFrame& frame, const EmbreeScene& scene) {
    check_topology(frame);
    const LightCache& c = *m_cache;
    m_direct.assign(c.direct.size(), 0.0f);
    m_radius.assign(scene.has_interface() ? std::size_t(c.vertices) : 0, 0.0f);
    m_shadow.assign(scene.has_interface() ? c.direct.size() : 0, 0.0f);
    m_guess.assign(scene.has_interface() && m_settings.cull_shadows ? 3 * c.direct.size() : 0,
                   0.0f);
    const std::vector<Vec3> normals = coating_normals(frame.coating);
    tbb::parallel_for(0, c.vertices, [&](int v) {
        const Vec3 n = normals[std::size_t(v)];
        const Vec3 p = frame.coating.V.row(v).cast<double>().transpose() + kHitGap_mm * n;
        const auto radius =
            scene.has_interface() ? m_path.radius_below(scene, p) : std::optional<double>();
        const bool refresh = m_settings.refresh_direct && radius.has_value();
        for (int k = 0; k < c.leds; ++k) {
            // The point LED's light through this frame's inner surface, scaled by the area
            // LED's to the point LED's at rest; the rest value where this frame's solve fails.
            const std::size_t i = 3 * (std::size_t(v) * c.leds + k);
            const Eigen::Vector3f area(c.direct.data() + i), rest(c.point_rest.data() + i);
            InterfaceConnection refracted;
            refracted.direction = Vec3::Zero();
            // The solves start from the rest's connections (PointLedPaths).
            const Vec3 now = !scene.has_interface() || radius
                                 ? m_path.led_flux_point(scene, p, n, k, radius, &refracted,
                                                         &m_rest_paths[i / 3])
                                 : Vec3::Zero();
            const Vec3 model =
                radius ? m_path.refracted_direction(p, m_path.led_point(k, 0.5, 0.5), *radius)
                       : Vec3::Zero();
            if (!m_shadow.empty() && refracted.direction.squaredNorm() > 0.0) {
                // What the sphere model misses: near the contact the deformed surface is far
                // from the sphere through the point below (0.1 rad RMS at 5 N, 0.009 rad
                // with this correction).
                float* out = m_shadow.data() + 3 * (std::size_t(v) * c.leds + k);
                for (int a = 0; a < 3; ++a)
                    out[a] = float(refracted.direction[a] - model[a]);
            }
            if (!m_guess.empty() && radius) {
                // The culling's guess: the centre's direction and its change across the LED
                // (central differences over the middle half of each side), each by Newton
                // from the centre's (the whole bracket where that fails), to 1e-9 in the sines
                // or a step below 1e-4 rad (finer than the samples' kShadowStepTolerance: the
                // guess is the start of every shadow ray's solve).
                const auto towards = [&](double u1, double u2) {
                    SphereRefraction solver(p, m_path.led_point(k, u1, u2), *radius,
                                            m_shading.optics().refractive_index);
                    const auto near = model.squaredNorm() > 0.0
                                          ? solver.newton(model, kShadowTolerance, 1e-4)
                                          : std::nullopt;
                    return near ? *near : solver.solve(kShadowTolerance);
                };
                const Vec3 across = 2.0 * (towards(0.75, 0.5) - towards(0.25, 0.5));
                const Vec3 up = 2.0 * (towards(0.5, 0.75) - towards(0.5, 0.25));
                float* out = m_guess.data() + 9 * (std::size_t(v) * c.leds + k);
                for (int a = 0; a < 3; ++a) {
                    out[a] = float(model[a]);
                    out[3 + a] = float(across[a]);
                    out[6 + a] = float(up[a]);
                }
            }
            // The area LED's vector at rest turned and scaled as the point LED's changed: the
            // two point in different directions (the area's is weighted by MIS between the
            // Chains, the point's is not), so the point's direction with the area's length
            // would leave G_k 1 % low at the apex and 3 to 5 % low near the LEDs at rest.
            Eigen::Vector3f flux = area;
            if (rest.norm() > 0.0f && now.norm() > 0.0) {
                const Eigen::Vector3d from = rest.cast<double>();
                flux = (Eigen::Quaterniond::FromTwoVectors(from, now) *
                        (area.cast<double>() * (now.norm() / from.norm())))
                           .cast<float>();
            }
            // A relative change, or light where there was none at rest (a vertex the press
            // turned towards an LED).
            if (refresh &&
                (now - rest.cast<double>()).norm() > m_settings.refresh_threshold * rest.norm())
                flux = area_flux(scene, p, n, k, radius, m_settings, std::uint64_t(v) * c.leds + k)
                           .cast<float>();
            for (int a = 0; a < 3; ++a)
                m_direct[i + std::size_t(a)] = flux[a];
        }
        if (!m_radius.empty()) m_radius[std::size_t(v)] = radius ? float(*radius) : 0.0f;
    });
    build_shadow_culling(frame);
    // The quadratic terms, scaled as their edge's ends changed from rest.
    m_direct_edge.assign(c.direct_edge.size(), 0.0f);
    for (std::size_t e = 0; e < m_edges.size(); ++e)
        for (int k = 0; k < c.leds; ++k) {
            const auto norm = [&](const std::vector<float>& g, std::uint32_t v) {
                return Eigen::Vector3f(g.data() + (std::size_t(v) * c.leds + k) * 3).norm();
            };
            const auto [a, b] = m_edges[e];
            const float rest = norm(c.direct, a) + norm(c.direct, b);
            const float scale = rest > 0.0f ? (norm(m_direct, a) + norm(m_direct, b)) / rest : 0.0f;
            const std::size_t i = (e * std::size_t(c.leds) + std::size_t(k)) * 3;
            for (int x = 0; x < 3; ++x)
                m_direct_edge[i + std::size_t(x)] = scale * c.direct_edge[i + std::size_t(x)];
        }
    update_frame_share(frame);
}

namespace {

/// Each marker's bounding ball (centre, radius; its closed surface lies in its corners' convex
/// hull); none when markers lack their grouping (triangles_per_marker).
std::optional<std::vector<Eigen::Vector4d>> marker_balls(const SensorFrame& frame) {
    std::vector<Eigen::Vector4d> out;
    const int per_marker = frame.triangles_per_marker;
    for (const SurfaceMesh* mesh : {&frame.inner_markers, &frame.outer_markers}) {
        if (mesh->F.rows() == 0) continue;
        if (per_marker < 1) return std::nullopt;
        for (Eigen::Index first = 0; first < mesh->F.rows(); first += per_marker) {
            const Eigen::Index last = std::min<Eigen::Index>(first + per_marker, mesh->F.rows());
            Vec3 centre = Vec3::Zero();
            for (Eigen::Index f = first; f < last; ++f)
                for (int a = 0; a < 3; ++a)
                    centre += mesh->V.row(mesh->F(f, a)).cast<double>().transpose();
            centre /= double(3 * (last - first));
            double r2 = 0.0;
            for (Eigen::Index f = first; f < last; ++f)
                for (int a = 0; a < 3; ++a)
                    r2 = std::max(r2,
                                  (mesh->V.row(mesh->F(f, a)).cast<double>().transpose() - centre)
                                      .squaredNorm());
            out.emplace_back(centre.x(), centre.y(), centre.z(),
                             std::sqrt(r2) * (1.0 + 1e-9) + 1e-9);
        }
    }
    return out;
}

/// Where the coating folds inwards (an edge whose neighbour rises above a triangle's plane,
/// seen from the cavity), a path from the cavity can meet the coating before its end. A
/// path that does so leaves and re-enters the coating, so in the plane through the origin
/// and the path the coating's section between the two points is not convex: the path's
/// radial projection crosses such an edge. So each fold is kept as the cone of directions
/// of its edge (axis, chord to the ends), and is in the way of paths whose directions come
/// that close. Under load the contact's edges fold by up to about 0.01 mm.
std::vector<Eigen::Vector4d> fold_cones(const SensorFrame& frame,
                                        const std::vector<std::array<std::uint32_t, 2>>& edges,
                                        const std::vector<std::uint32_t>& triangle_edges,
                                        const std::vector<std::uint32_t>& triangles) {
    std::vector<Eigen::Vector4d> out;
    const auto nf = std::size_t(frame.coating.F.rows());
    const auto& V = frame.coating.V;
    const auto vertex = [&](std::uint32_t v) -> Vec3 {
        return V.row(Eigen::Index(v)).cast<double>().transpose();
    };
    std::vector<std::array<std::int64_t, 2>> sides(edges.size(), {-1, -1});
    for (std::size_t f = 0; f < nf; ++f)
        for (int a = 0; a < 3; ++a) {
            auto& side = sides[triangle_edges[3 * f + std::size_t(a)]];
            side[side[0] < 0 ? 0 : 1] = std::int64_t(f);
        }
    for (std::size_t e = 0; e < edges.size(); ++e) {
        if (sides[e][1] < 0) continue; // the rim
        bool fold = false;
        for (int s = 0; s < 2; ++s) {
            const std::uint32_t* t = triangles.data() + 3 * std::size_t(sides[e][s]);
            const std::uint32_t* o = triangles.data() + 3 * std::size_t(sides[e][1 - s]);
            Vec3 n = (vertex(t[1]) - vertex(t[0])).cross(vertex(t[2]) - vertex(t[0]));
            if (n.dot(vertex(t[0]) + vertex(t[1]) + vertex(t[2])) < 0.0) n = -n; // outwards
            // A triangle squeezed to no area has no plane to tell: counted as a fold.
            if (!(n.norm() > 0.0) || !n.allFinite()) fold = true;
            for (int a = 0; a < 3 && !fold; ++a)
                if (o[a] != edges[e][0] && o[a] != edges[e][1])
                    fold = !(n.normalized().dot(vertex(o[a]) - vertex(t[0])) <= kFoldHeight_mm);
        }
        if (fold) {
            const Vec3 a = vertex(edges[e][0]).normalized(), b = vertex(edges[e][1]).normalized();
            const Vec3 axis = (a + b).normalized();
            out.emplace_back(axis.x(), axis.y(), axis.z(), (axis - a).norm() + 1e-9);
        }
    }
    return out;
}

/// A fold cone's half-angle b (its chord w seen as 2 asin(w / 2)) plus the margin, as cos b
/// and sin b: a ball whose directions spread by a about its centre's meets the cone where
/// the angle between the axes is at most a + b, i.e. cos(apart) >= cos(a + b) =
/// cos a cos b - sin a sin b while a + b < pi; no trigonometry per triangle and LED.
struct ConeAngle {
    double angle, cos_b, sin_b;
};
std::vector<ConeAngle> cone_angles(const std::vector<Eigen::Vector4d>& cones) {
    std::vector<ConeAngle> out(cones.size());
    for (std::size_t i = 0; i < cones.size(); ++i) {
        const double b = 2.0 * std::asin(std::min(1.0, 0.5 * cones[i].w())) + 1e-6;
        out[i] = {b, std::cos(b), std::sin(b)};
    }
    return out;
}

/// The markers' balls as structure of arrays: the test of a ball against them all
/// vectorises (thousands of triangles' balls against every marker, each frame).
std::array<std::vector<double>, 4> ball_arrays(const std::vector<Eigen::Vector4d>& balls) {
    std::array<std::vector<double>, 4> out;
    for (int a = 0; a < 4; ++a) {
        out[std::size_t(a)].resize(balls.size());
        for (std::size_t m = 0; m < balls.size(); ++m)
            out[std::size_t(a)][m] = balls[m][a];
    }
    return out;
}

/// Appends to `list` the markers whose balls meet the ball (centre, r); `meets`: scratch of
/// one entry per marker.
void add_markers_meeting(const std::array<std::vector<double>, 4>& balls, const Vec3& centre,
                         double r, std::vector<std::uint32_t>& meets,
                         std::vector<std::uint32_t>& list) {
    const double *bx = balls[0].data(), *by = balls[1].data(), *bz = balls[2].data(),
                 *br = balls[3].data();
    const double cx = centre.x(), cy = centre.y(), cz = centre.z(), grow = r + 1e-9;
    const auto n = std::uint32_t(balls[0].size()); // a local bound: the loop vectorises
    std::uint32_t* out = meets.data();
    for (std::uint32_t m = 0; m < n; ++m) {
        const double reach = br[m] + grow; // round-off: never narrower
        const double dx = bx[m] - cx, dy = by[m] - cy, dz = bz[m] - cz;
        out[m] = dx * dx + dy * dy + dz * dz <= reach * reach;
    }
    for (std::uint32_t m = 0; m < n; ++m)
        if (out[m]) list.push_back(m);
}

/// Appends to `list` the folds (numbered from `first`) whose cones meet the directions of the
/// ball (centre, r): they lie within a = asin(r / |centre|) of the centre's (all directions
/// where the ball holds the origin).
void add_folds_meeting(const std::vector<Eigen::Vector4d>& cones,
                       const std::vector<ConeAngle>& angles, const Vec3& centre, double r,
                       std::uint32_t first, std::vector<std::uint32_t>& list) {
    const double distance = centre.norm();
    const bool everywhere = !(r < distance);
    const double sin_a = everywhere ? 1.0 : r / distance;
    const double cos_a = std::sqrt(std::max(0.0, 1.0 - sin_a * sin_a));
    const double a = everywhere ? std::numbers::pi : std::asin(sin_a);
    const Vec3 towards = centre / distance;
    for (std::size_t i = 0; i < cones.size(); ++i) {
        const ConeAngle& b = angles[i];
        // Round-off only widens the test (1e-12), so a fold is never left out.
        if (everywhere || a + b.angle >= std::numbers::pi ||
            cones[i].head<3>().dot(towards) >= cos_a * b.cos_b - sin_a * b.sin_b - 1e-12)
            list.push_back(first + std::uint32_t(i));
    }
}

} // namespace

std::optional<Eigen::Vector4d> FastIntegrator::culling_ball(const SensorFrame& frame,
                                                            const std::uint32_t* t,
                                                            std::size_t k) const {
    const std::size_t leds = std::size_t(m_cache->leds);
    std::array<Vec3, 15> points;
    int count = 0;
    for (int a = 0; a < 3; ++a) {
        const Vec3 p = frame.coating.V.row(Eigen::Index(t[a])).cast<double>().transpose();
        points[std::size_t(count++)] = p;
        const double radius = m_radius[t[a]];
        if (!(radius > 0.0)) return std::nullopt;
        const float* cor = m_shadow.data() + 3 * (std::size_t(t[a]) * leds + k);
        for (const double u1 : {-0.5, 0.5})
            for (const double u2 : {-0.5, 0.5}) {
                Vec3 w = guessed_direction(t[a], int(k), u1, u2);
                for (int x = 0; x < 3; ++x)
                    w[x] += cor[x];
                if (!(w.norm() > 0.0)) continue;
                if (const auto q = sphere_exit(p, w.normalized(), radius))
                    points[std::size_t(count++)] = *q;
            }
    }
    Vec3 centre = Vec3::Zero();
    for (int i = 0; i < count; ++i)
        centre += points[std::size_t(i)];
    centre /= double(count);
    double r = 0.0;
    for (int i = 0; i < count; ++i)
        r = std::max(r, (points[std::size_t(i)] - centre).norm());
    r += kCullMargin_mm;
    return Eigen::Vector4d(centre.x(), centre.y(), centre.z(), r);
}

void FastIntegrator::build_shadow_culling(const SensorFrame& frame) {
    m_cull_ball.clear();
    m_cull_first.assign(1, 0);
    m_cull_markers.clear();
    m_marker_balls.clear();
    m_fold_cones.clear();
    if (m_guess.empty()) return;
    const LightCache& c = *m_cache;
    const std::size_t leds = std::size_t(c.leds);
    const auto nf = std::size_t(frame.coating.F.rows());
    m_cull_ball.assign(nf * leds, Eigen::Vector4d(0.0, 0.0, 0.0, -1.0));
    m_cull_first.assign(nf * leds + 1, 0);
    auto balls_of_markers = marker_balls(frame);
    if (!balls_of_markers) return; // markers without their grouping: no culling
    m_marker_balls = std::move(*balls_of_markers);
    m_fold_cones = fold_cones(frame, m_edges, m_triangle_edges, c.coating_triangles);
    // Each triangle's ball per LED (culling_ball); then the markers whose balls meet it and
    // the folds whose cones meet its cone.
    const auto markers = std::uint32_t(m_marker_balls.size());
    const std::array<std::vector<double>, 4> balls = ball_arrays(m_marker_balls);
    const std::vector<ConeAngle> angles = cone_angles(m_fold_cones);
    // Per triangle, its LEDs' lists one after the other (one allocation a triangle, not one
    // per triangle and LED: tens of thousands), and each list's length.
    std::vector<std::vector<std::uint32_t>> lists(nf);
    std::vector<std::uint32_t> lengths(nf * leds, 0);
    tbb::parallel_for(std::size_t(0), nf, [&](std::size_t f) {
        const std::uint32_t* t = c.coating_triangles.data() + 3 * f;
        thread_local std::vector<std::uint32_t> meets, list;
        meets.resize(markers);
        list.clear();
        for (std::size_t k = 0; k < leds; ++k) {
            const auto ball = culling_ball(frame, t, k);
            if (!ball) continue;
            m_cull_ball[f * leds + k] = *ball;
            const std::size_t before = list.size();
            const Vec3 centre = ball->head<3>();
            add_markers_meeting(balls, centre, ball->w(), meets, list);
            add_folds_meeting(m_fold_cones, angles, centre, ball->w(), markers, list);
            lengths[f * leds + k] = std::uint32_t(list.size() - before);
        }
        lists[f].assign(list.begin(), list.end());
    });
    for (std::size_t i = 0; i < lengths.size(); ++i)
        m_cull_first[i + 1] = m_cull_first[i] + lengths[i];
    m_cull_markers.reserve(m_cull_first.back());
    for (const std::vector<std::uint32_t>& list : lists)
        m_cull_markers.insert(m_cull_markers.end(), list.begin(), list.end());
}

} // namespace chromasim::render::detail
