#include "generators/pipeline/generate.hpp"

#include "generators/pipeline/progress.hpp"

#include "generators/io/file_io.hpp"
#include "generators/io/image_io.hpp"
#include "generators/io/stopwatch.hpp"
#include "generators/output/dataset_writer.hpp"
#include "generators/pipeline/light_cache_store.hpp"
#include "generators/pipeline/sensor_bridge.hpp"
#include "generators/plan/plan.hpp"
#include "render/renderer.hpp"

#include <tbb/parallel_for.h>

#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <memory>
#include <optional>
#include <ostream>
#include <sstream>
#include <vector>

namespace chromasim::generators {

namespace {

using Clock = std::chrono::steady_clock;

void write_markers(DatasetWriter& writer, const FrameLabels& frame, const std::string& finger,
                   const mechanics::DomeModel& model, const mechanics::FrameResult& r) {
    const mechanics::MarkerDiscs& discs = model.markers();
    for (int layer = 0; layer < 2; ++layer)
        for (int m = 0; m < discs.markers_per_layer; ++m) {
            const int row = (layer * discs.markers_per_layer + m) * discs.points_per_marker;
            double x0[3], u[3];
            for (int k = 0; k < 3; ++k) {
                x0[k] = discs.points(row, k);
                u[k] = r.marker_points_mm(row, k) - x0[k];
            }
            writer.write_marker(frame, finger, layer == 0 ? "inner" : "outer", m, x0, u);
        }
}

/// Test only (generate.hpp): kills the process at the CHROMASIM_TEST_KILL_AT-th write step.
void test_kill_point() {
    static const long kill_at = [] {
        const char* v = std::getenv("CHROMASIM_TEST_KILL_AT");
        return v ? std::atol(v) : 0L;
    }();
    static long steps = 0;
    if (kill_at > 0 && ++steps >= kill_at) std::raise(SIGKILL);
}

/// What every trial shares: each stage's settings, the models and the writer.
struct Stages {
    const StageSettings& settings;
    const mechanics::DomeModel& model;
    render::Renderer* renderer; ///< null when no images are asked for
    const render::SensorModel* sensor;
    mechanics::FrameRequest request;
    DatasetWriter& writer;
    GenerateReport& report;
    std::ostream& log;
    bool quiet;
    Progress* progress = nullptr;
};

/// One fingertip through a trial: the state its frames carry from one to the next.
struct FingerRun {
    mechanics::ObjectShape object;
    mechanics::FrameResult result;    ///< the last frame's
    const FingerLoad* load = nullptr; ///< the last frame's load (null before the first)
    /// The last converged frame's result: the next frame starts from it, so a frame the solver
    /// could not solve passes nothing on (null: none yet, the next frame starts from rest).
    std::optional<mechanics::FrameResult> history;
    render::Image image; ///< rendered from `result` (valid when `rendered`)
    bool rendered = false;
    render::SensorFrame sensor_frame;
};

/// The noise index of a recorded image: distinct per trial, finger and frame.
std::uint64_t noise_index(int trial, int finger, int frame) {
    return (std::uint64_t(trial) << 32) | (std::uint64_t(finger) << 31) | std::uint64_t(frame);
}

/// Renders (or reuses) and writes finger `f`'s images of a frame; fills the image paths.
void write_images(Stages& s, const FrameLabels& labels, int f, FingerRun& run, bool reused,
                  LabelRow& row) {
    auto t0 = Clock::now();
    if (!reused || !run.rendered) { // an unmoved scene renders to the same image
        fill_sensor_frame(s.model, run.result, run.sensor_frame);
        s.renderer->set_frame(run.sensor_frame);
        run.image = s.renderer->render(s.settings.render);
        run.rendered = true;
        ++s.report.renders;
    }
    std::optional<render::Image> recorded;
    if (s.sensor)
        recorded = s.sensor->capture(run.image, noise_index(labels.trial, f, labels.frame));
    s.report.render_s += seconds_since(t0);
    t0 = Clock::now();
    const std::string finger = finger_name(f);
    if (s.settings.outputs.images)
        write_png(s.writer.image_path(labels.split, labels.trial, finger, labels.frame, &row.image),
                  recorded ? *recorded : run.image);
    if (s.settings.outputs.exr)
        write_exr(
            s.writer.image_path(labels.split, labels.trial, finger, labels.frame, &row.exr, "exr"),
            run.image);
    s.report.write_s += seconds_since(t0);
    ++s.report.images;
}

/// One fingertip's mechanics for a frame: a solve, or the last result when the load has not
/// changed. Returns whether it was reused. Safe to run for several fingertips at once.
bool solve_finger(const Stages& s, const FingerLoad& load, FingerRun& run) {
    const bool reused = run.load && load == *run.load;
    if (!reused) {
        run.result = s.model.solve(contact_load(load), s.request, run.object,
                                   run.history ? &*run.history : nullptr);
        if (run.result.contact.converged) run.history = run.result;
    }
    run.load = &load;
    return reused;
}

/// Every fingertip's mechanics for a frame, the fingertips in parallel (they share nothing).
std::vector<char> solve_fingers(Stages& s, const FramePlan& frame, std::vector<FingerRun>& runs) {
    std::vector<char> reused(runs.size());
    const auto t0 = Clock::now();
    tbb::parallel_for(std::size_t(0), runs.size(), [&](std::size_t f) {
        reused[f] = solve_finger(s, frame.fingers[f], runs[f]);
    });
    s.report.mechanics_s += seconds_since(t0);
    for (char r : reused)
        ++(r ? s.report.reused_solves : s.report.solves);
    return reused;
}

/// One fingertip's frame after its mechanics: labels, images, markers, strain.
LabelRow finish_finger(Stages& s, const FramePlan& frame, const FrameLabels& labels, int f,
                       FingerRun& run, bool reused) {
    LabelRow row = label_row(frame, frame.fingers[std::size_t(f)], run.result);
    row.reused = reused;
    if (s.renderer) write_images(s, labels, f, run, reused, row);
    const auto t0 = Clock::now();
    if (s.settings.outputs.markers)
        write_markers(s.writer, labels, finger_name(f), s.model, run.result);
    if (s.settings.outputs.strain)
        s.writer.write_strain(labels, finger_name(f), run.result.strain.eps_xx);
    s.report.write_s += seconds_since(t0);
    if (!row.converged) {
        ++s.report.flagged_frames;
        s.log << "chromasim: warning: trial " << labels.trial << " frame " << labels.frame << " "
              << finger_name(f) << " flagged: " << row.status << '\n';
    }
    return row;
}

void run_trial(Stages& s, const TrialPlan& trial) {
    const GenerateReport before = s.report;
    s.writer.begin_trial(trial.split, trial.id);
    const ObjectSource& source = s.settings.objects[std::size_t(trial.object)];
    const Spec::Object& object = source.object;
    std::vector<FingerRun> runs(trial.fingers.size());
    for (std::size_t f = 0; f < runs.size(); ++f)
        runs[f].object = object_shape(source, posed_object(object, trial.fingers[f]));
    for (const FramePlan& frame : trial.frames) {
        FrameLabels labels{trial.split,
                           trial.id,
                           frame.index,
                           frame.time_s,
                           phase_name(frame.phase),
                           object.name,
                           s.settings.friction_names[std::size_t(trial.friction)],
                           trial.grip_N,
                           frame.load_N,
                           frame.travel_mm,
                           {}};
        const std::vector<char> reused = solve_fingers(s, frame, runs);
        for (std::size_t f = 0; f < runs.size(); ++f)
            labels.fingers.push_back(finish_finger(s, frame, labels, int(f), runs[f], reused[f]));
        const auto t0 = Clock::now();
        s.writer.write_labels(labels);
        s.report.write_s += seconds_since(t0);
        test_kill_point();
        if (s.progress) s.progress->advance();
    }
    // The trial's counts go into its record: a resumed run's manifest sums the same numbers.
    TrialRecord record;
    record.frames = int(trial.frames.size());
    record.solves = s.report.solves - before.solves;
    record.reused_solves = s.report.reused_solves - before.reused_solves;
    record.renders = s.report.renders - before.renders;
    record.flagged_frames = s.report.flagged_frames - before.flagged_frames;
    const auto t0 = Clock::now();
    s.writer.end_trial(std::move(record));
    s.report.write_s += seconds_since(t0);
    test_kill_point();
    if (s.progress) s.progress->clear();
    if (!s.quiet)
        s.log << "  trial " << trial.id + 1 << "/" << s.report.planned_trials << " (" << trial.split
              << ", " << object.name << ", mu " << trial.mu << ", grip " << trial.grip_N
              << " N): " << trial.frames.size() << " frames"
              << (trial.first_slip_frame >= 0
                      ? ", slips at frame " + std::to_string(trial.first_slip_frame)
                      : std::string())
              << '\n';
}

/// `report` with the dataset's counts summed over the writer's trial records.
GenerateReport dataset_counts(const DatasetWriter& writer, GenerateReport report) {
    report.trials = report.frames = report.images = report.solves = report.reused_solves =
        report.renders = report.flagged_frames = 0;
    for (const auto& [id, r] : writer.records()) {
        ++report.trials;
        report.frames += r.frames;
        report.images += r.images;
        report.solves += r.solves;
        report.reused_solves += r.reused_solves;
        report.renders += r.renders;
        report.flagged_frames += r.flagged_frames;
    }
    return report;
}

/// What only the run knows, for the manifest (or a part's part.json).
ManifestInfo manifest_info(const mechanics::DomeModel& model, bool strain, int planned_trials) {
    ManifestInfo info;
    info.planned_trials = planned_trials;
    const auto& st = model.stats();
    info.mesh_level = model.options().mesh_level;
    info.element_order = model.options().element_order;
    info.mesh_nodes = st.nodes;
    info.mesh_tets = st.tets;
    const mechanics::StrainGridSpec& grid = model.options().strain_grid;
    info.strain = strain;
    info.strain_nx = grid.nx;
    info.strain_ny = grid.ny;
    info.strain_half_width_x_mm = grid.half_width_x_mm;
    info.strain_half_width_y_mm = grid.half_width_y_mm;
    return info;
}

} // namespace

LabelRow label_row(const FramePlan& f, const FingerLoad& load, const mechanics::FrameResult& r) {
    LabelRow row;
    row.frame = f.index;
    row.phase = phase_name(f.phase);
    row.normal_force_N = r.contact.normal_force_N;
    row.tangential_x_N = r.contact.tangential_force_N.x();
    row.tangential_y_N = r.contact.tangential_force_N.y();
    row.requested_tangential_N = load.tangential_force_N.norm();
    row.mu = load.mu;
    row.gamma = r.contact.gamma;
    row.sliding = r.contact.sliding;
    row.indentation_mm = r.contact.indentation_mm;
    row.contact_area_mm2 = r.contact_area_mm2;
    row.stick_area_mm2 = r.stick_area_mm2;
    row.contact_nodes = int(r.contact.active.size());
    row.solver_iterations = r.contact.iterations;
    row.solver_residual_mm = r.contact.residual_mm;
    row.solver_residual_N = r.contact.residual_N;
    row.object_travel_x_mm = r.contact.object_displacement_mm.x();
    row.object_travel_y_mm = r.contact.object_displacement_mm.y();
    row.converged = r.contact.converged && !r.at_candidate_edge;
    row.status = r.at_candidate_edge ? "contact_at_candidate_edge" : r.contact.status;
    return row;
}

Spec::Object posed_object(const Spec::Object& object, const FingerSetup& finger) {
    Spec::Object posed = object;
    posed.offset_x_mm = finger.offset_mm.x();
    posed.offset_y_mm = finger.offset_mm.y();
    posed.yaw_deg = finger.yaw_deg;
    return posed;
}

LightCacheOutcome prepare_renderer(render::Renderer& renderer, const StageSettings& settings,
                                   const render::SensorFrame& rest,
                                   const std::filesystem::path& cache_dir) {
    const render::Integrator integrator = settings.render.integrator;
    if (integrator == render::Integrator::preview) return {};
    // Auto exposure of the path and fast integrators: the path-traced bare dome at rest
    // (render/renderer.hpp); the fast integrator also needs its light cache (once per sensor).
    renderer.set_exposure_reference(rest);
    if (integrator != render::Integrator::fast) return {};
    return provide_light_cache(renderer, rest, settings.optics.value(), settings.light_cache,
                               cache_dir);
}

void log_dome_model(const mechanics::DomeModel& model, double precompute_s,
                    const std::filesystem::path& cache_dir, std::ostream& log) {
    const auto& st = model.stats();
    log << "chromasim: dome mesh '" << model.options().mesh_level << "', "
        << (model.options().element_order == 2 ? "quadratic" : "linear") << " tets: " << st.nodes
        << " nodes, " << st.tets << " tets, " << st.candidates
        << " contact candidates; precomputed in " << precompute_s << " s (cache: " << st.cache
        << (cache_dir.empty() ? "" : ", " + cache_dir.string()) << ")\n";
    if (!st.cache_note.empty()) log << "chromasim: cache: " << st.cache_note << '\n';
}

std::filesystem::path default_cache_dir() {
    if (const char* dir = std::getenv("CHROMASIM_CACHE_DIR"); dir && *dir) return dir;
    if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg && *xdg)
        return std::filesystem::path(xdg) / "chromasim";
    if (const char* home = std::getenv("HOME"); home && *home)
        return std::filesystem::path(home) / ".cache" / "chromasim";
    return {};
}

