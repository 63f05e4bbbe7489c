#include "render/shading.hpp"

#include <cmath>
#include <limits>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <string>

namespace chromasim::render::detail {

namespace {

constexpr double kInvPi = 1.0 / std::numbers::pi;

[[noreturn]] void reject(const std::string& name, const std::string& value,
                         const std::string& allowed) {
    throw std::invalid_argument("OpticsParams: " + name + " = " + value +
                                " is invalid; allowed: " + allowed);
}

void require_in(const std::string& name, double value, double lo, double hi,
                const std::string& allowed) {
    if (!(value >= lo && value <= hi)) reject(name, std::to_string(value), allowed);
}

void require_in(const std::string& name, const Vec3& value, double lo, double hi,
                const std::string& allowed) {
    if (!value.allFinite() || value.minCoeff() < lo || value.maxCoeff() > hi) {
        std::ostringstream text;
        text << "(" << value.x() << ", " << value.y() << ", " << value.z() << ")";
        reject(name, text.str(), allowed);
    }
}

const OpticsParams& validated(const OpticsParams& o) {
    constexpr double big = std::numeric_limits<double>::max();
    require_in("coating_albedo", o.coating_albedo, 0.0, 1.0, "each channel in [0, 1]");
    require_in("inner_marker_absorption_per_mm", o.inner_marker_absorption_per_mm, 0.0, big,
               "each channel finite and >= 0 (1/mm)");
    require_in("outer_marker_absorption_per_mm", o.outer_marker_absorption_per_mm, 0.0, big,
               "each channel finite and >= 0 (1/mm)");
    require_in("outer_marker_albedo", o.outer_marker_albedo, 0.0, 1.0, "each channel in [0, 1]");
    require_in("outer_marker_scatter_fraction", o.outer_marker_scatter_fraction, 0.0, 1.0,
               "[0, 1]");
    require_in("marker_thickness_mm", o.marker_thickness_mm, 0.0, big, "finite, >= 0 (mm)");
    if (o.led_count < 1) reject("led_count", std::to_string(o.led_count), "integer >= 1");
    require_in("led_ring_radius_mm", o.led_ring_radius_mm, 0.0, big, "finite, >= 0 (mm)");
    require_in("led_z_mm", o.led_z_mm, -big, big, "finite (mm)");
    require_in("led_rgb", o.led_rgb, 0.0, big, "each channel finite and >= 0");
    require_in("exposure", o.exposure, std::numeric_limits<double>::min(), big, "finite, > 0");
    return o;
}

std::vector<Vec3> led_ring(const OpticsParams& optics) {
    std::vector<Vec3> leds;
    for (int k = 0; k < optics.led_count; ++k) {
        const double phi = 2.0 * std::numbers::pi * k / optics.led_count;
        leds.emplace_back(optics.led_ring_radius_mm * std::cos(phi),
                          optics.led_ring_radius_mm * std::sin(phi), optics.led_z_mm);
    }
    return leds;
}

/// The unit normal turned to face against `direction` (towards where the ray came from).
Vec3 facing(const Vec3& normal, const Vec3& direction) {
    return normal.dot(direction) > 0.0 ? Vec3(-normal) : normal;
}

} // namespace

double marker_path_mm(double thickness_mm, double cos_incidence) {
    const double cos_abs = std::abs(cos_incidence);
    // Written as a comparison, not a division, so that cos = 0 never makes an infinity.
    if (thickness_mm >= kMaxMarkerPath_mm * cos_abs) return kMaxMarkerPath_mm;
    return thickness_mm / cos_abs;
}

ShadingModel::ShadingModel(const OpticsParams& optics)
    : m_optics(validated(optics)), m_led_positions_mm(led_ring(optics)) {}

Rgb ShadingModel::inner_marker_filter(double cos_incidence) const {
    const double path_mm = marker_path_mm(m_optics.marker_thickness_mm, cos_incidence);
    return (-m_optics.inner_marker_absorption_per_mm.array() * path_mm).exp();
}

Rgb ShadingModel::outer_marker_transmission(double cos_incidence) const {
    const double path_mm = marker_path_mm(m_optics.marker_thickness_mm, cos_incidence);
    return (1.0 - m_optics.outer_marker_scatter_fraction) *
           (-m_optics.outer_marker_absorption_per_mm.array() * path_mm).exp();
}

Rgb ShadingModel::led_irradiance(const Vec3& led_mm, const Vec3& p_mm, const Vec3& normal) const {
    const Vec3 to_p = p_mm - led_mm;
    const double d2 = to_p.squaredNorm();
    if (!(d2 > 0.0)) return Rgb::Zero();
    const Vec3 w = to_p / std::sqrt(d2);
    const double cos_emit = w.z();             // Lambertian emission about +z
    const double cos_surface = -w.dot(normal); // light arrives against the normal
    if (cos_emit <= 0.0 || cos_surface <= 0.0) return Rgb::Zero();
    return m_optics.led_rgb.array() * (cos_emit * cos_surface / d2);
}

Rgb ShadingModel::unoccluded_irradiance(const Vec3& p_mm, const Vec3& normal) const {
    Rgb total = Rgb::Zero();
    for (const Vec3& led : m_led_positions_mm)
        total += led_irradiance(led, p_mm, normal);
    return total;
}

Rgb ShadingModel::irradiance(const EmbreeScene& scene, const Vec3& p_mm, const Vec3& normal) const {
    Rgb total = Rgb::Zero();
    for (const Vec3& led : m_led_positions_mm) {
        const Rgb direct = led_irradiance(led, p_mm, normal);
        if ((direct > 0.0).any()) total += direct * transmittance(scene, led, p_mm);
    }
    return total;
}

Rgb ShadingModel::transmittance(const EmbreeScene& scene, const Vec3& from_mm,
                                const Vec3& to_mm) const {
    const Vec3 segment = to_mm - from_mm;
    const double length_mm = segment.norm();
    const double tfar_mm = length_mm - kHitGap_mm;
    if (!(tfar_mm > 0.0)) return Rgb::Ones();
    const Vec3 w = segment / length_mm;
    Rgb result = Rgb::Ones();
    double tnear_mm = 0.0;
    for (int i = 0; i < kMaxHits; ++i) {
        const RayHit hit = scene.closest_hit(from_mm, w, tnear_mm, tfar_mm);
        const double cos_incidence = hit.normal.dot(w);
        switch (hit.kind) {
        case SurfaceKind::none:
            return result;
        case SurfaceKind::coating:
            return Rgb::Zero();
        case SurfaceKind::inner_marker:
            result *= inner_marker_filter(cos_incidence);
            break;
        case SurfaceKind::outer_marker:
            result *= outer_marker_transmission(cos_incidence);
            break;
        }
        tnear_mm = hit.t_mm + kHitGap_mm;
    }
    return Rgb::Zero(); // more than kMaxHits surfaces in the way: treat as blocked
}

Rgb ShadingModel::radiance(const EmbreeScene& scene, const Vec3& origin_mm,
                           const Vec3& direction) const {
    constexpr double inf = std::numeric_limits<double>::infinity();
    Rgb radiance = Rgb::Zero();
    Rgb throughput = Rgb::Ones();
    double tnear_mm = 0.0;
    for (int i = 0; i < kMaxHits; ++i) {
        // Find the next surface; a miss sees nothing (black).
        const RayHit hit = scene.closest_hit(origin_mm, direction, tnear_mm, inf);
        if (!hit.hit()) break;
        // Shade with the geometric normal turned towards the camera: winding is irrelevant.
        const Vec3 p_mm = origin_mm + hit.t_mm * direction;
        const Vec3 normal = facing(hit.normal, direction);
        const double cos_view = normal.dot(direction);
        switch (hit.kind) {
        case SurfaceKind::coating: // Lambertian background: the path ends here
            return radiance + throughput * m_optics.coating_albedo.array() * kInvPi *
                                  irradiance(scene, p_mm, normal);
        case SurfaceKind::inner_marker: // translucent magenta filter
            throughput *= inner_marker_filter(cos_view);
            break;
        case SurfaceKind::outer_marker: // scatters a share back, filters the rest
            radiance += throughput * m_optics.outer_marker_scatter_fraction *
                        m_optics.outer_marker_albedo.array() * kInvPi *
                        irradiance(scene, p_mm, normal);
            throughput *= outer_marker_transmission(cos_view);
            break;
        case SurfaceKind::none:
            break;
        }
        // Continue just past this surface.
        tnear_mm = hit.t_mm + kHitGap_mm;
    }
    return radiance;
}

} // namespace chromasim::render::detail
