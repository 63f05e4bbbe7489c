#pragma once
/// The spec's sections as each stage's parameters: the mechanics' dome and objects, the
/// camera, the optics and the render settings. Plain translation, no work beyond reading the
/// files the spec names (object meshes, spectra).
#include "generators/spec/spec.hpp"
#include "mechanics/dome_model.hpp"
#include "render/scene_data.hpp"
#include "render/sensor_model.hpp"

#include <optional>
#include <string>
#include <vector>

namespace chromasim::generators {

mechanics::DomeModelOptions dome_options(const Spec& spec);
/// One of spec.objects with its mesh file read (mesh objects only), so that posing it for every
/// fingertip of every trial reads no file.
struct ObjectSource {
    Spec::Object object;
    std::optional<mechanics::TriangleSurface> mesh;
};
/// `object`'s source; `spec` resolves its mesh file's path.
ObjectSource object_source(const Spec& spec, const Spec::Object& object);
/// The mechanics' shape of `source`, posed as `posed` says (its offset, roll, pitch and yaw).
mechanics::ObjectShape object_shape(const ObjectSource& source, const Spec::Object& posed);
/// The mechanics' shape of `object` as it stands, its mesh file read now.
mechanics::ObjectShape object_shape(const Spec& spec, const Spec::Object& object);
render::CameraParams camera_params(const Spec& spec);
/// sensor.led.gains, one per LED (one number repeated).
std::vector<double> led_gains(const Spec& spec);
render::OpticsParams optics_params(const Spec& spec);
/// `optics` in RGB mode: with spectra, the coating and marker colours the camera sees under
/// the LEDs (albedos, and the markers' absorption over a path of `marker_path_mm`, the
/// markers' median thickness), the spectra dropped; without, `optics` unchanged.
render::OpticsParams rgb_optics(const render::OpticsParams& optics, double marker_path_mm);
/// The integrator a render.integrator value names (preview, path or fast; anything else:
/// preview).
render::Integrator integrator_of(const std::string& name);
/// One render.quality preset: the fast integrator's sample counts for its costly pixels
/// (render::RenderSettings has what each count does). A count at most samples_per_pixel
/// adds nothing.
struct QualityPreset {
    const char* name;
    int rim_samples_per_pixel;           ///< on the markers' rims
    int reflection_samples_per_pixel;    ///< where the inner surface mirrors an LED
    int reflected_led_samples_per_pixel; ///< rays for the mirrored LEDs, in those pixels
    int shadow_rays_per_sample;          ///< 0: one a sample; n: n * samples_per_pixel a pixel
    int wavelengths_per_sample;          ///< 0: 16 at 1 sample per pixel, else 8
    double shadow_filter_rim_px;         ///< the shadow filter on the rims
};
/// draft, default and high, in that order.
const std::vector<QualityPreset>& quality_presets();
/// The presets' names, in that order (render.quality's choices).
std::vector<std::string> quality_names();
/// The preset a render.quality value names (the spec's choice list guarantees one).
const QualityPreset& quality_preset(const std::string& name);
/// The presets as a Markdown table, for docs/SPEC.md.
std::string quality_presets_markdown();

/// samples per pixel, seed, extra channels, integrator and render.quality of the spec.
render::RenderSettings render_settings(const Spec& spec);
/// The fast integrator's light cache settings (render.fast.*).
render::LightCacheSettings light_cache_settings(const Spec& spec);
/// The camera sensor model's parameters of render.sensor (used only when it is enabled).
render::SensorParams sensor_params(const Spec& spec);

/// The spec resolved once into what each stage reads, so that the stages get their own
/// settings and never the spec. Only what the outputs need is read: no optics (and no spectra)
/// without images, no sensor model without PNGs through render.sensor.
struct StageSettings {
    mechanics::DomeModelOptions dome;        ///< without a cache folder
    std::vector<ObjectSource> objects;       ///< spec.objects, in order
    std::vector<std::string> friction_names; ///< spec.friction's names, in order (labels)
    render::CameraParams camera;
    std::optional<render::OpticsParams> optics; ///< with outputs.images or outputs.exr
    render::RenderSettings render;
    render::LightCacheSettings light_cache;
    std::optional<render::SensorParams> sensor; ///< with outputs.images and render.sensor
    Spec::Outputs outputs;
};
/// Reads the files the spec names that the outputs need (object meshes; spectra when it
/// renders); their errors name the file.
StageSettings stage_settings(const Spec& spec);

} // namespace chromasim::generators
