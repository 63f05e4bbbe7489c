#include "generators/validation/verify_sensor.hpp"

#include "generators/io/stopwatch.hpp"
#include "generators/output/csv_rows.hpp"
#include "generators/pipeline/generate.hpp"
#include "generators/pipeline/sensor_bridge.hpp"
#include "generators/spec/spec_schema.hpp"
#include "mechanics/dome_geometry.hpp"
#include "render/fisheye_camera.hpp"
#include "render/renderer.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <numbers>
#include <optional>
#include <ostream>
#include <unistd.h>

namespace chromasim::generators {

namespace fs = std::filesystem;

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

/// The press and the lateral load of every verify run (docs/VALIDATION.md, "Sensor laws").
constexpr double kPressN = 3.0;
constexpr int kPressFrames = 12;
constexpr double kMu = 0.5;
constexpr double kLoadStepN = 0.125; ///< mu * kPressN in 12 steps: 11 frames before the slip

/// The spec of the run: `base`'s sensor and render sections, our objects, protocol, outputs.
Spec verify_spec(const Spec& base, int size_px) {
    Spec s = base;
    s.name = "verify_sensor";
    s.seed = 1;
    Spec::Object sphere;
    sphere.name = sphere.shape = "sphere";
    sphere.radius_mm = 45.0;
    s.objects = {Spec::Object{}, sphere};
    s.friction = {Spec::Friction{"verify", Factor{{kMu}}}};
    s.fingers = Spec::Fingers{};
    s.fingers.count = 1;
    s.protocol = Spec::Protocol{};
    s.protocol.frame_rate_Hz = 1.0;
    s.protocol.grip_N = Factor{{kPressN}};
    s.protocol.grasp_s = kPressFrames;
    s.protocol.hold_s = 0;
    s.protocol.load_rate_N_per_s = Factor{{kLoadStepN}};
    s.protocol.target_load_N = Factor{{2 * kMu * kPressN}};
    s.protocol.slip_frames = 0;
    s.sampling = Spec::Sampling{};
    s.splits = {Spec::Split{}};
    s.render.width_px = s.render.height_px = size_px;
    s.render.sensor.enabled = false; // the optics' laws, without camera noise
    s.outputs = Spec::Outputs{};
    s.outputs.exr = s.outputs.marker_ids = true;
    s.resolved_yaml = resolved_spec_yaml(s);
    return s;
}

/// Image width (px) of a marker at the apex, seen through the outer marker layer's mid radius.
double marker_span_px(const Spec& spec) {
    const mechanics::DomeParams dome = dome_options(spec).dome;
    const double r = 0.5 * (dome.radii_mm[2] + dome.radii_mm[3]);
    const double a = std::asin(dome.marker_radius_mm / r);
    const render::FisheyeCamera camera(camera_params(spec));
    const auto p = camera.project(render::Vec3(r * std::sin(a), 0, r * std::cos(a)));
    const auto q = camera.project(render::Vec3(-r * std::sin(a), 0, r * std::cos(a)));
    return p && q ? (*p - *q).norm() : 0.0;
}

/// Refuses what cannot give a measurement, before any work (SensorVerifyOptions).
void check_options(const Spec& spec, const SensorVerifyOptions& o) {
    const auto zero = [](const Rgb& a) { return a[0] <= 0 && a[1] <= 0 && a[2] <= 0; };
    const std::string where = o.spec_file.empty() ? "the default sensor" : o.spec_file.string();
    if (!spec.render.spectral && zero(spec.sensor.inner_marker_absorption_per_mm) &&
        zero(spec.sensor.outer_marker_absorption_per_mm))
        throw SpecError(where + ": sensor.optics.inner_marker_absorption_per_mm and "
                                "sensor.optics.outer_marker_absorption_per_mm are both 0: the "
                                "markers are invisible; verify sensor needs coloured markers");
    if (o.size_px < 16 || o.size_px > 4096)
        throw SpecError("--size-px " + std::to_string(o.size_px) +
                        ": out of range; allowed: integer in [16, 4096] (render.width_px's)");
    const double span = marker_span_px(spec);
    if (span < kMinMarkerSpanPx)
        throw SpecError(
            "--size-px " + std::to_string(o.size_px) + ": a marker spans " +
            std::to_string(span).substr(0, 4) + " px of the image; the metrics need at least " +
            std::to_string(int(kMinMarkerSpanPx)) + ": use --size-px " +
            std::to_string(int(std::ceil(o.size_px * kMinMarkerSpanPx / std::max(span, 1e-3)))) +
            " or more");
    for (const fs::path& out : {o.json, o.picture}) {
        if (out.empty()) continue;
        const fs::path dir = out.parent_path().empty() ? fs::path(".") : out.parent_path();
        if (!fs::is_directory(dir))
            throw SpecError(out.string() + ": no folder " + dir.string() + " to write it in");
    }
    if (!o.keep_dir.empty() && fs::exists(o.keep_dir))
        throw SpecError("--keep " + o.keep_dir.string() +
                        ": already exists; give a new folder for the rendered dataset");
}

/// The undeformed sensor rendered as generate renders a frame (generate.cpp).
render::Image render_rest(const Spec& spec, const fs::path& cache_dir) {
    const StageSettings settings = stage_settings(spec); // its outputs have images
    mechanics::DomeModelOptions model_options = settings.dome;
    model_options.cache_dir = cache_dir;
    const mechanics::DomeModel model(model_options);
    render::Renderer renderer(settings.camera, settings.optics.value());
    const render::SensorFrame rest = undeformed_sensor_frame(model);
    prepare_renderer(renderer, settings, rest, cache_dir);
    renderer.set_frame(rest);
    return renderer.render(settings.render);
}

/// Refuses a sensor whose rest image shows fewer than half of the markers in view as blobs of
/// the 50 % saturation rule: its markers are too pale (or absent) for the papers' method.
void check_rest_blobs(const Spec& spec, const SensorVerifyOptions& o, const Image8& rest) {
    const render::FisheyeCamera camera(camera_params(spec));
    const mechanics::DomeParams dome = dome_options(spec).dome;
    int in_view = 0;
    for (const Eigen::Vector3d& d : mechanics::marker_directions(dome))
        in_view += camera.project(dome.radii_mm[2] * d).has_value();
    const auto blobs = find_blobs(rest, 0.5, 3);
    if (2 * int(blobs.size()) >= in_view) return;
    throw SpecError(
        (o.spec_file.empty() ? std::string("the default sensor") : o.spec_file.string()) +
        ": the rest image shows " + std::to_string(blobs.size()) +
        " blobs with saturation above 50 % for " + std::to_string(in_view) +
        " markers in view: the markers are too pale for the papers' rule; "
        "verify sensor needs coloured markers (sensor.optics.*)");
}

/// One image of a trial's sequence and its outer markers' displacements.
struct FrameData {
    int trial = 0;
    std::string phase, object;
    bool converged = true;
    fs::path png, exr;
    std::vector<Eigen::Vector3d> u; ///< per outer marker (mm)
};

/// Each trial's frames in order, after the rest image; the outer markers' rest positions.
std::vector<std::vector<FrameData>> read_dataset(const fs::path& dir, const fs::path& rest_png,
                                                 const fs::path& rest_exr,
                                                 std::vector<Eigen::Vector3d>& x0) {
    std::map<std::pair<int, int>, std::vector<Eigen::Vector3d>> u;
    CsvRows markers(dir, "markers.csv");
    while (markers.next()) {
        if (markers.cell("layer") != "outer") continue;
        const auto m = std::size_t(markers.number("marker"));
        auto& field = u[{int(markers.number("trial")), int(markers.number("frame"))}];
        if (field.size() <= m) field.resize(m + 1, Eigen::Vector3d::Zero());
        if (x0.size() <= m) x0.resize(m + 1, Eigen::Vector3d::Zero());
        field[m] = {markers.number("ux_mm"), markers.number("uy_mm"), markers.number("uz_mm")};
        x0[m] = {markers.number("x0_mm"), markers.number("y0_mm"), markers.number("z0_mm")};
    }
    std::vector<std::vector<FrameData>> trials;
    CsvRows labels(dir, "labels.csv");
    while (labels.next()) {
        const int trial = int(labels.number("trial")), frame = int(labels.number("frame"));
        if (std::size_t(trial) >= trials.size()) trials.resize(std::size_t(trial) + 1);
        auto& seq = trials[std::size_t(trial)];
        if (seq.empty())
            seq.push_back({trial, "rest", labels.cell("object"), true, rest_png, rest_exr,
                           std::vector<Eigen::Vector3d>(x0.size(), Eigen::Vector3d::Zero())});
        seq.push_back({trial, labels.cell("phase"), labels.cell("object"),
                       labels.number("left_converged") == 1, dir / labels.cell("left_image"),
                       dir / labels.cell("left_exr"), u[{trial, frame}]});
    }
    return trials;
}

/// The blob tracked for each marker in each frame of a sequence (nullopt: not seen).
using Tracks = std::vector<std::vector<std::optional<Blob>>>; // [frame][marker]

/// Which marker each blob's pixels belong to, by the marker id channels (inner, else outer).
std::vector<int> blob_markers(const fs::path& exr, const std::vector<int>& labels, int blobs) {
    const ImageF ids = read_image_float(exr);
    std::vector<std::map<int, int>> votes(static_cast<std::size_t>(blobs));
    for (int y = 0; y < ids.height; ++y)
        for (int x = 0; x < ids.width; ++x) {
            const int b = labels[std::size_t(y) * ids.width + x];
            if (b < 0) continue;
            for (const char* channel : {"inner_marker_id", "outer_marker_id"}) {
                const int id = int(ids.at(x, y, channel));
                if (id >= 0) ++votes[std::size_t(b)][id];
            }
        }
    std::vector<int> owner(std::size_t(blobs), -1);
    for (std::size_t b = 0; b < votes.size(); ++b) {
        int best = 0;
        for (const auto& [id, count] : votes[b])
            if (count > best) owner[b] = id, best = count;
    }
    return owner;
}

/// Follows every marker from its projected rest position through the sequence: in each frame,
/// the blob nearest to where it was, within a marker's span.
Tracks track(const std::vector<FrameData>& seq, const std::vector<Eigen::Vector3d>& x0,
             const render::FisheyeCamera& camera, double span_px, ObjectLaws& laws) {
    std::vector<std::optional<Eigen::Vector2d>> at(x0.size());
    for (std::size_t m = 0; m < x0.size(); ++m)
        at[m] = camera.project(x0[m]);
    Tracks tracks;
    for (std::size_t f = 0; f < seq.size(); ++f) {
        const Image8 png = read_image8(seq[f].png);
        std::vector<int> labels;
        const std::vector<Blob> blobs = find_blobs(png, 0.5, 3, &labels);
        const std::vector<int> owner = blob_markers(seq[f].exr, labels, int(blobs.size()));
        auto& found = tracks.emplace_back(x0.size());
        for (std::size_t m = 0; m < x0.size(); ++m) {
            if (!at[m]) continue;
            double best = (f == 0 ? 0.75 : 1.0) * span_px;
            int chosen = -1;
            for (std::size_t b = 0; b < blobs.size(); ++b) {
                const double d = (blobs[b].centroid_px - *at[m]).norm();
                if (d < best) best = d, chosen = int(b);
            }
            if (chosen < 0) { // lost: left out from here on
                at[m].reset();
                continue;
            }
            found[m] = blobs[std::size_t(chosen)];
            at[m] = found[m]->centroid_px;
            ++laws.id_checks;
            laws.id_mismatches += owner[std::size_t(chosen)] != int(m);
        }
        ++laws.frames;
        laws.flagged_frames += !seq[f].converged;
    }
    return tracks;
}

} // namespace

