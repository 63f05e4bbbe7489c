#include "generators/output/check.hpp"

#include "generators/io/file_io.hpp"
#include "generators/output/csv_rows.hpp"
#include "generators/plan/sensor_variants.hpp"
#include "generators/spec/spec.hpp"
#include "generators/spec/spec_schema.hpp"
#include "mechanics/dome_geometry.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <optional>
#include <ostream>
#include <sstream>

namespace chromasim::generators {

namespace {

namespace fs = std::filesystem;

/// Bounds shared by every rule: the dome's outer radius (no indentation, travel under force
/// control or marker displacement reaches it) and the tolerances of the consistency rules.
struct Bounds {
    double outer_radius_mm = mechanics::DomeParams{}.radii_mm.back();
    double relative = 1e-6; ///< of forces (labels are written to 9 significant digits)
    double absolute = 1e-9;
    double gamma = 1e-6; ///< of Gamma against the forces it is computed from
};

[[noreturn]] void refuse(const fs::path& path, const std::string& why) {
    throw SpecError("chromasim check: " + path.string() + ": " + why);
}

/// "0.27.0" -> {0, 27, 0}; an unreadable version compares as newer than any.
std::vector<int> version_numbers(const std::string& v) {
    std::vector<int> out;
    std::stringstream in(v);
    std::string part;
    while (std::getline(in, part, '.')) {
        try {
            out.push_back(std::stoi(part));
        } catch (const std::exception&) {
            return {1 << 30};
        }
    }
    return out;
}

/// manifest.json's version, refusing folders and formats this build cannot read.
std::string read_manifest(const fs::path& dir, std::map<std::string, std::string>& files) {
    if (!fs::is_directory(dir)) refuse(dir, "no such dataset folder");
    const fs::path manifest = dir / "manifest.json";
    std::ifstream in(manifest);
    if (!in)
        refuse(manifest, "missing: not a complete chromasim dataset (an interrupted run's "
                         "DIR.partial is finished by `generate --resume`)");
    nlohmann::json j;
    try {
        in >> j;
    } catch (const std::exception& e) {
        refuse(manifest, std::string("not valid JSON: ") + e.what());
    }
    if (!j.is_object() || !j.contains("chromasim_version") || !j.contains("manifest_version"))
        refuse(manifest, "not a chromasim manifest (no chromasim_version or manifest_version)");
    const int format =
        j["manifest_version"].is_number_integer() ? j["manifest_version"].get<int>() : -1;
    const std::string version = j["chromasim_version"].is_string()
                                    ? j["chromasim_version"].get<std::string>()
                                    : std::string("?");
    if (format != 1)
        refuse(manifest, "manifest_version " + j["manifest_version"].dump() +
                             ": this chromasim " CHROMASIM_VERSION " reads manifest_version 1");
    if (version_numbers(version) > version_numbers(CHROMASIM_VERSION))
        refuse(manifest, "written by chromasim " + version + ", newer than this " +
                             CHROMASIM_VERSION + ": check it with that version or a later one");
    if (j.contains("files") && j["files"].is_object())
        for (const auto& [path, sha] : j["files"].items())
            if (sha.is_string()) files[path] = sha.get<std::string>();
    return version;
}

/// Collects findings for one row of a file.
class Checker {
public:
    Checker(const CsvRows& rows, CheckReport& report, const CheckOptions& options)
        : m_rows(rows), m_report(report), m_options(options) {}
    void at(int trial, int frame, std::string finger) {
        m_trial = trial;
        m_frame = frame;
        m_finger = std::move(finger);
    }
    void find(const std::string& column, const std::string& problem) {
        ++m_report.findings_total;
        if (m_report.findings.size() >= m_options.max_findings) return;
        m_report.findings.push_back({m_rows.name(), m_rows.line(), m_trial, m_frame, m_finger,
                                     column, m_rows.cell(column), problem});
    }
    /// The column's number; a finding (and NaN) when it is not a finite number.
    double number(const std::string& column) {
        const std::string& text = m_rows.cell(column);
        char* end = nullptr;
        const double v = std::strtod(text.c_str(), &end);
        if (text.empty() || *end != '\0' || !std::isfinite(v)) {
            find(column, "not a finite number");
            return std::nan("");
        }
        return v;
    }

private:
    const CsvRows& m_rows;
    CheckReport& m_report;
    const CheckOptions& m_options;
    int m_trial = -1, m_frame = -1;
    std::string m_finger;
};

bool near(double a, double b, const Bounds& k) {
    return std::abs(a - b) <= k.absolute + k.relative * std::max(std::abs(a), std::abs(b));
}

/// One fingertip's labels of a row (prefix "left_" or "right_"); returns its normal force.
double check_finger(const CsvRows& rows, Checker& c, const std::string& p, const Bounds& k,
                    double requested_travel_mm, CheckReport& report) {
    const auto col = [&](const char* name) { return p + name; };
    const double gamma = c.number(col("gamma")), mu = c.number(col("mu"));
    const double fn = c.number(col("normal_force_N")), ft = c.number(col("tangential_force_N"));
    const double strength = c.number(col("frictional_strength_N"));
    const double sliding = c.number(col("sliding")), converged = c.number(col("converged"));
    const double d = c.number(col("indentation_mm"));
    const double wx = c.number(col("object_travel_x_mm")), wy = c.number(col("object_travel_y_mm"));
    const double area = c.number(col("contact_area_mm2")), stick = c.number(col("stick_area_mm2"));
    for (const char* name : {"tangential_force_x_N", "tangential_force_y_N", "stick_ratio",
                             "solver_residual_mm", "solver_residual_N"})
        if (rows.has(col(name))) c.number(col(name));
    if (converged == 0) ++report.flagged;
    if (!(gamma >= 0 && gamma <= 1)) c.find(col("gamma"), "outside [0, 1]");
    if (sliding != 0 && sliding != 1) c.find(col("sliding"), "not 0 or 1");
    if (sliding == 1 && gamma != 0) c.find(col("gamma"), "not 0 on a sliding frame");
    if (converged != 0 && converged != 1) c.find(col("converged"), "not 0 or 1");
    if (converged == 1 && rows.cell(col("status")) != "ok")
        c.find(col("status"), "converged = 1 with a status other than ok");
    if (!near(strength, mu * fn, k))
        c.find(col("frictional_strength_N"), "not mu * normal_force_N");
    if (fn < 0) c.find(col("normal_force_N"), "negative (the object pulls on the dome)");
    if (ft > strength * (1 + k.relative) + k.absolute)
        c.find(col("tangential_force_N"), "above mu * normal_force_N (Coulomb's law)");
    if (strength > 0 && sliding == 0 &&
        std::abs(gamma - std::clamp((strength - ft) / strength, 0.0, 1.0)) > k.gamma)
        c.find(col("gamma"), "not (mu f_n - f_t) / (mu f_n)");
    if (!(d >= -k.absolute && d < k.outer_radius_mm))
        c.find(col("indentation_mm"), "outside [0, the dome's outer radius)");
    const double travel = std::hypot(wx, wy);
    if (rows.cell("phase") == "slide") {
        if (!near(travel, std::abs(requested_travel_mm), k))
            c.find(col("object_travel_x_mm"), "not the slide's prescribed travel_mm");
    } else if (!(travel < k.outer_radius_mm)) {
        c.find(col("object_travel_x_mm"), "travel beyond the dome's outer radius under force "
                                          "control");
    }
    if (!(area >= 0) || !(stick >= 0) || stick > area + k.absolute)
        c.find(col("stick_area_mm2"), "negative, or above contact_area_mm2");
    return fn;
}

/// labels.csv: every row's fingertips, frames in order, no frame twice.
void check_labels(const fs::path& dir, const Bounds& k, const CheckOptions& options,
                  CheckReport& report,
                  std::map<std::string, std::pair<std::string, double>>& image_objects) {
    CsvRows rows(dir, "labels.csv", "chromasim check: ");
    std::vector<std::string> fingers;
    for (const char* f : {"left", "right"})
        if (rows.has(std::string(f) + "_gamma")) fingers.push_back(f);
    for (const char* required : {"trial", "frame", "phase", "object", "travel_mm"})
        if (!rows.has(required))
            refuse(dir / "labels.csv",
                   std::string("no column '") + required + "': not a labels.csv this check reads");
    if (fingers.empty()) refuse(dir / "labels.csv", "no left_gamma column: no fingertip labels");
    Checker c(rows, report, options);
    long last_trial = -1, last_frame = -1;
    while (rows.next()) {
        ++report.label_rows;
        c.at(-1, -1, "");
        const double trial = c.number("trial"), frame = c.number("frame");
        c.at(int(trial), int(frame), "");
        const double travel_mm = c.number("travel_mm");
        if (trial < last_trial || (trial == last_trial && frame <= last_frame))
            c.find("frame", "rows not in trial then frame order, or a frame twice");
        last_trial = long(trial);
        last_frame = long(frame);
        for (const std::string& f : fingers) {
            c.at(int(trial), int(frame), f);
            const double fn = check_finger(rows, c, f + "_", k, travel_mm, report);
            const std::string& image = rows.cell(f + "_image");
            if (!image.empty()) image_objects[image] = {rows.cell("object"), fn};
        }
    }
}

/// markers.csv: every displacement finite and within the dome.
void check_markers(const fs::path& dir, const Bounds& k, const CheckOptions& options,
                   CheckReport& report) {
    if (!fs::exists(dir / "markers.csv")) return;
    CsvRows rows(dir, "markers.csv", "chromasim check: ");
    Checker c(rows, report, options);
    while (rows.next()) {
        ++report.marker_rows;
        c.at(std::atoi(rows.cell("trial").c_str()), std::atoi(rows.cell("frame").c_str()),
             rows.cell("finger"));
        double u2 = 0;
        for (const char* column : {"ux_mm", "uy_mm", "uz_mm"}) {
            const double u = c.number(column);
            u2 += u * u;
        }
        if (!(std::sqrt(u2) < k.outer_radius_mm))
            c.find("ux_mm", "marker displacement beyond the dome's outer radius");
    }
}

/// The dataset's spec (spec.resolved.yaml), or nothing when it is missing or this build cannot
/// read it (an older chromasim's keys).
std::optional<Spec> stored_spec(const fs::path& dir) {
    const fs::path path = dir / "spec.resolved.yaml";
    try {
        return parse_stored_spec(read_file(path), path.string());
    } catch (const std::exception&) {
        return std::nullopt;
    }
}

/// Whether `value` is one the factor can draw: in its range, or one of its listed values.
bool drawable(const Factor& f, double value) {
    if (f.is_range) return value >= f.min && value <= f.max;
    return std::find(f.values.begin(), f.values.end(), value) != f.values.end();
}

/// sensors.csv of a dataset whose spec varies its sensor: one row per trial, naming a sensor
/// of the plan, each value one its key can draw and the plan's own draw.
void check_sensors(const fs::path& dir, const CheckOptions& options, CheckReport& report) {
    const std::optional<Spec> spec = stored_spec(dir);
    const bool present = fs::exists(dir / "sensors.csv");
    if (!spec || (!varies_sensor(*spec) && !present)) return;
    if (!present) {
        ++report.findings_total;
        report.findings.push_back({"sensors.csv", 0, -1, -1, "", "", "",
                                   "missing: the spec varies its sensor"});
        return;
    }
    const Plan plan = make_plan(*spec);
    const auto draws = sensor_draws(*spec);
    const std::map<std::string, Factor> drawn(draws.begin(), draws.end());
    CsvRows rows(dir, "sensors.csv", "chromasim check: ");
    Checker c(rows, report, options);
    while (rows.next()) {
        ++report.sensor_rows;
        const double trial = c.number("trial"), sensor = c.number("sensor");
        c.at(int(trial), -1, "");
        if (!(trial >= 0 && trial < double(plan.trials.size()))) {
            c.find("trial", "not a trial of the spec's plan");
            continue;
        }
        const TrialPlan& planned = plan.trials[std::size_t(trial)];
        if (sensor != double(planned.sensor)) c.find("sensor", "not the plan's sensor of the trial");
        if (!(planned.sensor >= 0)) continue;
        for (const auto& [key, value] : plan.sensors[std::size_t(planned.sensor)].values) {
            const double written = c.number(key);
            if (!drawable(drawn.at(key), written))
                c.find(key,
                       "outside the spec's " + value_to_yaml(drawn.at(key), ValueType::Varied));
            else if (written != value)
                c.find(key, "not the plan's draw " + format_number(value));
        }
    }
}

/// Two different objects pressed into a fingertip never give the same image bytes.
void check_images(const std::map<std::string, std::string>& files,
                  const std::map<std::string, std::pair<std::string, double>>& image_objects,
                  CheckReport& report, const CheckOptions& options) {
    std::map<std::string, std::pair<std::string, std::string>> by_hash; // sha -> (image, object)
    for (const auto& [image, object_force] : image_objects) {
        const auto sha = files.find(image);
        if (sha == files.end() || !(object_force.second > 0)) continue;
        const auto [it, inserted] =
            by_hash.emplace(sha->second, std::pair(image, object_force.first));
        if (inserted || it->second.second == object_force.first) continue;
        ++report.findings_total;
        if (report.findings.size() < options.max_findings)
            report.findings.push_back({"manifest.json", 0, -1, -1, "", image, sha->second,
                                       "the same bytes as " + it->second.first + " (object " +
                                           it->second.second + ", this one " + object_force.first +
                                           ")"});
    }
}

} // namespace

CheckReport check_dataset(const fs::path& dir, const CheckOptions& options) {
    CheckReport report;
    std::map<std::string, std::string> files;
    report.version = read_manifest(dir, files);
    const Bounds bounds;
    std::map<std::string, std::pair<std::string, double>> image_objects;
    check_labels(dir, bounds, options, report, image_objects);
    check_markers(dir, bounds, options, report);
    check_images(files, image_objects, report, options);
    check_sensors(dir, options, report);
    return report;
}

void print_check_report(const fs::path& dir, const CheckReport& r, std::ostream& out) {
    out << "chromasim check: " << dir.string() << " (written by chromasim " << r.version
        << "): " << r.label_rows << " label rows, " << r.marker_rows << " marker rows, "
        << (r.sensor_rows > 0 ? std::to_string(r.sensor_rows) + " sensor rows, " : "")
        << r.flagged << " fingertip frame(s) flagged converged = 0; " << r.findings_total
        << " impossible or inconsistent value(s)\n";
    for (const CheckFinding& f : r.findings) {
        out << "  " << f.file;
        if (f.line > 0) out << ':' << f.line;
        if (f.trial >= 0) out << ": trial " << f.trial << " frame " << f.frame;
        if (!f.finger.empty()) out << ' ' << f.finger;
        out << ": " << f.column << " = " << (f.value.empty() ? "(empty)" : f.value) << ": "
            << f.problem << '\n';
    }
    if (r.findings_total > long(r.findings.size()))
        out << "  ... and " << r.findings_total - long(r.findings.size()) << " more\n";
}

} // namespace chromasim::generators
