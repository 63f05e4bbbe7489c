// The coarse render stage: every pixel value comes from Embree rays through the deformed
// sensor; no texture or analytic shortcut stands in for geometry.
//
// Camera, and the preview integrator's shading model (per lane: linear RGB, or hero
// wavelengths in spectral mode; the path and fast integrators: render/path_integrator.hpp and
// render/fast_integrator.hpp)
// -------------------------------------------------------------------------------------------
// Camera. FisheyeCamera: by default the equidistant fisheye at the origin looking along +z;
// or OpenCV's Kannala-Brandt model, at any pose in the dome frame. Each pixel averages
// `samples_per_pixel` samples, one per cell of an nx x ny grid (nx the largest divisor of the
// count not above its square root), multi-jittered so that they also fall one per column and
// row of the pixel (detail::multi_jittered). In a pixel the field's edge (the image circle)
// crosses, a sample outside is drawn anew over the pixel, and the pixel's value is its
// coverage times the mean of its samples inside (Impl::draw, render()); a pixel wholly
// outside is black. The jitters come from a SplitMix64 stream and the permutations from
// seeds, both from (settings.seed, pixel index), so an image depends on neither the thread
// count nor the order in which TBB runs the rows.
//
// Camera ray. Traced from the camera position through the scene, surface after surface (closest
// hit, then again from kHitGap_mm past it, at most kMaxHits surfaces), straight through the
// inner surface (no refraction), with a throughput per lane that starts at 1. Normals are the
// triangles' geometric normals turned to face the camera ray, so triangle winding never
// matters; cos is the cosine between ray and that normal.
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
// led_ring_radius_mm at height led_z_mm, the first on +x, each emitting led_rgb (spectral:
// the LED spectrum times the mean of led_rgb) with a Lambertian (cosine) pattern about +z):
//     I * max(0, cos_emit) * max(0, cos_surface) / d^2 * T(LED -> p),
// where T multiplies, along the shadow segment (iterated Embree hits, stopping kHitGap_mm
// before p), exp(-a * L) for the path L inside each marker crossed, (1 - s) for each outer
// marker entered, and 0 if the coating is in the way (a deep indentation shadowing itself)
// or the segment crosses the frame or the lens barrel (ShadingModel::crosses_mount).
// Light scattered between surfaces (coating -> marker -> coating) is left out.
//
// Exposure. Computed once per Renderer from OpticsParams and the undeformed geometry: the
// radiance of the Lambertian coating at the apex (0, 0, kCoatingInnerRadius_mm) facing the
// camera, lit by all LEDs with no markers, L_ref = max over channels of
// albedo_coat / pi * E(apex). Image = radiance * exposure * 0.8 / L_ref, the same scale for
// every frame so that frames of a sequence stay comparable. The path and fast integrators
// use Renderer::set_exposure_reference instead: the brightest of the bare dome's directions.
#include "render/renderer_impl.hpp"

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

Renderer::Impl::Impl(const CameraParams& camera_params, const OpticsParams& optics)
    : camera(camera_params), shading(optics), scale(detail::exposure_scale(shading)),
      led_scale(optics.led_rgb.mean()) {
    if (optics.spectra) {
        wavelengths.emplace(camera_weight(optics.spectra->camera));
        tabulate_hero_sets(*optics.spectra);
    }
}

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
                m.sample_rgb<Integrator::path>(apex, origin, w, u_lambda, rng);
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

