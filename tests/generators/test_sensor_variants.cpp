// A randomized sensor: `varied` keys written as lists or ranges, the sensors the plan draws
// from them, the spec of each, and end to end: sensors.csv names each trial's sensor and its
// values, the values change what the images and labels show, `check` verifies them, and a
// sharded run merges into the same bytes.
#include "generators/output/check.hpp"
#include "generators/pipeline/simulator.hpp"
#include "generators/plan/plan.hpp"
#include "generators/plan/sensor_variants.hpp"
#include "generators/spec/spec.hpp"
#include "generators/spec/stage_params.hpp"

#include "run_chromasim.hpp"
#include "scratch_dir.hpp"
#include "test_files.hpp"

#include <catch2/catch.hpp>

#include <fstream>
#include <map>
#include <set>
#include <string>

namespace fs = std::filesystem;
using namespace chromasim::generators;
using Catch::Matchers::Contains;
using Catch::Matchers::StartsWith;
using chromasim::generators::test::error_of;
using chromasim::generators::test::read_csv;

namespace {

const char* kE = "sensor.materials.clear_layer.E_MPa";
const char* kInk = "sensor.optics.inner_marker_absorption_scale";

/// One fingertip, linear tets (a fast precompute), 32 px preview images; the clear layer's E
/// and the inner dye's strength vary over `variants` sensors.
std::string varied_spec(int variants, int repetitions = 4) {
    return R"(name: varied
seed: 5
sensor:
  mesh_level: very_coarse
  element_order: 1
  material_model: linear
  materials:
    clear_layer: {E_MPa: [0.2, 0.4]}
  optics:
    inner_marker_absorption_scale: {min: 0.5, max: 2.0}
objects: [{name: flat, shape: flat}]
friction: [{name: m, mu: 0.8}]
fingers: {count: 1}
protocol: {type: grasp_load, frame_rate_Hz: 10, grip_N: 1.0, grasp_s: 0.2, hold_s: 0.1,
           load_rate_N_per_s: 2.0, target_load_N: 0.4}
sampling: {method: full_grid, repetitions: )" +
           std::to_string(repetitions) + ", sensor_variants: " + std::to_string(variants) + R"(}
render: {width_px: 32, height_px: 32, samples_per_pixel: 1, integrator: preview}
outputs: {images: true, labels: true, markers: false}
)";
}

} // namespace

TEST_CASE("a varied key is one number, or a list or range kept apart with a nominal value",
          "[generators][sensors]") {
    const Spec fixed = parse_spec("sensor: {materials: {clear_layer: {E_MPa: 0.35}}}\n", "a.yaml");
    CHECK(fixed.sensor.clear_layer.E_MPa == 0.35);
    CHECK(fixed.varied.empty());
    CHECK_THAT(fixed.resolved_yaml, Contains("E_MPa: 0.35\n")); // a plain number, as before
    const Spec spec = parse_spec(varied_spec(2), "v.yaml");
    REQUIRE(spec.varied.size() == 2);
    CHECK(spec.sensor.clear_layer.E_MPa == 0.2);                 // a list's first item
    CHECK(spec.sensor.inner_marker_absorption_scale == 1.25);    // a range's middle
    CHECK_THAT(spec.resolved_yaml, Contains("E_MPa: [0.2, 0.4]"));
    CHECK_THAT(spec.resolved_yaml, Contains("inner_marker_absorption_scale: {min: 0.5, max: 2.0}"));
    CHECK(parse_stored_spec(spec.resolved_yaml, "v.yaml").varied == spec.varied);
}

