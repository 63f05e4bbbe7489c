// chromasim bench: speed and accuracy tables (medians) of the mechanics, the render and the
// whole pipeline.
#include "generators/validation/bench.hpp"
#include "generators/cli/command.hpp"
#include "generators/spec/stage_params.hpp"

#include <iostream>

namespace chromasim::cli {
namespace gen = generators;
namespace {

constexpr const char* kJsonHelp =
    "also write the table to this file as JSON: {command, chromasim_version, tables: "
    "[{caption, header, rows}]}, each cell the text printed (checked before any work)";

void add_mechanics(CLI::App* bench, Action& action) {
    auto options = std::make_shared<gen::DomeBenchOptions>();
    gen::DomeBenchOptions& o = *options;
    auto* command =
        bench->add_subcommand("mechanics", "dome mesh level vs accuracy, time and memory");
    command->alias("dome");
    command->add_option("--levels", o.levels, "mesh levels; the last is the reference")
        ->delimiter(',')
        ->check(CLI::IsMember({"very_coarse", "coarse", "medium", "fine", "refined", "reference"}));
    command->add_option("--material", o.material, "material model")
        ->check(CLI::IsMember({"linear", "neo_hookean"}));
    command->add_option("--element-order", o.element_order, "1: linear tets, 2: quadratic")
        ->check(CLI::Range(1, 2));
    command->add_option("--trial-frames", o.trial_frames, "frames of the timed trial")
        ->check(CLI::Range(4, 100000));
    command->add_option("--volumetric", o.volumetric, "volumetric formulation")
        ->check(CLI::IsMember({"nodal_average", "element"}));
    command->add_option("--repeat", o.repeats, "timed frames per level")
        ->check(CLI::Range(1, 1000));
    command->add_option("--interior", o.interior, "inside the dome")
        ->check(CLI::IsMember({"hollow", "rigid_core", "soft_fill"}));
    command->add_option("--fill-E", o.fill_E_MPa, "soft fill's Young's modulus, MPa")
        ->check(CLI::Range(1e-6, 1000.0));
    command->add_option("--json", o.json_out, kJsonHelp);
    on_chosen(command, action, options, [](const gen::DomeBenchOptions& opts) {
        gen::bench_dome(opts, std::cout);
        return 0;
    });
}

// The frame, the integrators and the reference of `bench render`.
void add_render_frame_options(CLI::App* command, gen::RenderBenchOptions& o) {
    command->add_option("--spp", o.samples_per_pixel, "samples per pixel")
        ->delimiter(',')
        ->check(CLI::Range(1, 4096));
    command->add_option("--reference-spp", o.reference_spp, "error reference")
        ->check(CLI::Range(1, 4096));
    command->add_option("--size", o.size_px, "image width = height, px")
        ->check(CLI::Range(16, 4096));
    command->add_option("--repeat", o.repeats, "timed renders per setting")
        ->check(CLI::Range(1, 1000));
    command
        ->add_option("--normal-N", o.normal_N, "the frame's normal force, N (0: the dome at rest)")
        ->check(CLI::Range(0.0, 20.0));
    command->add_option("--shear-N", o.shear_N, "the frame's pull along x, N")
        ->check(CLI::Range(0.0, 20.0));
    command->add_option("--mu", o.mu, "the frame's friction coefficient")
        ->check(CLI::Range(0.0, 10.0));
    command->add_option("--modes", o.modes, "spectral and/or rgb")
        ->delimiter(',')
        ->check(CLI::IsMember({"spectral", "rgb"}));
    command->add_option("--integrators", o.integrators, "preview, path, fast")
        ->delimiter(',')
        ->check(CLI::IsMember({"preview", "path", "fast"}));
    command
        ->add_option("--reference-integrator", o.reference_integrator,
                     "integrator of the error reference")
        ->check(CLI::IsMember({"preview", "path", "fast"}));
    command
        ->add_option("--reference-in", o.reference_in,
                     "read the reference from this EXR (written by --reference-out); two or "
                     "more: independent renders (--reference-seed), averaged, their spread "
                     "gives the reference's noise")
        ->check(CLI::ExistingFile);
    command->add_option("--reference-out", o.reference_out,
                        "write the rendered reference (with variance) to this EXR");
    command->add_option("--images-out", o.images_out,
                        "write each timed setting's image to this folder as an EXR named "
                        "after the setting, to see where its error lies: one more render, "
                        "untimed, the same R, G, B, with the variance and marker id "
                        "channels");
    command->add_option("--json", o.json_out, kJsonHelp);
    command->add_option("--reference-seed", o.reference_seed,
                        "seed of the rendered reference (another seed: an independent "
                        "reference, to measure its noise)");
}

// The fast integrator's light-cache and camera-cache knobs that `bench render` times.
void add_render_cache_options(CLI::App* command, gen::RenderBenchOptions& o) {
    command
        ->add_option("--cache-paths", o.light_cache.paths_per_vertex,
                     "fast integrator: light-cache paths per coating vertex")
        ->check(CLI::Range(1, 65536));
    command
        ->add_option("--cache-direct", o.light_cache.direct_samples,
                     "fast integrator: light-cache LED points per LED per vertex")
        ->check(CLI::Range(1, 4096));
    command
        ->add_option("--cache-smoothing", o.light_cache.smoothing_mm,
                     "fast integrator: light-cache smoothing, mm")
        ->check(CLI::Range(0.0, 10.0));
    command
        ->add_option("--refresh-threshold", o.light_cache.refresh_threshold,
                     "fast integrator: re-estimate a vertex's LED light per frame where the "
                     "point LED's changed by more than this fraction")
        ->check(CLI::Range(0.0, 10.0));
    command->add_flag(
        "!--no-refresh", o.light_cache.refresh_direct,
        "fast integrator: keep the rest ratio of area to point LED light on every vertex");
    command->add_flag("!--no-camera-cache", o.keep_camera_samples,
                      "fast integrator: draw the camera samples anew for every render "
                      "instead of keeping them from the first (the same image; to measure "
                      "what keeping them saves)");
}

// The fast integrator's sample counts and filters that `bench render` times, one row each.
void add_render_count_options(CLI::App* command, gen::RenderBenchOptions& o) {
    command
        ->add_option("--shadow-filter", o.shadow_filter_px,
                     "fast integrator: the shadow filters to time, px, each at every spp "
                     "(render.fast.shadow_filter_px; 0: none); the reference has none")
        ->check(CLI::Range(0.0, chromasim::render::kMaxShadowFilterPx));
    command
        ->add_option("--reflection-spp", o.reflection_spp,
                     "fast integrator: the samples per pixel to time where the inner surface "
                     "mirrors an LED, each at every spp and filter "
                     "(set by render.quality; 0: none extra); the reference "
                     "has none")
        ->check(CLI::Range(0, 4096));
    command
        ->add_option("--rim-spp", o.rim_spp,
                     "fast integrator: the samples per pixel to time on the markers' rims, each "
                     "at every spp, filter and reflection count "
                     "(set by render.quality; 0: none extra); the reference has "
                     "none")
        ->check(CLI::Range(0, 4096));
    command
        ->add_option("--reflected-led-spp", o.reflected_led_spp,
                     "fast integrator: the rays per pixel to time for the LEDs seen by "
                     "reflection in the inner surface, apart, where an LED is mirrored, each at "
                     "every spp, filter, reflection and rim count "
                     "(set by render.quality; 0: in the samples); the "
                     "reference has none")
        ->check(CLI::Range(0, 4096));
    command
        ->add_option("--shadow-rays", o.shadow_rays_per_pixel,
                     "fast integrator: the fewest shadow rays a pixel to time (at least one "
                     "and at most 4 a sample), each at every spp, filter, reflection, rim and "
                     "LED-ray count (set by render.quality; 0: one a sample); the "
                     "reference has one a sample")
        ->check(CLI::Range(0, 4096));
    command
        ->add_option("--fast-wavelengths", o.fast_wavelengths,
                     "fast integrator, spectral mode: the hero wavelengths a sample carries to "
                     "time, 8 or 16 (0: 16 at 1 spp, else 8, the default), each at every other "
                     "setting (set by render.quality); the reference has 16")
        ->check(CLI::IsMember({0, 8, 16}));
    command
        ->add_option("--shadow-filter-rim", o.shadow_filter_rim_px,
                     "fast integrator: the shadow filter's widths on the markers' rims to time, "
                     "px, each at every filter (set by render.quality; none given: "
                     "the filter's own)")
        ->check(CLI::Range(0.0, 8.0));
}

/// `bench render --quality NAME`: the preset's counts for the options left out.
void apply_quality(const CLI::App& command, const gen::QualityPreset& q,
                   gen::RenderBenchOptions& o) {
    const auto given = [&](const char* name) { return command.get_option(name)->count() > 0; };
    if (!given("--rim-spp")) o.rim_spp = {q.rim_samples_per_pixel};
    if (!given("--reflection-spp")) o.reflection_spp = {q.reflection_samples_per_pixel};
    if (!given("--reflected-led-spp")) o.reflected_led_spp = {q.reflected_led_samples_per_pixel};
    if (!given("--shadow-rays"))
        o.shadow_rays_per_pixel = {q.shadow_rays_per_sample * o.samples_per_pixel.front()};
    if (!given("--fast-wavelengths")) o.fast_wavelengths = {q.wavelengths_per_sample};
    if (!given("--shadow-filter-rim")) o.shadow_filter_rim_px = {q.shadow_filter_rim_px};
    if (!given("--shadow-filter")) o.shadow_filter_px = {1.0};
}

void add_render(CLI::App* bench, Action& action) {
    auto options = std::make_shared<gen::RenderBenchOptions>();
    auto* command = bench->add_subcommand("render", "samples per pixel vs error and time");
    add_render_frame_options(command, *options);
    add_render_cache_options(command, *options);
    add_render_count_options(command, *options);
    auto quality = std::make_shared<std::string>();
    command
        ->add_option("--quality", *quality,
                     "fast integrator: take render.quality's counts (rims, mirrored pixels, LED "
                     "rays, shadow rays with the first --spp, wavelengths, rim filter) where "
                     "their options are not given, and a 1 px shadow filter unless "
                     "--shadow-filter is")
        ->check(CLI::IsMember(gen::quality_names()));
    on_chosen(command, action, options, [command, quality](const gen::RenderBenchOptions& opts) {
        gen::RenderBenchOptions o = opts;
        if (!quality->empty()) apply_quality(*command, gen::quality_preset(*quality), o);
        gen::bench_render(o, std::cout);
        return 0;
    });
}

void add_pipeline(CLI::App* bench, Action& action) {
    auto options = std::make_shared<gen::PipelineBenchOptions>();
    gen::PipelineBenchOptions& o = *options;
    auto* command = bench->add_subcommand(
        "pipeline", "labelled stereo frames per second of generate, per stage");
    command->add_option("--trials", o.trials, "trials of the seed000 slice")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    command->add_option("--repeat", o.repeats, "runs of each spec")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    command
        ->add_option("--integrator", o.integrator,
                     "the slice's render.integrator (default: the spec's)")
        ->check(CLI::IsMember({"preview", "path", "fast"}));
    command
        ->add_option("--spp", o.samples_per_pixel,
                     "the slice's samples per pixel (default: the spec's)")
        ->check(CLI::Range(1, 1024));

    on_chosen(command, action, options, [](const gen::PipelineBenchOptions& opts) {
        gen::bench_pipeline(opts, std::cout);
        return 0;
    });
}

} // namespace

void add_bench(CLI::App& app, Action& action) {
    auto* bench = app.add_subcommand("bench", "print speed and accuracy tables (medians)");
    bench->require_subcommand(1);
    add_mechanics(bench, action);
    add_render(bench, action);
    add_pipeline(bench, action);
}

} // namespace chromasim::cli
