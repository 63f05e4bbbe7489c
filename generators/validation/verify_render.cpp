#include "generators/validation/verify_render.hpp"

#include "generators/io/stopwatch.hpp"
#include "generators/pipeline/sensor_bridge.hpp"
#include "generators/spec/spec.hpp"
#include "mechanics/dome_model.hpp"
#include "render/embree_scene.hpp"
#include "render/fisheye_camera.hpp"
#include "render/furnace.hpp"
#include "render/renderer.hpp"

#include <tbb/global_control.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <iomanip>
#include <limits>
#include <numbers>
#include <ostream>
#include <sstream>

namespace chromasim::generators {

namespace {

using Clock = std::chrono::steady_clock;
constexpr double kPi = std::numbers::pi;

render::OpticsParams spectral_optics() {
    render::OpticsParams o;
    o.spectra = render::load_sensor_spectra(
        render::SensorSpectraFiles::in_directory(spectra_directory(Spec{})));
    return o;
}

/// The coarse dome's sensor frame, undeformed (`load` empty) or under a load from rest.
render::SensorFrame dome_frame(const mechanics::DomeModel& model,
                               const mechanics::ContactLoad* load) {
    if (!load) return undeformed_sensor_frame(model);
    mechanics::FrameRequest request{true, true, false};
    request.inner_surface = true;
    const mechanics::FrameResult r = model.solve(*load, request);
    render::SensorFrame frame;
    fill_sensor_frame(model, r, frame);
    return frame;
}

/// Largest and mean distance (px) between each inner marker's image and the projection
/// `predict` of its centre. The image is the marker's footprint in a marker id mask: camera
/// rays through 4 x 4 points per pixel, traced with Embree against the undeformed dome, each
/// first hit of an inner marker's volume counted for that marker; its centroid is the
/// marker's image position. Markers whose footprint touches the image circle's edge are left
/// out.
template <class Predict>
std::pair<double, double> marker_centroid_error(const mechanics::DomeModel& model,
                                                const render::CameraParams& camera, Predict predict,
                                                int* counted) {
    render::SensorFrame frame = dome_frame(model, nullptr);
    frame.outer_markers = render::SurfaceMesh{};
    frame.inner_surface = render::SurfaceMesh{}; // straight rays: the projection alone
    render::detail::EmbreeScene scene;
    scene.set_frame(frame);
    const render::FisheyeCamera fisheye(camera);
    const mechanics::MarkerDiscs& discs = model.markers();
    const int markers = discs.markers_per_layer;
    std::vector<Eigen::Vector2d> sum(std::size_t(markers), Eigen::Vector2d::Zero());
    std::vector<int> hits(std::size_t(markers), 0);
    std::vector<bool> clipped(std::size_t(markers), false);
    constexpr int kSub = 4;
    for (int y = 0; y < camera.height_px; ++y)
        for (int x = 0; x < camera.width_px; ++x)
            for (int j = 0; j < kSub * kSub; ++j) {
                const Eigen::Vector2d px(x + (j % kSub + 0.5) / kSub, y + (j / kSub + 0.5) / kSub);
                const auto w = fisheye.direction(px);
                if (!w) continue;
                const auto hit = scene.closest_hit(fisheye.origin_mm(), *w, 0.0, 1e3);
                if (hit.kind != render::detail::SurfaceKind::inner_marker) continue;
                const auto m = std::size_t(hit.prim_id) / std::size_t(frame.triangles_per_marker);
                sum[m] += px;
                ++hits[m];
                if (!fisheye.direction(px + Eigen::Vector2d(2, 0)) ||
                    !fisheye.direction(px - Eigen::Vector2d(2, 0)) ||
                    !fisheye.direction(px + Eigen::Vector2d(0, 2)) ||
                    !fisheye.direction(px - Eigen::Vector2d(0, 2)))
                    clipped[m] = true;
            }
    double worst = 0, total = 0;
    int n = 0;
    for (int m = 0; m < markers; ++m) {
        if (hits[std::size_t(m)] == 0 || clipped[std::size_t(m)]) continue;
        const Eigen::Vector3d c = discs.points.row(discs.ring_row(m, 0));
        const double e = (sum[std::size_t(m)] / hits[std::size_t(m)] - predict(c)).norm();
        worst = std::max(worst, e);
        total += e;
        ++n;
    }
    *counted = n;
    return {worst, n ? total / n : 0.0};
}

void projection_cases(const mechanics::DomeModel& model, std::vector<RenderVerifyCase>& out) {
    // Equidistant at the dome centre: r = theta / half_fov * 448 px at azimuth phi.
    render::CameraParams camera{896, 896, 84.0};
    const double half_fov = 84.0 * kPi / 180;
    auto equidistant = [&](const Eigen::Vector3d& c) {
        const double theta = std::acos(c.z() / c.norm()), phi = std::atan2(c.y(), c.x());
        const double r = theta / half_fov * 448.0;
        return Eigen::Vector2d(448.0 + r * std::cos(phi), 448.0 + r * std::sin(phi));
    };
    // Kannala-Brandt (OpenCV convention: pixel centres at integers, so + 0.5 here).
    render::CameraParams kb = camera;
    kb.model = render::CameraModel::kannala_brandt;
    kb.fx_px = 300.0, kb.fy_px = 310.0, kb.cx_px = 450.0, kb.cy_px = 440.0;
    kb.k1 = 0.03, kb.k2 = -0.01, kb.k3 = 0.002, kb.k4 = -0.0002;
    auto kannala_brandt = [&](const Eigen::Vector3d& c) {
        const double theta = std::acos(c.z() / c.norm()), phi = std::atan2(c.y(), c.x());
        const double t2 = theta * theta;
        const double td = theta * (1 + t2 * (kb.k1 + t2 * (kb.k2 + t2 * (kb.k3 + t2 * kb.k4))));
        return Eigen::Vector2d(kb.fx_px * td * std::cos(phi) + kb.cx_px + 0.5,
                               kb.fy_px * td * std::sin(phi) + kb.cy_px + 0.5);
    };
    for (const bool is_kb : {false, true}) {
        const auto t0 = Clock::now();
        int n = 0;
        const auto [worst, mean] = is_kb ? marker_centroid_error(model, kb, kannala_brandt, &n)
                                         : marker_centroid_error(model, camera, equidistant, &n);
        RenderVerifyCase c;
        c.key = "fisheye_projection";
        c.mode = is_kb ? "kannala_brandt" : "equidistant";
        c.measured = worst;
        // Fewer than 60 of the 82 markers measured (the rest touch the image circle's edge)
        // means the measurement broke: fail rather than pass on nothing.
        c.error = n >= 60 ? worst : std::numeric_limits<double>::infinity();
        c.target = 0.5;
        c.unit = "px";
        c.seconds = seconds_since(t0);
        std::ostringstream note;
        note << std::setprecision(3) << n << " inner markers, 896 px: largest distance from "
             << "the centroid of a marker's footprint in the id mask to the analytic pixel of "
             << "its centre; mean " << mean << " px";
        c.note = note.str();
        out.push_back(c);
    }
}

/// A closed prism (12-gon of radius 0.5 mm, `thickness_mm` along z) centred on the axis at z.
void add_axis_prism(render::SurfaceMesh& mesh, double z_mm, double thickness_mm) {
    constexpr int rim = 12;
    mesh.V.resize(2 * (rim + 1), 3);
    for (int face = 0; face < 2; ++face) {
        const float z = float(z_mm + (face ? 0.5 : -0.5) * thickness_mm);
        mesh.V.row(face * (rim + 1)) << 0.0f, 0.0f, z;
        for (int k = 0; k < rim; ++k)
            mesh.V.row(face * (rim + 1) + 1 + k) << float(0.5 * std::cos(2 * kPi * k / rim)),
                float(0.5 * std::sin(2 * kPi * k / rim)), z;
    }
    mesh.F.resize(4 * rim, 3);
    const std::uint32_t lo = 0, hi = rim + 1;
    for (std::uint32_t k = 0; k < rim; ++k) {
        const std::uint32_t a = 1 + k, b = 1 + (k + 1) % rim;
        mesh.F.row(4 * k) << lo, lo + b, lo + a;
        mesh.F.row(4 * k + 1) << hi, hi + a, hi + b;
        mesh.F.row(4 * k + 2) << lo + a, lo + b, hi + b;
        mesh.F.row(4 * k + 3) << lo + a, hi + b, hi + a;
    }
}

void filter_product_cases(const mechanics::DomeModel& model, std::vector<RenderVerifyCase>& out) {
    const auto t0 = Clock::now();
    render::OpticsParams optics = spectral_optics();
    optics.outer_marker_scatter_fraction = 0.0; // the cyan dye as a pure filter
    const render::SensorSpectra& sp = *optics.spectra;
    // On the axis of the undeformed dome: a magenta prism (z 10.505..10.995) and a cyan one
    // below it (9.505..9.995); every LED -> apex segment passes them > 1.2 mm off the axis.
    render::SensorFrame bare = dome_frame(model, nullptr);
    bare.inner_markers = bare.outer_markers = render::SurfaceMesh{};
    render::SensorFrame filtered = bare;
    constexpr double t = 0.49;
    add_axis_prism(filtered.inner_markers, 10.75, t);
    add_axis_prism(filtered.outer_markers, 9.75, t);
    filtered.triangles_per_marker = bare.triangles_per_marker = 48;
    const render::CameraParams camera{3, 3, 1.0};
    render::Renderer renderer(camera, optics);
    renderer.set_frame(bare);
    const render::Image white = renderer.render({4096, 3});
    renderer.set_frame(filtered);
    const render::Image seen = renderer.render({4096, 3});
    const render::Spectrum lit = sp.camera.led_emission() * sp.coating_albedo;
    const Eigen::Array3d expected =
        sp.camera.rgb_of_radiance(lit *
                                  render::transmittance(sp.inner_marker_absorption_per_mm, t) *
                                  render::transmittance(sp.outer_marker_absorption_per_mm, t)) /
        sp.camera.rgb_of_radiance(lit);
    const render::FilterPairRgb pair = render::rgb_of_filter_pair(
        sp.camera, sp.inner_marker_absorption_per_mm, t, sp.outer_marker_absorption_per_mm, t);
    const char* channel[3] = {"red", "green", "blue"};
    for (int k = 0; k < 3; ++k) {
        RenderVerifyCase c;
        c.key = "filter_product";
        c.mode = "spectral";
        c.measured = double(seen.pixel(1, 1)[k]) / white.pixel(1, 1)[k];
        c.reference = expected[k];
        c.relative = true;
        c.error = (c.measured - c.reference) / c.reference;
        c.target = 0.01;
        c.seconds = seconds_since(t0);
        std::ostringstream note;
        note << std::setprecision(4) << channel[k] << ": magenta over cyan, 0.49 mm each; the "
             << "RGB product would give " << pair.rgb_product[k];
        c.note = note.str();
        out.push_back(c);
    }
}

/// `rest`: the sensor at rest, for the fast integrator's light cache (nullptr otherwise).
void determinism_case(const render::SensorFrame& frame, render::Integrator integrator, int size,
                      std::vector<RenderVerifyCase>& out,
                      const render::SensorFrame* rest = nullptr) {
    const auto t0 = Clock::now();
    const render::OpticsParams optics = spectral_optics();
    auto render_with = [&](int threads) {
        const tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                                        std::size_t(threads));
        render::Renderer renderer({size, size, 84.0}, optics);
        if (rest) {
            render::LightCacheSettings cache;
            cache.paths_per_vertex = 32; // the cache's own determinism, at a quick size
            renderer.set_light_cache(*rest, cache);
        }
        renderer.set_frame(frame);
        render::RenderSettings settings{4, 11};
        settings.integrator = integrator;
        return renderer.render(settings);
    };
    const render::Image one = render_with(1), two = render_with(2);
    int differing = 0;
    for (std::size_t i = 0; i < one.rgb.size(); ++i)
        differing += std::memcmp(&one.rgb[i], &two.rgb[i], sizeof(float)) != 0;
    RenderVerifyCase c;
    c.key = "determinism";
    c.mode = integrator == render::Integrator::path   ? "spectral path"
             : integrator == render::Integrator::fast ? "spectral fast"
                                                      : "spectral preview";
    c.measured = differing;
    c.error = differing;
    c.target = 0;
    c.unit = "floats";
    c.seconds = seconds_since(t0);
    c.note = "values that differ between 1 and 2 threads (" + std::to_string(size) +
             " px, 4 spp, loaded dome" + (rest ? ", light cache built on each" : "") + ")";
    out.push_back(c);
}

void furnace_cases(std::vector<RenderVerifyCase>& out) {
    const render::FurnaceResult r = render::run_furnace({});
    const render::FurnaceSettings s;
    for (int k = 0; k < 3; ++k) {
        RenderVerifyCase c;
        c.key = "furnace";
        c.mode = "path";
        c.measured = r.measured[k];
        c.reference = r.expected[k];
        c.relative = true;
        c.error = (c.measured - c.reference) / c.reference;
        c.target = 0.005;
        c.seconds = r.seconds / 3;
        std::ostringstream note;
        note << std::setprecision(3) << "integrating sphere R " << s.radius_mm << " mm, albedo "
             << s.albedo[k] << ", " << s.paths << " paths, standard error "
             << 100 * r.standard_error[k] / r.expected[k] << " %";
        c.note = note.str();
        out.push_back(c);
    }
}

/// Slope of log RMSE against log spp for `integrator` on `frame` (size px square).
void convergence_case(const render::SensorFrame& frame, render::Integrator integrator, int size,
                      int reference_spp, std::vector<RenderVerifyCase>& out) {
    const auto t0 = Clock::now();
    render::Renderer renderer({size, size, 84.0}, spectral_optics());
    renderer.set_frame(frame);
    const auto settings = [integrator](int spp, std::uint64_t seed) {
        render::RenderSettings s;
        s.samples_per_pixel = spp;
        s.seed = seed;
        s.integrator = integrator;
        return s;
    };
    const render::Image ref = renderer.render(settings(reference_spp, 1));
    std::vector<double> log_spp, log_rmse;
    for (int spp : {1, 2, 4, 8, 16}) {
        const render::Image img = renderer.render(settings(spp, 7));
        double sum2 = 0;
        for (std::size_t i = 0; i < img.rgb.size(); ++i)
            sum2 += std::pow(double(img.rgb[i]) - ref.rgb[i], 2);
        log_spp.push_back(std::log(double(spp)));
        log_rmse.push_back(0.5 * std::log(sum2 / double(img.rgb.size())));
    }
    const double n = double(log_spp.size());
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    for (std::size_t i = 0; i < log_spp.size(); ++i) {
        sx += log_spp[i], sy += log_rmse[i];
        sxx += log_spp[i] * log_spp[i], sxy += log_spp[i] * log_rmse[i];
    }
    RenderVerifyCase c;
    c.key = "convergence_slope";
    c.mode = integrator == render::Integrator::path ? "spectral path" : "spectral preview";
    c.measured = (n * sxy - sx * sy) / (n * sxx - sx * sx);
    c.reference = -0.5;
    c.error = c.measured - c.reference;
    c.target = 0.1;
    c.seconds = seconds_since(t0);
    std::ostringstream note;
    note << "log RMSE against log spp, 1 to 16 spp against " << reference_spp << " spp (" << size
         << " px, loaded dome)"
         << (integrator == render::Integrator::path
                 ? ""
                 : "; direct light only: stratified jitter converges faster than -0.5 at edges");
    c.note = note.str();
    out.push_back(c);
}

} // namespace