TEST_CASE("a varied key's values and every value it can draw are checked before any work",
          "[generators][sensors]") {
    CHECK(error_of("sensor: {materials: {clear_layer: {E_MPa: [0.2, -1]}}}\n") ==
          "bad.yaml:1:49: sensor.materials.clear_layer.E_MPa[1]: value '-1' is out of range; "
          "allowed: number in (0, 1000] (MPa), or a list or {min, max} of them (a varied "
          "sensor)");
    // The coating's spectrum peaks at 0.85: a scale that may draw 1.3 makes it reflect 1.1.
    CHECK_THAT(error_of("sensor: {optics: {coating_albedo_scale: {min: 0.9, max: 1.3}}}\n"),
               StartsWith("bad.yaml:1:19: sensor.optics.coating_albedo_scale: value '{min: 0.9, "
                          "max: 1.3}' scales the coating's largest albedo 0.85 to 1.105"));
    // A rule between keys holds at the ends of each varied range: a wide field of view with a
    // Kannala-Brandt camera whose distortion folds back is refused at the range's top.
    CHECK_THAT(error_of("sensor:\n  camera: {model: kannala_brandt, k1: -0.2,\n"
                        "           half_fov_deg: {min: 40, max: 99}}\n"),
               Contains("(with sensor.camera.half_fov_deg at its highest, 99.0)"));
}

TEST_CASE("sensors are drawn per variant, picked per trial, and stay put in a slice",
          "[generators][sensors]") {
    const Spec fixed = parse_spec("name: x\n", "a.yaml");
    const Plan none = make_plan(fixed);
    CHECK(none.sensors.empty());
    CHECK(none.trials.front().sensor == -1);

    const Plan plan = make_plan(parse_spec(varied_spec(3, 40), "v.yaml"));
    REQUIRE(plan.sensors.size() == 3);
    std::set<int> used;
    std::set<double> E;
    for (const TrialPlan& t : plan.trials) {
        REQUIRE(t.sensor >= 0);
        REQUIRE(t.sensor < 3);
        used.insert(t.sensor);
    }
    CHECK(used.size() == 3); // 40 trials over 3 sensors
    for (const SensorVariant& v : plan.sensors) {
        REQUIRE(v.values.size() == 2);
        CHECK(v.values[0].first == kE);
        CHECK((v.values[0].second == 0.2 || v.values[0].second == 0.4));
        E.insert(v.values[0].second);
        CHECK(v.values[1].first == kInk);
        CHECK(v.values[1].second >= 0.5);
        CHECK(v.values[1].second <= 2.0);
    }
    CHECK(E.size() == 2);
    // Fewer trials (a shorter grid) keep each trial's sensor and each sensor's values.
    const Plan shorter = make_plan(parse_spec(varied_spec(3, 5), "v.yaml"));
    for (std::size_t k = 0; k < shorter.trials.size(); ++k)
        CHECK(shorter.trials[k].sensor == plan.trials[k].sensor);
    for (std::size_t v = 0; v < 3; ++v)
        CHECK(shorter.sensors[v].values == plan.sensors[v].values);
    // sensor_variants 0: a sensor per trial.
    const Plan own = make_plan(parse_spec(varied_spec(0, 6), "v.yaml"));
    REQUIRE(own.sensors.size() == 6);
    for (const TrialPlan& t : own.trials)
        CHECK(t.sensor == t.id);
}

TEST_CASE("crossed sensors run every grid cell on every sensor, repetitions times",
          "[generators][sensors]") {
    std::string yaml = varied_spec(3, 2);
    yaml.replace(yaml.find("sensor_variants"), 0, "sensor_assignment: crossed, ");
    yaml.replace(yaml.find("friction: [{name: m, mu: 0.8}]"), 30,
                 "friction: [{name: a, mu: 0.5}, {name: b, mu: 1.0}]");
    const Plan plan = make_plan(parse_spec(yaml, "v.yaml"));
    REQUIRE(plan.trials.size() == 2 * 3 * 2); // 2 cells x 3 sensors x 2 repetitions
    std::map<std::pair<int, int>, int> runs;  // (friction, sensor) -> trials
    for (const TrialPlan& t : plan.trials)
        ++runs[{t.friction, t.sensor}];
    REQUIRE(runs.size() == 6);
    for (const auto& [cell, n] : runs)
        CHECK(n == 2);
    CHECK(plan.trials[2].sensor == 1); // the sensor changes every 2 cells
    CHECK(error_of("sampling: {method: random, trials: 4, sensor_assignment: crossed}\n") ==
          "bad.yaml:1:39: sampling.sensor_assignment: value 'crossed' is crossed, which needs a "
          "full grid and a number of sensors; allowed: crossed with sampling.method full_grid "
          "and sampling.sensor_variants >= 1, or random");
}

