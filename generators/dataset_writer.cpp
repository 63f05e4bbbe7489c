#include "generators/dataset_writer.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <iomanip>
#include <sstream>
#include <unistd.h>

namespace fs = std::filesystem;

namespace chromasim::generators {

namespace {

std::string read_file(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

std::string utc_now() {
    const std::time_t t = std::time(nullptr);
    char buf[32];
    std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&t));
    return buf;
}

/// A YAML double-quoted scalar.
std::string quoted(const std::string& text) {
    std::string out = "\"";
    for (char c : text) {
        if (c == '"' || c == '\\') out += '\\';
        out += c;
    }
    return out + '"';
}

std::ofstream open_csv(const fs::path& p, const char* header) {
    std::ofstream out(p);
    if (!out) throw std::runtime_error("cannot write " + p.string());
    out << header << '\n' << std::setprecision(9);
    return out;
}

} // namespace

std::string stored_spec_text(const Spec& spec, int max_trials) {
    std::string text = "# resolved by chromasim " CHROMASIM_VERSION "\n" + spec.resolved_yaml;
    if (max_trials > 0)
        text += "# slice: the first " + std::to_string(max_trials) +
                " trials of the plan (generate --max-trials)\n";
    return text;
}

const char* finger_name(int finger) {
    return finger == 0 ? "left" : "right";
}

OutputState inspect_output(const fs::path& out_dir, const Spec& spec, int max_trials) {
    std::error_code ec;
    if (!fs::exists(out_dir, ec)) return OutputState::absent;
    if (!fs::is_directory(out_dir, ec))
        throw SpecError(out_dir.string() + ": output path exists and is not a folder; allowed: " +
                        "a new path or an existing dataset folder");
    if (fs::is_empty(out_dir, ec)) return OutputState::absent;
    const fs::path stored = out_dir / "spec.resolved.yaml";
    if (fs::exists(out_dir / "manifest.yaml") && fs::exists(stored) &&
        read_file(stored) == stored_spec_text(spec, max_trials))
        return OutputState::up_to_date;
    return OutputState::other_content;
}

DatasetWriter::DatasetWriter(fs::path out_dir, const Spec& spec, bool overwrite, int max_trials)
    : m_out(std::move(out_dir)), m_spec(spec), m_overwrite(overwrite), m_max_trials(max_trials) {
    if (!m_overwrite && inspect_output(m_out, spec, max_trials) == OutputState::other_content)
        throw SpecError(m_out.string() + ": output folder already holds other content (a " +
                        "dataset from another spec or version, or other files); allowed: a new " +
                        "path, or --overwrite to replace it once the new dataset is complete");
    const fs::path parent = fs::absolute(m_out).parent_path();
    fs::create_directories(parent);
    m_staging = parent / (m_out.filename().string() + ".partial-" + std::to_string(::getpid()));
    fs::remove_all(m_staging);
    fs::create_directories(m_staging);
    try {
        open_outputs();
    } catch (...) {
        std::error_code ec;
        fs::remove_all(m_staging, ec); // the destructor does not run for a failed constructor
        throw;
    }
}

/// The labels.csv header: the frame's columns, then each finger's, prefixed by its name.
std::string labels_header(int fingers) {
    std::string h = "split,trial,frame,time_s,phase,object,friction,grip_N,load_N,travel_mm";
    for (int f = 0; f < fingers; ++f)
        for (const char* column : {"image",
                                   "exr",
                                   "mu",
                                   "normal_force_N",
                                   "requested_tangential_force_N",
                                   "tangential_force_N",
                                   "tangential_force_x_N",
                                   "tangential_force_y_N",
                                   "frictional_strength_N",
                                   "gamma",
                                   "stick_ratio",
                                   "sliding",
                                   "indentation_mm",
                                   "object_travel_x_mm",
                                   "object_travel_y_mm",
                                   "contact_area_mm2",
                                   "stick_area_mm2",
                                   "contact_nodes",
                                   "solver_iterations",
                                   "solver_residual_mm",
                                   "solver_residual_N",
                                   "converged",
                                   "status",
                                   "reused"})
            h += std::string(",") + finger_name(f) + "_" + column;
    return h;
}

void DatasetWriter::open_outputs() {
    if (m_spec.outputs.images || m_spec.outputs.exr) fs::create_directories(m_staging / "images");
    if (m_spec.outputs.labels)
        m_labels = open_csv(m_staging / "labels.csv", labels_header(m_spec.fingers.count).c_str());
    if (m_spec.outputs.markers)
        m_markers = open_csv(m_staging / "markers.csv",
                             "split,trial,frame,finger,layer,marker,x0_mm,y0_mm,z0_mm,ux_mm,"
                             "uy_mm,uz_mm");
}

DatasetWriter::~DatasetWriter() {
    if (!m_committed) {
        std::error_code ec;
        fs::remove_all(m_staging, ec);
    }
}

namespace {
std::string trial_folder(const std::string& split, int trial) {
    char name[32];
    std::snprintf(name, sizeof name, "trial_%06d", trial);
    return split + "/" + name;
}
} // namespace

