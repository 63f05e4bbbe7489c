#pragma once
/// `chromasim verify sensor`: the sensor's own laws measured from rendered images, as the
/// ChromaTouch papers measure them on the real sensor (docs/SENSOR.md). It generates a press
/// from 0 to 3 N and then a lateral load to slip, for a flat and a 45 mm sphere, and reads the
/// PNGs back: blobs of pixels with saturation above 50 %, tracked from the rest image; each
/// blob's mean hue and pixel count against its outer marker's inward normal displacement, and
/// its centroid against the marker's lateral displacement (markers.csv). The marker id channel
/// only checks that each tracked blob is the marker it was taken for.
#include "generators/validation/sensor_laws.hpp"

#include <filesystem>
#include <iosfwd>
#include <string>
#include <vector>

namespace chromasim::generators {

struct SensorVerifyOptions {
    /// The spec whose sensor and render sections are verified (empty: the default sensor with
    /// the shipped fast render settings). Its objects, protocol and outputs are replaced.
    std::filesystem::path spec_file;
    int size_px = 448;               ///< square image side; a marker must span >= 10 px
    std::filesystem::path json;      ///< also write the results here (empty: no)
    std::filesystem::path picture;   ///< PNG of the apex marker at rest and at 3 N (empty: no)
    std::filesystem::path keep_dir;  ///< keep the rendered dataset here (empty: a temporary one)
    std::filesystem::path cache_dir; ///< mechanics and light cache (GenerateOptions::cache_dir)
};

inline constexpr double kLawCapDeg = 25.0;       ///< markers within this of the apex
inline constexpr double kLawMinTravelMm = 0.2;   ///< a marker's law needs this much travel
inline constexpr double kMinMarkerSpanPx = 10.0; ///< smallest marker image the metrics take
/// A hue change a person sees in the marker under the contact's centre: the ICRA 2020 dome's
/// calibration of that marker spans about 13 deg over 1.4 mm (docs/SENSOR.md).
inline constexpr double kVisibleHueChangeDeg = 10.0;
/// A size change a person and the CNN see: the apex marker's apparent diameter grows by at
/// least this many pixels at the CNN's input size (seed 000 resizes its images to 224 px).
inline constexpr double kVisibleSizeChangePx = 1.0;
inline constexpr int kCnnInputPx = 224;

/// One marker's laws over the press (hue, area) and the lateral load (centroid).
struct MarkerLaw {
    int marker = 0;
    double polar_deg = 0;
    double normal_travel_mm = 0; ///< largest inward normal displacement over the press
    LineFit hue;                 ///< hue change (deg) against inward normal displacement (mm)
    LineFit area;                ///< relative pixel count change against it
    double hue_range_deg = 0;    ///< largest minus smallest hue change over the press
    double delta_e = 0;          ///< CIE76 difference of its mean colour, rest to full press
    double hue_rest_deg = 0, hue_pressed_deg = 0; ///< its mean hue at rest and at full press
    double area_change = 0; ///< relative change of its pixel count, rest to full press
    double lateral_travel_mm = 0;
    LineFit centroid; ///< centroid shift (px) against lateral displacement (mm)
};

/// Median and 10th percentile of one law's R^2 over the markers that qualify.
struct LawSummary {
    int markers = 0;
    double r2_median = 0, r2_p10 = 0, slope_median = 0;
    double range_median = 0; ///< hue: hue range (deg); area: colour change (CIE76); centroid: mm
    LineFit pooled;          ///< one line through every qualifying marker's points
};

struct ObjectLaws {
    std::string object;
    int frames = 0;         ///< images read (rest included)
    int flagged_frames = 0; ///< frames left out: the solver did not converge
    int tracked = 0;        ///< markers tracked from rest to the last frame
    int id_checks = 0, id_mismatches = 0;
    std::vector<MarkerLaw> markers;
    LawSummary hue, area, centroid;
    double apex_hue_rest_deg = 0, apex_hue_pressed_deg = 0, apex_delta_e = 0;
    double apex_area_change = 0;
};

/// The cue that carries the normal displacement, and so the law a sensor is held to. A
/// supported clear layer (`rigid_core`, `soft_fill`) is squeezed between the marker arrays, as
/// in the papers' builds: the hue cue. A hollow shell moves both arrays together and the far
/// marker grows in the image instead: the size cue (docs/SENSOR.md).
enum class NormalCue { hue, size };
NormalCue normal_cue(const std::string& interior);

struct SensorVerifyReport {
    std::string spec;   ///< the spec file, or "default sensor"
    std::string render; ///< integrator, samples, size
    double marker_span_px = 0;
    NormalCue cue = NormalCue::size; ///< the cue the targets hold the sensor to
    std::vector<ObjectLaws> objects;
    double seconds = 0;
    /// The targets of docs/VALIDATION.md ("Sensor laws"), each with its result.
    struct Target {
        std::string what;
        double measured = 0, bound = 0;
        bool at_least = true;
        bool met() const { return at_least ? measured >= bound : measured <= bound; }
    };
    std::vector<Target> targets;
    bool all_met() const;
};

/// Fills `report.targets` from its objects' laws and its cue (docs/VALIDATION.md, "Sensor
/// laws").
void add_sensor_targets(SensorVerifyReport& report, int size_px);

/// Checks the options (spec, image size, output paths) before any work: a SpecError names what
/// to fix and nothing is written. Then generates, measures and returns the report; writes the
/// JSON and the picture when asked for.
SensorVerifyReport verify_sensor(const SensorVerifyOptions& options, std::ostream& log);

void print_sensor_verify(const SensorVerifyReport& report, std::ostream& out);
void write_sensor_verify_json(const SensorVerifyReport& report, std::ostream& out);

} // namespace chromasim::generators
