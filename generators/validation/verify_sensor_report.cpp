// `chromasim verify sensor`'s table and JSON (verify_sensor.hpp).
#include "generators/validation/verify_sensor.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <iomanip>
#include <ostream>

namespace chromasim::generators {

namespace {

/// A number for JSON: null when not finite.
nlohmann::json number(double x) {
    return std::isfinite(x) ? nlohmann::json(x) : nlohmann::json();
}

nlohmann::json fit_json(const LineFit& f) {
    return {{"slope", number(f.slope)}, {"r2", number(f.r2)}, {"points", f.points}};
}

nlohmann::json summary_json(const LawSummary& s) {
    return {{"markers", s.markers},
            {"r2_median", number(s.r2_median)},
            {"r2_p10", number(s.r2_p10)},
            {"slope_median", number(s.slope_median)},
            {"range_median", number(s.range_median)},
            {"pooled", fit_json(s.pooled)}};
}

void print_law(std::ostream& out, const std::string& object, const char* law, const LawSummary& s,
               const char* slope_unit, const char* range_name) {
    out << "  " << std::left << std::setw(7) << object << std::setw(32) << law << std::right
        << std::setw(4) << s.markers << std::setw(9) << s.r2_median << std::setw(9) << s.r2_p10
        << std::setw(9) << s.pooled.r2 << std::setw(10) << s.slope_median << " " << std::left
        << std::setw(8) << slope_unit << std::right << std::setw(8) << s.range_median << " "
        << range_name << "\n";
}

const char* cue_name(NormalCue cue) {
    return cue == NormalCue::size ? "size" : "hue";
}

} // namespace

void print_sensor_verify(const SensorVerifyReport& r, std::ostream& out) {
    out << "chromasim verify sensor: " << r.spec << ", " << r.render << " (a marker spans "
        << std::fixed << std::setprecision(1) << r.marker_span_px << " px); " << r.seconds
        << " s\n";
    out << "  hue and area: markers within " << kLawCapDeg << " deg of the apex that move "
        << kLawMinTravelMm << " mm or more inward; centroid: markers that move " << kLawMinTravelMm
        << " mm or more sideways\n\n";
    out << "  object law                           markers R2 med   R2 p10   pooled    "
           "slope (median)    range (median)\n"
        << std::setprecision(3);
    for (const ObjectLaws& o : r.objects) {
        print_law(out, o.object, "hue vs normal displacement", o.hue, "deg/mm", "deg");
        print_law(out, o.object, "area vs normal displacement", o.area, "1/mm", "dE76");
        print_law(out, o.object, "centroid vs lateral displ.", o.centroid, "px/mm", "mm");
    }
    out << "\n" << std::setprecision(1);
    for (const ObjectLaws& o : r.objects)
        out << "  " << o.object << ": apex marker hue " << o.apex_hue_rest_deg << " deg at rest, "
            << o.apex_hue_pressed_deg << " deg at the full press (colour change dE76 "
            << o.apex_delta_e << ", area " << std::showpos << 100 * o.apex_area_change
            << std::noshowpos << " %); " << o.frames << " images, " << o.flagged_frames
            << " flagged frames left out, " << o.tracked << " markers tracked to the end; "
            << o.id_checks << " blobs checked against the marker id channel, " << o.id_mismatches
            << " not the marker taken for\n";
    out << "\n  targets: the " << cue_name(r.cue) << " cue carries the normal displacement ("
        << (r.cue == NormalCue::size ? "a hollow shell: its marker arrays move together"
                                     : "a supported clear layer, squeezed between the arrays")
        << ")\n"
        << std::setprecision(3);
    for (const auto& t : r.targets)
        out << "  " << (t.met() ? "ok  " : "FAIL") << "  " << t.what << ": " << t.measured
            << (t.at_least ? " >= " : " <= ") << t.bound << "\n";
    out << std::defaultfloat;
}

void write_sensor_verify_json(const SensorVerifyReport& r, std::ostream& out) {
    nlohmann::json j{{"spec", r.spec},
                     {"render", r.render},
                     {"marker_span_px", r.marker_span_px},
                     {"cue", cue_name(r.cue)},
                     {"cap_deg", kLawCapDeg},
                     {"min_travel_mm", kLawMinTravelMm},
                     {"seconds", r.seconds},
                     {"all_targets_met", r.all_met()}};
    for (const ObjectLaws& o : r.objects) {
        nlohmann::json markers = nlohmann::json::array();
        for (const MarkerLaw& m : o.markers)
            markers.push_back({{"marker", m.marker},
                               {"polar_deg", m.polar_deg},
                               {"normal_travel_mm", m.normal_travel_mm},
                               {"hue", fit_json(m.hue)},
                               {"area", fit_json(m.area)},
                               {"hue_range_deg", m.hue_range_deg},
                               {"hue_rest_deg", m.hue_rest_deg},
                               {"hue_pressed_deg", m.hue_pressed_deg},
                               {"delta_e76", m.delta_e},
                               {"area_change", m.area_change},
                               {"lateral_travel_mm", m.lateral_travel_mm},
                               {"centroid", fit_json(m.centroid)}});
        j["objects"].push_back({{"object", o.object},
                                {"frames", o.frames},
                                {"flagged_frames", o.flagged_frames},
                                {"tracked", o.tracked},
                                {"id_checks", o.id_checks},
                                {"id_mismatches", o.id_mismatches},
                                {"hue", summary_json(o.hue)},
                                {"area", summary_json(o.area)},
                                {"centroid", summary_json(o.centroid)},
                                {"apex_hue_rest_deg", o.apex_hue_rest_deg},
                                {"apex_hue_pressed_deg", o.apex_hue_pressed_deg},
                                {"apex_delta_e76", o.apex_delta_e},
                                {"apex_area_change", o.apex_area_change},
                                {"markers", markers}});
    }
    for (const auto& t : r.targets)
        j["targets"].push_back({{"what", t.what},
                                {"measured", number(t.measured)},
                                {"bound", t.bound},
                                {"at_least", t.at_least},
                                {"met", t.met()}});
    out << j.dump(2) << "\n";
}

} // namespace chromasim::generators