namespace {

/// Throws std::invalid_argument naming the first setting out of its range.
void check_settings(const RenderSettings& settings) {
    if (settings.samples_per_pixel < 1) {
        throw std::invalid_argument(
            "RenderSettings: samples_per_pixel = " + std::to_string(settings.samples_per_pixel) +
            " is invalid; allowed: integer >= 1");
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
    if (settings.rim_samples_per_pixel < 0) {
        throw std::invalid_argument("RenderSettings: rim_samples_per_pixel = " +
                                    std::to_string(settings.rim_samples_per_pixel) +
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
        throw std::invalid_argument(
            "RenderSettings: camera_cache_mb = " + std::to_string(settings.camera_cache_mb) +
            " is invalid; allowed: >= 0 MiB (0: none kept)");
    }
}

} // namespace

/// A render's sample counts: every pixel's `samples_per_pixel`, and for the fast integrator
/// the pixels that mirror an LED and those on a marker's rim at their own counts (`classes`:
/// 2 where an LED is mirrored, 1 on a rim, 0 or no classes at all elsewhere; a pixel that is
/// both takes the mirror's count), with runs of up to 16 / count neighbouring pixels sharing
/// packets of up to 16 samples (one pixel where the count is 16 or more).
struct Renderer::Impl::Counts {
    bool fast = false;
    int n = 1, nx = 1, ny = 1, batch = 1;
    /// The LEDs by reflection apart (reflected_led_samples_per_pixel); the mirrored pixels'
    /// count, at least n; the rims'.
    int n_led = 0, n_mirror = 1, n_rim = 0;
    bool mirrors = false, rims = false;
    std::vector<std::uint8_t> classes;
    int nx_mirror = 1, ny_mirror = 1, nx_rim = 1, ny_rim = 1, rim_batch = 1, mirror_batch = 1;

    Counts(const Impl& m, const RenderSettings& settings)
        : fast(settings.integrator == Integrator::fast), n(settings.samples_per_pixel) {
        std::tie(nx, ny) = detail::strata_grid(n);
        batch = batch_at(n);
        n_led = fast ? settings.reflected_led_samples_per_pixel : 0;
        n_mirror = std::max(settings.reflection_samples_per_pixel, n);
        n_rim = settings.rim_samples_per_pixel;
        mirrors = fast && (n_mirror > n || n_led > 0);
        rims = fast && n_rim > n && m.triangles_per_marker > 0;
        if (mirrors || rims) classes = m.pixel_classes(mirrors, rims);
        std::tie(nx_mirror, ny_mirror) = detail::strata_grid(std::max(n_mirror, 1));
        std::tie(nx_rim, ny_rim) = detail::strata_grid(std::max(n_rim, 1));
        rim_batch = batch_at(n_rim);
        mirror_batch = batch_at(n_mirror);
    }
    int batch_at(int count) const {
        return fast ? std::max(1, kMaxBatchPixels / std::max(count, 1)) : 1;
    }
};

/// Before a fast render: each count's camera samples kept from frame to frame where they fit
/// (RenderSettings::camera_cache_mb); returns the budget in bytes (0: none kept). One render
/// at a time uses the store: a render that finds it in use (another thread's render of this
/// renderer) draws its samples anew, the same bytes, and never waits (a wait inside a
/// caller's TBB task could deadlock).
std::size_t Renderer::Impl::prepare_kept(const RenderSettings& settings, const Counts& c,
                                         std::unique_lock<std::mutex>& lock) const {
    const bool store = c.fast && lock.try_lock();
    const std::size_t budget =
        store ? std::size_t(std::min(settings.camera_cache_mb, 1e12) * 1024.0 * 1024.0) : 0;
    if (!store) return budget;
    // At a budget of 0 this frees what is kept.
    keep_for(kMainClass, settings.seed, c.n, shadow_rays(settings, c.n), budget);
    const int rim = c.rims ? c.n_rim : 0, mirror = c.mirrors ? c.n_mirror : 0;
    keep_for(kRimClass, settings.seed, rim, rim ? shadow_rays(settings, rim) : 0, budget);
    keep_for(kMirrorClass, settings.seed, mirror, mirror ? shadow_rays(settings, mirror) : 0,
             budget);
    keep_for(kLedClass, settings.seed ^ kReflectedLedSeed, c.mirrors ? c.n_led : 0, 0, budget);
    return budget;
}

/// Turns a pixel's sample sums into its value, variance and marker ids, and keeps its direct
/// light apart for the shadow filter.
///
/// A pixel the field's edge crosses (0 < coverage < 1): its value is the coverage times the
/// mean of its samples inside the field, not the mean of all its samples with those outside
/// black. Both estimate the same pixel integral; the first has no noise from how many
/// samples happen to fall inside, which would otherwise give the edge's pixels a large share
/// of the image's squared error. A pixel none of whose samples fall inside stays black.
struct Renderer::Impl::Writer {
    const Impl& m;
    const RenderSettings& settings;
    Image& image;
    double scale;
    int n_led;
    /// The shadow filter's inputs: each pixel's direct light with and without the shadows,
    /// per shadow group g (render/shadow_filter.hpp): 9 floats a group and pixel.
    bool filter;
    std::size_t groups;
    std::unique_ptr<float[]> direct_light;
    std::span<float> lit, chosen, shadowed;
    /// The LEDs' radiance per unit of F in camera RGB, as the samples' (l.led / the LED's
    /// area, the same for every hero-wavelength set: their weights are normalised on the LED).
    detail::Rgb led_rgb;

    Writer(const Impl& impl, const RenderSettings& s, const Counts& c, Image& out)
        : m(impl), settings(s), image(out), scale(impl.scale_for(s)), n_led(c.n_led),
          filter(c.fast && s.shadow_filter_px > 0.0),
          groups(filter ? std::size_t(impl.fast.shadow_groups()) : 0) {
        const std::size_t pixels = std::size_t(image.width) * image.height;
        // Not zeroed: operator() sets every pixel's (at 896 px, zeroing and faulting in
        // 173 MB anew would cost a few % of a render).
        const std::size_t per_part = 3 * groups * pixels;
        if (per_part > 0) direct_light.reset(new float[3 * per_part]);
        lit = std::span<float>(direct_light.get(), per_part);
        chosen = std::span<float>(direct_light.get() + per_part, per_part);
        shadowed = std::span<float>(direct_light.get() + 2 * per_part, per_part);
        if (m.hero_sets.empty()) {
            led_rgb = m.shading.rgb_lanes().led.head<3>() / m.path.led_area_mm2();
        } else {
            const HeroSet& h = m.hero_sets.front();
            led_rgb = detail::Rgb(h.to_rgb * h.lanes.led.matrix()) / m.path.led_area_mm2();
        }
    }

    /// Pixel (x, y)'s value from its sample sum (and sum of squares, and the direct light's);
    /// `led`: its LEDs by reflection apart (reflected_led_samples_per_pixel), or none.
    void operator()(int x, int y, const detail::Rgb& sum, const detail::Rgb& sum2,
                    const DirectSums& direct, int inside, int samples, const LedSums* led) {
        const std::size_t p = std::size_t(y) * image.width + x;
        const double coverage = m.camera.field_coverage(x, y);
        const bool edge = coverage < 1.0; // or outside the field: no samples inside, black
        // The weight of each sample: 1 / samples inside the field (the pixel's count:
        // samples_per_pixel, or its class's, the rims' or the mirrored pixels'; written so,
        // not as coverage / inside, to keep those pixels' bytes), coverage / inside at the
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
            // round-off; at the edge, of the samples inside, times coverage^2. About the
            // samples' own mean, without the LEDs by reflection (their variance is led_var's).
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
                m.marker_ids(x, y, settings.integrator != Integrator::preview);
            image.inner_marker_id[p] = inner;
            image.outer_marker_id[p] = outer;
        }
    }

    /// The shadow filter over the written image; the rims' pixels (class 1) with a sigma of
    /// their own, where they were found.
    void filter_shadows(const Counts& c) {
        std::vector<std::uint8_t> rim_flags;
        if (c.rims && settings.shadow_filter_rim_px) {
            rim_flags.resize(c.classes.size());
            for (std::size_t i = 0; i < c.classes.size(); ++i)
                rim_flags[i] = c.classes[i] == 1;
        }
        detail::shadow_filter(image.width, image.height, int(groups), image.rgb, lit, chosen,
                              shadowed, settings.shadow_filter_px, rim_flags,
                              settings.shadow_filter_rim_px.value_or(0.0));
    }
};

/// Row y's pixels, sampled in runs of up to a batch of one count (the fast integrator), or
/// one by one (preview and path), and written.
Renderer::Impl::AnySampler Renderer::Impl::sampler_for(Integrator integrator) {
    switch (integrator) {
    case Integrator::path:
        return Sampler<Integrator::path>{};
    case Integrator::fast:
        return Sampler<Integrator::fast>{};
    case Integrator::preview:
        break;
    }
    return Sampler<Integrator::preview>{};
}

template <Integrator I>
void Renderer::Impl::render_row(Sampler<I>, int y, const RenderSettings& settings, const Counts& c,
                                std::size_t budget, Writer& write) const {
    std::array<detail::Rgb, kMaxBatchPixels> sums, sum2;
    std::array<DirectSums, kMaxBatchPixels> direct;
    std::array<int, kMaxBatchPixels> inside{};
    std::array<LedSums, kMaxBatchPixels> led;
    const int width = camera.width_px();
    const std::size_t row = std::size_t(y) * width;
    for (int x = 0; x < width;) {
        // Runs of up to `batch` pixels (`mirror_batch` where an LED is mirrored, `rim_batch`
        // on the markers' rims), up to the next pixel of another count.
        const int pixel_class = c.classes.empty() ? 0 : c.classes[row + x];
        int pixels = std::min(pixel_class == 2   ? c.mirror_batch
                              : pixel_class == 1 ? c.rim_batch
                                                 : c.batch,
                              width - x);
        for (int j = 1; j < pixels && !c.classes.empty(); ++j)
            if (c.classes[row + x + j] != pixel_class) pixels = j;
        const int px_n = pixel_class == 2 ? c.nx_mirror : pixel_class == 1 ? c.nx_rim : c.nx;
        const int py_n = pixel_class == 2 ? c.ny_mirror : pixel_class == 1 ? c.ny_rim : c.ny;
        const auto some = [&](auto& a, bool wanted) {
            return wanted ? std::span(a.data(), std::size_t(pixels)) : std::span<detail::Rgb>{};
        };
        const bool leds_apart = I == Integrator::fast && pixel_class == 2 && c.n_led > 0;
        if constexpr (I == Integrator::fast) {
            sample_pixels_fast(
                x, y, pixels, px_n, py_n, settings, write.scale,
                {some(sums, true), some(sum2, settings.variance),
                 write.filter ? std::span(direct.data(), std::size_t(pixels))
                              : std::span<DirectSums>{},
                 std::span(inside.data(), std::size_t(pixels)),
                 leds_apart ? std::span(led.data(), std::size_t(pixels)) : std::span<LedSums>{}},
                pixel_class == 2   ? kMirrorClass
                : pixel_class == 1 ? kRimClass
                                   : kMainClass,
                budget);
        } else {
            sum2[0] = detail::Rgb::Zero();
            sums[0] = sample_pixel<I>(x, y, c.nx, c.ny, settings, write.scale,
                                      settings.variance ? &sum2[0] : nullptr, inside[0]);
        }
        for (int j = 0; j < pixels; ++j)
            write(x + j, y, sums[std::size_t(j)],
                  settings.variance ? sum2[std::size_t(j)] : detail::Rgb::Zero(),
                  direct[std::size_t(j)], inside[std::size_t(j)], px_n * py_n,
                  leds_apart ? &led[std::size_t(j)] : nullptr);
        x += pixels;
    }
}

Image Renderer::render(const RenderSettings& settings) const {
    check_settings(settings);
    if (!m_impl->scene.has_frame()) {
        throw std::logic_error("Renderer::render called before set_frame");
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
    image.image_per_radiance = m.scale_for(settings);
    const Impl::Counts counts(m, settings);
    std::unique_lock kept_lock(m.kept_mutex, std::defer_lock);
    const std::size_t budget = m.prepare_kept(settings, counts, kept_lock);
    Impl::Writer write(m, settings, counts, image);
    std::visit(
        [&](auto sampler) {
            tbb::parallel_for(tbb::blocked_range<int>(0, image.height), [&](const auto& rows) {
                for (int y = rows.begin(); y != rows.end(); ++y)
                    m.render_row(sampler, y, settings, counts, budget, write);
            });
        },
        Impl::sampler_for(settings.integrator));
    if (write.filter) write.filter_shadows(counts);
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
