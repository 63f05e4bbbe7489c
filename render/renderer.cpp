// The coarse render stage: every pixel value comes from Embree rays through the deformed
// sensor; no texture or analytic shortcut stands in for geometry.
//
// Shading model (linear RGB per channel; a full spectral path tracer comes later)
// -------------------------------------------------------------------------------
// Camera. FisheyeCamera: by default the equidistant fisheye at the origin looking along +z;
// or OpenCV's Kannala-Brandt model, at any pose in the dome frame. Each pixel averages
// `samples_per_pixel` samples, one per cell of an nx x ny grid (nx the largest divisor of the
// count not above its square root), multi-jittered so that they also fall one per column and
// row of the pixel (detail::multi_jittered). Samples outside the field (the image circle) are
// black. The jitters come from a SplitMix64 stream and the permutations from seeds, both from
// (settings.seed, pixel index), so an image depends on neither the thread count nor the order
// in which TBB runs the rows.
//
// Camera ray. Traced from the camera position through the scene, surface after surface (closest
// hit, then again from kHitGap_mm past it, at most kMaxHits surfaces), with an RGB throughput that
// starts at 1. Normals are the triangles' geometric normals turned to face the camera ray,
// so triangle winding never matters; cos is the cosine between ray and that normal.
//   - markers are closed volumes (prisms deformed with the FE mesh, faces wound outwards):
//     a hit against a face's normal enters, along it leaves; on leaving (or where the ray
//     stops inside) throughput *= exp(-a * L), L the distance travelled inside, so grazing
//     rays take the real chord and a ray starting inside counts from its start.
//   - inner marker (magenta, translucent filter): absorption a_in only.
//   - outer marker (cyan, dyed scatterer), on entering: radiance += throughput * s *
//     albedo_out / pi * E(p); throughput *= (1 - s). s = outer_marker_scatter_fraction.
//   - coating (white, Lambertian): radiance += throughput * albedo_coat / pi * E(p); stop.
//   - miss: stop (black).
//
// Irradiance. E(p) = sum over the led_count point LEDs (evenly on a ring of radius
// led_ring_radius_mm at height led_z_mm, the first on +x, each emitting led_rgb with a
// Lambertian (cosine) pattern about +z):
//     I * max(0, cos_emit) * max(0, cos_surface) / d^2 * T(LED -> p),
// where T multiplies, along the shadow segment (iterated Embree hits, stopping kHitGap_mm
// before p), exp(-a * L) for the path L inside each marker crossed, (1 - s) for each outer
// marker entered, and 0 if the coating is in the way (a deep indentation shadowing itself).
// Light scattered between surfaces (coating -> marker -> coating) is left out.
//
// Exposure. Computed once per Renderer from OpticsParams and the undeformed geometry: the
// radiance of the Lambertian coating at the apex (0, 0, kCoatingInnerRadius_mm) facing the
// camera, lit by all LEDs with no markers, L_ref = max over channels of
// albedo_coat / pi * E(apex). Image = radiance * exposure * 0.8 / L_ref, the same scale for
// every frame so that frames of a sequence stay comparable. The path and fast integrators
// use Renderer::set_exposure_reference instead: the brightest of the bare dome's directions.
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
#include <utility>
#include <vector>

namespace chromasim::render {

namespace detail {

namespace {

/// Inner radius of the white coating, mm [K] (SENSOR.md section 1): the undeformed surface
/// the camera sees, so the apex used for auto exposure is (0, 0, 12.7).
constexpr double kCoatingInnerRadius_mm = 12.7;
/// Image value of the exposure reference at exposure 1, headroom for brighter spots.
constexpr double kApexImageValue = 0.8;

/// exposure * 0.8 / L_ref (see the model at the top of this file).
double exposure_scale(const ShadingModel& shading) {
    const Vec3 apex_mm(0.0, 0.0, kCoatingInnerRadius_mm);
    const Vec3 normal(0.0, 0.0, -1.0);
    const OpticsParams& o = shading.optics();
    // Spectral: the camera RGB of the LED spectrum on the coating's albedo, white balanced.
    const Rgb radiance =
        o.spectra ? Rgb(rgb_of_reflectance(o.spectra->camera, o.spectra->coating_albedo) *
                        o.led_rgb.mean() / std::numbers::pi *
                        shading.unoccluded_geometry(apex_mm, normal))
                  : Rgb(o.coating_albedo.array() / std::numbers::pi *
                        shading.unoccluded_irradiance(apex_mm, normal));
    const double reference = radiance.maxCoeff();
    if (!(reference > 0.0)) {
        throw std::invalid_argument(
            "OpticsParams: the LEDs leave the undeformed apex (0, 0, 12.7) mm dark, so auto "
            "exposure is undefined; allowed: led_rgb and coating_albedo not all zero, and "
            "led_z_mm below the apex so that the LEDs shine on it");
    }
    return shading.optics().exposure * kApexImageValue / reference;
}

/// Throws std::invalid_argument unless the marker meshes split into whole fans.
void validate_marker_layout(const SensorFrame& frame) {
    const Eigen::Index tpm = frame.triangles_per_marker;
    for (const auto* mesh : {&frame.inner_markers, &frame.outer_markers}) {
        const Eigen::Index n = mesh->F.rows();
        if (n == 0) continue;
        if (tpm < 1 || n % tpm != 0) {
            throw std::invalid_argument(
                "SensorFrame: triangles_per_marker = " + std::to_string(tpm) +
                " does not divide the " + std::to_string(n) +
                " marker triangles; allowed: an integer >= 1 that divides each marker mesh's "
                "triangle count");
        }
    }
}

} // namespace

} // namespace detail

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
    const GridDirections& grid_directions() const {
        std::call_once(grid_once, [this] {
            const int w = camera.width_px(), h = camera.height_px();
            const Vec3 none = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
            const auto fill = [&](std::vector<Vec3>& out, int nx, int ny, double offset) {
                out.resize(std::size_t(nx) * std::size_t(ny));
                for (int y = 0; y < ny; ++y)
                    for (int x = 0; x < nx; ++x) {
                        const auto d = camera.direction(Eigen::Vector2d(x + offset, y + offset));
                        out[std::size_t(y) * std::size_t(nx) + std::size_t(x)] = d ? *d : none;
                    }
            };
            fill(grid.corners, w + 1, h + 1, 0.0);
            fill(grid.centres, w, h, 0.5);
        });
        return grid;
    }
    /// grid_directions' ray through corner (x, y) (centre: of pixel (x, y)); none outside the
    /// field. Pre-condition: grid_directions() called.
    std::optional<Vec3> grid_direction(int x, int y, bool centre) const {
        const std::size_t nx = std::size_t(camera.width_px()) + (centre ? 0 : 1);
        const Vec3& d =
            (centre ? grid.centres : grid.corners)[std::size_t(y) * nx + std::size_t(x)];
        if (std::isnan(d.x())) return std::nullopt;
        return d;
    }
    double scale; ///< image value per unit radiance (analytic: the direct model's apex)
    /// The path integrator's scale once set_exposure_reference measured its apex.
    std::optional<double> path_scale;
    double led_scale; ///< spectral mode: relative LED intensity (mean of led_rgb)
    /// Spectral mode: wavelengths drawn in proportion to what the camera sees of the LED
    /// (camera_weight), 10 % uniform: per sample, a white surface's standard deviation falls
    /// from 0.42, 0.29, 1.15 (R, G, B) with uniform wavelengths to 0.22, 0.12, 0.21
    /// (tests/render/test_spectrum.cpp).
    std::optional<WavelengthSampler> wavelengths;

