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
/// one, the light reaching p from l passes the surface along a chain of specular events (Chain):
/// refracted once, or refracted and then reflected off the surface from the cavity side. For
/// each chain a Newton solve on the direction w leaving p finds the path obeying Snell's law
/// and the mirror law at the (shading-normal) surface points (manifold next-event estimation,
/// Hanika et al. 2015); it starts from the same chain on the sphere through the surface below
/// p (one start for a refraction; for a reflection one of the sphere's solutions, drawn
/// uniformly, the density divided by their number). The solid-angle density is pdf_area *
/// |det dl/dw| / candidates, the 2 x 2 Jacobian of the map w -> l carried exactly through the
/// chain's events on its triangles' planes (to_led_plane). Weight: the Fresnel factors times
/// the markers' transmittance on p -> x, zero if anything lies between x and l. NEE and BSDF
/// sampling are combined with the power heuristic on (pdf_nee, cos/pi times the Fresnel
/// factors); a path no chain makes (more crossings or reflections) gets weight 1 from BSDF
/// sampling.
#include "render/embree_scene.hpp"
#include "render/sampling.hpp"
#include "render/shading.hpp"

#include <array>
#include <optional>
#include <vector>

namespace chromasim::render::detail {

/// Most bounces of a path (Russian roulette ends nearly all paths long before).
inline constexpr int kMaxBounces = 256;

/// The specular events at the inner surface on a connection from a point p in the layers to an
/// LED: the light leaves the layers (refracted), and may then reflect off the surface from the
/// cavity side on its way to the LED (refracted_reflected: the LED seen in the cavity wall,
/// strong at the grazing angles near the rim). Next-event estimation tries both.
enum class Chain : std::uint8_t { refracted = 1, refracted_reflected = 2 };
inline int chain_length(Chain c) {
    return int(c);
}

/// One connection p -> x[0] (-> x[1]) -> l found by `PathIntegrator::connect`.
struct InterfaceConnection {
    Vec3 direction;                 ///< unit direction leaving p
    Vec3 x_mm[2];                   ///< the surface points (the second for refracted_reflected)
    std::uint32_t prim[2] = {0, 0}; ///< their triangles
    double fresnel = 1.0;           ///< (1 - F) at x[0], times F at x[1]
    double jacobian_mm2_per_sr;     ///< |det dl / dw|: LED-plane area per solid angle at p
    /// Number of connections of the sphere model the start was drawn from (refracted: 1);
    /// the connection's density is divided by it.
    int candidates = 1;
};

/// The directions leaving p of a point LED's connections (PathIntegrator::led_flux_point):
/// the refracted chain's (zero: none) and each reflected one's. A frame's solves start from
/// those found at rest (FastIntegrator::set_frame).
struct PointLedPaths {
    Vec3 refracted = Vec3::Zero();
    std::vector<Vec3> reflected;
    /// Where each connection meets the inner surface first, as a material point: its
    /// triangle, barycentric weights of the second and third corners (prim ~0u: unknown) and
    /// the point they give at rest. A frame's solve starts towards that point on the deformed
    /// surface, or along the rest's direction where the surface there has not moved.
    struct SurfacePoint {
        std::uint32_t prim = ~0u;
        double b1 = 0.0, b2 = 0.0;
        Vec3 rest_mm = Vec3::Zero();
    };
    SurfacePoint refracted_at;
    std::vector<SurfacePoint> reflected_at;
};

class PathIntegrator {
public:
    /// Keeps a reference to `shading` (optics, marker absorption, transmittance).
    /// `next_event` false: BSDF sampling alone (every LED hit weighs 1), the unbiased but
    /// noisy estimator the tests compare next-event estimation with.
    explicit PathIntegrator(const ShadingModel& shading, bool next_event = true);

    /// Radiance along the camera ray (origin, unit direction), per lane, in the preview's
    /// units (LED intensity per mm^2 per sr).
    template <int N>
    LanesN<N> radiance(const EmbreeScene& scene, const Vec3& origin_mm, const Vec3& direction,
                       const LaneOptics<N>& lanes, PixelRng& rng) const;

    /// The light arriving at `p_mm` (a diffuse point inside the layers, unit `normal` facing
    /// the side the light comes from) other than straight from an LED, in one estimate: a
    /// cosine-distributed direction, then the path as `radiance` follows it, with the LED
    /// light that reaches p through a Chain weighted by multiple importance sampling against
    /// led_flux_sample (power heuristic; `nee_per_bsdf`: led_flux_sample's samples per LED
    /// over this function's samples), and left out without an inner surface (straight light
    /// is led_flux_sample's alone). The mean over many calls is the irradiance at p over pi
    /// that led_flux_sample (with the reciprocal ratio) does not estimate, per lane.
    template <int N>
    LanesN<N> indirect(const EmbreeScene& scene, const Vec3& p_mm, const Vec3& normal,
                       const LaneOptics<N>& lanes, PixelRng& rng, double nee_per_bsdf) const;

