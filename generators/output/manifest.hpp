#pragma once
/// manifest.json (docs/DATASET_FORMAT.md) and the per-trial records a run keeps in its partial
/// folder until the dataset is assembled. Plain data in, JSON text out: no file access here.
#include "generators/plan/plan.hpp"
#include "generators/spec/spec.hpp"

#include <map>
#include <optional>
#include <string>
#include <vector>

namespace chromasim::generators {

/// What one trial wrote: the record that makes the trial complete (DIR.partial/_progress/
/// trial_NNNNNN.json). A trial without a record, or whose files do not match it, is redone.
struct TrialRecord {
    int trial = 0;
    std::string split;
    int frames = 0, images = 0; ///< frames (labels rows) and image files written
    int solves = 0, reused_solves = 0, renders = 0, flagged_frames = 0;
    std::map<std::string, std::string> files; ///< path relative to the dataset -> SHA-256 hex
};

std::string trial_record_json(const TrialRecord& record);
/// The record in `text`, or nothing if it is not a whole, well-formed record.
std::optional<TrialRecord> parse_trial_record(const std::string& text);

/// What only the run knows: the mesh it built and the strain grid.
struct ManifestInfo {
    int planned_trials = 0; ///< trials in the whole plan (the dataset may be a slice)
    std::string mesh_level;
    int element_order = 1;
    int mesh_nodes = 0, mesh_tets = 0;
    bool strain = false;
    int strain_nx = 0, strain_ny = 0;
    double strain_half_width_x_mm = 0, strain_half_width_y_mm = 0;
    bool operator==(const ManifestInfo&) const = default;
};

/// manifest.json's text: the resolved spec `spec_text` (spec.resolved.yaml's bytes) and its
/// SHA-256, versions, counts per split summed over `records` (in plan order), and
/// `checksums` (every other file of the dataset, relative path -> SHA-256). Holds nothing
/// that depends on the clock, the thread count or the machine: identical runs give identical
/// bytes.
std::string manifest_json(const Spec& spec, const std::string& spec_text, int max_trials,
                          const ManifestInfo& info, const std::vector<TrialRecord>& records,
                          const std::map<std::string, std::string>& checksums);

/// part.json of a completed part (`generate --shard K/N`, docs/DATASET_FORMAT.md, "Shards and
/// merge"): what `merge` needs besides the trials' records to write the manifest an unsharded
/// run writes, and to check that the parts belong together.
struct PartInfo {
    std::string chromasim_version; ///< the version that wrote the part
    std::string instruction_set;   ///< the build's (CMakeLists.txt, CHROMASIM_ARCH)
    Shard shard;
    std::string spec_source; ///< the spec path as given to generate (manifest spec.source)
    std::string spec_sha256; ///< of the part's spec.resolved.yaml
    int max_trials = 0;      ///< the slice (0: every trial of the plan)
    std::vector<int> trials; ///< the trials the part holds, ascending
    ManifestInfo info;       ///< planned trials, mesh, strain grid
};

std::string part_json(const PartInfo& part);
/// The part in `text`, or nothing if it is not a whole, well-formed part.json.
std::optional<PartInfo> parse_part_json(const std::string& text);

} // namespace chromasim::generators
