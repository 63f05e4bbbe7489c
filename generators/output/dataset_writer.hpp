#pragma once
/// Writes a dataset so that it is either complete or absent, and so that a run killed at any
/// moment can be resumed: everything goes to DIR.partial beside the output (locked against a
/// second run), one trial at a time. A trial's files are written under temporary names and
/// renamed; its record (_progress/trial_NNNNNN.json, with every file's SHA-256) is written
/// last and makes it complete. At the end labels.csv and markers.csv are assembled from the
/// trials' shards in plan order, manifest.json lists every file's SHA-256, and the folder is
/// renamed into place. An existing dataset is never touched unless the user asked to overwrite
/// it, and then only replaced once the new one is complete. docs/DATASET_FORMAT.md.
///
/// A part of a sharded run (`generate --shard K/N`) is written the same way, but sealed with
/// part.json instead of being assembled: it keeps the trials' shards and records for `merge`
/// (generators/output/merge.hpp), which imports them into a new writer and assembles the dataset.
#include "generators/output/manifest.hpp"
#include "generators/spec/spec.hpp"

#include <filesystem>
#include <iosfwd>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

namespace chromasim::generators {

/// What is at the output path now.
enum class OutputState {
    absent,        ///< nothing there (or an empty folder)
    up_to_date,    ///< a complete dataset (manifest.json) from the same resolved spec and version
    other_content, ///< anything else
};

/// Inspects `out_dir`. `max_trials` is the slice the dataset holds (0: every trial): a dataset
/// of another slice is other content. With `shard` (a part of a sharded run) only a complete
/// part (part.json) of that shard is up to date, and a dataset is other content; without it, a
/// part is other content. Throws SpecError if it exists but is not a folder.
OutputState inspect_output(const std::filesystem::path& out_dir, const Spec& spec,
                           int max_trials = 0, const Shard& shard = {});

/// The resolved spec as stored in a dataset (first line names the chromasim version; a last
/// comment line names the slice when `max_trials` > 0).
std::string stored_spec_text(const Spec& spec, int max_trials = 0);

/// The resolved YAML inside `stored` (spec.resolved.yaml's bytes), the inverse of
/// stored_spec_text: nothing if its first line names another chromasim version or it does not
/// end with the comment of slice `max_trials`.
std::optional<std::string> resolved_yaml_of(const std::string& stored, int max_trials);

/// The record of trial `trial` in the completed folder `root` (a part, or DIR.partial),
/// checked: whole and well-formed, and every file it lists there with its SHA-256. Throws
/// SpecError naming the record or the first file that is missing or differs.
TrialRecord checked_trial_record(const std::filesystem::path& root, int trial);

/// "left" (finger 0) or "right" (finger 1).
const char* finger_name(int finger);

/// One fingertip's labels in one frame.
struct LabelRow {
    int frame = 0;
    std::string phase, image, exr;
    double normal_force_N = 0, tangential_x_N = 0, tangential_y_N = 0, requested_tangential_N = 0;
    double mu = 0, gamma = 0, indentation_mm = 0, contact_area_mm2 = 0, stick_area_mm2 = 0;
    bool sliding = false, converged = false;
    int contact_nodes = 0, solver_iterations = 0;
    double solver_residual_mm = 0, solver_residual_N = 0;
    double object_travel_x_mm = 0, object_travel_y_mm = 0;
    std::string status;
    bool reused = false; ///< the previous frame's result, not solved again (same load)
};

/// One labels.csv row: a frame of a trial, with every fingertip's labels.
struct FrameLabels {
    std::string split;
    int trial = 0, frame = 0;
    double time_s = 0;
    std::string phase, object, friction;
    double grip_N = 0, load_N = 0, travel_mm = 0;
    std::vector<LabelRow> fingers; ///< left, then right
};

/// How the writer treats what is already there.
struct WriterOptions {
    bool overwrite = false; ///< replace `out_dir` at commit; discard a partial folder (no resume)
    bool resume = false;    ///< finish the run that left DIR.partial (same resolved spec)
    int max_trials = 0;     ///< the slice written (0: every trial)
    Shard shard;            ///< a part of a sharded run: sealed with part.json, not assembled
    /// The command can resume (generate); false for merge, whose refusal of a DIR.partial then
    /// names only --overwrite.
    bool can_resume = true;
};

class DatasetWriter {
public:
    /// Checks the output, then creates (or, with `resume`, takes over) DIR.partial and locks
    /// it. Throws SpecError, naming the path and what is allowed, if `out_dir` holds other
    /// content and `overwrite` is false; if DIR.partial exists and neither `resume` nor
    /// `overwrite` is set; if another process holds its lock; or if DIR.partial was written
    /// from another resolved spec. Throws std::runtime_error naming the path and the OS error
    /// if the folder cannot be made or written. Resuming logs what it found on `log`.
    DatasetWriter(std::filesystem::path out_dir, const Spec& spec, const WriterOptions& options,
                  std::ostream& log);
    /// Removes DIR.partial if this run made it and completed no trial in it; otherwise keeps
    /// it for --resume.
    ~DatasetWriter();
    DatasetWriter(const DatasetWriter&) = delete;
    DatasetWriter& operator=(const DatasetWriter&) = delete;

