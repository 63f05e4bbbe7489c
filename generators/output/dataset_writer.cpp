#include "generators/output/dataset_writer.hpp"

#include "generators/io/file_io.hpp"
#include "generators/output/label_cells.hpp"
#include "generators/output/sensor_table.hpp"
#include "generators/plan/sensor_variants.hpp"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <iomanip>
#include <ostream>
#include <stdexcept>

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

namespace fs = std::filesystem;

namespace chromasim::generators {

namespace {

constexpr const char* kProgress = "_progress"; ///< trial records and shards, in DIR.partial only
constexpr const char* kLock = "lock";          ///< in DIR.partial: flock()ed by the running process
constexpr const char* kManifest = "manifest.json";
constexpr const char* kSpec = "spec.resolved.yaml";
constexpr const char* kPart = "part.json"; ///< a completed part's seal (generate --shard)
/// In DIR.partial/_progress of a part: "K/N", so that --resume refuses another --shard.
constexpr const char* kShardMarker = "shard";
constexpr const char* kMarkersHeader =
    "split,trial,frame,finger,layer,marker,x0_mm,y0_mm,z0_mm,ux_mm,uy_mm,uz_mm";

std::string trial_name(int trial) {
    char name[32];
    std::snprintf(name, sizeof name, "trial_%06d", trial);
    return name;
}

std::string trial_folder(const std::string& split, int trial) {
    return split + "/" + trial_name(trial);
}

/// A filesystem call's failure as the user should read it: the path and the OS's reason.
[[noreturn]] void fail(const std::string& what, const fs::path& path, const std::error_code& ec) {
    throw std::runtime_error(what + " " + path.string() + ": " + ec.message());
}

void make_folder(const fs::path& path) {
    std::error_code ec;
    fs::create_directories(path, ec);
    if (ec) fail("cannot create folder", path, ec);
}

void remove_path(const fs::path& path) {
    std::error_code ec;
    fs::remove_all(path, ec);
    if (ec) fail("cannot remove", path, ec);
}

std::string partial_error(const fs::path& staging, const std::string& what) {
    return staging.string() + ": " + what;
}

/// The shard a partial folder was written for ("" when not sharded).
std::string stored_shard(const fs::path& staging) {
    const fs::path marker = staging / kProgress / kShardMarker;
    std::error_code ec;
    return fs::exists(marker, ec) ? read_file(marker) : std::string();
}

/// Trial `trial`'s record in `root`, whole, every file there with its SHA-256; else nothing,
/// and `problem` says why (the path first).
std::optional<TrialRecord> read_checked(const fs::path& root, int trial, std::string* problem) {
    const fs::path record_path = root / kProgress / (trial_name(trial) + ".json");
    std::error_code ec;
    if (!fs::exists(record_path, ec)) {
        *problem = record_path.string() + ": missing (the trial is not complete)";
        return std::nullopt;
    }
    std::optional<TrialRecord> record = parse_trial_record(read_file(record_path));
    if (!record || record->trial != trial) {
        *problem = record_path.string() + ": not a whole trial record of " + trial_name(trial);
        return std::nullopt;
    }
    for (const auto& [relative, sha] : record->files) {
        const fs::path file = root / relative;
        if (fs::path(relative).is_absolute() || relative.find("..") != std::string::npos) {
            *problem = record_path.string() + ": lists a file outside its folder, " + relative;
            return std::nullopt;
        }
        if (!fs::is_regular_file(file, ec)) {
            *problem = file.string() + ": missing (listed in " + record_path.string() + ")";
            return std::nullopt;
        }
        if (sha256_file(file) != sha) {
            *problem = file.string() + ": SHA-256 differs from its record " + record_path.string() +
                       " (the file was changed or damaged)";
            return std::nullopt;
        }
    }
    return record;
}

/// Hard-links `from` to `to`, or copies it where a link cannot be made (another filesystem);
/// true if linked.
bool link_or_copy(const fs::path& from, const fs::path& to) {
    std::error_code ec;
    fs::create_hard_link(from, to, ec);
    if (!ec) return true;
    fs::copy_file(from, to, fs::copy_options::overwrite_existing, ec);
    if (ec) fail("cannot copy " + from.string() + " to", to, ec);
    return false;
}

} // namespace

std::string stored_spec_text(const Spec& spec, int max_trials) {
    std::string text = "# resolved by chromasim " CHROMASIM_BUILD "\n" + spec.resolved_yaml;
    if (max_trials > 0)
        text += "# slice: the first " + std::to_string(max_trials) +
                " trials of the plan (generate --max-trials)\n";
    return text;
}

std::optional<std::string> resolved_yaml_of(const std::string& stored, int max_trials) {
    const std::string head = stored_spec_text(Spec(), 0);
    const std::string tail = stored_spec_text(Spec(), max_trials).substr(head.size());
    if (!stored.starts_with(head) || !stored.ends_with(tail) ||
        stored.size() < head.size() + tail.size())
        return std::nullopt;
    return stored.substr(head.size(), stored.size() - head.size() - tail.size());
}

TrialRecord checked_trial_record(const fs::path& root, int trial) {
    std::string problem;
    std::optional<TrialRecord> record = read_checked(root, trial, &problem);
    if (!record) throw SpecError(problem);
    return std::move(*record);
}

const char* finger_name(int finger) {
    return finger == 0 ? "left" : "right";
}

OutputState inspect_output(const fs::path& out_dir, const Spec& spec, int max_trials,
                           const Shard& shard) {
    std::error_code ec;
    if (!fs::exists(out_dir, ec)) return OutputState::absent;
    if (!fs::is_directory(out_dir, ec))
        throw SpecError(out_dir.string() + ": output path exists and is not a folder; allowed: " +
                        "a new path or an existing dataset folder");
    if (fs::is_empty(out_dir, ec)) return OutputState::absent;
    const fs::path stored = out_dir / kSpec;
    if (!fs::exists(stored) || read_file(stored) != stored_spec_text(spec, max_trials))
        return OutputState::other_content;
    if (!shard.sharded())
        return fs::exists(out_dir / kManifest) && !fs::exists(out_dir / kPart)
                   ? OutputState::up_to_date
                   : OutputState::other_content;
    if (!fs::exists(out_dir / kPart)) return OutputState::other_content;
    const std::optional<PartInfo> part = parse_part_json(read_file(out_dir / kPart));
    return part && part->shard == shard ? OutputState::up_to_date : OutputState::other_content;
}

DatasetWriter::DatasetWriter(fs::path out_dir, const Spec& spec, const WriterOptions& options,
                             std::ostream& log)
    : m_out(std::move(out_dir)), m_spec(spec), m_overwrite(options.overwrite),
      m_max_trials(options.max_trials), m_shard(options.shard) {
    if (!m_overwrite &&
        inspect_output(m_out, spec, m_max_trials, m_shard) == OutputState::other_content)
        throw SpecError(m_out.string() + ": output folder already holds other content (a " +
                        "dataset from another spec, version or instruction set, or other files); "
                        "allowed: a new " +
                        "path, or --overwrite to replace it once the new dataset is complete");
    const fs::path parent = fs::absolute(m_out).parent_path();
    make_folder(parent);
    m_staging = parent / (m_out.filename().string() + ".partial");
    std::error_code ec;
    try {
        if (fs::exists(m_staging, ec)) {
            take_over_partial(options, log);
        } else {
            make_folder(m_staging);
            m_made_here = true;
            lock();
        }
        write_pid(); // only now: a refused run leaves the folder as it found it
        make_folder(m_staging / kProgress);
        // The shard before the spec: a partial folder with a spec always names its shard.
        const fs::path marker = m_staging / kProgress / kShardMarker;
        if (m_shard.sharded() && !fs::exists(marker)) write_file_atomic(marker, m_shard.text());
        if (!fs::exists(m_staging / kSpec))
            write_file_atomic(m_staging / kSpec, stored_spec_text(spec, m_max_trials));
    } catch (...) { // the destructor does not run for a constructor that throws
        if (m_made_here) fs::remove_all(m_staging, ec);
        if (m_lock_fd >= 0) ::close(m_lock_fd); // a library caller may try again in-process
        throw;
    }
}

void DatasetWriter::take_over_partial(const WriterOptions& options, std::ostream& log) {
    if (!fs::is_directory(m_staging))
        throw SpecError(partial_error(m_staging, "exists and is not a folder; allowed: remove "
                                                 "it, or another output path"));
    lock(); // first: a running generation is not an interrupted one
    if (!options.resume && !options.overwrite)
        throw SpecError(partial_error(
            m_staging, options.can_resume
                           ? "holds an interrupted generation of this output; allowed: --resume "
                             "to finish it (same spec), or --overwrite to discard it and start "
                             "over"
                           : "holds an interrupted run writing this output; allowed: "
                             "--overwrite to discard it, or another output path"));
    const fs::path spec_file = m_staging / kSpec;
    const bool has_spec = fs::exists(spec_file);
    if (options.resume && has_spec &&
        read_file(spec_file) != stored_spec_text(m_spec, m_max_trials))
        throw SpecError(partial_error(
            spec_file, "the interrupted generation was made from another resolved spec (or "
                       "chromasim version, or --max-trials); allowed: --resume with the same "
                       "spec and options, or --overwrite to discard it and start over"));
    const std::string shard = has_spec ? stored_shard(m_staging) : std::string();
    if (options.resume && has_spec && shard != m_shard.text())
        throw SpecError(partial_error(
            m_staging / kProgress / kShardMarker,
            "the interrupted generation was made " +
                (shard.empty() ? std::string("without --shard") : "with --shard " + shard) +
                "; allowed: --resume with the same --shard, or --overwrite to discard it and "
                "start over"));
    if (!options.resume || !has_spec) { // start over, keeping only the lock we hold
        for (const auto& entry : fs::directory_iterator(m_staging))
            if (entry.path().filename() != kLock) remove_path(entry.path());
        if (options.resume)
            log << "chromasim: " << m_staging.string()
                << " holds no spec yet (killed at the start); starting over\n";
        return;
    }
    m_assembled = fs::exists(m_staging / (m_shard.sharded() ? kPart : kManifest));
    log << "chromasim: resuming the generation in " << m_staging.string() << '\n';
}

void DatasetWriter::lock() {
    const fs::path path = m_staging / kLock;
    m_lock_fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (m_lock_fd < 0) fail("cannot write", path, std::error_code(errno, std::generic_category()));
    // flock: released by the kernel when the process ends, however it ends (kill -9 too).
    if (::flock(m_lock_fd, LOCK_EX | LOCK_NB) != 0) {
        const std::string holder = read_file(path);
        ::close(m_lock_fd);
        m_lock_fd = -1;
        throw SpecError(partial_error(
            m_staging, "another chromasim process (pid " + holder +
                           ") is writing this output now; allowed: wait for it to finish"));
    }
}

void DatasetWriter::write_pid() const {
    const std::string pid = std::to_string(::getpid());
    if (::ftruncate(m_lock_fd, 0) != 0 || ::pwrite(m_lock_fd, pid.data(), pid.size(), 0) < 0)
        fail("cannot write", m_staging / kLock, std::error_code(errno, std::generic_category()));
}

DatasetWriter::~DatasetWriter() {
    std::error_code ec;
    if (!m_committed && m_made_here && m_records.empty()) fs::remove_all(m_staging, ec);
    if (m_lock_fd >= 0) ::close(m_lock_fd);
}

bool DatasetWriter::completed(int trial) {
    std::string problem;
    std::optional<TrialRecord> record = read_checked(m_staging, trial, &problem);
    if (!record) return false;
    m_records[trial] = std::move(*record);
    return true;
}

void DatasetWriter::begin_trial(const std::string& split, int trial) {
    const std::string name = trial_name(trial);
    remove_path(m_staging / kProgress / (name + ".json"));
    remove_path(m_staging / "images" / trial_folder(split, trial));
    remove_path(m_staging / "strain" / trial_folder(split, trial));
    m_split = split;
    m_trial = trial;
    m_images = 0;
    m_labels.str({});
    m_markers.str({});
    m_sensor.clear();
    m_labels << std::setprecision(9);
    m_markers << std::setprecision(9);
    m_strain.clear();
}

fs::path DatasetWriter::image_path(const std::string& split, int trial, const std::string& finger,
                                   int frame, std::string* relative, const char* extension) {
    char name[64];
    std::snprintf(name, sizeof name, "%s_%06d.%s", finger.c_str(), frame, extension);
    const std::string folder = "images/" + trial_folder(split, trial);
    make_folder(m_staging / folder);
    if (relative) *relative = folder + "/" + name;
    ++m_images;
    return m_staging / folder / name;
}

void DatasetWriter::write_labels(const FrameLabels& f) {
    if (!m_spec.outputs.labels) return;
    bool first = true;
    for (const auto& [name, cell] : label_cells(f)) {
        if (!first) m_labels << ',';
        first = false;
        std::visit([&](const auto& value) { m_labels << value; }, cell);
    }
    m_labels << '\n';
}

void DatasetWriter::write_marker(const FrameLabels& f, const std::string& finger, const char* layer,
                                 int marker, const double x0[3], const double u[3]) {
    if (!m_spec.outputs.markers) return;
    m_markers << f.split << ',' << f.trial << ',' << f.frame << ',' << finger << ',' << layer << ','
              << marker << ',' << x0[0] << ',' << x0[1] << ',' << x0[2] << ',' << u[0] << ','
              << u[1] << ',' << u[2] << '\n';
}

void DatasetWriter::write_strain(const FrameLabels& f, const std::string& finger,
                                 const std::vector<double>& eps_xx) {
    const std::string relative = "strain/" + trial_folder(f.split, f.trial) + "/" + finger + ".csv";
    auto it = m_strain.find(relative);
    if (it == m_strain.end()) {
        it = m_strain.emplace(relative, std::ostringstream()).first;
        it->second << "frame";
        for (std::size_t i = 0; i < eps_xx.size(); ++i)
            it->second << ",e" << i;
        it->second << '\n' << std::setprecision(9);
    }
    it->second << f.frame;
    for (const double e : eps_xx)
        it->second << ',' << e;
    it->second << '\n';
}

void DatasetWriter::end_trial(TrialRecord record) {
    const std::string name = trial_name(m_trial);
    // 1. The trial's text files, each under a temporary name and renamed.
    std::vector<std::string> written;
    const auto write = [&](const std::string& relative, const std::string& text) {
        make_folder((m_staging / relative).parent_path());
        write_file_atomic(m_staging / relative, text);
        written.push_back(relative);
    };
    if (m_spec.outputs.labels)
        write(std::string(kProgress) + "/" + name + ".labels.csv", m_labels.str());
    if (m_spec.outputs.markers)
        write(std::string(kProgress) + "/" + name + ".markers.csv", m_markers.str());
    if (!m_sensor.empty()) write(std::string(kProgress) + "/" + name + ".sensors.csv", m_sensor);
    for (const auto& [relative, text] : m_strain)
        write(relative, text.str());
    m_strain.clear();
    // 2. Every file's checksum, the images' too (already renamed into place by image_io).
    const fs::path images = m_staging / "images" / trial_folder(m_split, m_trial);
    std::error_code ec;
    if (fs::exists(images, ec))
        for (const auto& e : fs::directory_iterator(images))
            written.push_back(fs::relative(e.path(), m_staging).generic_string());
    for (const std::string& relative : written)
        record.files[relative] = sha256_file(m_staging / relative);
    record.trial = m_trial;
    record.split = m_split;
    record.images = m_images;
    // 3. The record, last: from here on the trial is complete.
    write_file_atomic(m_staging / kProgress / (name + ".json"), trial_record_json(record));
    m_records[m_trial] = std::move(record);
}

void DatasetWriter::assemble_csv(const char* name, const std::string& header,
                                 const char* shard) const {
    const fs::path tmp = m_staging / (std::string(name) + ".tmp");
    FileWriter out(tmp);
    out.append(header + "\n");
    for (const auto& [trial, record] : m_records) // std::map: plan order (trial ids ascend)
        out.append(read_file(m_staging / kProgress / (trial_name(trial) + shard)));
    out.close();
    rename_path(tmp, m_staging / name);
}

std::map<std::string, std::string> DatasetWriter::checksums() const {
    // A trial's files were hashed when it completed (and checked again on resume): only the
    // files assembled since are read here.
    std::map<std::string, std::string> known;
    for (const auto& [trial, record] : m_records)
        known.insert(record.files.begin(), record.files.end());
    std::map<std::string, std::string> sums;
    for (const auto& e : fs::recursive_directory_iterator(m_staging)) {
        const std::string relative = fs::relative(e.path(), m_staging).generic_string();
        if (relative == kProgress || relative.starts_with(std::string(kProgress) + "/") ||
            relative == kLock || relative == kManifest || !e.is_regular_file())
            continue;
        // Every writer renames its temporary before returning, and a trial's leftovers are
        // removed before it is redone: a temporary here is a bug of ours, not a user's file.
        if (relative.ends_with(".tmp") || relative.find(".tmp.") != std::string::npos)
            throw std::logic_error("leftover temporary " + e.path().string());
        const auto it = known.find(relative);
        sums[relative] = it != known.end() ? it->second : sha256_file(e.path());
    }
    return sums;
}

void DatasetWriter::assemble(const ManifestInfo& info, int trials) {
    if (int(m_records.size()) != trials)
        throw std::logic_error("assemble: " + std::to_string(m_records.size()) + " of " +
                               std::to_string(trials) + " trials complete");
    if (m_spec.outputs.labels)
        assemble_csv("labels.csv", labels_header(m_spec.fingers.count), ".labels.csv");
    if (m_spec.outputs.markers) assemble_csv("markers.csv", kMarkersHeader, ".markers.csv");
    if (varies_sensor(m_spec)) assemble_csv("sensors.csv", sensors_header(m_spec), ".sensors.csv");
    std::vector<TrialRecord> records;
    for (const auto& [trial, record] : m_records)
        records.push_back(record);
    const std::string spec_text = read_file(m_staging / kSpec);
    write_file_atomic(m_staging / kManifest,
                      manifest_json(m_spec, spec_text, m_max_trials, info, records, checksums()));
}

void DatasetWriter::seal_part(const PartInfo& part) {
    std::vector<int> complete;
    for (const auto& [trial, record] : m_records)
        complete.push_back(trial);
    if (complete != part.trials)
        throw std::logic_error("seal_part: the part lists other trials than the complete ones");
    write_file_atomic(m_staging / kPart, part_json(part));
}

int DatasetWriter::import_trial(const fs::path& from, const TrialRecord& record) {
    int copied = 0;
    for (const auto& [relative, sha] : record.files) {
        const fs::path to = m_staging / relative;
        make_folder(to.parent_path());
        copied += link_or_copy(from / relative, to) ? 0 : 1;
    }
    write_file_atomic(m_staging / kProgress / (trial_name(record.trial) + ".json"),
                      trial_record_json(record));
    m_records[record.trial] = record;
    return copied;
}

void DatasetWriter::finish() {
    if (!m_shard.sharded()) remove_path(m_staging / kProgress); // a part keeps them for merge
    move_into_place();
}

void DatasetWriter::move_into_place() {
    remove_path(m_staging / kLock); // the lock stays held (open descriptor) until we return
    // Swap into place: the old dataset (if replacing) is removed only after the rename.
    fs::path old;
    std::error_code ec;
    if (fs::exists(m_out, ec)) {
        old = m_staging.parent_path() /
              (m_out.filename().string() + ".old-" + std::to_string(::getpid()));
        rename_path(m_out, old);
    }
    rename_path(m_staging, m_out);
    m_committed = true;
    if (!old.empty()) remove_path(old);
    remove_stale_old_copies();
}

void DatasetWriter::remove_stale_old_copies() const {
    // A run killed between its two renames above leaves DIR.old-<pid>: the dataset that
    // --overwrite was asked to replace. Now that DIR holds the new one, it goes too. Only
    // names of exactly that form; the lock on DIR.partial kept every other writer out.
    const std::string prefix = m_out.filename().string() + ".old-";
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(fs::absolute(m_out).parent_path(), ec)) {
        const std::string name = entry.path().filename().string();
        if (name.size() <= prefix.size() || name.compare(0, prefix.size(), prefix) != 0) continue;
        const std::string pid = name.substr(prefix.size());
        if (pid.find_first_not_of("0123456789") != std::string::npos) continue;
        std::error_code rm;
        fs::remove_all(entry.path(), rm); // best effort: the dataset itself is in place
    }
}

} // namespace chromasim::generators
