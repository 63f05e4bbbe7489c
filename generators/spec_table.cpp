// The spec's table: every key's schema entry (type, default, unit, range, doc line, field),
// the lists of mappings and the cross-key rules. spec_schema.cpp owns the singletons and the
// machinery that reads, checks and prints values; this file only says what the keys are.
#include "generators/spec_table.hpp"

#include "generators/sensor_bridge.hpp"

#include "render/fisheye_camera.hpp"
#include "render/sensor_model.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <type_traits>

namespace chromasim::generators::detail {
namespace { // internal linkage: these names are common

/// The longest trial a spec may plan, frames.
constexpr double kMaxTrialFrames = 1e6;

// ---- Storing values into fields and reading them back ---------------------------------------

/// Stores a validated value; integers travel as int64_t and narrow to the field's type (the
/// schema range guarantees they fit).
template <class T> void assign(T& field, const SpecValue& v) {
    if constexpr (std::is_integral_v<T> && !std::is_same_v<T, bool>) {
        field = static_cast<T>(std::get<std::int64_t>(v));
    } else {
        field = std::get<T>(v);
    }
}

template <class T> SpecValue to_value(const T& x) {
    if constexpr (std::is_integral_v<T> && !std::is_same_v<T, bool>) {
        return static_cast<std::int64_t>(x);
    } else {
        return x;
    }
}

// ---- Building entries -----------------------------------------------------------------------

/// `access` is a generic lambda `(auto& spec) -> auto&` naming the field, so one expression
/// serves both the setter (Spec&) and the getter (const Spec&).
template <class Access>
SchemaEntry make_entry(std::string key, ValueType type, SpecValue def, std::string unit,
                       Range range, std::string doc, Access access) {
    SchemaEntry e;
    e.key = std::move(key);
    e.type = type;
    e.default_value = std::move(def);
    e.unit = std::move(unit);
    e.range = range;
    e.doc = std::move(doc);
    if constexpr (std::is_invocable_v<Access, Spec&, std::size_t>) {
        e.set = [access](Spec& s, std::size_t i, const SpecValue& v) { assign(access(s, i), v); };
        e.get = [access](const Spec& s, std::size_t i) { return to_value(access(s, i)); };
    } else {
        e.set = [access](Spec& s, std::size_t, const SpecValue& v) { assign(access(s), v); };
        e.get = [access](const Spec& s, std::size_t) { return to_value(access(s)); };
    }
    return e;
}

Range closed(double lo, double hi) {
    return {lo, hi, true, true};
}
Range left_open(double lo, double hi) {
    return {lo, hi, false, true};
}

template <class Access>
SchemaEntry number(std::string key, double def, Range range, std::string unit, std::string doc,
                   Access access) {
    return make_entry(std::move(key), ValueType::Number, def, std::move(unit), range,
                      std::move(doc), access);
}

template <class Access>
SchemaEntry integer(std::string key, std::int64_t def, Range range, std::string unit,
                    std::string doc, Access access) {
    return make_entry(std::move(key), ValueType::Integer, def, std::move(unit), range,
                      std::move(doc), access);
}

template <class Access> SchemaEntry boolean(std::string key, bool def, std::string doc, Access a) {
    return make_entry(std::move(key), ValueType::Bool, def, "", Range{}, std::move(doc), a);
}

template <class Access>
SchemaEntry choice(std::string key, std::string def, std::vector<std::string> choices,
                   std::string doc, Access access) {
    SchemaEntry e = make_entry(std::move(key), ValueType::Enum, std::move(def), "", Range{},
                               std::move(doc), access);
    e.choices = std::move(choices);
    return e;
}

template <class Access>
SchemaEntry text(std::string key, std::string def, std::string doc, Access access) {
    return make_entry(std::move(key), ValueType::String, std::move(def), "", Range{},
                      std::move(doc), access);
}

template <class Access>
SchemaEntry rgb(std::string key, Rgb def, Range range, std::string unit, std::string doc,
                Access access) {
    return make_entry(std::move(key), ValueType::Rgb, def, std::move(unit), range, std::move(doc),
                      access);
}

template <class Access>
SchemaEntry factor(std::string key, Factor def, Range range, std::string unit, std::string doc,
                   Access access) {
    return make_entry(std::move(key), ValueType::Factor, std::move(def), std::move(unit), range,
                      std::move(doc), access);
}

template <class Access>
SchemaEntry vec3(std::string key, Rgb def, Range range, std::string unit, std::string doc,
                 Access access) {
    return make_entry(std::move(key), ValueType::Vec3, def, std::move(unit), range, std::move(doc),
                      access);
}

// ---- The table ------------------------------------------------------------------------------

// The accessor of one Spec field, for both Spec& and const Spec& (see make_entry).
// clang-format off
#define CHROMASIM_FIELD(member) [](auto& s) -> auto& { return s.member; }
// The accessor of a field of item i of a list of the Spec.
#define CHROMASIM_ITEM(list, member) [](auto& s, std::size_t i) -> auto& { return s.list[i].member; }
// clang-format on

/// "inner_marker_layer" -> "inner marker layer".
std::string words(std::string key) {
    std::replace(key.begin(), key.end(), '_', ' ');
    return key;
}

/// The E and nu entries of one layer; `what` describes the material for the doc line.
template <class Access>
void add_layer(std::vector<SchemaEntry>& out, const std::string& layer, double E_MPa,
               const std::string& what, Access layer_access) {
    const std::string key = "sensor.materials." + layer;
    out.push_back(number(
        key + ".E_MPa", E_MPa, left_open(0, 1000), "MPa",
        "Young's modulus of the " + what + " [G].", [layer_access](auto& s) -> auto& {
            return layer_access(s).E_MPa;
        }));
    out.push_back(number(
        key + ".nu", 0.45, closed(0, 0.4999), "",
        "Poisson's ratio of the " + words(layer) + " (nearly incompressible: 0.45 to 0.49) [G].",
        [layer_access](auto& s) -> auto& { return layer_access(s).nu; }));
}

void add_general(std::vector<SchemaEntry>& out) {
    out.push_back(text("name", "unnamed", "Dataset name.", CHROMASIM_FIELD(name)));
    out.push_back(integer("seed", 1, closed(0, 2147483647), "",
                          "Seed of every random draw made for the dataset.",
                          CHROMASIM_FIELD(seed)));
}

void add_sensor_mechanics(std::vector<SchemaEntry>& out) {
    out.push_back(choice("sensor.mesh_level", "coarse",
                         {"coarse", "medium", "fine", "refined", "reference"},
                         "TetGen mesh level of the dome: uniform coarse (1.2 mm, the fastest), "
                         "medium (0.8 mm), fine (0.5 mm), or refined where contact happens: "
                         "refined (0.5 mm within 40 deg of the apex, 1.2 mm far), reference "
                         "(0.3 mm, 0.8 mm far).",
                         CHROMASIM_FIELD(sensor.mesh_level)));
    add_layer(out, "inner_marker_layer", 0.8,
              "inner marker layer (printed flexible clear resin, Agilus30-like: 0.6 to 1.0 MPa)",
              CHROMASIM_FIELD(sensor.inner_marker_layer));
    add_layer(out, "clear_layer", 0.3,
              "clear layer between the marker arrays (SortaClear 12A: 0.2 to 0.4 MPa)",
              CHROMASIM_FIELD(sensor.clear_layer));
    add_layer(out, "outer_marker_layer", 0.8,
              "outer marker layer (printed flexible clear resin, Agilus30-like: 0.6 to 1.0 MPa)",
              CHROMASIM_FIELD(sensor.outer_marker_layer));
    add_layer(out, "coating", 1.0, "white diffusing coating (pigmented silicone: about 1 MPa)",
              CHROMASIM_FIELD(sensor.coating));
    add_layer(out, "fill", 0.05,
              "soft fill inside the dome (clear silicone gel, used only when sensor.interior "
              "is soft_fill: about 0.02 to 0.1 MPa)",
              CHROMASIM_FIELD(sensor.fill));
    out.push_back(choice("sensor.volumetric", "nodal_average", {"nodal_average", "element"},
                         "How the volumetric strain energy is integrated: nodal_average (average "
                         "nodal pressure, no locking of nearly incompressible layers) or element "
                         "(standard linear tets: too stiff as nu approaches 0.5; faster).",
                         CHROMASIM_FIELD(sensor.volumetric)));
    out.push_back(choice("sensor.interior", "hollow", {"hollow", "rigid_core", "soft_fill"},
                         "Inside the inner layer: hollow (air; camera and LEDs sit there), a "
                         "rigid core bonded to the inner surface (a stiffer fingertip), or "
                         "soft_fill (a meshed gel of sensor.materials.fill bonded to the inner "
                         "layer, clamped on the base plane; mechanics only, the renderer still "
                         "sees a hollow dome).",
                         CHROMASIM_FIELD(sensor.interior)));
    out.push_back(choice("sensor.material_model", "neo_hookean", {"linear", "neo_hookean"},
                         "Constitutive model of the layers: neo_hookean (compressible, large "
                         "deformation; about 50 ms a trial frame on the coarse mesh) or linear "
                         "(small strain, under 1 ms, but 17 to 32 % too stiff at 1 to 3.2 N).",
                         CHROMASIM_FIELD(sensor.material_model)));
    out.push_back(integer("sensor.contact_steps", 4, closed(1, 1000), "",
                          "Steps of the first frame's load path from rest: the grip force ramps "
                          "up in this many steps with friction on, then the tangential load.",
                          CHROMASIM_FIELD(sensor.contact_steps)));
    out.push_back(number("sensor.contact_candidate_angle_deg", 50, closed(5, 80), "deg",
                         "Polar angle of the outer-surface cap whose nodes may touch the object; "
                         "a frame whose contact reaches it is flagged.",
                         CHROMASIM_FIELD(sensor.contact_candidate_angle_deg)));
}

/// The sensor.camera keys after half_fov_deg: projection model, OpenCV intrinsics, pose.
void add_camera_model(std::vector<SchemaEntry>& out) {
    out.push_back(choice("sensor.camera.model", "equidistant", {"equidistant", "kannala_brandt"},
                         "Projection: equidistant (r = theta / half_fov_deg * min(width, height) "
                         "/ 2 px, the lens at the dome centre) or kannala_brandt (OpenCV's "
                         "cv::fisheye model, a user's calibration: fx_px ... k4; rays beyond "
                         "half_fov_deg stay black).",
                         CHROMASIM_FIELD(sensor.camera_model)));
    const std::string derived = " (OpenCV convention: pixel centres at integers); 0: derived "
                                "from the image size and half_fov_deg, as the equidistant camera.";
    out.push_back(number("sensor.camera.fx_px", 0, closed(0, 1e4), "px",
                         "Kannala-Brandt focal length along x, K(0, 0)" + derived,
                         CHROMASIM_FIELD(sensor.camera_fx_px)));
    out.push_back(number("sensor.camera.fy_px", 0, closed(0, 1e4), "px",
                         "Kannala-Brandt focal length along y, K(1, 1)" + derived,
                         CHROMASIM_FIELD(sensor.camera_fy_px)));
    out.push_back(number("sensor.camera.cx_px", 0, closed(-1e4, 1e4), "px",
                         "Kannala-Brandt principal point x, K(0, 2)" + derived,
                         CHROMASIM_FIELD(sensor.camera_cx_px)));
    out.push_back(number("sensor.camera.cy_px", 0, closed(-1e4, 1e4), "px",
                         "Kannala-Brandt principal point y, K(1, 2)" + derived,
                         CHROMASIM_FIELD(sensor.camera_cy_px)));
    const auto k = [&out](const std::string& name, int index, auto access) {
        out.push_back(number("sensor.camera." + name, 0, closed(-100, 100), "",
                             "Kannala-Brandt distortion D[" + std::to_string(index) +
                                 "]: theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 "
                                 "+ k4 theta^8), theta in rad.",
                             access));
    };
    k("k1", 0, CHROMASIM_FIELD(sensor.camera_k1));
    k("k2", 1, CHROMASIM_FIELD(sensor.camera_k2));
    k("k3", 2, CHROMASIM_FIELD(sensor.camera_k3));
    k("k4", 3, CHROMASIM_FIELD(sensor.camera_k4));
    out.push_back(vec3("sensor.camera.position_mm", {0.0, 0.0, 0.0}, closed(-10, 10), "mm",
                       "Camera position in the dome frame (origin: the dome centre; the inner "
                       "surface has radius 10.5 mm), both models.",
                       CHROMASIM_FIELD(sensor.camera_position_mm)));
    out.push_back(number("sensor.camera.roll_deg", 0, closed(-180, 180), "deg",
                         "Camera rotation about the dome's x axis (applied first; 0, 0, 0: "
                         "looking along +z, image x along +x).",
                         CHROMASIM_FIELD(sensor.camera_roll_deg)));
    out.push_back(number("sensor.camera.pitch_deg", 0, closed(-180, 180), "deg",
                         "Camera rotation about the dome's y axis (applied second).",
                         CHROMASIM_FIELD(sensor.camera_pitch_deg)));
    out.push_back(number("sensor.camera.yaw_deg", 0, closed(-180, 180), "deg",
                         "Camera rotation about the dome's z axis (applied last).",
                         CHROMASIM_FIELD(sensor.camera_yaw_deg)));
}

void add_sensor_optics(std::vector<SchemaEntry>& out) {
    out.push_back(number("sensor.camera.half_fov_deg", 84, left_open(10, 100), "deg",
                         "Half field of view: the polar angle at the image-circle edge "
                         "(equidistant) or of the imaged field (kannala_brandt).",
                         CHROMASIM_FIELD(sensor.camera_half_fov_deg)));
    add_camera_model(out);
    out.push_back(
        number("sensor.camera.lens_radius_mm", 8, closed(0, 10.5), "mm",
               "Radius of the camera's lens barrel, a black cylinder from the rim plane "
               "down (FUSE CAD [K]; 0: none); it hides LEDs below the rim from most of the dome.",
               CHROMASIM_FIELD(sensor.lens_radius_mm)));
    out.push_back(integer("sensor.led.count", 6, closed(1, 64), "",
                          "Number of LEDs on the ring (6 on the real board).",
                          CHROMASIM_FIELD(sensor.led_count)));
    out.push_back(number("sensor.led.ring_radius_mm", 10, closed(0, 13), "mm",
                         "Radius of the LED ring around the lens (FUSE CAD [K]: 10.0 to 10.2 mm).",
                         CHROMASIM_FIELD(sensor.led_ring_radius_mm)));
    out.push_back(number("sensor.led.z_mm", -13.8, closed(-20, 10), "mm",
                         "Height of the LEDs' emitting faces; the dome rim plane is z = 0 (FUSE "
                         "CAD [K]: 13.8 mm below it).",
                         CHROMASIM_FIELD(sensor.led_z_mm)));
    out.push_back(number("sensor.led.width_mm", 3.5, closed(0.01, 10), "mm",
                         "Side of each LED's emitting rectangle along the ring (SMD 3528 package "
                         "[K]); render.integrator path only.",
                         CHROMASIM_FIELD(sensor.led_width_mm)));
    out.push_back(number("sensor.led.height_mm", 2.8, closed(0.01, 10), "mm",
                         "Side of each LED's emitting rectangle across the ring (radial) [K]; "
                         "render.integrator path only.",
                         CHROMASIM_FIELD(sensor.led_height_mm)));
    out.push_back(rgb("sensor.led.rgb", {1.0, 1.0, 1.0}, closed(0, 100), "",
                      "Relative emission of each LED, linear RGB (white) [G]; spectral mode: "
                      "their mean scales the LED spectrum.",
                      CHROMASIM_FIELD(sensor.led_rgb)));
    out.push_back(number("sensor.optics.marker_thickness_mm", 0.5, left_open(0, 0.5), "mm",
                         "Thickness of the marker discs [K]: closed volumes deformed with the "
                         "mesh, at most 98 % of their layer's 0.5 mm; light is absorbed over "
                         "its path inside.",
                         CHROMASIM_FIELD(sensor.marker_thickness_mm)));
    out.push_back(number("sensor.optics.refractive_index", 1.4, closed(1, 2), "",
                         "Refractive index of the clear layers, index-matched among themselves "
                         "[G] (silicones and clear resins: 1.40 to 1.47); the path integrator "
                         "refracts at the hollow dome's inner surface (air inside); 1: no "
                         "refraction.",
                         CHROMASIM_FIELD(sensor.refractive_index)));
    out.push_back(rgb("sensor.optics.coating_albedo", {0.85, 0.85, 0.85}, closed(0, 1), "",
                      "Diffuse albedo of the white coating, linear RGB [G] (RGB mode only: "
                      "render.spectral false).",
                      CHROMASIM_FIELD(sensor.coating_albedo)));
    out.push_back(rgb("sensor.optics.inner_marker_absorption_per_mm", {0.2, 3.0, 0.3},
                      closed(0, 100), "1/mm",
                      "Absorption coefficient of the inner markers (magenta filter), RGB [G] "
                      "(RGB mode only).",
                      CHROMASIM_FIELD(sensor.inner_marker_absorption_per_mm)));
    out.push_back(rgb("sensor.optics.outer_marker_absorption_per_mm", {3.0, 0.3, 0.2},
                      closed(0, 100), "1/mm",
                      "Absorption coefficient of the outer markers (cyan), RGB [G] (RGB mode "
                      "only).",
                      CHROMASIM_FIELD(sensor.outer_marker_absorption_per_mm)));
    out.push_back(rgb("sensor.optics.outer_marker_albedo", {0.10, 0.70, 0.75}, closed(0, 1), "",
                      "Albedo of the outer markers (cyan), linear RGB [G] (RGB mode only).",
                      CHROMASIM_FIELD(sensor.outer_marker_albedo)));
    out.push_back(number("sensor.optics.outer_marker_scatter_fraction", 0.5, closed(0, 1), "",
                         "Fraction of the light at an outer marker that it scatters back; the "
                         "rest is filtered through it [G].",
                         CHROMASIM_FIELD(sensor.outer_marker_scatter_fraction)));
    out.push_back(text("sensor.optics.spectra_dir", "",
                       "Folder of the six spectrum CSVs of render.spectral (file names and "
                       "formats: assets/spectra/README.md); empty: the shipped assets/spectra; a "
                       "relative path starts at the spec file's folder.",
                       CHROMASIM_FIELD(sensor.spectra_dir)));
}

void add_objects(std::vector<SchemaEntry>& out) {
    out.push_back(text("objects[].name", "flat",
                       "Name of the object, written in labels.csv; unique in the list.",
                       CHROMASIM_ITEM(objects, name)));
    out.push_back(choice("objects[].shape", "flat", {"flat", "sphere", "mesh"},
                         "Shape of the rigid object: a plane, a sphere of radius radius_mm "
                         "centred on the dome axis, or the triangle mesh of mesh_file (its "
                         "underside touches).",
                         CHROMASIM_ITEM(objects, shape)));
    out.push_back(number("objects[].radius_mm", 45, left_open(0, 1e4), "mm",
                         "Sphere radius (seed 000's curved object: 45 mm); unused for a flat.",
                         CHROMASIM_ITEM(objects, radius_mm)));
    out.push_back(text("objects[].mesh_file", "",
                       "glTF 2.0 file (.gltf or .glb, metres) of a mesh object; a relative path "
                       "starts at the spec file's folder (assets/objects/ has a 45 mm sphere cap "
                       "and a 40 mm plate).",
                       CHROMASIM_ITEM(objects, mesh_file)));
    out.push_back(
        number("objects[].offset_x_mm", 0, closed(-20, 20), "mm",
               "Mesh: x of its frame's origin; sphere: x of its axis; flat: no effect (the left "
               "finger's frame; the right finger sees it mirrored, fingers section).",
               CHROMASIM_ITEM(objects, offset_x_mm)));
    out.push_back(number("objects[].offset_y_mm", 0, closed(-20, 20), "mm",
                         "Mesh: y of its frame's origin; sphere: y of its axis; flat: no effect.",
                         CHROMASIM_ITEM(objects, offset_y_mm)));
    out.push_back(number("objects[].roll_deg", 0, closed(-180, 180), "deg",
                         "Mesh or flat (tilts it): rotation about the sensor's x axis, applied "
                         "first; a sphere is unchanged.",
                         CHROMASIM_ITEM(objects, roll_deg)));
    out.push_back(
        number("objects[].pitch_deg", 0, closed(-180, 180), "deg",
               "Mesh or flat (tilts it): rotation about the sensor's y axis, applied second.",
               CHROMASIM_ITEM(objects, pitch_deg)));
    out.push_back(number(
        "objects[].yaw_deg", 0, closed(-180, 180), "deg",
        "Mesh: rotation about the sensor's z axis, applied last (a flat or sphere is unchanged).",
        CHROMASIM_ITEM(objects, yaw_deg)));
    out.push_back(text("friction[].name", "medium",
                       "Name of the friction condition (e.g. dry, water, soap), written in "
                       "labels.csv; unique in the list.",
                       CHROMASIM_ITEM(friction, name)));
    out.push_back(factor("friction[].mu", Factor{{0.8}}, closed(0, 10), "",
                         "Coulomb friction coefficient between coating and object: a value, a "
                         "list (one drawn per trial) or {min, max} (uniform per trial). Seed "
                         "001: 1.1, 0.8, 0.5 [G].",
                         CHROMASIM_ITEM(friction, mu)));
}

void add_fingers(std::vector<SchemaEntry>& out) {
    out.push_back(integer("fingers.count", 2, closed(1, 2), "",
                          "Fingertips: 1 (left only) or 2 (left and right squeeze the object "
                          "from opposite sides; each has the full grip force and carries half "
                          "the load; the right one sees the object rotated 180 deg about its "
                          "z axis: load direction + 180 deg, offsets negated, yaw + 180 deg).",
                          CHROMASIM_FIELD(fingers.count)));
    out.push_back(number("fingers.mu_jitter", 0, closed(0, 0.5), "",
                         "Per-finger difference in friction: each finger's mu is the trial's "
                         "mu times (1 + u), u uniform in [-mu_jitter, mu_jitter], drawn per "
                         "trial and finger [G].",
                         CHROMASIM_FIELD(fingers.mu_jitter)));
    out.push_back(number("fingers.offset_jitter_mm", 0, closed(0, 5), "mm",
                         "Per-finger difference in pose: the object's x and y offset in each "
                         "finger's frame moves by a uniform draw in [-j, j] per trial and finger "
                         "(no effect on a flat) [G].",
                         CHROMASIM_FIELD(fingers.offset_jitter_mm)));
}

void add_protocol(std::vector<SchemaEntry>& out) {
    out.push_back(choice("protocol.type", "grasp_load", {"grasp_load", "slide"},
                         "grasp_load (seed 000): grasp to the grip force, hold, then a "
                         "tangential load ramps at load_rate_N_per_s until target_load_N or "
                         "slip; slide (seed 001): grasp, hold, then the object slides under "
                         "displacement control from slide_start_mm to slide_end_mm.",
                         CHROMASIM_FIELD(protocol.type)));
    out.push_back(number("protocol.frame_rate_Hz", 100, left_open(0, 10000), "Hz",
                         "Frames per second of the grasp, hold and load phases (seed 000: 100 "
                         "Hz); the first frame is 1 / rate after first touch.",
                         CHROMASIM_FIELD(protocol.frame_rate_Hz)));
    out.push_back(factor("protocol.grip_N", Factor{{1.5}}, left_open(0, 50), "N",
                         "Grip (normal) force on each finger: a value, a list or {min, max} "
                         "(seed 000: 1.0 to 2.5 by 0.5).",
                         CHROMASIM_FIELD(protocol.grip_N)));
    out.push_back(number("protocol.grasp_s", 0.5, closed(0, 100), "s",
                         "Duration of the linear grip-force ramp from first touch (0: no grasp "
                         "frames; the first frame reaches its load from rest in "
                         "sensor.contact_steps steps).",
                         CHROMASIM_FIELD(protocol.grasp_s)));
    out.push_back(number("protocol.hold_s", 2, closed(0, 100), "s",
                         "Hold at the grip force before the load (seed 000: 2 s). Hold frames "
                         "are not re-solved: the previous frame's result is reused.",
                         CHROMASIM_FIELD(protocol.hold_s)));
    out.push_back(factor("protocol.load_rate_N_per_s", Factor{{1.0}}, left_open(0, 1000), "N/s",
                         "grasp_load: rate of the total tangential load, shared equally by the "
                         "fingers (seed 000: 0.5 or 1.0).",
                         CHROMASIM_FIELD(protocol.load_rate_N_per_s)));
    out.push_back(factor("protocol.target_load_N", Factor{{2.5}}, left_open(0, 100), "N",
                         "grasp_load: total tangential load at which the ramp (and the trial) "
                         "ends, shared equally by the fingers (seed 000: uniform in [2, 3]).",
                         CHROMASIM_FIELD(protocol.target_load_N)));
    out.push_back(number("protocol.load_direction_deg", 0, closed(-360, 360), "deg",
                         "Direction of the load (or slide) in the left finger's x-y plane, "
                         "from +x; the right finger's is 180 deg away.",
                         CHROMASIM_FIELD(protocol.load_direction_deg)));
    out.push_back(integer("protocol.slip_frames", 3, closed(0, 100000), "",
                          "grasp_load: frames kept from the first frame where a finger's "
                          "load reaches mu f_n (it slips: Gamma = 0); then the trial ends. 0: "
                          "it ends before that frame.",
                          CHROMASIM_FIELD(protocol.slip_frames)));
    out.push_back(number("protocol.slide.start_mm", 0.05, closed(0, 50), "mm",
                         "slide: the object's travel at the first slide frame (seed 001: 0.05).",
                         CHROMASIM_FIELD(protocol.slide_start_mm)));
    out.push_back(number("protocol.slide.end_mm", 6, closed(0, 50), "mm",
                         "slide: travel at the last slide frame (seed 001: 6).",
                         CHROMASIM_FIELD(protocol.slide_end_mm)));
    out.push_back(integer("protocol.slide.frames", 30, closed(1, 100000), "",
                          "slide: frames evenly spaced in travel from start_mm to end_mm (seed "
                          "001: 30).",
                          CHROMASIM_FIELD(protocol.slide_frames)));
    out.push_back(number("protocol.slide.speed_mm_per_s", 10, left_open(0, 1000), "mm/s",
                         "slide: sliding speed, which sets the slide frames' times (seed 001: "
                         "10).",
                         CHROMASIM_FIELD(protocol.slide_speed_mm_per_s)));
}

void add_sampling_and_splits(std::vector<SchemaEntry>& out) {
    out.push_back(choice("sampling.method", "full_grid", {"full_grid", "random", "latin_hypercube"},
                         "full_grid: every combination of objects, friction conditions and the "
                         "listed values of grip_N, load_rate_N_per_s and target_load_N, "
                         "repetitions times (a {min, max} factor is drawn per trial); random: "
                         "`trials` trials, each factor drawn independently (a list uniformly, "
                         "a range uniformly); latin_hypercube: `trials` trials, each factor "
                         "(objects and friction included) cut in `trials` equal strata, each "
                         "stratum used by exactly one trial.",
                         CHROMASIM_FIELD(sampling.method)));
    out.push_back(integer("sampling.repetitions", 1, closed(1, 100000), "",
                          "full_grid: trials per grid cell.",
                          CHROMASIM_FIELD(sampling.repetitions)));
    out.push_back(integer("sampling.trials", 1, closed(1, 1000000), "",
                          "random and latin_hypercube: number of trials.",
                          CHROMASIM_FIELD(sampling.trials)));
    out.push_back(text("splits[].name", "all",
                       "Name of the split (e.g. train, test); images go to images/<name>/. "
                       "Unique in the list.",
                       CHROMASIM_ITEM(splits, name)));
    out.push_back(number("splits[].fraction", 1, left_open(0, 1), "",
                         "Fraction of the trials in this split; the fractions sum to 1. Trials "
                         "are assigned by a shuffle seeded by `seed`; counts are rounded (the "
                         "cumulative sums, times the trial count, rounded).",
                         CHROMASIM_ITEM(splits, fraction)));
}
/// render.sensor: the optional camera sensor model (render/sensor_model.hpp). The ranges are the
/// ones render::SensorModel checks.
void add_render_sensor(std::vector<SchemaEntry>& out) {
    const std::string defaults =
        " [G]: a typical value for the Sony IMX392 of the Basler dart daA1920-160uc (datasheet "
        "class, SENSOR.md 1); replace it with your camera's measurement.";
    out.push_back(boolean("render.sensor.enabled", false,
                          "Pass the PNG through the camera sensor model: exposure gain, "
                          "vignetting, shot and read noise, full-well clipping, ADC "
                          "quantization, then the sRGB encoding of every PNG. The EXR keeps "
                          "the noise-free linear render. false: the PNG is the render itself.",
                          CHROMASIM_FIELD(render.sensor.enabled)));
    out.push_back(integer("render.sensor.seed", 1, closed(0, 2147483647), "",
                          "Seed of the sensor noise, independent of the top-level seed; mixed "
                          "with the frame index, so every frame has its own noise.",
                          CHROMASIM_FIELD(render.sensor.seed)));
    out.push_back(number("render.sensor.gain", 1, left_open(0, render::kSensorMaxGain), "",
                         "Exposure multiplier on the linear render before photo-conversion "
                         "(1.0 in the render = full well): more light, relatively less shot "
                         "noise.",
                         CHROMASIM_FIELD(render.sensor.gain)));
    out.push_back(number("render.sensor.full_well_e", 10000,
                         left_open(0, render::kSensorMaxFullWellE), "e-",
                         "Full-well capacity: photo-electrons at linear value 1.0, where the "
                         "pixel saturates; sets the shot noise (sqrt of the electron count)." +
                             defaults,
                         CHROMASIM_FIELD(render.sensor.full_well_e)));
    out.push_back(number("render.sensor.read_noise_e", 2.3, closed(0, render::kSensorMaxReadNoiseE),
                         "e-",
                         "Read noise, standard deviation of a Gaussian in electrons." + defaults,
                         CHROMASIM_FIELD(render.sensor.read_noise_e)));
    out.push_back(integer("render.sensor.adc_bits", 12,
                          closed(render::kSensorMinAdcBits, render::kSensorMaxAdcBits), "bit",
                          "ADC bit depth: the full well maps to code 2^bits - 1." + defaults,
                          CHROMASIM_FIELD(render.sensor.adc_bits)));
    out.push_back(boolean("render.sensor.shot_noise", true,
                          "Poisson photon (shot) noise: by inversion below a mean of 64 "
                          "electrons, by its normal approximation above; false: no shot noise.",
                          CHROMASIM_FIELD(render.sensor.shot_noise)));
    out.push_back(choice("render.sensor.vignetting.model", "polynomial",
                         {"none", "cos4", "polynomial"},
                         "Relative illumination RI at the field angle theta of each pixel: none "
                         "(1), cos4 (cos^4 theta, a rectilinear lens's natural vignetting: far "
                         "too dark near 90 deg for a fisheye), polynomial (max(0, 1 + k1 t^2 + "
                         "k2 t^4), t = theta / sensor.camera.half_fov_deg, the image radius over "
                         "the image circle's for the equidistant lens).",
                         CHROMASIM_FIELD(render.sensor.vignetting)));
    out.push_back(
        number("render.sensor.vignetting.k1", -0.3,
               closed(-render::kSensorMaxVignettingCoeff, render::kSensorMaxVignettingCoeff), "",
               "t^2 coefficient of the polynomial vignetting [G]: -0.3 gives 70 % "
               "illumination at the edge of the field, an assumed mild fall-off (not from the "
               "lens's datasheet); fit your own to a flat-field image.",
               CHROMASIM_FIELD(render.sensor.vignetting_k1)));
    out.push_back(
        number("render.sensor.vignetting.k2", 0,
               closed(-render::kSensorMaxVignettingCoeff, render::kSensorMaxVignettingCoeff), "",
               "t^4 coefficient of the polynomial vignetting [G].",
               CHROMASIM_FIELD(render.sensor.vignetting_k2)));
}

void add_render_and_outputs(std::vector<SchemaEntry>& out) {
    out.push_back(integer("render.width_px", 256, closed(16, 4096), "px", "Image width.",
                          CHROMASIM_FIELD(render.width_px)));
    out.push_back(integer("render.height_px", 256, closed(16, 4096), "px", "Image height.",
                          CHROMASIM_FIELD(render.height_px)));
    out.push_back(integer("render.samples_per_pixel", 4, closed(1, 1024), "",
                          "Samples per pixel (multi-jittered positions, stratified "
                          "wavelengths and, for the fast integrator, the shadow ray's LED and "
                          "point on it from a scrambled Sobol set). Fast integrator at 224 px "
                          "on 2 cores (a machine where Embree alone traces 10.2 M rays/s), "
                          "with the specs' shadow filter (1.0 px, 0.5 px on the markers' rims), "
                          "8 spp on the rims, 4 where an LED is mirrored and 32 rays for the "
                          "LEDs by reflection: 2 spp gives 0.89 % RMS of the white level in "
                          "0.13 s at 1.5 N + 0.6 N (0.92 % at 5 N + 2 N, 0.88 % at rest), 3 spp "
                          "0.80 % (its own noise and the filter's bias); at 896 px, 1 spp with "
                          "4 on the rims, 4 where mirrored, 16 LED rays and a 2 px filter 0.74 % "
                          "in 1.1 s (0.84 % at 5 N + 2 N) (docs/VALIDATION.md, session 26); "
                          "the path integrator needs thousands for 1 %.",
                          CHROMASIM_FIELD(render.samples_per_pixel)));
    out.push_back(number("render.exposure", 1, left_open(0, 100), "",
                         "Linear scale applied to the rendered radiance before writing.",
                         CHROMASIM_FIELD(render.exposure)));
    out.push_back(
        boolean("render.spectral", true,
                "Spectral rendering (16 hero wavelengths per sample, 8 with the fast "
                "integrator by default: render.fast.wavelengths_per_sample; colour "
                "mixing per wavelength, the spectra of sensor.optics.spectra_dir); false: "
                "the RGB approximation with the sensor.optics RGB values.",
                CHROMASIM_FIELD(render.spectral)));
    out.push_back(choice("render.integrator", "fast", {"direct", "path", "fast"},
                         "Light transport: fast (the path integrator's light with its smooth "
                         "part cached once per sensor, render.fast.*), path (unbiased path "
                         "tracing, the reference) or direct (LED light straight to the coating, "
                         "no refraction or interreflection: a quick preview, far off path). "
                         "docs/VALIDATION.md has each one's error and cost.",
                         CHROMASIM_FIELD(render.integrator)));
    out.push_back(integer("render.fast.paths_per_vertex", 1024, closed(1, 65536), "",
                          "Fast integrator: paths traced per coating vertex (at the coating "
                          "and above the outer markers) for the cached indirect light, once "
                          "per sensor (and kept on disk with --cache-dir); its noise is a "
                          "fixed pattern across frames. Measured against the path reference "
                          "(64 spp at 64 px, RMS over the image circle less the reference's "
                          "noise; cache build on 2 cores): 256 paths, 4.6 s: 2.3 % at rest, "
                          "2.5 % at 1.5 N + 0.6 N, 2.8 % at 5 N; 1024, 15 s: 1.7, 2.1, 2.1 %; "
                          "4096, 55 s: 1.6, 1.9, 2.1 % (docs/VALIDATION.md).",
                          CHROMASIM_FIELD(render.fast.paths_per_vertex)));
    out.push_back(number("render.fast.smoothing_mm", 0.75, closed(0, 10), "mm",
                         "Fast integrator: standard deviation of the Gaussian (local linear "
                         "regression) that smooths the cached indirect light over the "
                         "coating; 0: none. At 1024 paths, at rest (with the light cache's MIS "
                         "ratio 16 then, 4 now): 0.5 mm, 2.5 % RMS off the path reference; "
                         "0.75 mm, 1.9 %; 1 mm, 1.9 % (docs/VALIDATION.md).",
                         CHROMASIM_FIELD(render.fast.smoothing_mm)));
    out.push_back(integer("render.fast.direct_samples", 16, closed(1, 4096), "",
                          "Fast integrator: LED points per LED per coating vertex for the "
                          "cached unshadowed LED light.",
                          CHROMASIM_FIELD(render.fast.direct_samples)));
    out.push_back(boolean("render.fast.refresh_direct", true,
                          "Fast integrator: per frame, re-estimate a coating vertex's light "
                          "from an LED on the frame's own surfaces (render.fast.direct_samples "
                          "points) where a contact changed it by more than "
                          "render.fast.refresh_threshold; elsewhere the cache's rest value is "
                          "carried over. At 64 px against the path integrator (RMS of white "
                          "less the reference's noise; 0.19.0, one run each) it takes 1.5 N + "
                          "0.6 N from 2.20 to 1.76 % for 11 ms more per frame update (36.5 "
                          "against 25.7 ms) and 5 N + 2 N from 6.17 to 2.08 % for 24 ms more "
                          "(47.9 against 24.1 ms) (docs/VALIDATION.md).",
                          CHROMASIM_FIELD(render.fast.refresh_direct)));
    out.push_back(number("render.fast.refresh_threshold", 0.5, closed(0, 10), "",
                         "Fast integrator: the relative change of a vertex's point-LED light "
                         "from rest above which render.fast.refresh_direct re-estimates it; "
                         "0: every vertex whose point-LED light changed at all. At 1.5 N + "
                         "0.6 N, 64 px against the path integrator over the image circle "
                         "(0.19.0, one run each): 0.5, 36.5 ms per frame update, 1.95 % RMS "
                         "of white; 0.1, 115 ms, 1.88 %; 0, 361 ms, 1.83 %. At 5 N + 2 N: "
                         "0.5, 48 ms, 2.30 %; 0.1, 251 ms, 2.02 %; 0, 326 ms, 2.00 % "
                         "(docs/VALIDATION.md).",
                         CHROMASIM_FIELD(render.fast.refresh_threshold)));
    out.push_back(boolean("render.fast.scale_indirect", false,
                          "Fast integrator: per frame, scale the cached indirect light by the "
                          "LEDs' unshadowed flux onto the coating over rest; false keeps the rest "
                          "value, which is closer to the path integrator (docs/VALIDATION.md).",
                          CHROMASIM_FIELD(render.fast.scale_indirect)));
    out.push_back(number(
        "render.fast.shadow_filter_px", 1.0, closed(0, render::kMaxShadowFilterPx), "px",
        "Fast integrator: standard deviation of the shadow filter, in pixels; 0: none. The "
        "LEDs' direct light in a pixel is taken without the shadow rays' noise (the light "
        "cache's unshadowed light), per LED, times the fraction of that LED's light that "
        "gets through the markers' shadows, that fraction averaged with Gaussian weights "
        "over the neighbouring pixels' shadow rays that went to that LED (a ratio "
        "estimator; LEDs beyond 8 in groups). It blurs the shadows' edges by about this "
        "width and leaves the markers' own edges sharp; on the markers' rims "
        "render.fast.shadow_filter_rim_px takes over. At 224 px with 8 spp on the rims, 4 "
        "where an LED is mirrored and 32 rays for the LEDs by reflection (RMS of white, noise "
        "and bias, 1.5 N + 0.6 N): with 0.5 px on the rims, 2 spp gives 0.95 % at 0.8 px, "
        "0.89 % at 1 px, 0.88 % at 1.2 px, and 3 spp 0.84, 0.80 and 0.81 %; with this width "
        "on the rims too (0.19.0) 3 spp gave 0.89 % at 0.8 px and 0.90 % at 1 px. At 5 N + "
        "2 N and at rest 1 px is also better than 0.8 px (2 spp: 0.92 against 0.97 % and "
        "0.88 against 0.94 %). Larger images want a wider filter: at 896 px, 1 spp with 4 on "
        "the rims, 4 where mirrored and 16 LED rays, 1.03 % at 1 px, 0.81 % at 1.5 px, 0.74 % "
        "at 2 px, 0.73 % at 2.5 px (1.5 N + 0.6 N; 5 N + 2 N: 1.08, 0.89, 0.84, 0.84 %). At "
        "many samples a narrower one: at 224 px and 64 spp, 0.44 % with these widths against "
        "0.31 % unfiltered and 0.36 % at 0.8 px (docs/VALIDATION.md, session 26).",
        CHROMASIM_FIELD(render.fast.shadow_filter_px)));
    out.push_back(number(
        "render.fast.shadow_filter_rim_px", 0.5, closed(0, render::kMaxShadowFilterPx), "px",
        "Fast integrator: the shadow filter's standard deviation in the pixels on the "
        "markers' rims (those of render.fast.edge_samples_per_pixel, where it is above "
        "render.samples_per_pixel; 0: each pools its own samples alone). The LEDs sit beside "
        "the camera, so a marker's shadow on the coating nearly coincides with its image: "
        "pooled over the whole filter, the transmittance is blurred across the marker's edge "
        "(at 224 px and 64 spp the 0.8 px filter alone put 0.38 % RMS of white of bias into "
        "the image, most of it there). At 224 px, 3 spp, 8 on the rims, 0.8 px elsewhere "
        "(RMS of white at 1.5 N + 0.6 N): 0.88 % with 0.2 px here, 0.85 % with 0.4, 0.84 % "
        "with 0.5, 0.85 % with 0.6, 0.89 % with 0.8 (the same filter everywhere, 0.19.0), "
        "0.94 % with 1; 0.5 px is also the best of these at 5 N + 2 N (0.87 against 0.93 %) "
        "and at rest (0.83 against 0.88 %). At 896 px (1.5 px elsewhere) 0.5 to 1 px are "
        "within 0.005 % of each other (docs/VALIDATION.md, session 26).",
        CHROMASIM_FIELD(render.fast.shadow_filter_rim_px)));
    out.push_back(integer(
        "render.fast.reflection_samples_per_pixel", 4, closed(0, 1024), "",
        "Fast integrator: samples per pixel where the inner surface mirrors an LED (the bright "
        "streaks near the rim: the ray through the pixel's centre, reflected, crosses the LEDs' "
        "plane within 0.25 mm of an LED plus half the distance to its neighbours' crossings) "
        "and in those pixels' 8 neighbours; at most render.samples_per_pixel (0 included): none "
        "take more. Chosen before any sample, so each pixel stays unbiased: such a pixel is the "
        "pixel a render at this count would give. At 224 px, 1.5 N + 0.6 N (5 % of the pixels; "
        "11 % at 5 N + 2 N), RMS of white with the 0.7 px shadow filter: 4 spp 1.14 % in 0.10 s "
        "against 1.39 % in 0.08 s without, 5 spp 1.05 % in 0.12 s, 6 spp 0.92 % in 0.14 s. With "
        "the LEDs by reflection from rays of their own "
        "(render.fast.reflected_led_samples_per_pixel, 32) these pixels need few samples more: "
        "with 3 spp, 8 on the markers' rims and the 0.8 px filter (the shipped 224 px specs), 4 "
        "gives 0.89 % at 1.5 N + 0.6 N, 0.93 % at 5 N + 2 N and 0.88 % at rest, against 0.92, "
        "0.94 and 0.87 % with 12 and the LEDs in the samples (0.18.0's defaults), in 4 %, 10 % "
        "and about 0 % less time (docs/VALIDATION.md).",
        CHROMASIM_FIELD(render.fast.reflection_samples_per_pixel)));
    out.push_back(integer(
        "render.fast.edge_samples_per_pixel", 6, closed(0, 1024), "",
        "Fast integrator: samples per pixel on the markers' rims: the pixels whose 4 corners' "
        "first marker of each layer are not all the same (8 to 11 % of the fisheye's circle at "
        "224 px; up to 0.22.0 the pixels whose centre's markers differed from one of its 8 "
        "neighbours', 15 to 18 %, for the numbers below up to 0.22.0); at most "
        "render.samples_per_pixel (0 included): none take more; pixels that "
        "mirror an LED keep render.fast.reflection_samples_per_pixel. Chosen from the frame's "
        "geometry before any sample, so each pixel stays unbiased. At 224 px, 1.5 N + 0.6 N, "
        "with the 0.7 px shadow filter and 16 spp where an LED is mirrored, RMS of white: 3 spp "
        "with 6 on the rims 0.98 % in 0.10 s (0.16.0's 224 px specs), with 8 0.91 % in 0.11 "
        "s, 4 spp with 6 0.90 % in 0.11 s, against 4 spp alone 1.07 % in 0.10 s and 3 spp 1.31 "
        "% in 0.08 s; at rest 3 + 6 spp 0.94 % in 0.09 s against 4 spp 1.05 % in 0.09 s; at 5 N "
        "+ 2 N a wash (0.95 % in 0.14 s, as 4 spp alone); at 896 px, 2 spp with a 1.5 px "
        "filter, 4 on the rims 0.59 % in 0.98 s against 0.78 % in 0.84 s and 3 spp alone 0.61 % "
        "in 1.13 s. With 0.8 px and 12 where an LED is mirrored (0.18.0's defaults), 3 spp with 8 "
        "on the rims (the shipped 224 px specs) gives 0.92 % at 1.5 N + 0.6 N, 0.93 % at 5 N "
        "+ 2 N and 0.87 % at rest, against 0.96, 0.93 and 0.93 % with 6 and 16 (0.16.0's "
        "defaults), with 2 % more rays, 3 % fewer and 5 % more. Finding the rims costs about "
        "7 ms at 224 px. 0.23.0 (the corners' rule, the frame's share apart; 6 by default, 8 up "
        "to 0.22.0): 2 spp with 6 on the rims, 4 where mirrored, 32 LED rays, 1 px filter and "
        "0.5 px on the rims (the shipped 224 px specs) give 0.90 % at 1.5 N + 0.6 N in 75 to 79 "
        "ms, 0.95 % at 5 N + 2 N in 93 to 103 ms and 0.87 % at rest in 67 ms on a 2-core Xeon; "
        "8 on the rims 0.83, 0.90 and 0.79 % in 80 to 86, 99 to 108 and 74 ms "
        "(docs/VALIDATION.md, session 31).",
        CHROMASIM_FIELD(render.fast.edge_samples_per_pixel)));
    out.push_back(integer(
        "render.fast.reflected_led_samples_per_pixel", 32, closed(0, 1024), "",
        "Fast integrator: in the pixels where an LED is mirrored (those of "
        "render.fast.reflection_samples_per_pixel), the LEDs seen by reflection in the inner "
        "surface come from this many rays per pixel of their own, which go only as far as the "
        "reflection (the camera ray to the inner surface and its reflection on, no shading), and "
        "the pixel's samples leave them out: the pixel is the sum of the two estimates, "
        "unbiased. The LEDs' small, bright images were most of those pixels' noise. 0: the "
        "LEDs stay in the samples. At 224 px with the shipped specs (3 spp, 8 on the rims, 4 "
        "where an LED is mirrored, 0.8 px filter), RMS of white at 1.5 N + 0.6 N: 1.18 % with "
        "0, 0.90 % with 24, 0.89 % with 32 (0.92 % with 12 where mirrored and 0 here, 0.18.0's "
        "defaults); 32 such rays cost about as much as 4 samples of the pixel. At 896 px (2 "
        "spp, 1.5 px filter) 0.53 % against 0.54 % (docs/VALIDATION.md).",
        CHROMASIM_FIELD(render.fast.reflected_led_samples_per_pixel)));
    out.push_back(integer(
        "render.fast.shadow_rays_per_pixel", 0, closed(0, 4096), "",
        "Fast integrator: the fewest shadow rays (from a sample's coating hit towards the "
        "LEDs, through the markers' shadows) a pixel traces, spread evenly over its samples, "
        "at least one and at most 4 a sample; 0, or up to the pixel's sample count: one a "
        "sample. A pixel with 2 samples and 4 here traces 2 a sample, one with 8 (a marker's "
        "rim) one a sample. The shadow rays' noise is most of the error in the bulk of the "
        "image; this spends time there without more camera samples. Best at a multiple of "
        "render.samples_per_pixel. At 224 px with 2 spp, 8 on the rims, 4 where mirrored, 32 "
        "LED rays and the 1 px filter (RMS of white; times: medians of alternated runs on one "
        "2-core machine): at 1.5 N + 0.6 N, 0 gives 0.89 % in 100 ms, 4 gives 0.77 % in 113 "
        "ms, where 3 spp with 0 gives 0.80 % in 113 ms; at 5 N + 2 N 0.92 % in 120 ms, 0.79 % "
        "in 135 ms, 0.84 % in 138 ms; at rest 0.87, 0.75 and 0.79 %. At 896 px, 1 spp, 4 on "
        "the rims, 4 where mirrored, 16 LED rays and the 2 px filter (one run each): 0 gives "
        "0.74 % in 0.73 s, 2 0.67 % in 0.87 s, 4 0.63 % in 1.15 s (docs/VALIDATION.md, "
        "session 29).",
        CHROMASIM_FIELD(render.fast.shadow_rays_per_pixel)));
    out.push_back(choice(
        "render.fast.wavelengths_per_sample", "auto", {"auto", "8", "16"},
        "Fast integrator, spectral mode: the hero wavelengths each camera sample carries "
        "(the direct and path integrators carry 16); auto: 16 at render.samples_per_pixel 1, "
        "else 8. A pixel's samples split the wavelengths' strata between them, so 2 samples "
        "of 8 are about as noisy in colour as one of 16. The rays do not depend on the "
        "wavelength, so this is arithmetic, not rays: 8 take about 5 % off a 224 px render. "
        "The light cache is the same for both (16 fixed wavelengths of its own). At 224 px "
        "with the shipped 224 px specs' counts (2 spp), RMS of white: 8 give 0.90 % at 1.5 N "
        "+ 0.6 N in 63 ms, 0.86 % at 2.5 N + 1.5 N in 66 ms, 0.88 % at 5 N + 2 N in 76 ms and "
        "0.90 % at rest; 16 give 0.88, 0.83, 0.85 and 0.87 % in 67, 70 and 81 ms (render "
        "alone on a 2-core Xeon). At 896 px and 1 spp, 8 give 0.71 % in 0.55 s against 0.58 % "
        "in 0.57 s (docs/VALIDATION.md, session 36).",
        CHROMASIM_FIELD(render.fast.wavelengths_per_sample)));
    add_render_sensor(out);
    out.push_back(boolean("outputs.images", true,
                          "Write a PNG per frame (8-bit sRGB); with outputs.exr false too, the "
                          "render stage is skipped.",
                          CHROMASIM_FIELD(outputs.images)));
    out.push_back(
        boolean("outputs.labels", true, "Write labels.csv.", CHROMASIM_FIELD(outputs.labels)));
    out.push_back(boolean("outputs.markers", true,
                          "Write markers.csv (3D displacement of every marker).",
                          CHROMASIM_FIELD(outputs.markers)));
    out.push_back(boolean("outputs.exr", false,
                          "Write a linear float OpenEXR per frame (channels R, G, B; "
                          "docs/DATASET_FORMAT.md).",
                          CHROMASIM_FIELD(outputs.exr)));
    out.push_back(boolean("outputs.marker_ids", false,
                          "Add EXR channels inner_marker_id and outer_marker_id: the marker seen "
                          "through each pixel's centre, per layer (-1: none). Needs outputs.exr.",
                          CHROMASIM_FIELD(outputs.marker_ids)));
    out.push_back(boolean("outputs.variance", false,
                          "Add EXR channels variance.R, variance.G, variance.B: each pixel's "
                          "variance of the mean over its samples. Needs outputs.exr.",
                          CHROMASIM_FIELD(outputs.variance)));
    out.push_back(boolean("outputs.strain", false,
                          "Write the surface strain eps_xx on a 101 x 76 grid (seed 001, eq. 3) "
                          "per frame: strain/<split>/<trial>/<finger>.csv, one row per frame "
                          "(docs/DATASET_FORMAT.md).",
                          CHROMASIM_FIELD(outputs.strain)));
}

#undef CHROMASIM_FIELD
#undef CHROMASIM_ITEM

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
    const auto lowest = [](const Factor& f) {
        return f.is_range ? f.min : *std::min_element(f.values.begin(), f.values.end());
    };
    const auto highest = [](const Factor& f) {
        return f.is_range ? f.max : *std::max_element(f.values.begin(), f.values.end());
    };
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

std::vector<SchemaEntry> build_schema() {
    std::vector<SchemaEntry> out;
    add_general(out);
    add_sensor_mechanics(out);
    add_sensor_optics(out);
    add_objects(out);
    add_fingers(out);
    add_protocol(out);
    add_sampling_and_splits(out);
    add_render_and_outputs(out);
    return out;
}

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

std::vector<SchemaRule> build_rules() {
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
    SchemaRule channels;
    channels.key = "outputs.exr";
    channels.holds = [](const Spec& s, std::size_t) {
        return s.outputs.exr || !(s.outputs.marker_ids || s.outputs.variance);
    };
    channels.problem =
        "is false while outputs.marker_ids or outputs.variance asks for EXR channels";
    channels.allowed = "outputs.exr: true, or outputs.marker_ids and outputs.variance false";
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
            optics_params(s);
        } catch (const std::exception& e) {
            return std::string("holds spectra that cannot be used (") + e.what() + ")";
        }
        return "";
    };
    spectra.allowed = "a folder with the six spectrum CSVs (assets/spectra/README.md), or empty "
                      "for the shipped ones";
    mesh.allowed = "a .gltf or .glb file; a relative path starts at the spec file's folder";
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
    std::vector<SchemaRule> rules{outputs, channels, mesh, camera, tilt, spectra};
    for (const char* list : {"objects", "friction", "splits"})
        rules.push_back(unique_name(list));
    rules.push_back(split_sum());
    rules.push_back(led_beside_lens());
    rules.push_back(slide_travel());
    rules.push_back(trial_length());
    return rules;
}

} // namespace chromasim::generators::detail