render::Image render_reference_dome(int samples_per_pixel, std::uint64_t seed) {
    const mechanics::DomeModel model{dome_options(Spec{})};
    render::Renderer renderer({kReferenceDomeSize_px, kReferenceDomeSize_px, 84.0},
                              optics_params(Spec{}));
    const render::SensorFrame rest = undeformed_sensor_frame(model);
    renderer.set_exposure_reference(rest);
    renderer.set_frame(rest);
    render::RenderSettings settings{samples_per_pixel, seed};
    settings.variance = true;
    settings.integrator = render::Integrator::path;
    return renderer.render(settings);
}

std::vector<RenderVerifyCase> verify_render() {
    const mechanics::DomeModel model{mechanics::DomeModelOptions{}};
    std::vector<RenderVerifyCase> out;
    projection_cases(model, out);
    filter_product_cases(model, out);
    const mechanics::ContactLoad load{1.5, {0.6, 0.0}, 0.8};
    const render::SensorFrame loaded = dome_frame(model, &load);
    determinism_case(loaded, render::Integrator::preview, 224, out);
    determinism_case(loaded, render::Integrator::path, 96, out);
    const render::SensorFrame rest = undeformed_sensor_frame(model);
    determinism_case(loaded, render::Integrator::fast, 224, out, &rest);
    convergence_case(loaded, render::Integrator::preview, 224, 256, out);
    convergence_case(loaded, render::Integrator::path, 64, 1024, out);
    furnace_cases(out);
    return out;
}

