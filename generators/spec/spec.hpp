#pragma once
/// The typed, validated contents of a dataset spec file (YAML). Every field has a schema
/// entry (generators/spec/spec_table.cpp) with its type, default, unit, allowed range and doc
/// line; `chromasim spec-doc` prints that table, docs/SPEC.md holds a copy.
#include <array>
#include <cstdint>
#include <filesystem>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace chromasim::generators {

/// A user's mistake in a spec file or argument. The message already names the file,
/// line:column, the key, the bad value and what is allowed, e.g.
/// `spec.yaml:12:5: render.width_px: value '-3' is out of range; allowed: integer in [16, 4096]
/// (px)`.
class SpecError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

using Rgb = std::array<double, 3>;

/// A factor of the sampling plan: a list of values, or a uniform range [min, max].
struct Factor {
    std::vector<double> values; ///< the listed values (empty for a range)
    bool is_range = false;
    double min = 0.0, max = 0.0; ///< the range (is_range only)
    bool operator==(const Factor&) const = default;
};

/// The smallest and the largest value a factor can take.
double lowest(const Factor& f);
double highest(const Factor& f);

struct LayerMaterial {
    double E_MPa = 1.0; ///< Young's modulus, MPa (= N/mm^2)
    double nu = 0.45;   ///< Poisson's ratio
};

struct Spec {
    std::filesystem::path source_path; ///< the file it was read from
    std::string name = "unnamed";
    std::uint64_t seed = 1;

    struct Sensor {
        std::string mesh_level = "very_coarse";     ///< very_coarse | coarse | medium | ...
        int element_order = 2;                      ///< 2: quadratic tets, 1: linear
        std::string volumetric = "nodal_average";   ///< nodal_average | element
        std::string material_model = "neo_hookean"; ///< neo_hookean | linear
        std::string interior = "hollow";            ///< hollow | rigid_core | soft_fill
        int contact_steps = 4; ///< load steps from rest to the first frame, per phase
        LayerMaterial inner_marker_layer{0.8, 0.45};
        LayerMaterial clear_layer{0.3, 0.45};
        LayerMaterial outer_marker_layer{0.8, 0.45};
        LayerMaterial coating{1.0, 0.45};
        LayerMaterial fill{0.05, 0.45}; ///< used only with interior soft_fill
        double contact_candidate_angle_deg = 50.0;
        double camera_half_fov_deg = 84.0;
        std::string camera_model = "equidistant"; ///< equidistant | kannala_brandt
        /// Kannala-Brandt intrinsics, OpenCV convention; 0: derived from the image size and
        /// camera_half_fov_deg (the equidistant camera's values).
        double camera_fx_px = 0, camera_fy_px = 0, camera_cx_px = 0, camera_cy_px = 0;
        double camera_k1 = 0, camera_k2 = 0, camera_k3 = 0, camera_k4 = 0;
        std::array<double, 3> camera_position_mm{0.0, 0.0, 0.0}; ///< in the dome frame
        double camera_position_tolerance_mm = 0.0; ///< each sensor's draw: position +- this
        double camera_roll_deg = 0, camera_pitch_deg = 0, camera_yaw_deg = 0;
        double lens_radius_mm = 8.0; ///< the lens barrel below the rim plane (0: none)
        int led_count = 6;
        double led_ring_radius_mm = 10.0;
        double led_z_mm = -13.8;
        double led_width_mm = 3.5, led_height_mm = 2.8;
        Rgb led_rgb{1.0, 1.0, 1.0};
        std::vector<double> led_gains{1.0}; ///< one for all, or one per LED
        double led_gain_tolerance = 0.0;    ///< each sensor's draw: gains (1 +- this)
        double refractive_index = 1.4;
        double marker_thickness_mm = 0.5;
        double marker_radius_mm = 0.5;
        double marker_jitter_mm = 0.0; ///< each marker's centre moved within this radius
        /// Not a spec key: the sensor's index in the plan (plan/sensor_variants.hpp), which
        /// seeds its marker jitter; -1: the spec's own sensor.
        int variant = -1;
        Rgb coating_albedo{0.85, 0.85, 0.85};
        double coating_albedo_scale = 1.0; ///< multiplies the coating's albedo (both modes)
        /// multiply the markers' absorption (both modes: the RGB values or the spectra)
        double inner_marker_absorption_scale = 1.0, outer_marker_absorption_scale = 1.0;
        Rgb inner_marker_absorption_per_mm{0.2, 3.0, 0.3};
        Rgb outer_marker_absorption_per_mm{3.0, 0.3, 0.2};
        Rgb outer_marker_albedo{0.10, 0.70, 0.75};
        double outer_marker_scatter_fraction = 0.5;
        std::string spectra_dir; ///< spectrum CSVs (empty: the shipped assets/spectra)
    } sensor;

