#pragma once
/// The renderer's internals (Renderer::Impl), shared by its files: renderer.cpp (the public
/// methods, exposure and the pixel loop), pixel_samples.cpp (each pixel's camera samples
/// through the integrators, kept between frames) and pixel_classes.cpp (which pixels take
/// more samples, and the marker id channels). Include only from those.
#include "render/renderer.hpp"

#include "render/embree_scene.hpp"
#include "render/fast_integrator.hpp"
#include "render/fisheye_camera.hpp"
#include "render/path_integrator.hpp"
#include "render/sampling.hpp"
#include "render/shading.hpp"
#include "render/shadow_filter.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <mutex>
#include <numbers>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>
#include <variant>
#include <vector>

namespace chromasim::render {

struct Renderer::Impl {
    FisheyeCamera camera;
    detail::ShadingModel shading;
    detail::PathIntegrator path{shading};
    detail::FastIntegrator fast{shading, path};
    /// The current frame's coating and markers (no inner surface: the scene has it), for a
    /// light cache built after set_frame.
    SensorFrame frame;
    detail::EmbreeScene scene;
    /// The camera rays through the image grid's points (x, y), x in 0 .. w, y in 0 .. h: the
    /// pixels' corners, and through the pixels' centres (x + 0.5, y + 0.5), row by row, a NaN
    /// x outside the field. Worked out once (the camera never changes), the first time a fast
    /// render chooses its pixels' counts, which reads them every frame
    /// (grid_direction); serially, so that no TBB task waits inside call_once.
    struct GridDirections {
        std::vector<Vec3> corners, centres;
    };
    mutable std::once_flag grid_once;
    mutable GridDirections grid;
    const GridDirections& grid_directions() const;
    /// grid_directions' ray through corner (x, y) (centre: of pixel (x, y)); none outside the
    /// field. Pre-condition: grid_directions() called.
    std::optional<Vec3> grid_direction(int x, int y, bool centre) const {
        const std::size_t nx = std::size_t(camera.width_px()) + (centre ? 0 : 1);
        const Vec3& d =
            (centre ? grid.centres : grid.corners)[std::size_t(y) * nx + std::size_t(x)];
        if (std::isnan(d.x())) return std::nullopt;
        return d;
    }
    double scale; ///< image value per unit radiance (analytic: the preview's apex)
    /// The path integrator's scale once set_exposure_reference measured its apex.
    std::optional<double> path_scale;
    double led_scale; ///< spectral mode: relative LED intensity (mean of led_rgb)
    /// Spectral mode: wavelengths drawn in proportion to what the camera sees of the LED
    /// (camera_weight), 10 % uniform: per sample, a white surface's standard deviation falls
    /// from 0.42, 0.29, 1.15 (R, G, B) with uniform wavelengths to 0.22, 0.12, 0.21
    /// (tests/render/test_spectrum.cpp).
    std::optional<WavelengthSampler> wavelengths;

    Impl(const CameraParams& camera_params, const OpticsParams& optics);

    /// The spectral mode's hero-wavelength sets, tabulated once per sensor: set i holds the
    /// N (16, or the fast integrator's 8) wavelengths WavelengthSampler draws from u = (i + 1/2) /
    /// kHeroSets, the spectra at them (lanes) and the weights that turn the lanes' radiance into
    /// white-balanced camera RGB, self-normalised so that each set renders the LED's white exactly
    /// (camera_rgb_weights). A sample picks set floor(u kHeroSets): the wavelengths then come
    /// from a 1024-point midpoint rule in the sampling distribution's CDF, and a sample costs
    /// one table read instead of 16 CDF inversions and 128 spectrum lookups. (Over the table,
    /// the plain weights are within 1e-3 of white of the trapezoid integral, in blue;
    /// self-normalised, within 7.6e-4 on the marker filters and exact on the white:
    /// tests/render/test_spectrum.cpp.)
    static constexpr int kHeroSets = 1024;
    template <int N> struct HeroSetN {
        detail::LanesN<N> lambda_nm;
        detail::LaneOptics<N> lanes;
        Eigen::Matrix<double, 3, N> to_rgb;
        /// lambda_nm on the fast integrator's light-cache grid.
        detail::CacheLambdas<N> cache_lambdas{detail::LanesN<N>::Zero()};
    };
    using HeroSet = HeroSetN<detail::kSpectralLanes>;
    /// The sets of the preview and path integrators, and of the fast one at 16 wavelengths
    /// (RenderSettings::fast_wavelengths).
    std::vector<HeroSet> hero_sets;
    /// The fast integrator's at kFastSpectralLanes (RenderSettings::fast_wavelengths): set i
    /// from u = (i + 1/2) / kHeroSets as above, the first kHeroSets / kFastSpectralLanes only
    /// (it reads set i / N: the others repeat them with their lanes rotated).
    std::vector<HeroSetN<detail::kFastSpectralLanes>> fast_hero_sets;
    template <int N> const std::vector<HeroSetN<N>>& hero_table() const {
        if constexpr (N == detail::kSpectralLanes)
            return hero_sets;
        else
            return fast_hero_sets;
    }