namespace {

/// The plan's trials this run owns (its shard's), and of those the ones to run: an interrupted
/// run's complete trials (checked against their records' checksums) are kept.
struct TrialSelection {
    std::vector<int> owned;
    std::vector<const TrialPlan*> to_run;
};

TrialSelection select_trials(const Plan& plan, const GenerateOptions& options,
                             DatasetWriter& writer, std::ostream& log) {
    TrialSelection t;
    const Shard& shard = options.shard;
    for (const TrialPlan& trial : plan.trials) {
        if (!shard.owns(trial.id)) continue;
        t.owned.push_back(trial.id);
        if (!options.resume || !writer.completed(trial.id)) t.to_run.push_back(&trial);
    }
    if (shard.sharded())
        log << "chromasim: shard " << shard.text() << ": " << t.owned.size() << " of "
            << plan.trials.size() << " trials (those with index mod " << shard.count << " = "
            << shard.index - 1 << ")\n";
    const std::size_t resumed = t.owned.size() - t.to_run.size();
    if (resumed > 0)
        log << "chromasim: " << resumed << " of " << t.owned.size()
            << " trials already complete (checksums match); running the other " << t.to_run.size()
            << '\n';
    return t;
}

/// What every trial shares, computed once: the dome model and, with images, the renderer
/// (exposure, light cache) and the camera sensor model.
struct Precomputed {
    std::unique_ptr<mechanics::DomeModel> model;
    std::unique_ptr<render::Renderer> renderer;
    std::optional<render::SensorModel> sensor;
};

void log_light_cache(const GenerateReport& report, const LightCacheOutcome& cache,
                     const std::filesystem::path& cache_dir, std::ostream& log) {
    if (report.light_cache_s > 0.0)
        log << "chromasim: the fast integrator's light cache took " << report.light_cache_s
            << " s of that ("
            << (report.light_cache_from_file
                    ? "read from " + cache_dir.string()
                    : "built once per sensor; render.fast.*" +
                          (cache_dir.empty() ? std::string() : ", saved to " + cache_dir.string()))
            << ")\n";
    if (!cache.note.empty()) log << "chromasim: light cache: " << cache.note << '\n';
}

Precomputed precompute(const StageSettings& settings, const std::filesystem::path& cache_dir,
                       GenerateReport& report, std::ostream& log) {
    const auto t0 = Clock::now();
    Precomputed p;
    mechanics::DomeModelOptions model_options = settings.dome;
    model_options.cache_dir = cache_dir;
    p.model = std::make_unique<mechanics::DomeModel>(model_options);
    LightCacheOutcome cache;
    if (settings.optics) {
        p.renderer = std::make_unique<render::Renderer>(settings.camera, *settings.optics);
        cache =
            prepare_renderer(*p.renderer, settings, undeformed_sensor_frame(*p.model), cache_dir);
        report.light_cache_s = cache.seconds;
        report.light_cache_from_file = cache.from_file;
    }
    // The camera sensor turns the PNG's pixels into a recording; the EXR stays noise-free.
    if (settings.sensor) p.sensor.emplace(settings.camera, *settings.sensor);
    report.precompute_s = seconds_since(t0);
    log_dome_model(*p.model, report.precompute_s, cache_dir, log);
    log_light_cache(report, cache, cache_dir, log);
    return p;
}

/// What a frame's solve must return beyond its labels: only what the outputs need.
mechanics::FrameRequest frame_request(const StageSettings& settings) {
    const bool render_stage = settings.optics.has_value();
    mechanics::FrameRequest request;
    request.coating = render_stage;
    request.markers = render_stage || settings.outputs.markers;
    // Only the path and fast integrators refract at the inner surface.
    request.inner_surface =
        render_stage && settings.render.integrator != render::Integrator::preview;
    request.strain = settings.outputs.strain;
    return request;
}

void log_up_to_date(const GenerateOptions& options, std::ostream& log) {
    log << "chromasim: " << options.out_dir.string() << " already holds this "
        << (options.shard.sharded() ? "part (same resolved spec and --shard)"
                                    : "dataset (same resolved spec)")
        << "; nothing to do.\n";
}

/// Runs `trials` in order; an error keeps the complete trials for --resume and says so.
void run_trials(Stages& stages, const std::vector<const TrialPlan*>& trials,
                const GenerateOptions& options) {
    std::size_t frames = 0;
    for (const TrialPlan* trial : trials)
        frames += trial->frames.size();
    Progress progress(stages.log, frames, options.terminal, options.quiet);
    stages.progress = &progress;
    try {
        for (const TrialPlan* trial : trials)
            run_trial(stages, *trial);
        progress.finish();
    } catch (const std::exception& e) {
        progress.clear();
        const DatasetWriter& writer = stages.writer;
        if (writer.completed_trials() == 0) throw;
        throw std::runtime_error(std::string(e.what()) + "\nchromasim: the " +
                                 std::to_string(writer.completed_trials()) +
                                 " complete trial(s) are kept in " + writer.staging().string() +
                                 "; fix the cause, then run the same command with --resume");
    }
}

} // namespace

