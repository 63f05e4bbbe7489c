#pragma once
/// Benchmarks that print numbers (medians of repeated runs), never pass/fail: the machine is
/// shared and noisy. Each prints a Markdown table that docs/VALIDATION.md quotes; mechanics
/// and render also write it as JSON when asked (json_out; the shape: bench_table.hpp).
#include "render/scene_data.hpp"
#include <iosfwd>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace chromasim::generators {

struct DomeBenchOptions {
    std::vector<std::string> levels{"coarse", "medium"}; ///< the last one is the reference
    int repeats = 7;             ///< frames timed per level (median reported)
    double normal_force_N = 1.5; ///< load of the timed frame
    double tangential_force_N = 0.6;
    double mu = 0.8;
    std::string volumetric = "nodal_average"; ///< nodal_average | element
    std::string material = "linear";          ///< linear | neo_hookean
    int element_order = 1;                    ///< 1 linear tets, 2 quadratic
    int trial_frames = 40; ///< frames of the timed trial (a quarter pressing, then pulling)
    std::string interior = "hollow"; ///< hollow | rigid_core | soft_fill
    double fill_E_MPa = 0.05;        ///< soft fill's Young's modulus
    /// Also write the table to this JSON file (bench_table.hpp); its folder is checked before
    /// the first level. Empty: none written.
    std::filesystem::path json_out;
};

/// Mesh level vs accuracy and time: nodes, tets, meshed volume error, precompute breakdown,
/// median frame time (labels only, and with displacement fields), indentation and apex
/// marker displacement with their difference to the reference (last) level, peak memory.
void bench_dome(const DomeBenchOptions& options, std::ostream& out);

struct RenderBenchOptions {
    std::vector<int> samples_per_pixel{1, 2, 4, 16};
    int reference_spp = 64; ///< the error reference
    int size_px = 256;
    std::vector<std::string> modes{"spectral", "rgb"}; ///< spectral | rgb
    std::vector<std::string> integrators{
        "preview"}; ///< preview | path | fast, each with every mode
    /// The reference is always spectral; `path` makes it the physical reference, so a preview
    /// row's error includes the preview's own bias.
    std::string reference_integrator = "preview";
    int repeats = 5;
    /// The frame: the object presses with normal_N and pulls with shear_N along x, friction
    /// mu (the default: the quickstart's loaded frame). normal_N 0: the dome at rest.
    double normal_N = 1.5, shear_N = 0.6, mu = 0.8;
    /// The fast integrator's light cache.
    render::LightCacheSettings light_cache;
    /// Read the reference from these EXRs (R, G, B and variance.*, as written by
    /// `reference_out`) instead of rendering it; each must be size_px square. Two or more:
    /// independent renders (different `reference_seed`), averaged; the reference's noise is
    /// then measured from their spread, not taken from the variance channel (which a
    /// heavy-tailed path estimate understates).
    std::vector<std::filesystem::path> reference_in;
    /// Write the rendered reference (with its variance channels) to this EXR.
    std::filesystem::path reference_out;
    /// Seed of the rendered reference (the timed renders use 7). Two references with
    /// different seeds measure the reference's noise without trusting its variance channel.
    std::uint64_t reference_seed = 1;
    /// Fast integrator: keep the camera samples at the main count from render to render
    /// (RenderSettings::camera_cache_mb; false: 0, drawn anew each render, the same image).
    bool keep_camera_samples = true;
    /// Fast integrator: the shadow filters to time, px (RenderSettings::shadow_filter_px;
    /// 0: none), each at every spp. The reference never has one.
    std::vector<double> shadow_filter_px{0.0};
    /// Fast integrator: the shadow filter's widths on the markers' rims to time, px
    /// (RenderSettings::shadow_filter_rim_px), each at every filter; none: the filter's own.
    std::vector<double> shadow_filter_rim_px;
    /// Fast integrator: the samples per pixel to time in the pixels mirroring an LED
    /// (RenderSettings::reflection_samples_per_pixel; 0: none extra), each at every spp and
    /// filter. The reference never has them.
    std::vector<int> reflection_spp{0};
    /// Fast integrator: the samples per pixel to time on the markers' rims
    /// (RenderSettings::rim_samples_per_pixel; 0: none extra), each at every spp, filter and
    /// reflection count. The reference never has them.
    std::vector<int> rim_spp{0};
    /// Fast integrator: the rays per pixel to time for the LEDs seen by reflection, apart
    /// (RenderSettings::reflected_led_samples_per_pixel; 0: in the samples), each at every
    /// spp, filter, reflection and rim count. The reference never has them.
    std::vector<int> reflected_led_spp{0};
    /// Fast integrator: the fewest shadow rays a pixel to time (RenderSettings::
    /// shadow_rays_per_pixel; 0: one a sample), each at every spp, filter, reflection, rim
    /// and LED-ray count. The reference has one a sample.
    std::vector<int> shadow_rays_per_pixel{0};
    /// Fast integrator, spectral mode: the hero wavelengths a sample carries to time
    /// (RenderSettings::fast_wavelengths, 8 or 16; 0: 16 at 1 spp, else 8), each at every
    /// other setting. The reference has 16.
    std::vector<int> fast_wavelengths{0};
    /// Write each timed setting's image to this folder as an EXR named after the setting, to
    /// see where its error lies: one more render after the timed ones (the same seed, so the
    /// same R, G, B), with its variance and marker id channels. The folder is made before the
    /// first render; empty: none written.
    std::filesystem::path images_out;
    /// Also write the table to this JSON file (bench_table.hpp); its folder is checked before
    /// the first render. Empty: none written.
    std::filesystem::path json_out;
};

