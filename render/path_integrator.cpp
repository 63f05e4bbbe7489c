#include "render/path_integrator.hpp"

#include <Eigen/Geometry>
#include <Eigen/LU>

#include <cmath>
#include <limits>
#include <numbers>

namespace chromasim::render::detail {

namespace {

constexpr double kInvPi = 1.0 / std::numbers::pi;
/// Newton on the connection's direction: stop when the LED-plane point is this close (mm).
constexpr double kConnectTolerance_mm = 1e-6;
constexpr int kConnectIterations = 24;
/// Largest Newton step on the direction (rad): keeps the walk on the surface it started on.
constexpr double kConnectMaxStep = 0.1;
/// Central-difference step on the direction (rad) for the connection's Jacobian.
constexpr double kJacobianStep = 1e-6;

/// Power heuristic weight of the strategy with density `a` against `b`.
double power_heuristic(double a, double b) {
    const double a2 = a * a, b2 = b * b;
    return a2 + b2 > 0.0 ? a2 / (a2 + b2) : 0.0;
}

Vec3 facing(const Vec3& normal, const Vec3& direction) {
    return normal.dot(direction) > 0.0 ? Vec3(-normal) : normal;
}

/// The refracted ray of one interface triangle, continued to the LED plane.
struct PlanePoint {
    Vec3 l;   ///< on the plane z = led_z
    Vec3 x;   ///< on the triangle's plane
    double F; ///< Fresnel reflectance at x
};

/// p (inside the clear layers) -> the plane of `t` along w, refract into the air (index 1)
/// with the normal interpolated from the vertex normals, -> the plane z = led_z.
std::optional<PlanePoint> to_led_plane(const EmbreeScene::Triangle& t, const Vec3& p, const Vec3& w,
                                       double eta, double led_z) {
    const Vec3 e1 = t.p[1] - t.p[0], e2 = t.p[2] - t.p[0];
    const Vec3 ng = e1.cross(e2);
    const double denom = ng.dot(w);
    if (!(std::abs(denom) > 1e-300)) return std::nullopt;
    const double s = ng.dot(t.p[0] - p) / denom;
    if (!(s > 0.0)) return std::nullopt;
    const Vec3 x = p + s * w;
    // Barycentric coordinates in the triangle's plane (outside it: linear extrapolation).
    const Vec3 q = x - t.p[0];
    const double d00 = e1.dot(e1), d01 = e1.dot(e2), d11 = e2.dot(e2);
    const double d20 = q.dot(e1), d21 = q.dot(e2);
    const double det = d00 * d11 - d01 * d01;
    if (!(det > 0.0)) return std::nullopt;
    const double b1 = (d11 * d20 - d01 * d21) / det, b2 = (d00 * d21 - d01 * d20) / det;
    Vec3 n = (1.0 - b1 - b2) * t.n[0] + b1 * t.n[1] + b2 * t.n[2];
    if (!(n.norm() > 0.0)) return std::nullopt;
    n = facing(n.normalized(), w);
    Vec3 out;
    if (!refract(w, n, eta, out)) return std::nullopt; // total internal reflection
    if (!(out.z() < 0.0)) return std::nullopt;
    const double r = (led_z - x.z()) / out.z();
    if (!(r > 0.0)) return std::nullopt;
    return PlanePoint{x + r * out, x, fresnel_dielectric(-w.dot(n), eta)};
}

/// 2 x 2 Jacobian of the LED-plane point (x, y) with respect to the direction w, in the
/// tangent coordinates (b1, b2) of w (an isometry to first order: |det| is per steradian).
bool led_plane_jacobian(const EmbreeScene::Triangle& t, const Vec3& p, const Vec3& w, double eta,
                        double led_z, Eigen::Matrix2d& J) {
    Vec3 b1, b2;
    orthonormal_basis(w, b1, b2);
    const Vec3 tangents[2] = {b1, b2};
    for (int c = 0; c < 2; ++c) {
        const auto plus =
            to_led_plane(t, p, (w + kJacobianStep * tangents[c]).normalized(), eta, led_z);
        const auto minus =
            to_led_plane(t, p, (w - kJacobianStep * tangents[c]).normalized(), eta, led_z);
        if (!plus || !minus) return false;
        J.col(c) = (plus->l - minus->l).head<2>() / (2.0 * kJacobianStep);
    }
    return J.allFinite();
}

/// The first guess of a connection p -> x -> l: the path refracted by a sphere about the
/// origin of radius `radius` (the inner surface as built), found by bisection on the angle of x
/// in the plane of the origin, p and l; Snell's law says the tangential components of the unit
/// directions match, n (w_in . tau) = w_out . tau.
Vec3 sphere_guess(const Vec3& p, const Vec3& l, double radius, double eta) {
    const Vec3 e1 = p.normalized();
    Vec3 e2 = l - l.dot(e1) * e1;
    if (!(e2.norm() > 1e-9)) return (l - p).normalized(); // l on p's axis: straight down
    e2.normalize();
    const double psi_l = std::atan2(l.dot(e2), l.dot(e1)); // p is at angle 0
    auto mismatch = [&](double psi) {
        const Vec3 radial = std::cos(psi) * e1 + std::sin(psi) * e2;
        const Vec3 tau = -std::sin(psi) * e1 + std::cos(psi) * e2;
        const Vec3 x = radius * radial;
        return eta * (x - p).normalized().dot(tau) - (l - x).normalized().dot(tau);
    };
    double lo = 0.0, hi = psi_l;
    const double f_lo = mismatch(lo);
    if (f_lo * mismatch(hi) > 0.0) return (l - p).normalized();
    for (int i = 0; i < 60; ++i) {
        const double mid = 0.5 * (lo + hi);
        if ((mismatch(mid) > 0.0) == (f_lo > 0.0))
            lo = mid;
        else
            hi = mid;
    }
    const double psi = 0.5 * (lo + hi);
    return (radius * (std::cos(psi) * e1 + std::sin(psi) * e2) - p).normalized();
}

} // namespace

PathIntegrator::PathIntegrator(const ShadingModel& shading, bool next_event)
    : m_shading(shading), m_next_event(next_event), m_eta(shading.optics().refractive_index),
      m_led_area_mm2(shading.optics().led_width_mm * shading.optics().led_height_mm) {
    for (const Vec3& c : shading.led_positions_mm()) {
        m_led_centres.push_back(c);
        Vec3 radial(c.x(), c.y(), 0.0);
        radial = radial.norm() > 0.0 ? Vec3(radial.normalized()) : Vec3(1.0, 0.0, 0.0);
        m_led_radials.push_back(radial);
        m_led_tangents.push_back(Vec3(-radial.y(), radial.x(), 0.0));
    }
}

Vec3 PathIntegrator::led_point(int k, double u1, double u2) const {
    const OpticsParams& o = m_shading.optics();
    return m_led_centres[std::size_t(k)] + (u1 - 0.5) * o.led_width_mm * m_led_tangents[k] +
           (u2 - 0.5) * o.led_height_mm * m_led_radials[k];
}

std::optional<std::pair<double, bool>> PathIntegrator::led_hit(const Vec3& origin,
                                                               const Vec3& direction, double tnear,
                                                               double tfar) const {
    if (direction.z() == 0.0) return std::nullopt;
    const OpticsParams& o = m_shading.optics();
    const double t = (o.led_z_mm - origin.z()) / direction.z();
    if (!(t > tnear && t < tfar)) return std::nullopt;
    const Vec3 q = origin + t * direction;
    for (std::size_t k = 0; k < m_led_centres.size(); ++k) {
        const Vec3 local = q - m_led_centres[k];
        if (std::abs(local.dot(m_led_tangents[k])) <= 0.5 * o.led_width_mm &&
            std::abs(local.dot(m_led_radials[k])) <= 0.5 * o.led_height_mm)
            return std::make_pair(t, direction.z() < 0.0);
    }
    return std::nullopt;
}

std::optional<InterfaceConnection> PathIntegrator::through_triangle(const EmbreeScene& scene,
                                                                    std::uint32_t prim,
                                                                    const Vec3& p, const Vec3& w,
                                                                    Vec3* led_plane_point) const {
    const EmbreeScene::Triangle t = scene.interface_triangle(prim);
    const double led_z = m_shading.optics().led_z_mm;
    const auto point = to_led_plane(t, p, w, m_eta, led_z);
    Eigen::Matrix2d J;
    if (!point || !led_plane_jacobian(t, p, w, m_eta, led_z, J)) return std::nullopt;
    if (led_plane_point) *led_plane_point = point->l;
    return InterfaceConnection{w, point->x, 1.0 - point->F, std::abs(J.determinant())};
}

std::optional<InterfaceConnection> PathIntegrator::connect(const EmbreeScene& scene, const Vec3& p,
                                                           const Vec3& l) const {
    constexpr double inf = std::numeric_limits<double>::infinity();
    const double led_z = m_shading.optics().led_z_mm;
    // First guess: refraction by the sphere through the inner surface below p.
    const RayHit below = scene.closest_interface_hit(p, -p.normalized(), kHitGap_mm, inf);
    if (!below.hit()) return std::nullopt;
    const double radius = (p - below.t_mm * p.normalized()).norm();
    Vec3 w = sphere_guess(p, l, radius, m_eta);
    // Newton on w in its tangent plane; a step that leaves the valid region (total internal
    // reflection, a miss) is halved.
    struct Iterate {
        Vec3 w;
        std::uint32_t prim;
        PlanePoint point;
        Eigen::Matrix2d J;
    };
    auto evaluate = [&](const Vec3& dir) -> std::optional<Iterate> {
        const RayHit hit = scene.closest_interface_hit(p, dir, kHitGap_mm, inf);
        if (!hit.hit()) return std::nullopt;
        const EmbreeScene::Triangle t = scene.interface_triangle(hit.prim_id);
        const auto point = to_led_plane(t, p, dir, m_eta, led_z);
        Eigen::Matrix2d J;
        if (!point || !led_plane_jacobian(t, p, dir, m_eta, led_z, J)) return std::nullopt;
        return Iterate{dir, hit.prim_id, *point, J};
    };
    std::optional<Iterate> current = evaluate(w);
    if (!current) return std::nullopt;
    for (int it = 0; it < kConnectIterations; ++it) {
        const Eigen::Vector2d g = (current->point.l - l).head<2>();
        if (g.norm() < kConnectTolerance_mm)
            return InterfaceConnection{current->w, current->point.x, 1.0 - current->point.F,
                                       std::abs(current->J.determinant())};
        if (!(std::abs(current->J.determinant()) > 1e-12)) return std::nullopt;
        Eigen::Vector2d step = -current->J.inverse() * g;
        if (step.norm() > kConnectMaxStep) step *= kConnectMaxStep / step.norm();
        Vec3 b1, b2;
        orthonormal_basis(current->w, b1, b2);
        std::optional<Iterate> next;
        for (int halving = 0; halving < 8 && !next; ++halving, step *= 0.5)
            next = evaluate((current->w + step.x() * b1 + step.y() * b2).normalized());
        if (!next) return std::nullopt;
        current = next;
    }
    return std::nullopt;
}

template <int N>
LanesN<N> PathIntegrator::next_event(const EmbreeScene& scene, const Vec3& p, const Vec3& n,
                                     const LaneOptics<N>& lanes, PixelRng& rng) const {
    const int leds = led_count();
    const int k = std::min(int(rng.uniform() * leds), leds - 1);
    const double u1 = rng.uniform(), u2 = rng.uniform();
    const Vec3 l = led_point(k, u1, u2);
    const double pdf_area = 1.0 / (leds * m_led_area_mm2);
    const LanesN<N> emitted = lanes.led / m_led_area_mm2; // Lambertian radiance
    if (!scene.has_interface()) {
        const Vec3 to_led = l - p;
        const double d2 = to_led.squaredNorm();
        const Vec3 w = to_led / std::sqrt(d2);
        const double cos_p = n.dot(w), cos_l = -w.z();
        if (!(cos_p > 0.0 && cos_l > 0.0)) return LanesN<N>::Zero();
        const LanesN<N> T = m_shading.transmittance(scene, l, p, lanes);
        const double pdf_nee = pdf_area * d2 / cos_l;
        return emitted * T * (cos_p / pdf_nee * power_heuristic(pdf_nee, cos_p * kInvPi));
    }
    const auto c = connect(scene, p, l);
    if (!c) return LanesN<N>::Zero();
    const double cos_p = n.dot(c->direction);
    if (!(cos_p > 0.0)) return LanesN<N>::Zero();
    // Nothing between x and the LED in the cavity (the surface again, a marker poking out).
    const Vec3 air = l - c->x_mm;
    const double air_mm = air.norm();
    if (air_mm > 2.0 * kHitGap_mm &&
        (m_shading.crosses_frame(c->x_mm, air / air_mm, 0.0, air_mm) ||
         scene.closest_hit(c->x_mm, air / air_mm, kHitGap_mm, air_mm - kHitGap_mm).hit()))
        return LanesN<N>::Zero();
    const LanesN<N> T = m_shading.transmittance(scene, c->x_mm, p, lanes, kHitGap_mm);
    const double pdf_nee = pdf_area * c->jacobian_mm2_per_sr;
    const double pdf_bsdf = cos_p * kInvPi * c->fresnel_transmittance;
    return emitted * T *
           (c->fresnel_transmittance * cos_p / pdf_nee * power_heuristic(pdf_nee, pdf_bsdf));
}

template <int N>
LanesN<N> PathIntegrator::radiance(const EmbreeScene& scene, const Vec3& origin,
                                   const Vec3& direction, const LaneOptics<N>& lanes,
                                   PixelRng& rng) const {
    constexpr double inf = std::numeric_limits<double>::infinity();
    const OpticsParams& optics = m_shading.optics();
    const double pdf_area = 1.0 / (led_count() * m_led_area_mm2);
    LanesN<N> L = LanesN<N>::Zero();
    LanesN<N> beta = LanesN<N>::Ones();
    Vec3 o = origin, d = direction;
    double tnear = 0.0;
    MarkerPath path(0.0);
    // The last diffuse vertex and what happened since, for the MIS weight of an LED hit.
    struct {
        bool diffuse = false;
        Vec3 p, w;              ///< the vertex and the direction sampled there
        double pdf_bsdf = 0.0;  ///< cos / pi
        int transmissions = 0;  ///< interface crossings since
        bool reflected = false; ///< a reflection at the interface since
        std::uint32_t prim = 0; ///< triangle of the last crossing
    } last;
    int bounces = 0;
    // Lambertian scattering at p (normal n facing the incoming ray): NEE, then a new direction.
    auto scatter = [&](const Vec3& p, const Vec3& n, const LanesN<N>& albedo) -> bool {
        if (m_next_event) L += beta * albedo * kInvPi * next_event(scene, p, n, lanes, rng);
        beta *= albedo;
        if (++bounces > kMaxBounces) return false;
        if (bounces >= 3) {
            const double q = std::min(1.0, beta.maxCoeff());
            if (!(rng.uniform() < q)) return false;
            beta /= q;
        }
        const double u1 = rng.uniform(), u2 = rng.uniform();
        d = cosine_direction(n, u1, u2);
        last.diffuse = true;
        last.p = p;
        last.w = d;
        last.pdf_bsdf = std::max(0.0, n.dot(d)) * kInvPi;
        last.transmissions = 0;
        last.reflected = false;
        o = p;
        tnear = kHitGap_mm;
        path = MarkerPath(0.0);
        return last.pdf_bsdf > 0.0;
    };
    for (int event = 0; event < kMaxBounces * kMaxHits; ++event) {
        const RayHit hit = scene.closest_hit(o, d, tnear, inf);
        const double tfar = hit.hit() ? hit.t_mm : inf;
        if (m_shading.crosses_frame(o, d, tnear, tfar)) break; // absorbed by the black frame
        if (const auto led = led_hit(o, d, tnear, tfar)) {
            if (!led->second) break; // the black back of an LED
            double weight = 1.0;
            if (m_next_event && last.diffuse && !last.reflected) {
                if (!scene.has_interface() && last.transmissions == 0) {
                    const Vec3 l = o + led->first * d;
                    const double pdf_nee = pdf_area * (l - last.p).squaredNorm() / -d.z();
                    weight = power_heuristic(last.pdf_bsdf, pdf_nee);
                } else if (scene.has_interface() && last.transmissions == 1) {
                    if (const auto c = through_triangle(scene, last.prim, last.p, last.w))
                        weight = power_heuristic(last.pdf_bsdf * c->fresnel_transmittance,
                                                 pdf_area * c->jacobian_mm2_per_sr);
                }
            }
            L += beta * (lanes.led / m_led_area_mm2) * weight;
            break;
        }
        if (!hit.hit()) break;
        if (!(hit.normal.squaredNorm() > 0.5)) { // a zero-area triangle: no surface there
            tnear = hit.t_mm + kHitGap_mm;
            continue;
        }
        const Vec3 p = o + hit.t_mm * d;
        const double cos_g = hit.normal.dot(d);
        bool go_on = true;
        switch (hit.kind) {
        case SurfaceKind::coating:
            go_on = scatter(p, facing(hit.normal, d), lanes.coating_albedo);
            break;
        case SurfaceKind::inner_marker:
        case SurfaceKind::outer_marker: {
            tnear = hit.t_mm + kHitGap_mm;
            if (cos_g == 0.0) break; // degenerate or edge-on face: no entry, no exit
            const bool outer = hit.kind == SurfaceKind::outer_marker;
            const double inside = path.cross(outer, hit.t_mm, cos_g < 0.0);
            if (inside >= 0.0)
                beta *= m_shading.marker_absorption(lanes, outer, inside);
            else if (outer && rng.uniform() < optics.outer_marker_scatter_fraction)
                go_on = scatter(p, facing(hit.normal, d), lanes.outer_albedo);
            break;
        }
        case SurfaceKind::inner_surface: {
            if (cos_g == 0.0) {
                tnear = hit.t_mm + kHitGap_mm;
                break;
            }
            // The winding makes the normal point into the cavity: against it, air -> layers.
            const double eta = cos_g < 0.0 ? 1.0 / m_eta : m_eta;
            const Vec3 n_geometric = facing(hit.normal, d);
            const Vec3 n = facing(hit.shading_normal, d);
            const double cos_i = -d.dot(n);
            Vec3 next = Vec3::Zero();
            if (rng.uniform() < fresnel_dielectric(cos_i, eta)) {
                next = (d + 2.0 * cos_i * n).normalized();
                last.reflected = true;
                go_on = next.dot(n_geometric) > 0.0; // shading normal sent it through
            } else {
                go_on = refract(d, n, eta, next) && next.dot(n_geometric) < 0.0;
                ++last.transmissions;
                last.prim = hit.prim_id;
            }
            o = p;
            d = next;
            tnear = kHitGap_mm;
            path = MarkerPath(0.0);
            break;
        }
        case SurfaceKind::none:
            break;
        }
        if (!go_on) break;
    }
    return L;
}

template LanesN<kRgbLanes> PathIntegrator::radiance(const EmbreeScene&, const Vec3&, const Vec3&,
                                                    const LaneOptics<kRgbLanes>&, PixelRng&) const;
template LanesN<kSpectralLanes> PathIntegrator::radiance(const EmbreeScene&, const Vec3&,
                                                         const Vec3&,
                                                         const LaneOptics<kSpectralLanes>&,
                                                         PixelRng&) const;

} // namespace chromasim::render::detail