TEST_CASE("a sensor's spec holds its draws and varies nothing", "[generators][sensors]") {
    const Spec spec = parse_spec(varied_spec(2), "v.yaml");
    const Plan plan = make_plan(spec);
    const Spec one = sensor_spec(spec, plan.sensors[1]);
    CHECK(one.varied.empty());
    CHECK(one.sensor.clear_layer.E_MPa == plan.sensors[1].values[0].second);
    CHECK(one.sensor.inner_marker_absorption_scale == plan.sensors[1].values[1].second);
    CHECK(one.sensor.coating.E_MPa == spec.sensor.coating.E_MPa);
}

// Generate writes each trial's sensor; its values show in the labels and images, check
// verifies them, and shards merge into the same bytes.
TEST_CASE("generate records each trial's sensor, check verifies it, shards merge the same",
          "[generators][sensors]") {
    ScratchDir dir("sensors");
    const fs::path spec_path = dir.write("varied.yaml", varied_spec(2));
    const Plan plan = make_plan(load_spec(spec_path));
    // Seed 5 draws both clear-layer moduli: the test compares them.
    REQUIRE(plan.sensors[0].values[0].second != plan.sensors[1].values[0].second);
    const fs::path out = dir.path / "out";
    const std::string cache = " --cache-dir " + (dir.path / "cache").string();
    const Run gen =
        run_chromasim(dir, "generate " + spec_path.string() + " -o " + out.string() + " -q" + cache);
    INFO(gen.output);
    REQUIRE(gen.code == 0);

    const auto sensors = read_csv(out / "sensors.csv");
    const auto labels = read_csv(out / "labels.csv");
    REQUIRE(sensors.size() == plan.trials.size());
    std::map<int, const chromasim::generators::test::CsvRow*> last_frame; // trial -> its last row
    for (const auto& row : labels)
        last_frame[std::stoi(row.at("trial"))] = &row;
    std::map<std::string, std::set<std::string>> indentation_by_E, image_by_sensor;
    for (const auto& row : sensors) {
        const int trial = std::stoi(row.at("trial"));
        const TrialPlan& t = plan.trials[std::size_t(trial)];
        CHECK(std::stoi(row.at("sensor")) == t.sensor);
        CHECK(std::stod(row.at(kE)) == plan.sensors[std::size_t(t.sensor)].values[0].second);
        const auto& last = *last_frame.at(trial);
        indentation_by_E[row.at(kE)].insert(last.at("left_indentation_mm"));
        image_by_sensor[row.at("sensor")].insert(
            chromasim::generators::sha256_file(out / last.at("left_image")));
    }
    // The same load on the same E indents the same; the softer clear layer indents deeper.
    REQUIRE(indentation_by_E.size() == 2);
    CHECK(indentation_by_E.at("0.2").size() == 1);
    CHECK(indentation_by_E.at("0.4").size() == 1);
    CHECK(std::stod(*indentation_by_E.at("0.2").begin()) >
          std::stod(*indentation_by_E.at("0.4").begin()));
    // Each sensor renders its own images.
    std::set<std::string> images;
    for (const auto& [sensor, hashes] : image_by_sensor) {
        CHECK(hashes.size() == 1);
        images.insert(hashes.begin(), hashes.end());
    }
    CHECK(images.size() == image_by_sensor.size());

    CheckReport report = check_dataset(out);
    CHECK(report.findings_total == 0);
    CHECK(report.sensor_rows == long(plan.trials.size()));

    // Shards merge into the unsharded bytes.
    for (const char* part : {"1/2", "2/2"}) {
        const fs::path p = dir.path / ("part" + std::string(1, part[0]));
        const Run r = run_chromasim(dir, "generate " + spec_path.string() + " -o " + p.string() +
                                             " -q --shard " + part + cache);
        INFO(r.output);
        REQUIRE(r.code == 0);
    }
    const fs::path merged = dir.path / "merged";
    const Run m = run_chromasim(dir, "merge -o " + merged.string() + " " +
                                         (dir.path / "part1").string() + " " +
                                         (dir.path / "part2").string());
    INFO(m.output);
    REQUIRE(m.code == 0);
    CHECK(tree(merged) == tree(out));

    // A value that is not the plan's draw, or not one the spec allows, is found.
    const auto rewrite = [&](const std::string& from, const std::string& to) {
        std::string text = chromasim::generators::read_file(out / "sensors.csv");
        const std::size_t at = text.find(from, text.find('\n'));
        REQUIRE(at != std::string::npos);
        text.replace(at, from.size(), to);
        std::ofstream(out / "sensors.csv", std::ios::binary) << text;
    };
    const std::string E = sensors.front().at(kE);
    rewrite("," + E + ",", E == "0.2" ? ",0.4," : ",0.2,");
    report = check_dataset(out);
    REQUIRE(report.findings_total == 1);
    CHECK(report.findings[0].file == "sensors.csv");
    CHECK(report.findings[0].line == 2);
    CHECK(report.findings[0].column == kE);
    CHECK_THAT(report.findings[0].problem, StartsWith("not the plan's draw"));
    rewrite(E == "0.2" ? ",0.4," : ",0.2,", ",0.3,");
    report = check_dataset(out);
    REQUIRE(report.findings_total == 1);
    CHECK(report.findings[0].problem == "outside the spec's [0.2, 0.4]");
}

