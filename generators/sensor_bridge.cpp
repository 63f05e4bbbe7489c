#include "generators/sensor_bridge.hpp"

#include "generators/gltf_io.hpp"
#include "render/fisheye_camera.hpp"

#include <algorithm>
#include <stdexcept>
#include <vector>

namespace chromasim::generators {

namespace {
mechanics::Material material(const LayerMaterial& m) {
    return {m.E_MPa, m.nu};
}
render::Vec3 vec(const Rgb& c) {
    return {c[0], c[1], c[2]};
}

/// Marker discs as triangle fans (centre, rim k, rim k+1), layer `layer` (0 inner, 1 outer).
/// Triangles of one marker prism: its inner and outer faces as fans and the side as quads, all
/// facing out of the volume (the rims run counter-clockwise about the outward radial n).
constexpr int kPrismTriangles = 4; // per rim point

/// The closed marker volumes of one layer (MarkerDiscs layout: per marker the mid ring, then
/// the inner-face and outer-face rings) as a SurfaceMesh of 4 rim triangles per marker.
void fill_prisms(const mechanics::Points& points, const mechanics::MarkerDiscs& discs, int layer,
                 render::SurfaceMesh& out) {
    const int markers = discs.markers_per_layer, rim = discs.rim_points, ring = 1 + rim;
    const int first = layer * markers * discs.points_per_marker;
    out.V = points.middleRows(first, Eigen::Index(markers) * discs.points_per_marker).cast<float>();
    const Eigen::Index triangles = Eigen::Index(markers) * kPrismTriangles * rim;
    if (out.F.rows() == triangles) return; // topology unchanged
    out.F.resize(triangles, 3);
    Eigen::Index f = 0;
    for (int m = 0; m < markers; ++m) {
        const auto in = std::uint32_t(m * discs.points_per_marker + ring); // inner-face centre
        const auto outer = in + std::uint32_t(ring);                       // outer-face centre
        for (int k = 0; k < rim; ++k) {
            const std::uint32_t a = 1 + std::uint32_t(k), b = 1 + std::uint32_t((k + 1) % rim);
            out.F.row(f++) << in, in + b, in + a;          // faces -n
            out.F.row(f++) << outer, outer + a, outer + b; // faces +n
            out.F.row(f++) << in + a, in + b, outer + b;   // side, faces outwards
            out.F.row(f++) << in + a, outer + b, outer + a;
        }
    }
}
} // namespace

mechanics::DomeModelOptions dome_options(const Spec& spec) {
    mechanics::DomeModelOptions o;
    o.mesh_level = spec.sensor.mesh_level;
    o.material = spec.sensor.material_model == "neo_hookean" ? mechanics::MaterialModel::neo_hookean
                                                             : mechanics::MaterialModel::linear;
    o.load_path.normal_steps = o.load_path.tangential_steps = spec.sensor.contact_steps;
    using Interior = mechanics::DomeModelOptions::Interior;
    o.interior = spec.sensor.interior == "rigid_core"  ? Interior::rigid_core
                 : spec.sensor.interior == "soft_fill" ? Interior::soft_fill
                                                       : Interior::hollow;
    o.fill = material(spec.sensor.fill);
    o.volumetric = spec.sensor.volumetric == "element" ? mechanics::Volumetric::element
                                                       : mechanics::Volumetric::nodal_average;
    o.materials = {material(spec.sensor.inner_marker_layer), material(spec.sensor.clear_layer),
                   material(spec.sensor.outer_marker_layer), material(spec.sensor.coating)};
    o.contact_candidate_angle_deg = spec.sensor.contact_candidate_angle_deg;
    o.dome.marker_thickness_mm = spec.sensor.marker_thickness_mm;
    return o;
}

/// Side of the plate that stands for a tilted flat, mm: wider than the dome (26.4 mm).
constexpr double kTiltedPlate_mm = 80.0;

mechanics::ObjectShape object_shape(const Spec& spec, const Spec::Object& object) {
    mechanics::ObjectShape o;
    o.kind = object.shape == "sphere" ? mechanics::ObjectShape::Kind::sphere
                                      : mechanics::ObjectShape::Kind::flat;
    o.radius_mm = object.radius_mm;
    mechanics::Pose pose;
    pose.rotation = mechanics::rotation_from_roll_pitch_yaw_deg(object.roll_deg, object.pitch_deg,
                                                                object.yaw_deg);
    pose.translation_mm = {object.offset_x_mm, object.offset_y_mm, 0.0};
    if (object.shape == "mesh") {
        o.kind = mechanics::ObjectShape::Kind::mesh;
        o.mesh = std::make_shared<mechanics::MeshHeightField>(
            load_gltf_surface(resolve_spec_path(spec, object.mesh_file)), pose);
    } else if (object.shape == "sphere") {
        o.offset_mm = {object.offset_x_mm, object.offset_y_mm};
    } else if (pose.rotation(2, 2) < 1.0 - 1e-15) {
        // A tilted flat: a posed plate much wider than the contact cap (a plane's offset and
        // yaw change nothing, so an untilted flat stays the exact analytic plane).
        o.kind = mechanics::ObjectShape::Kind::mesh;
        o.mesh = std::make_shared<mechanics::MeshHeightField>(
            mechanics::make_plate(kTiltedPlate_mm, kTiltedPlate_mm), pose);
    }
    return o;
}

mechanics::ContactLoad contact_load(const FingerLoad& f) {
    mechanics::ContactLoad load{f.normal_force_N, f.tangential_force_N, f.mu};
    if (f.displacement_control) {
        load.tangential = mechanics::TangentialControl::displacement;
        load.tangential_displacement_mm = f.travel_mm;
    }
    return load;
}

render::CameraParams camera_params(const Spec& spec) {
    const Spec::Sensor& s = spec.sensor;
    render::CameraParams c;
    c.width_px = spec.render.width_px;
    c.height_px = spec.render.height_px;
    c.half_fov_deg = s.camera_half_fov_deg;
    if (s.camera_model == "kannala_brandt") {
        // A spec value of 0 stands for the equidistant camera's value (spec_schema.cpp).
        const render::CameraParams equidistant = render::with_equidistant_intrinsics(c);
        const auto or_derived = [](double given, double derived) {
            return given != 0.0 ? given : derived;
        };
        c.model = render::CameraModel::kannala_brandt;
        c.fx_px = or_derived(s.camera_fx_px, equidistant.fx_px);
        c.fy_px = or_derived(s.camera_fy_px, equidistant.fy_px);
        c.cx_px = or_derived(s.camera_cx_px, equidistant.cx_px);
        c.cy_px = or_derived(s.camera_cy_px, equidistant.cy_px);
        c.k1 = s.camera_k1, c.k2 = s.camera_k2, c.k3 = s.camera_k3, c.k4 = s.camera_k4;
    }
    c.position_mm = {s.camera_position_mm[0], s.camera_position_mm[1], s.camera_position_mm[2]};
    c.roll_deg = s.camera_roll_deg;
    c.pitch_deg = s.camera_pitch_deg;
    c.yaw_deg = s.camera_yaw_deg;
    return c;
}

render::OpticsParams optics_params(const Spec& spec) {
    render::OpticsParams o;
    o.coating_albedo = vec(spec.sensor.coating_albedo);
    o.inner_marker_absorption_per_mm = vec(spec.sensor.inner_marker_absorption_per_mm);
    o.outer_marker_absorption_per_mm = vec(spec.sensor.outer_marker_absorption_per_mm);
    o.outer_marker_albedo = vec(spec.sensor.outer_marker_albedo);
    o.outer_marker_scatter_fraction = spec.sensor.outer_marker_scatter_fraction;
    o.led_count = spec.sensor.led_count;
    o.led_ring_radius_mm = spec.sensor.led_ring_radius_mm;
    o.led_z_mm = spec.sensor.led_z_mm;
    o.led_width_mm = spec.sensor.led_width_mm;
    o.led_height_mm = spec.sensor.led_height_mm;
    o.refractive_index = spec.sensor.refractive_index;
    o.frame_inner_radius_mm = mechanics::DomeParams{}.radii_mm[0];
    o.lens_radius_mm = spec.sensor.lens_radius_mm;
    o.led_rgb = vec(spec.sensor.led_rgb);
    o.exposure = spec.render.exposure;
    if (spec.render.spectral)
        o.spectra = render::load_sensor_spectra(
            render::SensorSpectraFiles::in_directory(spectra_directory(spec)));
    return o;
}

render::OpticsParams rgb_optics(const render::OpticsParams& optics, double path_mm) {
    if (!optics.spectra) return optics;
    const render::SensorSpectra& sp = *optics.spectra;
    render::OpticsParams rgb = optics;
    rgb.spectra.reset();
    rgb.coating_albedo = render::rgb_of_reflectance(sp.camera, sp.coating_albedo).matrix();
    rgb.outer_marker_albedo =
        render::rgb_of_reflectance(sp.camera, sp.outer_marker_albedo).matrix();
    rgb.inner_marker_absorption_per_mm =
        render::rgb_absorption_per_mm(sp.camera, sp.inner_marker_absorption_per_mm, path_mm)
            .matrix();
    rgb.outer_marker_absorption_per_mm =
        render::rgb_absorption_per_mm(sp.camera, sp.outer_marker_absorption_per_mm, path_mm)
            .matrix();
    return rgb;
}

double median_marker_thickness_mm(const mechanics::DomeModel& model) {
    std::vector<double> thickness = model.markers().thickness_mm;
    const auto middle = thickness.begin() + std::ptrdiff_t(thickness.size() / 2);
    std::nth_element(thickness.begin(), middle, thickness.end());
    return *middle;
}

render::RenderSettings render_settings(const Spec& spec) {
    render::RenderSettings s;
    s.samples_per_pixel = spec.render.samples_per_pixel;
    s.seed = spec.seed;
    s.marker_ids = spec.outputs.marker_ids;
    s.variance = spec.outputs.variance;
    s.integrator = spec.render.integrator == "path"   ? render::Integrator::path
                   : spec.render.integrator == "fast" ? render::Integrator::fast
                                                      : render::Integrator::direct;
    s.shadow_filter_px = spec.render.fast.shadow_filter_px;
    s.shadow_filter_rim_px = spec.render.fast.shadow_filter_rim_px;
    s.reflection_samples_per_pixel = spec.render.fast.reflection_samples_per_pixel;
    s.edge_samples_per_pixel = spec.render.fast.edge_samples_per_pixel;
    s.reflected_led_samples_per_pixel = spec.render.fast.reflected_led_samples_per_pixel;
    s.shadow_rays_per_pixel = spec.render.fast.shadow_rays_per_pixel;
    const std::string& lanes = spec.render.fast.wavelengths_per_sample; // auto | 8 | 16
    s.fast_wavelengths = lanes == "auto" ? 0 : std::stoi(lanes);
    return s;
}

render::LightCacheSettings light_cache_settings(const Spec& spec) {
    render::LightCacheSettings s;
    s.paths_per_vertex = spec.render.fast.paths_per_vertex;
    s.direct_samples = spec.render.fast.direct_samples;
    s.smoothing_mm = spec.render.fast.smoothing_mm;
    s.refresh_direct = spec.render.fast.refresh_direct;
    s.refresh_threshold = spec.render.fast.refresh_threshold;
    s.scale_indirect = spec.render.fast.scale_indirect;
    return s;
}

render::SensorParams sensor_params(const Spec& spec) {
    const Spec::Render::Sensor& in = spec.render.sensor;
    render::SensorParams p;
    p.seed = in.seed;
    p.gain = in.gain;
    p.full_well_e = in.full_well_e;
    p.read_noise_e = in.read_noise_e;
    p.adc_bits = in.adc_bits;
    p.shot_noise = in.shot_noise;
    p.vignetting = in.vignetting == "none"   ? render::Vignetting::none
                   : in.vignetting == "cos4" ? render::Vignetting::cos4
                                             : render::Vignetting::polynomial;
    p.vignetting_k1 = in.vignetting_k1;
    p.vignetting_k2 = in.vignetting_k2;
    return p;
}

render::SensorFrame undeformed_sensor_frame(const mechanics::DomeModel& model) {
    mechanics::FrameResult rest;
    rest.coating_displacement_mm =
        mechanics::Points::Zero(Eigen::Index(model.coating_surface().nodes.size()), 3);
    rest.inner_surface_displacement_mm =
        mechanics::Points::Zero(Eigen::Index(model.inner_surface().nodes.size()), 3);
    rest.marker_points_mm = model.markers().points;
    render::SensorFrame frame;
    fill_sensor_frame(model, rest, frame);
    return frame;
}

void fill_sensor_frame(const mechanics::DomeModel& model, const mechanics::FrameResult& frame,
                       render::SensorFrame& out) {
    if (frame.coating_displacement_mm.rows() == 0 || frame.marker_points_mm.rows() == 0)
        throw std::logic_error("fill_sensor_frame: frame solved without displacement fields");
    const mechanics::SurfacePatch& coating = model.coating_surface();
    const mechanics::TetMesh& mesh = model.mesh();
    out.coating.V.resize(Eigen::Index(coating.nodes.size()), 3);
    for (std::size_t i = 0; i < coating.nodes.size(); ++i) {
        const int n = coating.nodes[i];
        out.coating.V.row(Eigen::Index(i)) =
            (mesh.V.row(n) + frame.coating_displacement_mm.row(Eigen::Index(i))).cast<float>();
    }
    if (out.coating.F.rows() != coating.F.rows()) out.coating.F = coating.F.cast<std::uint32_t>();
    const mechanics::SurfacePatch& inner = model.inner_surface();
    if (frame.inner_surface_displacement_mm.rows() == Eigen::Index(inner.nodes.size())) {
        out.inner_surface.V.resize(Eigen::Index(inner.nodes.size()), 3);
        for (std::size_t i = 0; i < inner.nodes.size(); ++i) {
            const int n = inner.nodes[i];
            out.inner_surface.V.row(Eigen::Index(i)) =
                (mesh.V.row(n) + frame.inner_surface_displacement_mm.row(Eigen::Index(i)))
                    .cast<float>();
        }
        if (out.inner_surface.F.rows() != inner.F.rows())
            out.inner_surface.F = inner.F.cast<std::uint32_t>();
    } else {
        out.inner_surface = {};
    }
    const mechanics::MarkerDiscs& discs = model.markers();
    fill_prisms(frame.marker_points_mm, discs, 0, out.inner_markers);
    fill_prisms(frame.marker_points_mm, discs, 1, out.outer_markers);
    out.triangles_per_marker = kPrismTriangles * discs.rim_points;
}

} // namespace chromasim::generators
