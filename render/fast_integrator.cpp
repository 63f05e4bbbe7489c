// The fast integrator's samples: a ray's path through the layers and its shading with the
// cached light and coloured shadow rays (the camera packets are in fast_camera.cpp).
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
        at.direct[std::size_t(k)] = std::max(0.0, g) * m_path.led_gain(k);
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
            // The cached indirect light at the hit: the height above the markers only where a
            // marker is involved (E_ind / pi per unit LED emission, at the lanes).
            const auto cached = [&](const std::vector<float>& field) -> LanesN<N> {
                return spectral_at(field, at.triangle, at.weights, lambdas);
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

// radiance16 (fast_camera.cpp) walks the layers of each split ray with these.
template LanesN<kRgbLanes> FastIntegrator::inside(const EmbreeScene&, const Vec3&, const Vec3&,
                                                  double, const LaneOptics<kRgbLanes>&,
                                                  const CacheLambdas<kRgbLanes>*, PixelRng&,
                                                  const ShadowDraw&, const RayHit*,
                                                  DirectLight<kRgbLanes>*, double) const;
template LanesN<kSpectralLanes> FastIntegrator::inside(const EmbreeScene&, const Vec3&, const Vec3&,
                                                       double, const LaneOptics<kSpectralLanes>&,
                                                       const CacheLambdas<kSpectralLanes>*,
                                                       PixelRng&, const ShadowDraw&, const RayHit*,
                                                       DirectLight<kSpectralLanes>*, double) const;
template LanesN<kFastSpectralLanes>
FastIntegrator::inside(const EmbreeScene&, const Vec3&, const Vec3&, double,
                       const LaneOptics<kFastSpectralLanes>&,
                       const CacheLambdas<kFastSpectralLanes>*, PixelRng&, const ShadowDraw&,
                       const RayHit*, DirectLight<kFastSpectralLanes>*, double) const;
// update_frame_share (fast_light_cache.cpp) takes its shadow rays as the RGB samples do.
template std::optional<Vec3> FastIntegrator::shadow_exit(const Lookup<kRgbLanes>&, const Vec3&, int,
                                                         double, double) const;

} // namespace chromasim::render::detail
