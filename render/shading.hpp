#pragma once
/// Per-ray light transport of the coarse render stage: marker filters, LED irradiance with
/// shadow transmittance, and the camera-ray loop. The model and its assumptions are written
/// out at the top of render/renderer.cpp.
#include "render/embree_scene.hpp"
#include "render/scene_data.hpp"

#include <Eigen/Core>

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

/// The optical model of one sensor: LED ring, coating and the two marker layers.
class ShadingModel {
public:
    /// Throws std::invalid_argument when a parameter is outside its allowed range (the message
    /// names the parameter, its value and the range).
    explicit ShadingModel(const OpticsParams& optics);

    /// Radiance seen from `origin_mm` looking along the unit vector `direction`, in LED
    /// intensity units per mm^2 per sr. Follows the ray through markers to the coating.
    Rgb radiance(const EmbreeScene& scene, const Vec3& origin_mm, const Vec3& direction) const;

    /// Irradiance at `p_mm` on a surface with unit normal `normal` (pointing to the side that
    /// is lit and seen), summed over the LEDs, each attenuated by `transmittance`.
    Rgb irradiance(const EmbreeScene& scene, const Vec3& p_mm, const Vec3& normal) const;

    /// Same, with nothing in the way: the analytic reference used for auto exposure.
    Rgb unoccluded_irradiance(const Vec3& p_mm, const Vec3& normal) const;

    /// Transmittance of the open segment from `from_mm` to `to_mm` (stops kHitGap_mm short of
    /// `to_mm`, so the surface at `to_mm` does not shadow itself): product of the marker
    /// transmissions crossed; zero if the coating is in the way.
    Rgb transmittance(const EmbreeScene& scene, const Vec3& from_mm, const Vec3& to_mm) const;

    /// Beer-Lambert transmittance exp(-absorption * path_mm) of `path_mm` inside a marker of
    /// layer `outer` (false: the inner, magenta filter; true: the outer, cyan dye).
    Rgb marker_absorption(bool outer, double path_mm) const;

    /// LED positions, mm: led_count points on the ring, the first on the +x axis.
    const std::vector<Vec3>& led_positions_mm() const { return m_led_positions_mm; }
    const OpticsParams& optics() const { return m_optics; }

private:
    /// Contribution of one LED before any occlusion, or zero if it faces away.
    Rgb led_irradiance(const Vec3& led_mm, const Vec3& p_mm, const Vec3& normal) const;

    OpticsParams m_optics;
    std::vector<Vec3> m_led_positions_mm;
};

} // namespace chromasim::render::detail
