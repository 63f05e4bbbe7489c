#include "generators/pipeline/scene_export.hpp"

#include "generators/io/file_io.hpp"
#include "generators/io/stopwatch.hpp"
#include "generators/pipeline/generate.hpp"
#include "generators/pipeline/sensor_bridge.hpp"
#include "generators/plan/sensor_variants.hpp"
#include "render/fisheye_camera.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <ostream>
#include <stdexcept>

namespace chromasim::generators {

namespace {

using Clock = std::chrono::steady_clock;
constexpr double kDeg = std::numbers::pi / 180.0;

/// Vertical field of the perspective stand-in for the fisheye. The fisheye sees up to 180 deg
/// across; viewers refuse or badly distort perspective fields near that, 120 deg they show.
constexpr double kStandInYfov_deg = 120.0;
/// Outer radius of the black frame plane exported at z = 0 (the renderer's plane has none).
constexpr double kFrameOuterRadius_mm = 40.0;
constexpr int kFrameSegments = 96;
/// The lens barrel's top face below the rim plane, where the camera sits, mm.
constexpr double kBarrelTopGap_mm = 0.01;
/// Distance over which the marker volumes' attenuationColor is the transmittance, mm.
constexpr double kAttenuationDistance_mm = 1.0;

Eigen::Vector4d rgba(const render::Vec3& rgb) {
    return {rgb[0], rgb[1], rgb[2], 1.0};
}

/// `rgb` scaled to a largest channel of 1 (black stays black).
Eigen::Vector3d normalised_colour(const render::Vec3& rgb) {
    const double peak = rgb.maxCoeff();
    return peak > 0.0 ? Eigen::Vector3d(rgb / peak) : Eigen::Vector3d::Zero();
}

GltfMesh mesh(const std::string& name, const render::SurfaceMesh& surface, bool smooth) {
    GltfMesh m;
    m.name = name;
    m.surface = surface;
    if (smooth) m.normals = area_weighted_normals(surface);
    m.material.name = name;
    m.material.metallic = 0.0;
    return m;
}

/// A clear silicone surface or volume: smooth, fully transmissive.
void make_clear(GltfMaterial& m, double ior) {
    m.roughness = 0.0;
    m.transmission = 1.0;
    m.ior = ior;
}

/// A dyed marker volume: Beer-Lambert absorption a (1/mm) as glTF's attenuation, the
/// transmittance exp(-a d) over d = kAttenuationDistance_mm.
void make_dyed(GltfMaterial& m, const render::Vec3& absorption_per_mm, double thickness_mm,
               double ior) {
    make_clear(m, ior);
    GltfVolume v;
    v.thickness_mm = thickness_mm;
    v.attenuation_distance_mm = kAttenuationDistance_mm;
    v.attenuation_color = (-absorption_per_mm * kAttenuationDistance_mm).array().exp();
    m.volume = v;
}

/// Azimuth of LED k on the ring (render's layout: evenly spaced, the first on +x), rad.
double led_azimuth(const render::OpticsParams& o, int k) {
    return 2.0 * std::numbers::pi * k / o.led_count;
}

/// Position of LED k, mm.
Eigen::Vector3d led_position(const render::OpticsParams& o, int k) {
    const double phi = led_azimuth(o, k);
    return {o.led_ring_radius_mm * std::cos(phi), o.led_ring_radius_mm * std::sin(phi), o.led_z_mm};
}

/// One emissive rectangle per LED in the LED plane, facing +z (towards the dome): the
/// renderer's Lambertian LEDs, `led_width_mm` along the ring and `led_height_mm` across it.
GltfMesh led_rectangles(const render::OpticsParams& o) {
    render::SurfaceMesh s;
    s.V.resize(4 * o.led_count, 3);
    s.F.resize(2 * o.led_count, 3);
    for (int k = 0; k < o.led_count; ++k) {
        const double phi = led_azimuth(o, k);
        const Eigen::Vector3d radial(std::cos(phi), std::sin(phi), 0.0);
        const Eigen::Vector3d along(-std::sin(phi), std::cos(phi), 0.0); // the ring's tangent
        const Eigen::Vector3d c = led_position(o, k);
        const double a = o.led_width_mm / 2, b = o.led_height_mm / 2;
        const int v = 4 * k;
        s.V.row(v + 0) = (c - b * radial - a * along).transpose().cast<float>();
        s.V.row(v + 1) = (c + b * radial - a * along).transpose().cast<float>();
        s.V.row(v + 2) = (c + b * radial + a * along).transpose().cast<float>();
        s.V.row(v + 3) = (c - b * radial + a * along).transpose().cast<float>();
        const auto u = std::uint32_t(v); // counter-clockwise seen from +z
        s.F.row(2 * k) << u, u + 1, u + 2;
        s.F.row(2 * k + 1) << u, u + 2, u + 3;
    }
    GltfMesh m = mesh("leds", s, false);
    m.material.name = "led";
    m.material.emissive = normalised_colour(o.led_rgb);
    // chromasim's LED face radiance: the on-axis intensity led_rgb spread over the face.
    m.material.extras = {{"chromasim_optics", std::string("lambertian emitter, front (+z) only")},
                         {"relative_radiance",
                          o.led_rgb.maxCoeff() / (o.led_width_mm * o.led_height_mm)}};
    return m;
}

/// A mesh of the mount: black, matte, seen from both sides.
GltfMesh black_absorber(GltfMesh m) {
    m.material.base_color = {0.0, 0.0, 0.0, 1.0};
    m.material.roughness = 1.0;
    m.material.double_sided = true;
    m.material.extras = {{"chromasim_optics", std::string("black absorber")}};
    return m;
}

/// The rigid frame that clamps the dome: black, in the rim plane z = 0, from the renderer's
/// frame_inner_radius_mm outwards.
GltfMesh frame_plane(const render::OpticsParams& o) {
    render::SurfaceMesh s;
    s.V.resize(2 * kFrameSegments, 3);
    s.F.resize(2 * kFrameSegments, 3);
    for (int k = 0; k < kFrameSegments; ++k) {
        const double phi = 2.0 * std::numbers::pi * k / kFrameSegments;
        const Eigen::Vector3d d(std::cos(phi), std::sin(phi), 0.0);
        s.V.row(2 * k) = (o.frame_inner_radius_mm * d).transpose().cast<float>();
        s.V.row(2 * k + 1) = (kFrameOuterRadius_mm * d).transpose().cast<float>();
        const auto i = std::uint32_t(2 * k), j = std::uint32_t(2 * ((k + 1) % kFrameSegments));
        s.F.row(2 * k) << i, i + 1, j + 1; // counter-clockwise seen from +z
        s.F.row(2 * k + 1) << i, j + 1, j;
    }
    return black_absorber(mesh("frame", s, false));
}

/// The camera's lens barrel: a black closed cylinder about the z axis of radius
/// lens_radius_mm, from just below the rim plane (the camera sits on it) to 3 mm below the
/// LEDs; the renderer's barrel runs on down, where no light goes.
GltfMesh lens_barrel(const render::OpticsParams& o) {
    const double top = -kBarrelTopGap_mm, bottom = std::min(o.led_z_mm, 0.0) - 3.0;
    const double R = o.lens_radius_mm;
    render::SurfaceMesh s;
    s.V.resize(2 * kFrameSegments + 2, 3);
    s.F.resize(4 * kFrameSegments, 3);
    const int top_centre = 2 * kFrameSegments, bottom_centre = top_centre + 1;
    s.V.row(top_centre) << 0.0f, 0.0f, float(top);
    s.V.row(bottom_centre) << 0.0f, 0.0f, float(bottom);
    for (int k = 0; k < kFrameSegments; ++k) {
        const double phi = 2.0 * std::numbers::pi * k / kFrameSegments;
        s.V.row(2 * k) << float(R * std::cos(phi)), float(R * std::sin(phi)), float(top);
        s.V.row(2 * k + 1) << float(R * std::cos(phi)), float(R * std::sin(phi)), float(bottom);
        const auto i = std::uint32_t(2 * k), j = std::uint32_t(2 * ((k + 1) % kFrameSegments));
        const auto tc = std::uint32_t(top_centre), bc = std::uint32_t(bottom_centre);
        s.F.row(4 * k) << i, i + 1, j + 1; // outward normals
        s.F.row(4 * k + 1) << i, j + 1, j;
        s.F.row(4 * k + 2) << tc, i, j;
        s.F.row(4 * k + 3) << bc, j + 1, i + 1;
    }
    return black_absorber(mesh("lens_barrel", s, false));
}

/// The fisheye's intrinsics in OpenCV's cv::fisheye convention (the equidistant camera's
/// own for the equidistant model) and image size.
GltfExtras fisheye_extras(const render::CameraParams& c) {
    const bool kb = c.model == render::CameraModel::kannala_brandt;
    const render::CameraParams k = kb ? c : render::with_equidistant_intrinsics(c);
    return {{"model", std::string(kb ? "kannala_brandt" : "equidistant")},
            {"half_fov_deg", c.half_fov_deg},
            {"fx", k.fx_px},
            {"fy", k.fy_px},
            {"cx", k.cx_px},
            {"cy", k.cy_px},
            {"k1", k.k1},
            {"k2", k.k2},
            {"k3", k.k3},
            {"k4", k.k4},
            {"width", double(c.width_px)},
            {"height", double(c.height_px)},
            {"pixel_convention", std::string("OpenCV: centre of the first pixel at (0, 0)")},
            {"note", std::string("glTF has no fisheye model: this perspective camera stands in "
                                 "for the pose only; the real camera is the fisheye above")}};
}

GltfCamera stand_in_camera(const render::CameraParams& params) {
    const render::FisheyeCamera fisheye(params); // validates, and applies the pose
    GltfCamera c;
    c.name = "fisheye_camera";
    c.position_mm = fisheye.origin_mm();
    c.rotation = fisheye.rotation();
    c.yfov_rad = kStandInYfov_deg * kDeg;
    c.aspect_ratio = double(params.width_px) / params.height_px;
    c.extras = fisheye_extras(params);
    return c;
}

GltfExtras frame_extras(const Spec& spec, const SceneExportReport& report) {
    const LabelRow& row = report.labels;
    const int frames = report.frames;
    return {{"chromasim_version", std::string(CHROMASIM_VERSION)},
            {"spec_name", spec.name},
            {"spec_sha256", sha256_hex(stored_spec_text(spec))},
            {"trial", double(report.trial)},
            {"finger", std::string(finger_name(report.finger))},
            {"frame", double(row.frame)},
            {"frames", double(frames)},
            {"phase", row.phase},
            {"mu", row.mu},
            {"gamma", row.gamma},
            {"sliding", row.sliding ? 1.0 : 0.0},
            {"normal_force_N", row.normal_force_N},
            {"tangential_force_x_N", row.tangential_x_N},
            {"tangential_force_y_N", row.tangential_y_N},
            {"requested_tangential_force_N", row.requested_tangential_N},
            {"indentation_mm", row.indentation_mm},
            {"contact_area_mm2", row.contact_area_mm2},
            {"converged", row.converged ? 1.0 : 0.0},
            {"status", row.status}};
}

} // namespace

render::VertexArray area_weighted_normals(const render::SurfaceMesh& mesh) {
    Eigen::MatrixX3d sum = Eigen::MatrixX3d::Zero(mesh.V.rows(), 3);
    for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
        const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)).cast<double>();
        const Eigen::Vector3d b = mesh.V.row(mesh.F(f, 1)).cast<double>();
        const Eigen::Vector3d c = mesh.V.row(mesh.F(f, 2)).cast<double>();
        const Eigen::RowVector3d n = (b - a).cross(c - a).transpose(); // |n| = twice the area
        for (int k = 0; k < 3; ++k)
            sum.row(mesh.F(f, k)) += n;
    }
    render::VertexArray N(mesh.V.rows(), 3);
    for (Eigen::Index v = 0; v < sum.rows(); ++v) {
        const double length = sum.row(v).norm();
        N.row(v) = length > 0.0 ? (sum.row(v) / length).cast<float>().eval()
                                : Eigen::RowVector3f(0.0f, 0.0f, 1.0f);
    }
    return N;
}

