// PathIntegrator's path tracing: the LEDs' geometry, next-event estimation, and the path loop of
// radiance() and indirect(). The connections through the inner surface are path_connection.cpp's.
#include "render/path_integrator.hpp"

#include "render/sampling.hpp"

#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>

namespace chromasim::render::detail {

namespace {

constexpr double kInvPi = 1.0 / std::numbers::pi;

/// Power heuristic weight of the strategy with density `a` against `b`.
double power_heuristic(double a, double b) {
    const double a2 = a * a, b2 = b * b;
    return a2 + b2 > 0.0 ? a2 / (a2 + b2) : 0.0;
}

/// The last diffuse vertex of a path and what happened since, for the MIS weight of an LED hit.
struct DiffuseVertex {
    bool diffuse = false;
    Vec3 p, w;                       ///< the vertex and the direction sampled there
    double pdf_bsdf = 0.0;           ///< cos / pi
    int events = 0;                  ///< interface events since, while they form a Chain
    bool chain = true;               ///< false once they no longer do
    std::uint32_t prims[2] = {0, 0}; ///< their triangles
};

/// A path as PathIntegrator::trace follows it from one event to the next.
template <int N> struct PathState {
    PathState(const Vec3& origin, const Vec3& direction) : o(origin), d(direction) {}

    LanesN<N> L = LanesN<N>::Zero();    ///< the radiance gathered
    LanesN<N> beta = LanesN<N>::Ones(); ///< the throughput
    Vec3 o, d;                          ///< the current ray
    double tnear = 0.0;
    MarkerPath path{0.0}; ///< where the ray entered the markers it is inside
    DiffuseVertex last;
    int bounces = 0;
    /// indirect(): still at its start vertex, whose light straight from the LEDs through a Chain
    /// (next-event estimation's domain) is left out.
    bool at_start = false;
    /// The current ray's hits (RayHits: its markers and the next other surface from one
    /// traversal), traced anew whenever the path turns.
    std::optional<RayHits> hits;

    /// On from p along the unit direction `next`: a new ray, inside no marker.
    void turn(const Vec3& p, const Vec3& next) {
        o = p;
        d = next;
        tnear = kHitGap_mm;
        path = MarkerPath(0.0);
        hits.reset();
    }
};

/// indirect(): the path starts at a diffuse vertex (unit `normal`), one bounce in.
template <int N> void start_at_vertex(PathState<N>& s, const Vec3& normal) {
    s.at_start = true;
    s.last.diffuse = true;
    s.last.p = s.o;
    s.last.w = s.d;
    s.last.pdf_bsdf = normal.dot(s.d) * kInvPi;
    s.tnear = kHitGap_mm;
    s.bounces = 1;
}

/// A Lambertian event at p (unit normal n facing the incoming ray) after its next-event
/// estimation: the albedo, Russian roulette from the third bounce on, then a cosine-distributed
/// direction. False where the path ends.
template <int N>
bool bounce(PathState<N>& s, const Vec3& p, const Vec3& n, const LanesN<N>& albedo, PixelRng& rng) {
    s.beta *= albedo;
    if (++s.bounces > kMaxBounces) return false;
    if (s.bounces >= 3) {
        const double q = std::min(1.0, s.beta.maxCoeff());
        if (!(rng.uniform() < q)) return false;
        s.beta /= q;
    }
    const double u1 = rng.uniform(), u2 = rng.uniform();
    const Vec3 d = cosine_direction(n, u1, u2);
    s.last.diffuse = true;
    s.last.p = p;
    s.last.w = d;
    s.last.pdf_bsdf = std::max(0.0, n.dot(d)) * kInvPi;
    s.last.events = 0;
    s.last.chain = true;
    s.turn(p, d);
    return s.last.pdf_bsdf > 0.0;
}

/// A marker face (`hit`; cos_g: its normal . the ray): the ray goes on past it, entering or
/// leaving the volume, and on leaving takes the Beer-Lambert factor of the chord inside. True
/// where it enters an outer marker and scatters there (outer_marker_scatter_fraction).
template <int N>
bool cross_marker(PathState<N>& s, const RayHit& hit, double cos_g, const ShadingModel& shading,
                  const LaneOptics<N>& lanes, PixelRng& rng) {
    s.tnear = hit.t_mm + kHitGap_mm;
    if (cos_g == 0.0) return false; // degenerate or edge-on face: no entry, no exit
    const bool outer = hit.kind == SurfaceKind::outer_marker;
    const double inside = s.path.cross(outer, hit.t_mm, cos_g < 0.0);
    if (inside >= 0.0)
        s.beta *= shading.marker_absorption(lanes, outer, inside);
    else if (outer && rng.uniform() < shading.optics().outer_marker_scatter_fraction)
        return true;
    return false;
}

/// An interface event after the last diffuse vertex: the Chain goes on with triangle `prim`
/// where the event `extends` it; otherwise the path no longer forms one.
void continue_chain(DiffuseVertex& last, bool extends, std::uint32_t prim) {
    if (extends)
        last.prims[last.events++] = prim;
    else
        last.chain = false;
}

/// The inner surface at p (`hit`, cos_g = its geometric normal . the ray, nonzero): reflection
/// with Fresnel's probability, else refraction (`eta_layers`: the clear layers' index). False
/// where the shading normal sends the ray to the wrong side of the surface.
template <int N>
bool cross_interface(PathState<N>& s, const RayHit& hit, const Vec3& p, double cos_g,
                     double eta_layers, PixelRng& rng) {
    // The winding makes the normal point into the cavity: against it, air -> layers.
    const double eta = cos_g < 0.0 ? 1.0 / eta_layers : eta_layers;
    const Vec3 n_geometric = facing(hit.normal, s.d);
    const Vec3 n = facing(hit.shading_normal, s.d);
    const double cos_i = -s.d.dot(n);
    Vec3 next = Vec3::Zero();
    bool go_on = true;
    if (rng.uniform() < fresnel_dielectric(cos_i, eta)) {
        next = (s.d + 2.0 * cos_i * n).normalized();
        // A reflection in the cavity after the refraction continues a Chain.
        continue_chain(s.last, s.last.events == 1 && cos_g < 0.0, hit.prim_id);
        go_on = next.dot(n_geometric) > 0.0; // shading normal sent it through
    } else {
        go_on = refract(s.d, n, eta, next) && next.dot(n_geometric) < 0.0;
        // A refraction out of the layers starts a Chain.
        continue_chain(s.last, s.last.events == 0 && cos_g > 0.0, hit.prim_id);
    }
    s.turn(p, next);
    return go_on;
}

/// The Chain of interface events from the last diffuse vertex to the LED point l as `along`
/// follows it (none where it fails), and nee_share's factor for it (0 then).
struct ChainDensity {
    std::optional<InterfaceConnection> c;
    double share;
};
ChainDensity chain_density(const PathIntegrator& integrator, const EmbreeScene& scene,
                           const DiffuseVertex& last, const Vec3& l) {
    const Chain chain = Chain(last.events);
    const auto c = integrator.along(scene, chain, last.prims, last.p, last.w);
    const double share = c ? integrator.nee_share(scene, chain, last.p, l, last.w) : 0.0;
    return {c, share};
}

/// The MIS weight of the light of an LED that the path meets at o + t_led d: against next-event
/// estimation's density (`next_event`: whether it runs; `pdf_area`: its density of a point on
/// the LEDs), or at indirect()'s start vertex against led_flux_sample's (`start_nee_per_bsdf`:
/// its samples per sample here); nullopt where the light is led_flux_sample's alone.
template <int N>
std::optional<double> led_weight(const PathIntegrator& integrator, const EmbreeScene& scene,
                                 const PathState<N>& s, double t_led, bool next_event,
                                 double pdf_area, double start_nee_per_bsdf) {
    const DiffuseVertex& last = s.last;
    if (s.at_start && last.chain && !scene.has_interface() && last.events == 0)
        return std::nullopt; // straight light of the start vertex: led_flux_sample's
    if (s.at_start && last.chain && scene.has_interface() && last.events > 0) {
        // Light of the start vertex through a Chain: led_flux_sample's share under
        // MIS (weight 1 where no start of its solve finds this path).
        const Vec3 l = s.o + t_led * s.d;
        const auto [c, share] = chain_density(integrator, scene, last, l);
        if (!(share > 0.0)) return 1.0;
        const double pdf_nee =
            start_nee_per_bsdf * c->jacobian_mm2_per_sr * share / integrator.led_area_mm2();
        return power_heuristic(last.pdf_bsdf * c->fresnel, pdf_nee);
    }
    if (!(next_event && last.diffuse && last.chain)) return 1.0;
    const Vec3 l = s.o + t_led * s.d;
    if (!scene.has_interface() && last.events == 0) {
        const double pdf_nee = pdf_area * (l - last.p).squaredNorm() / -s.d.z();
        return power_heuristic(last.pdf_bsdf, pdf_nee);
    }
    if (scene.has_interface() && last.events > 0) {
        // The density next-event estimation gives this chain (what next_event does).
        const auto [c, share] = chain_density(integrator, scene, last, l);
        if (share > 0.0)
            return power_heuristic(last.pdf_bsdf * c->fresnel,
                                   pdf_area * c->jacobian_mm2_per_sr * share);
    }
    return 1.0;
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

std::optional<PathIntegrator::LedHit> PathIntegrator::led_hit(const Vec3& origin,
                                                              const Vec3& direction, double tnear,
                                                              double tfar) const {
    if (direction.z() == 0.0) return std::nullopt;
    const OpticsParams& o = m_shading.optics();
    const double t = (o.led_z_mm - origin.z()) / direction.z();
    if (!(t > tnear && t < tfar)) return std::nullopt;
    const int k = led_at(origin + t * direction, 0.0);
    if (k < 0) return std::nullopt;
    return LedHit{t, direction.z() < 0.0, k};
}

PathIntegrator::RayEnd PathIntegrator::ray_end(const Vec3& origin, const Vec3& direction,
                                               double tnear, double tfar) const {
    RayEnd end;
    end.led = led_hit(origin, direction, tnear, tfar);
    end.blocked = m_shading.crosses_mount(origin, direction, tnear, end.led ? end.led->t_mm : tfar);
    if (end.blocked) end.led.reset();
    return end;
}

std::optional<Vec3> PathIntegrator::led_plane_crossing(const Vec3& origin,
                                                       const Vec3& direction) const {
    if (direction.z() == 0.0) return std::nullopt;
    const double t = (m_shading.optics().led_z_mm - origin.z()) / direction.z();
    if (!(t > 0.0)) return std::nullopt;
    return origin + t * direction;
}

int PathIntegrator::led_at(const Vec3& q, double margin_mm) const {
    const OpticsParams& o = m_shading.optics();
    for (std::size_t k = 0; k < m_led_centres.size(); ++k) {
        const Vec3 local = q - m_led_centres[k];
        if (std::abs(local.dot(m_led_tangents[k])) <= 0.5 * o.led_width_mm + margin_mm &&
            std::abs(local.dot(m_led_radials[k])) <= 0.5 * o.led_height_mm + margin_mm)
            return int(k);
    }
    return -1;
}

bool PathIntegrator::quad_near_led(const std::array<Vec3, 4>& q, double margin_mm) const {
    // In the plane's (x, y): the quad strictly convex (its turns all of one sign), else no
    // proof.
    const auto xy = [&](int i) {
        return Eigen::Vector2d(q[std::size_t(i)].x(), q[std::size_t(i)].y());
    };
    double sign = 0.0;
    for (int i = 0; i < 4; ++i) {
        const Eigen::Vector2d a = xy((i + 1) % 4) - xy(i), b = xy((i + 2) % 4) - xy((i + 1) % 4);
        const double turn = a.x() * b.y() - a.y() * b.x();
        if (!(std::abs(turn) > 0.0) || (sign != 0.0 && turn * sign < 0.0)) return true;
        sign = turn;
    }
    const OpticsParams& o = m_shading.optics();
    for (std::size_t k = 0; k < m_led_centres.size(); ++k) {
        const Eigen::Vector2d c(m_led_centres[k].x(), m_led_centres[k].y());
        const Eigen::Vector2d t(m_led_tangents[k].x(), m_led_tangents[k].y()),
            r(m_led_radials[k].x(), m_led_radials[k].y());
        const double ht = 0.5 * o.led_width_mm + margin_mm, hr = 0.5 * o.led_height_mm + margin_mm;
        const std::array<Eigen::Vector2d, 4> box = {c - ht * t - hr * r, c + ht * t - hr * r,
                                                    c + ht * t + hr * r, c - ht * t + hr * r};
        // Separated along an axis: the two shapes' projections do not overlap.
        const auto separated = [&](const Eigen::Vector2d& axis) {
            double a_lo = std::numeric_limits<double>::infinity(), a_hi = -a_lo;
            double b_lo = a_lo, b_hi = -a_lo;
            for (int i = 0; i < 4; ++i) {
                const double pa = axis.dot(xy(i)), pb = axis.dot(box[std::size_t(i)]);
                a_lo = std::min(a_lo, pa), a_hi = std::max(a_hi, pa);
                b_lo = std::min(b_lo, pb), b_hi = std::max(b_hi, pb);
            }
            return a_hi < b_lo || b_hi < a_lo;
        };
        bool apart = separated(t) || separated(r);
        for (int i = 0; i < 4 && !apart; ++i) {
            const Eigen::Vector2d e = xy((i + 1) % 4) - xy(i);
            apart = separated(Eigen::Vector2d(-e.y(), e.x()));
        }
        if (!apart) return true;
    }
    return false;
}

template <class Visit>
void PathIntegrator::for_each_connection(const EmbreeScene& scene, const Vec3& p, const Vec3& n,
                                         const Vec3& l, double u_choice, double radius_mm,
                                         Visit&& visit, int chains,
                                         const std::vector<Vec3>* mirrors) const {
    for (Chain chain : {Chain::refracted, Chain::refracted_reflected}) {
        if (!(chains & int(chain))) continue;
        const auto c = connect(scene, p, l, chain, u_choice, radius_mm, mirrors);
        if (!c) continue;
        if (const auto cos_p = arriving_cosine(scene, *c, chain, n, l)) visit(*c, *cos_p);
    }
}

template <int N>
LanesN<N> PathIntegrator::next_event(const EmbreeScene& scene, const Vec3& p, const Vec3& n,
                                     const LaneOptics<N>& lanes, PixelRng& rng) const {
    const int leds = led_count();
    const int k = std::min(int(rng.uniform() * leds), leds - 1);
    const double u1 = rng.uniform(), u2 = rng.uniform();
    const Vec3 l = led_point(k, u1, u2);
    const double pdf_area = 1.0 / (leds * m_led_area_mm2);
    const LanesN<N> emitted = lanes.led / m_led_area_mm2 * led_gain(k); // Lambertian radiance
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
    LanesN<N> total = LanesN<N>::Zero();
    const double u_choice = rng.uniform();
    const auto radius = radius_below(scene, p); // the sphere model's, for both chains
    if (!radius) return total;
    for_each_connection(
        scene, p, n, l, u_choice, *radius, [&](const InterfaceConnection& c, double cos_p) {
            const LanesN<N> T = m_shading.transmittance(scene, c.x_mm[0], p, lanes, kHitGap_mm);
            const double pdf_nee = pdf_area * c.jacobian_mm2_per_sr / c.candidates;
            const double pdf_bsdf = cos_p * kInvPi * c.fresnel;
            total +=
                emitted * T * (c.fresnel * cos_p / pdf_nee * power_heuristic(pdf_nee, pdf_bsdf));
        });
    return total;
}

Vec3 PathIntegrator::led_flux_sample(const EmbreeScene& scene, const Vec3& p, const Vec3& n, int k,
                                     double u1, double u2, double u_choice, double bsdf_per_nee,
                                     std::optional<double> radius_mm) const {
    const Vec3 l = led_point(k, u1, u2);
    if (!scene.has_interface()) {
        const Vec3 to_led = l - p;
        const double d2 = to_led.squaredNorm();
        const Vec3 w = to_led / std::sqrt(d2);
        const double cos_p = n.dot(w), cos_l = -w.z();
        if (!(cos_p > 0.0 && cos_l > 0.0)) return Vec3::Zero();
        if (m_shading.crosses_mount(p, w, 0.0, std::sqrt(d2)) ||
            scene.closest_hit(p, w, kHitGap_mm, std::sqrt(d2) - kHitGap_mm).hit())
            return Vec3::Zero();
        return (cos_l / d2) * w;
    }
    const auto radius = radius_mm ? radius_mm : radius_below(scene, p);
    if (!radius) return Vec3::Zero();
    Vec3 sum = Vec3::Zero();
    for_each_connection(
        scene, p, n, l, u_choice, *radius, [&](const InterfaceConnection& c, double cos_p) {
            // MIS against indirect()'s cosine samples (power heuristic with
            // the sample counts' ratio).
            const double pdf_nee = c.jacobian_mm2_per_sr / (c.candidates * m_led_area_mm2);
            const double pdf_bsdf = cos_p * kInvPi * c.fresnel;
            sum += (c.fresnel * c.candidates / c.jacobian_mm2_per_sr *
                    power_heuristic(pdf_nee, bsdf_per_nee * pdf_bsdf)) *
                   c.direction;
        });
    return sum;
}

template <int N>
LanesN<N> PathIntegrator::radiance(const EmbreeScene& scene, const Vec3& origin,
                                   const Vec3& direction, const LaneOptics<N>& lanes,
                                   PixelRng& rng) const {
    return trace(scene, origin, direction, lanes, rng, nullptr, 0.0);
}

template <int N>
LanesN<N> PathIntegrator::indirect(const EmbreeScene& scene, const Vec3& p_mm, const Vec3& normal,
                                   const LaneOptics<N>& lanes, PixelRng& rng,
                                   double nee_per_bsdf) const {
    const double u1 = rng.uniform(), u2 = rng.uniform();
    const Vec3 d = cosine_direction(normal, u1, u2);
    if (!(normal.dot(d) > 0.0)) return LanesN<N>::Zero();
    return trace(scene, p_mm, d, lanes, rng, &normal, nee_per_bsdf);
}

template <int N>
LanesN<N> PathIntegrator::trace(const EmbreeScene& scene, const Vec3& origin, const Vec3& direction,
                                const LaneOptics<N>& lanes, PixelRng& rng, const Vec3* start_normal,
                                double start_nee_per_bsdf) const {
    constexpr double inf = std::numeric_limits<double>::infinity();
    const double pdf_area = 1.0 / (led_count() * m_led_area_mm2);
    PathState<N> s(origin, direction);
    if (start_normal) start_at_vertex(s, *start_normal);
    // Lambertian scattering at p (normal n facing the incoming ray): NEE, then a new direction.
    const auto scatter = [&](const Vec3& p, const Vec3& n, const LanesN<N>& albedo) {
        s.at_start = false;
        if (m_next_event) s.L += s.beta * albedo * kInvPi * next_event(scene, p, n, lanes, rng);
        return bounce(s, p, n, albedo, rng);
    };
    for (int event = 0; event < kMaxBounces * kMaxHits; ++event) {
        // The ray's next surface, unless the black frame absorbs the ray before it.
        if (!s.hits) s.hits.emplace(scene, s.o, s.d, s.tnear, inf);
        const RayHit hit = s.hits->next(s.tnear);
        const double tfar = hit.hit() ? hit.t_mm : inf;
        const RayEnd end = ray_end(s.o, s.d, s.tnear, tfar);
        if (end.blocked) break;
        // An LED ends the path, adding its light under MIS where the ray meets its front.
        if (const auto& led = end.led) {
            if (!led->front) break; // the black back of an LED
            const auto weight =
                led_weight(*this, scene, s, led->t_mm, m_next_event, pdf_area, start_nee_per_bsdf);
            if (weight) s.L += s.beta * (lanes.led / m_led_area_mm2) * *weight * led_gain(led->k);
            break;
        }
        if (!hit.hit()) break;
        if (!(hit.normal.squaredNorm() > 0.5)) { // a zero-area triangle: no surface there
            s.tnear = hit.t_mm + kHitGap_mm;
            continue;
        }
        // The event at the surface: scatter, cross a marker face, or reflect or refract.
        const Vec3 p = s.o + hit.t_mm * s.d;
        const double cos_g = hit.normal.dot(s.d);
        bool go_on = true;
        switch (hit.kind) {
        case SurfaceKind::coating:
            go_on = scatter(p, facing(hit.normal, s.d), lanes.coating_albedo);
            break;
        case SurfaceKind::inner_marker:
        case SurfaceKind::outer_marker:
            if (cross_marker(s, hit, cos_g, m_shading, lanes, rng))
                go_on = scatter(p, facing(hit.normal, s.d), lanes.outer_albedo);
            break;
        case SurfaceKind::inner_surface:
            if (cos_g == 0.0)
                s.tnear = hit.t_mm + kHitGap_mm;
            else
                go_on = cross_interface(s, hit, p, cos_g, m_eta, rng);
            break;
        case SurfaceKind::none:
            break;
        }
        if (!go_on) break;
    }
    return s.L;
}

template LanesN<kRgbLanes> PathIntegrator::indirect(const EmbreeScene&, const Vec3&, const Vec3&,
                                                    const LaneOptics<kRgbLanes>&, PixelRng&,
                                                    double) const;
template LanesN<kSpectralLanes> PathIntegrator::indirect(const EmbreeScene&, const Vec3&,
                                                         const Vec3&,
                                                         const LaneOptics<kSpectralLanes>&,
                                                         PixelRng&, double) const;
template LanesN<kRgbLanes> PathIntegrator::radiance(const EmbreeScene&, const Vec3&, const Vec3&,
                                                    const LaneOptics<kRgbLanes>&, PixelRng&) const;
template LanesN<kSpectralLanes> PathIntegrator::radiance(const EmbreeScene&, const Vec3&,
                                                         const Vec3&,
                                                         const LaneOptics<kSpectralLanes>&,
                                                         PixelRng&) const;

} // namespace chromasim::render::detail
