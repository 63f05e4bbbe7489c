#include "generators/output/merge.hpp"

#include "generators/output/dataset_writer.hpp"
#include "generators/io/file_io.hpp"
#include "generators/io/stopwatch.hpp"

#include <chrono>
#include <optional>
#include <ostream>

namespace fs = std::filesystem;

namespace chromasim::generators {

namespace {

constexpr const char* kPart = "part.json";
constexpr const char* kSpec = "spec.resolved.yaml";

/// A part as read and checked on its own.
struct Part {
    fs::path dir;
    PartInfo info;
    std::string spec_text; ///< spec.resolved.yaml's bytes
};

[[noreturn]] void refuse(const fs::path& path, const std::string& what) {
    throw SpecError(path.string() + ": " + what);
}

/// Why `dir` is not a completed part, for a folder without part.json.
[[noreturn]] void not_a_part(const fs::path& dir) {
    const std::string allowed = "; allowed: the folders written by generate SPEC -o PART "
                                "--shard K/N, once complete";
    std::error_code ec;
    const fs::path partial = dir.string() + ".partial";
    if (dir.string().ends_with(".partial"))
        refuse(dir, "is an unfinished part (its shard is still running or was interrupted); "
                    "finish it with the same generate command and --resume" +
                        allowed);
    if (!fs::exists(dir, ec) && fs::exists(partial, ec))
        refuse(dir, "is not complete: " + partial.string() +
                        " holds its unfinished shard; finish it with the same generate command "
                        "and --resume" +
                        allowed);
    if (!fs::exists(dir, ec)) refuse(dir, "does not exist" + allowed);
    if (!fs::is_directory(dir, ec)) refuse(dir, "is not a folder" + allowed);
    if (fs::exists(dir / "manifest.json", ec))
        refuse(dir, "is a whole dataset, not a part of a sharded run" + allowed);
    refuse(dir, "holds no part.json: not a completed part" + allowed);
}

Part read_part(const fs::path& dir) {
    std::error_code ec;
    if (!fs::is_regular_file(dir / kPart, ec)) not_a_part(dir);
    Part part{dir, {}, {}};
    const std::optional<PartInfo> info = parse_part_json(read_file(dir / kPart));
    if (!info) refuse(dir / kPart, "not a whole, well-formed part.json");
    part.info = *info;
    const Shard& shard = part.info.shard;
    if (shard.count < 1 || shard.index < 1 || shard.index > shard.count)
        refuse(dir / kPart, "shard " + std::to_string(shard.index) + "/" +
                                std::to_string(shard.count) + " is not K/N with 1 <= K <= N");
    if (part.info.chromasim_version != CHROMASIM_VERSION)
        refuse(dir / kPart, "written by chromasim " + part.info.chromasim_version +
                                ", this is " CHROMASIM_VERSION
                                "; allowed: merge with the version that generated the parts "
                                "(the manifest names one version)");
    if (part.info.instruction_set != CHROMASIM_ARCH)
        refuse(dir / kPart, "built for instruction set " + part.info.instruction_set +
                                ", this build is for " CHROMASIM_ARCH
                                "; allowed: merge with a build for the parts' instruction set "
                                "(cmake -DCHROMASIM_ARCH=" +
                                part.info.instruction_set +
                                "): builds for two differ in the last bits of their images");
    if (!fs::is_regular_file(dir / kSpec, ec)) refuse(dir / kSpec, "missing");
    part.spec_text = read_file(dir / kSpec);
    if (sha256_hex(part.spec_text) != part.info.spec_sha256)
        refuse(dir / kSpec, "SHA-256 differs from the one in " + (dir / kPart).string() +
                                " (the file was changed or damaged)");
    return part;
}

/// Every part agrees with the first on what the merged dataset is.
void check_same_dataset(const std::vector<Part>& parts) {
    const Part& first = parts.front();
    for (const Part& p : parts) {
        if (p.spec_text != first.spec_text)
            refuse(p.dir / kSpec, "differs from " + (first.dir / kSpec).string() +
                                      ": the parts were generated from different specs (or "
                                      "--max-trials); allowed: the parts of one sharded run");
        const fs::path json = p.dir / kPart;
        const PartInfo &a = p.info, &b = first.info;
        if (a.shard.count != b.shard.count)
            refuse(json, "shard " + a.shard.text() + " is one of " + std::to_string(a.shard.count) +
                             ", but " + (first.dir / kPart).string() + " is one of " +
                             std::to_string(b.shard.count) +
                             "; allowed: the parts of one sharded run (the same N)");
        if (a.spec_source != b.spec_source)
            refuse(json, "spec source '" + a.spec_source + "' differs from '" + b.spec_source +
                             "' in " + (first.dir / kPart).string() +
                             "; the manifest names one spec path: allowed: parts generated "
                             "with the same SPEC argument");
        if (a.max_trials != b.max_trials || !(a.info == b.info))
            refuse(json, "its slice, mesh or strain grid differ from " +
                             (first.dir / kPart).string() +
                             "; allowed: the parts of one sharded run");
    }
}

/// The parts by shard index, 1..N each exactly once.
std::vector<const Part*> by_shard(const std::vector<Part>& parts) {
    const int n = parts.front().info.shard.count;
    std::vector<const Part*> shards(std::size_t(n) + 1, nullptr);
    for (const Part& p : parts) {
        const Shard& s = p.info.shard;
        const Part*& slot = shards[std::size_t(s.index)];
        if (slot)
            throw SpecError("shard " + s.text() + " is given twice: " + slot->dir.string() +
                            " and " + p.dir.string() + "; allowed: each shard 1.." +
                            std::to_string(n) + " exactly once");
        slot = &p;
    }
    for (int k = 1; k <= n; ++k)
        if (!shards[std::size_t(k)])
            throw SpecError("shard " + std::to_string(k) + "/" + std::to_string(n) +
                            " is missing: the parts given hold " + std::to_string(parts.size()) +
                            " of the " + std::to_string(n) + " shards; allowed: each shard 1.." +
                            std::to_string(n) + " exactly once");
    return shards;
}

/// Each part's trials are its shard's, and every file of each is as its record says.
std::vector<std::pair<const Part*, TrialRecord>>
checked_trials(const std::vector<const Part*>& shards) {
    const PartInfo& any = shards[1]->info;
    const int trials = any.max_trials > 0 ? any.max_trials : any.info.planned_trials;
    for (std::size_t k = 1; k < shards.size(); ++k) {
        std::vector<int> expected;
        for (int t = int(k) - 1; t < trials; t += any.shard.count)
            expected.push_back(t);
        if (shards[k]->info.trials != expected)
            refuse(shards[k]->dir / kPart,
                   "lists other trials than shard " + shards[k]->info.shard.text() + " of " +
                       std::to_string(trials) + " owns (those with index mod " +
                       std::to_string(any.shard.count) + " = " + std::to_string(k - 1) + ")");
    }
    std::vector<std::pair<const Part*, TrialRecord>> records;
    for (int t = 0; t < trials; ++t) {
        const Part& p = *shards[std::size_t(t % any.shard.count + 1)];
        records.emplace_back(&p, checked_trial_record(p.dir, t));
    }
    return records;
}

} // namespace

MergeReport merge(const MergeOptions& options, std::ostream& log) {
    const auto t_start = std::chrono::steady_clock::now();
    if (options.parts.empty()) throw SpecError("merge: no parts given; allowed: PART...");
    // 1. Every check, before anything is written.
    std::vector<Part> parts;
    for (const fs::path& dir : options.parts) {
        if (fs::weakly_canonical(dir) == fs::weakly_canonical(options.out_dir))
            refuse(dir, "is both a part and the output; allowed: another output path (merge "
                        "never replaces a part)");
        parts.push_back(read_part(dir));
    }
    check_same_dataset(parts);
    const std::vector<const Part*> shards = by_shard(parts);
    const PartInfo& first = parts.front().info;
    const std::optional<std::string> yaml =
        resolved_yaml_of(parts.front().spec_text, first.max_trials);
    if (!yaml)
        refuse(parts.front().dir / kSpec, "not a spec.resolved.yaml of chromasim " CHROMASIM_VERSION
                                          " (first line) and of the part's slice (last line)");
    const Spec spec = parse_stored_spec(*yaml, first.spec_source);
    MergeReport report;
    report.parts = int(parts.size());
    if (inspect_output(options.out_dir, spec, first.max_trials) == OutputState::up_to_date &&
        !options.overwrite) {
        report.up_to_date = true;
        log << "chromasim: " << options.out_dir.string()
            << " already holds this dataset (same resolved spec); nothing to do.\n";
        return report;
    }
    const auto records = checked_trials(shards);
    log << "chromasim: " << parts.size() << " parts of " << records.size()
        << " trials checked (spec, shards, every file's SHA-256); merging into "
        << options.out_dir.string() << '\n';

    // 2. DIR.partial as generate writes it, from the parts' files; then assembled and renamed.
    DatasetWriter writer(options.out_dir, spec,
                         {options.overwrite, false, first.max_trials, {}, false}, log);
    try {
        for (const auto& [part, record] : records) {
            report.copied += writer.import_trial(part->dir, record);
            report.files += int(record.files.size());
        }
        writer.assemble(first.info, int(records.size()));
        writer.finish();
    } catch (...) { // only links and copies of the parts' files: nothing of the user's is lost
        std::error_code ec;
        fs::remove_all(writer.staging(), ec);
        throw;
    }
    report.trials = int(records.size());
    report.total_s = seconds_since(t_start);
    return report;
}

} // namespace chromasim::generators
