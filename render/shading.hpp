#pragma once
/// Per-ray light transport of the coarse render stage: marker filters, LED irradiance with
/// shadow transmittance, and the camera-ray loop. The model and its assumptions are written
/// out at the top of render/renderer.cpp.
#include "render/embree_scene.hpp"
#include "render/scene_data.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace chromasim::render::detail {

/// Linear RGB triple (radiance, irradiance, transmittance or albedo).
using Rgb = Eigen::Array3d;

/// Most surfaces a camera or shadow ray is followed through; a ray still going after that
/// many carries no more light (in practice a ray crosses 2 marker volumes, 4 faces, and
/// meets the coating).
inline constexpr int kMaxHits = 16;
/// Gap left after a hit before searching for the next one, mm: far above float round-off at
/// dome scale (about 1e-6 mm), far below the 0.25 mm between marker discs and the coating.
inline constexpr double kHitGap_mm = 1e-3;

/// Lanes of a value carried along a ray: linear R, G, B and an unused lane in RGB mode
/// (kRgbLanes), or kSpectralLanes wavelengths in spectral mode (render/spectrum.hpp). The
/// preview's rays do not depend on the wavelength, so more lanes cost arithmetic,
/// not rays: 16 stratified wavelengths per sample take the spectral noise down to about the
/// RGB mode's. The fast integrator carries RenderSettings::fast_wavelengths of them, by
/// default kFastSpectralLanes from 2 samples per pixel on: half the arithmetic for a little
/// more colour noise.
inline constexpr int kRgbLanes = 4;
inline constexpr int kSpectralLanes = 16;
inline constexpr int kFastSpectralLanes = 8;
static_assert(kFastSpectralLanes != kRgbLanes && kFastSpectralLanes != kSpectralLanes,
              "the renderer tells the lane widths apart by their count");
template <int N> using LanesN = Eigen::Array<double, N, 1>;
using Lanes = LanesN<kSpectralLanes>;
using RgbLanes = LanesN<kRgbLanes>;

/// The optical properties of one sample, per lane: albedos, absorption coefficients (1/mm) and
/// the emission of every LED.
template <int N> struct LaneOptics {
    LanesN<N> coating_albedo, inner_absorption_per_mm, outer_absorption_per_mm, outer_albedo, led;
};

/// The lanes of a hero sample (wavelengths `lambda_nm`): the spectra at those wavelengths, the
/// LED's emission times `led_scale`.
template <int N>
LaneOptics<N> spectral_lanes(const SensorSpectra& spectra, const LanesN<N>& lambda_nm,
                             double led_scale) {
    return {spectra.coating_albedo.at_each(lambda_nm),
            spectra.inner_marker_absorption_per_mm.at_each(lambda_nm),
            spectra.outer_marker_absorption_per_mm.at_each(lambda_nm),
            spectra.outer_marker_albedo.at_each(lambda_nm),
            led_scale * spectra.camera.led_emission().at_each(lambda_nm)};
}

/// Where a ray entered the marker volumes it is inside (inner, outer; mm along the ray): the
/// marker meshes are closed, their triangles facing out of the volume, so each hit is an entry
/// (the ray against the face's normal) or an exit, and the Beer-Lambert path is the distance
/// between them. A ray that starts inside a volume has entered it at its own start; a segment
/// that ends inside one (a shadow ray's end) counts up to its end (`open_path`).
///
/// Faces closer than kHitGap_mm (a marker squeezed to nearly nothing) hide each other: the
/// exit is never seen. An entry left open when the ray meets the coating or enters another
/// marker of the same layer is such a lost exit and absorbs nothing (at most kHitGap_mm of
/// path is missed); the outer markers' faces stay 1 % of the layer (5 um) off the coating.
class MarkerPath {
public:
    explicit MarkerPath(double start_mm) : m_start_mm(start_mm) {}

    /// Records a hit of a marker face (`outer` layer or not) at t_mm; returns the path length
    /// just completed inside that volume on an exit, or a negative number on an entry.
    double cross(bool outer, double t_mm, bool entering) {
        const int layer = outer ? 1 : 0;
        double& entry = m_entry_mm[layer];
        const bool first = !m_seen[layer];
        m_seen[layer] = true;
        if (entering) {
            entry = t_mm;
            return -1.0;
        }
        // An exit with no entry: the ray started inside (the layer's first face), or the entry
        // hid behind a face closer than the gap (nothing to count).
        const double from = !std::isnan(entry) ? entry : first ? m_start_mm : t_mm;
        entry = std::numeric_limits<double>::quiet_NaN();
        return std::max(0.0, t_mm - from);
    }
    /// Path inside a volume still open at t_mm (a ray stopped by the coating inside a marker).
    double open_path(bool outer, double t_mm) const {
        const double entry = m_entry_mm[outer ? 1 : 0];
        return std::isnan(entry) ? 0.0 : std::max(0.0, t_mm - entry);
    }

private:
    double m_start_mm;
    bool m_seen[2] = {false, false};
    double m_entry_mm[2] = {std::numeric_limits<double>::quiet_NaN(),
                            std::numeric_limits<double>::quiet_NaN()};
};