GltfScene make_gltf_scene(const render::SensorFrame& frame, const render::CameraParams& camera,
                          const render::OpticsParams& optics, const SceneInfo& info) {
    const double ior = optics.refractive_index; // sensor.optics.refractive_index
    GltfScene scene;
    scene.name = info.name;
    scene.extras = info.extras;
    // The white diffusing coating, seen from both sides (a viewer outside sees its back); flat
    // shaded, as the renderer shades it with each triangle's own normal.
    GltfMesh coating = mesh("coating", frame.coating, false);
    coating.material.base_color = rgba(optics.coating_albedo);
    coating.material.roughness = 1.0;
    coating.material.double_sided = true;
    coating.material.extras = {{"chromasim_optics", std::string("lambertian")}};
    scene.meshes.push_back(std::move(coating));
    if (frame.inner_surface.F.rows() > 0) {
        GltfMesh inner = mesh("inner_surface", frame.inner_surface, true);
        make_clear(inner.material, ior);
        inner.material.double_sided = true;
        inner.material.extras = {
            {"chromasim_optics", std::string("smooth dielectric: air on the normal's side")}};
        scene.meshes.push_back(std::move(inner));
    }
    // The markers lie in silicone of their own index: no refraction at their faces (ior 1).
    GltfMesh magenta = mesh("inner_markers", frame.inner_markers, false);
    make_dyed(magenta.material, optics.inner_marker_absorption_per_mm, info.marker_thickness_mm,
              1.0);
    magenta.material.extras = {{"chromasim_optics", std::string("absorbing, index-matched")}};
    scene.meshes.push_back(std::move(magenta));
    // The cyan layer also scatters: entering light is scattered back diffusely with this
    // probability, of the marker albedo; the rest passes and is absorbed.
    GltfMesh cyan = mesh("outer_markers", frame.outer_markers, false);
    make_dyed(cyan.material, optics.outer_marker_absorption_per_mm, info.marker_thickness_mm, 1.0);
    cyan.material.base_color = rgba(optics.outer_marker_albedo);
    cyan.material.transmission = 1.0 - optics.outer_marker_scatter_fraction;
    cyan.material.extras = {
        {"chromasim_optics",
         std::string("absorbing, index-matched; scatters back on entry (front faces)")},
        {"scatter_fraction", optics.outer_marker_scatter_fraction}};
    scene.meshes.push_back(std::move(cyan));
    scene.meshes.push_back(led_rectangles(optics));
    scene.meshes.push_back(frame_plane(optics));
    if (optics.lens_radius_mm > 0.0) scene.meshes.push_back(lens_barrel(optics));
    scene.camera = stand_in_camera(camera);
    return scene;
}

