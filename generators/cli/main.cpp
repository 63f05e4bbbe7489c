// chromasim: the command line. Parses arguments and calls the libraries; nothing else.
#include "generators/bench.hpp"
#include "generators/check.hpp"
#include "generators/generate.hpp"
#include "generators/image_io.hpp"
#include "generators/merge.hpp"
#include "generators/plan.hpp"
#include "generators/scene_export.hpp"
#include "generators/spec.hpp"
#include "generators/verify.hpp"
#include "generators/verify_render.hpp"
#include "generators/verify_sensor.hpp"

#include <CLI/CLI.hpp>
#include <tbb/global_control.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>

namespace gen = chromasim::generators;

namespace {

int run_generate(const std::string& spec_path, const std::optional<std::string>& shard,
                 const gen::GenerateOptions& options) {
    gen::GenerateOptions with_terminal = options;
    if (shard) with_terminal.shard = gen::parse_shard(*shard); // before any work
    const gen::Spec spec = gen::load_spec(spec_path);          // validation before any work
    with_terminal.terminal = ::isatty(::fileno(stderr)) != 0;
    const gen::GenerateReport r = gen::generate(spec, with_terminal, std::cerr);
    if (r.up_to_date || r.moved_only) return 0; // generate() said so on the log
    if (r.resumed_trials > 0)
        std::cout << "chromasim: kept " << r.resumed_trials
                  << " trial(s) of the interrupted run (--resume)\n";
    const gen::Shard& part = with_terminal.shard;
    std::cout << "chromasim: wrote " << (part.sharded() ? "part " + part.text() + ", " : "")
              << r.trials << " of " << r.planned_trials << " trials, " << r.frames << " frames ("
              << r.images << " images, " << r.renders << " rendered; " << r.solves << " solves, "
              << r.reused_solves << " reused) to " << options.out_dir.string() << " in "
              << r.total_s << " s (precompute " << r.precompute_s << " s, mechanics "
              << r.mechanics_s << " s, render " << r.render_s << " s, write " << r.write_s
              << " s)\n";
    const auto& out = options.out_dir;
    if (part.sharded()) { // the dataset's files come with the merge
        std::cout << "  when all " << part.count
                  << " parts are written: chromasim merge PART... -o "
                  << "DIR (docs/DATASET_FORMAT.md, \"Shards and merge (clusters)\")\n";
        return 0;
    }
    if (spec.outputs.images)
        std::cout << "  images: " << (out / "images").string()
                  << "/<split>/trial_NNNNNN/<finger>_NNNNNN.png\n";
    if (spec.outputs.exr)
        std::cout << "  exr: " << (out / "images").string()
                  << "/<split>/trial_NNNNNN/<finger>_NNNNNN.exr\n";
    if (spec.outputs.labels) std::cout << "  labels: " << (out / "labels.csv").string() << "\n";
    if (spec.outputs.markers) std::cout << "  markers: " << (out / "markers.csv").string() << "\n";
    if (spec.outputs.strain)
        std::cout << "  strain: " << (out / "strain").string()
                  << "/<split>/trial_NNNNNN/<finger>.csv\n";
    if (r.flagged_frames > 0)
        std::cerr << "chromasim: " << r.flagged_frames
                  << " frame(s) flagged as not converged (labels.csv: converged = 0)\n";
    return 0;
}

int run_merge(const gen::MergeOptions& options) {
    const gen::MergeReport r = gen::merge(options, std::cerr);
    if (r.up_to_date) return 0; // merge() said so on the log
    std::cout << "chromasim: merged " << r.parts << " parts, " << r.trials << " trials (" << r.files
              << " files of trials, " << r.copied << " copied, the others hard-linked) into "
              << options.out_dir.string() << " in " << r.total_s << " s\n";
    return 0;
}

int run_export_scene(const std::string& spec_path, const gen::SceneSelection& which,
                     const std::string& out, const gen::SceneExportOptions& options) {
    const gen::Spec spec = gen::load_spec(spec_path); // validation before any work
    const gen::SceneExportReport r = gen::export_scene(spec, which, out, options, std::cerr);
    const gen::LabelRow& l = r.labels;
    std::cout << "chromasim: wrote trial " << r.trial << " " << gen::finger_name(r.finger)
              << " frame " << r.frame << " of " << r.frames << " (" << l.phase << ", Fn "
              << l.normal_force_N << " N, Ft " << std::hypot(l.tangential_x_N, l.tangential_y_N)
              << " N, Gamma " << l.gamma << ") to " << out << " in " << r.total_s << " s\n";
    return 0;
}

// --cache-dir (default: default_cache_dir()) and --no-cache on `command`.
void add_cache_options(CLI::App* command, std::string& cache_dir, bool& no_cache) {
    command
        ->add_option("--cache-dir", cache_dir,
                     "cache of mesh and contact responses, reused across runs")
        ->capture_default_str();
    command->add_flag("--no-cache", no_cache, "neither read nor write the cache");
}

} // namespace