TEST_CASE("a Simulator is one sensor: a varied spec is refused with what to do",
          "[generators][sensors]") {
    const Spec spec = parse_spec(varied_spec(2), "v.yaml");
    try {
        Simulator simulator(spec, "");
        FAIL("a Simulator was made of a varied spec");
    } catch (const SpecError& e) {
        CHECK_THAT(e.what(), Contains("varies its sensor (sensor.materials.clear_layer.E_MPa, "
                                      "...); a Simulator is one sensor"));
    }
}

TEST_CASE("LED gains: one number or one per LED, and each sensor draws its own within the "
          "tolerance",
          "[generators][sensors]") {
    const Spec fixed = parse_spec("sensor: {led: {count: 3, gains: [1.0, 0.9, 1.1]}}\n", "a.yaml");
    CHECK(fixed.sensor.led_gains == std::vector<double>{1.0, 0.9, 1.1});
    CHECK_FALSE(varies_sensor(fixed));
    CHECK(optics_params(fixed).led_gain == std::vector<double>{1.0, 0.9, 1.1});
    CHECK(optics_params(parse_spec("name: x\n", "a.yaml")).led_gain == std::vector<double>(6, 1.0));
    CHECK(error_of("sensor: {led: {count: 3, gains: [1.0, 0.9]}}\n") ==
          "bad.yaml:1:26: sensor.led.gains: value '[1.0, 0.9]' does not hold one gain per LED; "
          "allowed: "
          "one number for every LED, or a list of sensor.led.count numbers");
    CHECK_THAT(error_of("sensor: {led: {gains: {min: 0.9, max: 1.1}}}\n"),
               Contains("sensor.led.gains: value '{min: 0.9, max: 1.1}' is a mapping, not a list"));
    CHECK_THAT(error_of("sensor: {led: {gains: [1, -0.5]}}\n"), Contains("sensor.led.gains[1]"));

    std::string yaml = varied_spec(3);
    yaml.insert(yaml.find("sensor:\n") + 8, "  led: {count: 3, gains: 2.0, gain_tolerance: 0.1}\n");
    const Spec spec = parse_spec(yaml, "v.yaml");
    REQUIRE(varies_sensor(spec));
    const Plan plan = make_plan(spec);
    for (const SensorVariant& v : plan.sensors) {
        REQUIRE(v.values.size() == 5); // E, the inner dye, then 3 LEDs
        CHECK(v.values[2].first == "sensor.led.gains[0]");
        const Spec one = sensor_spec(spec, v);
        CHECK_FALSE(varies_sensor(one));
        for (int k = 0; k < 3; ++k) {
            const double g = v.values[std::size_t(2 + k)].second;
            CHECK(g >= 1.8);
            CHECK(g <= 2.2);
            CHECK(one.sensor.led_gains[std::size_t(k)] == g);
        }
    }
    CHECK(plan.sensors[0].values[2].second != plan.sensors[1].values[2].second);
    // The varied keys draw as they did without LED gains.
    const Plan without = make_plan(parse_spec(varied_spec(3), "v.yaml"));
    CHECK(without.sensors[2].values[1] == plan.sensors[2].values[1]);
}