    /// One estimate of the vector irradiance at `p_mm` straight from LED `k` (point (u1, u2)
    /// on it; u_choice picks among the sphere model's reflections), per unit of the LED's
    /// emission (LaneOptics::led), nothing but the cavity in the way: through both Chains when
    /// the scene has an inner surface, in a straight line when not; connections arriving
    /// behind the unit `normal` are left out. Through the inner surface each connection is
    /// weighted by MIS against indirect()'s cosine samples (`bsdf_per_nee`: their count over
    /// this function's per LED; 0: weight 1). Its mean over uniform (u1, u2, u_choice),
    /// dotted with a normal near `normal`, is that share of the irradiance (1/mm^2).
    /// `radius_mm`: radius_below(scene, p_mm) when the caller has it; looked up when absent.
    Vec3 led_flux_sample(const EmbreeScene& scene, const Vec3& p_mm, const Vec3& normal, int k,
                         double u1, double u2, double u_choice, double bsdf_per_nee,
                         std::optional<double> radius_mm = std::nullopt) const;

    /// The same for a point LED at the centre of LED `k`, deterministic: every connection of
    /// both Chains (each of the sphere model's reflections), fresnel / J times the direction.
    /// `radius_mm`: radius_below(scene, p_mm) when the caller has it (a frame update asks for
    /// every LED at the same point); looked up when absent.
    /// `refracted`: when given, receives the refracted chain's connection (unchanged when it
    /// has none or it does not count: blocked, or from behind the normal).
    /// A connection that two starts find counts once.
    /// `starts`: when given (the connections found at rest, `found` there), the Newton solves
    /// start from these directions instead of the sphere model's (the refracted chain from the
    /// sphere model's where starts->refracted is zero): the rest's connections, continued as
    /// the surface deforms, so that a frame update costs less for about the same error.
    /// `found`: when given, set to the directions of the connections solved, blocked or not
    /// (the first refracted one).
    Vec3 led_flux_point(const EmbreeScene& scene, const Vec3& p_mm, const Vec3& normal, int k,
                        std::optional<double> radius_mm = std::nullopt,
                        InterfaceConnection* refracted = nullptr,
                        const PointLedPaths* starts = nullptr,
                        PointLedPaths* found = nullptr) const;

    /// The sphere model's refraction from `p_mm` towards `led_point_mm` through the sphere of
    /// radius `radius_mm` about the origin: the unit direction leaving p.
    Vec3 refracted_direction(const Vec3& p_mm, const Vec3& led_point_mm, double radius_mm) const;
    /// Radius of the inner surface below p (the sphere model's), or nullopt without one.
    std::optional<double> radius_below(const EmbreeScene& scene, const Vec3& p_mm) const;

    /// A path from `p_mm` (inside the clear layers) to `led_point_mm` (in the cavity) through
    /// the inner surface with the events of `chain`, or nullopt if the Newton solve fails
    /// (total internal reflection, a miss, no convergence). The start is the connection of the
    /// sphere model through the surface below p; where that model has several (a reflection),
    /// `u` picks one uniformly. Does not check occlusion. Pre-condition: scene.has_interface().
    std::optional<InterfaceConnection> connect(const EmbreeScene& scene, const Vec3& p_mm,
                                               const Vec3& led_point_mm, Chain chain,
                                               double u = 0.5) const;
    /// The same with the sphere model's radius below p already known (radius_below), and
    /// optionally its reflected chain's starts for p and l (the directions from p towards its
    /// mirror points; computed when null).
    std::optional<InterfaceConnection> connect(const EmbreeScene& scene, const Vec3& p_mm,
                                               const Vec3& led_point_mm, Chain chain, double u,
                                               double radius_mm,
                                               const std::vector<Vec3>* mirrors = nullptr) const;

    /// The chain followed from `p_mm` along `direction` on the planes of the given triangles
    /// (normals interpolated, and extrapolated linearly off the triangle) down to the LED plane,
    /// with |det dl/dw| there and `landed` the LED-plane point; nullopt on total internal
    /// reflection or when the ray does not go down to the plane. `candidates` is left 1.
    std::optional<InterfaceConnection> along(const EmbreeScene& scene, Chain chain,
                                             const std::uint32_t* prims, const Vec3& p_mm,
                                             const Vec3& direction,
                                             Vec3* landed_mm = nullptr) const;

    /// Connections of the sphere model from p to l for `chain` (refracted: 1).
    int sphere_candidates(const EmbreeScene& scene, const Vec3& p_mm, const Vec3& led_point_mm,
                          Chain chain) const;
    /// The share of connect()'s starts for p and l whose Newton solve ends on the path that
    /// leaves p along `direction`: the factor of next-event estimation's density of that path
    /// over pdf_area |det dl/dw|. 0 where next-event estimation never finds it (a deformed
    /// surface has connections that no start leads to), so that BSDF sampling keeps it whole.
    double nee_share(const EmbreeScene& scene, Chain chain, const Vec3& p_mm,
                     const Vec3& led_point_mm, const Vec3& direction) const;