fs::path DatasetWriter::image_path(const std::string& split, int trial, const std::string& finger,
                                   int frame, std::string* relative, const char* extension) {
    char name[64];
    std::snprintf(name, sizeof name, "%s_%06d.%s", finger.c_str(), frame, extension);
    const std::string folder = "images/" + trial_folder(split, trial);
    fs::create_directories(m_staging / folder);
    if (relative) *relative = folder + "/" + name;
    ++m_images;
    return m_staging / folder / name;
}

void DatasetWriter::write_labels(const FrameLabels& f) {
    if (!m_labels.is_open()) return;
    m_labels << f.split << ',' << f.trial << ',' << f.frame << ',' << f.time_s << ',' << f.phase
             << ',' << f.object << ',' << f.friction << ',' << f.grip_N << ',' << f.load_N << ','
             << f.travel_mm;
    for (const LabelRow& r : f.fingers) {
        const double ft = std::hypot(r.tangential_x_N, r.tangential_y_N);
        const double stick_ratio =
            r.contact_area_mm2 > 0 ? r.stick_area_mm2 / r.contact_area_mm2 : 0.0;
        m_labels << ',' << r.image << ',' << r.exr << ',' << r.mu << ',' << r.normal_force_N << ','
                 << r.requested_tangential_N << ',' << ft << ',' << r.tangential_x_N << ','
                 << r.tangential_y_N << ',' << r.mu * r.normal_force_N << ',' << r.gamma << ','
                 << stick_ratio << ',' << int(r.sliding) << ',' << r.indentation_mm << ','
                 << r.object_travel_x_mm << ',' << r.object_travel_y_mm << ',' << r.contact_area_mm2
                 << ',' << r.stick_area_mm2 << ',' << r.contact_nodes << ',' << r.solver_iterations
                 << ',' << r.solver_residual_mm << ',' << r.solver_residual_N << ','
                 << int(r.converged) << ',' << r.status << ',' << int(r.reused);
    }
    m_labels << '\n';
    ++m_label_rows;
}

void DatasetWriter::write_marker(const FrameLabels& f, const std::string& finger, const char* layer,
                                 int marker, const double x0[3], const double u[3]) {
    if (!m_markers.is_open()) return;
    m_markers << f.split << ',' << f.trial << ',' << f.frame << ',' << finger << ',' << layer << ','
              << marker << ',' << x0[0] << ',' << x0[1] << ',' << x0[2] << ',' << u[0] << ','
              << u[1] << ',' << u[2] << '\n';
}

void DatasetWriter::write_strain(const FrameLabels& f, const std::string& finger,
                                 const std::vector<double>& eps_xx) {
    const std::string relative = "strain/" + trial_folder(f.split, f.trial) + "/" + finger + ".csv";
    auto it = m_strain.find(relative);
    if (it == m_strain.end()) {
        fs::create_directories((m_staging / relative).parent_path());
        std::string header = "frame";
        for (std::size_t i = 0; i < eps_xx.size(); ++i)
            header += ",e" + std::to_string(i);
        it = m_strain.emplace(relative, open_csv(m_staging / relative, header.c_str())).first;
    }
    it->second << f.frame;
    for (const double e : eps_xx)
        it->second << ',' << e;
    it->second << '\n';
}

void DatasetWriter::end_trial() {
    for (auto& [relative, file] : m_strain) {
        file.close();
        if (!file) throw std::runtime_error("write error in " + (m_staging / relative).string());
    }
    m_strain.clear();
}

void DatasetWriter::commit(const std::string& manifest_extra) {
    for (std::ofstream* f : {&m_labels, &m_markers})
        if (f->is_open()) {
            f->close();
            if (!*f) throw std::runtime_error("write error in " + m_staging.string());
        }
    end_trial();
    std::ofstream(m_staging / "spec.resolved.yaml", std::ios::binary)
        << stored_spec_text(m_spec, m_max_trials);
    std::ofstream manifest(m_staging / "manifest.yaml");
    manifest << "# chromasim dataset manifest (docs/DATASET_FORMAT.md)\n"
             << "name: " << quoted(m_spec.name) << "\nchromasim_version: " CHROMASIM_VERSION "\n"
             << "created_utc: " << utc_now()
             << "\nspec_source: " << quoted(m_spec.source_path.string()) << "\nimages: " << m_images
             << "\nlabel_rows: " << m_label_rows << '\n'
             << manifest_extra;
    manifest.close();
    if (!manifest) throw std::runtime_error("write error in " + m_staging.string());
    // Swap into place: the old dataset (if replacing) is removed only after the rename.
    fs::path old;
    if (fs::exists(m_out)) {
        old = m_staging.parent_path() /
              (m_out.filename().string() + ".old-" + std::to_string(::getpid()));
        fs::rename(m_out, old);
    }
    fs::rename(m_staging, m_out);
    m_committed = true;
    if (!old.empty()) fs::remove_all(old);
}

} // namespace chromasim::generators
