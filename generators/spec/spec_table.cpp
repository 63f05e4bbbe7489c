// The spec's table: every key's schema entry (type, default, unit, range, doc line, field).
// spec_schema.cpp owns the singletons and the machinery that reads, checks and prints
// values; spec_rules.cpp has the lists of mappings and the cross-key rules; this file only
// says what the keys are.
#include "generators/spec/spec_table.hpp"

#include "generators/spec/stage_params.hpp"
#include "render/fisheye_camera.hpp"
#include "render/sensor_model.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <type_traits>
namespace chromasim::generators::detail {
namespace { // internal linkage: these names are common

// ---- Storing values into fields and reading them back ---------------------------------------

/// Stores a validated value; integers travel as int64_t and narrow to the field's type (the
/// schema range guarantees they fit).
template <class T> void assign(T& field, const SpecValue& v) {
    if constexpr (std::is_integral_v<T> && !std::is_same_v<T, bool>) {
        field = static_cast<T>(std::get<std::int64_t>(v));
    } else if constexpr (std::is_same_v<T, std::vector<double>>) {
        field = std::get<Factor>(v).values; // a `numbers` entry
    } else {
        field = std::get<T>(v);
    }
}

template <class T> SpecValue to_value(const T& x) {
    if constexpr (std::is_integral_v<T> && !std::is_same_v<T, bool>) {
        return static_cast<std::int64_t>(x);
    } else if constexpr (std::is_same_v<T, std::vector<double>>) {
        return Factor{x};
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

/// A `varied` entry: one number is the field's value; a list or a range goes into
/// Spec::varied under the key, and the field holds its nominal value (the list's first item,
/// the range's middle).
template <class Access>
SchemaEntry varied(std::string key, double def, Range range, std::string unit, std::string doc,
                   Access access) {
    SchemaEntry e = make_entry(std::move(key), ValueType::Varied, Factor{std::vector<double>{def}},
                               std::move(unit), range, std::move(doc), access);
    e.set = [key = e.key, access](Spec& s, std::size_t, const SpecValue& v) {
        const Factor& f = std::get<Factor>(v);
        if (!f.is_range && f.values.size() == 1) {
            access(s) = f.values.front();
            s.varied.erase(key);
            return;
        }
        access(s) = f.is_range ? 0.5 * (f.min + f.max) : f.values.front();
        s.varied[key] = f;
    };
    e.get = [key = e.key, access](const Spec& s, std::size_t) -> SpecValue {
        const auto it = s.varied.find(key);
        return it != s.varied.end() ? it->second : Factor{std::vector<double>{access(s)}};
    };
    return e;
}

/// A `numbers` entry: one number or a list, into a std::vector<double> field.
template <class Access>
SchemaEntry numbers(std::string key, double def, Range range, std::string unit, std::string doc,
                    Access access) {
    return make_entry(std::move(key), ValueType::Numbers, Factor{std::vector<double>{def}},
                      std::move(unit), range, std::move(doc), access);
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
    out.push_back(varied(
        key + ".E_MPa", E_MPa, left_open(0, 1000), "MPa",
        "Young's modulus of the " + what + " [G].", [layer_access](auto& s) -> auto& {
            return layer_access(s).E_MPa;
        }));
    out.push_back(varied(
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
    out.push_back(choice("sensor.mesh_level", "very_coarse",
                         {"very_coarse", "coarse", "medium", "fine", "refined", "reference"},
                         "TetGen mesh level of the dome: uniform very_coarse (2 mm edges), "
                         "coarse (1.2 mm), medium (0.8 mm), fine (0.5 mm), or refined where "
                         "contact happens: "
                         "refined (0.5 mm within 40 deg of the apex, 1.2 mm far), reference "
                         "(0.3 mm, 0.8 mm far).",
                         CHROMASIM_FIELD(sensor.mesh_level)));
    out.push_back(integer("sensor.element_order", 2, closed(1, 2), "",
                          "Tets of the dome: 2 (quadratic, edge nodes on the layers' spheres; "
                          "presses within 3 % of CalculiX on very_coarse) or 1 (linear, about "
                          "3x faster but 5 to 17 % too stiff on coarse and very_coarse). "
                          "sensor.volumetric applies to linear tets only.",
                          CHROMASIM_FIELD(sensor.element_order)));
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
                         "layer, clamped on the base plane). A core or fill renders as "
                         "index-matched to the layers: no inner surface, no refraction.",
                         CHROMASIM_FIELD(sensor.interior)));
    out.push_back(choice("sensor.material_model", "neo_hookean", {"linear", "neo_hookean"},
                         "Constitutive model of the layers: neo_hookean (compressible, large "
                         "deformation) or linear (small strain, about 1 ms a frame on linear "
                         "tets, but 16 to 33 % too stiff at 0.5 to 3.2 N).",
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
    out.push_back(number("sensor.camera.position_tolerance_mm", 0, closed(0, 1), "mm",
                         "Each sensor variant draws its camera's position uniformly within this "
                         "distance of `position_mm` along each axis (0: as written).",
                         CHROMASIM_FIELD(sensor.camera_position_tolerance_mm)));
    out.push_back(varied("sensor.camera.roll_deg", 0, closed(-180, 180), "deg",
                         "Camera rotation about the dome's x axis (applied first; 0, 0, 0: "
                         "looking along +z, image x along +x).",
                         CHROMASIM_FIELD(sensor.camera_roll_deg)));
    out.push_back(varied("sensor.camera.pitch_deg", 0, closed(-180, 180), "deg",
                         "Camera rotation about the dome's y axis (applied second).",
                         CHROMASIM_FIELD(sensor.camera_pitch_deg)));
    out.push_back(varied("sensor.camera.yaw_deg", 0, closed(-180, 180), "deg",
                         "Camera rotation about the dome's z axis (applied last).",
                         CHROMASIM_FIELD(sensor.camera_yaw_deg)));
}

void add_sensor_leds(std::vector<SchemaEntry>& out) {
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
    out.push_back(numbers("sensor.led.gains", 1, closed(0, 10), "",
                          "Each LED's intensity relative to `rgb`, in ring order from +x "
                          "(`chromasim calibrate` fits them); one number sets every LED.",
                          CHROMASIM_FIELD(sensor.led_gains)));
    out.push_back(number("sensor.led.gain_tolerance", 0, closed(0, 0.5), "",
                         "Each sensor variant draws every LED's gain uniformly within this "
                         "fraction either side of its `gains` value (0: the gains as written).",
                         CHROMASIM_FIELD(sensor.led_gain_tolerance)));
}

void add_sensor_optics(std::vector<SchemaEntry>& out) {
    out.push_back(varied("sensor.camera.half_fov_deg", 84, left_open(10, 100), "deg",
                         "Half field of view: the polar angle at the image-circle edge "
                         "(equidistant) or of the imaged field (kannala_brandt).",
                         CHROMASIM_FIELD(sensor.camera_half_fov_deg)));
    add_camera_model(out);
    out.push_back(
        number("sensor.camera.lens_radius_mm", 8, closed(0, 10.5), "mm",
               "Radius of the camera's lens barrel, a black cylinder from the rim plane "
               "down (FUSE CAD [K]; 0: none); it hides LEDs below the rim from most of the dome.",
               CHROMASIM_FIELD(sensor.lens_radius_mm)));
    add_sensor_leds(out);
    out.push_back(varied("sensor.optics.marker_thickness_mm", 0.5, left_open(0, 0.5), "mm",
                         "Thickness of the marker discs [K]: closed volumes deformed with the "
                         "mesh, at most 98 % of their layer's 0.5 mm; light is absorbed over "
                         "its path inside.",
                         CHROMASIM_FIELD(sensor.marker_thickness_mm)));
    out.push_back(varied("sensor.optics.marker_radius_mm", 0.5, left_open(0, 1), "mm",
                         "Radius of the marker discs [K]: 0.5 mm (1.0 mm across), as printed.",
                         CHROMASIM_FIELD(sensor.marker_radius_mm)));
    out.push_back(number("sensor.optics.marker_jitter_mm", 0, closed(0, 0.5), "mm",
                         "Printing tolerance of the marker layout: each marker's centre moves in "
                         "its layer by an offset uniform in a disc of this radius, drawn per "
                         "sensor (every sensor variant its own) [G].",
                         CHROMASIM_FIELD(sensor.marker_jitter_mm)));
    out.push_back(varied("sensor.optics.refractive_index", 1.4, closed(1, 2), "",
                         "Refractive index of the clear layers, index-matched among themselves "
                         "[G] (silicones and clear resins: 1.40 to 1.47); the path integrator "
                         "refracts at the hollow dome's inner surface (air inside); 1: no "
                         "refraction.",
                         CHROMASIM_FIELD(sensor.refractive_index)));
    out.push_back(rgb("sensor.optics.coating_albedo", {0.85, 0.85, 0.85}, closed(0, 1), "",
                      "Diffuse albedo of the white coating, linear RGB [G] (RGB mode only: "
                      "render.spectral false).",
                      CHROMASIM_FIELD(sensor.coating_albedo)));
    out.push_back(varied("sensor.optics.coating_albedo_scale", 1, left_open(0, 2), "",
                         "Multiplies the coating's albedo, RGB or spectrum, which must stay at "
                         "most 1 [G].",
                         CHROMASIM_FIELD(sensor.coating_albedo_scale)));
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
    out.push_back(varied("sensor.optics.inner_marker_absorption_scale", 1, left_open(0, 10), "",
                         "Multiplies the inner markers' absorption, RGB or spectrum: the dye's "
                         "concentration [G].",
                         CHROMASIM_FIELD(sensor.inner_marker_absorption_scale)));
    out.push_back(varied("sensor.optics.outer_marker_absorption_scale", 1, left_open(0, 10), "",
                         "Multiplies the outer markers' absorption, RGB or spectrum [G].",
                         CHROMASIM_FIELD(sensor.outer_marker_absorption_scale)));
    out.push_back(rgb("sensor.optics.outer_marker_albedo", {0.10, 0.70, 0.75}, closed(0, 1), "",
                      "Albedo of the outer markers (cyan), linear RGB [G] (RGB mode only).",
                      CHROMASIM_FIELD(sensor.outer_marker_albedo)));
    out.push_back(varied("sensor.optics.outer_marker_scatter_fraction", 0.5, closed(0, 1), "",
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
                         "How trials are drawn: full_grid (every combination of objects, friction "
                         "and listed factor values, `repetitions` times), random (`trials` trials, "
                         "each factor drawn independently) or latin_hypercube (`trials` trials, "
                         "each factor cut in `trials` strata, each stratum used once).",
                         CHROMASIM_FIELD(sampling.method)));
    out.push_back(integer("sampling.repetitions", 1, closed(1, 100000), "",
                          "full_grid: trials per grid cell.",
                          CHROMASIM_FIELD(sampling.repetitions)));
    out.push_back(integer("sampling.trials", 1, closed(1, 1000000), "",
                          "random and latin_hypercube: number of trials.",
                          CHROMASIM_FIELD(sampling.trials)));
    out.push_back(integer("sampling.sensor_variants", 8, closed(0, 1000000), "",
                          "Sensors drawn from the `varied` keys given as lists or ranges, each "
                          "trial using one (sensor_assignment); each costs a mechanics "
                          "precompute and a light cache (0: one per trial).",
                          CHROMASIM_FIELD(sampling.sensor_variants)));
    out.push_back(choice("sampling.sensor_assignment", "random", {"random", "crossed"},
                         "How trials get their sensor: random (each picks one) or crossed "
                         "(full_grid: every grid cell runs on every sensor, like seed 001's "
                         "participants, so trials times sensor_variants).",
                         CHROMASIM_FIELD(sampling.sensor_assignment)));
    out.push_back(text("splits[].name", "all",
                       "Name of the split (e.g. train, test), unique in the list; its images go to "
                       "images/<name>/.",
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
                          "Pass the PNG through the camera sensor model (gain, vignetting, shot "
                          "and read noise, full-well clipping, ADC quantization); the EXR keeps "
                          "the noise-free linear render. false: the PNG is the render itself.",
                          CHROMASIM_FIELD(render.sensor.enabled)));
    out.push_back(integer("render.sensor.seed", 1, closed(0, 2147483647), "",
                          "Seed of the sensor noise, independent of the top-level seed; mixed "
                          "with the frame index, so every frame has its own noise.",
                          CHROMASIM_FIELD(render.sensor.seed)));
    out.push_back(varied("render.sensor.gain", 1, left_open(0, render::kSensorMaxGain), "",
                         "Exposure multiplier on the linear render before photo-conversion "
                         "(1.0 in the render = full well): more light, relatively less shot "
                         "noise.",
                         CHROMASIM_FIELD(render.sensor.gain)));
    out.push_back(varied("render.sensor.full_well_e", 10000,
                         left_open(0, render::kSensorMaxFullWellE), "e-",
                         "Full-well capacity: photo-electrons at linear value 1.0, where the "
                         "pixel saturates; sets the shot noise (sqrt of the electron count)." +
                             defaults,
                         CHROMASIM_FIELD(render.sensor.full_well_e)));
    out.push_back(varied("render.sensor.read_noise_e", 2.3, closed(0, render::kSensorMaxReadNoiseE),
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
                         "Relative illumination at each pixel's field angle theta: none (1), cos4 "
                         "(cos^4 theta, too dark near 90 deg for a fisheye) or polynomial (max(0, "
                         "1 + k1 t^2 + k2 t^4), t = theta / sensor.camera.half_fov_deg).",
                         CHROMASIM_FIELD(render.sensor.vignetting)));
    out.push_back(
        varied("render.sensor.vignetting.k1", -0.3,
               closed(-render::kSensorMaxVignettingCoeff, render::kSensorMaxVignettingCoeff), "",
               "t^2 coefficient of the polynomial vignetting [G]: -0.3 gives 70 % "
               "illumination at the edge of the field, an assumed mild fall-off (not from the "
               "lens's datasheet); fit your own to a flat-field image.",
               CHROMASIM_FIELD(render.sensor.vignetting_k1)));
    out.push_back(
        varied("render.sensor.vignetting.k2", 0,
               closed(-render::kSensorMaxVignettingCoeff, render::kSensorMaxVignettingCoeff), "",
               "t^4 coefficient of the polynomial vignetting [G].",
               CHROMASIM_FIELD(render.sensor.vignetting_k2)));
}

/// render: image size, samples, exposure, integrator.
void add_render(std::vector<SchemaEntry>& out) {
    out.push_back(integer("render.width_px", 256, closed(16, 4096), "px", "Image width.",
                          CHROMASIM_FIELD(render.width_px)));
    out.push_back(integer("render.height_px", 256, closed(16, 4096), "px", "Image height.",
                          CHROMASIM_FIELD(render.height_px)));
    out.push_back(integer("render.samples_per_pixel", 4, closed(1, 1024), "",
                          "Camera samples per pixel. More lowers the noise at a proportional cost; "
                          "docs/VALIDATION.md gives each integrator's error against samples and "
                          "time.",
                          CHROMASIM_FIELD(render.samples_per_pixel)));
    out.push_back(number("render.exposure", 1, left_open(0, 100), "",
                         "Linear scale applied to the rendered radiance before writing.",
                         CHROMASIM_FIELD(render.exposure)));
    out.push_back(
        boolean("render.spectral", true,
                "Spectral rendering (hero wavelengths per sample, as render.quality sets "
                "them for the fast integrator; colour mixing per wavelength, the spectra of "
                "sensor.optics.spectra_dir); false: the RGB approximation with the "
                "sensor.optics RGB values.",
                CHROMASIM_FIELD(render.spectral)));
    SchemaEntry integrator = choice(
        "render.integrator", "fast", {"preview", "path", "fast"},
        "Light transport: fast (path-traced light with its smooth part cached per sensor), path "
        "(unbiased, the reference, thousands of samples for 1 %) or preview (the LEDs' direct "
        "light only, far off path). docs/VALIDATION.md gives each one's error and cost.",
        CHROMASIM_FIELD(render.integrator));
    integrator.renamed = {{"direct", "preview"}};
    out.push_back(std::move(integrator));
}

/// render.quality and render.fast: the fast integrator's preset and its expert keys.
void add_render_fast(std::vector<SchemaEntry>& out) {
    out.push_back(choice("render.quality", "default", quality_names(),
                         "Fast integrator: the extra samples for the costly pixels (the markers' "
                         "rims, the LEDs mirrored in the inner surface) and the shadows, as listed "
                         "under Quality presets. Draft is for a first look, high for figures.",
                         CHROMASIM_FIELD(render.quality)));
    out.push_back(integer("render.fast.paths_per_vertex", 1024, closed(1, 65536), "",
                          "Fast integrator: paths per coating vertex for the cached indirect "
                          "light, traced once per sensor and kept with --cache-dir. More lowers "
                          "the cache's fixed-pattern noise, at a longer cache build.",
                          CHROMASIM_FIELD(render.fast.paths_per_vertex)));
    out.push_back(number("render.fast.refresh_threshold", 1.0, closed(0, 10), "",
                         "Fast integrator: the relative change of a vertex's LED light under a "
                         "contact above which it is estimated anew on the frame; 0: every "
                         "vertex whose light changed. Lower costs more time per frame.",
                         CHROMASIM_FIELD(render.fast.refresh_threshold)));
    out.push_back(number(
        "render.fast.shadow_filter_px", 1.0, closed(0, render::kMaxShadowFilterPx), "px",
        "Fast integrator: standard deviation (px) of the Gaussian over neighbouring pixels that "
        "averages the share of each LED's light passing the markers' shadows; 0: none. Widen it "
        "for larger images or fewer samples, narrow it at many samples.",
        CHROMASIM_FIELD(render.fast.shadow_filter_px)));
}

/// outputs: which files a dataset holds.
void add_outputs(std::vector<SchemaEntry>& out) {
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
    add_render(out);
    add_render_fast(out);
    add_render_sensor(out);
    add_outputs(out);
    return out;
}

} // namespace chromasim::generators::detail
