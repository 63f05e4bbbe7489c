#pragma once
/// `chromasim merge`: joins the parts of a sharded run (`generate --shard K/N`) into the
/// dataset an unsharded `generate` of the same spec writes, byte for byte, manifest.json
/// included. docs/DATASET_FORMAT.md, "Shards and merge (clusters)".
#include <filesystem>
#include <iosfwd>
#include <vector>

namespace chromasim::generators {

struct MergeOptions {
    std::vector<std::filesystem::path> parts; ///< the N parts' folders, in any order
    std::filesystem::path out_dir;
    bool overwrite = false; ///< replace an existing DIR (once complete) and discard DIR.partial
};

struct MergeReport {
    bool up_to_date = false; ///< nothing done: DIR already holds this dataset
    int parts = 0, trials = 0, files = 0;
    int copied = 0; ///< files copied because a hard link could not be made (another filesystem)
    double total_s = 0;
};

/// Checks the parts, then writes the dataset. Before anything is written it requires: every
/// part complete (part.json), written by this chromasim version, the same spec.resolved.yaml
/// bytes (and SHA-256 as recorded), spec path, shard count N, slice, mesh and strain grid;
/// shards 1..N each exactly once; each part holding exactly its trials; every file of every
/// trial matching its record's SHA-256; DIR none of the parts. Any failure throws SpecError naming
/// the part, file or shard, and leaves neither DIR nor DIR.partial. Then it writes DIR.partial as
/// DatasetWriter does for generate (locked; files hard-linked from the parts, copied where a
/// link cannot be made; labels.csv and markers.csv assembled in plan order; manifest.json last)
/// and renames it to DIR. The parts are only read.
MergeReport merge(const MergeOptions& options, std::ostream& log);

} // namespace chromasim::generators
