#include "generators/pipeline/generate.hpp"

#include "generators/pipeline/progress.hpp"

#include "generators/io/file_io.hpp"
#include "generators/io/image_io.hpp"
#include "generators/io/stopwatch.hpp"
#include "generators/output/dataset_writer.hpp"
#include "generators/output/sensor_table.hpp"
#include "generators/pipeline/light_cache_store.hpp"
#include "generators/plan/plan.hpp"
#include "generators/plan/sensor_variants.hpp"
#include "render/renderer.hpp"

#include <algorithm>
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
    for (int layer = 0; layer < 2; ++layer) {
        const Eigen::MatrixX3d x0 = marker_rest_positions(model, layer);
        const Eigen::MatrixX3d u = marker_displacements(model, r, layer);
        for (Eigen::Index m = 0; m < x0.rows(); ++m) {
            const double x[3] = {x0(m, 0), x0(m, 1), x0(m, 2)};
            const double d[3] = {u(m, 0), u(m, 1), u(m, 2)};
            writer.write_marker(frame, finger, layer == 0 ? "inner" : "outer", int(m), x, d);
        }
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

/// What every trial shares: the simulator (of the trial's sensor), the writer and the report.
struct Stages {
    Simulator* simulator;
    const Plan& plan;
    DatasetWriter& writer;
    GenerateReport& report;
    std::ostream& log;
    bool quiet;
    Progress* progress = nullptr;
};

/// Renders (or reuses) and writes finger `f`'s images of a frame; fills the image paths.
void write_images(Stages& s, const FrameLabels& labels, int f, SolvedFrame& frame,
                  LabelRow& row) {
    auto t0 = Clock::now();
    const StageSettings& settings = s.simulator->settings();
    // An unmoved scene renders to the same image: a reused frame keeps its render.
    if (s.simulator->render(frame)) ++s.report.renders;
    std::optional<render::Image> recorded;
    if (settings.outputs.images)
        recorded = s.simulator->recorded(frame, noise_index(labels.trial, f, labels.frame));
    s.report.render_s += seconds_since(t0);
    t0 = Clock::now();
    const std::string finger = finger_name(f);
    if (settings.outputs.images)
        write_png(s.writer.image_path(labels.split, labels.trial, finger, labels.frame, &row.image),
                  *recorded);
    if (settings.outputs.exr)
        write_exr(
            s.writer.image_path(labels.split, labels.trial, finger, labels.frame, &row.exr, "exr"),
            *frame.image);
    s.report.write_s += seconds_since(t0);
    ++s.report.images;
}

/// One fingertip's frame after its mechanics: images, markers, strain.
void finish_finger(Stages& s, const FrameLabels& labels, int f, SolvedFrame& frame,
                   LabelRow& row) {
    const StageSettings& settings = s.simulator->settings();
    if (s.simulator->renders()) write_images(s, labels, f, frame, row);
    const auto t0 = Clock::now();
    if (settings.outputs.markers)
        write_markers(s.writer, labels, finger_name(f), s.simulator->model(), frame.result);
    if (settings.outputs.strain)
        s.writer.write_strain(labels, finger_name(f), frame.result.strain.eps_xx);
    s.report.write_s += seconds_since(t0);
    if (!row.converged) {
        ++s.report.flagged_frames;
        s.log << "chromasim: warning: trial " << labels.trial << " frame " << labels.frame << " "
              << finger_name(f) << " flagged: " << row.status << '\n';
    }
}

void run_trial(Stages& s, const TrialPlan& trial) {
    const GenerateReport before = s.report;
    s.writer.begin_trial(trial.split, trial.id);
    if (trial.sensor >= 0)
        s.writer.write_sensor(sensors_row(trial, s.plan.sensors[std::size_t(trial.sensor)]));
    TrialRun run(*s.simulator, trial);
    while (!run.done()) {
        FrameLabels labels = run.next();
        for (int f = 0; f < run.fingers(); ++f) {
            ++(run.reused(f) ? s.report.reused_solves : s.report.solves);
            finish_finger(s, labels, f, *run.frame(f), labels.fingers[std::size_t(f)]);
        }
        const auto t0 = Clock::now();
        s.writer.write_labels(labels);
        s.report.write_s += seconds_since(t0);
        test_kill_point();
        if (s.progress) s.progress->advance();
    }
    s.report.mechanics_s += run.mechanics_seconds();
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
              << ", " << s.simulator->settings().objects[std::size_t(trial.object)].object.name
              << ", mu " << trial.mu << ", grip " << trial.grip_N << " N"
              << (trial.sensor >= 0 ? ", sensor " + std::to_string(trial.sensor) : std::string())
              << "): " << trial.frames.size() << " frames"
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

/// What every trial of one sensor shares, computed once: the dome model and, with images, the
/// renderer (exposure, light cache) and the camera sensor model. Adds its times to `report`.
std::unique_ptr<Simulator> precompute(const Spec& spec, StageSettings settings,
                                      const std::filesystem::path& cache_dir,
                                      GenerateReport& report, std::ostream& log) {
    const auto t0 = Clock::now();
    auto simulator = std::make_unique<Simulator>(spec, std::move(settings), cache_dir);
    LightCacheOutcome cache;
    GenerateReport times;
    if (simulator->renders()) {
        cache = simulator->prepare_renderer();
        times.light_cache_s = cache.seconds;
        times.light_cache_from_file = cache.from_file;
    }
    times.precompute_s = seconds_since(t0);
    log_dome_model(simulator->model(), times.precompute_s, cache_dir, log);
    log_light_cache(times, cache, cache_dir, log);
    report.precompute_s += times.precompute_s;
    report.light_cache_s += times.light_cache_s;
    report.light_cache_from_file = times.light_cache_from_file;
    return simulator;
}

/// The simulator of each trial's sensor: the spec's own, or one per sensor variant, built
/// when its first trial comes (one at a time: the caches keep the others' precomputes).
class Simulators {
public:
    Simulators(const Spec& spec, const Plan& plan, StageSettings settings,
               std::filesystem::path cache_dir, GenerateReport& report, std::ostream& log)
        : m_spec(spec), m_plan(plan), m_settings(std::move(settings)),
          m_cache_dir(std::move(cache_dir)), m_report(report), m_log(log) {}

    /// The simulator of sensor `sensor` (-1: the spec's own), built now if it is not the
    /// current one.
    Simulator& of(int sensor) {
        if (m_simulator && sensor == m_sensor) return *m_simulator;
        m_simulator.reset(); // one dome model and light cache in memory at a time
        m_sensor = sensor;
        if (sensor < 0) {
            m_simulator = precompute(m_spec, m_settings, m_cache_dir, m_report, m_log);
            return *m_simulator;
        }
        const Spec variant = sensor_spec(m_spec, m_plan.sensors[std::size_t(sensor)]);
        m_log << "chromasim: sensor " << sensor << " of " << m_plan.sensors.size() << '\n';
        m_simulator = precompute(variant, stage_settings(variant), m_cache_dir, m_report, m_log);
        return *m_simulator;
    }
    /// The current simulator, else the first sensor's (its mesh for the manifest).
    Simulator& any() { return m_simulator ? *m_simulator : of(m_plan.sensors.empty() ? -1 : 0); }

private:
    const Spec& m_spec;
    const Plan& m_plan;
    StageSettings m_settings;
    std::filesystem::path m_cache_dir;
    GenerateReport& m_report;
    std::ostream& m_log;
    std::unique_ptr<Simulator> m_simulator;
    int m_sensor = -1;
};

void log_up_to_date(const GenerateOptions& options, std::ostream& log) {
    log << "chromasim: " << options.out_dir.string() << " already holds this "
        << (options.shard.sharded() ? "part (same resolved spec and --shard)"
                                    : "dataset (same resolved spec)")
        << "; nothing to do.\n";
}

/// Runs `trials` in order, each on its sensor's simulator; an error keeps the complete trials
/// for --resume and says so.
void run_trials(Stages& stages, Simulators& simulators,
                const std::vector<const TrialPlan*>& trials, const GenerateOptions& options) {
    std::size_t frames = 0;
    for (const TrialPlan* trial : trials)
        frames += trial->frames.size();
    Progress progress(stages.log, frames, options.terminal, options.quiet);
    stages.progress = &progress;
    try {
        for (const TrialPlan* trial : trials) {
            if (stages.simulator == nullptr || trial->sensor >= 0) {
                progress.clear();
                stages.simulator = &simulators.of(trial->sensor);
            }
            run_trial(stages, *trial);
        }
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
    StageSettings settings = stage_settings(spec);
    DatasetWriter writer(options.out_dir, spec,
                         {options.overwrite, options.resume, slice, shard, true}, log);
    if (writer.assembled()) { // killed after the last write, before the rename
        writer.finish();
        report.moved_only = true;
        log << "chromasim: " << writer.staging().string()
            << " held the whole dataset; moved it into place\n";
        return report;
    }
    TrialSelection trials = select_trials(plan, options, writer, log);
    report.resumed_trials = int(trials.owned.size() - trials.to_run.size());

    // 2. Precompute what every trial of a sensor shares: mesh, factorization, contact
    // compliance, scene; the spec's own sensor at once, a varied sensor's before its first
    // trial (trials grouped by sensor, plan order within).
    Simulators simulators(spec, plan, std::move(settings), options.cache_dir, report, log);
    Stages stages{nullptr, plan, writer, report, log, options.quiet};
    if (plan.sensors.empty())
        stages.simulator = &simulators.of(-1);
    else
        std::stable_sort(trials.to_run.begin(), trials.to_run.end(),
                         [](const TrialPlan* a, const TrialPlan* b) { return a->sensor < b->sensor; });

    // 3. Trials, one after the other; in each, frames: mechanics, render (only if images are
    // asked for), writers.
    run_trials(stages, simulators, trials.to_run, options);

    // 4. The dataset's counts, over every trial (resumed ones too), then assemble (a part:
    // seal) and rename.
    report = dataset_counts(writer, report);
    const auto t0 = Clock::now();
    const ManifestInfo info = manifest_info(simulators.any().model(), spec.outputs.strain,
                                            report.planned_trials);
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
