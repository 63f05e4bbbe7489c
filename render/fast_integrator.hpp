#pragma once
/// The fast integrator: the path integrator's light transport with the light that barely
/// changes between frames computed once per sensor (the light cache) and rays spent only on
/// what moves. The code: fast_light_cache.cpp (the light cache), fast_frame.cpp (a frame's
/// update and shadow-ray culling), fast_integrator.cpp (a sample's walk through the layers,
/// shading and shadow rays), fast_camera.cpp (the camera packets), fast_common.hpp.
///
/// Split. The radiance a camera ray brings back from the coating point x (or from an outer
/// marker it enters) is albedo / pi times the irradiance there, and that irradiance is
///   - direct: the LEDs' light straight through the inner surface (the path integrator's
///     Chains), sum over LEDs k of G_k(x) T_k(x), G_k the LED's unshadowed irradiance (times
///     its gain, OpticsParams::led_gain, where a sample looks it up) and
///     T_k the markers' transmittance on the way (their coloured shadows), plus
///   - indirect: everything else (diffuse interreflection in the dome, light through the
///     markers and back, Fresnel and total reflections), smooth over the coating and barely
///     changed by a deformation.
///
/// Light cache (once per sensor, on the undeformed dome), at every coating vertex:
///   - the vector irradiance of each LED, V_k (G_k on a surface of normal n is V_k . n), by
///     next-event estimation through the Chains on the bare dome (coating and inner surface,
///     `direct_samples` points per LED; MIS against the indirect paths below with a fixed
///     ratio, kCacheBsdfPerNee), and the same for a point LED at the LED's centre
///     (PathIntegrator::led_flux_point, deterministic); and per coating edge, V_k at its
///     midpoint less the mean of its ends' (the quadratic term: near the rim the LEDs are
///     close and G_k curves within a 1.2 mm triangle, so linear interpolation alone leaves
///     the rim about 2 % dark at rest);
///   - the indirect irradiance / pi by path tracing on the dome with its markers
///     (PathIntegrator::indirect, `paths_per_vertex` paths) at two heights: at the coating, and
///     above the outer marker layer (where the markers' inner faces are). A vertex an outer
///     marker covers gets its above value at both heights (times the uncovered neighbours'
///     coating / above ratio at the coating height), so that uncovered coating interpolates
///     uncovered values. Each height is then smoothed by local linear regression with a
///     Gaussian of `smoothing_mm` (single paths that reach an LED after several reflections
///     make each vertex's estimate heavy-tailed);
///   - all per unit of LED emission; spectral: the indirect term at 16 fixed wavelengths, 400
///     to 700 nm every 20 nm, interpolated linearly at a sample's wavelengths (a product of
///     smooth albedo and transmittance spectra; the LED spectrum multiplies it per sample).
///
/// Per frame (set_frame): the cache moves with the coating's vertices (the same material
/// points). V_k is the cached (area LED) V_k at rest turned and scaled as the point LED's
/// vector irradiance changed from rest to this frame's inner surface (the deformation changes
/// the refraction a lot near the rim, which a straight-line model misses), one
/// Newton solve per LED, Chain and vertex. (Only the change comes from the point LED: the area
/// LED's vector is weighted by MIS between the Chains, the point LED's is not, so they point
/// differently.) Also per frame: the radius of the inner surface below each vertex (one ray);
/// per vertex and LED, the refracted solve's direction less the sphere model's (the shadow
/// rays' correction). The indirect light is the cache's, at rest: the path integrator finds a
/// press's indirect light within 1 % of rest (tests/render/test_fast.cpp). With
/// LightCacheSettings::refresh_direct, where the point LED's light at a vertex changed by more
/// than `refresh_threshold` of its rest value (near a contact), the rest relation is stale:
/// the vertex's light from that LED is estimated anew as the cache does (`direct_samples`
/// points, the same MIS weights, a fixed stream per vertex and LED).
///
/// Per camera sample: the camera ray meets the inner surface and splits deterministically:
/// (1 - F) refracts into the layers, F reflects into the cavity and is followed to the LED it
/// may hit or the dome wall it meets (which it enters with (1 - F') and is shaded like a
/// refracted ray; the further reflection F F' is left out; a reflection whose share is below
/// kUnshadowedReflection is shaded without shadow rays: from a camera at the dome's centre it
/// runs back across the cavity to the far wall near the rim plane, where no marker lies). In the
/// layers the ray crosses the markers (Beer-Lambert; an outer marker scatters the share
/// `outer_marker_scatter_fraction` of what enters it, shaded with the light above the marker layer)
/// to the coating, where the cache is interpolated with the hit's barycentric coordinates (V_k
/// quadratically: the corners' values linearly plus each edge's term times its bubble 4 w_i w_j,
/// scaled per frame by the change of the edge's ends) and G_k taken on the hit triangle's normal.
/// Below an outer marker the indirect term is the light above it times (1 - scatter fraction) times
/// the marker's diffuse transmittance 2 E_3(a t), t its thickness along the normal. T_k: the mean
/// of the sample's shadow rays (ShadowDraw), each to a point on one LED drawn with probability
/// G_k / sum G, along the sphere model's refraction through the inner surface below the point
/// (SphereRefraction: by Newton from the frame's per-vertex guess with
/// LightCacheSettings::cull_shadows, else over the whole bracket) plus the frame's correction,
/// interpolated over the hit triangle: the sphere model alone is 0.08 rad off near a flattened
/// contact, 0.008 rad with the correction (tests/render/test_fast.cpp).
/// Near the rim the sphere model's shadow paths leave the layers below the rim plane, and the
/// frame's plane blocks some (an artefact that offsets the cache's light from under the
/// frame). So the share of LED k's light so blocked is
/// taken per frame at the corners and edge midpoints of the triangles that had one at rest
/// (8 x 8 LED points each, the shadow rays' own paths), interpolated as G_k and taken off it;
/// the shadow rays to LED k from those triangles leave the plane out: the same mean without
/// the binary noise those rays make in the field's outer ring.
///
/// What it leaves out or approximates, each part of its error against the path integrator:
/// the indirect light's change with the deformation (the contact under a hard press stays a
/// few % of white too bright) and with the markers' motion; the finite LED's change under
/// deformation beyond the point LED's; the shadow of the LED seen by reflection in the
/// cavity wall (taken as the refracted one's); the
/// cache's resolution (the coating mesh's vertices, about 1.2 mm apart on the coarse mesh,
/// against 1 mm markers) and smoothing; F F' and higher cavity reflections of camera rays.
#include "render/path_integrator.hpp"