GenerateReport generate(const Spec& spec, const GenerateOptions& options, std::ostream& log) {
    const auto t_start = Clock::now();
    GenerateReport report;
    // 1. The plan (cheap, plain data), then the output path: nothing is computed for a
    // dataset that exists or cannot be written. A slice as long as the plan is the whole.
    Plan plan = make_plan(spec);
    report.planned_trials = int(plan.trials.size());
    const int slice = options.max_trials > 0 && options.max_trials < report.planned_trials
                          ? options.max_trials
                          : 0;
    if (slice > 0) plan.trials.resize(std::size_t(slice));
    const Shard& shard = options.shard;
    if (inspect_output(options.out_dir, spec, slice, shard) == OutputState::up_to_date &&
        !options.overwrite) {
        report.up_to_date = true;
        log_up_to_date(options, log);
        return report;
    }
    // Every file the outputs need (object meshes, spectra) is read before any work: a bad
    // file stops here, nothing written.
    const StageSettings settings = stage_settings(spec);
    DatasetWriter writer(options.out_dir, spec,
                         {options.overwrite, options.resume, slice, shard, true}, log);
    if (writer.assembled()) { // killed after the last write, before the rename
        writer.finish();
        report.moved_only = true;
        log << "chromasim: " << writer.staging().string()
            << " held the whole dataset; moved it into place\n";
        return report;
    }
    const TrialSelection trials = select_trials(plan, options, writer, log);
    report.resumed_trials = int(trials.owned.size() - trials.to_run.size());

    // 2. Precompute what every trial shares: mesh, factorization, contact compliance, scene.
    const Precomputed pre = precompute(settings, options.cache_dir, report, log);

    // 3. Trials, one after the other; in each, frames: mechanics, render (only if images are
    // asked for), writers.
    Stages stages{settings,
                  *pre.model,
                  pre.renderer.get(),
                  pre.sensor ? &*pre.sensor : nullptr,
                  frame_request(settings),
                  writer,
                  report,
                  log,
                  options.quiet};
    run_trials(stages, trials.to_run, options);

    // 4. The dataset's counts, over every trial (resumed ones too), then assemble (a part:
    // seal) and rename.
    report = dataset_counts(writer, report);
    const auto t0 = Clock::now();
    const ManifestInfo info =
        manifest_info(*pre.model, settings.outputs.strain, report.planned_trials);
    if (shard.sharded())
        writer.seal_part({CHROMASIM_VERSION, CHROMASIM_ARCH, shard, spec.source_path.string(),
                          sha256_hex(stored_spec_text(spec, slice)), slice, trials.owned, info});
    else
        writer.assemble(info, int(plan.trials.size()));
    test_kill_point();
    writer.finish();
    report.write_s += seconds_since(t0);
    report.total_s = seconds_since(t_start);
    return report;
}

} // namespace chromasim::generators