void print_render_verify_table(const std::vector<RenderVerifyCase>& cases, std::ostream& out) {
    out << "| case | mode | measured | reference | error | target | within | s | note |\n"
        << "|---|---|---|---|---|---|---|---|---|\n";
    for (const RenderVerifyCase& c : cases) {
        out << "| " << c.key << " | " << c.mode << " | " << std::setprecision(5) << c.measured
            << " " << c.unit << " | " << c.reference << " | ";
        if (c.relative)
            out << std::fixed << std::setprecision(2) << 100 * c.error << " % | " << 100 * c.target
                << " % | ";
        else
            out << std::fixed << std::setprecision(3) << c.error << " | " << c.target << " | ";
        out << (std::abs(c.error) <= c.target ? "yes" : "no") << " | " << std::setprecision(1)
            << c.seconds << std::defaultfloat << " | " << c.note << " |\n";
    }
}

void write_render_verify_json(const std::vector<RenderVerifyCase>& cases, std::ostream& out) {
    out << "{\n  \"cases\": [\n" << std::setprecision(10);
    for (std::size_t i = 0; i < cases.size(); ++i) {
        const RenderVerifyCase& c = cases[i];
        out << "    {\"key\": \"" << c.key << "\", \"mode\": \"" << c.mode
            << "\", \"measured\": " << c.measured << ", \"reference\": " << c.reference
            << ", \"error\": " << c.error << ", \"relative\": " << (c.relative ? "true" : "false")
            << ", \"target\": " << c.target
            << ", \"within_target\": " << (std::abs(c.error) <= c.target ? "true" : "false")
            << ", \"unit\": \"" << c.unit << "\", \"seconds\": " << c.seconds << ", \"note\": \""
            << c.note << "\"}" << (i + 1 < cases.size() ? "," : "") << "\n";
    }
    out << "  ]\n}\n";
}

} // namespace chromasim::generators