/// The optical model of one sensor: LED ring, coating and the two marker layers.
class ShadingModel {
public:
    /// Throws std::invalid_argument when a parameter is outside its allowed range (the message
    /// names the parameter, its value and the range).
    explicit ShadingModel(const OpticsParams& optics);

    /// The RGB mode's lanes: OpticsParams' linear RGB values, the fourth lane 0.
    LaneOptics<kRgbLanes> rgb_lanes() const;

    /// Radiance seen from `origin_mm` looking along the unit vector `direction`, in LED
    /// intensity units per mm^2 per sr, per lane. Follows the ray through the marker volumes to
    /// the coating.
    template <int N>
    LanesN<N> radiance(const EmbreeScene& scene, const Vec3& origin_mm, const Vec3& direction,
                       const LaneOptics<N>& lanes) const;
    /// RGB mode.
    Rgb radiance(const EmbreeScene& scene, const Vec3& origin_mm, const Vec3& direction) const;

    /// Irradiance at `p_mm` on a surface with unit normal `normal` (pointing to the side that
    /// is lit and seen), summed over the LEDs, each attenuated by `transmittance`.
    template <int N>
    LanesN<N> irradiance(const EmbreeScene& scene, const Vec3& p_mm, const Vec3& normal,
                         const LaneOptics<N>& lanes) const;
    Rgb irradiance(const EmbreeScene& scene, const Vec3& p_mm, const Vec3& normal) const;

    /// Sum over the LEDs of gain cos_emit cos_surface / d^2 at p (1/mm^2), nothing in the way:
    /// times an LED's emission it is the analytic irradiance used for auto exposure.
    double unoccluded_geometry(const Vec3& p_mm, const Vec3& normal) const;
    /// RGB: led_rgb times unoccluded_geometry.
    Rgb unoccluded_irradiance(const Vec3& p_mm, const Vec3& normal) const;

    /// Transmittance of the open segment from `from_mm` to `to_mm` (stops kHitGap_mm short of
    /// `to_mm`, so the surface at `to_mm` does not shadow itself): Beer-Lambert over the path
    /// inside each marker volume, (1 - scatter_fraction) per outer marker entered; zero if the
    /// coating is in the way.
    /// `tnear_mm` > 0 skips the start of the segment (a start on a surface). The inner surface
    /// (the air / clear-layer interface) does not attenuate: callers that refract handle it.
    /// A segment across the frame (crosses_mount) is blocked, unless `frame` is false (the
    /// fast integrator's shadow rays where it takes the frame's share off apart).
    template <int N>
    LanesN<N> transmittance(const EmbreeScene& scene, const Vec3& from_mm, const Vec3& to_mm,
                            const LaneOptics<N>& lanes, double tnear_mm = 0.0,
                            bool frame = true) const;
    Rgb transmittance(const EmbreeScene& scene, const Vec3& from_mm, const Vec3& to_mm) const;

    /// Beer-Lambert transmittance exp(-absorption * path_mm) of `path_mm` inside a marker of
    /// layer `outer` (false: the inner, magenta filter; true: the outer, cyan dye).
    template <int N>
    LanesN<N> marker_absorption(const LaneOptics<N>& lanes, bool outer, double path_mm) const;

    /// True if the segment origin + t * direction, t in (t0, t1), is blocked by the mount:
    /// it crosses the rim plane z = 0 on the frame (at a radius >= frame_inner_radius_mm), or
    /// it enters the lens barrel (below the plane, within lens_radius_mm of the axis). A
    /// segment that starts on or below the plane and goes down does not cross the plane: the
    /// light cache's paths from the coating's rim vertices (z = -4e-5 mm) reach the LEDs under
    /// the frame that way.
    bool crosses_mount(const Vec3& origin_mm, const Vec3& direction, double t0, double t1) const {
        return crosses_rim_plane(origin_mm, direction, t0, t1) ||
               crosses_lens(origin_mm, direction, t0, t1);
    }

    /// LED positions, mm: led_count points on the ring, the first on the +x axis.
    const std::vector<Vec3>& led_positions_mm() const { return m_led_positions_mm; }
    /// LED k's intensity relative to led_rgb (OpticsParams::led_gain; 1 where that is empty).
    double led_gain(int k) const { return m_led_gain[std::size_t(k)]; }
    const OpticsParams& optics() const { return m_optics; }

private:
    bool crosses_rim_plane(const Vec3& origin_mm, const Vec3& direction, double t0,
                           double t1) const {
        if (direction.z() == 0.0) return false;
        const double t = -origin_mm.z() / direction.z();
        if (!(t > t0 && t < t1)) return false;
        return (origin_mm + t * direction).head<2>().squaredNorm() >=
               m_optics.frame_inner_radius_mm * m_optics.frame_inner_radius_mm;
    }
    bool crosses_lens(const Vec3& origin_mm, const Vec3& direction, double t0, double t1) const;
    /// cos_emit cos_surface / d^2 of one LED before any occlusion, or zero if it faces away.
    double led_geometry(const Vec3& led_mm, const Vec3& p_mm, const Vec3& normal) const;

    OpticsParams m_optics;
    std::vector<Vec3> m_led_positions_mm;
    std::vector<double> m_led_gain;
};

} // namespace chromasim::render::detail