#include <algorithm>
#include <array>
#include <memory>
#include <span>
#include <vector>

namespace chromasim::render::detail {

/// Wavelengths of the spectral indirect term, nm.
inline constexpr int kCacheLambdas = 16;
inline constexpr double kCacheLambdaMin_nm = 400.0;
inline constexpr double kCacheLambdaStep_nm = 20.0;

/// A hero-wavelength set's place on that grid, computed once per set (the renderer's table of
/// sets): lane j interpolates the cached values at grid points i0[j] and i0[j] + 1, with
/// weight t[j] on the second (clamped to the grid's ends). The spectral lookups of a sample
/// then need no division, clamp or rounding per lane.
template <int N> struct CacheLambdas {
    std::array<int, N> i0{};
    LanesN<N> t = LanesN<N>::Zero();
    explicit CacheLambdas(const LanesN<N>& lambda_nm) {
        for (int j = 0; j < N; ++j) {
            const double x = std::clamp((lambda_nm[j] - kCacheLambdaMin_nm) / kCacheLambdaStep_nm,
                                        0.0, double(kCacheLambdas - 1));
            i0[std::size_t(j)] = std::min(int(x), kCacheLambdas - 2);
            t[j] = x - i0[std::size_t(j)];
        }
    }
};

/// The ratio of indirect paths to LED points per vertex that the light cache's MIS weights
/// between the two assume: 4, whatever the sample counts. Any fixed ratio keeps the weights a
/// partition of unity (the sum stays unbiased); a fixed one keeps the split between the direct
/// light, which each frame updates vertex by vertex, and the indirect light, which it at most
/// scales, where it is: with the actual counts, many paths would move much of the LEDs' light
/// into the indirect term and raise the bias under a press. A low ratio leaves the light near
/// the LEDs to the direct term (interpolated quadratically, not smoothed); 4 is about the
/// best of 1, 2, 4 and 16 at rest and at 5 N.
inline constexpr double kCacheBsdfPerNee = 4.0;

/// The most shadow rays one camera sample traces from its coating hit (ShadowDraw::rays).
inline constexpr int kMaxShadowRaysPerSample = 4;

/// The largest share of a camera sample (F, or
/// F (1 - F') through the far wall) whose reflection off the inner surface is shaded without
/// shadow rays; a larger one (grazing incidence, a surface tilted by a press) traces them.
inline constexpr double kUnshadowedReflection = 0.1;

/// A camera sample's uniforms for its coating hit's shadow rays, `rays` of them (1 to
/// kMaxShadowRaysPerSample, RenderSettings::shadow_rays_per_pixel; their mean estimates the
/// shadows): per ray, u_led picks the LED (with probability G_k / sum G), (u1, u2) the point
/// on it (PathIntegrator::led_point); the first ray's in (u_led, u1, u2), the others' in
/// `further`. The renderer stratifies them jointly over a pixel's shadow rays
/// (shadow_uniforms); u_led < 0: that ray's three drawn from the pixel's stream. rays 0: none,
/// the LEDs' direct light taken unshadowed and not apart (no DirectPart): the camera ray's
/// reflection off the inner surface (kUnshadowedReflection).
struct ShadowDraw {
    double u_led = -1.0, u1 = 0.0, u2 = 0.0;
    int rays = 1;
    std::array<std::array<double, 3>, kMaxShadowRaysPerSample - 1> further{};
};

/// The shadow filter (RenderSettings::shadow_filter_px, render/shadow_filter.hpp) takes the
/// fraction of the LEDs' light that gets through the shadows per group of LEDs, from the
/// shadow rays that went to that group: LED k of n in group k g / n, g = min(n,
/// kMaxShadowGroups) groups (one per LED on the real board's 6).
inline int shadow_group(int k, int leds, int groups) {
    return leds == groups ? k : k * groups / leds; // no division with up to 8 LEDs
}

/// One shadow ray's share of a camera sample's direct light at one coating point (a shade
/// with n shadow rays gives n of these, each 1 / n of the point's light): `lit` as if no
/// marker or fold cast a shadow (sum_k G_k times the path's factors, over n), `shadowed` with
/// the shadow ray's transmittance, `group` the shadow group of the LED the shadow ray went to,
/// `share[g]` group g's part of `lit`
/// (sum over its LEDs of G_k / sum G; the first shadow_groups() add up to 1, or all 0 where
/// no LED lights the point).
template <int N> struct DirectPart {
    LanesN<N> lit, shadowed;
    bool clear; ///< shadowed == lit (the shadow ray met nothing): no second conversion to RGB
    int group;
    std::array<double, kMaxShadowGroups> share;
};

/// The most direct-light parts of a camera sample: in each of its refracted and reflected
/// branches, the coating hit's shadow rays (at most kMaxShadowRaysPerSample) and the outer
/// markers' scattering above it (at most 4, one shadow ray each).
inline constexpr int kMaxDirectParts = 2 * (kMaxShadowRaysPerSample + 4);

/// The LEDs' direct light in a camera sample's radiance, apart (the renderer's shadow
/// filter), one DirectPart per coating point the sample shades (each times the path's factors
/// up to it); the rest of the radiance (indirect light, LEDs seen directly) is in none. Only
/// the first `parts` are set (the renderer keeps 16 per batch of pixels, which would cost
/// about 50 KB of zeroing per batch of spectral samples): radiance16 sets `parts` for each one it
/// is given.
template <int N> struct DirectLight {
    int parts = 0;
    std::array<DirectPart<N>, kMaxDirectParts> part;
    /// The sums over the parts.
    LanesN<N> lit() const {
        LanesN<N> sum = LanesN<N>::Zero();
        for (int i = 0; i < parts; ++i)
            sum += part[std::size_t(i)].lit;
        return sum;
    }
    LanesN<N> shadowed() const {
        LanesN<N> sum = LanesN<N>::Zero();
        for (int i = 0; i < parts; ++i)
            sum += part[std::size_t(i)].shadowed;
        return sum;
    }
};

class FastIntegrator {
public:
    FastIntegrator(const ShadingModel& shading, const PathIntegrator& path);

