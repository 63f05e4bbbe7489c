// The spec's lists of mappings (objects, friction, splits) and its cross-key rules, in the
// order they are checked.
#include "generators/spec/spec_table.hpp"

#include "generators/spec/stage_params.hpp"
#include "render/fisheye_camera.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numbers>

namespace chromasim::generators::detail {
namespace {

/// The longest trial a spec may plan, frames.
constexpr double kMaxTrialFrames = 1e6;

template <class Item>
SchemaList make_list(std::string name, std::string doc, std::vector<Item> Spec::*member) {
    SchemaList l;
    l.name = std::move(name);
    l.doc = std::move(doc);
    l.size = [member](const Spec& s) { return (s.*member).size(); };
    l.resize = [member](Spec& s, std::size_t n) { (s.*member).resize(n); };
    return l;
}

/// Names of the items of a list are unique (labels and folders are named by them).
SchemaRule unique_name(const std::string& list) {
    SchemaRule r;
    r.key = list + "[].name";
    r.holds = [list](const Spec& s, std::size_t i) {
        const SchemaEntry* name = find_schema_entry(list + "[].name");
        for (std::size_t j = 0; j < i; ++j)
            if (name->get(s, j) == name->get(s, i)) return false;
        return true;
    };
    r.problem = "is the name of an earlier item of " + list;
    r.allowed = "a name used once in " + list;
    return r;
}

/// A list item's name goes into labels.csv as a cell (and a split's into folder names): no
/// character may end the cell, the line or the folder.
SchemaRule plain_name(const std::string& list) {
    SchemaRule r;
    r.key = list + "[].name";
    r.diagnose = [list](const Spec& s, std::size_t i) -> std::string {
        const SchemaEntry* entry = find_schema_entry(list + "[].name");
        const std::string name = std::get<std::string>(entry->get(s, i));
        for (const char c : name)
            if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f)
                return "holds a control character";
        if (name.find_first_of(",\"/\\") != std::string::npos)
            return "holds a comma, a quote, a slash or a backslash";
        if (name == "." || name == "..") return "names a folder's own or parent folder";
        if (name.size() > 100) return "is longer than 100 bytes";
        return "";
    };
    r.allowed = "text of at most 100 bytes without commas, quotes, slashes, backslashes or "
                "control characters (it is a labels.csv cell, and a split's name is a folder's)";
    return r;
}

SchemaRule split_sum() {
    SchemaRule r;
    r.key = "splits";
    r.holds = [](const Spec& s, std::size_t) {
        double sum = 0;
        for (const Spec::Split& split : s.splits)
            sum += split.fraction;
        return std::abs(sum - 1.0) <= 1e-9;
    };
    r.problem = "has fractions whose sum is not 1";
    r.allowed = "splits[].fraction summing to 1 (within 1e-9), e.g. train 0.8, test 0.2";
    return r;
}

/// LEDs under the rim plane must lie beside the lens barrel, or it would hide them entirely.
SchemaRule led_beside_lens() {
    SchemaRule r;
    r.key = "sensor.camera.lens_radius_mm";
    r.holds = [](const Spec& s, std::size_t) {
        const auto& c = s.sensor;
        return !(c.led_z_mm < 0.0) ||
               c.led_ring_radius_mm - 0.5 * c.led_height_mm > c.lens_radius_mm;
    };
    r.problem = "puts the lens barrel over the LEDs (below the rim plane, the barrel covers "
                "the LEDs' rectangles)";
    r.allowed = "lens_radius_mm below sensor.led.ring_radius_mm - sensor.led.height_mm / 2, or "
                "sensor.led.z_mm >= 0";
    return r;
}

/// The most frames a trial of `spec` can plan (the longest load ramp: the largest target at
/// the smallest rate).
double max_frames_per_trial(const Spec& s) {
    const Spec::Protocol& p = s.protocol;
    const double phases =
        std::round(p.grasp_s * p.frame_rate_Hz) + std::round(p.hold_s * p.frame_rate_Hz);
    if (p.type == "slide") return phases + p.slide_frames;
    return phases +
           std::ceil(highest(p.target_load_N) / lowest(p.load_rate_N_per_s) * p.frame_rate_Hz);
}

SchemaRule trial_length() {
    SchemaRule r;
    r.key = "protocol.frame_rate_Hz";
    r.holds = [](const Spec& s, std::size_t) { return max_frames_per_trial(s) <= kMaxTrialFrames; };
    r.problem = "with the grasp, hold and load durations plans a trial longer than 1000000 frames";
    r.allowed = "(grasp_s + hold_s + max target_load_N / min load_rate_N_per_s) * frame_rate_Hz "
                "(slide: the slide frames instead of the load) up to 1000000 frames per trial";
    return r;
}

/// sensor.led.gains sets every LED with one number, or each with its own.
SchemaRule led_gains() {
    SchemaRule r;
    r.key = "sensor.led.gains";
    r.holds = [](const Spec& s, std::size_t) {
        const std::size_t n = s.sensor.led_gains.size();
        return n == 1 || n == std::size_t(s.sensor.led_count);
    };
    r.problem = "does not hold one gain per LED";
    r.allowed = "one number for every LED, or a list of sensor.led.count numbers";
    return r;
}

/// A drawn camera position stays within sensor.camera.position_mm's range.
SchemaRule camera_position_tolerance() {
    SchemaRule r;
    r.key = "sensor.camera.position_tolerance_mm";
    r.holds = [](const Spec& s, std::size_t) {
        const auto& p = s.sensor.camera_position_mm;
        const double t = s.sensor.camera_position_tolerance_mm;
        return std::all_of(p.begin(), p.end(), [t](double x) { return std::abs(x) + t <= 10.0; });
    };
    r.problem = "lets a drawn camera position leave [-10, 10] mm";
    r.allowed = "|each of sensor.camera.position_mm| + the tolerance up to 10 mm";
    return r;
}

SchemaRule crossed_sensors() {
    SchemaRule r;
    r.key = "sampling.sensor_assignment";
    r.holds = [](const Spec& s, std::size_t) {
        return s.sampling.sensor_assignment != "crossed" ||
               (s.sampling.method == "full_grid" && s.sampling.sensor_variants > 0);
    };
    r.problem = "is crossed, which needs a full grid and a number of sensors";
    r.allowed = "crossed with sampling.method full_grid and sampling.sensor_variants >= 1, or "
                "random";
    return r;
}

SchemaRule slide_travel() {
    SchemaRule r;
    r.key = "protocol.slide.end_mm";
    r.holds = [](const Spec& s, std::size_t) {
        return s.protocol.slide_end_mm >= s.protocol.slide_start_mm;
    };
    r.problem = "is below protocol.slide.start_mm";
    r.allowed = "protocol.slide.end_mm >= protocol.slide.start_mm";
    return r;
}

} // namespace

