#pragma once
/// `chromasim check DATASET`: reads a dataset folder (also one written by an older chromasim)
/// and lists every label that is impossible or inconsistent, by file, line, trial, frame,
/// fingertip and column. The rules and bounds: docs/DATASET_FORMAT.md, "Checking a dataset".
/// Only reads: nothing in the folder or beside it is written.
#include <filesystem>
#include <iosfwd>
#include <string>
#include <vector>

namespace chromasim::generators {

/// One impossible or inconsistent value.
struct CheckFinding {
    std::string file; ///< relative to the dataset: labels.csv, markers.csv, sensors.csv, ...
    long line = 0;    ///< 1-based line of the file (0: the file as a whole)
    int trial = -1, frame = -1;
    std::string finger; ///< left, right, or empty for a frame's own columns
    std::string column, value;
    std::string problem; ///< the rule it breaks, with the bound
};

struct CheckReport {
    std::string version;     ///< chromasim_version in manifest.json
    long label_rows = 0;     ///< labels.csv rows
    long marker_rows = 0;    ///< markers.csv rows (0 when the dataset has none)
    long sensor_rows = 0;    ///< sensors.csv rows (0 when the spec varies no sensor key)
    long flagged = 0;        ///< fingertip frames with converged = 0 (marked, not errors)
    long findings_total = 0; ///< every finding, also those past the list's limit
    std::vector<CheckFinding> findings; ///< the first `max_findings`
};

struct CheckOptions {
    std::size_t max_findings = 200; ///< findings kept in the report (all are counted)
};

/// Checks the dataset in `dir`. Throws SpecError, before reading any label, when `dir` is not a
/// complete chromasim dataset (no folder, no manifest.json or labels.csv, an unreadable
/// manifest) or was written by a newer chromasim or manifest format than this build reads.
CheckReport check_dataset(const std::filesystem::path& dir, const CheckOptions& options = {});

/// The report as text: a summary line, then one line per finding.
void print_check_report(const std::filesystem::path& dir, const CheckReport& report,
                        std::ostream& out);

} // namespace chromasim::generators
