#pragma once
/// Writes a dataset so that it is either complete or absent: everything goes to a staging
/// folder beside the output, which is renamed into place only after the last file is closed.
/// An existing dataset is never touched unless the user asked to overwrite it, and then only
/// replaced once the new one is complete.
#include "generators/spec.hpp"

#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

namespace chromasim::generators {

/// What is at the output path now.
enum class OutputState {
    absent,        ///< nothing there (or an empty folder)
    up_to_date,    ///< a complete dataset from the same resolved spec and chromasim version
    other_content, ///< anything else
};

/// Inspects `out_dir`. `max_trials` is the slice the dataset holds (0: every trial): a dataset
/// of another slice is other content. Throws SpecError if it exists but is not a folder.
OutputState inspect_output(const std::filesystem::path& out_dir, const Spec& spec,
                           int max_trials = 0);

/// The resolved spec as stored in a dataset (first line names the chromasim version; a last
/// comment line names the slice when `max_trials` > 0).
std::string stored_spec_text(const Spec& spec, int max_trials = 0);

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

class DatasetWriter {
public:
    /// Creates the staging folder. `overwrite` allows replacing `out_dir` at commit;
    /// `max_trials` is the slice written (0: every trial). Throws SpecError if `out_dir` holds
    /// other content and `overwrite` is false.
    DatasetWriter(std::filesystem::path out_dir, const Spec& spec, bool overwrite,
                  int max_trials = 0);
    /// Removes the staging folder unless commit() succeeded.
    ~DatasetWriter();
    DatasetWriter(const DatasetWriter&) = delete;
    DatasetWriter& operator=(const DatasetWriter&) = delete;

    /// Path (inside staging) of a fingertip's image of a frame,
    /// images/<split>/trial_NNNNNN/<finger>_NNNNNN.<extension> (png, exr), its folder made;
    /// `relative` gets the path stored in labels.
    std::filesystem::path image_path(const std::string& split, int trial, const std::string& finger,
                                     int frame, std::string* relative = nullptr,
                                     const char* extension = "png");
    void write_labels(const FrameLabels& row);
    /// One row per marker: centre displacement of marker `m` of layer `layer`.
    void write_marker(const FrameLabels& frame, const std::string& finger, const char* layer,
                      int marker, const double x0_mm[3], const double u_mm[3]);
    /// A frame's eps_xx grid (row-major) as a row of strain/<split>/trial_NNNNNN/<finger>.csv.
    void write_strain(const FrameLabels& frame, const std::string& finger,
                      const std::vector<double>& eps_xx);
    /// Closes the trial's strain files.
    void end_trial();
    /// Closes the files, writes the manifest and moves the dataset into place.
    void commit(const std::string& manifest_extra);

    const std::filesystem::path& staging() const { return m_staging; }

private:
    void open_outputs();
    std::filesystem::path m_out, m_staging;
    const Spec& m_spec;
    bool m_overwrite = false, m_committed = false;
    std::ofstream m_labels, m_markers;
    std::map<std::string, std::ofstream> m_strain; ///< the current trial's, by relative path
    int m_max_trials = 0;
    int m_images = 0, m_label_rows = 0;
};

} // namespace chromasim::generators
