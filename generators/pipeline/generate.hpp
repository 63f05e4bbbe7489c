#pragma once
/// The main job: spec -> plan -> mechanics -> render -> writers.
#include "generators/output/dataset_writer.hpp"
#include "generators/pipeline/light_cache_store.hpp"
#include "generators/pipeline/simulator.hpp"
#include "generators/plan/plan.hpp"
#include "generators/spec/spec.hpp"
#include "generators/spec/stage_params.hpp"
#include "mechanics/dome_model.hpp"
#include "render/renderer.hpp"

#include <filesystem>
#include <iosfwd>

namespace chromasim::generators {

struct GenerateOptions {
    std::filesystem::path out_dir;
    bool overwrite = false; ///< replace an existing dataset from another spec
    bool quiet = false;     ///< no per-trial lines, no progress (generators/pipeline/progress.hpp)
    /// On-disk cache of the mechanics precomputation and of the fast integrator's light
    /// cache (empty: off). See default_cache_dir().
    std::filesystem::path cache_dir;
    /// Run only the first `max_trials` trials of the plan (0, or at least the plan's count:
    /// all): a slice of a big spec. Trial k of the slice is trial k of the whole plan (same
    /// content, same split).
    int max_trials = 0;
    /// Finish the interrupted run that left DIR.partial: its complete trials are checked
    /// against their SHA-256 and kept, the others run; the dataset is byte-identical to an
    /// uninterrupted run's.
    bool resume = false;
    /// Write only this shard's part of the dataset (generate --shard K/N): the trials t with
    /// t mod N = K - 1 (of the slice, with max_trials), sealed with part.json instead of
    /// assembled; `merge` joins the N parts (generators/output/merge.hpp). Not sharded by default.
    Shard shard;
    /// The log is a terminal: the progress line is redrawn in place; else plain lines every
    /// 10 s.
    bool terminal = false;
};

/// $CHROMASIM_CACHE_DIR, else $XDG_CACHE_HOME/chromasim, else $HOME/.cache/chromasim; empty
/// if none of these variables is set.
std::filesystem::path default_cache_dir();

struct GenerateReport {
    bool up_to_date = false; ///< nothing done: the output already holds this dataset
    int trials = 0; ///< trials in the dataset or part (run now or kept from an interrupted run)
    int resumed_trials = 0; ///< of those, trials an interrupted run had completed (--resume)
    /// --resume found the whole dataset assembled in DIR.partial and only renamed it (the
    /// counts are then in its manifest.json, not here).
    bool moved_only = false;
    int planned_trials = 0; ///< trials in the whole plan
    /// The dataset's counts (resumed trials included).
    int frames = 0, images = 0;
    int flagged_frames = 0; ///< finger-frames whose solver did not converge
    /// Finger-frames solved, and those that reused the previous frame's result (same load).
    int solves = 0, reused_solves = 0;
    int renders = 0; ///< images rendered (a reused result of an unmoved scene reuses its image)
    double precompute_s = 0, mechanics_s = 0, render_s = 0, write_s = 0, total_s = 0;
    double light_cache_s = 0;           ///< the fast integrator's light cache, part of precompute_s
    bool light_cache_from_file = false; ///< read from GenerateOptions::cache_dir
};

/// Logs the dome mesh's size, the precompute time and the cache state of `model` (one line,
/// plus a line with the cache note if there is one).
void log_dome_model(const mechanics::DomeModel& model, double precompute_s,
                    const std::filesystem::path& cache_dir, std::ostream& log);

/// Runs a validated spec: every trial of make_plan (or the first options.max_trials), each
/// finger's frames in order from the state its previous frame left. A finger whose load equals
/// its previous frame's (the hold) is not solved again: the result is reused, and so is the
/// image rendered from it. Checks the output path and reads every object's file before any
/// work; writes atomically and resumably (dataset_writer.hpp). Frames whose solver did not converge
/// are written with converged = 0 and a status, counted in `flagged_frames`, and reported on `log`.
/// With options.shard, only that shard's trials, written as a part (DatasetWriter::seal_part);
/// a shard that owns no trial (more shards than trials) is a valid, empty part.
///
/// Test only: CHROMASIM_TEST_KILL_AT=K makes the process kill itself (SIGKILL) at its K-th
/// write step (each frame written, each trial's record, the assembled dataset before its
/// rename), so that tests can check --resume at every kind of step.
GenerateReport generate(const Spec& spec, const GenerateOptions& options, std::ostream& log);

} // namespace chromasim::generators
