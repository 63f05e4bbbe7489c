#pragma once
/// Writes a dataset so that it is either complete or absent: everything goes to a staging
/// folder beside the output, which is renamed into place only after the last file is closed.
/// An existing dataset is never touched unless the user asked to overwrite it, and then only
/// replaced once the new one is complete.
#include "generators/spec.hpp"

#include <filesystem>
#include <fstream>
#include <string>

namespace chromasim::generators {

/// What is at the output path now.
enum class OutputState {
    absent,        ///< nothing there (or an empty folder)
    up_to_date,    ///< a complete dataset from the same resolved spec and chromasim version
    other_content, ///< anything else
};

/// Inspects `out_dir`. Throws SpecError if it exists but is not a folder.
OutputState inspect_output(const std::filesystem::path& out_dir, const Spec& spec);

/// The resolved spec as stored in a dataset (first line names the chromasim version).
std::string stored_spec_text(const Spec& spec);

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
};

class DatasetWriter {
public:
    /// Creates the staging folder. `overwrite` allows replacing `out_dir` at commit.
    /// Throws SpecError if `out_dir` holds other content and `overwrite` is false.
    DatasetWriter(std::filesystem::path out_dir, const Spec& spec, bool overwrite);
    /// Removes the staging folder unless commit() succeeded.
    ~DatasetWriter();
    DatasetWriter(const DatasetWriter&) = delete;
    DatasetWriter& operator=(const DatasetWriter&) = delete;

    /// Path (inside staging) for a frame's image file of `extension` (png, exr); `relative`
    /// gets the path stored in labels.
    std::filesystem::path image_path(int frame, std::string* relative = nullptr,
                                     const char* extension = "png");
    void write_label(const LabelRow& row);
    /// One row per marker: centre displacement of marker `m` of layer `layer`.
    void write_marker(int frame, const char* layer, int marker, const double x0_mm[3],
                      const double u_mm[3]);
    /// Closes the files, writes the manifest and moves the dataset into place.
    void commit(const std::string& manifest_extra);

    const std::filesystem::path& staging() const { return m_staging; }

private:
    void open_outputs();
    std::filesystem::path m_out, m_staging;
    const Spec& m_spec;
    bool m_overwrite = false, m_committed = false;
    std::ofstream m_labels, m_markers;
    int m_images = 0, m_label_rows = 0;
};

} // namespace chromasim::generators
