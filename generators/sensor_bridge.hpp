#pragma once
/// Where mechanics and render meet: translates a spec into each stage's parameters and a
/// mechanics frame into the plain SensorFrame that render takes. Render never sees mechanics.
#include "generators/plan.hpp"
#include "generators/spec.hpp"
#include "mechanics/dome_model.hpp"
#include "render/scene_data.hpp"
#include "render/sensor_model.hpp"

namespace chromasim::generators {

mechanics::DomeModelOptions dome_options(const Spec& spec);
/// The mechanics' shape of `object` (one of spec.objects, posed as a finger sees it); `spec`
/// resolves its mesh file's path.
mechanics::ObjectShape object_shape(const Spec& spec, const Spec::Object& object);
render::CameraParams camera_params(const Spec& spec);
/// The load of one fingertip in a planned frame: its grip force, mu and pull (a force, or the
/// object's travel under displacement control).
mechanics::ContactLoad contact_load(const FingerLoad& f);
render::OpticsParams optics_params(const Spec& spec);
/// `optics` in RGB mode: with spectra, the coating and marker colours the camera sees under
/// the LEDs (albedos, and the markers' absorption over a path of `marker_path_mm`, the
/// markers' median thickness), the spectra dropped; without, `optics` unchanged.
render::OpticsParams rgb_optics(const render::OpticsParams& optics, double marker_path_mm);
/// The median face-to-face thickness of `model`'s marker discs as built (mm): the path at which
/// rgb_optics reduces the markers' absorption spectra.
double median_marker_thickness_mm(const mechanics::DomeModel& model);
/// samples per pixel, seed, extra channels and integrator of the spec.
render::RenderSettings render_settings(const Spec& spec);
/// The fast integrator's light cache settings (render.fast.*).
render::LightCacheSettings light_cache_settings(const Spec& spec);
/// The camera sensor model's parameters of render.sensor (used only when it is enabled).
render::SensorParams sensor_params(const Spec& spec);

/// The sensor at rest: coating, inner surface (if the dome has one) and markers undeformed.
render::SensorFrame undeformed_sensor_frame(const mechanics::DomeModel& model);

/// Fills `out` with the deformed coating and marker discs of `frame`, which must carry the coating
/// displacement and marker points, and with the inner surface when the frame carries its
/// displacement (else it is left empty). Reuses `out`'s buffers (same sizes every frame).
void fill_sensor_frame(const mechanics::DomeModel& model, const mechanics::FrameResult& frame,
                       render::SensorFrame& out);

} // namespace chromasim::generators
