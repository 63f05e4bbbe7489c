// The fast integrator's samples: a camera ray's path through the layers, its shading with
// the cached light and coloured shadow rays, 16 rays at a time in Embree packets.
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
    // rim vertices gather from under the frame (ShadingModel::crosses_mount), so neither is
    // removed alone.
    // Where the frame's share is taken off G_k (tabulate_frame_share), not again.
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
    // it is made, a fifth of this function's own time.
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
                return spectral_at(level, at.triangle, at.weights, lambdas);
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
            const bool unshadowed = reflected && weight < kUnshadowedReflection;
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
// update_frame_share (fast_light_cache.cpp) takes its shadow rays as the RGB samples do.
template std::optional<Vec3> FastIntegrator::shadow_exit(const Lookup<kRgbLanes>&, const Vec3&, int,
                                                         double, double) const;

} // namespace chromasim::render::detail