    Impl(const CameraParams& camera_params, const OpticsParams& optics)
        : camera(camera_params), shading(optics), scale(detail::exposure_scale(shading)),
          led_scale(optics.led_rgb.mean()) {
        if (optics.spectra) {
            wavelengths.emplace(camera_weight(optics.spectra->camera));
            tabulate_hero_sets(*optics.spectra);
        }
    }

    /// The spectral mode's hero-wavelength sets, tabulated once per sensor: set i holds the
    /// N (16, or the fast integrator's 8) wavelengths WavelengthSampler draws from u = (i + 1/2) /
    /// kHeroSets, the spectra at them (lanes) and the weights that turn the lanes' radiance into
    /// white-balanced camera RGB, self-normalised so that each set renders the LED's white exactly
    /// (camera_rgb_weights). A sample picks set floor(u
    /// kHeroSets): the wavelengths then come from a 1024-point midpoint rule in the sampling
    /// distribution's CDF, and a sample costs one table read instead of 16 CDF inversions and
    /// 128 spectrum lookups. (Over the table, the plain weights were within 1e-3 of white of
    /// the trapezoid integral, in blue; self-normalised, within 7.6e-4 on the marker filters
    /// and exact on the white: tests/render/test_spectrum.cpp.)
    static constexpr int kHeroSets = 1024;
    template <int N> struct HeroSetN {
        detail::LanesN<N> lambda_nm;
        detail::LaneOptics<N> lanes;
        Eigen::Matrix<double, 3, N> to_rgb;
        /// lambda_nm on the fast integrator's light-cache grid.
        detail::CacheLambdas<N> cache_lambdas{detail::LanesN<N>::Zero()};
    };
    using HeroSet = HeroSetN<detail::kSpectralLanes>;
    /// The sets of the direct and path integrators, and of the fast one at 16 wavelengths
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
    detail::Rgb sample_pixel(int x, int y, int nx, int ny, const RenderSettings& settings,
                             double scale, detail::Rgb* sum2, int& inside) const {
        const std::uint64_t index = std::uint64_t(y) * std::uint64_t(camera.width_px()) + x;
        detail::PixelRng rng(settings.seed, index);
        const detail::PixelSeeds seeds(settings.seed, index);
        detail::Rgb sum = detail::Rgb::Zero();
        inside = 0;
        for (int sy = 0; sy < ny; ++sy) {
            for (int sx = 0; sx < nx; ++sx) {
                const Draw d = draw(x, y, sy * nx + sx, nx, ny, rng, seeds);
                if (!d.direction) continue;
                ++inside;
                const detail::Rgb value = sample_rgb(scene, camera.origin_mm(), *d.direction,
                                                     settings.integrator, d.u_lambda, rng);
                sum += value;
                if (sum2) *sum2 += (value * scale).square();
            }
        }
        return sum;
    }

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
              const detail::PixelSeeds& seeds) const {
        const int count = nx * ny;
        Draw d;
        const double jx = rng.uniform(), jy = rng.uniform();
        const auto [u, v] = detail::multi_jittered(k, nx, ny, seeds.position, jx, jy);
        d.direction = camera.direction(Eigen::Vector2d(x + u, y + v));
        // Outside the field in a pixel its edge crosses: a position drawn anew, uniformly
        // over the pixel until inside (at most kFieldRedraws tries; still outside: the sample
        // is dropped). With the pixel's value the coverage times the mean of its samples
        // inside (render()), this keeps the estimate unbiased: stratum k's sample is uniform
        // over the part of the stratum inside, else over the part of the pixel inside, and
        // those two weigh in as the coverage and its complement.
        if (!d.direction && camera.field_coverage(x, y) > 0.0)
            for (int i = 0; i < kFieldRedraws && !d.direction; ++i) {
                const double rx = rng.uniform(), ry = rng.uniform();
                d.direction = camera.direction(Eigen::Vector2d(x + rx, y + ry));
            }
        if (wavelengths)
            d.u_lambda =
                (detail::wavelength_stratum(k, count, seeds.wavelength) + rng.uniform()) / count;
        return d;
    }

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
                                                  const detail::PixelSeeds& seeds) const {
        const Draw d = draw(x, y, k, nx, ny, rng, seeds);
        if (!d.direction) return std::nullopt;
        const int hero =
            hero_sets.empty() ? 0 : std::clamp(int(d.u_lambda * kHeroSets), 0, kHeroSets - 1);
        return std::make_pair(*d.direction, hero);
    }
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
    /// The pixels' camera samples of one of a render's counts (KeptLevel), kept from render
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
    enum KeptLevel { kMainLevel, kRimLevel, kMirrorLevel, kLedLevel, kKeptLevels };
    mutable std::mutex kept_mutex;
    mutable std::array<KeptSamples, kKeptLevels> kept;
    mutable std::atomic<std::size_t> kept_bytes{0};
    /// Before a render: each level's store for its stream and count (emptied where they
    /// changed; `count` 0: the level is not drawn).
    void keep_for(KeptLevel level, std::uint64_t seed, int count, int rays,
                  std::size_t budget_bytes) const {
        KeptSamples& k = kept[level];
        std::size_t pixels =
            budget_bytes > 0 && count > 0 ? std::size_t(camera.width_px()) * camera.height_px() : 0;
        if (k.seed == seed && k.count == count && k.rays == rays && k.pixel.size() == pixels)
            return;
        for (const auto& d : k.pixel)
            if (d) kept_bytes -= PixelDraws::size(k.count, k.rays) * sizeof(double);
        kept_bytes -= k.pixel.size() * sizeof(std::unique_ptr<double[]>);
        k.pixel.clear();
        k.pixel.shrink_to_fit();
        k.seed = seed, k.count = count, k.rays = rays;
        // The budget holds the pixels' index too (8 bytes a pixel and count).
        const std::size_t index_bytes = pixels * sizeof(std::unique_ptr<double[]>);
        if (kept_bytes + index_bytes > budget_bytes) pixels = 0;
        kept_bytes += pixels * sizeof(std::unique_ptr<double[]>);
        k.pixel.resize(pixels);
    }
    /// Pixel (x, y)'s samples at a level: the kept ones, else drawn now into `scratch` and
    /// kept where they fit the budget (`budget_bytes`; 0: the store is not this render's, or
    /// keeps nothing, and is not touched); none for a pixel wholly
    /// outside the field. The LED rays (kLedLevel) draw from their own stream
    /// (kReflectedLedSeed) with the pixel's own seeds, and keep their directions alone.
    std::optional<PixelDraws> pixel_draws(KeptLevel level, int x, int y, std::uint64_t seed,
                                          int count, int rays, std::size_t budget_bytes,
                                          std::vector<double>& scratch) const {
        KeptSamples& k = kept[level]; // keep_for: for this seed, count and rays
        const std::size_t index = pixel_index(x, y);
        const bool keep = budget_bytes > 0 && !k.pixel.empty(); // the store, within the budget
        if (keep && k.pixel[index]) return PixelDraws{k.pixel[index].get(), count};
        if (!(camera.field_coverage(x, y) > 0.0)) return std::nullopt;
        const auto [nx, ny] = detail::strata_grid(count);
        detail::PixelRng rng(seed, index);
        const detail::PixelSeeds seeds =
            level == kLedLevel ? detail::PixelSeeds(seed, index) : pixel_seeds(seed, x, y);
        const std::size_t size = PixelDraws::size(count, rays);
        scratch.resize(size);
        for (int s = 0; s < count; ++s) {
            const auto d = fast_draw(x, y, s, nx, ny, rng, seeds);
            const Vec3 w = d ? d->first : Vec3::Zero();
            for (int a = 0; a < 3; ++a)
                scratch[std::size_t(3 * s + a)] = w[a];
            scratch[std::size_t(3 * count + s)] = d ? double(d->second) : PixelDraws::kOutside;
        }
        for (int r = 0; r < rays; ++r) {
            const std::array<double, 3> u = detail::shadow_uniforms(r, rays, seeds);
            for (int a = 0; a < 3; ++a)
                scratch[std::size_t(4 * count + 3 * r + a)] = u[std::size_t(a)];
        }
        if (keep) {
            const std::size_t bytes = size * sizeof(double);
            if (kept_bytes.fetch_add(bytes) + bytes <= budget_bytes) {
                k.pixel[index] = std::make_unique_for_overwrite<double[]>(size);
                std::copy(scratch.begin(), scratch.end(), k.pixel[index].get());
                return PixelDraws{k.pixel[index].get(), count};
            }
            kept_bytes -= bytes; // over the budget: drawn anew each render
        }
        return PixelDraws{scratch.data(), count};
    }
    /// The stream of the rays for the LEDs seen by reflection: the pixel's own seed and index,
    /// the seed changed by this, so that they are independent of the pixel's samples.
    static constexpr std::uint64_t kReflectedLedSeed = 0x4C45445245464C31ull;
    void sample_pixels_fast(int x, int y, int pixels, int nx, int ny,
                            const RenderSettings& settings, double scale, const PixelSums& out,
                            KeptLevel level, std::size_t budget_bytes) const {
        if (hero_sets.empty())
            batches<detail::kRgbLanes>(x, y, pixels, nx, ny, settings, scale, out, level,
                                       budget_bytes);
        else if (fast_wavelengths_of(settings) == detail::kFastSpectralLanes)
            batches<detail::kFastSpectralLanes>(x, y, pixels, nx, ny, settings, scale, out, level,
                                                budget_bytes);
        else
            batches<detail::kSpectralLanes>(x, y, pixels, nx, ny, settings, scale, out, level,
                                            budget_bytes);
        if (!out.led.empty()) reflected_leds(x, y, pixels, settings, out.led, budget_bytes);
    }
    /// RenderSettings::cull_reflected_leds: the pixel's mirrored footprint on the LEDs' plane
    /// may bulge past its corners' quadrilateral (the inner surface is curved): the LEDs are
    /// grown by kReflectionMargin_mm plus this share of the quadrilateral's diameter.
    static constexpr double kLedCullSpread = 0.25;
    /// Whether each of `pixels` neighbouring pixels of row y from x provably mirrors no LED
    /// (RenderSettings::cull_reflected_leds; reflected_leds then traces none of its rays:
    /// they would all miss): the rays through its 4 corners meet the inner surface, and their
    /// reflections (the interpolated normal, as FastIntegrator::reflected_leds16 reflects)
    /// cross the LEDs' plane as a strictly convex quadrilateral that meets no LED's rectangle
    /// grown by kReflectionMargin_mm plus kLedCullSpread times its diameter
    /// (PathIntegrator::quad_near_led). A corner outside the field, a miss, a reflection that
    /// never reaches the plane or a folded quadrilateral: no proof, the pixel is traced.
    void leds_out_of_reach(int x, int y, int pixels, std::span<std::uint8_t> out) const {
        grid_directions();
        const double inf = std::numeric_limits<double>::infinity();
        const bool cavity = scene.in_cavity(camera.origin_mm());
        std::array<Vec3, 16> origins, directions;
        origins.fill(camera.origin_mm());
        std::array<detail::RayHit, 16> hits;
        // 4 pixels' corners a packet.
        for (int j0 = 0; j0 < pixels; j0 += 4) {
            const int n = std::min(4, pixels - j0);
            std::array<bool, 4> valid{};
            for (int j = 0; j < n; ++j) {
                valid[std::size_t(j)] = true;
                for (int c = 0; c < 4; ++c) {
                    const auto d = grid_direction(x + j0 + j + (c & 1), y + (c >> 1), false);
                    valid[std::size_t(j)] = valid[std::size_t(j)] && d.has_value();
                    directions[std::size_t(4 * j + c)] = d ? *d : Vec3::UnitZ();
                }
            }
            const std::size_t m = std::size_t(4 * n);
            const auto o = std::span(origins.data(), m), d = std::span(directions.data(), m);
            if (cavity)
                scene.closest_interface_hits16(o, d, 0.0, inf, std::span(hits.data(), m));
            else
                scene.closest_hits16(o, d, 0.0, inf, std::span(hits.data(), m));
            for (int j = 0; j < n; ++j) {
                std::array<Vec3, 4> q;
                bool proof = valid[std::size_t(j)];
                for (int c = 0; c < 4 && proof; ++c) {
                    const std::size_t i = std::size_t(4 * j + c);
                    const detail::RayHit& hit = hits[i];
                    if (!hit.hit() || hit.kind != detail::SurfaceKind::inner_surface) {
                        proof = false;
                        break;
                    }
                    const Vec3& dir = directions[i];
                    const Vec3 normal = detail::facing(hit.shading_normal, dir);
                    const Vec3 reflected = (dir - 2.0 * dir.dot(normal) * normal).normalized();
                    const auto crossing =
                        path.led_plane_crossing(camera.origin_mm() + hit.t_mm * dir, reflected);
                    if (!crossing || !crossing->allFinite())
                        proof = false;
                    else
                        q[std::size_t(c)] = *crossing;
                }
                if (proof) {
                    double spread = 0.0;
                    for (int a = 0; a < 4; ++a)
                        for (int b = a + 1; b < 4; ++b)
                            spread =
                                std::max(spread, (q[std::size_t(a)] - q[std::size_t(b)]).norm());
                    // Round the quad: corners 0 (x, y), 1 (x + 1, y), 3, 2.
                    proof = !path.quad_near_led({q[0], q[1], q[3], q[2]},
                                                kReflectionMargin_mm + kLedCullSpread * spread);
                }
                out[std::size_t(j0 + j)] = proof;
            }
        }
    }
    /// The LEDs seen by reflection in `pixels` neighbouring pixels of row y from x, apart
    /// (LedSums): RenderSettings::reflected_led_samples_per_pixel rays a pixel, each pixel's
    /// positions multi-jittered over it (draw(), the field's edge as for the samples) from
    /// its own stream (kReflectedLedSeed), in packets of 16; none in a pixel that provably
    /// mirrors no LED (leds_out_of_reach: its rays would all miss, so its sums are the same).
    void reflected_leds(int x, int y, int pixels, const RenderSettings& settings,
                        std::span<LedSums> out, std::size_t budget_bytes) const {
        const int count = settings.reflected_led_samples_per_pixel;
        std::array<std::uint8_t, kMaxBatchPixels> skip{};
        if (settings.cull_reflected_leds)
            leds_out_of_reach(x, y, pixels, std::span(skip.data(), std::size_t(pixels)));
        std::array<Vec3, 16> directions;
        std::array<int, 16> owner;
        std::array<double, 16> fresnel;
        std::size_t m = 0;
        const auto flush = [&] {
            fast.reflected_leds16(scene, camera.origin_mm(), std::span(directions.data(), m),
                                  std::span(fresnel.data(), m));
            for (std::size_t i = 0; i < m; ++i) {
                LedSums& sums = out[std::size_t(owner[i])];
                sums.sum += fresnel[i];
                sums.sum2 += fresnel[i] * fresnel[i];
            }
            m = 0;
        };
        thread_local std::vector<double> scratch;
        for (int j = 0; j < pixels; ++j) {
            LedSums& sums = out[std::size_t(j)];
            sums = {};
            if (skip[std::size_t(j)]) continue;
            const auto draws = pixel_draws(kLedLevel, x + j, y, settings.seed ^ kReflectedLedSeed,
                                           count, 0, budget_bytes, scratch);
            if (!draws) continue;
            for (int k = 0; k < count; ++k) {
                if (draws->hero(k) == PixelDraws::kOutside) continue;
                ++sums.inside;
                directions[m] = draws->direction(k);
                owner[m++] = j;
                if (m == directions.size()) flush();
            }
        }
        if (m > 0) flush();
    }
    /// The most pixels sample_pixels_fast takes at once: 16 samples' worth.
    static constexpr int kMaxBatchPixels = 16;
    template <int N>
    void batches(int x, int y, int pixels, int nx, int ny, const RenderSettings& settings,
                 double scale, const PixelSums& out, KeptLevel level,
                 std::size_t budget_bytes) const {
        const int count = nx * ny;
        const bool split = !out.direct.empty();
        const int rays = shadow_rays(settings, count);
        const auto groups = std::size_t(split ? fast.shadow_groups() : 0);
        const detail::LaneOptics<N> rgb = [&] {
            if constexpr (N == detail::kRgbLanes)
                return shading.rgb_lanes();
            else
                return detail::LaneOptics<N>{};
        }();
        // Each pixel's camera samples (kept, or drawn now into a scratch of its own), and its
        // shading's stream (kShadeSeed: apart from the draws', so that kept samples are the
        // ones drawn anew).
        thread_local std::array<std::vector<double>, kMaxBatchPixels> scratch;
        std::array<std::optional<PixelDraws>, kMaxBatchPixels> draws;
        std::array<std::optional<detail::PixelRng>, kMaxBatchPixels> shade_rngs;
        for (int j = 0; j < pixels; ++j) {
            draws[std::size_t(j)] = pixel_draws(level, x + j, y, settings.seed, count, rays,
                                                budget_bytes, scratch[std::size_t(j)]);
            shade_rngs[std::size_t(j)].emplace(settings.seed ^ kShadeSeed, pixel_index(x + j, y));
            out.sums[std::size_t(j)] = detail::Rgb::Zero();
            out.inside[std::size_t(j)] = 0;
            if (!out.sum2.empty()) out.sum2[std::size_t(j)] = detail::Rgb::Zero();
            for (std::size_t g = 0; g < groups; ++g) {
                DirectSums& d = out.direct[std::size_t(j)];
                d.lit[g] = d.chosen[g] = d.shadowed[g] = detail::Rgb::Zero();
            }
        }
        std::array<Vec3, 16> directions;
        std::array<const detail::LaneOptics<N>*, 16> lanes;
        std::array<const detail::CacheLambdas<N>*, 16> lambda;
        std::array<const HeroSetN<N>*, 16> sets;
        std::array<detail::ShadowDraw, 16> shadow;
        std::array<detail::PixelRng*, 16> streams;
        std::array<int, 16> owner; // the sample's pixel, 0 .. pixels - 1
        std::array<detail::LanesN<N>, 16> radiance;
        std::array<detail::DirectLight<N>, 16> direct;
        // Packets of equal size: 20 samples as 10 + 10, not 16 + 4 (a part-empty packet
        // wastes Embree's lanes; docs/VALIDATION.md, session 15).
        const int total = pixels * count;
        const int packets = (total + 15) / 16, size = (total + packets - 1) / packets;
        for (int first = 0; first < total; first += size) {
            std::size_t m = 0;
            for (int s = first; s < std::min(total, first + size); ++s) {
                const int j = s / count, k = s % count;
                // The sample's shadow rays: the pixel's `rays` spread evenly over its samples
                // (at least one each), their uniforms stratified over the pixel's rays.
                const int r0 = k * rays / count, r1 = (k + 1) * rays / count;
                const std::optional<PixelDraws>& d = draws[std::size_t(j)];
                if (!d || d->hero(k) == PixelDraws::kOutside) continue;
                const int hero = int(d->hero(k));
                ++out.inside[std::size_t(j)];
                directions[m] = d->direction(k);
                const std::array<double, 3> u = d->uniforms(r0);
                shadow[m] = {.u_led = u[0], .u1 = u[1], .u2 = u[2], .rays = r1 - r0};
                for (int r = r0 + 1; r < r1; ++r)
                    shadow[m].further[std::size_t(r - r0 - 1)] = d->uniforms(r);
                streams[m] = &*shade_rngs[std::size_t(j)];
                owner[m] = j;
                if constexpr (N != detail::kRgbLanes) {
                    // Set hero / N: the lanes of set i sit at (i + 1/2) / kHeroSets + l / N
                    // in the sampling CDF, so sets i and i + kHeroSets / N hold the same
                    // wavelengths, and a draw's stratum over [0, 1) is no stratum of them.
                    // Scaled into [0, 1 / N), sample k's lanes lie in stratum k of each of
                    // the N intervals: a pixel's count x N wavelengths are stratified
                    // (docs/VALIDATION.md, session 36).
                    const HeroSetN<N>& h = hero_table<N>()[std::size_t(hero / N)];
                    sets[m] = &h, lanes[m] = &h.lanes, lambda[m] = &h.cache_lambdas;
                } else {
                    lanes[m] = &rgb, lambda[m] = nullptr;
                }
                ++m;
            }
            fast.radiance16<N>(scene, camera.origin_mm(), std::span(directions.data(), m),
                               std::span<const detail::LaneOptics<N>* const>(lanes.data(), m),
                               std::span<const detail::CacheLambdas<N>* const>(lambda.data(), m),
                               std::span<const detail::ShadowDraw>(shadow.data(), m),
                               std::span<detail::PixelRng* const>(streams.data(), m),
                               std::span(radiance.data(), m),
                               split ? std::span(direct.data(), m)
                                     : std::span<detail::DirectLight<N>>{},
                               out.led.empty());
            for (std::size_t i = 0; i < m; ++i) {
                const auto rgb_of = [&](const detail::LanesN<N>& lanes_value) {
                    if constexpr (N != detail::kRgbLanes)
                        return detail::Rgb(sets[i]->to_rgb * lanes_value.matrix());
                    else
                        return detail::Rgb(lanes_value.template head<3>());
                };
                const detail::Rgb value = rgb_of(radiance[i]);
                const auto j = std::size_t(owner[i]);
                out.sums[j] += value;
                if (!out.sum2.empty()) out.sum2[j] += (value * scale).square();
                if (split) {
                    DirectSums& d = out.direct[j];
                    for (int q = 0; q < direct[i].parts; ++q) {
                        const detail::DirectPart<N>& part = direct[i].part[std::size_t(q)];
                        const detail::Rgb lit = rgb_of(part.lit);
                        for (std::size_t g = 0; g < groups; ++g)
                            d.lit[g] += part.share[g] * lit;
                        const auto g = std::size_t(part.group);
                        d.chosen[g] += lit;
                        d.shadowed[g] += part.clear ? lit : rgb_of(part.shadowed);
                    }
                }
            }
        }
    }

    /// Image value per unit radiance for this integrator.
    double scale_for(const RenderSettings& settings) const {
        return settings.integrator != Integrator::direct && path_scale ? *path_scale : scale;
    }

    /// Camera RGB (before exposure) of one sample along the ray: the RGB mode's lanes, or 16
    /// hero wavelengths from u_lambda (a tabulated set), through the direct or the path
    /// integrator (the fast integrator takes a pixel's samples together: sample_pixel_fast).
    detail::Rgb sample_rgb(const detail::EmbreeScene& in, const Vec3& origin, const Vec3& direction,
                           Integrator integrator, double u_lambda, detail::PixelRng& rng) const {
        const bool path_traced = integrator == Integrator::path;
        if (hero_sets.empty()) { // RGB mode
            const auto lanes = shading.rgb_lanes();
            return path_traced
                       ? detail::Rgb(path.radiance(in, origin, direction, lanes, rng).head<3>())
                       : shading.radiance(in, origin, direction);
        }
        const HeroSet& h =
            hero_sets[std::size_t(std::clamp(int(u_lambda * kHeroSets), 0, kHeroSets - 1))];
        const detail::Lanes radiance = path_traced
                                           ? path.radiance(in, origin, direction, h.lanes, rng)
                                           : shading.radiance(in, origin, direction, h.lanes);
        return detail::Rgb(h.to_rgb * radiance.matrix());
    }

    /// Each pixel's count class (render()'s `levels`): 2 where an LED is mirrored (with
    /// `mirrors`), 1 on a marker's rim (with `rims`: markers with triangles, render() checks),
    /// 0 elsewhere; a pixel that is both is 2.
    /// - Mirrored (RenderSettings::reflection_samples_per_pixel): the pixels whose centre's
    ///   ray, reflected off the inner surface it meets first (the interpolated normal),
    ///   crosses the LEDs' plane within kReflectionMargin_mm of an LED plus the pixel's reach
    ///   there (half the largest distance to its 4 neighbours' crossings), and their 8
    ///   neighbours.
    /// - Rims (RenderSettings::edge_samples_per_pixel): the pixels whose 4 corners' markers
    ///   (marker_ids_row: the first of each layer before the coating, along the camera ray
    ///   refracted at the inner surface as the samples are; up to 0.25.0 along the straight
    ///   ray, which misplaced the rims by about a pixel where a press tilts the surface) are
    ///   not all the same: a marker's rim crosses the pixel. (Up to 0.22.0: the pixels whose
    ///   centre's markers differed from one of its 8 neighbours', a band about twice as wide,
    ///   whose extra pixels hold no rim and gained little from their samples;
    ///   docs/VALIDATION.md, session 31.) A rim that enters and leaves the pixel between the
    ///   same two corners is missed: a sliver of at most w^2 / (8 r) of it for a marker of
    ///   radius r px (0.04 px^2 for the markers' 3.5 px at 224 px), sampled at the pixel's
    ///   own count.
    std::vector<std::uint8_t> pixel_levels(bool mirrors, bool rims) const {
        const int w = camera.width_px(), h = camera.height_px();
        grid_directions();
        const std::size_t pixels = std::size_t(w) * std::size_t(h);
        const auto at = [w](int x, int y) { return std::size_t(y) * std::size_t(w) + x; };
        const bool cavity = scene.in_cavity(camera.origin_mm());
        const double inf = std::numeric_limits<double>::infinity();
        // The centres' reflections onto the LEDs' plane, 16 rays a packet (from a camera in
        // the cavity against the inner surface alone: the centres' first surface, if any).
        std::vector<std::optional<Vec3>> crossing(mirrors ? pixels : 0);
        if (mirrors)
            tbb::parallel_for(0, h, [&](int y) {
                std::array<Vec3, 16> origins, directions;
                std::array<detail::RayHit, 16> first;
                std::array<int, 16> xs;
                origins.fill(camera.origin_mm());
                for (int x0 = 0; x0 < w; x0 += 16) {
                    std::size_t m = 0;
                    for (int x = x0; x < std::min(w, x0 + 16); ++x)
                        if (const auto d = grid_direction(x, y, true))
                            directions[m] = *d, xs[m++] = x;
                    if (m == 0) continue;
                    const auto o = std::span(origins.data(), m),
                               d = std::span(directions.data(), m);
                    if (cavity)
                        scene.closest_interface_hits16(o, d, 0.0, inf, std::span(first.data(), m));
                    else
                        scene.closest_hits16(o, d, 0.0, inf, std::span(first.data(), m));
                    for (std::size_t i = 0; i < m; ++i) {
                        const detail::RayHit& hit = first[i];
                        if (!hit.hit() || hit.kind != detail::SurfaceKind::inner_surface) continue;
                        const Vec3& dir = directions[i];
                        const Vec3 normal = detail::facing(hit.shading_normal, dir);
                        const Vec3 reflected = (dir - 2.0 * dir.dot(normal) * normal).normalized();
                        crossing[at(xs[i], y)] =
                            path.led_plane_crossing(camera.origin_mm() + hit.t_mm * dir, reflected);
                    }
                }
            });
        // The markers at the pixels' corners, (w + 1) x (h + 1): corner (x, y) at image point
        // (x, y), the top left one of pixel (x, y).
        const std::size_t corners_per_row = std::size_t(w) + 1;
        std::vector<std::pair<std::int32_t, std::int32_t>> corner_ids(
            rims ? corners_per_row * (std::size_t(h) + 1) : 0);
        if (rims)
            tbb::parallel_for(0, h + 1, [&](int y) {
                marker_ids_row(y, std::span(corner_ids.data() + std::size_t(y) * corners_per_row,
                                            corners_per_row));
            });
        // The pixels that mirror an LED themselves, then with their 8 neighbours.
        std::vector<std::uint8_t> mirrored(mirrors ? pixels : 0, 0);
        if (mirrors)
            tbb::parallel_for(0, h, [&](int y) {
                for (int x = 0; x < w; ++x) {
                    const auto& q = crossing[at(x, y)];
                    if (!q) continue;
                    double reach = 0.0;
                    for (const auto& [dx, dy] : {std::pair{1, 0}, {-1, 0}, {0, 1}, {0, -1}})
                        if (x + dx >= 0 && x + dx < w && y + dy >= 0 && y + dy < h)
                            if (const auto& o = crossing[at(x + dx, y + dy)])
                                reach = std::max(reach, 0.5 * (*o - *q).norm());
                    mirrored[at(x, y)] = path.near_led(*q, kReflectionMargin_mm + reach);
                }
            });
        std::vector<std::uint8_t> out(pixels, 0);
        tbb::parallel_for(0, h, [&](int y) {
            for (int x = 0; x < w; ++x) {
                std::uint8_t& level = out[at(x, y)];
                if (mirrors)
                    for (int dy = -1; dy <= 1 && level == 0; ++dy)
                        for (int dx = -1; dx <= 1; ++dx) {
                            const int qx = x + dx, qy = y + dy;
                            if (qx < 0 || qy < 0 || qx >= w || qy >= h) continue;
                            if (mirrored[at(qx, qy)]) level = 2;
                        }
                if (rims && level == 0) {
                    const std::size_t c = std::size_t(y) * corners_per_row + std::size_t(x);
                    const auto& ids = corner_ids[c];
                    if (corner_ids[c + 1] != ids || corner_ids[c + corners_per_row] != ids ||
                        corner_ids[c + corners_per_row + 1] != ids)
                        level = 1;
                }
            }
        });
        return out;
    }

    /// The markers the camera rays through the pixels' corners (i, y), i = 0 .. out.size() - 1,
    /// show, as the fast integrator's samples see them (FastIntegrator::marker_ids16: refracted
    /// into the layers at the inner surface); outside the field none (-1, -1). 16 rays at a
    /// time, as Embree packets.
    void marker_ids_row(int y, std::span<std::pair<std::int32_t, std::int32_t>> out) const {
        const int n = int(out.size());
        grid_directions();
        std::array<Vec3, 16> directions;
        std::array<std::pair<std::int32_t, std::int32_t>, 16> ids;
        std::array<int, 16> xs;
        for (int x0 = 0; x0 < n; x0 += 16) {
            std::size_t m = 0;
            for (int x = x0; x < std::min(n, x0 + 16); ++x) {
                out[std::size_t(x)] = {-1, -1};
                if (const auto d = grid_direction(x, y, false)) directions[m] = *d, xs[m++] = x;
            }
            if (m == 0) continue;
            fast.marker_ids16(scene, camera.origin_mm(), std::span(directions.data(), m),
                              triangles_per_marker, std::span(ids.data(), m));
            for (std::size_t i = 0; i < m; ++i)
                out[std::size_t(xs[i])] = ids[i];
        }
    }

    /// The marker of each layer (index within the layer, or -1) that the ray through the
    /// pixel's centre meets first before the coating: refracted into the layers at the inner
    /// surface as the path and fast integrators' rays are (`refracted`;
    /// FastIntegrator::marker_ids16), else straight through it as the direct integrator sees.
    std::pair<std::int32_t, std::int32_t> marker_ids(int x, int y, bool refracted) const {
        const Eigen::Vector2d at(x + 0.5, y + 0.5);
        if (!refracted || triangles_per_marker < 1) return marker_ids_at(at);
        const auto direction = camera.direction(at);
        if (!direction) return {-1, -1};
        std::pair<std::int32_t, std::int32_t> ids;
        fast.marker_ids16(scene, camera.origin_mm(), std::span(&*direction, 1),
                          triangles_per_marker, std::span(&ids, 1));
        return ids;
    }
    /// The markers of each layer that the straight ray through image point `at` meets first
    /// before the coating (px; pixel (x, y) spans [x, x + 1) x [y, y + 1)), as the direct
    /// integrator sees through the inner surface; outside the field none.
    std::pair<std::int32_t, std::int32_t> marker_ids_at(const Eigen::Vector2d& at) const {
        std::int32_t ids[2] = {-1, -1};
        const auto direction = camera.direction(at);
        if (!direction || triangles_per_marker < 1) return {-1, -1};
        // The hits past the inner surface (left out of the query: the ray goes straight
        // through it), the markers before the coating from one traversal (RayHits).
        double tnear = 0.0;
        detail::RayHits hits(
            scene, camera.origin_mm(), *direction, tnear, std::numeric_limits<double>::infinity(),
            detail::kAllKinds & ~detail::kind_bit(detail::SurfaceKind::inner_surface));
        for (int i = 0; i < detail::kMaxHits; ++i) {
            const detail::RayHit hit = hits.next(tnear);
            if (!hit.hit() || hit.kind == detail::SurfaceKind::coating) break;
            tnear = hit.t_mm + detail::kHitGap_mm;
            std::int32_t& id = ids[hit.kind == detail::SurfaceKind::outer_marker ? 1 : 0];
            if (id < 0) id = std::int32_t(hit.prim_id / std::uint32_t(triangles_per_marker));
        }
        return {ids[0], ids[1]};
    }

    int triangles_per_marker = 0;

    /// After a new light cache: the loaded frame's data for it (if a frame is loaded).
    void refresh_fast_frame() {
        if (!scene.has_frame()) return;
        fast.set_frame(frame, scene);
    }
};