    /// True if a previous run was killed after assembling the whole dataset in DIR.partial
    /// (manifest.json written; part.json for a part), only the final rename missing: call
    /// finish() and nothing else.
    bool assembled() const { return m_assembled; }
    /// Removes the run's own files (records, shards, lock) from the assembled DIR.partial and
    /// renames it to DIR (an old DIR, with --overwrite, is removed only after that). A part
    /// keeps its records and shards (merge reads them); only the lock goes.
    void finish();

    /// True (and the record kept for the manifest) if a previous run completed `trial` and
    /// every file of its record is there with its SHA-256. Otherwise false, and the trial must
    /// be run: begin_trial() removes whatever it left.
    bool completed(int trial);
    /// Starts trial `trial` of split `split`: removes any files an interrupted run left for it.
    void begin_trial(const std::string& split, int trial);

    /// Path (inside staging) of a fingertip's image of a frame,
    /// images/<split>/trial_NNNNNN/<finger>_NNNNNN.<extension> (png, exr), its folder made;
    /// `relative` gets the path stored in labels.
    std::filesystem::path image_path(const std::string& split, int trial, const std::string& finger,
                                     int frame, std::string* relative = nullptr,
                                     const char* extension = "png");
    void write_labels(const FrameLabels& row);
    /// The trial's sensors.csv row (a spec that varies its sensor: sensor_table.hpp).
    void write_sensor(std::string row) { m_sensor = std::move(row); }
    /// One row per marker: centre displacement of marker `m` of layer `layer`.
    void write_marker(const FrameLabels& frame, const std::string& finger, const char* layer,
                      int marker, const double x0_mm[3], const double u_mm[3]);
    /// A frame's eps_xx grid (row-major) as a row of strain/<split>/trial_NNNNNN/<finger>.csv.
    void write_strain(const FrameLabels& frame, const std::string& finger,
                      const std::vector<double>& eps_xx);
    /// Writes the trial's shards and strain files (temporary names, renamed), then its record
    /// with every file's SHA-256: from here on the trial is complete. `record` holds the
    /// trial's counts; its file list is filled here.
    void end_trial(TrialRecord record);
    /// Assembles labels.csv, markers.csv and (a varied sensor) sensors.csv from the shards of
    /// every trial in plan order and
    /// writes manifest.json (last). Every trial of the plan (slice) must be complete, `trials`
    /// of them. Then call finish().
    void assemble(const ManifestInfo& info, int trials);
    /// Seals a part instead: writes part.json (last), listing `part.trials`, which must be
    /// exactly the complete trials. Then call finish().
    void seal_part(const PartInfo& part);
    /// Makes trial `record.trial`, complete in the folder `from` (a checked part, see
    /// checked_trial_record), complete here: each of its files hard-linked into DIR.partial
    /// (copied where a link cannot be made, another filesystem), its record written. `from` is
    /// only read. Returns the number of files copied (0: every file linked).
    int import_trial(const std::filesystem::path& from, const TrialRecord& record);

    const std::filesystem::path& staging() const { return m_staging; }
    /// Trials complete in DIR.partial (run now or resumed).
    int completed_trials() const { return int(m_records.size()); }
    const std::map<int, TrialRecord>& records() const { return m_records; }

private:
    void take_over_partial(const WriterOptions& options, std::ostream& log);
    void lock();            ///< flock()s DIR.partial/lock; throws if another process holds it
    void write_pid() const; ///< the holder's pid in the lock file, for the message above
    void assemble_csv(const char* name, const std::string& header, const char* shard) const;
    std::map<std::string, std::string> checksums() const;
    void move_into_place();
    void remove_stale_old_copies() const;

    std::filesystem::path m_out, m_staging;
    const Spec& m_spec;
    bool m_overwrite = false, m_committed = false, m_made_here = false, m_assembled = false;
    int m_max_trials = 0;
    Shard m_shard;
    int m_lock_fd = -1;
    std::map<int, TrialRecord> m_records; ///< complete trials, by id
    // The current trial's text, written at end_trial.
    std::string m_split;
    int m_trial = -1, m_images = 0;
    std::ostringstream m_labels, m_markers;
    std::string m_sensor;
    std::map<std::string, std::ostringstream> m_strain; ///< by relative path
};

} // namespace chromasim::generators
