#include "render/fast_integrator.hpp"

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
/// frame correction's own 8e-3 rad against the refracted solve, in 1.33 evaluations a shadow
/// ray where 1e-4 (to 0.22.0) took 2.28 for at most 1.5e-7 rad (docs/VALIDATION.md,
/// sessions 27 and 31).
constexpr double kShadowStepTolerance = 1e-2;
/// Shadow-ray culling: the margin of each triangle's ball over its corners' paths (mm).
constexpr double kCullMargin_mm = 0.1;
/// An edge of the coating folds inwards where its neighbour's far corner rises more than this
/// above a triangle's plane, seen from the cavity: ten times the vertices' float round-off at
/// the dome's radius (coplanar triangles of a tessellated sphere are no fold), a hundredth of
/// the rays' kHitGap_mm.
constexpr double kFoldHeight_mm = 1e-5;
/// LightCacheSettings::frame_share: the LED points a side (their cells' centres) over which
/// the frame's share of an LED's light is taken at a coating vertex or edge midpoint.
constexpr int kFrameShareGrid = 8;
/// A shade's draws: none (ShadowDraw::rays 0), and one shadow ray from the stream (both
/// referred to, not copied, per sample).
constexpr ShadowDraw kNoShadowRays{.rays = 0};
constexpr ShadowDraw kStreamShadowRay{};
/// radiance16 sends a level's rays to Embree as one packet from this many on, else one by one.
constexpr std::size_t kMinPacket = 4;

/// Where the ray from p (outside the sphere of radius R about the origin) along the unit w
/// first meets the sphere; none if it misses it or meets it behind p.
std::optional<Vec3> sphere_exit(const Vec3& p, const Vec3& w, double R) {
    const double b = p.dot(w), c = p.squaredNorm() - R * R;
    const double disc = b * b - c;
    if (!(disc >= 0.0)) return std::nullopt;
    const double t = -b - std::sqrt(disc);
    if (!(t > 0.0)) return std::nullopt;
    return p + t * w;
}