    template <int N>
    void tabulate(const SensorSpectra& spectra, std::vector<HeroSetN<N>>& sets, int count) const {
        sets.resize(std::size_t(count));
        for (int i = 0; i < count; ++i) {
            HeroSetN<N>& h = sets[std::size_t(i)];
            detail::LanesN<N> pdf_per_nm;
            wavelengths->sample<N>((i + 0.5) / kHeroSets, h.lambda_nm, pdf_per_nm);
            h.lanes = detail::spectral_lanes<N>(spectra, h.lambda_nm, led_scale);
            h.cache_lambdas = detail::CacheLambdas<N>(h.lambda_nm);
            h.to_rgb = camera_rgb_weights<N>(spectra.camera, h.lambda_nm, pdf_per_nm);
        }
    }
    void tabulate_hero_sets(const SensorSpectra& spectra) {
        tabulate(spectra, hero_sets, kHeroSets);
        tabulate(spectra, fast_hero_sets, kHeroSets / detail::kFastSpectralLanes);
    }

    /// The sum over the pixel's samples (unscaled camera RGB; samples outside the image
    /// circle are left out, draw), from the stream (seed, pixel index) and the pixel's seeds: one
    /// per cell of the pixel's multi-jittered grid, the wavelength strata paired with them by a
    /// per-pixel permutation. `sum2` gets the squares of the scaled samples, `inside` the
    /// number of samples inside the field. (The fast integrator's pixels: sample_pixels_fast.)
    template <Integrator I>
    detail::Rgb sample_pixel(int x, int y, int nx, int ny, const RenderSettings& settings,
                             double scale, detail::Rgb* sum2, int& inside) const;

    /// Most positions drawn anew for a sample outside the field in a pixel its edge crosses
    /// (draw): a pixel 1 % inside keeps a sample with probability 0.47.
    static constexpr int kFieldRedraws = 64;
    /// Sample k of a pixel's nx x ny: its camera ray through its position (multi_jittered;
    /// in a pixel the field's edge crosses, drawn anew if outside; none if still outside)
    /// and its hero-wavelength uniform (a stratum by a per-pixel permutation, so that
    /// position and wavelength strata do not pair up along the pixel's rows; zero in RGB
    /// mode, which draws none), drawn from `rng` in that order.
    struct Draw {
        std::optional<Vec3> direction;
        double u_lambda = 0.0;
    };
    Draw draw(int x, int y, int k, int nx, int ny, detail::PixelRng& rng,
              const detail::PixelSeeds& seeds) const;

