#include "generators/generate.hpp"

#include "generators/dataset_writer.hpp"
#include "generators/image_io.hpp"
#include "generators/plan.hpp"
#include "generators/sensor_bridge.hpp"
#include "mechanics/stopwatch.hpp"
#include "render/renderer.hpp"

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <optional>
#include <ostream>
#include <sstream>

namespace chromasim::generators {

namespace {

using Clock = std::chrono::steady_clock;
using mechanics::seconds_since;

void write_markers(DatasetWriter& writer, int frame, const mechanics::DomeModel& model,
                   const mechanics::FrameResult& r) {
    const mechanics::MarkerDiscs& discs = model.markers();
    for (int layer = 0; layer < 2; ++layer)
        for (int m = 0; m < discs.markers_per_layer; ++m) {
            const int row = (layer * discs.markers_per_layer + m) * discs.points_per_marker;
            double x0[3], u[3];
            for (int k = 0; k < 3; ++k) {
                x0[k] = discs.points(row, k);
                u[k] = r.marker_points_mm(row, k) - x0[k];
            }
            writer.write_marker(frame, layer == 0 ? "inner" : "outer", m, x0, u);
        }
}

} // namespace

LabelRow label_row(const FramePlan& f, const mechanics::FrameResult& r) {
    LabelRow row;
    row.frame = f.index;
    row.phase = f.phase;
    row.normal_force_N = r.contact.normal_force_N;
    row.tangential_x_N = r.contact.tangential_force_N.x();
    row.tangential_y_N = r.contact.tangential_force_N.y();
    row.requested_tangential_N = f.tangential_force_N.norm();
    row.mu = f.mu;
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

void log_dome_model(const Spec& spec, const mechanics::DomeModel& model, double precompute_s,
                    const std::filesystem::path& cache_dir, std::ostream& log) {
    const auto& st = model.stats();
    log << "chromasim: dome mesh '" << spec.sensor.mesh_level << "': " << st.nodes << " nodes, "
        << st.tets << " tets, " << st.candidates << " contact candidates; precomputed in "
        << precompute_s << " s (cache: " << st.cache
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

GenerateReport generate(const Spec& spec, const GenerateOptions& options, std::ostream& log) {
    const auto t_start = Clock::now();
    GenerateReport report;
    // 1. Output path first: nothing is computed for a dataset that exists or cannot be written.
    const OutputState state = inspect_output(options.out_dir, spec);
    if (state == OutputState::up_to_date && !options.overwrite) {
        report.up_to_date = true;
        log << "chromasim: " << options.out_dir.string()
            << " already holds this dataset (same resolved spec); nothing to do.\n";
        return report;
    }
    // A mesh object's file and the spectra are read before any work: a bad file stops here,
    // nothing written.
    const mechanics::ObjectShape object = object_shape(spec);
    const bool render_stage = spec.outputs.images || spec.outputs.exr;
    std::optional<render::OpticsParams> optics;
    if (render_stage) optics = optics_params(spec);
    DatasetWriter writer(options.out_dir, spec, options.overwrite);
    const Plan plan = make_plan(spec);

    // 2. Precompute what every frame shares: mesh, factorization, contact compliance, scene.
    auto t0 = Clock::now();
    mechanics::DomeModelOptions model_options = dome_options(spec);
    model_options.cache_dir = options.cache_dir;
    const mechanics::DomeModel model(model_options);
    std::unique_ptr<render::Renderer> renderer;
    if (render_stage) {
        renderer = std::make_unique<render::Renderer>(camera_params(spec), *optics);
        // The path integrator's auto exposure: its own undeformed apex (render/renderer.hpp).
        // The fast integrator uses the same, and its light cache (once per sensor).
        if (spec.render.integrator != "direct") {
            const render::SensorFrame rest = undeformed_sensor_frame(model);
            renderer->set_exposure_reference(rest);
            if (spec.render.integrator == "fast")
                renderer->set_light_cache(rest, light_cache_settings(spec));
        }
    }
    // The camera sensor turns the PNG's pixels into a recording; the EXR stays noise-free.
    std::optional<render::SensorModel> sensor;
    if (spec.outputs.images && spec.render.sensor.enabled)
        sensor.emplace(camera_params(spec), sensor_params(spec));
    report.precompute_s = seconds_since(t0);
    log_dome_model(spec, model, report.precompute_s, options.cache_dir, log);

    // 3. Frames: mechanics, then (only if images are asked for) render, then writers.
    mechanics::FrameRequest request;
    request.coating = render_stage;
    request.markers = render_stage || spec.outputs.markers;
    const render::RenderSettings settings = render_settings(spec);
    // Only the path and fast integrators refract at the inner surface.
    request.inner_surface = render_stage && settings.integrator != render::Integrator::direct;
    render::SensorFrame sensor_frame;
    // The frames form one trial: each starts from the stick/slip state the previous one left.
    mechanics::FrameResult previous;
    for (const FramePlan& f : plan.frames) {
        t0 = Clock::now();
        mechanics::FrameResult r =
            model.solve(contact_load(f), request, object, f.index > 0 ? &previous : nullptr);
        report.mechanics_s += seconds_since(t0);
        LabelRow row = label_row(f, r);
        if (renderer) {
            t0 = Clock::now();
            fill_sensor_frame(model, r, sensor_frame);
            renderer->set_frame(sensor_frame);
            const render::Image image = renderer->render(settings);
            std::optional<render::Image> recorded;
            if (sensor) recorded = sensor->capture(image, std::uint64_t(f.index));
            report.render_s += seconds_since(t0);
            t0 = Clock::now();
            if (spec.outputs.images)
                write_png(writer.image_path(f.index, &row.image), recorded ? *recorded : image);
            if (spec.outputs.exr) write_exr(writer.image_path(f.index, &row.exr, "exr"), image);
            report.write_s += seconds_since(t0);
            ++report.images;
        }
        t0 = Clock::now();
        writer.write_label(row);
        if (spec.outputs.markers) write_markers(writer, f.index, model, r);
        report.write_s += seconds_since(t0);
        if (!row.converged) {
            ++report.flagged_frames;
            log << "chromasim: warning: frame " << f.index << " flagged: " << row.status << '\n';
        }
        previous = std::move(r);
        if (!options.quiet)
            log << "  frame " << f.index + 1 << "/" << plan.frames.size() << " " << f.phase
                << "  Fn " << row.normal_force_N << " N  Ft "
                << std::hypot(row.tangential_x_N, row.tangential_y_N) << " N  Gamma " << row.gamma
                << '\n';
    }
    report.frames = int(plan.frames.size());
    report.total_s = seconds_since(t_start);
    const auto& st = model.stats();
    std::ostringstream extra;
    extra << "frames: " << report.frames << "\nflagged_frames: " << report.flagged_frames
          << "\nmesh: {level: " << spec.sensor.mesh_level << ", nodes: " << st.nodes
          << ", tets: " << st.tets << "}\nwall_time_s: " << report.total_s << '\n';
    writer.commit(extra.str());
    return report;
}

} // namespace chromasim::generators
