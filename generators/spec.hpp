#pragma once
/// The typed, validated contents of a dataset spec file (YAML). Every field has a schema
/// entry (generators/spec_schema.cpp) with its type, default, unit, allowed range and doc
/// line; `chromasim schema` prints that table, docs/SPEC_REFERENCE.md holds a copy.
#include <array>
#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>

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

struct LayerMaterial {
    double E_MPa = 1.0; ///< Young's modulus, MPa (= N/mm^2)
    double nu = 0.45;   ///< Poisson's ratio
};

struct Spec {
    std::filesystem::path source_path; ///< the file it was read from
    std::string name = "unnamed";
    std::uint64_t seed = 1;

    struct Sensor {
        std::string mesh_level = "coarse";        ///< coarse | medium | fine
        std::string volumetric = "nodal_average"; ///< nodal_average | element
        std::string material_model = "linear";    ///< linear | neo_hookean
        std::string interior = "hollow";          ///< hollow | rigid_core | soft_fill
        int contact_steps = 4; ///< load steps from rest to the first frame, per phase
        LayerMaterial inner_marker_layer{0.8, 0.45};
        LayerMaterial clear_layer{0.3, 0.45};
        LayerMaterial outer_marker_layer{0.8, 0.45};
        LayerMaterial coating{1.0, 0.45};
        LayerMaterial fill{0.05, 0.45}; ///< used only with interior soft_fill
        double contact_candidate_angle_deg = 35.0;
        double camera_half_fov_deg = 84.0;
        std::string camera_model = "equidistant"; ///< equidistant | kannala_brandt
        /// Kannala-Brandt intrinsics, OpenCV convention; 0: derived from the image size and
        /// camera_half_fov_deg (the equidistant camera's values).
        double camera_fx_px = 0, camera_fy_px = 0, camera_cx_px = 0, camera_cy_px = 0;
        double camera_k1 = 0, camera_k2 = 0, camera_k3 = 0, camera_k4 = 0;
        std::array<double, 3> camera_position_mm{0.0, 0.0, 0.0}; ///< in the dome frame
        double camera_roll_deg = 0, camera_pitch_deg = 0, camera_yaw_deg = 0;
        int led_count = 6;
        double led_ring_radius_mm = 10.0;
        double led_z_mm = -1.0;
        double led_width_mm = 3.5, led_height_mm = 2.8;
        Rgb led_rgb{1.0, 1.0, 1.0};
        double refractive_index = 1.4;
        double marker_thickness_mm = 0.5;
        Rgb coating_albedo{0.85, 0.85, 0.85};
        Rgb inner_marker_absorption_per_mm{0.2, 3.0, 0.3};
        Rgb outer_marker_absorption_per_mm{3.0, 0.3, 0.2};
        Rgb outer_marker_albedo{0.10, 0.70, 0.75};
        double outer_marker_scatter_fraction = 0.5;
        std::string spectra_dir; ///< spectrum CSVs (empty: the shipped assets/spectra)
    } sensor;

    struct Object {
        std::string shape = "flat"; ///< flat (rigid plane) | sphere | mesh
        double radius_mm = 45.0;    ///< sphere radius
        double mu = 0.8;            ///< Coulomb friction coefficient
        std::string mesh_file;      ///< glTF file of a mesh object (relative: to the spec file)
        double offset_x_mm = 0, offset_y_mm = 0;         ///< mesh object's origin in x-y
        double roll_deg = 0, pitch_deg = 0, yaw_deg = 0; ///< its rotation (x, then y, then z)
    } object;

    struct Press {
        double normal_force_N = 1.5; ///< grip force reached at the end of the press
        int frames = 2; ///< frames of the linear normal-force ramp (last one at full force)
    } press;

    struct Pull {
        std::string control = "force";   ///< force | displacement
        double tangential_force_N = 0.5; ///< tangential load reached at the end of the pull
        double displacement_mm = 1.0;    ///< object travel at the end of a displacement pull
        double direction_deg = 0.0;      ///< direction of the pull in the x-y plane, from +x
        int frames = 3;                  ///< frames of the linear tangential ramp (0: no pull)
    } pull;

    struct Render {
        int width_px = 256;
        int height_px = 256;
        int samples_per_pixel = 4;
        double exposure = 1.0;
        bool spectral = true; ///< hero-wavelength spectral mode; false: RGB approximation
        std::string integrator = "direct"; ///< direct | path | fast
        /// The fast integrator's light cache (render::LightCacheSettings).
        struct Fast {
            int paths_per_vertex = 256;
            int direct_samples = 16;
            double smoothing_mm = 0.75;
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
    } outputs;

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

/// The schema as a Markdown table (key, type, default, unit, allowed, doc): the user manual.
std::string schema_markdown();

} // namespace chromasim::generators