Renderer::Renderer(const CameraParams& camera, const OpticsParams& optics)
    : m_impl(std::make_unique<Impl>(camera, optics)) {}

Renderer::~Renderer() = default;

void Renderer::set_exposure_reference(const SensorFrame& undeformed) {
    // The bare dome: coating and inner surface, no markers.
    SensorFrame bare;
    bare.coating = undeformed.coating;
    bare.inner_surface = undeformed.inner_surface;
    detail::EmbreeScene apex;
    apex.set_frame(bare);
    // Directions along polar angles 0, 10, ..., 70 deg at azimuth 0 (towards the first LED)
    // and half an LED spacing; fixed blocks per direction, each with its own stream, summed in
    // order: the same value on any threads.
    constexpr int kPolar = 8, kAzimuths = 2, kBlocks = 16, kPathsPerBlock = 1024;
    constexpr int kDirections = kPolar * kAzimuths;
    const Impl& m = *m_impl;
    std::vector<detail::Rgb> partial(std::size_t(kDirections * kBlocks), detail::Rgb::Zero());
    const Vec3 origin = Vec3::Zero();
    const double spacing = 2.0 * std::numbers::pi / m.shading.optics().led_count;
    tbb::parallel_for(0, kDirections * kBlocks, [&](int job) {
        const int dir = job / kBlocks;
        const double theta = (dir % kPolar) * 10.0 * std::numbers::pi / 180.0;
        const double phi = (dir / kPolar) * 0.5 * spacing;
        const Vec3 w(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi),
                     std::cos(theta));
        detail::PixelRng rng(0xA9E7, std::uint64_t(job));
        for (int i = 0; i < kPathsPerBlock; ++i) {
            const double u_lambda = m.wavelengths ? (i + rng.uniform()) / kPathsPerBlock : 0.0;
            partial[std::size_t(job)] +=
                m.sample_rgb(apex, origin, w, Integrator::path, u_lambda, rng);
        }
    });
    double reference = 0.0;
    for (int dir = 0; dir < kDirections; ++dir) {
        detail::Rgb sum = detail::Rgb::Zero();
        for (int b = 0; b < kBlocks; ++b)
            sum += partial[std::size_t(dir * kBlocks + b)];
        reference = std::max(reference, (sum / (kBlocks * kPathsPerBlock)).maxCoeff());
    }
    if (!(reference > 0.0)) {
        throw std::invalid_argument(
            "Renderer::set_exposure_reference: the path-traced undeformed dome is dark, so auto "
            "exposure is undefined; allowed: a frame whose coating the LEDs light");
    }
    m_impl->path_scale = m.shading.optics().exposure * detail::kApexImageValue / reference;
}