    /// sample_pixel for the fast integrator, for `pixels` neighbouring pixels of row y from x
    /// (sums[j], sum2[j]: pixel x + j's, sum2 empty without the variance; direct[j]: the sums
    /// of its samples' direct light apart per shadow group, DirectSums, empty without
    /// the shadow filter; inside[j]: how many of its samples lie in the field): the same
    /// strata and draws per sample, each pixel from its own
    /// stream and seeds, plus the shadow rays'
    /// uniforms, jointly stratified over the pixel's samples and its 2 x 2 block's
    /// (shadow_uniforms: no draws from the stream). The samples, pixel after pixel, go through
    /// FastIntegrator::radiance16 in packets of equal size, at most 16 (coherent packets); a
    /// pixel's draws come in the same order however many pixels share a packet, so the image does
    /// not depend on it.
    /// A pixel's direct light per shadow group g (render/shadow_filter.hpp): U_g (`lit`), C_g
    /// (`chosen`) and S_g (`shadowed`), sums over its samples.
    struct DirectSums {
        std::array<detail::Rgb, kMaxShadowGroups> lit, chosen, shadowed;
    };
    /// A pixel's LEDs seen by reflection, estimated apart
    /// (RenderSettings::reflected_led_samples_per_pixel): the sum over its rays of the Fresnel
    /// factor F where the reflection reaches an LED (FastIntegrator::reflected_leds16), of
    /// F^2, and how many of its rays lie in the field.
    struct LedSums {
        double sum = 0.0, sum2 = 0.0;
        int inside = 0;
    };
    struct PixelSums {
        std::span<detail::Rgb> sums, sum2;
        std::span<DirectSums> direct;
        std::span<int> inside;
        std::span<LedSums> led; ///< empty, or one per pixel: the LEDs by reflection apart
    };
    /// Pixel (x, y)'s index in the image, row by row: its streams' and seeds' name.
    std::uint64_t pixel_index(int x, int y) const {
        return std::uint64_t(y) * std::uint64_t(camera.width_px()) + std::uint64_t(x);
    }
    /// The fast integrator's seeds of pixel (x, y): its own, with the shadow rays' Sobol
    /// points shared by each 2 x 2 block of pixels (shadow_uniforms), the pixel's quad row by
    /// row within its block.
    detail::PixelSeeds pixel_seeds(std::uint64_t seed, int x, int y) const {
        const auto px = std::uint64_t(x), py = std::uint64_t(y);
        const std::uint64_t blocks_per_row = (std::uint64_t(camera.width_px()) + 1) / 2;
        return detail::PixelSeeds(seed, pixel_index(x, y), (py / 2) * blocks_per_row + px / 2,
                                  std::uint32_t(px % 2 + 2 * (py % 2)));
    }
    /// The fast integrator's shadow rays a pixel of `count` samples traces
    /// (RenderSettings::shadow_rays_per_pixel): at least one a sample, at most
    /// kMaxShadowRaysPerSample a sample.
    static int shadow_rays(const RenderSettings& settings, int count) {
        return std::clamp(settings.shadow_rays_per_pixel, count,
                          detail::kMaxShadowRaysPerSample * count);
    }
    /// The shading's stream of a fast-integrator pixel (the shade's own draws, where a shadow
    /// ray has no stratified uniforms): the pixel's seed changed by this, apart from the
    /// camera draws' stream, so that the camera samples can be kept between frames
    /// (pixel_draws) and be the same as drawn anew.
    static constexpr std::uint64_t kShadeSeed = 0x5348414445535431ull;
    /// Sample k of a fast-integrator pixel: its camera direction (draw) and hero-wavelength
    /// set (0 in RGB mode); none outside the field.
    std::optional<std::pair<Vec3, int>> fast_draw(int x, int y, int k, int nx, int ny,
                                                  detail::PixelRng& rng,
                                                  const detail::PixelSeeds& seeds) const;
    /// One pixel's camera samples at one count, as fast_draw and shadow_uniforms give them,
    /// in one block of doubles: `count` directions (x, y, z), `count` hero-wavelength sets
    /// (kOutside: the sample is outside the field; unused for the LED rays), `rays` uniforms
    /// (u_led, u1, u2).
    struct PixelDraws {
        static constexpr double kOutside = -1.0;
        const double* data;
        int count;
        Vec3 direction(int k) const { return Vec3(data[3 * k], data[3 * k + 1], data[3 * k + 2]); }
        double hero(int k) const { return data[3 * count + k]; }
        std::array<double, 3> uniforms(int r) const {
            const double* u = data + 4 * count + 3 * r;
            return {u[0], u[1], u[2]};
        }
        static std::size_t size(int count, int rays) { return std::size_t(4 * count + 3 * rays); }
    };
    /// The pixels' camera samples of one of a render's counts (SampleClass), kept from render
    /// to render (RenderSettings::camera_cache_mb): they depend only on the seed, the count
    /// and the shadow rays, not on the frame, and a dataset renders all its frames with its
    /// spec's seed. A pixel's are kept the first time it takes that count (each pixel is
    /// rendered by one thread, so no two fill one entry).
    struct KeptSamples {
        std::uint64_t seed = 0;
        int count = 0, rays = 0;
        std::vector<std::unique_ptr<double[]>> pixel; ///< per image pixel (PixelDraws), or none yet
    };
    /// The counts a fast render draws at: samples_per_pixel, the rims', the mirrored pixels'
    /// and the LED rays'.
    enum SampleClass { kMainClass, kRimClass, kMirrorClass, kLedClass, kSampleClasses };
    mutable std::mutex kept_mutex;
    mutable std::array<KeptSamples, kSampleClasses> kept;
    mutable std::atomic<std::size_t> kept_bytes{0};
    /// Before a render: each sample class's store for its stream and count (emptied where they
    /// changed; `count` 0: the class is not drawn).
    void keep_for(SampleClass sample_class, std::uint64_t seed, int count, int rays,
                  std::size_t budget_bytes) const;
    /// Pixel (x, y)'s samples in a class: the kept ones, else drawn now into `scratch` and
    /// kept where they fit the budget (`budget_bytes`; 0: the store is not this render's, or
    /// keeps nothing, and is not touched); none for a pixel wholly
    /// outside the field. The LED rays (kLedClass) draw from their own stream
    /// (kReflectedLedSeed) with the pixel's own seeds, and keep their directions alone.
    std::optional<PixelDraws> pixel_draws(SampleClass sample_class, int x, int y,
                                          std::uint64_t seed, int count, int rays,
                                          std::size_t budget_bytes,
                                          std::vector<double>& scratch) const;
    /// The stream of the rays for the LEDs seen by reflection: the pixel's own seed and index,
    /// the seed changed by this, so that they are independent of the pixel's samples.
    static constexpr std::uint64_t kReflectedLedSeed = 0x4C45445245464C31ull;
    void sample_pixels_fast(int x, int y, int pixels, int nx, int ny,
                            const RenderSettings& settings, double scale, const PixelSums& out,
                            SampleClass sample_class, std::size_t budget_bytes) const;
    /// The LED rays' culling (leds_out_of_reach): the pixel's mirrored footprint on the LEDs'
    /// plane may bulge past its corners' quadrilateral (the inner surface is curved): the LEDs
    /// are grown by kReflectionMargin_mm plus this share of the quadrilateral's diameter.
    static constexpr double kLedCullSpread = 0.25;
    /// Whether each of `pixels` neighbouring pixels of row y from x provably mirrors no LED
    /// (reflected_leds then traces none of its rays: they would all miss): the rays through its 4
    /// corners meet the inner surface, and their reflections (the interpolated normal, as
    /// FastIntegrator::reflected_leds16 reflects) cross the LEDs' plane as a strictly convex
    /// quadrilateral that meets no LED's rectangle grown by kReflectionMargin_mm plus
    /// kLedCullSpread times its diameter (PathIntegrator::quad_near_led). A corner outside the
    /// field, a miss, a reflection that never reaches the plane or a folded quadrilateral: no
    /// proof, the pixel is traced.
    void leds_out_of_reach(int x, int y, int pixels, std::span<std::uint8_t> out) const;
    /// The LEDs seen by reflection in `pixels` neighbouring pixels of row y from x, apart
    /// (LedSums): RenderSettings::reflected_led_samples_per_pixel rays a pixel, each pixel's
    /// positions multi-jittered over it (draw(), the field's edge as for the samples) from
    /// its own stream (kReflectedLedSeed), in packets of 16; none in a pixel that provably
    /// mirrors no LED (leds_out_of_reach: its rays would all miss, so its sums are the same).
    void reflected_leds(int x, int y, int pixels, const RenderSettings& settings,
                        std::span<LedSums> out, std::size_t budget_bytes) const;
    /// The most pixels sample_pixels_fast takes at once: 16 samples' worth.
    static constexpr int kMaxBatchPixels = 16;
    template <int N>
    void batches(int x, int y, int pixels, int nx, int ny, const RenderSettings& settings,
                 double scale, const PixelSums& out, SampleClass sample_class,
                 std::size_t budget_bytes) const;

