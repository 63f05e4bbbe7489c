// The spec's sections as each stage's parameter structs (mechanics, camera, optics, render).
#include "generators/spec/stage_params.hpp"

#include "generators/io/gltf_io.hpp"
#include "render/fisheye_camera.hpp"

#include <algorithm>
#include <sstream>
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
} // namespace

std::vector<double> led_gains(const Spec& spec) {
    const std::vector<double>& g = spec.sensor.led_gains;
    if (g.size() == 1) return std::vector<double>(std::size_t(spec.sensor.led_count), g[0]);
    return g;
}

mechanics::DomeModelOptions dome_options(const Spec& spec) {
    mechanics::DomeModelOptions o;
    o.mesh_level = spec.sensor.mesh_level;
    o.element_order = spec.sensor.element_order;
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
    o.dome.marker_radius_mm = spec.sensor.marker_radius_mm;
    o.dome.marker_jitter_mm = spec.sensor.marker_jitter_mm;
    o.dome.marker_jitter_seed =
        spec.seed * 0x9E3779B97F4A7C15ull + std::uint64_t(spec.sensor.variant + 1);
    return o;
}

/// Side of the plate that stands for a tilted flat, mm: wider than the dome (26.4 mm).
constexpr double kTiltedPlate_mm = 80.0;

ObjectSource object_source(const Spec& spec, const Spec::Object& object) {
    ObjectSource source{object, std::nullopt};
    if (object.shape == "mesh")
        source.mesh = load_gltf_surface(resolve_spec_path(spec, object.mesh_file));
    return source;
}

mechanics::ObjectShape object_shape(const ObjectSource& source, const Spec::Object& object) {
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
        o.mesh = std::make_shared<mechanics::MeshHeightField>(source.mesh.value(), pose);
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

mechanics::ObjectShape object_shape(const Spec& spec, const Spec::Object& object) {
    return object_shape(object_source(spec, object), object);
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

namespace {
void scale(render::Spectrum& s, double factor) {
    for (double& v : s.values)
        v *= factor;
}
} // namespace

render::OpticsParams optics_params(const Spec& spec) {
    const Spec::Sensor& c = spec.sensor;
    render::OpticsParams o;
    o.coating_albedo = vec(c.coating_albedo) * c.coating_albedo_scale;
    o.inner_marker_absorption_per_mm =
        vec(c.inner_marker_absorption_per_mm) * c.inner_marker_absorption_scale;
    o.outer_marker_absorption_per_mm =
        vec(c.outer_marker_absorption_per_mm) * c.outer_marker_absorption_scale;
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
    o.led_gain = led_gains(spec);
    o.exposure = spec.render.exposure;
    if (spec.render.spectral) {
        o.spectra = render::load_sensor_spectra(
            render::SensorSpectraFiles::in_directory(spectra_directory(spec)));
        scale(o.spectra->coating_albedo, c.coating_albedo_scale);
        scale(o.spectra->inner_marker_absorption_per_mm, c.inner_marker_absorption_scale);
        scale(o.spectra->outer_marker_absorption_per_mm, c.outer_marker_absorption_scale);
    }
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

render::Integrator integrator_of(const std::string& name) {
    return name == "path"   ? render::Integrator::path
           : name == "fast" ? render::Integrator::fast
                            : render::Integrator::preview;
}

const std::vector<QualityPreset>& quality_presets() {
    static const std::vector<QualityPreset> presets{
        {"draft", 0, 0, 16, 0, 0, 0.5},
        {"default", 6, 4, 32, 0, 0, 0.5},
        {"high", 12, 8, 64, 2, 16, 0.5},
    };
    return presets;
}

std::vector<std::string> quality_names() {
    std::vector<std::string> names;
    for (const QualityPreset& p : quality_presets())
        names.emplace_back(p.name);
    return names;
}

const QualityPreset& quality_preset(const std::string& name) {
    for (const QualityPreset& p : quality_presets())
        if (name == p.name) return p;
    throw std::invalid_argument("render.quality '" + name + "' is not draft, default or high");
}

std::string quality_presets_markdown() {
    std::ostringstream out;
    out << "| render.quality | rim samples | mirrored-LED pixels' samples | LED rays there | "
           "shadow rays a sample | wavelengths a sample | rim filter, px |\n"
           "|---|---|---|---|---|---|---|\n";
    for (const QualityPreset& p : quality_presets()) {
        out << "| `" << p.name << "` | " << p.rim_samples_per_pixel << " | "
            << p.reflection_samples_per_pixel << " | " << p.reflected_led_samples_per_pixel << " | "
            << std::max(p.shadow_rays_per_sample, 1) << " | "
            << (p.wavelengths_per_sample ? std::to_string(p.wavelengths_per_sample)
                                         : std::string("16 at 1 spp, else 8"))
            << " | " << p.shadow_filter_rim_px << " |\n";
    }
    return out.str();
}

render::RenderSettings render_settings(const Spec& spec) {
    render::RenderSettings s;
    s.samples_per_pixel = spec.render.samples_per_pixel;
    s.seed = spec.seed;
    s.marker_ids = spec.outputs.marker_ids;
    s.variance = spec.outputs.variance;
    s.integrator = integrator_of(spec.render.integrator);
    s.shadow_filter_px = spec.render.fast.shadow_filter_px;
    const QualityPreset& q = quality_preset(spec.render.quality);
    s.shadow_filter_rim_px = q.shadow_filter_rim_px;
    s.reflection_samples_per_pixel = q.reflection_samples_per_pixel;
    s.rim_samples_per_pixel = q.rim_samples_per_pixel;
    s.reflected_led_samples_per_pixel = q.reflected_led_samples_per_pixel;
    s.shadow_rays_per_pixel = q.shadow_rays_per_sample * s.samples_per_pixel;
    s.fast_wavelengths = q.wavelengths_per_sample;
    return s;
}

render::LightCacheSettings light_cache_settings(const Spec& spec) {
    render::LightCacheSettings s;
    s.paths_per_vertex = spec.render.fast.paths_per_vertex;
    s.refresh_threshold = spec.render.fast.refresh_threshold;
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

StageSettings stage_settings(const Spec& spec) {
    StageSettings s;
    s.dome = dome_options(spec);
    for (const Spec::Object& object : spec.objects)
        s.objects.push_back(object_source(spec, object));
    for (const Spec::Friction& friction : spec.friction)
        s.friction_names.push_back(friction.name);
    s.camera = camera_params(spec);
    if (spec.outputs.images || spec.outputs.exr) s.optics = optics_params(spec);
    s.render = render_settings(spec);
    s.light_cache = light_cache_settings(spec);
    if (spec.outputs.images && spec.render.sensor.enabled) s.sensor = sensor_params(spec);
    s.outputs = spec.outputs;
    return s;
}

} // namespace chromasim::generators
