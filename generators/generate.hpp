#pragma once
/// The main job: spec -> plan -> mechanics -> render -> writers.
#include "generators/dataset_writer.hpp"
#include "generators/plan.hpp"
#include "generators/spec.hpp"
#include "mechanics/dome_model.hpp"

#include <filesystem>
#include <iosfwd>

namespace chromasim::generators {

struct GenerateOptions {
    std::filesystem::path out_dir;
    bool overwrite = false; ///< replace an existing dataset from another spec
    bool quiet = false;     ///< no per-frame progress lines
    /// On-disk cache of the mechanics precomputation (empty: off). See default_cache_dir().
    std::filesystem::path cache_dir;
};

/// $CHROMASIM_CACHE_DIR, else $XDG_CACHE_HOME/chromasim, else $HOME/.cache/chromasim; empty
/// if none of these variables is set.
std::filesystem::path default_cache_dir();

struct GenerateReport {
    bool up_to_date = false; ///< nothing done: the output already holds this dataset
    int frames = 0, images = 0, flagged_frames = 0;
    double precompute_s = 0, mechanics_s = 0, render_s = 0, write_s = 0, total_s = 0;
};

/// The labels.csv row of a solved frame (image paths left empty).
LabelRow label_row(const FramePlan& f, const mechanics::FrameResult& r);

/// Logs the dome mesh's size, the precompute time and the cache state of `model` (one line,
/// plus a line with the cache note if there is one).
void log_dome_model(const Spec& spec, const mechanics::DomeModel& model, double precompute_s,
                    const std::filesystem::path& cache_dir, std::ostream& log);

/// Runs a validated spec. Checks the output path before any work; writes atomically
/// (dataset_writer.hpp). Frames whose solver did not converge are written with
/// converged = 0 and a status, counted in `flagged_frames`, and reported on `log`.
GenerateReport generate(const Spec& spec, const GenerateOptions& options, std::ostream& log);

} // namespace chromasim::generators