    /// Image value per unit radiance for this integrator.
    double scale_for(const RenderSettings& settings) const {
        return settings.integrator != Integrator::preview && path_scale ? *path_scale : scale;
    }

    /// Camera RGB (before exposure) of one sample along the ray: the RGB mode's lanes, or 16
    /// hero wavelengths from u_lambda (a tabulated set), through the preview or the path
    /// integrator (the fast integrator takes a pixel's samples together: sample_pixels_fast).
    template <Integrator I>
    detail::Rgb sample_rgb(const detail::EmbreeScene& in, const Vec3& origin, const Vec3& direction,
                           double u_lambda, detail::PixelRng& rng) const;

    /// Each pixel's count class (render()'s `classes`): 2 where an LED is mirrored (with
    /// `mirrors`), 1 on a marker's rim (with `rims`: markers with triangles, render() checks),
    /// 0 elsewhere; a pixel that is both is 2.
    /// - Mirrored (RenderSettings::reflection_samples_per_pixel): the pixels whose centre's
    ///   ray, reflected off the inner surface it meets first (the interpolated normal),
    ///   crosses the LEDs' plane within kReflectionMargin_mm of an LED plus the pixel's reach
    ///   there (half the largest distance to its 4 neighbours' crossings), and their 8
    ///   neighbours.
    /// - Rims (RenderSettings::rim_samples_per_pixel): the pixels whose 4 corners' markers
    ///   (marker_ids_row: the first of each layer before the coating, along the camera ray
    ///   refracted at the inner surface as the samples are, so that the rims stay in place
    ///   where a press tilts the surface) are not all the same: a marker's rim crosses the
    ///   pixel. The corners mark only the pixels a rim crosses, not a band of neighbours that
    ///   holds no rim. A rim that enters and leaves the pixel between the same two corners is
    ///   missed: a sliver of at most w^2 / (8 r) of it for a marker of radius r px (0.04 px^2
    ///   for the markers' 3.5 px at 224 px), sampled at the pixel's own count.
    std::vector<std::uint8_t> pixel_classes(bool mirrors, bool rims) const;
    /// Where each pixel centre's ray, reflected off the inner surface it meets first, crosses
    /// the LEDs' plane (none: it meets no inner surface, or does not cross), 16 rays a packet
    /// (from a camera in the cavity against the inner surface alone).
    std::vector<std::optional<Vec3>> led_plane_crossings() const;
    /// 1 where a pixel's crossing lies within kReflectionMargin_mm plus its reach of an LED.
    std::vector<std::uint8_t>
    mirroring_pixels(const std::vector<std::optional<Vec3>>& crossing) const;