namespace {

/// One marker's points: the press (rest first) and the lateral load (its reference first).
struct MarkerPoints {
    std::vector<double> normal_mm, hue_deg, area;
    std::vector<double> lateral_mm, shift_px;
};

/// The press: rest, then the converged grasp frames. Returns the last of those (0: none).
std::size_t press_points(const std::vector<FrameData>& seq, const Tracks& tracks, std::size_t m,
                         const Eigen::Vector3d& n, MarkerPoints& p) {
    const Blob& rest = *tracks[0][m];
    std::size_t last = 0;
    for (std::size_t f = 0; f < seq.size(); ++f) {
        if ((seq[f].phase != "rest" && seq[f].phase != "grasp") || !seq[f].converged ||
            !tracks[f][m])
            continue;
        const Blob& b = *tracks[f][m];
        p.normal_mm.push_back(-seq[f].u[m].dot(n));
        p.hue_deg.push_back(hue_difference_deg(b.mean_hue_deg, rest.mean_hue_deg));
        p.area.push_back(double(b.pixels) / rest.pixels - 1.0);
        last = f;
    }
    return last;
}

/// The lateral load from frame `ref`: tangential displacement and centroid shift, each along
/// the direction of its last value.
void lateral_points(const std::vector<FrameData>& seq, const Tracks& tracks, std::size_t m,
                    const Eigen::Vector3d& n, std::size_t ref, MarkerPoints& p) {
    std::vector<Eigen::Vector3d> du;
    std::vector<Eigen::Vector2d> shift;
    for (std::size_t f = ref + 1; f < seq.size(); ++f) {
        if (seq[f].phase != "load" || !seq[f].converged || !tracks[f][m]) continue;
        const Eigen::Vector3d d = seq[f].u[m] - seq[ref].u[m];
        du.push_back(d - d.dot(n) * n);
        shift.push_back(tracks[f][m]->centroid_px - tracks[ref][m]->centroid_px);
    }
    if (du.empty() || du.back().norm() == 0 || shift.back().norm() == 0) return;
    const Eigen::Vector3d e_mm = du.back().normalized();
    const Eigen::Vector2d e_px = shift.back().normalized();
    p.lateral_mm.assign(1, 0.0);
    p.shift_px.assign(1, 0.0);
    for (std::size_t i = 0; i < du.size(); ++i) {
        p.lateral_mm.push_back(du[i].dot(e_mm));
        p.shift_px.push_back(shift[i].dot(e_px));
    }
}

double largest(const std::vector<double>& v) {
    return v.empty() ? 0.0 : *std::max_element(v.begin(), v.end());
}

MarkerLaw marker_law(const std::vector<FrameData>& seq, const Tracks& tracks, std::size_t m,
                     const Eigen::Vector3d& x0, MarkerPoints& p) {
    MarkerLaw law;
    law.marker = int(m);
    const Eigen::Vector3d n = x0.normalized();
    law.polar_deg = std::acos(std::clamp(n.z(), -1.0, 1.0)) / kDeg;
    const std::size_t pressed = press_points(seq, tracks, m, n, p);
    law.normal_travel_mm = largest(p.normal_mm);
    law.hue = fit_line(p.normal_mm, p.hue_deg);
    law.area = fit_line(p.normal_mm, p.area);
    if (!p.hue_deg.empty())
        law.hue_range_deg =
            largest(p.hue_deg) - *std::min_element(p.hue_deg.begin(), p.hue_deg.end());
    if (pressed == 0) return law;
    law.delta_e = delta_e76(tracks[0][m]->mean_srgb, tracks[pressed][m]->mean_srgb);
    law.hue_rest_deg = tracks[0][m]->mean_hue_deg;
    law.hue_pressed_deg = tracks[pressed][m]->mean_hue_deg;
    law.area_change = p.area.back();
    lateral_points(seq, tracks, m, n, pressed, p);
    for (double s : p.lateral_mm)
        law.lateral_travel_mm = std::max(law.lateral_travel_mm, std::abs(s));
    law.centroid = fit_line(p.lateral_mm, p.shift_px);
    return law;
}

/// Median and 10th percentile over the markers `qualifies` admits, and the pooled line.
template <class Qualifies, class Range>
LawSummary summarise(const std::vector<MarkerLaw>& laws, const std::vector<MarkerPoints>& points,
                     Qualifies qualifies, LineFit MarkerLaw::*law,
                     std::vector<double> MarkerPoints::*x, std::vector<double> MarkerPoints::*y,
                     Range range) {
    LawSummary s;
    std::vector<double> r2, slope, ranges, xs, ys;
    for (std::size_t i = 0; i < laws.size(); ++i) {
        if (!qualifies(laws[i])) continue;
        ++s.markers;
        r2.push_back((laws[i].*law).r2);
        slope.push_back((laws[i].*law).slope);
        ranges.push_back(range(laws[i]));
        xs.insert(xs.end(), (points[i].*x).begin(), (points[i].*x).end());
        ys.insert(ys.end(), (points[i].*y).begin(), (points[i].*y).end());
    }
    s.r2_median = percentile(r2, 50);
    s.r2_p10 = percentile(r2, 10);
    s.slope_median = percentile(slope, 50);
    s.range_median = percentile(ranges, 50);
    s.pooled = fit_line(xs, ys);
    return s;
}

void object_laws(const std::vector<FrameData>& seq, const Tracks& tracks,
                 const std::vector<Eigen::Vector3d>& x0, ObjectLaws& out) {
    std::vector<MarkerPoints> points;
    for (std::size_t m = 0; m < x0.size(); ++m) {
        if (!tracks[0][m]) continue;
        out.tracked += tracks.back()[m].has_value();
        MarkerPoints p;
        out.markers.push_back(marker_law(seq, tracks, m, x0[m], p));
        points.push_back(std::move(p));
    }
    const auto pressed = [](const MarkerLaw& l) {
        return l.polar_deg <= kLawCapDeg + 0.01 && l.normal_travel_mm >= kLawMinTravelMm;
    };
    const auto sheared = [](const MarkerLaw& l) { return l.lateral_travel_mm >= kLawMinTravelMm; };
    using P = MarkerPoints;
    out.hue = summarise(out.markers, points, pressed, &MarkerLaw::hue, &P::normal_mm, &P::hue_deg,
                        [](const MarkerLaw& l) { return l.hue_range_deg; });
    out.area = summarise(out.markers, points, pressed, &MarkerLaw::area, &P::normal_mm, &P::area,
                         [](const MarkerLaw& l) { return l.delta_e; });
    out.centroid = summarise(out.markers, points, sheared, &MarkerLaw::centroid, &P::lateral_mm,
                             &P::shift_px, [](const MarkerLaw& l) { return l.lateral_travel_mm; });
    for (const MarkerLaw& l : out.markers)
        if (l.marker == 0) {
            out.apex_delta_e = l.delta_e;
            out.apex_hue_rest_deg = l.hue_rest_deg;
            out.apex_hue_pressed_deg = l.hue_pressed_deg;
            out.apex_area_change = l.area_change;
        }
}

} // namespace