std::vector<SchemaList> build_lists() {
    return {make_list("objects",
                      "The objects, a categorical factor of the sampling plan: every trial grasps "
                      "one of them.",
                      &Spec::objects),
            make_list("friction",
                      "The friction conditions, a categorical factor: every trial has one.",
                      &Spec::friction),
            make_list("splits", "The splits the trials are divided into.", &Spec::splits)};
}

namespace {

/// At least one output.
SchemaRule some_output() {
    SchemaRule outputs;
    outputs.key = "outputs";
    outputs.holds = [](const Spec& s, std::size_t) {
        return s.outputs.images || s.outputs.labels || s.outputs.markers || s.outputs.exr ||
               s.outputs.strain;
    };
    outputs.problem = "enables no output";
    outputs.allowed =
        "at least one of outputs.images, outputs.labels, outputs.markers, outputs.exr, "
        "outputs.strain is true";
    return outputs;
}

/// EXR channels only with the EXR.
SchemaRule exr_channels() {
    SchemaRule channels;
    channels.key = "outputs.exr";
    channels.holds = [](const Spec& s, std::size_t) {
        return s.outputs.exr || !(s.outputs.marker_ids || s.outputs.variance);
    };
    channels.problem =
        "is false while outputs.marker_ids or outputs.variance asks for EXR channels";
    channels.allowed = "outputs.exr: true, or outputs.marker_ids and outputs.variance false";
    return channels;
}

/// A mesh object names a usable glTF mesh.
SchemaRule mesh_file() {
    SchemaRule mesh;
    mesh.reads_files = true;
    mesh.key = "objects[].mesh_file";
    // The mesh is read as generate reads it: a file that is not a usable glTF mesh fails here.
    mesh.diagnose = [](const Spec& s, std::size_t i) -> std::string {
        const Spec::Object& o = s.objects[i];
        if (o.shape != "mesh") return "";
        std::error_code ec;
        if (o.mesh_file.empty() ||
            !std::filesystem::is_regular_file(resolve_spec_path(s, o.mesh_file), ec))
            return "names no existing file, and the object's shape is mesh";
        try {
            object_shape(s, o);
        } catch (const std::exception& e) {
            return std::string("is not a usable object mesh (") + e.what() + ")";
        }
        return "";
    };
    mesh.allowed = "a .gltf or .glb file; a relative path starts at the spec file's folder";
    return mesh;
}

/// The spectra load when the images are spectral.
SchemaRule spectra_dir() {
    SchemaRule spectra;
    spectra.reads_files = true;
    spectra.key = "sensor.optics.spectra_dir";
    // The spectra are read as generate reads them: a missing or malformed file fails here.
    spectra.diagnose = [](const Spec& s, std::size_t) -> std::string {
        if (!s.render.spectral || !(s.outputs.images || s.outputs.exr)) return "";
        std::error_code ec;
        if (!std::filesystem::is_directory(spectra_directory(s), ec))
            return "names no existing folder, and render.spectral is true";
        try {
            render::load_sensor_spectra(
                render::SensorSpectraFiles::in_directory(spectra_directory(s)));
        } catch (const std::exception& e) {
            return std::string("holds spectra that cannot be used (") + e.what() + ")";
        }
        return "";
    };
    spectra.allowed = "a folder with the six spectrum CSVs (assets/spectra/README.md), or empty "
                      "for the shipped ones";
    return spectra;
}

/// The coating's albedo times its scale stays a reflectance: at most 1 (RGB in RGB mode, the
/// coating's spectrum in spectral mode), for the scale's highest draw.
SchemaRule coating_albedo_scale() {
    SchemaRule rule;
    rule.reads_files = true;
    rule.key = "sensor.optics.coating_albedo_scale";
    rule.diagnose = [key = rule.key](const Spec& s, std::size_t) -> std::string {
        const auto varied = s.varied.find(key);
        const double scale =
            varied != s.varied.end() ? highest(varied->second) : s.sensor.coating_albedo_scale;
        double albedo = *std::max_element(s.sensor.coating_albedo.begin(),
                                          s.sensor.coating_albedo.end());
        if (s.render.spectral && (s.outputs.images || s.outputs.exr)) {
            try {
                const auto files = render::SensorSpectraFiles::in_directory(spectra_directory(s));
                const render::Spectrum c = render::read_spectrum_csv(
                    files.coating_albedo, render::SpectrumQuantity::albedo)[0];
                albedo = *std::max_element(c.values.begin(), c.values.end());
            } catch (const std::exception&) {
                return ""; // sensor.optics.spectra_dir's rule names the bad file
            }
        }
        if (scale * albedo <= 1.0) return "";
        return "scales the coating's largest albedo " + format_number(albedo) + " to " +
               format_number(scale * albedo);
    };
    rule.allowed = "at most 1 / the coating's largest albedo (sensor.optics.coating_albedo in "
                   "RGB mode, its spectrum in spectral mode), for every value it may draw";
    return rule;
}

/// A Kannala-Brandt camera maps every pixel back to one ray.
SchemaRule invertible_camera() {
    SchemaRule camera;
    camera.key = "sensor.camera";
    camera.holds = [](const Spec& s, std::size_t) {
        if (s.sensor.camera_model != "kannala_brandt") return true;
        const auto& c = s.sensor;
        return render::kannala_brandt_min_slope(c.camera_k1, c.camera_k2, c.camera_k3, c.camera_k4,
                                                c.camera_half_fov_deg * std::numbers::pi / 180)
                   .slope > 0.0;
    };
    camera.problem = "has k1..k4 whose theta_d(theta) stops increasing before half_fov_deg, so "
                     "pixels cannot be mapped back to rays";
    camera.allowed = "k1..k4 with 1 + 3 k1 t^2 + 5 k2 t^4 + 7 k3 t^6 + 9 k4 t^8 > 0 for every "
                     "polar angle t (rad) up to half_fov_deg, or a smaller half_fov_deg (the "
                     "field the calibration covers)";
    return camera;
}

/// A tilted flat touches within the contact cap.
SchemaRule flat_tilt() {
    SchemaRule tilt;
    tilt.key = "objects[].pitch_deg";
    tilt.holds = [](const Spec& s, std::size_t i) {
        const Spec::Object& o = s.objects[i];
        if (o.shape != "flat") return true;
        // A plane tilted by t touches the dome at polar angle t: it must stay in the cap.
        const double deg = std::numbers::pi / 180;
        const double cos_tilt = std::cos(o.roll_deg * deg) * std::cos(o.pitch_deg * deg);
        // The contact forces act along z: a steeper plane is beyond that approximation.
        const double limit = std::min(s.sensor.contact_candidate_angle_deg - 5, 30.0);
        return cos_tilt > std::cos(limit * deg);
    };
    tilt.problem = "with roll_deg tilts the flat object beyond 30 deg or to within 5 deg of "
                   "sensor.contact_candidate_angle_deg (the contact would leave the cap of "
                   "nodes that may touch, or the contact forces along z would not hold)";
    tilt.allowed = "a tilt acos(cos(roll) cos(pitch)) below 30 deg and below "
                   "sensor.contact_candidate_angle_deg - 5 deg";
    return tilt;
}

} // namespace

std::vector<SchemaRule> build_rules() {
    std::vector<SchemaRule> rules{some_output(),       exr_channels(), mesh_file(),
                                  invertible_camera(), flat_tilt(),    spectra_dir(),
                                  coating_albedo_scale()};
    for (const char* list : {"objects", "friction", "splits"}) {
        rules.push_back(plain_name(list));
        rules.push_back(unique_name(list));
    }
    rules.push_back(split_sum());
    rules.push_back(led_beside_lens());
    rules.push_back(led_gains());
    rules.push_back(camera_position_tolerance());
    rules.push_back(crossed_sensors());
    rules.push_back(slide_travel());
    rules.push_back(trial_length());
    return rules;
}

} // namespace chromasim::generators::detail