    /// The markers the camera rays through the pixels' corners (i, y), i = 0 .. out.size() - 1,
    /// show, as the fast integrator's samples see them (FastIntegrator::marker_ids16: refracted
    /// into the layers at the inner surface); outside the field none (-1, -1). 16 rays at a
    /// time, as Embree packets.
    void marker_ids_row(int y, std::span<std::pair<std::int32_t, std::int32_t>> out) const;

    /// The marker of each layer (index within the layer, or -1) that the ray through the
    /// pixel's centre meets first before the coating: refracted into the layers at the inner
    /// surface as the path and fast integrators' rays are (`refracted`;
    /// FastIntegrator::marker_ids16), else straight through it as the preview integrator sees.
    std::pair<std::int32_t, std::int32_t> marker_ids(int x, int y, bool refracted) const;
    /// The markers of each layer that the straight ray through image point `at` meets first
    /// before the coating (px; pixel (x, y) spans [x, x + 1) x [y, y + 1)), as the preview
    /// integrator sees through the inner surface; outside the field none.
    std::pair<std::int32_t, std::int32_t> marker_ids_at(const Eigen::Vector2d& at) const;

    /// render()'s parts (defined after Impl).
    struct Counts;
    struct Writer;
    std::size_t prepare_kept(const RenderSettings& settings, const Counts& counts,
                             std::unique_lock<std::mutex>& lock) const;
    /// The integrators as the pixel loop sees them, one type each (the integrator interface):
    /// render() picks one per image (sampler_for, std::visit) and runs render_row for it, so
    /// the loop over pixels exists once and no pixel, sample or ray asks which integrator it
    /// is in. Direct and path take one pixel at a time through sample_pixel<I>; fast takes
    /// runs of pixels of one count in packets of 16 (sample_pixels_fast).
    template <Integrator I> struct Sampler { static constexpr Integrator integrator = I; };
    using AnySampler = std::variant<Sampler<Integrator::preview>, Sampler<Integrator::path>,
                                    Sampler<Integrator::fast>>;
    static AnySampler sampler_for(Integrator integrator);
    template <Integrator I>
    void render_row(Sampler<I>, int y, const RenderSettings& settings, const Counts& counts,
                    std::size_t budget, Writer& write) const;

    int triangles_per_marker = 0;

    /// After a new light cache: the loaded frame's data for it (if a frame is loaded).
    void refresh_fast_frame() {
        if (!scene.has_frame()) return;
        fast.set_frame(frame, scene);
    }
};

} // namespace chromasim::render