/// Independent renders of one image averaged: per value, their mean and the variance of
/// that mean from their spread (the unbiased sample variance over the count).
struct MeanOfRenders {
    std::vector<double> mean;
    std::vector<double> variance_of_mean;
};
/// Throws std::invalid_argument for fewer than two renders or renders of different sizes.
MeanOfRenders mean_of_renders(const std::vector<std::vector<float>>& renders);

/// The error of `image` against a noisy reference, in the reference's units: the RMS
/// difference, and the same less the reference's noise in quadrature,
/// sqrt(max(0, RMS^2 - mean(reference_variance))) (reference_variance empty: no noise known).
struct ErrorAgainstReference {
    double rms = 0.0;
    double less_reference_noise = 0.0;
    double max = 0.0;
    /// less_reference_noise over the pixels (RGB triples) the reference lights, the fisheye's
    /// circle: outside it both images are exact zeros, which the whole image's RMS counts
    /// (at 224 px a fifth of the pixels, so the circle's RMS is 1.12 times the image's).
    double in_circle = 0.0;
};
ErrorAgainstReference error_against(const std::vector<float>& image,
                                    const std::vector<float>& reference,
                                    const std::vector<float>& reference_variance);

/// Samples per pixel vs image error and time on a loaded frame (coarse mesh; by default
/// 1.5 N, 0.6 N pull): median render time, RMS and max error against the spectral render of
/// `reference_integrator` at `reference_spp`, per integrator and mode.
void bench_render(const RenderBenchOptions& options, std::ostream& out);

struct PipelineBenchOptions {
    /// Trials of the seed000_train slice (its first trials, as `generate --max-trials`).
    int trials = 1;
    int repeats = 3; ///< runs of each spec (medians reported)
    /// The slice's render.integrator and render.samples_per_pixel (empty, 0: the spec's).
    /// The quickstart always runs as written.
    std::string integrator;
    int samples_per_pixel = 0;
    /// The folder of quickstart.yaml and seed000_train.yaml.
    std::filesystem::path spec_dir = std::filesystem::path(CHROMASIM_SOURCE_DIR) / "datasets_spec";
};

/// Labelled stereo frames per second of `generate` (mechanics, render, writers; precompute
/// apart) on the quickstart and on a seed000_train slice, each into a temporary folder that is
/// removed afterwards: median frames/s, and per frame the median mechanics, render, writing
/// and other time. Precompute (mesh, factorization, the fast integrator's light cache) is a
/// column of its own, not part of the per-frame rates. Runs without the precompute cache.
void bench_pipeline(const PipelineBenchOptions& options, std::ostream& out);

} // namespace chromasim::generators