    /// Builds the cache on `undeformed` (coating, inner surface and markers at rest).
    /// `spectral`: 16 fixed wavelengths from `spectra` (nullptr: the RGB lanes). Deterministic
    /// (a stream per vertex).
    void build_cache(const SensorFrame& undeformed, const render::LightCacheSettings& settings,
                     const SensorSpectra* spectra, double led_scale);
    /// Uses a cache built before (read from disk: generators/pipeline/light_cache_store.hpp)
    /// instead of building one; frames must then match its coating (check_topology). `settings`:
    /// those it was built with, and the per-frame refresh. `undeformed`: the sensor at rest it was
    /// built on, where the point LEDs' connections are found again (point_paths: as long as a frame
    /// update). Throws std::invalid_argument (and keeps the cache in use, if any) when its coating
    /// is not the cache's.
    void adopt_cache(LightCache cache, const render::LightCacheSettings& settings,
                     const SensorFrame& undeformed);
    bool has_cache() const { return m_cache != nullptr; }
    const LightCache& cache() const { return *m_cache; }

    /// The frame's G_k from the cache and the deformed coating, and the inner surface's
    /// radius below each coating vertex (`scene`: the frame, loaded). Throws
    /// std::invalid_argument when the coating's topology differs from the cache's.
    void set_frame(const SensorFrame& frame, const EmbreeScene& scene);
    /// Throws std::invalid_argument unless the frame's coating has the cache's topology.
    void check_topology(const SensorFrame& frame) const;