namespace {

/// The run's folder: `keep` (created), or a temporary one removed at the end.
class WorkDir {
public:
    explicit WorkDir(const fs::path& keep) : m_keep(!keep.empty()) {
        m_path = m_keep ? keep
                        : fs::temp_directory_path() /
                              ("chromasim-verify-sensor-" + std::to_string(::getpid()));
        if (!m_keep) fs::remove_all(m_path);
        fs::create_directories(m_path);
    }
    ~WorkDir() {
        std::error_code ec;
        if (!m_keep) fs::remove_all(m_path, ec);
    }
    WorkDir(const WorkDir&) = delete;
    WorkDir& operator=(const WorkDir&) = delete;
    const fs::path& path() const { return m_path; }

private:
    bool m_keep;
    fs::path m_path;
};

/// `side` x `side` pixels of `image` centred at `c`, each scaled to `scale` x `scale`, pasted
/// into `out` at column `x0`.
void paste_crop(const Image8& image, const Eigen::Vector2d& c, int side, int scale, Image8& out,
                int x0) {
    const int left = int(std::lround(c.x())) - side / 2, top = int(std::lround(c.y())) - side / 2;
    for (int y = 0; y < side * scale; ++y)
        for (int x = 0; x < side * scale; ++x) {
            const int sx = std::clamp(left + x / scale, 0, image.width - 1);
            const int sy = std::clamp(top + y / scale, 0, image.height - 1);
            for (int ch = 0; ch < 3; ++ch)
                out.data[(std::size_t(y) * out.width + x0 + x) * 3 + ch] = image.at(sx, sy, ch);
        }
}

/// The apex marker at rest, then pressed to 3 N by each object, side by side.
void write_apex_picture(const fs::path& path, const std::vector<fs::path>& pngs,
                        const Eigen::Vector2d& apex_px, double span_px) {
    const int side = int(std::ceil(3 * span_px)), scale = std::max(1, 160 / side), gap = 6;
    const int panel = side * scale;
    Image8 out{int(pngs.size()) * (panel + gap) - gap, panel, 3, {}};
    out.data.assign(std::size_t(out.width) * out.height * 3, 255);
    for (std::size_t i = 0; i < pngs.size(); ++i)
        paste_crop(read_image8(pngs[i]), apex_px, side, scale, out, int(i) * (panel + gap));
    write_png8(path, out);
}

/// The papers' hue law: R^2 bounds and a visible hue change at the apex marker.
void add_hue_targets(SensorVerifyReport& r, const ObjectLaws& o) {
    using T = SensorVerifyReport::Target;
    r.targets.push_back(
        T{o.object + ": hue vs normal displacement, R2 median", o.hue.r2_median, 0.95, true});
    r.targets.push_back(
        T{o.object + ": hue vs normal displacement, R2 10th percentile", o.hue.r2_p10, 0.90, true});
    r.targets.push_back(T{o.object + ": apex marker's hue change over the press (deg)",
                          std::abs(hue_difference_deg(o.apex_hue_pressed_deg, o.apex_hue_rest_deg)),
                          kVisibleHueChangeDeg, true});
}

/// The size law, as strict as the hue law: the same R^2 bounds, and the apex marker's area
/// growing by kVisibleSizeChangePx of diameter at the CNN's input size.
void add_size_targets(SensorVerifyReport& r, const ObjectLaws& o, int size_px) {
    using T = SensorVerifyReport::Target;
    const double span_cnn_px = r.marker_span_px * kCnnInputPx / size_px;
    const double visible = std::pow(1.0 + kVisibleSizeChangePx / span_cnn_px, 2) - 1.0;
    r.targets.push_back(
        T{o.object + ": area vs normal displacement, R2 median", o.area.r2_median, 0.95, true});
    r.targets.push_back(T{o.object + ": area vs normal displacement, R2 10th percentile",
                          o.area.r2_p10, 0.90, true});
    r.targets.push_back(T{o.object + ": apex marker's area change over the press",
                          o.apex_area_change, visible, true});
}

} // namespace