namespace {

/// Throws std::out_of_range naming `option`, its value and the allowed range [0, count - 1].
void check_index(const char* option, int value, int count, const std::string& what) {
    if (value >= 0 && value < count) return;
    throw std::out_of_range(std::string(option) + " " + std::to_string(value) +
                            " is out of range: " + what + " " + std::to_string(count) + ", so " +
                            option + " must be in [0, " + std::to_string(count - 1) + "]");
}

/// The trial `which` names, after checking its trial, finger and frame against the plan.
const TrialPlan& selected_trial(const Plan& plan, const std::string& spec_name,
                                const SceneSelection& which) {
    check_index("--trial", which.trial, int(plan.trials.size()),
                "spec '" + spec_name + "' plans trials:");
    const TrialPlan& trial = plan.trials[std::size_t(which.trial)];
    if (which.finger < 0 || which.finger >= int(trial.fingers.size()))
        throw std::out_of_range("--finger " + std::string(finger_name(which.finger)) +
                                " is out of range: spec '" + spec_name + "' has " +
                                std::to_string(trial.fingers.size()) +
                                " fingertip(s) (fingers.count), so --finger must be left");
    check_index("--frame", which.frame, int(trial.frames.size()),
                "trial " + std::to_string(which.trial) + " of spec '" + spec_name +
                    "' plans frames:");
    return trial;
}

/// The finger's frames 0 to `which.frame`, each from the state the previous one left, as
/// generate solves them; only the exported frame gets its surfaces.
mechanics::FrameResult solve_to_frame(const mechanics::DomeModel& model, const TrialPlan& trial,
                                      const SceneSelection& which,
                                      const mechanics::ObjectShape& object) {
    mechanics::FrameResult r;
    const auto load = [&](int k) -> const FingerLoad& {
        return trial.frames[std::size_t(k)].fingers[std::size_t(which.finger)];
    };
    for (int k = 0; k <= which.frame; ++k) {
        // As generate: a frame with its predecessor's load is not solved again (the exported
        // frame always is, for its surfaces).
        if (k > 0 && k < which.frame && load(k) == load(k - 1)) continue;
        mechanics::FrameRequest request;
        request.coating = request.markers = request.inner_surface = k == which.frame;
        mechanics::FrameResult next =
            model.solve(contact_load(load(k)), request, object, k > 0 ? &r : nullptr);
        r = std::move(next);
    }
    return r;
}

} // namespace