    /// Radiance along the camera ray, per lane, in the path integrator's units. `lambdas`:
    /// the lanes' wavelengths on the light cache's grid (spectral), nullptr in RGB mode. `shadow`:
    /// the uniforms of the coating hit's shadow ray (default: drawn from `rng`).
    template <int N>
    LanesN<N> radiance(const EmbreeScene& scene, const Vec3& origin_mm, const Vec3& direction,
                       const LaneOptics<N>& lanes, const CacheLambdas<N>* lambdas, PixelRng& rng,
                       ShadowDraw shadow = {}) const;

    /// The radiance along up to 16 camera rays from one origin (the samples of a pixel, or of
    /// a few neighbouring pixels, in order), as radiance() gives each: their first hits, their
    /// refracted and reflected rays and the reflected rays' refraction into the far wall go to
    /// Embree as coherent packets of 16; the rest (markers, shading, shadow rays) runs per
    /// sample, in order, sample i drawing from *rng[i] (its pixel's stream).
    /// lanes[i], lambdas[i], shadow[i]: sample i's, as radiance() takes them. `direct`
    /// (empty, or one per sample): also each sample's direct light apart (out is the same).
    /// `reflected_leds` false: without the LEDs seen by reflection in the inner surface (the
    /// camera ray's reflection F reaching an LED; reflected_leds16 gives that term apart).
    template <int N>
    void radiance16(const EmbreeScene& scene, const Vec3& origin_mm,
                    std::span<const Vec3> directions, std::span<const LaneOptics<N>* const> lanes,
                    std::span<const CacheLambdas<N>* const> lambdas,
                    std::span<const ShadowDraw> shadow, std::span<PixelRng* const> rng,
                    std::span<LanesN<N>> out, std::span<DirectLight<N>> direct = {},
                    bool reflected_leds = true) const;