NormalCue normal_cue(const std::string& interior) {
    return interior == "hollow" ? NormalCue::size : NormalCue::hue;
}

void add_sensor_targets(SensorVerifyReport& r, int size_px) {
    using T = SensorVerifyReport::Target;
    for (const ObjectLaws& o : r.objects) {
        if (r.cue == NormalCue::hue)
            add_hue_targets(r, o);
        else
            add_size_targets(r, o, size_px);
        r.targets.push_back(T{o.object + ": centroid vs lateral displacement, R2 median",
                              o.centroid.r2_median, 0.99, true});
        r.targets.push_back(T{o.object + ": blobs not the marker taken for (marker id channel)",
                              double(o.id_mismatches), 0.0, false});
    }
}

bool SensorVerifyReport::all_met() const {
    return std::all_of(targets.begin(), targets.end(), [](const Target& t) { return t.met(); });
}

SensorVerifyReport verify_sensor(const SensorVerifyOptions& o, std::ostream& log) {
    const auto t0 = std::chrono::steady_clock::now();
    Spec base = o.spec_file.empty() ? default_spec() : load_spec(o.spec_file);
    if (o.spec_file.empty()) { // the shipped render settings (datasets_spec/seed000_train.yaml)
        base.render.integrator = "fast";
        base.render.samples_per_pixel = 2;
    }
    const Spec spec = verify_spec(base, o.size_px);
    check_options(spec, o);
    SensorVerifyReport report;
    report.spec = o.spec_file.empty() ? "default sensor" : o.spec_file.string();
    report.render = spec.render.integrator + ", " + std::to_string(spec.render.samples_per_pixel) +
                    " spp, " + std::to_string(o.size_px) + " px";
    report.marker_span_px = marker_span_px(spec);
    report.cue = normal_cue(spec.sensor.interior);

    const render::Image rest = render_rest(spec, o.cache_dir);
    check_rest_blobs(spec, o, to_srgb8(rest));
    const WorkDir work(o.keep_dir);
    GenerateOptions generate_options;
    generate_options.out_dir = work.path() / "dataset";
    generate_options.quiet = true;
    generate_options.cache_dir = o.cache_dir;
    log << "chromasim verify sensor: rendering a press to " << kPressN
        << " N and a lateral load to slip, flat and 45 mm sphere (" << report.render << ")\n";
    generate(spec, generate_options, log);
    write_png(work.path() / "rest.png", rest);
    write_exr(work.path() / "rest.exr", rest);

    std::vector<Eigen::Vector3d> x0;
    const auto trials = read_dataset(generate_options.out_dir, work.path() / "rest.png",
                                     work.path() / "rest.exr", x0);
    const render::FisheyeCamera camera(camera_params(spec));
    std::vector<fs::path> pictures{work.path() / "rest.png"};
    std::optional<Eigen::Vector2d> apex_px;
    for (const auto& seq : trials) {
        ObjectLaws laws;
        laws.object = seq.front().object;
        const Tracks tracks = track(seq, x0, camera, report.marker_span_px, laws);
        object_laws(seq, tracks, x0, laws);
        report.objects.push_back(std::move(laws));
        for (std::size_t f = seq.size(); f-- > 0;)
            if (seq[f].phase == "grasp") {
                pictures.push_back(seq[f].png);
                break;
            }
        if (tracks[0][0]) apex_px = tracks[0][0]->centroid_px;
    }
    add_sensor_targets(report, o.size_px);
    if (!o.picture.empty() && apex_px)
        write_apex_picture(o.picture, pictures, *apex_px, report.marker_span_px);
    report.seconds = seconds_since(t0);
    return report;
}

} // namespace chromasim::generators