double Renderer::set_light_cache(const SensorFrame& undeformed,
                                 const LightCacheSettings& settings) {
    detail::validate_marker_layout(undeformed);
    const std::optional<SensorSpectra>& spectra = m_impl->shading.optics().spectra;
    m_impl->fast.build_cache(undeformed, settings, spectra ? &*spectra : nullptr,
                             m_impl->led_scale);
    m_impl->refresh_fast_frame();
    return m_impl->fast.cache().build_s;
}

void Renderer::set_light_cache(LightCache cache, const LightCacheSettings& settings,
                               const SensorFrame& undeformed) {
    detail::validate_marker_layout(undeformed);
    m_impl->fast.adopt_cache(std::move(cache), settings, undeformed);
    m_impl->refresh_fast_frame();
}

const LightCache* Renderer::light_cache() const {
    return m_impl->fast.has_cache() ? &m_impl->fast.cache() : nullptr;
}

void Renderer::set_frame(const SensorFrame& frame) {
    detail::validate_marker_layout(frame);
    if (m_impl->fast.has_cache()) m_impl->fast.check_topology(frame); // before any change
    m_impl->scene.set_frame(frame);
    m_impl->frame.coating = frame.coating;
    m_impl->frame.inner_markers = frame.inner_markers;
    m_impl->frame.outer_markers = frame.outer_markers;
    m_impl->frame.triangles_per_marker = frame.triangles_per_marker;
    if (m_impl->fast.has_cache()) m_impl->fast.set_frame(frame, m_impl->scene);
    m_impl->triangles_per_marker = frame.triangles_per_marker;
}

