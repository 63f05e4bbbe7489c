#pragma once
/// The reference light transport: unbiased spectral path tracing of the dome.
///
/// Scene. The camera and the LEDs sit in the air cavity; the inner surface (when the frame has
/// one) is a smooth dielectric boundary of index OpticsParams::refractive_index with
/// interpolated vertex normals; the clear layers are index-matched among themselves, so the
/// marker volumes only absorb (Beer-Lambert) and the outer markers scatter; the coating is a
/// Lambertian reflector; the LEDs are Lambertian rectangles facing +z (black on their back).
/// Rays that leave the dome through its open base and miss the LEDs are absorbed (the board
/// and the frame are black).
///
/// Events along a path (all lanes share the path: no dispersion, so the wavelengths only
/// change the weights):
///   - inner surface: reflect with Fresnel's probability F, else refract (Snell);
///   - marker faces: Beer-Lambert over the chord inside (MarkerPath); entering an outer marker
///     scatters diffusely back with probability outer_marker_scatter_fraction and weight
///     outer_albedo, else passes;
///   - coating: Lambertian bounce, weight coating_albedo;
///   - LED (front): adds its radiance, weighted by MIS when a diffuse vertex could have
///     reached it by next-event estimation; the path ends.
/// Russian roulette from the third bounce on (survival = largest lane throughput), at most
/// kMaxBounces bounces.
///
/// Next-event estimation at each diffuse vertex p: one point l drawn uniformly on one LED
/// drawn uniformly. Without an inner surface the connection is a straight shadow ray. With
/// one, the light reaching p from l is refracted once: a Newton solve on the direction w
/// leaving p finds the path p -> x -> l obeying Snell's law at the (shading-normal) interface
/// point x (manifold next-event estimation, Hanika et al. 2015, for one refraction); its
/// solid-angle density is pdf_area * |det dl/dw| with the 2 x 2 Jacobian of the map w -> l
/// taken by central differences on x's triangle. Weight: (1 - F) times the markers'
/// transmittance on p -> x, zero if anything lies between x and l. Both strategies are
/// combined with the power heuristic on (pdf_nee, cos/pi (1 - F)); a path MNEE cannot make
/// (a reflection at the interface between p and the LED, two crossings) gets weight 1 from
/// BSDF sampling.
#include "render/embree_scene.hpp"
#include "render/sampling.hpp"
#include "render/shading.hpp"

#include <optional>

namespace chromasim::render::detail {

/// Most bounces of a path (Russian roulette ends nearly all paths long before).
inline constexpr int kMaxBounces = 256;

/// One refracted connection p -> x -> l found by `PathIntegrator::connect`.
struct InterfaceConnection {
    Vec3 direction;               ///< unit direction leaving p towards x
    Vec3 x_mm;                    ///< the point on the inner surface
    double fresnel_transmittance; ///< 1 - F at x
    double jacobian_mm2_per_sr;   ///< |det dl / dw|: LED-plane area per solid angle at p
};

class PathIntegrator {
public:
    /// Keeps a reference to `shading` (optics, marker absorption, transmittance).
    /// `next_event` false: BSDF sampling alone (every LED hit weighs 1), the unbiased but
    /// noisy estimator the tests compare next-event estimation with.
    explicit PathIntegrator(const ShadingModel& shading, bool next_event = true);

    /// Radiance along the camera ray (origin, unit direction), per lane, in the direct model's
    /// units (LED intensity per mm^2 per sr).
    template <int N>
    LanesN<N> radiance(const EmbreeScene& scene, const Vec3& origin_mm, const Vec3& direction,
                       const LaneOptics<N>& lanes, PixelRng& rng) const;

    /// The refracted path from `p_mm` (inside the clear layers) to `led_point_mm` (in the
    /// cavity) through the inner surface, or nullopt if the Newton solve fails (no such path
    /// through the surface the first ray meets, total internal reflection, no convergence).
    /// Does not check occlusion. Pre-condition: scene.has_interface().
    std::optional<InterfaceConnection> connect(const EmbreeScene& scene, const Vec3& p_mm,
                                               const Vec3& led_point_mm) const;

    /// Where the ray from `p_mm` along `direction` meets the LED plane after refracting at the
    /// interface triangle `prim` (the plane of the triangle, its normals interpolated and
    /// extrapolated linearly), with |det dl/dw| there; nullopt on total internal reflection or
    /// when the refracted ray does not go down to the plane.
    std::optional<InterfaceConnection> through_triangle(const EmbreeScene& scene,
                                                        std::uint32_t prim, const Vec3& p_mm,
                                                        const Vec3& direction,
                                                        Vec3* led_plane_point_mm = nullptr) const;

    /// Number of LEDs, their area (mm^2), and the LED rectangle hit by the segment, if any.
    int led_count() const { return int(m_led_centres.size()); }
    double led_area_mm2() const { return m_led_area_mm2; }
    /// Closest LED crossing of origin + t * direction with t in (tnear, tfar): t, and whether
    /// the ray meets its emitting (+z) face.
    std::optional<std::pair<double, bool>> led_hit(const Vec3& origin_mm, const Vec3& direction,
                                                   double tnear_mm, double tfar_mm) const;
    /// A point on LED `k` from two uniforms.
    Vec3 led_point(int k, double u1, double u2) const;

private:
    template <int N>
    LanesN<N> next_event(const EmbreeScene& scene, const Vec3& p_mm, const Vec3& normal,
                         const LaneOptics<N>& lanes, PixelRng& rng) const;

    const ShadingModel& m_shading;
    bool m_next_event;
    double m_eta;                     ///< refractive index of the clear layers
    std::vector<Vec3> m_led_centres;  ///< on the ring, mm
    std::vector<Vec3> m_led_tangents; ///< unit, along the ring (width)
    std::vector<Vec3> m_led_radials;  ///< unit, outwards (height)
    double m_led_area_mm2;
};

} // namespace chromasim::render::detail