    /// The term radiance16 leaves out with reflected_leds = false, for up to 16 camera rays
    /// from `origin_mm`: fresnel[i] is the Fresnel reflectance F times the LED's gain where ray
    /// i's reflection off the inner surface reaches an LED (the LED's radiance, l.led / the
    /// LED's area per lane, times that is then its radiance), 0 elsewhere. The same two
    /// packets and tests as radiance16 (the camera ray to the inner surface, its reflection to
    /// the next surface), nothing else: no layers, no shading, no random draw.
    void reflected_leds16(const EmbreeScene& scene, const Vec3& origin_mm,
                          std::span<const Vec3> directions, std::span<double> fresnel) const;

    /// The markers that up to 16 camera rays from `origin_mm` show, as radiance16 traces
    /// them: ids[i] is, per layer (inner, outer), the marker (triangle / triangles_per_marker)
    /// whose surface ray i meets first on its way to the coating after refracting into the
    /// layers at the inner surface (its interpolated normal, as the samples refract), or -1.
    /// A ray that meets an LED, the frame, nothing, or the inner surface without refracting
    /// into it shows none. The same two packets as radiance16 (to the inner surface, then on
    /// into the layers), then the marker walk of the rays whose first hit there is a marker.
    /// Needs a loaded frame, not a light cache.
    void marker_ids16(const EmbreeScene& scene, const Vec3& origin_mm,
                      std::span<const Vec3> directions, int triangles_per_marker,
                      std::span<std::pair<std::int32_t, std::int32_t>> ids) const;

    /// The shadow ray's direction from `p_mm`, the point of coating triangle `prim` at
    /// barycentric coordinates (u, v), towards `led_point_mm` on LED k, as the samples take it
    /// but with the sphere model solved over the whole bracket (the samples' Newton start,
    /// with the culling, stops about 1e-5 rad from it on average), for tests and diagnostics.
    /// Pre-condition: set_frame with an inner surface.
    Vec3 shadow_direction(std::uint32_t prim, double u, double v, const Vec3& p_mm, int k,
                          const Vec3& led_point_mm) const;

    /// The frame's unshadowed light from LED k at coating vertex `vertex` (G_k on a normal n
    /// is its dot product with n), per unit LED emission, 1/mm^2 (for tests and diagnostics).
    /// Pre-condition: set_frame.
    Vec3 frame_direct(int vertex, int k) const {
        const float* g = m_direct.data() + 3 * (std::size_t(vertex) * m_cache->leds + k);
        return Vec3(g[0], g[1], g[2]);
    }

    /// The shadow filter's groups of LEDs: min(LEDs, kMaxShadowGroups) (shadow_group).
    /// Pre-condition: a cache.
    int shadow_groups() const { return std::min(m_cache->leds, kMaxShadowGroups); }

