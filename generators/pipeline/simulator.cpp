#include "generators/pipeline/simulator.hpp"

#include "generators/io/stopwatch.hpp"
#include "generators/pipeline/sensor_bridge.hpp"
#include "generators/plan/sensor_variants.hpp"

#include <tbb/parallel_for.h>

#include <chrono>

namespace chromasim::generators {

namespace {

using Clock = std::chrono::steady_clock;

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

} // namespace

std::uint64_t noise_index(int trial, int finger, int frame) {
    return (std::uint64_t(trial) << 32) | (std::uint64_t(finger) << 31) | std::uint64_t(frame);
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

Simulator::Simulator(const Spec& spec, std::filesystem::path cache_dir)
    : Simulator(spec, stage_settings(spec), std::move(cache_dir)) {}

Simulator::Simulator(const Spec& spec, StageSettings settings, std::filesystem::path cache_dir)
    : m_spec(spec), m_settings(std::move(settings)), m_cache_dir(std::move(cache_dir)),
      m_request(frame_request(m_settings)) {
    if (varies_sensor(spec))
        throw SpecError(spec.source_path.string() + ": the spec varies its sensor (" +
                        what_varies(spec) +
                        "); a Simulator is one sensor: make it from sensor_spec(spec, "
                        "make_plan(spec).sensors[k])");
    const auto t0 = Clock::now();
    mechanics::DomeModelOptions options = m_settings.dome;
    options.cache_dir = m_cache_dir;
    m_model = std::make_unique<mechanics::DomeModel>(options);
    m_model_s = seconds_since(t0);
}

Simulator::~Simulator() = default;

const LightCacheOutcome& Simulator::prepare_renderer() {
    std::lock_guard lock(m_render_mutex);
    if (m_renderer) return m_light_cache;
    if (!renders())
        throw SpecError(m_spec.source_path.string() +
                        ": the spec renders no images (outputs.images and outputs.exr are "
                        "false); set outputs.images: true to get images");
    auto renderer = std::make_unique<render::Renderer>(m_settings.camera, *m_settings.optics);
    m_light_cache = generators::prepare_renderer(*renderer, m_settings,
                                                 undeformed_sensor_frame(*m_model), m_cache_dir);
    // The camera sensor turns the PNG's pixels into a recording; the EXR stays noise-free.
    if (m_settings.sensor) m_sensor.emplace(m_settings.camera, *m_settings.sensor);
    m_renderer = std::move(renderer);
    return m_light_cache;
}

bool Simulator::render(SolvedFrame& frame) {
    if (frame.image) return false;
    prepare_renderer();
    std::lock_guard lock(m_render_mutex);
    if (frame.image) return false;
    fill_sensor_frame(*m_model, frame.result, m_sensor_frame);
    m_renderer->set_frame(m_sensor_frame);
    frame.image = m_renderer->render(m_settings.render);
    return true;
}

render::Image Simulator::recorded(SolvedFrame& frame, std::uint64_t index) {
    render(frame);
    return m_sensor ? m_sensor->capture(*frame.image, index) : *frame.image;
}

const render::SensorModel* Simulator::sensor_model() const {
    return m_sensor ? &*m_sensor : nullptr;
}

Fingertip::Fingertip(const Simulator& simulator, mechanics::ObjectShape object)
    : m_simulator(&simulator), m_object(std::move(object)) {}

bool Fingertip::step(const FingerLoad& load) {
    if (m_current && m_load && load == *m_load) return true;
    auto frame = std::make_shared<SolvedFrame>();
    frame->result =
        m_simulator->model().solve(contact_load(load), m_simulator->request(), m_object,
                                   m_history ? &m_history->result : nullptr);
    if (frame->result.contact.converged) m_history = frame;
    m_current = std::move(frame);
    m_load = load;
    return false;
}

void Fingertip::reset() {
    m_load.reset();
    m_current.reset();
    m_history.reset();
}

std::vector<char> step_fingertips(std::vector<Fingertip>& fingers,
                                  const std::vector<FingerLoad>& loads) {
    if (loads.size() != fingers.size())
        throw std::logic_error("step_fingertips: one load per fingertip");
    std::vector<char> reused(fingers.size());
    tbb::parallel_for(std::size_t(0), fingers.size(),
                      [&](std::size_t f) { reused[f] = fingers[f].step(loads[f]); });
    return reused;
}

Spec::Object posed_object(const Spec::Object& object, const FingerSetup& finger) {
    Spec::Object posed = object;
    posed.offset_x_mm = finger.offset_mm.x();
    posed.offset_y_mm = finger.offset_mm.y();
    posed.yaw_deg = finger.yaw_deg;
    return posed;
}

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

Eigen::MatrixX3d marker_rest_positions(const mechanics::DomeModel& model, int layer) {
    const mechanics::MarkerDiscs& discs = model.markers();
    Eigen::MatrixX3d x0(discs.markers_per_layer, 3);
    for (int m = 0; m < discs.markers_per_layer; ++m)
        x0.row(m) = discs.points.row((layer * discs.markers_per_layer + m) * discs.points_per_marker);
    return x0;
}

Eigen::MatrixX3d marker_displacements(const mechanics::DomeModel& model,
                                      const mechanics::FrameResult& r, int layer) {
    const mechanics::MarkerDiscs& discs = model.markers();
    if (r.marker_points_mm.rows() != discs.points.rows())
        throw std::logic_error("marker_displacements: frame solved without its markers");
    Eigen::MatrixX3d u(discs.markers_per_layer, 3);
    for (int m = 0; m < discs.markers_per_layer; ++m) {
        const int row = (layer * discs.markers_per_layer + m) * discs.points_per_marker;
        u.row(m) = r.marker_points_mm.row(row) - discs.points.row(row);
    }
    return u;
}

TrialRun::TrialRun(const Simulator& simulator, const TrialPlan& trial)
    : m_simulator(&simulator), m_trial(&trial), m_reused(trial.fingers.size(), 0) {
    const ObjectSource& source = simulator.settings().objects[std::size_t(trial.object)];
    for (const FingerSetup& finger : trial.fingers)
        m_fingers.emplace_back(simulator, object_shape(source, posed_object(source.object, finger)));
}

FrameLabels TrialRun::next() {
    const FramePlan& frame = m_trial->frames.at(m_next++);
    const StageSettings& settings = m_simulator->settings();
    FrameLabels labels{m_trial->split,
                       m_trial->id,
                       frame.index,
                       frame.time_s,
                       phase_name(frame.phase),
                       settings.objects[std::size_t(m_trial->object)].object.name,
                       settings.friction_names[std::size_t(m_trial->friction)],
                       m_trial->grip_N,
                       frame.load_N,
                       frame.travel_mm,
                       {}};
    const auto t0 = Clock::now();
    m_reused = step_fingertips(m_fingers, frame.fingers);
    m_mechanics_s += seconds_since(t0);
    for (std::size_t f = 0; f < m_fingers.size(); ++f) {
        LabelRow row = label_row(frame, frame.fingers[f], m_fingers[f].current()->result);
        row.reused = m_reused[f] != 0;
        labels.fingers.push_back(std::move(row));
    }
    return labels;
}

const std::shared_ptr<SolvedFrame>& TrialRun::frame(int f) const {
    return m_fingers.at(std::size_t(f)).current();
}

} // namespace chromasim::generators