SceneExportReport export_scene(const Spec& spec_in, const SceneSelection& which,
                               const std::filesystem::path& out, const SceneExportOptions& options,
                               std::ostream& log) {
    const auto t_start = Clock::now();
    // 1. Validate, then work: the trial, finger and frame and the output path; the object's
    // mesh file, the camera and the optics (of the trial's sensor) are read before the
    // mechanics start.
    const Plan plan = make_plan(spec_in);
    const TrialPlan& trial = selected_trial(plan, spec_in.name, which);
    const Spec spec = trial.sensor >= 0
                          ? sensor_spec(spec_in, plan.sensors[std::size_t(trial.sensor)])
                          : spec_in;
    SceneExportReport report;
    report.trial = which.trial;
    report.finger = which.finger;
    report.frame = which.frame;
    report.frames = int(trial.frames.size());
    check_gltf_output_path(out);
    // Only this trial's object is read.
    const ObjectSource source = object_source(spec, spec.objects[std::size_t(trial.object)]);
    const mechanics::ObjectShape object =
        object_shape(source, posed_object(source.object, trial.fingers[std::size_t(which.finger)]));
    const render::CameraParams camera = camera_params(spec);
    const render::OpticsParams spectral_or_rgb = optics_params(spec);

    // 2. The dome model (from the cache when there), then the frames up to the exported one.
    const auto t0 = Clock::now();
    mechanics::DomeModelOptions model_options = dome_options(spec);
    model_options.cache_dir = options.cache_dir;
    const mechanics::DomeModel model(model_options);
    log_dome_model(model, seconds_since(t0), options.cache_dir, log);
    const mechanics::FrameResult r = solve_to_frame(model, trial, which, object);
    const FramePlan& frame = trial.frames[std::size_t(which.frame)];
    report.labels = label_row(frame, frame.fingers[std::size_t(which.finger)], r);
    if (!report.labels.converged)
        log << "chromasim: warning: frame " << which.frame << " flagged: " << report.labels.status
            << " (exported all the same; the scene extras say so)\n";

    // 3. The scene, written atomically.
    render::SensorFrame sensor;
    fill_sensor_frame(model, r, sensor);
    const SceneInfo info{spec.name + " trial " + std::to_string(which.trial) + " " +
                             finger_name(which.finger) + " frame " + std::to_string(which.frame),
                         spec.sensor.marker_thickness_mm, frame_extras(spec, report)};
    // glTF colours are RGB: with spectra, the colours the camera sees (the markers'
    // absorption at their median thickness, as bench render's RGB mode).
    const render::OpticsParams optics =
        rgb_optics(spectral_or_rgb, median_marker_thickness_mm(model));
    write_gltf_scene(out, make_gltf_scene(sensor, camera, optics, info));
    report.total_s = seconds_since(t_start);
    return report;
}

} // namespace chromasim::generators