    /// G_k as a sample at barycentric (u, v) of coating triangle `prim` takes it (on `normal`):
    /// the corners' frame_direct linearly plus the edges' quadratic terms (for tests).
    double direct_at(std::uint32_t prim, double u, double v, const Vec3& normal, int k) const;
    /// Whether direct_at takes the frame's share of LED k's light off on coating triangle
    /// `prim` (tabulate_frame_share; for tests).
    bool frame_share_taken(std::uint32_t prim, int k) const {
        return !m_frame_triangle.empty() &&
               m_frame_triangle[std::size_t(prim) * std::size_t(m_cache->leds) + std::size_t(k)];
    }

private:
    /// What a ray in the cavity does at the surface it meets (radiance16's bounces): it
    /// brings back an LED's light (`led`), nothing (the black frame, a miss, the back of the
    /// inner surface), the layers' light straight (`straight`: a surface other than the inner
    /// one), or it splits at the inner surface into the refraction (1 - F) and the reflection F.
    enum class Then { nothing, led, straight, split };
    struct Bounce {
        Then then = Then::nothing;
        Vec3 p = Vec3::Zero(); ///< where it splits
        double F = 0.0;
        double led_gain = 1.0; ///< the LED's intensity (Then::led)
        bool refract = false, reflect = false;
        Vec3 refracted = Vec3::Zero(), reflected = Vec3::Zero();
    };
    /// The bounce of the ray from o along d (from tnear) whose first hit is `hit`; `reflect`:
    /// whether a split follows the reflection too (the camera's rays; not their reflections).
    Bounce classify(const Vec3& o, const Vec3& d, double tnear, const RayHit& hit,
                    bool reflect) const;
    /// The first step of radiance16, reflected_leds16 and marker_ids16: the camera rays from
    /// `origin` along `directions` (up to 16) as one packet, against the inner surface alone
    /// where `cavity_only`, into first[i], and their bounces (classify, `reflect`) into near[i].
    void camera_bounces(const EmbreeScene& scene, const Vec3& origin,
                        std::span<const Vec3> directions, bool cavity_only, bool reflect,
                        std::span<RayHit> first, std::span<Bounce> near) const;
    template <int N> struct Lookup;
    /// What build_cache's steps share: the sensor at rest, its scenes with and without the
    /// markers (`bare`: the coating and inner surface), the coating's normals and the outer
    /// markers' inner face above each vertex they cover (0 where none does).
    struct CacheGeometry {
        const SensorFrame& rest;
        const EmbreeScene& full;
        const EmbreeScene& bare;
        const std::vector<Vec3>& normals;
        std::vector<double> above_mm;
    };
    /// build_cache's per-vertex step: each vertex's LED light (area_flux) and indirect light
    /// at the coating and above the outer marker layer, path-traced.
    void cache_vertex_light(const CacheGeometry& g, const render::LightCacheSettings& settings,
                            const SensorSpectra* spectra, double led_scale,
                            LightCache& cache) const;
    /// build_cache's edge step: the coating's edges and the LED light's quadratic term along
    /// each (LightCache::direct_edge).
    void cache_edge_terms(const CacheGeometry& g, const render::LightCacheSettings& settings,
                          LightCache& cache, std::vector<std::array<std::uint32_t, 2>>& edges,
                          std::vector<std::uint32_t>& triangle_edges) const;
    /// The point LEDs' connections at each vertex of `rest`'s coating (a hair off it, as
    /// set_frame takes them) on `bare` (its coating and inner surface), [vertex * leds + k];
    /// `point_rest`: if given, set to their light (LightCache::point_rest).
    std::vector<PointLedPaths> point_paths(const SensorFrame& rest, const EmbreeScene& bare,
                                           std::vector<float>* point_rest) const;
    /// LED k's unshadowed light at p (normal n) through the scene's inner surface (radius_mm:
    /// the sphere model's radius below p; none: no light), by settings.direct_samples LED
    /// points with the cache's MIS weights, from the stream `stream` (build_cache and
    /// set_frame's refresh: vertex * leds + k).
    Vec3 area_flux(const EmbreeScene& scene, const Vec3& p, const Vec3& n, int k,
                   std::optional<double> radius_mm, const render::LightCacheSettings& settings,
                   std::uint64_t stream) const;
    template <int N>
    Lookup<N> lookup(std::uint32_t prim, double u, double v, const Vec3& normal) const;
    /// `direct`: if given, the direct light's parts of the result times `factor` (the path's
    /// factors up to p) are added to it, one per shadow ray.
    template <int N>
    LanesN<N> shade(const EmbreeScene& scene, const Vec3& p, const Lookup<N>& at,
                    const LanesN<N>& indirect, const LaneOptics<N>& lanes, PixelRng& rng,
                    const ShadowDraw& shadow, DirectLight<N>* direct,
                    const LanesN<N>& factor) const;
    /// The shadow ray's direction from the coating hit `p` towards `led_point` of LED k: the
    /// sphere model's refraction, plus the frame's correction to it interpolated over the
    /// hit triangle (m_shadow).
    template <int N>
    Vec3 shadow_direction(const Lookup<N>& at, const Vec3& p, int k, const Vec3& led_point) const;
    /// The frame's correction to the sphere model's shadow direction towards LED k (m_shadow),
    /// interpolated over the hit triangle.
    template <int N> Vec3 shadow_correction(const Lookup<N>& at, int k) const;
    /// The culling's guess (m_guess) at coating vertex `vertex`: the sphere model's direction
    /// towards the point of LED k offset (d1, d2) from its centre, in its width and height.
    Vec3 guessed_direction(std::uint32_t vertex, int k, double d1, double d2) const;
    /// The shadow ray's transmittance from p towards the LED point (u1, u2) of LED k through
    /// the sphere model, one where the ray provably meets nothing (the culling below).
    template <int N>
    LanesN<N> shadow_transmittance(const EmbreeScene& scene, const Vec3& p, const Lookup<N>& at,
                                   int k, double u1, double u2, const LaneOptics<N>& lanes) const;
    /// True if the shadow ray's path from p to q (where it leaves the sphere model) misses
    /// the markers, the frame and the coating: it lies above the rim plane and in triangle
    /// `prim`'s ball for LED k, and no marker of that ball's list comes that close (markers by
    /// their balls; folds by their cones of directions, against the path's directions from the
    /// origin).
    /// `frame_apart`: the frame's share of LED k's light is taken apart (m_frame_triangle):
    /// the path may cross the rim plane.
    bool path_clear(std::uint32_t prim, int k, const Vec3& p, const Vec3& q,
                    bool frame_apart) const;
    /// The frame's share, once per cache on the sensor at rest (`bare`: its
    /// coating and inner surface): which (triangle, LED) pairs take the frame's share apart
    /// (m_frame_triangle) and the corners' and edges' pairs each frame takes it at.
    void tabulate_frame_share(const SensorFrame& rest, const EmbreeScene& bare);
    /// The frame's share of an LED's light at p (the sphere model's radius below it
    /// `radius_mm`): of kFrameShareGrid^2 points (u1, u2) of the LED (their cells' centres),
    /// the fraction whose shadow path from where it leaves the layers, exit_towards(u1, u2)
    /// (none: no path), to p crosses the frame's plane (ShadingModel::crosses_mount).
    template <class Exit>
    float frame_share(const Vec3& p, double radius_mm, Exit&& exit_towards) const;
    /// Per frame (after the frame's radii, corrections and guesses): the shares at the
    /// tabulated pairs, as the frame's shadow rays take their paths.
    void update_frame_share(const SensorFrame& frame);
    /// Where the shadow ray from p (a sample at `at`) towards the point (u1, u2) of LED k
    /// leaves the layers: the sphere model's refraction (by Newton from the frame's guess
    /// where there is one) plus the frame's correction; none if it misses the sphere.
    template <int N>
    std::optional<Vec3> shadow_exit(const Lookup<N>& at, const Vec3& p, int k, double u1,
                                    double u2) const;
    /// The shadow-ray culling's ball of coating triangle `t` (its 3 vertices) and LED k: its
    /// corners and where the guessed paths from its corners to the LED's corners leave the
    /// sphere, plus kCullMargin_mm; none where a corner has no sphere below it.
    std::optional<Eigen::Vector4d> culling_ball(const SensorFrame& frame, const std::uint32_t* t,
                                                std::size_t k) const;
    /// Per frame (LightCacheSettings::cull_shadows): the markers' balls, the coating's inward
    /// folds, and each coating triangle's ball per LED with the markers and folds near it.
    void build_shadow_culling(const SensorFrame& frame);
    template <int N>
    LanesN<N> spectral_at(const std::vector<float>& values, const std::uint32_t* triangle,
                          const double* weights, const CacheLambdas<N>* lambdas) const;
    /// `direct`: if given, the direct light's parts of the result times `weight` are added
    /// to it (DirectLight); the result does not change.
    template <int N>
    LanesN<N> inside(const EmbreeScene& scene, const Vec3& origin, const Vec3& direction,
                     double tnear_mm, const LaneOptics<N>& lanes, const CacheLambdas<N>* lambdas,
                     PixelRng& rng, const ShadowDraw& shadow, const RayHit* first,
                     DirectLight<N>* direct, double weight) const;