TEST_CASE("generate records each sensor's LED gains and check verifies them",
          "[generators][sensors]") {
    ScratchDir dir("led_gains");
    std::string yaml = varied_spec(2, 2);
    yaml.insert(yaml.find("sensor:\n") + 8, "  led: {gain_tolerance: 0.2}\n");
    const fs::path spec_path = dir.write("gains.yaml", yaml);
    const Plan plan = make_plan(load_spec(spec_path));
    const fs::path out = dir.path / "out";
    const Run gen = run_chromasim(dir, "generate " + spec_path.string() + " -o " + out.string() +
                                           " -q --cache-dir " + (dir.path / "cache").string());
    INFO(gen.output);
    REQUIRE(gen.code == 0);
    const auto sensors = read_csv(out / "sensors.csv");
    REQUIRE(sensors.size() == plan.trials.size());
    for (const auto& row : sensors) {
        const SensorVariant& v = plan.sensors[std::size_t(std::stoi(row.at("sensor")))];
        for (int k = 0; k < 6; ++k) {
            const std::string key = "sensor.led.gains[" + std::to_string(k) + "]";
            CHECK(std::stod(row.at(key)) == v.values[std::size_t(2 + k)].second);
        }
    }
    CHECK(check_dataset(out).findings_total == 0);
    // A gain outside 1 +- 0.2 is found.
    std::string text = chromasim::generators::read_file(out / "sensors.csv");
    const std::string gain = sensors.front().at("sensor.led.gains[5]");
    const std::size_t at = text.find("," + gain + "\n");
    REQUIRE(at != std::string::npos);
    text.replace(at, gain.size() + 2, ",1.5\n");
    std::ofstream(out / "sensors.csv", std::ios::binary) << text;
    const CheckReport report = check_dataset(out);
    REQUIRE(report.findings_total == 1);
    CHECK(report.findings[0].column == "sensor.led.gains[5]");
    CHECK(report.findings[0].problem == "outside the spec's {min: 0.8, max: 1.2}");
}

TEST_CASE("each sensor draws its camera's position within the tolerance", "[generators][sensors]") {
    std::string yaml = varied_spec(3);
    yaml.insert(yaml.find("sensor:\n") + 8,
                "  camera: {position_mm: [0.1, 0.0, -0.2], position_tolerance_mm: 0.15}\n");
    const Spec spec = parse_spec(yaml, "v.yaml");
    REQUIRE(varies_sensor(spec));
    const Plan plan = make_plan(spec);
    const std::array<double, 3> centre{0.1, 0.0, -0.2};
    for (const SensorVariant& v : plan.sensors) {
        REQUIRE(v.values.size() == 5); // E, the inner dye, then x, y, z
        const Spec one = sensor_spec(spec, v);
        CHECK_FALSE(varies_sensor(one));
        for (std::size_t i = 0; i < 3; ++i) {
            CHECK(v.values[2 + i].first == "sensor.camera.position_mm[" + std::to_string(i) + "]");
            CHECK(std::abs(v.values[2 + i].second - centre[i]) <= 0.15);
            CHECK(one.sensor.camera_position_mm[i] == v.values[2 + i].second);
        }
    }
    CHECK(plan.sensors[0].values[2].second != plan.sensors[1].values[2].second);
    CHECK(error_of("sensor: {camera: {position_mm: [9.95, 0, 0], position_tolerance_mm: 0.1}}\n") ==
          "bad.yaml:1:46: sensor.camera.position_tolerance_mm: value '0.1' lets a drawn camera "
          "position leave [-10, 10] mm; allowed: |each of sensor.camera.position_mm| + the "
          "tolerance up to 10 mm");
}