    /// One rigid object of the `objects` list (a categorical factor of the sampling plan).
    struct Object {
        std::string name = "flat";  ///< label written in labels.csv; unique in the list
        std::string shape = "flat"; ///< flat (rigid plane) | sphere | mesh
        double radius_mm = 45.0;    ///< sphere radius
        std::string mesh_file;      ///< glTF file of a mesh object (relative: to the spec file)
        double offset_x_mm = 0, offset_y_mm = 0;         ///< mesh object's origin in x-y
        double roll_deg = 0, pitch_deg = 0, yaw_deg = 0; ///< its rotation (x, then y, then z)
    };
    std::vector<Object> objects{Object{}};

    /// One friction condition of the `friction` list (a categorical factor): a name and the
    /// Coulomb coefficient, a fixed value, a list or a range (drawn per trial).
    struct Friction {
        std::string name = "medium";
        Factor mu{std::vector<double>{0.8}};
    };
    std::vector<Friction> friction{Friction{}};

    /// The fingertips: `count` 1 (left only) or 2 (left and right, facing each other).
    struct Fingers {
        int count = 2;
        double mu_jitter = 0.0;        ///< per-finger relative mu jitter, uniform in [-j, j]
        double offset_jitter_mm = 0.0; ///< per-finger object offset jitter, x and y in [-j, j]
    } fingers;

    /// The load protocol of one trial (plan.hpp has the timeline).
    struct Protocol {
        std::string type = "grasp_load"; ///< grasp_load (seed 000) | slide (seed 001)
        double frame_rate_Hz = 100.0;
        Factor grip_N{std::vector<double>{1.5}}; ///< grip (normal) force per finger
        double grasp_s = 0.5;                    ///< grip force ramp from first touch
        double hold_s = 2.0;                     ///< hold at the grip force before the load
        Factor load_rate_N_per_s{
            std::vector<double>{1.0}}; ///< total tangential load rate (grasp_load)
        Factor target_load_N{
            std::vector<double>{2.5}};      ///< total tangential load at the end (grasp_load)
        double load_direction_deg = 0.0;    ///< in the left finger's x-y plane, from +x
        int slip_frames = 3;                ///< frames kept once a finger slips (grasp_load)
        double slide_start_mm = 0.05;       ///< first frame's object travel (slide)
        double slide_end_mm = 6.0;          ///< last frame's object travel (slide)
        int slide_frames = 30;              ///< frames from start to end (slide)
        double slide_speed_mm_per_s = 10.0; ///< sets the slide frames' time stamps (slide)
    } protocol;

    /// How trials are drawn from the factors (objects, friction, grip, rate, target load).
    struct Sampling {
        std::string method = "full_grid"; ///< full_grid | random | latin_hypercube
        int repetitions = 1;              ///< full_grid: every grid cell this many times
        int trials = 1;                   ///< random, latin_hypercube: number of trials
        int sensor_variants = 8; ///< sensors drawn from the varied keys; 0: one per trial
        /// random (each trial picks a sensor) | crossed (full_grid: every cell on every sensor)
        std::string sensor_assignment = "random";
    } sampling;

