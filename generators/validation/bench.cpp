#include "generators/validation/bench.hpp"

#include "generators/validation/bench_table.hpp"

#include "generators/io/image_io.hpp"
#include "generators/io/stopwatch.hpp"
#include "generators/pipeline/sensor_bridge.hpp"
#include "generators/spec/spec.hpp"
#include "generators/spec/spec_schema.hpp"
#include "mechanics/dome_model.hpp"
#include "render/embree_scene.hpp"
#include "render/fisheye_camera.hpp"
#include "render/renderer.hpp"
#include "render/shading.hpp"

#include <sys/resource.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <map>
#include <numbers>
#include <optional>
#include <ostream>
#include <random>
#include <span>
#include <sstream>

namespace chromasim::generators {

namespace {

using Clock = std::chrono::steady_clock;

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    const std::size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/// Median wall time (s) of `repeats` calls of f.
template <class F> double time_median(int repeats, F&& f) {
    std::vector<double> t;
    for (int i = 0; i < repeats; ++i) {
        const auto t0 = Clock::now();
        f();
        t.push_back(seconds_since(t0));
    }
    return median(t);
}

double peak_rss_mib() {
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    return usage.ru_maxrss / 1024.0; // Linux reports KiB
}

// `v` as a fixed-point cell with `digits` decimals.
std::string fixed_cell(double v, int digits) {
    std::ostringstream s;
    s << std::fixed << std::setprecision(digits) << v;
    return s.str();
}

struct LevelRow {
    std::string level;
    mechanics::PrecomputeStats stats;
    double volume_error = 0, frame_labels_ms = 0, frame_fields_ms = 0;
    double trial_frame_ms = 0, trial_frame_frictionless_ms = 0;
    double indentation_mm = 0, apex_uz_mm = 0, rss_mib = 0;
};

LevelRow bench_level(const std::string& level, const DomeBenchOptions& o) {
    // A spec's defaults (contact cap, materials), then the bench's own options.
    mechanics::DomeModelOptions options = dome_options(Spec{});
    options.mesh_level = level;
    options.element_order = o.element_order;
    options.volumetric = o.volumetric == "element" ? mechanics::Volumetric::element
                                                   : mechanics::Volumetric::nodal_average;
    options.material = o.material == "neo_hookean" ? mechanics::MaterialModel::neo_hookean
                                                   : mechanics::MaterialModel::linear;
    using Interior = mechanics::DomeModelOptions::Interior;
    options.interior = o.interior == "rigid_core"  ? Interior::rigid_core
                       : o.interior == "soft_fill" ? Interior::soft_fill
                                                   : Interior::hollow;
    options.fill.E_MPa = o.fill_E_MPa;
    const mechanics::DomeModel model(options);
    LevelRow row{level, model.stats()};
    const double fill_volume = options.interior == Interior::soft_fill
                                   ? mechanics::dome_layer_volume(options.dome, mechanics::kFill)
                                   : 0.0;
    row.volume_error = mechanics::mesh_volume(model.mesh()) /
                           (mechanics::dome_layer_volume(options.dome) + fill_volume) -
                       1.0;
    const mechanics::ContactLoad load{o.normal_force_N, {o.tangential_force_N, 0.0}, o.mu};
    row.frame_labels_ms = 1e3 * time_median(o.repeats, [&] { model.solve(load, {}); });
    row.frame_fields_ms = 1e3 * time_median(o.repeats, [&] {
                              model.solve(load, {true, true, false});
                          });
    // A trial: a quarter of the frames pressing to P, then pulling to Q, each one step from
    // the previous frame (labels only); median time per frame. Then the same without friction.
    const int frames = std::max(4, o.trial_frames), press = frames / 4;
    for (const double mu : {o.mu, 0.0}) {
        std::vector<double> times;
        mechanics::FrameResult previous;
        for (int k = 0; k < frames; ++k) {
            const double s = k < press ? double(k + 1) / press : 1.0;
            const double q = k < press ? 0.0 : double(k - press + 1) / (frames - press);
            const mechanics::ContactLoad step{
                s * o.normal_force_N, {q * o.tangential_force_N, 0.0}, mu};
            const auto t0 = Clock::now();
            mechanics::FrameResult next = model.solve(step, {}, {}, k > 0 ? &previous : nullptr);
            if (k > 0) times.push_back(seconds_since(t0));
            previous = std::move(next);
        }
        (mu > 0 ? row.trial_frame_ms : row.trial_frame_frictionless_ms) = 1e3 * median(times);
    }
    const mechanics::FrameResult r = model.solve(load, {false, true, false});
    row.indentation_mm = r.contact.indentation_mm;
    row.apex_uz_mm = r.marker_points_mm(0, 2) - model.markers().points(0, 2);
    row.rss_mib = peak_rss_mib();
    return row;
}

BenchTable dome_table_head(const DomeBenchOptions& o, const std::string& reference_level) {
    std::ostringstream caption;
    caption << "dome under a flat, P = " << o.normal_force_N << " N, Q = " << o.tangential_force_N
            << " N, mu = " << o.mu << ", material " << o.material << ", element order "
            << o.element_order << ", volumetric " << o.volumetric << ", interior " << o.interior
            << (o.interior == "soft_fill" ? " (E " + std::to_string(o.fill_E_MPa) + " MPa)" : "")
            << "; reference level: " << reference_level
            << "; a frame from rest follows the default load path (4 normal + 4 tangential "
            << "steps), median of " << o.repeats
            << "; a trial frame is one step from the previous frame (" << o.trial_frames
            << " frames, a quarter pressing, median)";
    return {caption.str(),
            {"level", "nodes", "tets", "volume err", "mesh s", "assemble s", "factorize s",
             "compliance s", "frame from rest ms (labels)", "(+fields)", "trial frame ms",
             "(mu = 0)", "indentation mm", "vs ref", "apex u_z mm", "vs ref", "peak RSS MiB"},
            {}};
}

std::vector<std::string> level_cells(const LevelRow& r, const LevelRow& ref) {
    const auto& s = r.stats;
    return {r.level,
            std::to_string(s.nodes),
            std::to_string(s.tets),
            fixed_cell(100 * r.volume_error, 3) + " %",
            fixed_cell(s.mesh_s, 2),
            fixed_cell(s.assemble_s, 2),
            fixed_cell(s.factorize_s, 2),
            fixed_cell(s.compliance_s, 2),
            fixed_cell(r.frame_labels_ms, 2),
            fixed_cell(r.frame_fields_ms, 2),
            fixed_cell(r.trial_frame_ms, 2),
            fixed_cell(r.trial_frame_frictionless_ms, 2),
            fixed_cell(r.indentation_mm, 4),
            fixed_cell(100 * (r.indentation_mm / ref.indentation_mm - 1), 1) + " %",
            fixed_cell(r.apex_uz_mm, 4),
            fixed_cell(100 * (r.apex_uz_mm / ref.apex_uz_mm - 1), 1) + " %",
            fixed_cell(r.rss_mib, 0)};
}

} // namespace

void bench_dome(const DomeBenchOptions& o, std::ostream& out) {
    check_json_out("bench mechanics", o.json_out);
    std::vector<LevelRow> rows;
    for (const auto& level : o.levels)
        rows.push_back(bench_level(level, o));
    TablePrinter table(dome_table_head(o, rows.back().level), out);
    for (const LevelRow& r : rows)
        table.row(level_cells(r, rows.back()));
    out << "\npeak RSS is cumulative over the levels run so far in this process\n";
    write_bench_json(o.json_out, "bench mechanics", {table.table()});
}

MeanOfRenders mean_of_renders(const std::vector<std::vector<float>>& renders) {
    if (renders.size() < 2)
        throw std::invalid_argument("mean_of_renders: " + std::to_string(renders.size()) +
                                    " render(s); allowed: two or more");
    const std::size_t size = renders.front().size();
    for (const auto& r : renders)
        if (r.size() != size)
            throw std::invalid_argument("mean_of_renders: renders of " + std::to_string(size) +
                                        " and " + std::to_string(r.size()) +
                                        " values; allowed: renders of one size");
    const double n = double(renders.size());
    MeanOfRenders out;
    out.mean.assign(size, 0.0);
    out.variance_of_mean.assign(size, 0.0);
    for (std::size_t i = 0; i < size; ++i) {
        double sum = 0.0;
        for (const auto& r : renders)
            sum += r[i];
        const double mean = sum / n;
        double ss = 0.0;
        for (const auto& r : renders)
            ss += (r[i] - mean) * (r[i] - mean);
        out.mean[i] = mean;
        out.variance_of_mean[i] = ss / (n - 1.0) / n;
    }
    return out;
}

ErrorAgainstReference error_against(const std::vector<float>& image,
                                    const std::vector<float>& reference,
                                    const std::vector<float>& reference_variance) {
    if (image.size() != reference.size() ||
        (!reference_variance.empty() && reference_variance.size() != reference.size()))
        throw std::invalid_argument("error_against: " + std::to_string(image.size()) +
                                    " image values, " + std::to_string(reference.size()) +
                                    " reference values, " +
                                    std::to_string(reference_variance.size()) +
                                    " variances; allowed: equal counts (no variances: none known)");
    ErrorAgainstReference error;
    if (image.empty()) return error;
    double sum2 = 0.0, var = 0.0;
    for (std::size_t i = 0; i < image.size(); ++i) {
        const double e = std::abs(double(image[i]) - double(reference[i]));
        sum2 += e * e;
        error.max = std::max(error.max, e);
    }
    for (float v : reference_variance)
        var += v;
    const double ms = sum2 / double(image.size());
    if (!reference_variance.empty()) var /= double(reference_variance.size());
    error.rms = std::sqrt(ms);
    error.less_reference_noise = std::sqrt(std::max(0.0, ms - var));
    // The same over the pixels the reference lights.
    double lit_sum2 = 0.0, lit_var = 0.0, lit = 0.0;
    for (std::size_t i = 0; i + 2 < image.size(); i += 3) {
        if (!(reference[i] > 0.0f || reference[i + 1] > 0.0f || reference[i + 2] > 0.0f)) continue;
        for (std::size_t c = i; c < i + 3; ++c) {
            const double e = double(image[c]) - double(reference[c]);
            lit_sum2 += e * e;
            if (!reference_variance.empty()) lit_var += reference_variance[c];
            lit += 1.0;
        }
    }
    if (lit > 0.0) error.in_circle = std::sqrt(std::max(0.0, (lit_sum2 - lit_var) / lit));
    return error;
}

namespace {

// Before any work: the --images-out folder is made, or the user hears why not.
void make_images_out(const std::filesystem::path& dir) {
    if (dir.empty()) return;
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    if (ec || !std::filesystem::is_directory(dir))
        throw std::invalid_argument("bench render: --images-out " + dir.string() +
                                    ": cannot make this folder (" +
                                    (ec ? ec.message() : "a file is in the way") +
                                    "); allowed: a folder that exists or can be made");
}

struct BenchFrame {
    render::SensorFrame sensor, rest;
    std::string name;
};

// The frame the bench renders: the default spec's dome (neo-Hookean, the sensor a dataset
// gets) at rest or under the options' load.
BenchFrame bench_frame(const mechanics::DomeModel& model, const RenderBenchOptions& o) {
    BenchFrame f;
    f.rest = undeformed_sensor_frame(model);
    if (o.normal_N <= 0.0) {
        f.sensor = f.rest;
        f.name = "the dome at rest";
        return f;
    }
    mechanics::FrameRequest request{true, true, false};
    request.inner_surface = true; // the path integrator's refraction
    const mechanics::FrameResult frame = model.solve({o.normal_N, {o.shear_N, 0.0}, o.mu}, request);
    fill_sensor_frame(model, frame, f.sensor);
    std::ostringstream name;
    name << "coarse neo-Hookean dome at " << o.normal_N << " N + " << o.shear_N << " N pull, mu "
         << o.mu;
    f.name = name.str();
    return f;
}

constexpr std::uint64_t kTimedSeed = 7; // the timed renders'
constexpr double kWhite = 0.8;          // the exposure reference's image value

render::RenderSettings bench_settings(const RenderBenchOptions& o, int spp, std::uint64_t seed,
                                      const std::string& integrator) {
    render::RenderSettings s;
    s.samples_per_pixel = spp;
    s.seed = seed;
    s.integrator = integrator_of(integrator);
    if (!o.keep_camera_samples) s.camera_cache_mb = 0.0;
    return s;
}

// One --reference-in file, checked against the bench's size.
render::Image read_reference_file(const std::filesystem::path& path, int size_px) {
    const ImageF file = read_image_float(path);
    if (file.width != size_px || file.height != size_px)
        throw std::invalid_argument(
            "bench render: --reference-in " + path.string() + " is " + std::to_string(file.width) +
            " x " + std::to_string(file.height) + " px; allowed: a reference of --size " +
            std::to_string(size_px) + " px");
    render::Image image;
    image.width = file.width;
    image.height = file.height;
    const char* rgb_names[3] = {"R", "G", "B"};
    const char* var_names[3] = {"variance.R", "variance.G", "variance.B"};
    const bool has_variance =
        std::find(file.channels.begin(), file.channels.end(), "variance.R") != file.channels.end();
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x)
            for (int c = 0; c < 3; ++c) {
                image.rgb.push_back(file.at(x, y, rgb_names[c]));
                if (has_variance) image.variance.push_back(file.at(x, y, var_names[c]));
            }
    return image;
}

// The reference read from --reference-in: one file, or the mean of independent renders with
// the noise of their spread. Every file is read and checked before the first render.
render::Image read_reference(const RenderBenchOptions& o, std::string& source) {
    std::vector<render::Image> files;
    for (const std::filesystem::path& path : o.reference_in) {
        files.push_back(read_reference_file(path, o.size_px));
        source += (source.empty() ? "" : " + ") + path.string();
    }
    if (files.size() == 1) return std::move(files.front());
    std::vector<std::vector<float>> renders;
    for (const render::Image& image : files)
        renders.push_back(image.rgb);
    const MeanOfRenders mean = mean_of_renders(renders);
    render::Image ref;
    ref.width = o.size_px;
    ref.height = o.size_px;
    ref.rgb.assign(mean.mean.begin(), mean.mean.end());
    ref.variance.assign(mean.variance_of_mean.begin(), mean.variance_of_mean.end());
    source = "the mean of " + std::to_string(files.size()) + " independent renders (" + source +
             "; its noise from their spread)";
    return ref;
}

// The error reference: read, or rendered (spectral, at the reference's spp and seed).
render::Image bench_reference(const RenderBenchOptions& o, const render::CameraParams& camera,
                              const render::OpticsParams& optics, const BenchFrame& frame,
                              std::string& source) {
    if (!o.reference_in.empty()) return read_reference(o, source);
    render::Renderer renderer(camera, optics);
    render::SensorFrame reference_frame = frame.sensor;
    if (o.reference_integrator == "preview") reference_frame.inner_surface = {};
    renderer.set_frame(reference_frame);
    renderer.set_exposure_reference(frame.rest);
    if (o.reference_integrator == "fast") renderer.set_light_cache(frame.rest, o.light_cache);
    render::RenderSettings rs =
        bench_settings(o, o.reference_spp, o.reference_seed, o.reference_integrator);
    rs.variance = true;
    rs.fast_wavelengths = 16; // the least noise
    render::Image ref = renderer.render(rs);
    source = "the spectral render at " + std::to_string(o.reference_spp) + " spp (" +
             o.reference_integrator + " integrator)";
    if (!o.reference_out.empty()) write_exr(o.reference_out, ref);
    return ref;
}

// One timed setting of the fast integrator's knobs (the other integrators have none).
struct Knobs {
    double filter = 0.0;
    std::optional<double> rim_filter;
    int mirror = 0, edge = 0, led = 0, shadow_rays = 0, wavelengths = 0, spp = 1;
};

// Every combination of the knobs asked for, spp innermost.
std::vector<Knobs> knob_grid(const RenderBenchOptions& o, const std::string& integrator,
                             const std::string& mode) {
    const bool fast = integrator == "fast";
    const auto knob = [fast]<class T>(const std::vector<T>& values) {
        return fast ? values : std::vector<T>{T{}};
    };
    // The rims' own filter widths (none given: the filter's).
    std::vector<std::optional<double>> rim_filters{std::nullopt};
    if (fast && !o.shadow_filter_rim_px.empty())
        rim_filters.assign(o.shadow_filter_rim_px.begin(), o.shadow_filter_rim_px.end());
    // The wavelengths a sample (spectral mode; 0: by the spp; -1: not a knob here).
    const std::vector<int> wavelengths =
        fast && mode == "spectral" ? o.fast_wavelengths : std::vector<int>{-1};
    std::vector<Knobs> grid;
    for (const double filter : knob(o.shadow_filter_px))
        for (const std::optional<double>& rim_filter : rim_filters)
            for (const int mirror : knob(o.reflection_spp))
                for (const int edge : knob(o.rim_spp))
                    for (const int led : knob(o.reflected_led_spp))
                        for (const int shadow_rays : knob(o.shadow_rays_per_pixel))
                            for (const int lanes : wavelengths)
                                for (const int spp : o.samples_per_pixel)
                                    grid.push_back({filter, rim_filter, mirror, edge, led,
                                                    shadow_rays, lanes, spp});
    return grid;
}

render::RenderSettings knob_settings(const RenderBenchOptions& o, const Knobs& k,
                                     const std::string& integrator) {
    render::RenderSettings rs = bench_settings(o, k.spp, kTimedSeed, integrator);
    rs.shadow_filter_px = k.filter;
    rs.shadow_filter_rim_px = k.rim_filter;
    rs.reflection_samples_per_pixel = k.mirror;
    rs.rim_samples_per_pixel = k.edge;
    rs.reflected_led_samples_per_pixel = k.led;
    rs.shadow_rays_per_pixel = k.shadow_rays;
    if (k.wavelengths >= 0) rs.fast_wavelengths = k.wavelengths;
    return rs;
}

// The --images-out file of a setting, named after it.
std::string image_file_name(const std::string& integrator, const std::string& mode, const Knobs& k,
                            const render::RenderSettings& rs) {
    std::ostringstream file;
    file << integrator << "_" << mode << "_spp" << k.spp << "_filter" << k.filter;
    if (k.rim_filter) file << "_rimfilter" << *k.rim_filter;
    file << "_mirror" << k.mirror << "_rim" << k.edge << "_led" << k.led;
    if (k.shadow_rays > 0) file << "_shadow" << k.shadow_rays;
    if (k.wavelengths >= 0) file << "_lambda" << render::fast_wavelengths_of(rs);
    file << ".exr";
    return file.str();
}

// The table's name of a setting.
std::string setting_name(const std::string& integrator, const Knobs& k,
                         const render::RenderSettings& rs) {
    std::ostringstream name;
    name << integrator;
    if (k.filter > 0.0) name << ", shadow filter " << std::setprecision(2) << k.filter << " px";
    if (k.filter > 0.0 && k.rim_filter && k.edge > k.spp)
        name << " (" << std::setprecision(2) << *k.rim_filter << " px on the rims)";
    if (k.shadow_rays > k.spp) name << ", at least " << k.shadow_rays << " shadow rays a pixel";
    if (k.mirror > k.spp) name << ", " << k.mirror << " spp where an LED is mirrored";
    if (k.edge > k.spp) name << ", " << k.edge << " on the markers' rims";
    if (k.led > 0) name << ", the LEDs by reflection apart from " << k.led << " rays a pixel";
    if (k.wavelengths >= 0)
        name << ", " << render::fast_wavelengths_of(rs) << " wavelengths a sample";
    return name.str();
}

BenchTable render_table_head(const RenderBenchOptions& o, const std::string& frame_name,
                             const std::string& reference_source, double path_mm, double ref_var) {
    std::ostringstream caption;
    caption << "render " << o.size_px << " x " << o.size_px << ", " << frame_name
            << ", error against " << reference_source << ", in % of the white level "
            << "(0.8, the exposure reference); RGB mode: the spectra "
            << "reduced to camera RGB (absorption at " << path_mm << " mm); times are medians of "
            << o.repeats << "; 'less ref noise': sqrt(RMS^2 - the reference's mean variance), "
            << "the error against the converged image (reference noise "
            << fixed_cell(100 * std::sqrt(ref_var) / kWhite, 2) << " % RMS); 'in the circle': "
            << "less ref noise over the pixels the reference lights (the others are black in "
            << "both)";
    return {caption.str(),
            {"integrator", "mode", "spp", "render ms", "RMS error %", "less ref noise %",
             "in the circle %", "max error %"},
            {}};
}

// What one integrator and mode's renders counted: rays and seconds of the first setting, and
// the camera samples kept between renders.
struct RayCount {
    double rays = 0.0, seconds = 0.0;
    std::size_t kept_bytes = 0;
};

// The light cache's build and a frame's update: what every new sensor and frame cost before
// their first sample (the BVH refit and the point LEDs' solves through the inner surface).
void time_fast_setup(const RenderBenchOptions& o, const std::string& mode,
                     render::Renderer& renderer, const BenchFrame& frame,
                     const render::SensorFrame& shown, TablePrinter& table) {
    const double build_s = renderer.set_light_cache(frame.rest, o.light_cache);
    table.row({"fast", mode, "light cache", fixed_cell(1e3 * build_s, 0) + " (once per sensor)", "",
               "", "", ""});
    const double update_s = time_median(o.repeats, [&] { renderer.set_frame(shown); });
    table.row({"fast", mode, "frame update", fixed_cell(1e3 * update_s, 1) + " (once per frame)",
               "", "", "", ""});
}

// Times every setting of one integrator and mode and prints its rows.
RayCount bench_integrator(const RenderBenchOptions& o, const std::string& integrator,
                          const std::string& mode, const render::CameraParams& camera,
                          const render::OpticsParams& optics, const BenchFrame& frame,
                          const render::Image& ref, TablePrinter& table) {
    render::Renderer renderer(camera, optics);
    // The preview integrator does not refract: no inner surface, as in generate.
    render::SensorFrame shown = frame.sensor;
    if (integrator == "preview") shown.inner_surface = {};
    renderer.set_frame(shown);
    renderer.set_exposure_reference(frame.rest); // used by the path integrator only
    if (integrator == "fast") time_fast_setup(o, mode, renderer, frame, shown, table);
    RayCount count;
    const std::vector<Knobs> grid = knob_grid(o, integrator, mode);
    for (std::size_t i = 0; i < grid.size(); ++i) {
        const Knobs& k = grid[i];
        const render::RenderSettings rs = knob_settings(o, k, integrator);
        render::Image img;
        const double t = time_median(o.repeats, [&] { img = renderer.render(rs); });
        if (!o.images_out.empty()) {
            // One more render, untimed, with the extra channels (the same seed: the same
            // R, G, B as the timed ones).
            render::RenderSettings extra = rs;
            extra.variance = extra.marker_ids = true;
            write_exr(o.images_out / image_file_name(integrator, mode, k, rs),
                      renderer.render(extra));
        }
        const ErrorAgainstReference error = error_against(img.rgb, ref.rgb, ref.variance);
        if (i == 0) { // rays of one render, counted once
            renderer.count_rays(true);
            renderer.render(rs);
            count = {double(renderer.rays_counted()), t, renderer.camera_samples_bytes()};
            renderer.count_rays(false);
        }
        table.row({setting_name(integrator, k, rs), mode, std::to_string(k.spp),
                   fixed_cell(1e3 * t, 1), fixed_cell(100 * error.rms / kWhite, 3),
                   fixed_cell(100 * error.less_reference_noise / kWhite, 3),
                   fixed_cell(100 * error.in_circle / kWhite, 3),
                   fixed_cell(100 * error.max / kWhite, 3)});
    }
    return count;
}

// Embree's raw rate on the same scene: incoherent rays from the camera and the LEDs in
// uniformly random directions, nothing but closest_hit, in parallel as the renderer does.
double raw_ray_rate(const render::detail::EmbreeScene& scene, const render::OpticsParams& optics,
                    int repeats, std::ostream& out) {
    constexpr int kRawRays = 4'000'000;
    const render::detail::ShadingModel leds(optics);
    std::vector<render::Vec3> origins{render::Vec3::Zero()};
    for (const auto& p : leds.led_positions_mm())
        origins.push_back(p);
    const double raw_s = time_median(repeats, [&] {
        tbb::parallel_for(tbb::blocked_range<int>(0, kRawRays, 4096), [&](const auto& r) {
            std::mt19937_64 rng(std::uint64_t(r.begin()));
            for (int i = r.begin(); i != r.end(); ++i) {
                const double z = 2.0 * double(rng() >> 11) * 0x1.0p-53 - 1.0;
                const double phi = 2.0 * std::numbers::pi * double(rng() >> 11) * 0x1.0p-53;
                const double s = std::sqrt(std::max(0.0, 1.0 - z * z));
                const render::Vec3 w(s * std::cos(phi), s * std::sin(phi), z);
                scene.closest_hit(origins[std::size_t(i) % origins.size()], w, 0.0, 1e3);
            }
        });
    });
    const double raw_rate = kRawRays / raw_s;
    out << "\nEmbree alone on this scene: " << std::fixed << std::setprecision(2) << raw_rate / 1e6
        << " M rays/s (" << kRawRays / 1000000 << " M incoherent rays from the camera and the "
        << "LEDs, median of " << repeats << ")\n";
    return raw_rate;
}

// The ceiling for coherent rays: the camera's, 16 per pixel on a 4 x 4 grid, to the first
// surface, one by one and as one packet per pixel.
void camera_ray_rates(const render::detail::EmbreeScene& scene, const render::CameraParams& camera,
                      int repeats, std::ostream& out) {
    const render::FisheyeCamera fisheye(camera);
    std::vector<std::vector<render::Vec3>> pixel_rays;
    for (int y = 0; y < camera.height_px; ++y)
        for (int x = 0; x < camera.width_px; ++x) {
            std::vector<render::Vec3> rays;
            for (int k = 0; k < 16; ++k)
                if (const auto d =
                        fisheye.direction({x + (k % 4 + 0.5) / 4.0, y + (k / 4 + 0.5) / 4.0}))
                    rays.push_back(*d);
            if (!rays.empty()) pixel_rays.push_back(std::move(rays));
        }
    std::size_t camera_rays = 0;
    for (const auto& rays : pixel_rays)
        camera_rays += rays.size();
    const auto rate = [&](bool packets) {
        const double s = time_median(repeats, [&] {
            tbb::parallel_for(
                tbb::blocked_range<std::size_t>(0, pixel_rays.size(), 64), [&](const auto& r) {
                    std::array<render::detail::RayHit, 16> hits;
                    std::array<render::Vec3, 16> origins;
                    origins.fill(fisheye.origin_mm());
                    for (std::size_t i = r.begin(); i != r.end(); ++i) {
                        const auto& rays = pixel_rays[i];
                        if (packets) {
                            scene.closest_hits16(std::span(origins).first(rays.size()), rays, 0.0,
                                                 1e3, std::span(hits).first(rays.size()));
                        } else {
                            for (std::size_t k = 0; k < rays.size(); ++k)
                                hits[k] = scene.closest_hit(fisheye.origin_mm(), rays[k], 0.0, 1e3);
                        }
                    }
                });
        });
        return double(camera_rays) / s;
    };
    const double single_rate = rate(false), packet_rate = rate(true);
    out << "Embree alone, coherent camera rays (" << camera_rays
        << ", 16 per pixel): " << std::fixed << std::setprecision(2) << packet_rate / 1e6
        << " M rays/s in packets of 16 (one per "
        << "pixel), " << single_rate / 1e6 << " M rays/s one by one (median of " << repeats
        << ")\n";
}

} // namespace

