#include "render/shading.hpp"

#include "render/sampling.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <string>

namespace chromasim::render::detail {

namespace {

constexpr double kInvPi = 1.0 / std::numbers::pi;
/// The surfaces the preview's rays meet: all but the inner surface, which it does not
/// refract at (it sees through it), so its queries leave it out.
constexpr unsigned kSeenThroughInterface = kAllKinds & ~kind_bit(SurfaceKind::inner_surface);

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
    if (o.led_count < 1) reject("led_count", std::to_string(o.led_count), "integer >= 1");
    require_in("led_ring_radius_mm", o.led_ring_radius_mm, 0.0, big, "finite, >= 0 (mm)");
    require_in("led_z_mm", o.led_z_mm, -big, big, "finite (mm)");
    require_in("led_rgb", o.led_rgb, 0.0, big, "each channel finite and >= 0");
    if (!o.led_gain.empty() && int(o.led_gain.size()) != o.led_count)
        reject("led_gain", std::to_string(o.led_gain.size()) + " values",
               "empty or one value per LED (" + std::to_string(o.led_count) + ")");
    for (const double g : o.led_gain)
        if (!(g >= 0.0 && g <= big)) reject("led_gain", std::to_string(g), "finite, >= 0");
    require_in("led_width_mm", o.led_width_mm, std::numeric_limits<double>::min(), big,
               "finite, > 0 (mm)");
    require_in("led_height_mm", o.led_height_mm, std::numeric_limits<double>::min(), big,
               "finite, > 0 (mm)");
    require_in("refractive_index", o.refractive_index, 1.0, 4.0, "[1, 4]");
    require_in("frame_inner_radius_mm", o.frame_inner_radius_mm, 0.0, big, "finite, >= 0 (mm)");
    require_in("lens_radius_mm", o.lens_radius_mm, 0.0, big, "finite, >= 0 (mm)");
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

} // namespace

ShadingModel::ShadingModel(const OpticsParams& optics)
    : m_optics(validated(optics)), m_led_positions_mm(led_ring(optics)),
      m_led_gain(optics.led_gain.empty() ? std::vector<double>(std::size_t(optics.led_count), 1.0)
                                         : optics.led_gain) {}

LaneOptics<kRgbLanes> ShadingModel::rgb_lanes() const {
    auto lanes = [](const Vec3& v) {
        RgbLanes l = RgbLanes::Zero();
        l.head<3>() = v.array();
        return l;
    };
    return {lanes(m_optics.coating_albedo), lanes(m_optics.inner_marker_absorption_per_mm),
            lanes(m_optics.outer_marker_absorption_per_mm), lanes(m_optics.outer_marker_albedo),
            lanes(m_optics.led_rgb)};
}

template <int N>
LanesN<N> ShadingModel::marker_absorption(const LaneOptics<N>& lanes, bool outer,
                                          double path_mm) const {
    return (-(outer ? lanes.outer_absorption_per_mm : lanes.inner_absorption_per_mm) * path_mm)
        .exp();
}

bool ShadingModel::crosses_lens(const Vec3& origin_mm, const Vec3& direction, double t0,
                                double t1) const {
    const double R = m_optics.lens_radius_mm;
    if (!(R > 0.0)) return false;
    // The part of the segment below the rim plane...
    if (direction.z() > 0.0)
        t1 = std::min(t1, -origin_mm.z() / direction.z());
    else if (direction.z() < 0.0)
        t0 = std::max(t0, -origin_mm.z() / direction.z());
    else if (!(origin_mm.z() < 0.0))
        return false;
    if (!(t0 < t1)) return false;
    // ...comes closest to the axis at t, within [t0, t1].
    const Eigen::Vector2d o = origin_mm.head<2>(), d = direction.head<2>();
    const double dd = d.squaredNorm();
    const double t = dd > 0.0 ? std::clamp(-o.dot(d) / dd, t0, t1) : t0;
    return (o + t * d).squaredNorm() < R * R;
}

double ShadingModel::led_geometry(const Vec3& led_mm, const Vec3& p_mm, const Vec3& normal) const {
    const Vec3 to_p = p_mm - led_mm;
    const double d2 = to_p.squaredNorm();
    if (!(d2 > 0.0)) return 0.0;
    const Vec3 w = to_p / std::sqrt(d2);
    const double cos_emit = w.z();             // Lambertian emission about +z
    const double cos_surface = -w.dot(normal); // light arrives against the normal
    if (cos_emit <= 0.0 || cos_surface <= 0.0) return 0.0;
    return cos_emit * cos_surface / d2;
}

double ShadingModel::unoccluded_geometry(const Vec3& p_mm, const Vec3& normal) const {
    double total = 0.0;
    for (std::size_t k = 0; k < m_led_positions_mm.size(); ++k)
        total += m_led_gain[k] * led_geometry(m_led_positions_mm[k], p_mm, normal);
    return total;
}

Rgb ShadingModel::unoccluded_irradiance(const Vec3& p_mm, const Vec3& normal) const {
    return m_optics.led_rgb.array() * unoccluded_geometry(p_mm, normal);
}

template <int N>
LanesN<N> ShadingModel::irradiance(const EmbreeScene& scene, const Vec3& p_mm, const Vec3& normal,
                                   const LaneOptics<N>& lanes) const {
    LanesN<N> total = LanesN<N>::Zero();
    for (std::size_t k = 0; k < m_led_positions_mm.size(); ++k) {
        const Vec3& led = m_led_positions_mm[k];
        const double geometry = m_led_gain[k] * led_geometry(led, p_mm, normal);
        if (geometry > 0.0) total += geometry * transmittance(scene, led, p_mm, lanes);
    }
    return lanes.led * total;
}

Rgb ShadingModel::irradiance(const EmbreeScene& scene, const Vec3& p_mm, const Vec3& normal) const {
    return irradiance(scene, p_mm, normal, rgb_lanes()).head<3>();
}

template <int N>
LanesN<N> ShadingModel::transmittance(const EmbreeScene& scene, const Vec3& from_mm,
                                      const Vec3& to_mm, const LaneOptics<N>& lanes,
                                      double tnear_mm, bool frame) const {
    const Vec3 segment = to_mm - from_mm;
    const double length_mm = segment.norm();
    const double tfar_mm = length_mm - kHitGap_mm;
    if (!(tfar_mm > tnear_mm)) return LanesN<N>::Ones();
    const Vec3 w = segment / length_mm;
    if (frame && crosses_mount(from_mm, w, tnear_mm, tfar_mm)) return LanesN<N>::Zero();
    LanesN<N> result = LanesN<N>::Ones();
    MarkerPath path(tnear_mm);
    RayHits hits(scene, from_mm, w, tnear_mm, tfar_mm, kSeenThroughInterface);
    for (int i = 0; i < kMaxHits; ++i) {
        const RayHit hit = hits.next(tnear_mm);
        const double cos_incidence = hit.normal.dot(w);
        switch (hit.kind) {
        case SurfaceKind::inner_surface: // not in the query
            break;
        case SurfaceKind::none: { // the end of the segment, maybe still inside a marker
            for (const bool outer : {false, true})
                if (const double open = path.open_path(outer, tfar_mm); open > 0.0)
                    result *= marker_absorption(lanes, outer, open);
            return result;
        }
        case SurfaceKind::coating:
            return LanesN<N>::Zero();
        case SurfaceKind::inner_marker:
        case SurfaceKind::outer_marker: {
            if (cos_incidence == 0.0) break; // degenerate or edge-on face: no entry, no exit
            const bool outer = hit.kind == SurfaceKind::outer_marker;
            const double inside = path.cross(outer, hit.t_mm, cos_incidence < 0.0);
            if (inside >= 0.0)
                result *= marker_absorption(lanes, outer, inside);
            else if (outer)
                result *= 1.0 - m_optics.outer_marker_scatter_fraction;
            break;
        }
        }
        tnear_mm = hit.t_mm + kHitGap_mm;
    }
    return LanesN<N>::Zero(); // more than kMaxHits surfaces in the way: treat as blocked
}

Rgb ShadingModel::transmittance(const EmbreeScene& scene, const Vec3& from_mm,
                                const Vec3& to_mm) const {
    return transmittance(scene, from_mm, to_mm, rgb_lanes()).head<3>();
}

template <int N>
LanesN<N> ShadingModel::radiance(const EmbreeScene& scene, const Vec3& origin_mm,
                                 const Vec3& direction, const LaneOptics<N>& lanes) const {
    constexpr double inf = std::numeric_limits<double>::infinity();
    LanesN<N> radiance = LanesN<N>::Zero();
    LanesN<N> throughput = LanesN<N>::Ones();
    MarkerPath path(0.0);
    double tnear_mm = 0.0;
    RayHits hits(scene, origin_mm, direction, 0.0, inf, kSeenThroughInterface);
    for (int i = 0; i < kMaxHits; ++i) {
        // Find the next surface; a miss sees nothing (black).
        const RayHit hit = hits.next(tnear_mm);
        if (!hit.hit()) break;
        // Shade with the geometric normal turned towards the camera: the coating's winding is
        // irrelevant; a marker face's winding says whether the ray enters or leaves.
        const Vec3 p_mm = origin_mm + hit.t_mm * direction;
        const Vec3 normal = facing(hit.normal, direction);
        const double cos_incidence = hit.normal.dot(direction);
        switch (hit.kind) {
        case SurfaceKind::coating: // Lambertian background: the path ends here (an entry still
                                   // open here lost its exit: MarkerPath)
            return radiance + throughput * lanes.coating_albedo * kInvPi *
                                  irradiance(scene, p_mm, normal, lanes);
        case SurfaceKind::inner_marker: // translucent magenta filter
        case SurfaceKind::outer_marker: {
            if (cos_incidence == 0.0) break; // degenerate or edge-on face: no entry, no exit
            const bool outer = hit.kind == SurfaceKind::outer_marker;
            const double inside = path.cross(outer, hit.t_mm, cos_incidence < 0.0);
            if (inside >= 0.0) {
                throughput *= marker_absorption(lanes, outer, inside);
            } else if (outer) { // entering the cyan dye: it scatters a share back
                radiance += throughput * m_optics.outer_marker_scatter_fraction *
                            lanes.outer_albedo * kInvPi * irradiance(scene, p_mm, normal, lanes);
                throughput *= 1.0 - m_optics.outer_marker_scatter_fraction;
            }
            break;
        }
        case SurfaceKind::inner_surface: // not in the query
        case SurfaceKind::none:
            break;
        }
        // Continue just past this surface.
        tnear_mm = hit.t_mm + kHitGap_mm;
    }
    return radiance;
}

Rgb ShadingModel::radiance(const EmbreeScene& scene, const Vec3& origin_mm,
                           const Vec3& direction) const {
    return radiance(scene, origin_mm, direction, rgb_lanes()).head<3>();
}

// The lane widths the renderer uses: RGB, 16 wavelengths ...
template LanesN<kRgbLanes> ShadingModel::radiance(const EmbreeScene&, const Vec3&, const Vec3&,
                                                  const LaneOptics<kRgbLanes>&) const;
template LanesN<kSpectralLanes> ShadingModel::radiance(const EmbreeScene&, const Vec3&, const Vec3&,
                                                       const LaneOptics<kSpectralLanes>&) const;
template LanesN<kRgbLanes> ShadingModel::transmittance(const EmbreeScene&, const Vec3&, const Vec3&,
                                                       const LaneOptics<kRgbLanes>&, double,
                                                       bool) const;
template LanesN<kSpectralLanes> ShadingModel::transmittance(const EmbreeScene&, const Vec3&,
                                                            const Vec3&,
                                                            const LaneOptics<kSpectralLanes>&,
                                                            double, bool) const;

// ... and the fast integrator's spectral lanes.
template LanesN<kFastSpectralLanes>
ShadingModel::transmittance(const EmbreeScene&, const Vec3&, const Vec3&,
                            const LaneOptics<kFastSpectralLanes>&, double, bool) const;
template LanesN<kFastSpectralLanes>
ShadingModel::marker_absorption(const LaneOptics<kFastSpectralLanes>&, bool, double) const;

template LanesN<kRgbLanes> ShadingModel::marker_absorption(const LaneOptics<kRgbLanes>&, bool,
                                                           double) const;
template LanesN<kSpectralLanes> ShadingModel::marker_absorption(const LaneOptics<kSpectralLanes>&,
                                                                bool, double) const;

} // namespace chromasim::render::detail
