#pragma once
/// Where mechanics and render meet: a planned frame's load for the mechanics, and a mechanics
/// frame as the plain SensorFrame that render takes. Render never sees mechanics.
#include "generators/plan/plan.hpp"
#include "generators/spec/stage_params.hpp"
#include "mechanics/dome_model.hpp"
#include "render/scene_data.hpp"

namespace chromasim::generators {

/// The load of one fingertip in a planned frame: its grip force, mu and pull (a force, or the
/// object's travel under displacement control).
mechanics::ContactLoad contact_load(const FingerLoad& f);
/// The median face-to-face thickness of `model`'s marker discs as built (mm): the path at which
/// rgb_optics reduces the markers' absorption spectra.
double median_marker_thickness_mm(const mechanics::DomeModel& model);

/// The sensor at rest: coating, inner surface (if the dome has one) and markers undeformed.
render::SensorFrame undeformed_sensor_frame(const mechanics::DomeModel& model);

/// Fills `out` with the deformed coating and marker discs of `frame`, which must carry the coating
/// displacement and marker points, and with the inner surface when the frame carries its
/// displacement (else it is left empty). Reuses `out`'s buffers (same sizes every frame).
void fill_sensor_frame(const mechanics::DomeModel& model, const mechanics::FrameResult& frame,
                       render::SensorFrame& out);

} // namespace chromasim::generators