    /// Number of LEDs, their area (mm^2), and the LED rectangle hit by the segment, if any.
    int led_count() const { return int(m_led_centres.size()); }
    double led_area_mm2() const { return m_led_area_mm2; }
    /// An LED crossing: at t_mm along the ray, on the emitting (+z) face or not (`front`), of
    /// LED `k`.
    struct LedHit {
        double t_mm = 0.0;
        bool front = false;
        int k = 0;
    };
    /// Closest LED crossing of origin + t * direction with t in (tnear, tfar).
    std::optional<LedHit> led_hit(const Vec3& origin_mm, const Vec3& direction, double tnear_mm,
                                  double tfar_mm) const;
    /// LED k's intensity relative to the lanes' `led` (OpticsParams::led_gain).
    double led_gain(int k) const { return m_shading.led_gain(k); }
    /// How origin_mm + t * direction ends for t in (tnear_mm, tfar_mm), before a surface at
    /// tfar_mm: at an LED (`led`, as led_hit gives it), or at the mount (`blocked`: the frame
    /// or the lens barrel, looked for only up to the LED, which ends the ray first).
    struct RayEnd {
        std::optional<LedHit> led;
        bool blocked = false;
    };
    RayEnd ray_end(const Vec3& origin_mm, const Vec3& direction, double tnear_mm,
                   double tfar_mm) const;
    /// Where the ray from origin_mm along direction (forwards) crosses the LEDs' plane, if it
    /// does; and whether a point of that plane lies within margin_mm of an LED's rectangle
    /// (the renderer's choice of the pixels that mirror an LED:
    /// RenderSettings::reflection_samples_per_pixel).
    std::optional<Vec3> led_plane_crossing(const Vec3& origin_mm, const Vec3& direction) const;
    bool near_led(const Vec3& q_mm, double margin_mm) const { return led_at(q_mm, margin_mm) >= 0; }
    /// The first LED whose rectangle, grown by margin_mm, holds q_mm (a point of the LEDs'
    /// plane), or -1.
    int led_at(const Vec3& q_mm, double margin_mm) const;
    /// Whether the quadrilateral q[0] q[1] q[2] q[3] (points on the LEDs' plane, in order
    /// round it) meets an LED's rectangle grown by margin_mm on each side, by separating axes;
    /// true (no proof of the contrary) where it is not strictly convex.
    bool quad_near_led(const std::array<Vec3, 4>& q_mm, double margin_mm) const;
    /// A point on LED `k` from two uniforms.
    Vec3 led_point(int k, double u1, double u2) const;

private:
    template <int N>
    LanesN<N> next_event(const EmbreeScene& scene, const Vec3& p_mm, const Vec3& normal,
                         const LaneOptics<N>& lanes, PixelRng& rng) const;
    /// The path of `radiance`; with `start_normal`, the path of `indirect` from a diffuse
    /// vertex at `origin`.
    template <int N>
    LanesN<N> trace(const EmbreeScene& scene, const Vec3& origin, const Vec3& direction,
                    const LaneOptics<N>& lanes, PixelRng& rng, const Vec3* start_normal,
                    double start_nee_per_bsdf) const;
    /// connect()'s Newton solve from the direction w (`candidates`: as connect sets it).
    std::optional<InterfaceConnection> solve_connection(const EmbreeScene& scene, const Vec3& p,
                                                        const Vec3& l, Chain chain, const Vec3& w,
                                                        int candidates) const;
    /// The cosine at p (unit normal n) of connection c to l, or nullopt where it arrives from
    /// behind n or something lies in its way in the cavity (the surface again, a marker, the
    /// frame).
    std::optional<double> arriving_cosine(const EmbreeScene& scene, const InterfaceConnection& c,
                                          Chain chain, const Vec3& n, const Vec3& l) const;
    /// Calls visit(connection, cos_p) for each Chain that connects p to l with nothing in the
    /// way in the cavity.
    /// `chains`: a mask of the Chain values to try.
    /// `mirrors`: the sphere model's reflected-chain starts for p and l, when already known.
    template <class Visit>
    void for_each_connection(const EmbreeScene& scene, const Vec3& p, const Vec3& n, const Vec3& l,
                             double u_choice, double radius_mm, Visit&& visit, int chains = 3,
                             const std::vector<Vec3>* mirrors = nullptr) const;

    const ShadingModel& m_shading;
    bool m_next_event;
    double m_eta;                     ///< refractive index of the clear layers
    std::vector<Vec3> m_led_centres;  ///< on the ring, mm
    std::vector<Vec3> m_led_tangents; ///< unit, along the ring (width)
    std::vector<Vec3> m_led_radials;  ///< unit, outwards (height)
    double m_led_area_mm2;
};

} // namespace chromasim::render::detail
