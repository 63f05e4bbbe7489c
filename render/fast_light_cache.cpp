// The fast integrator's light cache: the LEDs' light and the indirect light on the coating
// vertices, built once per sensor, and the frame's share of the LEDs' light near the rim.
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

FastIntegrator::FastIntegrator(const ShadingModel& shading, const PathIntegrator& path)
    : m_shading(shading), m_path(path) {
    if (path.led_count() > kMaxLeds) {
        throw std::invalid_argument("FastIntegrator: " + std::to_string(path.led_count()) +
                                    " LEDs; allowed: at most " + std::to_string(kMaxLeds));
    }
}

namespace {

/// The outer markers' inner face above each coating vertex they cover (its distance along
/// the normal, 0 where none covers it).
std::vector<double> outer_marker_heights(const SensorFrame& rest, const EmbreeScene& full,
                                         const std::vector<Vec3>& normals) {
    const int nv = int(rest.coating.V.rows());
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
    return above_mm;
}

/// Where no marker covers a vertex: the median height of the covered ones (0: none covered).
double median_height(const std::vector<double>& above_mm) {
    std::vector<double> heights;
    for (double h : above_mm)
        if (h > 0.0) heights.push_back(h);
    std::sort(heights.begin(), heights.end());
    return heights.empty() ? 0.0 : heights[heights.size() / 2];
}

/// Smoothing: the indirect light is smooth over millimetres, the estimate of each vertex
/// heavy-tailed (rare long paths that reach an LED). A Gaussian of `sigma` (3D distance at
/// rest, cut at 3 sigma), weighted by the vertices' tributary areas, preserves the field's
/// integral and takes the per-vertex noise down. `coating`: the field at the coating, where
/// covered and uncovered vertices hold different values and are smoothed apart.
void smooth_indirect(const SensorFrame& rest, const std::vector<double>& above_mm, double sigma,
                     int lanes, bool coating, std::vector<float>& field) {
    const int nv = int(rest.coating.V.rows());
    const std::vector<double> area = vertex_areas(rest.coating);
    const double cutoff2 = 9.0 * sigma * sigma;
    std::vector<float> smooth(field.size(), 0.0f);
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
            if (coating &&
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
                rhs.col(j) += (k * field[std::size_t(w) * lanes + j]) * basis;
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
    field.swap(smooth);
}

/// A covered vertex's coating value: its light above the marker times the ratio coating /
/// above of its uncovered neighbours (the grazing light their neighbouring markers filter),
/// so that uncovered coating interpolates uncovered values (a covered hit uses its own
/// marker's filter on indirect_above instead).
void covered_from_neighbours(const SensorFrame& rest, const std::vector<double>& above_mm,
                             LightCache& cache) {
    const int nv = cache.vertices, lanes = cache.lanes;
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
                const float up = cache.indirect_above[std::size_t(w) * lanes + j];
                if (above_mm[std::size_t(w)] > 0.0 || !(up > 0.0f)) continue;
                ratio += cache.indirect[std::size_t(w) * lanes + j] / up;
                ++count;
            }
            cache.indirect[std::size_t(v) * lanes + j] =
                cache.indirect_above[std::size_t(v) * lanes + j] *
                float(count > 0 ? ratio / count : 1.0);
        }
    }
}

} // namespace

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
    const CacheGeometry geometry{rest, full, bare, normals,
                                 outer_marker_heights(rest, full, normals)};
    std::vector<PointLedPaths> rest_paths = point_paths(rest, bare, &cache->point_rest);
    cache_vertex_light(geometry, settings, spectra, led_scale, *cache);
    std::vector<std::array<std::uint32_t, 2>> edges;
    std::vector<std::uint32_t> triangle_edges;
    cache_edge_terms(geometry, settings, *cache, edges, triangle_edges);
    if (settings.smoothing_mm > 0.0) {
        smooth_indirect(rest, geometry.above_mm, settings.smoothing_mm, cache->lanes, true,
                        cache->indirect);
        smooth_indirect(rest, geometry.above_mm, settings.smoothing_mm, cache->lanes, false,
                        cache->indirect_above);
    }
    covered_from_neighbours(rest, geometry.above_mm, *cache);
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

void FastIntegrator::cache_vertex_light(const CacheGeometry& g,
                                        const render::LightCacheSettings& settings,
                                        const SensorSpectra* spectra, double led_scale,
                                        LightCache& cache) const {
    const SensorFrame& rest = g.rest;
    const EmbreeScene &full = g.full, &bare = g.bare;
    const std::vector<Vec3>& normals = g.normals;
    const std::vector<double>& above_mm = g.above_mm;
    const int nv = cache.vertices, leds = cache.leds;
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
    const double typical_above_mm = median_height(above_mm);
    const int lanes = cache.lanes;
    cache.indirect_above.assign(cache.indirect.size(), 0.0f);
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
                cache.direct[(std::size_t(v) * leds + k) * 3 + a] = float(flux[a]);
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
        float* coating = cache.indirect.data() + std::size_t(v) * lanes;
        float* above = cache.indirect_above.data() + std::size_t(v) * lanes;
        const double h = above_mm[std::size_t(v)];
        mean_indirect(p + (h > 0.0 ? h : typical_above_mm) * n, above);
        if (h > 0.0 || typical_above_mm == 0.0)
            std::copy(above, above + lanes, coating);
        else
            mean_indirect(p, coating);
    });
}

void FastIntegrator::cache_edge_terms(const CacheGeometry& g,
                                      const render::LightCacheSettings& settings,
                                      LightCache& cache,
                                      std::vector<std::array<std::uint32_t, 2>>& edges,
                                      std::vector<std::uint32_t>& triangle_edges) const {
    const SensorFrame& rest = g.rest;
    const EmbreeScene& bare = g.bare;
    const std::vector<Vec3>& normals = g.normals;
    const int nv = cache.vertices, leds = cache.leds;
    // The direct light's quadratic term along each edge: at the midpoint, less the mean of the
    // ends (the LEDs near the rim make G_k curve within a triangle: linear interpolation
    // alone leaves the rim about 2 % dark at rest).
    coating_edges(cache.coating_triangles, edges, triangle_edges);
    cache.direct_edge.assign(edges.size() * std::size_t(leds) * 3, 0.0f);
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
            const float* ga = cache.direct.data() + (std::size_t(a) * leds + k) * 3;
            const float* gb = cache.direct.data() + (std::size_t(b) * leds + k) * 3;
            float* out = cache.direct_edge.data() + (std::size_t(e) * leds + k) * 3;
            for (int i = 0; i < 3; ++i)
                out[i] = float(flux[i] - 0.5 * (double(ga[i]) + double(gb[i])));
        }
    });
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
        cache.indirect_above.size() == cache.indirect.size() &&
        cache.coating_triangles.size() % 3 == 0;
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
    if (!bare.has_interface()) return;
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
            return sphere_exit(p, m_path.refracted_direction(p, m_path.led_point(k, u1, u2), R), R);
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
            blocked +=
                m_shading.crosses_mount(*exit, segment / length, kHitGap_mm, length - kHitGap_mm);
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
        return frame_share(p, at.radius_mm,
                           [&](double u1, double u2) { return shadow_exit(at, p, k, u1, u2); });
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
        m_frame_edge[pair] = now(a, b, int(k)) -
                             0.5f * (m_frame_vertex[a * leds + k] + m_frame_vertex[b * leds + k]);
    });
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

} // namespace chromasim::render::detail
