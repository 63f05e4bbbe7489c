#pragma once
/// A spec's sensor as objects to step from one's own code: `generate` runs its trials through
/// them, and the Python API (python/chromasim) exposes them, so both give the same bytes.
///
/// - Simulator: what every frame shares, built once: the dome model (mesh, factorization,
///   responses; the mechanics cache of `cache_dir`) and, only when a first image is asked for,
///   the renderer (auto exposure, the fast integrator's light cache, read from `cache_dir`)
///   and the camera sensor model.
/// - Fingertip: one fingertip against one posed object, frame after frame, with its stick/slip
///   history: a step solves from the last converged frame.
/// - TrialRun: a planned trial, frame by frame, every fingertip in parallel.
#include "generators/output/dataset_writer.hpp"
#include "generators/pipeline/light_cache_store.hpp"
#include "generators/plan/plan.hpp"
#include "generators/spec/spec.hpp"
#include "generators/spec/stage_params.hpp"
#include "mechanics/dome_model.hpp"
#include "render/renderer.hpp"
#include "render/sensor_model.hpp"

#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

namespace chromasim::generators {

/// A solved frame of one fingertip and, once asked for, its noise-free render. A frame whose
/// load equals the previous one's is not solved again: both share one SolvedFrame (and image).
struct SolvedFrame {
    mechanics::FrameResult result;
    std::optional<render::Image> image; ///< Simulator::image fills it on first request
};

/// The noise index of a recorded image: distinct per trial, finger and frame.
std::uint64_t noise_index(int trial, int finger, int frame);

class Simulator {
public:
    /// Builds the dome model (or reads it from `cache_dir`; empty: no cache). Reads every file
    /// the outputs need first (stage_settings): a bad file throws before any work.
    Simulator(const Spec& spec, std::filesystem::path cache_dir);
    /// The same with the spec's files already read (stage_settings(spec)).
    Simulator(const Spec& spec, StageSettings settings, std::filesystem::path cache_dir);
    ~Simulator();

    const Spec& spec() const { return m_spec; }
    const StageSettings& settings() const { return m_settings; }
    const mechanics::DomeModel& model() const { return *m_model; }
    /// What each solve returns beyond its labels: only what the spec's outputs need.
    const mechanics::FrameRequest& request() const { return m_request; }
    const std::filesystem::path& cache_dir() const { return m_cache_dir; }
    double model_seconds() const { return m_model_s; }

    /// The spec renders (outputs.images or outputs.exr).
    bool renders() const { return m_settings.optics.has_value(); }
    /// Builds the renderer now if it is not yet (exposure, light cache) and returns how the
    /// light cache was had. Throws SpecError if the spec renders nothing.
    const LightCacheOutcome& prepare_renderer();
    /// The renderer is built (prepare_renderer, or a first image).
    bool images_ready() const { return m_renderer != nullptr; }
    /// The noise-free render of `frame` (made once, then kept in it). Thread-safe: renders one
    /// image at a time (the renderer parallelizes inside). Returns whether it rendered now.
    bool render(SolvedFrame& frame);
    /// The image a PNG holds: `frame`'s render through the camera sensor model when the spec
    /// enables it (render.sensor), else the render itself.
    render::Image recorded(SolvedFrame& frame, std::uint64_t noise_index);
    /// The camera sensor model (null unless outputs.images and render.sensor.enabled).
    const render::SensorModel* sensor_model() const;

private:
    Spec m_spec;
    StageSettings m_settings;
    std::filesystem::path m_cache_dir;
    std::unique_ptr<mechanics::DomeModel> m_model;
    double m_model_s = 0.0;
    mechanics::FrameRequest m_request;
    std::mutex m_render_mutex;
    std::unique_ptr<render::Renderer> m_renderer;
    std::optional<render::SensorModel> m_sensor;
    render::SensorFrame m_sensor_frame; ///< buffers reused from frame to frame
    LightCacheOutcome m_light_cache;
};

/// One fingertip pressed by one posed rigid object, frame after frame.
class Fingertip {
public:
    Fingertip(const Simulator& simulator, mechanics::ObjectShape object);
    /// Solves the next frame under `load` from the last converged frame (from rest before the
    /// first, or after reset()). A load equal to the last frame's is not solved again: its
    /// result is shared. Returns whether it was. Safe to run for several fingertips at once.
    bool step(const FingerLoad& load);
    /// The last frame (null before the first step).
    const std::shared_ptr<SolvedFrame>& current() const { return m_current; }
    /// Forgets the history: the next step starts from rest.
    void reset();

private:
    const Simulator* m_simulator;
    mechanics::ObjectShape m_object;
    std::optional<FingerLoad> m_load;     ///< the last frame's load
    std::shared_ptr<SolvedFrame> m_current;
    /// The last converged frame: the next one starts from it (null: none yet, from rest).
    std::shared_ptr<SolvedFrame> m_history;
};

/// Gives `renderer` what settings.render's integrator needs before its first frame: the path
/// and fast integrators' auto exposure on `rest` (the undeformed sensor) and the fast
/// integrator's light cache of settings.optics (read from or saved to `cache_dir`). Returns the
/// light cache's outcome (empty for the preview and path integrators).
LightCacheOutcome prepare_renderer(render::Renderer& renderer, const StageSettings& settings,
                                   const render::SensorFrame& rest,
                                   const std::filesystem::path& cache_dir);

/// Steps every fingertip under its load in parallel (they share nothing); returns whether each
/// reused its last frame (Fingertip::step).
std::vector<char> step_fingertips(std::vector<Fingertip>& fingers,
                                  const std::vector<FingerLoad>& loads);

/// `object` as finger `finger` of `trial` sees it: its offset and yaw (mirror, jitter).
Spec::Object posed_object(const Spec::Object& object, const FingerSetup& finger);

/// One fingertip's labels of a solved frame: `load` is the finger's load in frame `f` (image
/// paths left empty).
LabelRow label_row(const FramePlan& f, const FingerLoad& load, const mechanics::FrameResult& r);

/// Marker displacements of `r` (mm): layer 0 (inner) or 1 (outer), one row per marker, the
/// displacement of its centre from its rest position (markers.csv's u).
Eigen::MatrixX3d marker_displacements(const mechanics::DomeModel& model,
                                      const mechanics::FrameResult& r, int layer);
/// Rest positions (mm) of a layer's marker centres (markers.csv's x0).
Eigen::MatrixX3d marker_rest_positions(const mechanics::DomeModel& model, int layer);

/// A planned trial, frame by frame.
class TrialRun {
public:
    TrialRun(const Simulator& simulator, const TrialPlan& trial);
    bool done() const { return m_next >= m_trial->frames.size(); }
    /// Solves the next frame, every fingertip in parallel (they share nothing), and returns its
    /// labels (image paths empty). Precondition: !done().
    FrameLabels next();
    const TrialPlan& plan() const { return *m_trial; }
    /// The last frame's fingertip `f` (TrialPlan::fingers order), and whether its result was
    /// the frame before's, reused.
    const std::shared_ptr<SolvedFrame>& frame(int f) const;
    bool reused(int f) const { return m_reused[std::size_t(f)] != 0; }
    int fingers() const { return int(m_fingers.size()); }
    double mechanics_seconds() const { return m_mechanics_s; } ///< over the frames so far

private:
    const Simulator* m_simulator;
    const TrialPlan* m_trial;
    std::vector<Fingertip> m_fingers;
    std::vector<char> m_reused;
    std::size_t m_next = 0;
    double m_mechanics_s = 0.0;
};

} // namespace chromasim::generators