Image Renderer::render(const RenderSettings& settings) const {
    if (settings.samples_per_pixel < 1) {
        throw std::invalid_argument(
            "RenderSettings: samples_per_pixel = " + std::to_string(settings.samples_per_pixel) +
            " is invalid; allowed: integer >= 1");
    }
    if (!m_impl->scene.has_frame()) {
        throw std::logic_error("Renderer::render called before set_frame");
    }
    if (!(settings.shadow_filter_px >= 0.0 && settings.shadow_filter_px <= kMaxShadowFilterPx)) {
        throw std::invalid_argument(
            "RenderSettings: shadow_filter_px = " + std::to_string(settings.shadow_filter_px) +
            " is invalid; allowed: 0 (none) to " + std::to_string(kMaxShadowFilterPx) + " px");
    }
    if (settings.reflection_samples_per_pixel < 0) {
        throw std::invalid_argument("RenderSettings: reflection_samples_per_pixel = " +
                                    std::to_string(settings.reflection_samples_per_pixel) +
                                    " is invalid; allowed: integer >= 0 (0: none extra)");
    }
    if (settings.shadow_filter_rim_px && !(*settings.shadow_filter_rim_px >= 0.0 &&
                                           *settings.shadow_filter_rim_px <= kMaxShadowFilterPx)) {
        throw std::invalid_argument("RenderSettings: shadow_filter_rim_px = " +
                                    std::to_string(*settings.shadow_filter_rim_px) +
                                    " is invalid; allowed: 0 (each rim "
                                    "pixel alone) to " +
                                    std::to_string(kMaxShadowFilterPx) +
                                    " px, or none (as "
                                    "shadow_filter_px)");
    }
    if (settings.reflected_led_samples_per_pixel < 0) {
        throw std::invalid_argument("RenderSettings: reflected_led_samples_per_pixel = " +
                                    std::to_string(settings.reflected_led_samples_per_pixel) +
                                    " is invalid; allowed: integer >= 0 (0: in the samples)");
    }
    if (settings.shadow_rays_per_pixel < 0) {
        throw std::invalid_argument("RenderSettings: shadow_rays_per_pixel = " +
                                    std::to_string(settings.shadow_rays_per_pixel) +
                                    " is invalid; allowed: integer >= 0 (0: one a sample)");
    }
    if (settings.edge_samples_per_pixel < 0) {
        throw std::invalid_argument("RenderSettings: edge_samples_per_pixel = " +
                                    std::to_string(settings.edge_samples_per_pixel) +
                                    " is invalid; allowed: integer >= 0 (0: none extra)");
    }
    if (settings.fast_wavelengths != 0 && settings.fast_wavelengths != detail::kFastSpectralLanes &&
        settings.fast_wavelengths != detail::kSpectralLanes) {
        throw std::invalid_argument(
            "RenderSettings: fast_wavelengths = " + std::to_string(settings.fast_wavelengths) +
            " is invalid; allowed: 0 (16 at 1 sample per pixel, else " +
            std::to_string(detail::kFastSpectralLanes) + "), " +
            std::to_string(detail::kFastSpectralLanes) + " or " +
            std::to_string(detail::kSpectralLanes));
    }
    if (!(settings.camera_cache_mb >= 0.0)) {
        throw std::invalid_argument("RenderSettings: camera_cache_mb = " +
                                    std::to_string(settings.camera_cache_mb) +
                                    " is invalid; allowed: >= 0 MiB (0: none kept)");
    }
    if (settings.integrator == Integrator::fast && !m_impl->fast.has_cache()) {
        throw std::logic_error("Renderer::render: Integrator::fast needs set_light_cache first");
    }
    Image image;
    image.width = m_impl->camera.width_px();
    image.height = m_impl->camera.height_px();
    const std::size_t pixels = std::size_t(image.width) * image.height;
    image.rgb.assign(3 * pixels, 0.0f);
    if (settings.variance) image.variance.assign(3 * pixels, 0.0f);
    if (settings.marker_ids) {
        image.inner_marker_id.assign(pixels, -1);
        image.outer_marker_id.assign(pixels, -1);
    }
    const Impl& m = *m_impl;
    const double scale = m.scale_for(settings);
    const int n = settings.samples_per_pixel;
    // The fast integrator takes up to 16 / n pixels of a row at once (batch_pixels): runs of
    // pixels at one count n share packets of up to 16 samples (one pixel where n >= 16).
    const bool fast = settings.integrator == Integrator::fast;
    const auto batch_at = [&](int count) {
        return fast && settings.batch_pixels
                   ? std::max(1, Impl::kMaxBatchPixels / std::max(count, 1))
                   : 1;
    };
    const int batch = batch_at(n);
    const auto [nx, ny] = detail::strata_grid(n);
    // Each pixel's count: `levels` 2 where it mirrors an LED, 1 on a marker's rim, 0 (or no
    // levels at all) at samples_per_pixel (RenderSettings); a pixel that is both takes the
    // mirror's count.
    // Where an LED is mirrored: at least n samples; with the LEDs by reflection apart
    // (reflected_led_samples_per_pixel), those pixels are chosen whatever their count.
    const int n_led = fast ? settings.reflected_led_samples_per_pixel : 0;
    const int n_mirror = std::max(settings.reflection_samples_per_pixel, n);
    const int n_edge = settings.edge_samples_per_pixel;
    const bool mirrors = fast && (n_mirror > n || n_led > 0);
    const bool rims = fast && n_edge > n && m.triangles_per_marker > 0;
    const std::vector<std::uint8_t> levels =
        mirrors || rims ? m.pixel_levels(mirrors, rims) : std::vector<std::uint8_t>{};
    const auto [nx_mirror, ny_mirror] = detail::strata_grid(std::max(n_mirror, 1));
    const auto [nx_edge, ny_edge] = detail::strata_grid(std::max(n_edge, 1));
    const int edge_batch = batch_at(n_edge), mirror_batch = batch_at(n_mirror);
    // The camera samples of each count, kept from frame to frame where they fit
    // (RenderSettings::camera_cache_mb). One render at a time uses the store: a render that
    // finds it in use (another thread's render of this renderer) draws its samples anew, the
    // same bytes, and never waits (a wait inside a caller's TBB task could deadlock).
    std::unique_lock kept_lock(m.kept_mutex, std::defer_lock);
    const bool store = fast && kept_lock.try_lock();
    const std::size_t budget =
        store ? std::size_t(std::min(settings.camera_cache_mb, 1e12) * 1024.0 * 1024.0) : 0;
    if (store) { // at a budget of 0 this frees what is kept
        m.keep_for(Impl::kMainLevel, settings.seed, n, Impl::shadow_rays(settings, n), budget);
        const int rim = rims ? n_edge : 0, mirror = mirrors ? n_mirror : 0;
        m.keep_for(Impl::kRimLevel, settings.seed, rim, rim ? Impl::shadow_rays(settings, rim) : 0,
                   budget);
        m.keep_for(Impl::kMirrorLevel, settings.seed, mirror,
                   mirror ? Impl::shadow_rays(settings, mirror) : 0, budget);
        m.keep_for(Impl::kLedLevel, settings.seed ^ Impl::kReflectedLedSeed,
                   mirrors ? n_led : 0, 0, budget);
    }
    // The shadow filter's inputs: each pixel's direct light with and without the shadows.
    const bool filter = fast && settings.shadow_filter_px > 0.0;
    // Per shadow group g (render/shadow_filter.hpp): 9 floats a group and pixel, 216 bytes a
    // pixel with 6 LEDs (10.8 MB at 224 px, 173 MB at 896 px).
    const std::size_t groups = filter ? std::size_t(m.fast.shadow_groups()) : 0;
    // Not zeroed: write() sets every pixel's (at 896 px, zeroing and faulting in 173 MB anew
    // took a few % of a render).
    const std::size_t per_part = 3 * groups * pixels;
    const std::unique_ptr<float[]> direct_light(per_part > 0 ? new float[3 * per_part] : nullptr);
    const std::span<float> lit(direct_light.get(), per_part),
        chosen(direct_light.get() + per_part, per_part),
        shadowed(direct_light.get() + 2 * per_part, per_part);
    // Pixel (x, y)'s value from its sample sum (and sum of squares, and the direct light's).
    // A pixel the field's edge crosses (0 < coverage < 1): its value is the coverage times
    // the mean of its samples inside the field, not the mean of all its samples with those
    // outside black. Both estimate the same pixel integral; the first has no noise from how
    // many samples happen to fall inside (at 224 px the edge's pixels held a fifth of the
    // image's squared error at 4 spp; docs/VALIDATION.md). A pixel none of whose samples
    // fall inside stays black.
    // The LEDs' radiance per unit of F in camera RGB, as the samples' (l.led / the LED's area,
    // the same for every hero-wavelength set: their weights are normalised on the LED).
    const detail::Rgb led_rgb = [&]() -> detail::Rgb {
        if (m.hero_sets.empty()) return m.shading.rgb_lanes().led.head<3>() / m.path.led_area_mm2();
        const Impl::HeroSet& h = m.hero_sets.front();
        return detail::Rgb(h.to_rgb * h.lanes.led.matrix()) / m.path.led_area_mm2();
    }();
    // `led`: the pixel's LEDs by reflection apart (reflected_led_samples_per_pixel), or none.
    const auto write = [&](int x, int y, const detail::Rgb& sum, const detail::Rgb& sum2,
                           const Impl::DirectSums& direct, int inside, int samples,
                           const Impl::LedSums* led) {
        const std::size_t p = std::size_t(y) * image.width + x;
        const double coverage = m.camera.field_coverage(x, y);
        const bool edge = coverage < 1.0; // or outside the field: no samples inside, black
        // The weight of each sample: 1 / samples (the pixel's count: samples_per_pixel, or
        // reflection_samples_per_pixel where the pixel mirrors an LED; the same expression as
        // always, so the pixels inside the field keep their bytes), coverage / inside at the
        // edge.
        const int count = edge ? inside : samples;
        const double weight =
            edge ? (inside > 0 ? scale * coverage / inside : 0.0) : scale / samples;
        const detail::Rgb samples_mean = sum * weight; // the samples' own, for the variance
        detail::Rgb value = samples_mean;
        // The LEDs by reflection: their own mean F (at the edge, coverage times the mean over
        // the rays inside), and its variance added to the samples'.
        const int led_count = led ? (edge ? led->inside : n_led) : 0;
        detail::Rgb led_var = detail::Rgb::Zero();
        if (led_count > 0) {
            const double led_weight = edge ? scale * coverage / led_count : scale / n_led;
            value += led_rgb * (led->sum * led_weight);
            if (settings.variance && led_count > 1) {
                const double mean = led->sum / led_count;
                const double var_f =
                    std::max(0.0, (led->sum2 - led_count * mean * mean) / (led_count - 1.0)) /
                    led_count;
                led_var =
                    (edge ? coverage * coverage : 1.0) * scale * scale * var_f * led_rgb.square();
            }
        }
        float* out = image.pixel(x, y);
        for (int c = 0; c < 3; ++c)
            out[c] = float(value[c]);
        for (std::size_t g = 0; g < groups; ++g) {
            for (int c = 0; c < 3; ++c) {
                const std::size_t i = 3 * (groups * p + g) + std::size_t(c);
                lit[i] = float(direct.lit[g][c] * weight);
                chosen[i] = float(direct.chosen[g][c] * weight);
                shadowed[i] = float(direct.shadowed[g][c] * weight);
            }
        }
        if (settings.variance && count > 1) {
            // Sample variance (count - 1 in the denominator) over count, floored at 0 against
            // round-off; at the edge, of the samples inside, times coverage^2.
            // About the samples' own mean, without the LEDs by reflection (their variance is
            // led_var's).
            const detail::Rgb mean = edge ? detail::Rgb(sum * (scale / count)) : samples_mean;
            const detail::Rgb var =
                (edge ? coverage * coverage : 1.0) *
                    ((sum2 - count * mean.square()) / (count - 1.0) / count).max(0.0) +
                led_var;
            for (int c = 0; c < 3; ++c)
                image.variance[3 * p + std::size_t(c)] = float(var[c]);
        }
        if (settings.marker_ids) {
            const auto [inner, outer] =
                m.marker_ids(x, y, settings.integrator != Integrator::direct);
            image.inner_marker_id[p] = inner;
            image.outer_marker_id[p] = outer;
        }
    };
    tbb::parallel_for(tbb::blocked_range<int>(0, image.height), [&](const auto& rows) {
        std::array<detail::Rgb, Impl::kMaxBatchPixels> sums, sum2;
        std::array<Impl::DirectSums, Impl::kMaxBatchPixels> direct;
        std::array<int, Impl::kMaxBatchPixels> inside{};
        std::array<Impl::LedSums, Impl::kMaxBatchPixels> led;
        for (int y = rows.begin(); y != rows.end(); ++y) {
            for (int x = 0; x < image.width;) {
                // Runs of up to `batch` pixels (`mirror_batch` where an LED is mirrored,
                // `edge_batch` on the markers' rims), up to the next pixel of another count.
                const std::size_t row = std::size_t(y) * image.width;
                const int level = levels.empty() ? 0 : levels[row + x];
                int pixels = std::min(level == 2   ? mirror_batch
                                      : level == 1 ? edge_batch
                                                   : batch,
                                      image.width - x);
                for (int j = 1; j < pixels && !levels.empty(); ++j)
                    if (levels[row + x + j] != level) pixels = j;
                const int px_n = level == 2 ? nx_mirror : level == 1 ? nx_edge : nx;
                const int py_n = level == 2 ? ny_mirror : level == 1 ? ny_edge : ny;
                const auto some = [&](auto& a, bool wanted) {
                    return wanted ? std::span(a.data(), std::size_t(pixels))
                                  : std::span<detail::Rgb>{};
                };
                if (fast) {
                    m.sample_pixels_fast(x, y, pixels, px_n, py_n, settings, scale,
                                         {some(sums, true), some(sum2, settings.variance),
                                          filter ? std::span(direct.data(), std::size_t(pixels))
                                                 : std::span<Impl::DirectSums>{},
                                          std::span(inside.data(), std::size_t(pixels)),
                                          level == 2 && n_led > 0
                                              ? std::span(led.data(), std::size_t(pixels))
                                              : std::span<Impl::LedSums>{}},
                                         level == 2   ? Impl::kMirrorLevel
                                         : level == 1 ? Impl::kRimLevel
                                                      : Impl::kMainLevel,
                                         budget);
                } else {
                    sum2[0] = detail::Rgb::Zero();
                    sums[0] = m.sample_pixel(x, y, nx, ny, settings, scale,
                                             settings.variance ? &sum2[0] : nullptr, inside[0]);
                }
                for (int j = 0; j < pixels; ++j)
                    write(x + j, y, sums[std::size_t(j)],
                          settings.variance ? sum2[std::size_t(j)] : detail::Rgb::Zero(),
                          direct[std::size_t(j)], inside[std::size_t(j)], px_n * py_n,
                          fast && level == 2 && n_led > 0 ? &led[std::size_t(j)] : nullptr);
                x += pixels;
            }
        }
    });
    if (filter) {
        // The rims' pixels (levels 1) with a sigma of their own, where they were found.
        std::vector<std::uint8_t> rim_flags;
        if (rims && settings.shadow_filter_rim_px) {
            rim_flags.resize(levels.size());
            for (std::size_t i = 0; i < levels.size(); ++i)
                rim_flags[i] = levels[i] == 1;
        }
        detail::shadow_filter(image.width, image.height, int(groups), image.rgb, lit, chosen,
                              shadowed, settings.shadow_filter_px, rim_flags,
                              settings.shadow_filter_rim_px.value_or(0.0));
    }
    return image;
}

std::optional<Eigen::Vector2d> Renderer::project(const Vec3& p_mm) const {
    return m_impl->camera.project(p_mm);
}

std::size_t Renderer::camera_samples_bytes() const {
    const std::lock_guard lock(m_impl->kept_mutex);
    return m_impl->kept_bytes;
}

void Renderer::count_rays(bool on) {
    m_impl->scene.count_rays(on);
}

std::uint64_t Renderer::rays_counted() const {
    return m_impl->scene.rays_counted();
}

} // namespace chromasim::render