void bench_render(const RenderBenchOptions& o, std::ostream& out) {
    check_json_out("bench render", o.json_out);
    make_images_out(o.images_out);
    const mechanics::DomeModel model(dome_options(default_spec()));
    const BenchFrame frame = bench_frame(model, o);
    // Spectral: the shipped spectra. RGB: the same sensor reduced to camera RGB (albedos as
    // seen under the LED, absorption coefficients at the markers' median thickness), so the
    // difference is the RGB approximation itself, not a different parameter set.
    const render::OpticsParams spectral = optics_params(Spec{}); // the default sensor
    const double path_mm = median_marker_thickness_mm(model);
    const render::OpticsParams rgb = rgb_optics(spectral, path_mm);
    const render::CameraParams camera{o.size_px, o.size_px, 84.0};
    std::string reference_source;
    const render::Image ref = bench_reference(o, camera, spectral, frame, reference_source);
    // The reference's own noise: the mean of its per-pixel variance of the mean (0 if unknown).
    double ref_var = 0.0;
    for (float v : ref.variance)
        ref_var += v;
    if (!ref.variance.empty()) ref_var /= double(ref.variance.size());
    TablePrinter table(render_table_head(o, frame.name, reference_source, path_mm, ref_var), out);
    std::map<std::string, RayCount> counts; // "integrator mode" -> its count
    for (const std::string& integrator : o.integrators)
        for (const std::string& mode : o.modes)
            counts[integrator + " " + mode] = bench_integrator(
                o, integrator, mode, camera, mode == "rgb" ? rgb : spectral, frame, ref, table);
    render::detail::EmbreeScene scene;
    scene.set_frame(frame.sensor);
    const double raw_rate = raw_ray_rate(scene, rgb, o.repeats, out);
    camera_ray_rates(scene, camera, o.repeats, out);
    for (const auto& [mode, counted] : counts) {
        if (counted.seconds <= 0.0) continue; // no setting was timed
        const double rate = counted.rays / counted.seconds;
        // Counted in traversals: a walk past markers in one (RayHits) is one ray here, and
        // costs more than one at the raw rate, so the share outside Embree is an upper bound.
        out << mode << " at " << o.samples_per_pixel.front() << " spp: " << std::fixed
            << std::setprecision(0) << counted.rays << " rays (Embree traversals), "
            << std::setprecision(2) << rate / 1e6 << " M rays/s; time outside Embree at most about "
            << std::setprecision(0) << 100 * std::max(0.0, 1.0 - rate / raw_rate) << " %";
        if (counted.kept_bytes > 0)
            out << "; camera samples kept from render to render: " << std::setprecision(1)
                << double(counted.kept_bytes) / (1024.0 * 1024.0) << " MiB";
        out << "\n";
    }
    write_bench_json(o.json_out, "bench render", {table.table()});
}

} // namespace chromasim::generators