/// Squared distance from x to the segment [a, b].
double distance2_to_segment(const Vec3& x, const Vec3& a, const Vec3& b) {
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
SensorFrame coating_and_interface(const SensorFrame& frame) {
    SensorFrame bare;
    bare.coating = frame.coating;
    bare.inner_surface = frame.inner_surface;
    return bare;
}

/// Area-weighted vertex normals of the coating, turned to face the dome centre.
std::vector<Vec3> coating_normals(const SurfaceMesh& mesh) {
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
std::vector<double> vertex_areas(const SurfaceMesh& mesh) {
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

/// The LEDs' unshadowed flux onto the coating, per unit LED emission: sum over vertices of
/// tributary area times sum_k max(0, n . V_k). `vectors`: V_k per vertex and LED,
/// [(vertex * leds + k) * 3].
double direct_flux(const SurfaceMesh& mesh, const std::vector<Vec3>& normals,
                   const std::vector<float>& vectors, int leds) {
    const std::vector<double> area = vertex_areas(mesh);
    double flux = 0.0;
    for (std::size_t v = 0; v < area.size(); ++v) {
        double g = 0.0;
        for (int k = 0; k < leds; ++k) {
            const float* V = vectors.data() + (v * std::size_t(leds) + std::size_t(k)) * 3;
            g += std::max(0.0,
                          normals[v].x() * V[0] + normals[v].y() * V[1] + normals[v].z() * V[2]);
        }
        flux += area[v] * g;
    }
    return flux;
}

/// The coating's edges, each once, in the order the triangles first name them, and each
/// triangle's three (edge i from corner i to corner i + 1 mod 3).
void coating_edges(const std::vector<std::uint32_t>& triangles,
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

FastIntegrator::FastIntegrator(const ShadingModel& shading, const PathIntegrator& path)
    : m_shading(shading), m_path(path) {
    if (path.led_count() > kMaxLeds) {
        throw std::invalid_argument("FastIntegrator: " + std::to_string(path.led_count()) +
                                    " LEDs; allowed: at most " + std::to_string(kMaxLeds));
    }
}

void FastIntegrator::build_cache(const SensorFrame& rest,
                                 const render::LightCacheSettings& settings,
                                 const SensorSpectra* spectra, double led_scale) {
    if (settings.paths_per_vertex < 1 || settings.direct_samples < 1) {
        throw std::invalid_argument(
            "LightCacheSettings: paths_per_vertex = " + std::to_string(settings.paths_per_vertex) +
            ", direct_samples = " + std::to_string(settings.direct_samples) +
            "; allowed: integers >= 1");
    }
    const auto start = std::chrono::steady_clock::now();
    EmbreeScene full;
    full.set_frame(rest);
    EmbreeScene bare;
    bare.set_frame(coating_and_interface(rest));

    auto cache = std::make_shared<LightCache>();
    const int nv = int(rest.coating.V.rows());
    const int leds = m_path.led_count();
    cache->vertices = nv;
    cache->leds = leds;
    cache->lanes = spectra ? kCacheLambdas : kRgbLanes;
    cache->direct.assign(std::size_t(nv) * leds * 3, 0.0f);
    cache->indirect.assign(std::size_t(nv) * cache->lanes, 0.0f);
    cache->coating_triangles.assign(rest.coating.F.data(),
                                    rest.coating.F.data() + rest.coating.F.size());
    const std::vector<Vec3> normals = coating_normals(rest.coating);

    // Lanes per unit LED emission: the indirect term scales with each sample's LED lanes.
    // The cache's fixed wavelengths are its own lanes, whatever a sample's hero lanes are.
    using CacheLanes = LanesN<kCacheLambdas>;
    LaneOptics<kCacheLambdas> spectral_optics{};
    LaneOptics<kRgbLanes> rgb_optics = m_shading.rgb_lanes();
    rgb_optics.led = RgbLanes::Ones();
    if (spectra) {
        CacheLanes lambda;
        for (int j = 0; j < kCacheLambdas; ++j)
            lambda[j] = kCacheLambdaMin_nm + kCacheLambdaStep_nm * j;
        spectral_optics = spectral_lanes<kCacheLambdas>(*spectra, lambda, led_scale);
        spectral_optics.led = CacheLanes::Ones();
    }
    // The outer markers' inner face above each vertex they cover (its distance along the
    // normal, 0 where none covers it).
    std::vector<double> above_mm(std::size_t(nv), 0.0);
    tbb::parallel_for(0, nv, [&](int v) {
        const Vec3 n = normals[std::size_t(v)];
        const Vec3 p = rest.coating.V.row(v).cast<double>().transpose() + kHitGap_mm * n;
        for (double t = 0.0; t < 2.0;) {
            const RayHit hit = full.closest_hit(p, n, t, 2.0);
            if (!hit.hit() || hit.kind != SurfaceKind::outer_marker) break;
            t = hit.t_mm + kHitGap_mm;
            if (hit.normal.dot(n) > 0.0) { // leaving the marker: its inner face
                above_mm[std::size_t(v)] = hit.t_mm + kHitGap_mm;
                break;
            }
        }
    });
    std::vector<PointLedPaths> rest_paths = point_paths(rest, bare, &cache->point_rest);
    // Vertices no marker covers: the median height of the covered ones.
    std::vector<double> heights;
    for (double h : above_mm)
        if (h > 0.0) heights.push_back(h);
    std::sort(heights.begin(), heights.end());
    const double typical_above_mm = heights.empty() ? 0.0 : heights[heights.size() / 2];
    const int lanes = cache->lanes;
    cache->indirect_above.assign(cache->indirect.size(), 0.0f);
    tbb::parallel_for(0, nv, [&](int v) {
        PixelRng rng(0x11C4CE, std::uint64_t(v));
        const Vec3 n = normals[std::size_t(v)];
        // A hair off the coating, on the cavity side (below an outer marker's face).
        const Vec3 p = rest.coating.V.row(v).cast<double>().transpose() + kHitGap_mm * n;
        const auto radius = m_path.radius_below(bare, p);
        for (int k = 0; k < leds; ++k) {
            // A stream per vertex and LED, which set_frame's refresh repeats on a frame.
            const Vec3 flux =
                area_flux(bare, p, n, k, radius, settings, std::uint64_t(v) * leds + k);
            for (int a = 0; a < 3; ++a)
                cache->direct[(std::size_t(v) * leds + k) * 3 + a] = float(flux[a]);
        }
        // The indirect light at the coating and above the outer marker layer; a covered
        // vertex's coating value is its unfiltered one (inside() filters per sample).
        // LED light reached through the inner surface is shared with the LED points by MIS
        // (the fixed ratio kCacheBsdfPerNee).
        auto mean_indirect = [&](const Vec3& at, float* out) {
            if (spectra) {
                CacheLanes sum = CacheLanes::Zero();
                for (int i = 0; i < settings.paths_per_vertex; ++i)
                    sum +=
                        m_path.indirect(full, at, n, spectral_optics, rng, 1.0 / kCacheBsdfPerNee);
                for (int j = 0; j < kCacheLambdas; ++j)
                    out[j] = float(sum[j] / settings.paths_per_vertex);
            } else {
                RgbLanes sum = RgbLanes::Zero();
                for (int i = 0; i < settings.paths_per_vertex; ++i)
                    sum += m_path.indirect(full, at, n, rgb_optics, rng, 1.0 / kCacheBsdfPerNee);
                for (int j = 0; j < kRgbLanes; ++j)
                    out[j] = float(sum[j] / settings.paths_per_vertex);
            }
        };
        float* coating = cache->indirect.data() + std::size_t(v) * lanes;
        float* above = cache->indirect_above.data() + std::size_t(v) * lanes;
        const double h = above_mm[std::size_t(v)];
        mean_indirect(p + (h > 0.0 ? h : typical_above_mm) * n, above);
        if (h > 0.0 || typical_above_mm == 0.0)
            std::copy(above, above + lanes, coating);
        else
            mean_indirect(p, coating);
    });
    // The direct light's quadratic term along each edge: at the midpoint, less the mean of the
    // ends (the LEDs near the rim make G_k curve within a triangle: linear interpolation
    // left the rim about 2 % dark at rest; docs/VALIDATION.md).
    std::vector<std::array<std::uint32_t, 2>> edges;
    std::vector<std::uint32_t> triangle_edges;
    coating_edges(cache->coating_triangles, edges, triangle_edges);
    cache->direct_edge.assign(edges.size() * std::size_t(leds) * 3, 0.0f);
    tbb::parallel_for(0, int(edges.size()), [&](int e) {
        const auto [a, b] = edges[std::size_t(e)];
        const Vec3 n = (normals[a] + normals[b]).normalized();
        const Vec3 mid =
            0.5 * (rest.coating.V.row(a) + rest.coating.V.row(b)).transpose().cast<double>();
        const Vec3 p = mid + kHitGap_mm * n;
        const auto radius = m_path.radius_below(bare, p);
        for (int k = 0; k < leds; ++k) {
            const Vec3 flux = area_flux(bare, p, n, k, radius, settings,
                                        (std::uint64_t(nv) + std::uint64_t(e)) * leds + k);
            const float* ga = cache->direct.data() + (std::size_t(a) * leds + k) * 3;
            const float* gb = cache->direct.data() + (std::size_t(b) * leds + k) * 3;
            float* out = cache->direct_edge.data() + (std::size_t(e) * leds + k) * 3;
            for (int i = 0; i < 3; ++i)
                out[i] = float(flux[i] - 0.5 * (double(ga[i]) + double(gb[i])));
        }
    });
    // Smoothing: the indirect light is smooth over millimetres, the estimate of each vertex
    // heavy-tailed (rare long paths that reach an LED). A Gaussian of settings.smoothing_mm
    // (3D distance at rest, cut at 3 sigma), weighted by the vertices' tributary areas,
    // preserves the field's integral and takes the per-vertex noise down.
    if (settings.smoothing_mm > 0.0) {
        const std::vector<double> area = vertex_areas(rest.coating);
        const double sigma = settings.smoothing_mm, cutoff2 = 9.0 * sigma * sigma;
        for (std::vector<float>* field : {&cache->indirect, &cache->indirect_above}) {
            std::vector<float> smooth(field->size(), 0.0f);
            tbb::parallel_for(0, nv, [&](int v) {
                const Vec3 pv = rest.coating.V.row(v).cast<double>().transpose();
                // Local linear regression (a + b . (x - x_v), weighted): unbiased for a
                // field that varies linearly, such as the fall-off towards the rim.
                Eigen::Matrix4d M = Eigen::Matrix4d::Zero();
                Eigen::Matrix<double, 4, kCacheLambdas> rhs =
                    Eigen::Matrix<double, 4, kCacheLambdas>::Zero();
                double weight = 0.0;
                for (int w = 0; w < nv; ++w) {
                    // Covered and uncovered vertices hold different coating values.
                    if (field == &cache->indirect &&
                        (above_mm[std::size_t(w)] > 0.0) != (above_mm[std::size_t(v)] > 0.0))
                        continue;
                    const Vec3 dx = rest.coating.V.row(w).cast<double>().transpose() - pv;
                    const double d2 = dx.squaredNorm();
                    if (d2 > cutoff2) continue;
                    const double k = area[std::size_t(w)] * std::exp(-0.5 * d2 / (sigma * sigma));
                    const Eigen::Vector4d basis(1.0, dx.x(), dx.y(), dx.z());
                    M += k * basis * basis.transpose();
                    weight += k;
                    for (int j = 0; j < lanes; ++j)
                        rhs.col(j) += (k * (*field)[std::size_t(w) * lanes + j]) * basis;
                }
                // A little ridge on the slope: the points lie near a surface, so the slope
                // along its normal is undetermined.
                const double ridge = 1e-2 * weight * sigma * sigma;
                for (int a = 1; a < 4; ++a)
                    M(a, a) += ridge;
                const Eigen::Matrix<double, 4, kCacheLambdas> coef = M.ldlt().solve(rhs);
                for (int j = 0; j < lanes; ++j)
                    smooth[std::size_t(v) * lanes + j] = float(std::max(0.0, coef(0, j)));
            });
            field->swap(smooth);
        }
    }
    // A covered vertex's coating value: its light above the marker times the ratio coating /
    // above of its uncovered neighbours (the grazing light their neighbouring markers filter),
    // so that uncovered coating interpolates uncovered values (a covered hit uses its own
    // marker's filter on indirect_above instead).
    std::vector<std::vector<int>> ring{std::size_t(nv)};
    for (Eigen::Index f = 0; f < rest.coating.F.rows(); ++f)
        for (int a = 0; a < 3; ++a) {
            const int i = int(rest.coating.F(f, a)), j = int(rest.coating.F(f, (a + 1) % 3));
            ring[std::size_t(i)].push_back(j);
            ring[std::size_t(j)].push_back(i);
        }
    for (int v = 0; v < nv; ++v) {
        if (!(above_mm[std::size_t(v)] > 0.0)) continue;
        for (int j = 0; j < lanes; ++j) {
            double ratio = 0.0;
            int count = 0;
            for (int w : ring[std::size_t(v)]) {
                const float up = cache->indirect_above[std::size_t(w) * lanes + j];
                if (above_mm[std::size_t(w)] > 0.0 || !(up > 0.0f)) continue;
                ratio += cache->indirect[std::size_t(w) * lanes + j] / up;
                ++count;
            }
            cache->indirect[std::size_t(v) * lanes + j] =
                cache->indirect_above[std::size_t(v) * lanes + j] *
                float(count > 0 ? ratio / count : 1.0);
        }
    }
    cache->direct_flux = direct_flux(rest.coating, normals, cache->direct, leds);
    cache->build_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    m_cache = std::move(cache);
    m_settings = settings;
    m_edges = std::move(edges);
    m_triangle_edges = std::move(triangle_edges);
    m_rest_paths = std::move(rest_paths);
    tabulate_frame_share(rest, bare);
    m_direct.clear(); // set_frame brings the frame's data up to date
}

std::vector<PointLedPaths> FastIntegrator::point_paths(const SensorFrame& rest,
                                                       const EmbreeScene& bare,
                                                       std::vector<float>* point_rest) const {
    const int nv = int(rest.coating.V.rows()), leds = m_path.led_count();
    std::vector<PointLedPaths> paths(std::size_t(nv) * std::size_t(leds));
    if (point_rest) point_rest->assign(paths.size() * 3, 0.0f);
    const std::vector<Vec3> normals = coating_normals(rest.coating);
    tbb::parallel_for(0, nv, [&](int v) {
        const Vec3 n = normals[std::size_t(v)];
        const Vec3 p = rest.coating.V.row(v).cast<double>().transpose() + kHitGap_mm * n;
        const auto radius = m_path.radius_below(bare, p);
        for (int k = 0; k < leds; ++k) {
            const std::size_t i = std::size_t(v) * std::size_t(leds) + std::size_t(k);
            const Vec3 flux =
                m_path.led_flux_point(bare, p, n, k, radius, nullptr, nullptr, &paths[i]);
            if (point_rest)
                for (int a = 0; a < 3; ++a)
                    (*point_rest)[i * 3 + std::size_t(a)] = float(flux[a]);
        }
    });
    return paths;
}

void FastIntegrator::adopt_cache(LightCache cache, const render::LightCacheSettings& settings,
                                 const SensorFrame& rest) {
    const int lanes = m_shading.optics().spectra ? kCacheLambdas : kRgbLanes;
    const auto nv = std::size_t(std::max(cache.vertices, 0));
    const bool sized =
        cache.vertices >= 0 && cache.direct.size() == nv * std::size_t(m_path.led_count()) * 3 &&
        cache.point_rest.size() == cache.direct.size() &&
        cache.indirect.size() == nv * std::size_t(lanes) &&
        cache.indirect_above.size() == cache.indirect.size() && std::isfinite(cache.direct_flux) &&
        cache.direct_flux >= 0.0 && cache.coating_triangles.size() % 3 == 0;
    std::vector<std::array<std::uint32_t, 2>> edges;
    std::vector<std::uint32_t> triangle_edges;
    if (sized) coating_edges(cache.coating_triangles, edges, triangle_edges);
    const bool edges_sized =
        cache.direct_edge.size() == edges.size() * std::size_t(m_path.led_count()) * 3;
    if (cache.leds != m_path.led_count() || cache.lanes != lanes || !sized || !edges_sized)
        throw std::invalid_argument(
            "FastIntegrator::adopt_cache: a cache for " + std::to_string(cache.leds) +
            " LEDs and " + std::to_string(cache.lanes) +
            " lanes, or with arrays of other sizes or a negative or non-finite rest flux; "
            "allowed: one built for this sensor's " +
            std::to_string(m_path.led_count()) + " LEDs and " + std::to_string(lanes) + " lanes (" +
            (m_shading.optics().spectra ? "spectral" : "RGB") + " mode)");
    auto adopted = std::make_shared<const LightCache>(std::move(cache));
    std::swap(m_cache, adopted);
    std::vector<PointLedPaths> rest_paths;
    EmbreeScene bare;
    try {
        check_topology(rest);
        // The point LEDs' connections at rest, where each frame's solves start (as
        // build_cache finds them: on the coating and inner surface alone).
        bare.set_frame(coating_and_interface(rest));
        rest_paths = point_paths(rest, bare, nullptr);
    } catch (...) {
        std::swap(m_cache, adopted); // the cache in use before, if any, stays
        throw;
    }
    m_rest_paths = std::move(rest_paths);
    m_settings = settings;
    m_edges = std::move(edges);
    m_triangle_edges = std::move(triangle_edges);
    tabulate_frame_share(rest, bare);
    m_direct.clear(); // set_frame brings the frame's data up to date
}

void FastIntegrator::tabulate_frame_share(const SensorFrame& rest, const EmbreeScene& bare) {
    m_frame_vertex.clear();
    m_frame_edge.clear();
    m_frame_triangle.clear();
    m_frame_vertex_pairs.clear();
    m_frame_edge_pairs.clear();
    if (!m_settings.frame_share || !bare.has_interface()) return;
    const std::size_t nv = std::size_t(rest.coating.V.rows()), leds = std::size_t(m_cache->leds);
    const std::vector<Vec3> normals = coating_normals(rest.coating);
    // At rest the frame's correction to the sphere model is the tessellation's: the shares
    // as a frame without guesses or corrections would take them, over the whole bracket.
    std::vector<float> radius(nv, 0.0f);
    tbb::parallel_for(std::size_t(0), nv, [&](std::size_t v) {
        const Vec3 p = rest.coating.V.row(Eigen::Index(v)).cast<double>().transpose() +
                       kHitGap_mm * normals[v];
        if (const auto R = m_path.radius_below(bare, p)) radius[v] = float(*R);
    });
    std::vector<float> at_vertex(nv * leds, 0.0f), at_edge(m_edges.size() * leds, 0.0f);
    const auto vertex = [&](std::uint32_t v) -> Vec3 {
        return rest.coating.V.row(Eigen::Index(v)).cast<double>().transpose();
    };
    // Between vertices a and b (a == b: at the vertex), over the whole bracket.
    const auto at_rest = [&](std::uint32_t a, std::uint32_t b, int k) {
        const Vec3 p = 0.5 * (vertex(a) + vertex(b));
        const double R = 0.5 * (double(radius[a]) + double(radius[b]));
        return frame_share(p, R, [&](double u1, double u2) {
            return sphere_exit(p, m_path.refracted_direction(p, m_path.led_point(k, u1, u2), R),
                               R);
        });
    };
    tbb::parallel_for(std::size_t(0), nv, [&](std::size_t v) {
        for (std::size_t k = 0; k < leds; ++k)
            at_vertex[v * leds + k] = at_rest(std::uint32_t(v), std::uint32_t(v), int(k));
    });
    tbb::parallel_for(std::size_t(0), m_edges.size(), [&](std::size_t e) {
        const auto [a, b] = m_edges[e];
        for (std::size_t k = 0; k < leds; ++k)
            at_edge[e * leds + k] = at_rest(a, b, int(k));
    });
    // The (triangle, LED) pairs with a share at a corner or edge midpoint at rest, and their
    // corners' and edges' pairs, which each frame takes anew.
    const std::size_t nf = m_cache->coating_triangles.size() / 3;
    std::vector<std::uint8_t> flagged(nf * leds, 0), corner(nv * leds, 0),
        side(m_edges.size() * leds, 0);
    bool any = false;
    for (std::size_t f = 0; f < nf; ++f)
        for (std::size_t k = 0; k < leds; ++k) {
            bool has = false;
            for (std::size_t i = 0; i < 3; ++i)
                has = has || at_vertex[m_cache->coating_triangles[3 * f + i] * leds + k] > 0.0f ||
                      at_edge[m_triangle_edges[3 * f + i] * leds + k] > 0.0f;
            if (!has) continue;
            flagged[f * leds + k] = 1;
            any = true;
            for (std::size_t i = 0; i < 3; ++i) {
                corner[m_cache->coating_triangles[3 * f + i] * leds + k] = 1;
                side[m_triangle_edges[3 * f + i] * leds + k] = 1;
            }
        }
    if (!any) return;
    for (std::size_t i = 0; i < corner.size(); ++i)
        if (corner[i]) m_frame_vertex_pairs.push_back(std::uint32_t(i));
    for (std::size_t i = 0; i < side.size(); ++i)
        if (side[i]) m_frame_edge_pairs.push_back(std::uint32_t(i));
    m_frame_vertex.assign(at_vertex.size(), 0.0f);
    m_frame_edge.assign(at_edge.size(), 0.0f);
    m_frame_triangle = std::move(flagged);
}

template <class Exit>
float FastIntegrator::frame_share(const Vec3& p, double radius_mm, Exit&& exit_towards) const {
    if (!(radius_mm > 0.0)) return 0.0f;
    // The path runs from where the model leaves the layers, at most the tangent's length from
    // p, to p: from a point higher than that above the plane it cannot cross it.
    const double R2 = radius_mm * radius_mm;
    if (!(p.squaredNorm() > R2) || p.z() > std::sqrt(p.squaredNorm() - R2)) return 0.0f;
    int blocked = 0;
    for (int i = 0; i < kFrameShareGrid; ++i)
        for (int j = 0; j < kFrameShareGrid; ++j) {
            const std::optional<Vec3> exit =
                exit_towards((i + 0.5) / kFrameShareGrid, (j + 0.5) / kFrameShareGrid);
            if (!exit) continue;
            const Vec3 segment = p - *exit;
            const double length = segment.norm();
            blocked += m_shading.crosses_mount(*exit, segment / length, kHitGap_mm,
                                               length - kHitGap_mm);
        }
    return float(blocked) / float(kFrameShareGrid * kFrameShareGrid);
}

void FastIntegrator::update_frame_share(const SensorFrame& frame) {
    if (m_frame_triangle.empty() || m_radius.empty()) return;
    const std::size_t leds = std::size_t(m_cache->leds);
    const auto vertex = [&](std::uint32_t v) -> Vec3 {
        return frame.coating.V.row(Eigen::Index(v)).cast<double>().transpose();
    };
    // Between vertices a and b (a == b: at the vertex), as a sample there takes its shadow
    // rays (shadow_exit: the frame's radius, guess and correction, interpolated).
    const auto now = [&](std::uint32_t a, std::uint32_t b, int k) {
        const std::array<std::uint32_t, 3> corners{a, b, a};
        Lookup<kRgbLanes> at;
        at.triangle = corners.data();
        at.weights[0] = at.weights[1] = 0.5;
        at.radius_mm = 0.5 * (double(m_radius[a]) + double(m_radius[b]));
        const Vec3 p = 0.5 * (vertex(a) + vertex(b));
        return frame_share(p, at.radius_mm, [&](double u1, double u2) {
            return shadow_exit(at, p, k, u1, u2);
        });
    };
    tbb::parallel_for(std::size_t(0), m_frame_vertex_pairs.size(), [&](std::size_t i) {
        const std::uint32_t pair = m_frame_vertex_pairs[i];
        const auto v = std::uint32_t(pair / leds);
        m_frame_vertex[pair] = now(v, v, int(pair % leds));
    });
    tbb::parallel_for(std::size_t(0), m_frame_edge_pairs.size(), [&](std::size_t i) {
        const std::uint32_t pair = m_frame_edge_pairs[i];
        const std::size_t e = pair / leds, k = pair % leds;
        const auto [a, b] = m_edges[e];
        m_frame_edge[pair] = now(a, b, int(k)) - 0.5f * (m_frame_vertex[a * leds + k] +
                                                        m_frame_vertex[b * leds + k]);
    });
}

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

Vec3 FastIntegrator::area_flux(const EmbreeScene& scene, const Vec3& p, const Vec3& n, int k,
                               std::optional<double> radius_mm,
                               const render::LightCacheSettings& settings,
                               std::uint64_t stream) const {
    if (scene.has_interface() && !radius_mm) return Vec3::Zero();
    // The cache's own estimate (build_cache): jittered strata of the LED, the chains' MIS
    // weights against the indirect paths' share, here on the frame's inner surface.
    const auto [gx, gy] = strata_grid(settings.direct_samples);
    PixelRng rng(0xD1EC7, stream);
    Vec3 flux = Vec3::Zero();
    for (int sy = 0; sy < gy; ++sy)
        for (int sx = 0; sx < gx; ++sx) {
            const double u1 = (sx + rng.uniform()) / gx, u2 = (sy + rng.uniform()) / gy;
            flux += m_path.led_flux_sample(scene, p, n, k, u1, u2, rng.uniform(), kCacheBsdfPerNee,
                                           radius_mm);
        }
    return flux / double(settings.direct_samples);
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
                // from the sphere through the point below (0.1 rad RMS at 5 N, against
                // 0.009 rad after this correction; docs/VALIDATION.md).
                float* out = m_shadow.data() + 3 * (std::size_t(v) * c.leds + k);
                for (int a = 0; a < 3; ++a)
                    out[a] = float(refracted.direction[a] - model[a]);
            }
            if (!m_guess.empty() && radius) {
                // The culling's guess: the centre's direction and its change across the LED
                // (central differences over the middle half of each side), each by Newton
                // from the centre's (the whole bracket where that fails), as the samples'
                // shadow rays solve (1e-9 in the sines, then steps below 1e-4 rad).
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
            // Chains, the point's is not), and taking the point's direction with the area's
            // length left G_k 1 % low at the apex and 3 to 5 % low near the LEDs at rest.
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
    // The indirect light follows the LEDs' light the coating receives: this frame's
    // unshadowed flux onto the coating over the rest cache's (docs/VALIDATION.md).
    m_indirect_scale = 1.0;
    if (m_settings.scale_indirect && c.direct_flux > 0.0) {
        const double now = direct_flux(frame.coating, normals, m_direct, c.leds);
        if (std::isfinite(now)) m_indirect_scale = now / c.direct_flux;
    }
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
    // Each marker's bounding ball (its closed surface lies in its corners' convex hull).
    const int per_marker = frame.triangles_per_marker;
    for (const SurfaceMesh* mesh : {&frame.inner_markers, &frame.outer_markers}) {
        if (mesh->F.rows() == 0) continue;
        if (per_marker < 1) return; // markers without their grouping: no culling
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
            m_marker_balls.emplace_back(centre.x(), centre.y(), centre.z(),
                                        std::sqrt(r2) * (1.0 + 1e-9) + 1e-9);
        }
    }
    // Where the coating folds inwards (an edge whose neighbour rises above a triangle's plane,
    // seen from the cavity), a path from the cavity can meet the coating before its end. A
    // path that does so leaves and re-enters the coating, so in the plane through the origin
    // and the path the coating's section between the two points is not convex: the path's
    // radial projection crosses such an edge. So each fold is kept as the cone of directions
    // of its edge (axis, chord to the ends), and is in the way of paths whose directions come
    // that close. Under load the contact's edges fold by up to about 0.01 mm.
    const auto& V = frame.coating.V;
    const auto vertex = [&](std::uint32_t v) -> Vec3 {
        return V.row(Eigen::Index(v)).cast<double>().transpose();
    };
    std::vector<std::array<std::int64_t, 2>> sides(m_edges.size(), {-1, -1});
    for (std::size_t f = 0; f < nf; ++f)
        for (int a = 0; a < 3; ++a) {
            auto& side = sides[m_triangle_edges[3 * f + std::size_t(a)]];
            side[side[0] < 0 ? 0 : 1] = std::int64_t(f);
        }
    for (std::size_t e = 0; e < m_edges.size(); ++e) {
        if (sides[e][1] < 0) continue; // the rim
        bool fold = false;
        for (int s = 0; s < 2; ++s) {
            const std::uint32_t* t = c.coating_triangles.data() + 3 * std::size_t(sides[e][s]);
            const std::uint32_t* o = c.coating_triangles.data() + 3 * std::size_t(sides[e][1 - s]);
            Vec3 n = (vertex(t[1]) - vertex(t[0])).cross(vertex(t[2]) - vertex(t[0]));
            if (n.dot(vertex(t[0]) + vertex(t[1]) + vertex(t[2])) < 0.0) n = -n; // outwards
            // A triangle squeezed to no area has no plane to tell: counted as a fold.
            if (!(n.norm() > 0.0) || !n.allFinite()) fold = true;
            for (int a = 0; a < 3 && !fold; ++a)
                if (o[a] != m_edges[e][0] && o[a] != m_edges[e][1])
                    fold = !(n.normalized().dot(vertex(o[a]) - vertex(t[0])) <= kFoldHeight_mm);
        }
        if (fold) {
            const Vec3 a = vertex(m_edges[e][0]).normalized(),
                       b = vertex(m_edges[e][1]).normalized();
            const Vec3 axis = (a + b).normalized();
            m_fold_cones.emplace_back(axis.x(), axis.y(), axis.z(), (axis - a).norm() + 1e-9);
        }
    }
    // Each triangle's ball per LED: its corners, and where the guessed paths from its
    // corners to the LED's corners leave the sphere, plus a margin; then the markers whose
    // balls meet it and the folds whose cones meet its cone.
    const auto markers = std::uint32_t(m_marker_balls.size());
    // The markers' balls as structure of arrays: the test of a ball against them all
    // vectorises (9246 balls against 164 markers at 1.5 N + 0.6 N took about 1.3 ms of the
    // frame update one by one).
    std::array<std::vector<double>, 4> balls;
    for (int a = 0; a < 4; ++a) {
        balls[std::size_t(a)].resize(markers);
        for (std::uint32_t m = 0; m < markers; ++m)
            balls[std::size_t(a)][m] = m_marker_balls[m][a];
    }
    // Each fold cone's half-angle b (its chord w seen as 2 asin(w / 2)) plus the margin, as
    // cos b and sin b: a ball whose directions spread by a about its centre's meets the cone
    // where the angle between the axes is at most a + b, i.e. cos(apart) >= cos(a + b) =
    // cos a cos b - sin a sin b while a + b < pi; no trigonometry per triangle and LED.
    struct ConeAngle {
        double angle, cos_b, sin_b;
    };
    std::vector<ConeAngle> cone_angles(m_fold_cones.size());
    for (std::size_t i = 0; i < m_fold_cones.size(); ++i) {
        const double b = 2.0 * std::asin(std::min(1.0, 0.5 * m_fold_cones[i].w())) + 1e-6;
        cone_angles[i] = {b, std::cos(b), std::sin(b)};
    }
    // Per triangle, its LEDs' lists one after the other (one allocation a triangle, where a
    // vector per triangle and LED took tens of thousands), and each list's length.
    std::vector<std::vector<std::uint32_t>> lists(nf);
    std::vector<std::uint32_t> lengths(nf * leds, 0);
    tbb::parallel_for(std::size_t(0), nf, [&](std::size_t f) {
        const std::uint32_t* t = c.coating_triangles.data() + 3 * f;
        thread_local std::vector<std::uint32_t> meets, list;
        meets.resize(markers);
        list.clear();
        for (std::size_t k = 0; k < leds; ++k) {
            std::array<Vec3, 15> points;
            int count = 0;
            bool lit = true;
            for (int a = 0; a < 3; ++a) {
                const Vec3 p = vertex(t[a]);
                points[std::size_t(count++)] = p;
                const double radius = m_radius[t[a]];
                lit = lit && radius > 0.0;
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
            if (!lit) continue;
            Vec3 centre = Vec3::Zero();
            for (int i = 0; i < count; ++i)
                centre += points[std::size_t(i)];
            centre /= double(count);
            double r = 0.0;
            for (int i = 0; i < count; ++i)
                r = std::max(r, (points[std::size_t(i)] - centre).norm());
            r += kCullMargin_mm;
            m_cull_ball[f * leds + k] = Eigen::Vector4d(centre.x(), centre.y(), centre.z(), r);
            const std::size_t before = list.size();
            {
                const double *bx = balls[0].data(), *by = balls[1].data(),
                             *bz = balls[2].data(), *br = balls[3].data();
                const double cx = centre.x(), cy = centre.y(), cz = centre.z(), grow = r + 1e-9;
                const std::uint32_t n = markers; // a local bound: the loop vectorises
                std::uint32_t* out = meets.data();
                for (std::uint32_t m = 0; m < n; ++m) {
                    const double reach = br[m] + grow; // round-off: never narrower
                    const double dx = bx[m] - cx, dy = by[m] - cy, dz = bz[m] - cz;
                    out[m] = dx * dx + dy * dy + dz * dz <= reach * reach;
                }
                for (std::uint32_t m = 0; m < n; ++m)
                    if (out[m]) list.push_back(m);
            }
            // The ball's directions lie within a = asin(r / |centre|) of the centre's (all
            // directions where the ball holds the origin).
            const double distance = centre.norm();
            const bool everywhere = !(r < distance);
            const double sin_a = everywhere ? 1.0 : r / distance;
            const double cos_a = std::sqrt(std::max(0.0, 1.0 - sin_a * sin_a));
            const double a = everywhere ? std::numbers::pi : std::asin(sin_a);
            const Vec3 towards = centre / distance;
            for (std::size_t i = 0; i < m_fold_cones.size(); ++i) {
                const ConeAngle& b = cone_angles[i];
                // Round-off only widens the test (1e-12), so a fold is never left out.
                if (everywhere || a + b.angle >= std::numbers::pi ||
                    m_fold_cones[i].head<3>().dot(towards) >=
                        cos_a * b.cos_b - sin_a * b.sin_b - 1e-12)
                    list.push_back(markers + std::uint32_t(i));
            }
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

template <int N>
FastIntegrator::Lookup<N> FastIntegrator::lookup(std::uint32_t prim, double u, double v,
                                                 const Vec3& normal) const {
    const LightCache& c = *m_cache;
    const std::uint32_t* f = c.coating_triangles.data() + 3 * std::size_t(prim);
    const double w[3] = {1.0 - u - v, u, v};
    Lookup<N> at;
    // Quadratic Lagrange interpolation: the corners' values linearly, plus each edge's
    // midpoint term times its bubble 4 w_i w_(i+1).
    const std::uint32_t* edges = m_triangle_edges.data() + 3 * std::size_t(prim);
    const double bubble[3] = {4.0 * w[0] * w[1], 4.0 * w[1] * w[2], 4.0 * w[2] * w[0]};
    for (int k = 0; k < c.leds; ++k) {
        double g = 0.0; // the vector irradiance interpolated, on the triangle's normal
        for (int i = 0; i < 3; ++i) {
            const float* flux = m_direct.data() + (std::size_t(f[i]) * c.leds + k) * 3;
            const float* edge = m_direct_edge.data() + (std::size_t(edges[i]) * c.leds + k) * 3;
            g += w[i] * (normal.x() * flux[0] + normal.y() * flux[1] + normal.z() * flux[2]) +
                 bubble[i] * (normal.x() * edge[0] + normal.y() * edge[1] + normal.z() * edge[2]);
        }
        at.direct[std::size_t(k)] = std::max(0.0, g);
    }
    if (!m_frame_triangle.empty()) {
        // The frame's share of each LED's light, interpolated as G_k is, taken off where it
        // is tabulated for this triangle.
        const std::uint8_t* flagged = m_frame_triangle.data() + std::size_t(prim) * c.leds;
        for (int k = 0; k < c.leds; ++k) {
            if (!flagged[k]) continue;
            at.frame_share |= std::uint64_t(1) << k;
            double share = 0.0;
            for (int i = 0; i < 3; ++i)
                share += w[i] * m_frame_vertex[std::size_t(f[i]) * c.leds + k] +
                         bubble[i] * m_frame_edge[std::size_t(edges[i]) * c.leds + k];
            at.direct[std::size_t(k)] *= std::clamp(1.0 - share, 0.0, 1.0);
        }
    }
    if (!m_radius.empty())
        for (int i = 0; i < 3; ++i)
            at.radius_mm += w[i] * m_radius[f[i]];
    at.triangle = f;
    at.prim = prim;
    for (int i = 0; i < 3; ++i)
        at.weights[i] = w[i];
    return at;
}

template <int N>
Vec3 FastIntegrator::shadow_direction(const Lookup<N>& at, const Vec3& p, int k,
                                      const Vec3& led_point) const {
    return (m_path.refracted_direction(p, led_point, at.radius_mm) + shadow_correction(at, k))
        .normalized();
}

Vec3 FastIntegrator::guessed_direction(std::uint32_t vertex, int k, double d1, double d2) const {
    const float* g = m_guess.data() + 9 * (std::size_t(vertex) * m_cache->leds + std::size_t(k));
    Vec3 w;
    for (int a = 0; a < 3; ++a)
        w[a] = g[a] + d1 * g[3 + a] + d2 * g[6 + a];
    return w;
}

template <int N> Vec3 FastIntegrator::shadow_correction(const Lookup<N>& at, int k) const {
    Vec3 c = Vec3::Zero();
    for (int i = 0; i < 3; ++i) {
        const float* at_vertex =
            m_shadow.data() + 3 * (std::size_t(at.triangle[i]) * m_cache->leds + k);
        for (int a = 0; a < 3; ++a)
            c[a] += at.weights[i] * at_vertex[a];
    }
    return c;
}

double FastIntegrator::direct_at(std::uint32_t prim, double u, double v, const Vec3& normal,
                                 int k) const {
    return lookup<kRgbLanes>(prim, u, v, normal).direct[std::size_t(k)];
}

Vec3 FastIntegrator::shadow_direction(std::uint32_t prim, double u, double v, const Vec3& p, int k,
                                      const Vec3& led_point) const {
    return shadow_direction(lookup<kRgbLanes>(prim, u, v, Vec3::UnitZ()), p, k, led_point);
}

template <int N>
LanesN<N> FastIntegrator::spectral_at(const std::vector<float>& values, const std::uint32_t* f,
                                      const double* w, const CacheLambdas<N>* lambdas) const {
    // The cached lanes at the hit, then at the sample's wavelengths.
    const int lanes = m_cache->lanes;
    std::array<double, kCacheLambdas> cached{};
    for (int j = 0; j < lanes; ++j) {
        double value = 0.0;
        for (int i = 0; i < 3; ++i)
            value += w[i] * values[std::size_t(f[i]) * lanes + j];
        cached[std::size_t(j)] = std::max(0.0, value);
    }
    LanesN<N> out;
    if (!lambdas) {
        for (int j = 0; j < N; ++j)
            out[j] = j < lanes ? cached[std::size_t(j)] : 0.0;
        return out;
    }
    for (int j = 0; j < N; ++j) {
        const auto i0 = std::size_t(lambdas->i0[std::size_t(j)]);
        const double t = lambdas->t[j];
        out[j] = (1.0 - t) * cached[i0] + t * cached[i0 + 1];
    }
    return out;
}

template <int N>
LanesN<N> FastIntegrator::shade(const EmbreeScene& scene, const Vec3& p, const Lookup<N>& at,
                                const LanesN<N>& indirect, const LaneOptics<N>& lanes,
                                PixelRng& rng, const ShadowDraw& shadow, DirectLight<N>* direct,
                                const LanesN<N>& factor) const {
    // E / pi per unit LED emission: the cached indirect term, plus the direct term with the
    // markers' shadows, sum_k G_k T_k, estimated by the mean of shadow.rays shadow rays, each
    // to one LED k drawn with probability G_k / sum G (exact where the LEDs' shadows agree).
    const int leds = m_cache->leds;
    double total = 0.0;
    for (int k = 0; k < leds; ++k)
        total += at.direct[std::size_t(k)];
    if (!(total > 0.0)) return indirect;
    if (shadow.rays == 0) return LanesN<N>::Constant(total * kInvPi) + indirect;
    const int rays = std::clamp(shadow.rays, 1, kMaxShadowRaysPerSample);
    const LanesN<N> lit = LanesN<N>::Constant(total * kInvPi / rays);
    // The direct light's parts, when asked for: one a ray, each with the unshadowed light its
    // ray carries (times `factor`) and the LED groups' shares of it (the same for every ray).
    const int groups = shadow_groups();
    std::array<double, kMaxShadowGroups> share{};
    if (direct) {
        const double inv = 1.0 / total;
        for (int j = 0; j < leds; ++j)
            share[std::size_t(shadow_group(j, leds, groups))] += at.direct[std::size_t(j)] * inv;
    }
    LanesN<N> sum = LanesN<N>::Zero();
    for (int r = 0; r < rays; ++r) {
        std::array<double, 3> u = r == 0 ? std::array<double, 3>{shadow.u_led, shadow.u1, shadow.u2}
                                         : shadow.further[std::size_t(r - 1)];
        if (!(u[0] >= 0.0)) u = {rng.uniform(), rng.uniform(), rng.uniform()};
        const double pick = u[0] * total;
        int k = 0;
        for (double acc = at.direct[0]; acc <= pick && k + 1 < leds;)
            acc += at.direct[std::size_t(++k)];
        LanesN<N> T = LanesN<N>::Ones();
        if (!scene.has_interface())
            T = m_shading.transmittance(scene, m_path.led_point(k, u[1], u[2]), p, lanes);
        else if (at.radius_mm > 0.0)
            T = shadow_transmittance(scene, p, at, k, u[1], u[2], lanes);
        if (direct) {
            if (direct->parts >= kMaxDirectParts)
                throw std::logic_error("FastIntegrator: more than kMaxDirectParts direct-light "
                                       "parts in one sample");
            DirectPart<N>& part = direct->part[std::size_t(direct->parts++)];
            part.lit = factor * lit;
            part.share = share;
            part.clear = (T == 1.0).all();
            part.shadowed = part.clear ? part.lit : LanesN<N>(part.lit * T);
            part.group = shadow_group(k, leds, groups);
        }
        sum += T;
    }
    return lit * sum + indirect;
}

template <int N>
std::optional<Vec3> FastIntegrator::shadow_exit(const Lookup<N>& at, const Vec3& p, int k,
                                                double u1, double u2) const {
    const Vec3 l = m_path.led_point(k, u1, u2);
    // The sphere model's refraction towards l: by Newton from the frame's guess where there
    // is one (with the culling), else over the whole bracket.
    SphereRefraction solver(p, l, at.radius_mm, m_shading.optics().refractive_index);
    std::optional<Vec3> model;
    if (!m_guess.empty()) {
        Vec3 guess = Vec3::Zero();
        for (int i = 0; i < 3; ++i)
            guess += at.weights[i] * guessed_direction(at.triangle[i], k, u1 - 0.5, u2 - 0.5);
        if (guess.norm() > 0.0)
            model = solver.newton(guess.normalized(), kShadowTolerance, kShadowStepTolerance);
    }
    // Plus the frame's correction (the deformed surface against the sphere), interpolated.
    const Vec3 w =
        ((model ? *model : solver.solve(kShadowTolerance)) + shadow_correction(at, k)).normalized();
    // Where the shadow ray towards l leaves the layers (through the sphere below).
    return sphere_exit(p, w, at.radius_mm);
}

template <int N>
LanesN<N> FastIntegrator::shadow_transmittance(const EmbreeScene& scene, const Vec3& p,
                                               const Lookup<N>& at, int k, double u1, double u2,
                                               const LaneOptics<N>& lanes) const {
    // From where the shadow ray towards the LED point leaves the layers to p it is traced,
    // unless the culling shows it meets nothing.
    const auto exit = shadow_exit(at, p, k, u1, u2);
    const bool frame_apart = (at.frame_share >> k) & 1u;
    if (!exit || (!m_guess.empty() && path_clear(at.prim, k, p, *exit, frame_apart)))
        return LanesN<N>::Ones();
    // This also tests the frame's plane. Near the rim the sphere model's exit lies below
    // z = 0, where no real connection goes, so it blocks light the cache counts as unshadowed
    // (and is the noise of the field's outer ring); it happens to offset the light the cache's
    // rim vertices gather from under the frame (ShadingModel::crosses_mount). Why neither is
    // removed alone: docs/VALIDATION.md, session 28.
    // Where the frame's share is taken off G_k (LightCacheSettings::frame_share), not again.
    return m_shading.transmittance(scene, *exit, p, lanes, kHitGap_mm, !frame_apart);
}

bool FastIntegrator::path_clear(std::uint32_t prim, int k, const Vec3& p, const Vec3& q,
                                bool frame_apart) const {
    const std::size_t i = std::size_t(prim) * std::size_t(m_cache->leds) + std::size_t(k);
    const Eigen::Vector4d& ball = m_cull_ball[i];
    if (!(ball.w() > 0.0)) return false;
    // Above the rim plane, so not across the frame (unless its share is taken apart).
    if (!frame_apart && !(p.z() > 0.0 && q.z() > 0.0)) return false;
    // Inside the ball, so only its markers can be in the way.
    const Vec3 centre = ball.head<3>();
    const double r2 = ball.w() * ball.w();
    if (!((p - centre).squaredNorm() < r2 && (q - centre).squaredNorm() < r2)) return false;
    // The path's directions from the origin: the arc from p's to q's, within its sagitta
    // (generously a quarter of the chord squared) of the chord.
    const auto markers = std::uint32_t(m_marker_balls.size());
    const Vec3 dp = p.normalized(), dq = q.normalized();
    const double sagitta = 0.25 * (dp - dq).squaredNorm();
    for (std::uint32_t j = m_cull_first[i]; j < m_cull_first[i + 1]; ++j) {
        const std::uint32_t index = m_cull_markers[j];
        if (index < markers) {
            const Eigen::Vector4d& m = m_marker_balls[index];
            if (distance2_to_segment(m.head<3>(), p, q) <= m.w() * m.w()) return false;
        } else {
            const Eigen::Vector4d& cone = m_fold_cones[index - markers];
            const double reach = cone.w() + sagitta;
            if (distance2_to_segment(cone.head<3>(), dp, dq) <= reach * reach) return false;
        }
    }
    return true;
}

template <int N>
LanesN<N> FastIntegrator::inside(const EmbreeScene& scene, const Vec3& origin, const Vec3& d,
                                 double tnear, const LaneOptics<N>& lanes,
                                 const CacheLambdas<N>* lambdas, PixelRng& rng,
                                 const ShadowDraw& shadow, const RayHit* first,
                                 DirectLight<N>* direct, double weight) const {
    constexpr double inf = std::numeric_limits<double>::infinity();
    const OpticsParams& optics = m_shading.optics();
    LanesN<N> beta = LanesN<N>::Ones();
    MarkerPath path(0.0);
    // Outer markers entered on the way: the light they scatter back, shaded once the coating
    // behind them (and its cache) is known.
    struct Scatter {
        LanesN<N> weight;
        Vec3 p;
    };
    std::array<Scatter, 4> scatters;
    int pending = 0;
    // The last outer marker left: where, and the chord through it.
    double outer_exit_mm = -inf, outer_chord_mm = 0.0;
    // The hits after the first in one traversal, once they are needed. Not a
    // std::optional: GCC 12's libstdc++ zero-fills the storage of one (816 bytes here) when
    // it is made, a fifth of this function's own time (docs/VALIDATION.md, session 25).
    static_assert(std::is_trivially_destructible_v<RayHits>);
    alignas(RayHits) unsigned char hits_storage[sizeof(RayHits)];
    RayHits* hits = nullptr;
    for (int i = 0; i < kMaxHits; ++i) {
        // The first hit may come traced already (radiance16: the same ray, in a packet).
        if (!(i == 0 && first) && !hits)
            hits = ::new (static_cast<void*>(hits_storage)) RayHits(scene, origin, d, tnear, inf);
        const RayHit hit = i == 0 && first ? *first : hits->next(tnear);
        if (!hit.hit()) break;
        tnear = hit.t_mm + kHitGap_mm;
        if (!(hit.normal.squaredNorm() > 0.5)) continue; // a zero-area triangle
        const Vec3 p = origin + hit.t_mm * d;
        const double cos_g = hit.normal.dot(d);
        if (hit.kind == SurfaceKind::coating) {
            const Lookup<N> at = lookup<N>(hit.prim_id, hit.u, hit.v, facing(hit.normal, d));
            // Below an outer marker the indirect light comes through it: the light above the
            // marker layer times the diffuse transmittance over the marker's thickness along
            // the normal. And the coating there shares its light with the marker's underside:
            // what it reflects up enters the marker and is scattered back with probability s
            // and albedo rho_m, so its irradiance is 1 / (1 - s rho_m rho_c) times what
            // arrives through the marker (the cache's own coating value, at a vertex, cannot
            // hold this: markers are smaller than the vertex spacing).
            const double open = path.open_path(true, hit.t_mm);
            const double chord = open > 0.0                                   ? open
                                 : hit.t_mm - outer_exit_mm < kUnderMarker_mm ? outer_chord_mm
                                                                              : 0.0;
            const double s = optics.outer_marker_scatter_fraction;
            // The cached indirect light at the hit: the level above the markers only where a
            // marker is involved (E_ind / pi per unit LED emission, at the lanes).
            const auto cached = [&](const std::vector<float>& level) -> LanesN<N> {
                return m_indirect_scale * spectral_at(level, at.triangle, at.weights, lambdas);
            };
            const LanesN<N> above =
                chord > 0.0 || pending > 0 ? cached(m_cache->indirect_above) : LanesN<N>::Zero();
            const LanesN<N> f = beta * lanes.coating_albedo * lanes.led;
            LanesN<N> L;
            // The direct light's parts, when asked for: each shade()'s times its factor.
            if (chord > 0.0) {
                const LanesN<N> through = (1.0 - s) *
                                          diffuse_transmittance<N>(lanes.outer_absorption_per_mm *
                                                                   (chord * std::abs(cos_g))) *
                                          above;
                const LanesN<N> below = 1.0 - s * lanes.outer_albedo * lanes.coating_albedo;
                L = f * (shade(scene, p, at, through, lanes, rng, shadow, direct,
                               LanesN<N>(weight * (f / below))) /
                         below);
            } else {
                L = f * shade(scene, p, at, cached(m_cache->indirect), lanes, rng, shadow, direct,
                              LanesN<N>(weight * f));
            }
            // The outer markers' scattering: one shadow ray each, from the stream, or none
            // where the sample takes none.
            const ShadowDraw& scatter = shadow.rays == 0 ? kNoShadowRays : kStreamShadowRay;
            for (int k = 0; k < pending; ++k) {
                const LanesN<N> factor = scatters[std::size_t(k)].weight * lanes.led;
                L += factor * shade(scene, scatters[std::size_t(k)].p, at, above, lanes, rng,
                                    scatter, direct, LanesN<N>(weight * factor));
            }
            return L;
        }
        if (hit.kind != SurfaceKind::inner_marker && hit.kind != SurfaceKind::outer_marker)
            break; // the inner surface again: the ray left the layers
        if (cos_g == 0.0) continue;
        const bool outer = hit.kind == SurfaceKind::outer_marker;
        const double inside = path.cross(outer, hit.t_mm, cos_g < 0.0);
        if (inside >= 0.0) {
            beta *= m_shading.marker_absorption(lanes, outer, inside);
            if (outer) outer_exit_mm = hit.t_mm, outer_chord_mm = inside;
        } else if (outer) {
            const double s = optics.outer_marker_scatter_fraction;
            if (s > 0.0 && pending < int(scatters.size()))
                scatters[std::size_t(pending++)] = {beta * s * lanes.outer_albedo, p};
            beta *= 1.0 - s;
        }
    }
    return LanesN<N>::Zero();
}

template <int N>
LanesN<N> FastIntegrator::radiance(const EmbreeScene& scene, const Vec3& origin,
                                   const Vec3& direction, const LaneOptics<N>& lanes,
                                   const CacheLambdas<N>* lambdas, PixelRng& rng,
                                   ShadowDraw shadow) const {
    // One sample through radiance16 (its rays go to Embree one by one).
    const LaneOptics<N>* lane_sets[1] = {&lanes};
    const CacheLambdas<N>* lambda_sets[1] = {lambdas};
    LanesN<N> out[1];
    PixelRng* rngs[1] = {&rng};
    radiance16<N>(scene, origin, std::span<const Vec3>(&direction, 1), lane_sets, lambda_sets,
                  std::span<const ShadowDraw>(&shadow, 1), rngs, out);
    return out[0];
}

namespace {

/// Traces ray(i) = (origin, direction) of each sample i < n that wants(i), from tnear, into
/// got[i]: as one Embree packet where at least kMinPacket rays go (a packet of a few active
/// rays costs more than the rays alone), else one by one; `interface`: against the inner
/// surface alone.
template <class Wants, class Ray>
void trace_some(const EmbreeScene& scene, std::size_t n, double tnear, Wants&& wants, Ray&& ray,
                std::span<RayHit> got, bool interface) {
    constexpr double inf = std::numeric_limits<double>::infinity();
    std::array<Vec3, 16> origins, rays;
    std::array<RayHit, 16> hits;
    std::array<std::size_t, 16> who;
    std::size_t m = 0;
    for (std::size_t i = 0; i < n; ++i)
        if (wants(i)) {
            const auto [o, d] = ray(i);
            origins[m] = o, rays[m] = d, who[m++] = i;
        }
    if (m >= kMinPacket) {
        const auto o = std::span(origins.data(), m), d = std::span(rays.data(), m);
        if (interface)
            scene.closest_interface_hits16(o, d, tnear, inf, std::span(hits.data(), m));
        else
            scene.closest_hits16(o, d, tnear, inf, std::span(hits.data(), m));
    } else {
        for (std::size_t j = 0; j < m; ++j)
            hits[j] = interface ? scene.closest_interface_hit(origins[j], rays[j], tnear, inf)
                                : scene.closest_hit(origins[j], rays[j], tnear, inf);
    }
    for (std::size_t j = 0; j < m; ++j)
        got[who[j]] = hits[j];
}

} // namespace

FastIntegrator::Level FastIntegrator::classify(const Vec3& o, const Vec3& d, double tnear,
                                               const RayHit& hit, bool reflect) const {
    constexpr double inf = std::numeric_limits<double>::infinity();
    const double eta = m_shading.optics().refractive_index;
    Level level;
    const double tfar = hit.hit() ? hit.t_mm : inf;
    if (m_shading.crosses_mount(o, d, tnear, tfar)) return level;
    if (const auto led = m_path.led_hit(o, d, tnear, tfar)) {
        if (led->second) level.then = Then::led;
        return level;
    }
    if (!hit.hit()) return level;
    if (hit.kind != SurfaceKind::inner_surface) {
        level.then = Then::straight;
        return level;
    }
    const double cos_g = hit.normal.dot(d);
    if (!(cos_g < 0.0)) return level; // the back of the surface: not from air
    level.then = Then::split;
    level.p = o + hit.t_mm * d;
    const Vec3 normal = facing(hit.shading_normal, d);
    const double cos_i = -d.dot(normal);
    level.F = fresnel_dielectric(cos_i, 1.0 / eta);
    level.refract =
        refract(d, normal, 1.0 / eta, level.refracted) && level.refracted.dot(hit.normal) < 0.0;
    level.reflected = (d + 2.0 * cos_i * normal).normalized();
    level.reflect = reflect && level.F > 0.0 && level.reflected.dot(hit.normal) > 0.0;
    return level;
}

void FastIntegrator::camera_levels(const EmbreeScene& scene, const Vec3& origin,
                                   std::span<const Vec3> directions, bool cavity_only, bool reflect,
                                   std::span<RayHit> first, std::span<Level> near) const {
    const std::size_t n = directions.size();
    trace_some(
        scene, n, 0.0, [](std::size_t) { return true; },
        [&](std::size_t i) {
            return std::pair{origin, directions[i]};
        },
        first, cavity_only);
    for (std::size_t i = 0; i < n; ++i)
        near[i] = classify(origin, directions[i], 0.0, first[i], reflect);
}

void FastIntegrator::reflected_leds16(const EmbreeScene& scene, const Vec3& origin,
                                      std::span<const Vec3> directions,
                                      std::span<double> fresnel) const {
    const std::size_t n = directions.size();
    if (n > 16 || fresnel.size() != n)
        throw std::invalid_argument("FastIntegrator::reflected_leds16: " + std::to_string(n) +
                                    " directions and " + std::to_string(fresnel.size()) +
                                    " results; allowed: at most 16, one result per direction");
    // radiance16's first two packets, as it traces them.
    const bool cavity_only = scene.in_cavity(origin);
    std::array<RayHit, 16> first, back;
    std::array<Level, 16> near{};
    camera_levels(scene, origin, directions, cavity_only, true, first, near);
    // Only the reflections that cross an LED at all are traced on (classify then finds the
    // same LED, or the inner surface or the frame before it).
    constexpr double inf = std::numeric_limits<double>::infinity();
    std::array<bool, 16> towards_led{};
    for (std::size_t i = 0; i < n; ++i)
        if (near[i].then == Then::split && near[i].reflect) {
            const auto led = m_path.led_hit(near[i].p, near[i].reflected, kHitGap_mm, inf);
            towards_led[i] = led && led->second;
        }
    const auto reflects = [&towards_led](std::size_t i) { return towards_led[i]; };
    trace_some(
        scene, n, kHitGap_mm, reflects,
        [&](std::size_t i) {
            return std::pair{near[i].p, near[i].reflected};
        },
        back, cavity_only);
    for (std::size_t i = 0; i < n; ++i)
        fresnel[i] =
            reflects(i) &&
                    classify(near[i].p, near[i].reflected, kHitGap_mm, back[i], false).then ==
                        Then::led
                ? near[i].F
                : 0.0;
}

void FastIntegrator::marker_ids16(const EmbreeScene& scene, const Vec3& origin,
                                  std::span<const Vec3> directions, int triangles_per_marker,
                                  std::span<std::pair<std::int32_t, std::int32_t>> ids) const {
    const std::size_t n = directions.size();
    if (n > 16 || ids.size() != n || triangles_per_marker < 1)
        throw std::invalid_argument(
            "FastIntegrator::marker_ids16: " + std::to_string(n) + " directions, " +
            std::to_string(ids.size()) + " results and " + std::to_string(triangles_per_marker) +
            " triangles a marker; allowed: at most 16, one result per direction, at least 1");
    // radiance16's first two packets, as it traces them.
    const bool cavity_only = scene.in_cavity(origin);
    std::array<RayHit, 16> first, into;
    std::array<Level, 16> near{};
    camera_levels(scene, origin, directions, cavity_only, false, first, near);
    const auto refracts = [&near](std::size_t i) {
        return near[i].then == Then::split && near[i].refract;
    };
    trace_some(
        scene, n, kHitGap_mm, refracts,
        [&](std::size_t i) {
            return std::pair{near[i].p, near[i].refracted};
        },
        into, false);
    constexpr double inf = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < n; ++i) {
        std::int32_t layer[2] = {-1, -1};
        const Level& a = near[i];
        const bool straight = a.then == Then::straight;
        if (straight || refracts(i)) {
            // inside()'s walk: the markers' faces up to the coating or the inner surface.
            const Vec3& o = straight ? origin : a.p;
            const Vec3& d = straight ? directions[i] : a.refracted;
            double tnear = straight ? 0.0 : kHitGap_mm;
            const RayHit& hit0 = straight ? first[i] : into[i];
            const auto marker = [](const RayHit& hit) {
                return hit.kind == SurfaceKind::inner_marker ||
                       hit.kind == SurfaceKind::outer_marker;
            };
            const auto take = [&](const RayHit& hit) {
                tnear = hit.t_mm + kHitGap_mm;
                if (!(hit.normal.squaredNorm() > 0.5)) return; // a zero-area triangle
                std::int32_t& id = layer[hit.kind == SurfaceKind::outer_marker ? 1 : 0];
                if (id < 0) id = std::int32_t(hit.prim_id / std::uint32_t(triangles_per_marker));
            };
            if (marker(hit0)) {
                take(hit0);
                RayHits hits(scene, o, d, tnear, inf);
                for (int k = 1; k < kMaxHits; ++k) {
                    const RayHit hit = hits.next(tnear);
                    if (!marker(hit)) break;
                    take(hit);
                }
            }
        }
        ids[i] = {layer[0], layer[1]};
    }
}

template <int N>
void FastIntegrator::radiance16(const EmbreeScene& scene, const Vec3& origin,
                                std::span<const Vec3> directions,
                                std::span<const LaneOptics<N>* const> lanes,
                                std::span<const CacheLambdas<N>* const> lambdas,
                                std::span<const ShadowDraw> shadow, std::span<PixelRng* const> rng,
                                std::span<LanesN<N>> out, std::span<DirectLight<N>> direct,
                                bool reflected_leds) const {
    if (!m_cache || m_direct.empty())
        throw std::logic_error("FastIntegrator::radiance called before build_cache/set_frame");
    const std::size_t n = directions.size();
    if (n > 16 || lanes.size() != n || lambdas.size() != n || shadow.size() != n ||
        rng.size() != n || out.size() != n || !(direct.empty() || direct.size() == n))
        throw std::invalid_argument("FastIntegrator::radiance16: " + std::to_string(n) +
                                    " directions; allowed: at most 16, one lane set, "
                                    "wavelength set, LED uniform, stream and result per "
                                    "direction, and none or one direct light per direction");
    // From a camera in the cavity, the rays there (the camera's, and their reflections off the
    // inner surface) can meet the inner surface first or nothing (the frame and the LEDs are
    // tested apart): its BVH alone answers them.
    const bool cavity_only = scene.in_cavity(origin);
    const auto trace = [&](double tnear, auto&& wants, auto&& ray, std::array<RayHit, 16>& got,
                           bool in_cavity) {
        trace_some(scene, n, tnear, wants, ray, got, in_cavity && cavity_only);
    };
    std::array<RayHit, 16> first, into, back, far_wall;
    std::array<Level, 16> near{}, far{};
    camera_levels(scene, origin, directions, cavity_only, true, first, near);
    const auto splits = [&](const std::array<Level, 16>& at, bool reflected) {
        return [&at, reflected](std::size_t i) {
            return at[i].then == Then::split && (reflected ? at[i].reflect : at[i].refract);
        };
    };
    trace(
        kHitGap_mm, splits(near, false),
        [&](std::size_t i) {
            return std::pair{near[i].p, near[i].refracted};
        },
        into, false);
    trace(
        kHitGap_mm, splits(near, true),
        [&](std::size_t i) {
            return std::pair{near[i].p, near[i].reflected};
        },
        back, true);
    for (std::size_t i = 0; i < n; ++i)
        if (splits(near, true)(i))
            far[i] = classify(near[i].p, near[i].reflected, kHitGap_mm, back[i], false);
    trace(
        kHitGap_mm, splits(far, false),
        [&](std::size_t i) {
            return std::pair{far[i].p, far[i].refracted};
        },
        far_wall, false);
    // Then each sample in order, as radiance() would: the refracted ray's layers first, then
    // the reflected ray's.
    for (std::size_t i = 0; i < n; ++i) {
        const LaneOptics<N>& l = *lanes[i];
        const LanesN<N> led_radiance = l.led / m_path.led_area_mm2();
        DirectLight<N>* const split = direct.empty() ? nullptr : &direct[i];
        if (split) split->parts = 0;
        // The layers' radiance; `weight`: the share of it the sample takes. Through the
        // camera ray's reflection (`reflected`), below kUnshadowedReflection, no shadow rays.
        const auto layers = [&](const Vec3& o, const Vec3& d, double tnear, const RayHit& hit,
                                double weight, bool reflected = false) {
            const bool unshadowed = reflected && m_settings.unshadowed_reflections &&
                                    weight < kUnshadowedReflection;
            return inside(scene, o, d, tnear, l, lambdas[i], *rng[i],
                          unshadowed ? kNoShadowRays : shadow[i], &hit, split, weight);
        };
        LanesN<N> L = LanesN<N>::Zero();
        const Level& a = near[i];
        if (a.then == Then::led) {
            L = led_radiance;
        } else if (a.then == Then::straight) {
            L = layers(origin, directions[i], 0.0, first[i], 1.0);
        } else if (a.then == Then::split) {
            if (a.refract)
                L += (1.0 - a.F) * layers(a.p, a.refracted, kHitGap_mm, into[i], 1.0 - a.F);
            if (a.reflect) {
                const Level& b = far[i];
                if (b.then == Then::led) {
                    if (reflected_leds) L += a.F * led_radiance;
                } else if (b.then == Then::straight)
                    L += a.F * layers(a.p, a.reflected, kHitGap_mm, back[i], a.F, true);
                else if (b.then == Then::split && b.refract)
                    L += a.F * ((1.0 - b.F) * layers(b.p, b.refracted, kHitGap_mm, far_wall[i],
                                                     a.F * (1.0 - b.F), true));
            }
        }
        out[i] = L;
    }
}

template void FastIntegrator::radiance16(const EmbreeScene&, const Vec3&, std::span<const Vec3>,
                                         std::span<const LaneOptics<kRgbLanes>* const>,
                                         std::span<const CacheLambdas<kRgbLanes>* const>,
                                         std::span<const ShadowDraw>, std::span<PixelRng* const>,
                                         std::span<LanesN<kRgbLanes>>,
                                         std::span<DirectLight<kRgbLanes>>, bool) const;
template void FastIntegrator::radiance16(const EmbreeScene&, const Vec3&, std::span<const Vec3>,
                                         std::span<const LaneOptics<kSpectralLanes>* const>,
                                         std::span<const CacheLambdas<kSpectralLanes>* const>,
                                         std::span<const ShadowDraw>, std::span<PixelRng* const>,
                                         std::span<LanesN<kSpectralLanes>>,
                                         std::span<DirectLight<kSpectralLanes>>, bool) const;
template void FastIntegrator::radiance16(const EmbreeScene&, const Vec3&, std::span<const Vec3>,
                                         std::span<const LaneOptics<kFastSpectralLanes>* const>,
                                         std::span<const CacheLambdas<kFastSpectralLanes>* const>,
                                         std::span<const ShadowDraw>, std::span<PixelRng* const>,
                                         std::span<LanesN<kFastSpectralLanes>>,
                                         std::span<DirectLight<kFastSpectralLanes>>, bool) const;

template LanesN<kRgbLanes> FastIntegrator::radiance(const EmbreeScene&, const Vec3&, const Vec3&,
                                                    const LaneOptics<kRgbLanes>&,
                                                    const CacheLambdas<kRgbLanes>*, PixelRng&,
                                                    ShadowDraw) const;
template LanesN<kSpectralLanes> FastIntegrator::radiance(const EmbreeScene&, const Vec3&,
                                                         const Vec3&,
                                                         const LaneOptics<kSpectralLanes>&,
                                                         const CacheLambdas<kSpectralLanes>*,
                                                         PixelRng&, ShadowDraw) const;

} // namespace chromasim::render::detail
