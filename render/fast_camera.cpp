// The fast integrator's camera packets: up to 16 camera rays from a pixel batch traced as one
// Embree packet, each split at the inner surface into its refraction and reflection, their
// layers walked by inside() (fast_integrator.cpp); and the marker ids and mirrored LEDs of
// the same rays.
#include "render/fast_common.hpp"

#include <array>
#include <cmath>
#include <limits>
#include <optional>
#include <span>

namespace chromasim::render::detail {

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

FastIntegrator::Bounce FastIntegrator::classify(const Vec3& o, const Vec3& d, double tnear,
                                                const RayHit& hit, bool reflect) const {
    constexpr double inf = std::numeric_limits<double>::infinity();
    const double eta = m_shading.optics().refractive_index;
    Bounce bounce;
    const double tfar = hit.hit() ? hit.t_mm : inf;
    const PathIntegrator::RayEnd end = m_path.ray_end(o, d, tnear, tfar);
    if (end.blocked) return bounce;
    if (const auto& led = end.led) {
        if (led->front) {
            bounce.then = Then::led;
            bounce.led_gain = m_path.led_gain(led->k);
        }
        return bounce;
    }
    if (!hit.hit()) return bounce;
    if (hit.kind != SurfaceKind::inner_surface) {
        bounce.then = Then::straight;
        return bounce;
    }
    const double cos_g = hit.normal.dot(d);
    if (!(cos_g < 0.0)) return bounce; // the back of the surface: not from air
    bounce.then = Then::split;
    bounce.p = o + hit.t_mm * d;
    const Vec3 normal = facing(hit.shading_normal, d);
    const double cos_i = -d.dot(normal);
    bounce.F = fresnel_dielectric(cos_i, 1.0 / eta);
    bounce.refract =
        refract(d, normal, 1.0 / eta, bounce.refracted) && bounce.refracted.dot(hit.normal) < 0.0;
    bounce.reflected = (d + 2.0 * cos_i * normal).normalized();
    bounce.reflect = reflect && bounce.F > 0.0 && bounce.reflected.dot(hit.normal) > 0.0;
    return bounce;
}

void FastIntegrator::camera_bounces(const EmbreeScene& scene, const Vec3& origin,
                                    std::span<const Vec3> directions, bool cavity_only,
                                    bool reflect, std::span<RayHit> first,
                                    std::span<Bounce> near) const {
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
    std::array<Bounce, 16> near{};
    camera_bounces(scene, origin, directions, cavity_only, true, first, near);
    // Only the reflections that cross an LED at all are traced on (classify then finds the
    // same LED, or the inner surface or the frame before it).
    constexpr double inf = std::numeric_limits<double>::infinity();
    std::array<bool, 16> towards_led{};
    for (std::size_t i = 0; i < n; ++i)
        if (near[i].then == Then::split && near[i].reflect) {
            const auto led = m_path.led_hit(near[i].p, near[i].reflected, kHitGap_mm, inf);
            towards_led[i] = led && led->front;
        }
    const auto reflects = [&towards_led](std::size_t i) { return towards_led[i]; };
    trace_some(
        scene, n, kHitGap_mm, reflects,
        [&](std::size_t i) {
            return std::pair{near[i].p, near[i].reflected};
        },
        back, cavity_only);
    for (std::size_t i = 0; i < n; ++i) {
        fresnel[i] = 0.0;
        if (!reflects(i)) continue;
        const Bounce b = classify(near[i].p, near[i].reflected, kHitGap_mm, back[i], false);
        if (b.then == Then::led) fresnel[i] = near[i].F * b.led_gain;
    }
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
    std::array<Bounce, 16> near{};
    camera_bounces(scene, origin, directions, cavity_only, false, first, near);
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
        const Bounce& a = near[i];
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
    std::array<Bounce, 16> near{}, far{};
    camera_bounces(scene, origin, directions, cavity_only, true, first, near);
    const auto splits = [&](const std::array<Bounce, 16>& at, bool reflected) {
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
        const Bounce& a = near[i];
        if (a.then == Then::led) {
            L = led_radiance * a.led_gain;
        } else if (a.then == Then::straight) {
            L = layers(origin, directions[i], 0.0, first[i], 1.0);
        } else if (a.then == Then::split) {
            if (a.refract)
                L += (1.0 - a.F) * layers(a.p, a.refracted, kHitGap_mm, into[i], 1.0 - a.F);
            if (a.reflect) {
                const Bounce& b = far[i];
                if (b.then == Then::led) {
                    if (reflected_leds) L += a.F * led_radiance * b.led_gain;
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