int main(int argc, char** argv) {
    CLI::App app{"chromasim: synthetic tactile images and labels for camera-based fingertips"};
    app.set_version_flag("--version", std::string("chromasim ") + CHROMASIM_BUILD);
    app.require_subcommand(1);
    int threads = 0;
    app.add_option("--threads", threads, "worker threads (0: all cores)")
        ->check(CLI::Range(0, 1024));

    std::string spec_path;
    gen::GenerateOptions options;
    auto* generate = app.add_subcommand("generate", "run a dataset spec and write the dataset");
    generate->add_option("spec", spec_path, "spec file (YAML)")->required();
    std::string out_dir;
    generate
        ->add_option("-o,--output", out_dir,
                     "output folder (created; written as DIR.partial, renamed when complete)")
        ->required();
    generate->add_flag("--overwrite", options.overwrite,
                       "replace an existing dataset once the new one is complete (and discard "
                       "an interrupted run's DIR.partial unless --resume)");
    generate->add_flag("--resume", options.resume,
                       "finish the interrupted run that left DIR.partial (same spec): its "
                       "complete trials are checked and kept");
    generate->add_flag("-q,--quiet", options.quiet, "no per-trial lines, no progress");
    generate
        ->add_option("--max-trials", options.max_trials,
                     "run only the first N trials of the plan (a slice; 0: all)")
        ->check(CLI::Range(0, 1 << 30));
    std::string shard;
    auto* shard_option =
        generate->add_option("--shard", shard,
                             "write only part K of N (K/N, 1 <= K <= N): trials t with t mod N = "
                             "K-1, for chromasim merge; combines with --max-trials (shards of the "
                             "slice), --resume and --overwrite");
    std::string cache_dir = gen::default_cache_dir().string();
    bool no_cache = false;
    add_cache_options(generate, cache_dir, no_cache);

    gen::MergeOptions merge_options;
    auto* merge = app.add_subcommand(
        "merge", "join the parts of a sharded generate (--shard K/N) into the dataset an "
                 "unsharded run writes");
    std::vector<std::string> merge_parts;
    merge->add_option("parts", merge_parts, "the N part folders, any order (e.g. out/part_*)")
        ->required();
    std::string merge_out;
    merge
        ->add_option("-o,--output", merge_out,
                     "dataset folder (written as DIR.partial, renamed when complete)")
        ->required();
    merge->add_flag("--overwrite", merge_options.overwrite,
                    "replace an existing dataset once the new one is complete, and discard a "
                    "DIR.partial");

    auto* export_scene = app.add_subcommand(
        "export-scene", "write one frame's scene as glTF 2.0 (meshes, materials, LEDs, camera)");
    export_scene->add_option("spec", spec_path, "spec file (YAML)")->required();
    gen::SceneSelection export_which;
    export_scene->add_option("--trial", export_which.trial, "trial of the plan (0: the first)")
        ->capture_default_str();
    std::string export_finger = "left";
    export_scene->add_option("--finger", export_finger, "fingertip")
        ->check(CLI::IsMember({"left", "right"}))
        ->capture_default_str();
    export_scene
        ->add_option("--frame", export_which.frame, "frame of the trial to export (0: the first)")
        ->required();
    std::string export_out;
    export_scene
        ->add_option("-o,--output", export_out,
                     "output file: .gltf (JSON, embedded buffers) or .glb (binary)")
        ->required();
    add_cache_options(export_scene, cache_dir, no_cache);

    std::vector<std::string> validate_paths;
    auto* validate = app.add_subcommand("validate", "check spec files; do no work");
    validate->add_option("spec", validate_paths, "spec file(s)")->required();

    std::string check_dir;
    auto* check = app.add_subcommand(
        "check", "list impossible or inconsistent labels of a dataset (exit 1 if any)");
    check->add_option("dataset", check_dir, "dataset folder (written by generate or merge)")
        ->required();

    auto* schema = app.add_subcommand(
        "spec-doc", "print every spec key: the user manual of spec files (Markdown table)");
    schema->alias("schema"); // its name before docs/SPEC.md

    auto* bench = app.add_subcommand("bench", "print speed and accuracy tables (medians)");
    bench->require_subcommand(1);
    gen::DomeBenchOptions dome_bench;
    auto* bench_dome =
        bench->add_subcommand("mechanics", "dome mesh level vs accuracy, time and memory");
    bench_dome->alias("dome");
    bench_dome->add_option("--levels", dome_bench.levels, "mesh levels; the last is the reference")
        ->delimiter(',')
        ->check(CLI::IsMember({"coarse", "medium", "fine", "refined", "reference"}));
    bench_dome->add_option("--material", dome_bench.material, "material model")
        ->check(CLI::IsMember({"linear", "neo_hookean"}));
    bench_dome->add_option("--trial-frames", dome_bench.trial_frames, "frames of the timed trial")
        ->check(CLI::Range(4, 100000));
    bench_dome->add_option("--volumetric", dome_bench.volumetric, "volumetric formulation")
        ->check(CLI::IsMember({"nodal_average", "element"}));
    bench_dome->add_option("--repeat", dome_bench.repeats, "timed frames per level")
        ->check(CLI::Range(1, 1000));
    bench_dome->add_option("--interior", dome_bench.interior, "inside the dome")
        ->check(CLI::IsMember({"hollow", "rigid_core", "soft_fill"}));
    bench_dome->add_option("--fill-E", dome_bench.fill_E_MPa, "soft fill's Young's modulus, MPa")
        ->check(CLI::Range(1e-6, 1000.0));
    gen::RenderBenchOptions render_bench;
    auto* bench_render = bench->add_subcommand("render", "samples per pixel vs error and time");
    bench_render->add_option("--spp", render_bench.samples_per_pixel, "samples per pixel")
        ->delimiter(',')
        ->check(CLI::Range(1, 4096));
    bench_render->add_option("--reference-spp", render_bench.reference_spp, "error reference")
        ->check(CLI::Range(1, 4096));
    bench_render->add_option("--size", render_bench.size_px, "image width = height, px")
        ->check(CLI::Range(16, 4096));
    bench_render->add_option("--repeat", render_bench.repeats, "timed renders per setting")
        ->check(CLI::Range(1, 1000));
    bench_render
        ->add_option("--normal-N", render_bench.normal_N,
                     "the frame's normal force, N (0: the dome at rest)")
        ->check(CLI::Range(0.0, 20.0));
    bench_render->add_option("--shear-N", render_bench.shear_N, "the frame's pull along x, N")
        ->check(CLI::Range(0.0, 20.0));
    bench_render->add_option("--mu", render_bench.mu, "the frame's friction coefficient")
        ->check(CLI::Range(0.0, 10.0));
    bench_render->add_option("--modes", render_bench.modes, "spectral and/or rgb")
        ->delimiter(',')
        ->check(CLI::IsMember({"spectral", "rgb"}));
    bench_render->add_option("--integrators", render_bench.integrators, "direct, path, fast")
        ->delimiter(',')
        ->check(CLI::IsMember({"direct", "path", "fast"}));
    bench_render
        ->add_option("--reference-integrator", render_bench.reference_integrator,
                     "integrator of the error reference")
        ->check(CLI::IsMember({"direct", "path", "fast"}));
    bench_render
        ->add_option("--cache-paths", render_bench.light_cache.paths_per_vertex,
                     "fast integrator: light-cache paths per coating vertex")
        ->check(CLI::Range(1, 65536));
    bench_render
        ->add_option("--cache-direct", render_bench.light_cache.direct_samples,
                     "fast integrator: light-cache LED points per LED per vertex")
        ->check(CLI::Range(1, 4096));
    bench_render
        ->add_option("--cache-smoothing", render_bench.light_cache.smoothing_mm,
                     "fast integrator: light-cache smoothing, mm")
        ->check(CLI::Range(0.0, 10.0));
    bench_render
        ->add_option("--refresh-threshold", render_bench.light_cache.refresh_threshold,
                     "fast integrator: re-estimate a vertex's LED light per frame where the "
                     "point LED's changed by more than this fraction")
        ->check(CLI::Range(0.0, 10.0));
    bench_render->add_flag(
        "!--no-refresh", render_bench.light_cache.refresh_direct,
        "fast integrator: keep the rest ratio of area to point LED light on every vertex");
    bench_render->add_flag("--indirect-scale", render_bench.light_cache.scale_indirect,
                           "fast integrator: scale the cached indirect light on every frame by "
                           "the coating's LED light over rest (render.fast.scale_indirect)");
    bench_render->add_flag("!--no-shadow-cull", render_bench.light_cache.cull_shadows,
                           "fast integrator: trace every shadow ray, also those that provably "
                           "meet no marker (the same image; to measure what the culling saves)");
    bench_render->add_flag("!--reflection-shadow-rays",
                           render_bench.light_cache.unshadowed_reflections,
                           "fast integrator: let the camera ray's reflection off the inner "
                           "surface trace its shadow rays, instead of taking the LEDs' light "
                           "there unshadowed where it is below a tenth of the sample (to "
                           "measure what leaving them out changes and saves)");
    bench_render->add_flag("!--no-frame-share", render_bench.light_cache.frame_share,
                           "fast integrator: let each shadow ray near the rim test the frame's "
                           "plane, instead of taking the share it blocks off the LEDs' light "
                           "once per cache (about the same mean, more noise in the field's "
                           "outer ring; to measure what the share saves)");
    bench_render->add_flag("!--no-led-cull", render_bench.cull_reflected_leds,
                           "fast integrator: trace the LED rays (--reflected-led-spp) also in "
                           "the pixels that provably mirror no LED (the same image; to measure "
                           "what skipping them saves)");
    bench_render->add_flag("!--no-camera-cache", render_bench.keep_camera_samples,
                           "fast integrator: draw the camera samples anew for every render "
                           "instead of keeping them from the first (the same image; to measure "
                           "what keeping them saves)");
    bench_render->add_flag("!--no-batch-pixels", render_bench.batch_pixels,
                           "fast integrator: trace each pixel's samples alone, never with its "
                           "neighbours' in one packet (the same image; to measure what the "
                           "batching saves below 16 spp)");
    bench_render
        ->add_option("--shadow-filter", render_bench.shadow_filter_px,
                     "fast integrator: the shadow filters to time, px, each at every spp "
                     "(render.fast.shadow_filter_px; 0: none); the reference has none")
        ->check(CLI::Range(0.0, chromasim::render::kMaxShadowFilterPx));
    bench_render
        ->add_option("--reflection-spp", render_bench.reflection_spp,
                     "fast integrator: the samples per pixel to time where the inner surface "
                     "mirrors an LED, each at every spp and filter "
                     "(render.fast.reflection_samples_per_pixel; 0: none extra); the reference "
                     "has none")
        ->check(CLI::Range(0, 4096));
    bench_render
        ->add_option("--edge-spp", render_bench.edge_spp,
                     "fast integrator: the samples per pixel to time on the markers' rims, each "
                     "at every spp, filter and reflection count "
                     "(render.fast.edge_samples_per_pixel; 0: none extra); the reference has "
                     "none")
        ->check(CLI::Range(0, 4096));
    bench_render
        ->add_option("--reflected-led-spp", render_bench.reflected_led_spp,
                     "fast integrator: the rays per pixel to time for the LEDs seen by "
                     "reflection in the inner surface, apart, where an LED is mirrored, each at "
                     "every spp, filter, reflection and rim count "
                     "(render.fast.reflected_led_samples_per_pixel; 0: in the samples); the "
                     "reference has none")
        ->check(CLI::Range(0, 4096));
    bench_render
        ->add_option("--shadow-rays", render_bench.shadow_rays_per_pixel,
                     "fast integrator: the fewest shadow rays a pixel to time (at least one "
                     "and at most 4 a sample), each at every spp, filter, reflection, rim and "
                     "LED-ray count (render.fast.shadow_rays_per_pixel; 0: one a sample); the "
                     "reference has one a sample")
        ->check(CLI::Range(0, 4096));
    bench_render
        ->add_option("--fast-wavelengths", render_bench.fast_wavelengths,
                     "fast integrator, spectral mode: the hero wavelengths a sample carries to "
                     "time, 8 or 16 (0: 16 at 1 spp, else 8, the default), each at every other "
                     "setting (render.fast.wavelengths_per_sample); the reference has 16")
        ->check(CLI::IsMember({0, 8, 16}));
    bench_render
        ->add_option("--reference-in", render_bench.reference_in,
                     "read the reference from this EXR (written by --reference-out); two or "
                     "more: independent renders (--reference-seed), averaged, their spread "
                     "gives the reference's noise")
        ->check(CLI::ExistingFile);
    bench_render->add_option("--reference-out", render_bench.reference_out,
                             "write the rendered reference (with variance) to this EXR");
    bench_render
        ->add_option("--shadow-filter-rim", render_bench.shadow_filter_rim_px,
                     "fast integrator: the shadow filter's widths on the markers' rims to time, "
                     "px, each at every filter (render.fast.shadow_filter_rim_px; none given: "
                     "the filter's own)")
        ->check(CLI::Range(0.0, 8.0));
    bench_render->add_option("--images-out", render_bench.images_out,
                             "write each timed setting's image to this folder as an EXR named "
                             "after the setting, to see where its error lies: one more render, "
                             "untimed, the same R, G, B, with the variance and marker id "
                             "channels");
    bench_render->add_option("--reference-seed", render_bench.reference_seed,
                             "seed of the rendered reference (another seed: an independent "
                             "reference, to measure its noise)");
    gen::PipelineBenchOptions pipeline_bench;
    auto* bench_pipeline = bench->add_subcommand(
        "pipeline", "labelled stereo frames per second of generate, per stage");
    bench_pipeline->add_option("--trials", pipeline_bench.trials, "trials of the seed000 slice")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    bench_pipeline->add_option("--repeat", pipeline_bench.repeats, "runs of each spec")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    bench_pipeline
        ->add_option("--integrator", pipeline_bench.integrator,
                     "the slice's render.integrator (default: the spec's)")
        ->check(CLI::IsMember({"direct", "path", "fast"}));
    bench_pipeline
        ->add_option("--spp", pipeline_bench.samples_per_pixel,
                     "the slice's samples per pixel (default: the spec's)")
        ->check(CLI::Range(1, 1024));

    auto* verify = app.add_subcommand("verify", "validation against analytic references");
    verify->require_subcommand(1);
    gen::VerifyOptions verify_options;
    std::string verify_json;
    auto* verify_mech =
        verify->add_subcommand("mechanics", "Hertz and Cattaneo-Mindlin on an elastic block");
    verify_mech->add_option("--levels", verify_options.levels, "block mesh levels")
        ->delimiter(',')
        ->check(CLI::IsMember({"coarse", "medium", "fine"}));
    verify_mech->add_option("--nu", verify_options.nus, "Poisson ratios")
        ->delimiter(',')
        ->check(CLI::Range(0.0, 0.4999));
    verify_mech->add_option("--volumetric", verify_options.volumetrics, "formulations")
        ->delimiter(',')
        ->check(CLI::IsMember({"nodal_average", "element"}));
    bool dome_curve = false;
    verify_mech->add_flag("--dome-curve", dome_curve,
                          "also print the dome's force-indentation curve beside Hertz");
    verify_mech->add_option("--json", verify_json, "also write the cases to this JSON file");
    auto* verify_rend = verify->add_subcommand(
        "render", "fisheye projection, filter product, determinism, convergence slope");
    verify_rend->add_option("--json", verify_json, "also write the cases to this JSON file");
    std::string reference_out;
    int reference_spp = 4096;
    verify_rend
        ->add_option("--write-reference", reference_out,
                     "only write the committed reference image (EXR) and stop")
        ->check(CLI::NonexistentPath);
    verify_rend->add_option("--reference-spp", reference_spp, "its samples per pixel")
        ->check(CLI::Range(1, 1 << 20));

    gen::SensorVerifyOptions sensor_verify;
    std::string sensor_spec, sensor_json, sensor_picture, sensor_keep;
    auto* verify_sens = verify->add_subcommand(
        "sensor", "the sensor's hue, size and centroid laws, measured from rendered images");
    verify_sens->add_option("spec", sensor_spec,
                            "spec whose sensor and render sections to verify (default: the "
                            "default sensor, fast integrator, 2 spp)");
    verify_sens->add_option("--size-px", sensor_verify.size_px, "image side (px)")
        ->check(CLI::Range(16, 4096))
        ->capture_default_str();
    verify_sens->add_option("--json", sensor_json, "also write the results to this JSON file");
    verify_sens->add_option("--picture", sensor_picture,
                            "write the apex marker at rest and at 3 N to this PNG");
    verify_sens->add_option("--keep", sensor_keep, "keep the rendered dataset in this new folder");
    add_cache_options(verify_sens, cache_dir, no_cache);

    CLI11_PARSE(app, argc, argv);
    std::unique_ptr<tbb::global_control> limit;
    if (threads > 0)
        limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                      std::size_t(threads));
    try {
        if (*generate) {
            options.out_dir = out_dir;
            if (!no_cache) options.cache_dir = cache_dir;
            return run_generate(
                spec_path, shard_option->count() ? std::optional(shard) : std::nullopt, options);
        }
        if (*merge) {
            for (const std::string& p : merge_parts)
                merge_options.parts.emplace_back(p);
            merge_options.out_dir = merge_out;
            return run_merge(merge_options);
        }
        if (*export_scene) {
            gen::SceneExportOptions export_options;
            if (!no_cache) export_options.cache_dir = cache_dir;
            export_which.finger = export_finger == "right" ? 1 : 0;
            return run_export_scene(spec_path, export_which, export_out, export_options);
        }
        if (*validate) {
            std::vector<gen::Spec> specs;
            for (const auto& p : validate_paths)
                specs.push_back(gen::load_spec(p));
            for (std::size_t i = 0; i < specs.size(); ++i) {
                const gen::Plan plan = gen::make_plan(specs[i]);
                const std::size_t frames = plan.frame_count();
                const std::size_t images =
                    specs[i].outputs.images ? frames * std::size_t(specs[i].fingers.count) : 0;
                std::cout << validate_paths[i] << ": ok (" << plan.trials.size() << " trials, "
                          << frames << " frames, " << images << " images)\n";
            }
            return 0;
        }
        if (*check) {
            const gen::CheckReport report = gen::check_dataset(check_dir);
            gen::print_check_report(check_dir, report, std::cout);
            return report.findings_total > 0 ? 1 : 0;
        }
        if (*bench_dome) {
            gen::bench_dome(dome_bench, std::cout);
            return 0;
        }
        if (*bench_render) {
            gen::bench_render(render_bench, std::cout);
            return 0;
        }
        if (*bench_pipeline) {
            gen::bench_pipeline(pipeline_bench, std::cout);
            return 0;
        }
        if (*verify_mech) {
            const auto cases = gen::verify_mechanics(verify_options);
            gen::print_verify_table(cases, std::cout);
            if (dome_curve) {
                std::cout << "\n";
                gen::print_dome_curve(std::cout);
            }
            if (!verify_json.empty()) {
                std::ofstream json(verify_json);
                gen::write_verify_json(cases, json);
                if (!json) throw std::runtime_error("cannot write " + verify_json);
            }
            return 0;
        }
        if (*verify_rend && !reference_out.empty()) {
            gen::write_exr(reference_out, gen::render_reference_dome(reference_spp, 1));
            std::cout << "wrote " << reference_out << " (" << gen::kReferenceDomeSize_px << " px, "
                      << reference_spp << " spp)\n";
            return 0;
        }
        if (*verify_rend) {
            const auto cases = gen::verify_render();
            gen::print_render_verify_table(cases, std::cout);
            if (!verify_json.empty()) {
                std::ofstream json(verify_json);
                gen::write_render_verify_json(cases, json);
                if (!json) throw std::runtime_error("cannot write " + verify_json);
            }
            return 0;
        }
        if (*verify_sens) {
            sensor_verify.spec_file = sensor_spec;
            sensor_verify.json = sensor_json;
            sensor_verify.picture = sensor_picture;
            sensor_verify.keep_dir = sensor_keep;
            if (!no_cache) sensor_verify.cache_dir = cache_dir;
            const auto report = gen::verify_sensor(sensor_verify, std::cout);
            gen::print_sensor_verify(report, std::cout);
            if (!sensor_json.empty()) {
                std::ofstream json(sensor_json);
                gen::write_sensor_verify_json(report, json);
                if (!json) throw std::runtime_error("cannot write " + sensor_json);
            }
            return report.all_met() ? 0 : 1;
        }
        if (*schema) {
            std::cout << gen::schema_markdown();
            return 0;
        }
    } catch (const gen::SpecError& e) {
        std::cerr << "error: " << e.what() << '\n';
        return 2;
    } catch (const std::exception& e) {
        std::cerr << "error: " << e.what() << '\n';
        return 1;
    }
    return 0;
}