    const ShadingModel& m_shading;
    const PathIntegrator& m_path;
    std::shared_ptr<const LightCache> m_cache;
    render::LightCacheSettings m_settings; ///< the cache's, and the per-frame refresh
    std::vector<float> m_direct;           ///< the frame's G_k, [vertex * leds + k]
    /// The point LEDs' connections at rest, [vertex * leds + k] (point_paths): where each
    /// frame's solves of the point LEDs' light start.
    std::vector<PointLedPaths> m_rest_paths;
    /// The frame's quadratic terms of G_k, [edge * leds + k] (LightCache::direct_edge).
    std::vector<float> m_direct_edge;
    std::vector<std::array<std::uint32_t, 2>> m_edges; ///< the coating's edges (their ends)
    std::vector<std::uint32_t> m_triangle_edges;       ///< each triangle's three edges
    std::vector<float> m_radius; ///< the sphere model's inner radius below each vertex, mm
    /// Per vertex and LED k, [(vertex * leds + k) * 3]: the frame's refracted connection to
    /// the LED's centre (the Newton solve on the deformed inner surface) less the sphere
    /// model's direction from the same point; zero where the solve found none.
    std::vector<float> m_shadow;
    /// Shadow-ray culling (LightCacheSettings::cull_shadows). Per vertex
    /// and LED k, [(vertex * leds + k) * 9]: the sphere model's direction from the vertex to
    /// the LED's centre and its change across the LED's width and height (per unit of the
    /// sample's u1, u2), interpolated over the hit triangle: the start of each shadow ray's
    /// Newton solve (SphereRefraction::newton).
    std::vector<float> m_guess;
    /// Per coating triangle f and LED k, [f * leds + k]: a ball (centre, radius; radius < 0:
    /// no culling) meant to hold the shadow paths from f to the LED, and the markers whose
    /// bounding balls meet it and the folds whose cones meet its cone (m_cull_markers[
    /// m_cull_first[i] .. m_cull_first[i + 1]]).
    std::vector<Eigen::Vector4d> m_cull_ball;
    std::vector<std::uint32_t> m_cull_first;
    std::vector<std::uint32_t> m_cull_markers;
    std::vector<Eigen::Vector4d> m_marker_balls; ///< each marker's (centre, radius), mm
    /// Where the coating folds inwards: each such edge's cone of directions from the origin
    /// (unit axis, chord to its ends); in m_cull_markers after the markers (index - markers).
    std::vector<Eigen::Vector4d> m_fold_cones;
    /// The frame's share of the LEDs' light near the rim (empty: no inner surface), this
    /// frame's: of LED k's light at each coating vertex, [vertex * leds + k], the fraction of
    /// its points whose shadow path crosses the frame's plane (frame_share_at); per edge,
    /// [edge * leds + k], the same at its midpoint less the mean of its ends' (the quadratic
    /// term, as m_direct_edge). Per (triangle, LED), [triangle * leds + k]: 1 where a corner or
    /// edge midpoint had a share at rest; there the lookup takes the interpolated share off
    /// G_k and the shadow rays to LED k leave the frame's plane out (elsewhere they test it).
    /// Each frame takes the shares anew at the flagged pairs' corners and edges
    /// (m_frame_vertex_pairs: vertex * leds + k; m_frame_edge_pairs: edge * leds + k).
    std::vector<float> m_frame_vertex, m_frame_edge;
    std::vector<std::uint8_t> m_frame_triangle;
    std::vector<std::uint32_t> m_frame_vertex_pairs, m_frame_edge_pairs;
};

} // namespace chromasim::render::detail