    /// One split of the `splits` list: a fraction of the trials, assigned by a seeded shuffle.
    struct Split {
        std::string name = "all";
        double fraction = 1.0;
    };
    std::vector<Split> splits{Split{}};

    struct Render {
        int width_px = 256;
        int height_px = 256;
        int samples_per_pixel = 4;
        double exposure = 1.0;
        bool spectral = true; ///< hero-wavelength spectral mode; false: RGB approximation
        std::string integrator = "fast"; ///< preview | path | fast
        /// draft | default | high: the fast integrator's per-pixel-class sample counts
        /// (stage_params.hpp: QualityPreset).
        std::string quality = "default";
        /// The fast integrator's expert keys.
        struct Fast {
            int paths_per_vertex = 1024;    ///< render::LightCacheSettings::paths_per_vertex
            double refresh_threshold = 1.0; ///< render::LightCacheSettings::refresh_threshold
            double shadow_filter_px = 1.0;  ///< render::RenderSettings::shadow_filter_px
        } fast;
        /// The camera sensor model (render/sensor_model.hpp); the PNG only, the EXR stays the
        /// noise-free render.
        struct Sensor {
            bool enabled = false;
            std::uint64_t seed = 1;
            double gain = 1.0;
            double full_well_e = 1.0e4;
            double read_noise_e = 2.3;
            int adc_bits = 12;
            bool shot_noise = true;
            std::string vignetting = "polynomial"; ///< none | cos4 | polynomial
            double vignetting_k1 = -0.3, vignetting_k2 = 0.0;
        } sensor;
    } render;

    struct Outputs {
        bool images = true;      ///< PNG per frame (skips the whole render stage when false)
        bool labels = true;      ///< labels.csv
        bool markers = true;     ///< markers.csv (3D displacement of every marker)
        bool exr = false;        ///< linear float OpenEXR per frame
        bool marker_ids = false; ///< EXR channels inner_marker_id, outer_marker_id
        bool variance = false;   ///< EXR channels variance.R/G/B
        bool strain = false;     ///< strain/<split>/<trial>/<finger>.csv (eps_xx grids)
    } outputs;

    /// The `varied` keys written as a list or a range, by schema key ("sensor.materials.
    /// clear_layer.E_MPa"); each one's field holds its nominal value (a list's first item, a
    /// range's middle) until plan.hpp's sensor_spec() puts a variant's draw there.
    std::map<std::string, Factor> varied;

    /// The resolved spec (every key, defaults filled) as YAML, in schema order. Written next to
    /// the dataset and hashed to tell whether an existing output came from the same spec.
    std::string resolved_yaml;
};

/// A path written in the spec, resolved: relative paths start at the spec file's folder
/// (the working directory for a spec parsed from text).
std::filesystem::path resolve_spec_path(const Spec& spec, const std::filesystem::path& written);
/// The folder of the spectrum CSVs: sensor.spectra_dir resolved, or the shipped
/// assets/spectra when it is empty.
std::filesystem::path spectra_directory(const Spec& spec);

/// Reads, validates and resolves a spec file. Throws SpecError (with file:line:column, key,
/// value and what is allowed) on malformed YAML, unknown keys, wrong types, out-of-range or
/// disallowed values, and on cross-key constraints (at least one output enabled). Does no
/// other work and writes nothing.
Spec load_spec(const std::filesystem::path& path);

/// Same, from text; `display_name` stands in for the file name in messages.
Spec parse_spec(const std::string& yaml_text, const std::string& display_name);

/// A resolved spec read back from a dataset or part (spec.resolved.yaml without its comment
/// lines), for work that reads none of the files it names (`merge`): validated like
/// parse_spec, except that objects' mesh files and the spectra folder need not exist.
/// `source_path` is `source` (the path generate was given), `resolved_yaml` the exact text.
Spec parse_stored_spec(const std::string& resolved_yaml, const std::string& source);

/// The schema as a Markdown table (key, type, default, unit, allowed, doc): the user manual.
std::string schema_markdown();

} // namespace chromasim::generators
