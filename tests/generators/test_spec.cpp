// Spec files: the committed quickstart validates, defaults fill, every class of bad input is
// rejected with FILE:LINE:COL, key, value and what is allowed, and the resolved YAML is a
// deterministic, exact round trip.
#include "generators/pipeline/sensor_bridge.hpp"
#include "generators/spec/spec.hpp"
#include "generators/spec/spec_schema.hpp"

#include "scratch_dir.hpp"
#include "test_files.hpp"

#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <numbers>
#include <regex>
#include <sstream>

using namespace chromasim::generators;
using Catch::Matchers::Contains;
using Catch::Matchers::EndsWith;
using Catch::Matchers::StartsWith;
using chromasim::generators::test::error_of;

namespace {

/// A path inside the repository (the tests also run from the repository root).
std::filesystem::path repo_file(const std::string& relative) {
#ifdef CHROMASIM_SOURCE_DIR
    return std::filesystem::path(CHROMASIM_SOURCE_DIR) / relative;
#else
    return relative;
#endif
}


/// Items of the list `entry` lies in (1 outside lists).
std::size_t items(const Spec& spec, const SchemaEntry& entry) {
    const std::string list = entry.list();
    return list.empty() ? 1 : find_schema_list(list)->size(spec);
}

/// Every schema value of two specs agrees, in every item of every list.
void require_same_values(const Spec& a, const Spec& b) {
    for (const SchemaEntry& e : spec_schema()) {
        INFO(e.key);
        REQUIRE(items(a, e) == items(b, e));
        for (std::size_t i = 0; i < items(a, e); ++i)
            CHECK(e.get(a, i) == e.get(b, i));
    }
}

const char* const quickstart_reordered = R"(# same values as quickstart.yaml, other order
outputs: {markers: true, labels: true, images: true}
render: {exposure: 1, samples_per_pixel: 4, integrator: fast, height_px: 128, width_px: 128,
         fast: {paths_per_vertex: 256}}
splits: [{fraction: 0.5, name: train}, {name: test, fraction: 0.5}]
sampling: {repetitions: 1}
protocol:
  slip_frames: 2
  target_load_N: [1.8]   # a comment
  load_rate_N_per_s: 4
  hold_s: 0.2
  grasp_s: 0.2
  grip_N: 1.0
  frame_rate_Hz: 10
friction:
  - {mu: 0.8}
objects: [{shape: flat}, {radius_mm: 45, shape: sphere, name: curved}]
seed: 1
name: quickstart
sensor:
  mesh_level: very_coarse
)";

} // namespace

TEST_CASE("the quickstart spec validates with its documented values", "[generators][spec]") {
    const std::filesystem::path path = repo_file("datasets_spec/quickstart.yaml");
    const Spec spec = load_spec(path);
    CHECK(spec.source_path == path);
    CHECK(spec.name == "quickstart");
    CHECK(spec.seed == 1);
    CHECK(spec.sensor.mesh_level == "very_coarse");
    CHECK(spec.sensor.element_order == 2);
    REQUIRE(spec.objects.size() == 2);
    CHECK(spec.objects[0].name == "flat");
    CHECK(spec.objects[0].shape == "flat");
    CHECK(spec.objects[1].name == "curved");
    CHECK(spec.objects[1].shape == "sphere");
    CHECK(spec.objects[1].radius_mm == 45.0);
    REQUIRE(spec.friction.size() == 1);
    CHECK(spec.friction[0].mu == Factor{{0.8}});
    CHECK(spec.fingers.count == 2);
    CHECK(spec.protocol.type == "grasp_load");
    CHECK(spec.protocol.frame_rate_Hz == 10.0);
    CHECK(spec.protocol.grip_N == Factor{{1.0}});
    CHECK(spec.protocol.target_load_N == Factor{{1.8}});
    CHECK(spec.protocol.load_direction_deg == 0.0);
    CHECK(spec.sampling.method == "full_grid");
    REQUIRE(spec.splits.size() == 2);
    CHECK(spec.splits[0].name == "train");
    CHECK(spec.splits[1].fraction == 0.5);
    CHECK(spec.render.width_px == 128);
    CHECK(spec.render.height_px == 128);
    CHECK(spec.render.samples_per_pixel == 4);
    CHECK((spec.outputs.images && spec.outputs.labels && spec.outputs.markers));
}

TEST_CASE("a minimal spec gets the documented defaults", "[generators][spec]") {
    const Spec spec = parse_spec("name: x\n", "min.yaml");
    CHECK(spec.name == "x");
    CHECK(spec.source_path.empty());
    for (const SchemaEntry& e : spec_schema()) {
        if (e.key == "name") continue;
        INFO(e.key);
        REQUIRE(items(spec, e) == 1); // a list left out holds one item of defaults
        CHECK(e.get(spec, 0) == e.default_value);
    }
    // The values the project brief asks for, independent of the schema table.
    CHECK(spec.seed == 1);
    CHECK(spec.sensor.mesh_level == "very_coarse");
    CHECK(spec.sensor.element_order == 2);
    CHECK(spec.sensor.inner_marker_layer.E_MPa == 0.8);
    CHECK(spec.sensor.clear_layer.E_MPa == 0.3);
    CHECK(spec.sensor.outer_marker_layer.E_MPa == 0.8);
    CHECK(spec.sensor.coating.E_MPa == 1.0);
    CHECK(spec.sensor.coating.nu == 0.45);
    CHECK(spec.sensor.contact_candidate_angle_deg == 50.0);
    CHECK(spec.sensor.material_model == "neo_hookean");
    CHECK(spec.sensor.camera_half_fov_deg == 84.0);
    CHECK(spec.sensor.led_count == 6);
    CHECK(spec.sensor.led_ring_radius_mm == 10.0);
    CHECK(spec.sensor.led_z_mm == -13.8);
    CHECK(spec.sensor.coating_albedo == Rgb{0.85, 0.85, 0.85});
    CHECK(spec.sensor.inner_marker_absorption_per_mm == Rgb{0.2, 3.0, 0.3});
    CHECK(spec.sensor.outer_marker_absorption_per_mm == Rgb{3.0, 0.3, 0.2});
    CHECK(spec.sensor.outer_marker_albedo == Rgb{0.10, 0.70, 0.75});
    CHECK(spec.sensor.outer_marker_scatter_fraction == 0.5);
    CHECK(spec.protocol.grip_N == Factor{{1.5}});
    CHECK(spec.protocol.hold_s == 2.0);
    CHECK(spec.protocol.frame_rate_Hz == 100.0);
    CHECK(spec.protocol.slip_frames == 3);
    CHECK(spec.fingers.count == 2);
    CHECK(spec.fingers.mu_jitter == 0.0);
    CHECK(spec.sampling.method == "full_grid");
    CHECK(spec.sampling.repetitions == 1);
    CHECK(spec.objects.size() == 1);
    CHECK(spec.friction[0].mu == Factor{{0.8}});
    CHECK(spec.splits.size() == 1);
    CHECK(spec.splits[0].fraction == 1.0);
    CHECK(spec.render.exposure == 1.0);
    CHECK(parse_spec("seed: 3\n", "min.yaml").name == "unnamed");
}

TEST_CASE("an empty section keeps its defaults", "[generators][spec]") {
    const Spec spec = parse_spec("sensor:\nprotocol:\n  slide:\n", "min.yaml");
    require_same_values(spec, default_spec());
}

TEST_CASE("the in-class defaults of Spec agree with the schema", "[generators][spec]") {
    const Spec plain;
    for (const SchemaEntry& e : spec_schema()) {
        if (e.key == "name") continue; // Spec{} leaves it empty; the schema says "unnamed"
        INFO(e.key);
        CHECK(e.get(plain, 0) == e.default_value);
    }
}

TEST_CASE("the schema is well formed", "[generators][spec]") {
    for (const SchemaEntry& e : spec_schema()) {
        INFO(e.key);
        CHECK(!e.doc.empty());
        CHECK(find_schema_entry(e.key) == &e); // keys are unique
        const std::string text = value_to_yaml(e.default_value, e.type);
        if (e.type == ValueType::Rgb || e.type == ValueType::Vec3) {
            for (double c : std::get<Rgb>(e.default_value))
                CHECK(e.range.contains(c));
        } else if (e.type == ValueType::Factor) {
            const Factor& f = std::get<Factor>(e.default_value);
            CHECK_FALSE(f.values.empty());
            for (double x : f.values)
                CHECK(e.range.contains(x));
        } else {
            CHECK(check_scalar(e, text, e.type == ValueType::String).problem.empty());
        }
    }
    CHECK(schema_children("") ==
          std::vector<std::string>{"name", "seed", "sensor", "objects", "friction", "fingers",
                                   "protocol", "sampling", "splits", "render", "outputs"});
    CHECK(schema_children("splits[]") == std::vector<std::string>{"name", "fraction"});
    for (const SchemaList& list : spec_lists()) // every list has item keys
        CHECK_FALSE(schema_children(list.name + "[]").empty());
    CHECK(is_schema_section("sensor.materials"));
    CHECK_FALSE(is_schema_section("sensor.materials.coating.E_MPa"));
    CHECK_FALSE(is_schema_section("sens"));
}

// The manual says what a key is, its unit and when to change it; measurements belong in
// docs/VALIDATION.md, where they are kept current.
TEST_CASE("every spec key's doc is at most two sentences and names no version",
          "[generators][spec]") {
    const std::regex sentence_end(R"([.!?](\s+[A-Z`(]|$))");
    const std::regex version(R"(\b\d+\.\d+\.\d+\b|session)");
    for (const SchemaEntry& e : spec_schema()) {
        INFO(e.key << ": " << e.doc);
        const auto ends = std::distance(
            std::sregex_iterator(e.doc.begin(), e.doc.end(), sentence_end), std::sregex_iterator());
        CHECK(ends <= 2);
        CHECK(e.doc.size() <= 400);
        CHECK_FALSE(std::regex_search(e.doc, version));
    }
}

TEST_CASE("malformed YAML is reported at its line and column", "[generators][spec]") {
    CHECK(error_of("name: x\nseed: 1\n  mu: 2\n") ==
          "bad.yaml:3:5: malformed YAML: illegal map value");
    CHECK(error_of("sensor:\n  led: [1, 2\n") ==
          "bad.yaml:3:1: malformed YAML: end of sequence flow not found");
}

TEST_CASE("a stray ',' is malformed YAML at its place, not a hang", "[generators][spec]") {
    // tests/fuzz/fuzz_spec's first finding: yaml-cpp 0.7's LoadAll looped forever, allocating,
    // on a ',' that no node starts with (jbeder/yaml-cpp#1040).
    const std::string allowed =
        "; allowed: a mapping of keys to values (',' only inside [ ] or { })";
    CHECK(error_of(",") == "bad.yaml:1:1: malformed YAML: unexpected ','" + allowed);
    CHECK(error_of("# quickstart\n, # a comment\nname: x\n") ==
          "bad.yaml:2:1: malformed YAML: unexpected ','" + allowed);
    CHECK_THAT(error_of("seed: 1\n,\n"), StartsWith("bad.yaml:2:1: "));
}

TEST_CASE("an unknown key is named with its position and the allowed keys", "[generators][spec]") {
    CHECK(error_of("sensor:\n  materials:\n    coatng:\n      E_MPa: 1\n") ==
          "bad.yaml:3:5: sensor.materials.coatng: unknown key 'coatng' (did you mean "
          "'coating'?); allowed keys in 'sensor.materials': inner_marker_layer, clear_layer, "
          "outer_marker_layer, coating, fill");
    CHECK(error_of("render:\n  widht_px: 300\n") ==
          "bad.yaml:2:3: render.widht_px: unknown key 'widht_px' (did you mean 'width_px'?); "
          "allowed keys in 'render': width_px, height_px, samples_per_pixel, exposure, spectral, "
          "integrator, quality, fast, sensor");
    CHECK(error_of("name: x\nfrobnicate: 1\n") ==
          "bad.yaml:2:1: frobnicate: unknown key 'frobnicate'; allowed keys at the top level: "
          "name, seed, sensor, objects, friction, fingers, protocol, sampling, splits, render, "
          "outputs");
    CHECK_THAT(error_of("sensor.mesh_level: fine\n"),
               StartsWith("bad.yaml:1:1: sensor.mesh_level: unknown key 'sensor.mesh_level' "
                          "(a dotted key is written nested"));
}

TEST_CASE("a key given twice is rejected", "[generators][spec]") {
    CHECK(error_of("seed: 1\nname: x\nseed: 2\n") ==
          "bad.yaml:3:1: seed: value 'seed' is given twice (first at line 1); allowed: each key "
          "once per mapping");
}

TEST_CASE("a value of the wrong type is rejected", "[generators][spec]") {
    SECTION("text for a number") {
        CHECK(error_of("objects:\n  - radius_mm: big\n") ==
              "bad.yaml:2:16: objects[0].radius_mm: value 'big' is not a number; allowed: number "
              "in (0, 10000] (mm)");
    }
    SECTION("quoted text for a number") {
        CHECK(
            error_of("fingers:\n  mu_jitter: \"0.5\"\n") ==
            "bad.yaml:2:14: fingers.mu_jitter: value '0.5' is quoted text, not a number; allowed: "
            "number in [0, 0.5]");
    }
    SECTION("a fraction or text for an integer") {
        CHECK(error_of("name: x\nseed: 2.5\n") ==
              "bad.yaml:2:7: seed: value '2.5' is not an integer; allowed: integer in [0, "
              "2147483647]");
        CHECK(error_of("render:\n    width_px: abc\n") ==
              "bad.yaml:2:15: render.width_px: value 'abc' is not an integer; allowed: integer "
              "in [16, 4096] (px)");
    }
    SECTION("a mapping or a list for a single value") {
        CHECK(error_of("seed: {a: 1}\n") ==
              "bad.yaml:1:7: seed: value '{a: 1}' is a mapping, not a single value; allowed: "
              "integer in [0, 2147483647]");
        CHECK(error_of("objects:\n  - shape: [flat]\n") ==
              "bad.yaml:2:12: objects[0].shape: value '[flat]' is a list, not a single value; "
              "allowed: one of flat, sphere, mesh");
    }
    SECTION("a single value for a section") {
        CHECK(error_of("render: 5\n") ==
              "bad.yaml:1:9: render: value '5' is a single value, not a mapping; allowed: a "
              "mapping with keys in 'render': width_px, height_px, samples_per_pixel, exposure, "
              "spectral, integrator, quality, fast, sensor");
    }
    SECTION("anything but true or false for a bool") {
        CHECK(error_of("outputs:\n  images: yes\n") ==
              "bad.yaml:2:11: outputs.images: value 'yes' is not true or false; allowed: true "
              "or false");
        CHECK(error_of("outputs:\n  labels: maybe\n") ==
              "bad.yaml:2:11: outputs.labels: value 'maybe' is not true or false; allowed: true "
              "or false");
        CHECK_THAT(error_of("outputs:\n  labels: True\n"), Contains("value 'True'"));
        CHECK_THAT(error_of("outputs:\n  labels: 'true'\n"), Contains("quoted text"));
    }
    SECTION("an empty value") {
        CHECK(error_of("seed:\nname: x\n") ==
              "bad.yaml:1:1: seed: value '' is empty; allowed: integer in [0, 2147483647]");
        CHECK(error_of("name: ''\n") ==
              "bad.yaml:1:7: name: value '' is empty; allowed: non-empty string");
    }
}

TEST_CASE("a value out of its range is rejected", "[generators][spec]") {
    SECTION("below") {
        CHECK(error_of("protocol:\n  slide:\n    frames: 0\n") ==
              "bad.yaml:3:13: protocol.slide.frames: value '0' is out of range; allowed: "
              "integer in [1, 100000]");
        CHECK(error_of("seed: -1\n") ==
              "bad.yaml:1:7: seed: value '-1' is out of range; allowed: integer in [0, "
              "2147483647]");
    }
    SECTION("above") {
        CHECK(error_of("render:\n  width_px: 5000\n") ==
              "bad.yaml:2:13: render.width_px: value '5000' is out of range; allowed: integer "
              "in [16, 4096] (px)");
        CHECK(error_of("sensor:\n  materials:\n    clear_layer: {nu: 0.5}\n") ==
              "bad.yaml:3:23: sensor.materials.clear_layer.nu: value '0.5' is out of range; "
              "allowed: number in [0, 0.4999], or a list or {min, max} of them (a varied "
              "sensor)");
        CHECK_THAT(error_of("seed: 2147483648\n"), Contains("value '2147483648' is out of range"));
        CHECK_THAT(error_of("seed: 99999999999999999999\n"), Contains("is out of range"));
    }
    SECTION("exclusive bounds exclude, inclusive bounds include") {
        CHECK(error_of("protocol:\n  slide:\n    speed_mm_per_s: 0\n") ==
              "bad.yaml:3:21: protocol.slide.speed_mm_per_s: value '0' is out of range; "
              "allowed: number in (0, 1000] (mm/s)");
        CHECK(error_of("sensor:\n  camera:\n    half_fov_deg: 10\n") ==
              "bad.yaml:3:19: sensor.camera.half_fov_deg: value '10' is out of range; allowed: "
              "number in (10, 100] (deg), or a list or {min, max} of them (a varied sensor)");
        const Spec edge = parse_spec("protocol:\n  slide: {speed_mm_per_s: 1000, frames: 1}\n"
                                     "sensor:\n  camera: {half_fov_deg: 10.000001}\n"
                                     "seed: 2147483647\nrender: {exposure: 1e-300}\n",
                                     "edge.yaml");
        CHECK(edge.protocol.slide_speed_mm_per_s == 1000.0);
        CHECK(edge.sensor.camera_half_fov_deg == 10.000001);
        CHECK(edge.seed == 2147483647u);
        CHECK(edge.render.exposure == 1e-300);
    }
    SECTION("not finite") {
        CHECK_THAT(error_of("friction: [{mu: inf}]\n"), Contains("value 'inf' is not a finite"));
    }
}

TEST_CASE("a value outside an enum is rejected", "[generators][spec]") {
    CHECK(error_of("sensor:\n  mesh_level: ultra\n") ==
          "bad.yaml:2:15: sensor.mesh_level: value 'ultra' is not one of the allowed values; "
          "allowed: one of very_coarse, coarse, medium, fine, refined, reference");
    CHECK(error_of("sensor:\n  mesh_level: Fine\n") ==
          "bad.yaml:2:15: sensor.mesh_level: value 'Fine' is not one of the allowed values (did "
          "you mean 'fine'?); allowed: one of very_coarse, coarse, medium, fine, refined, "
          "reference");
}

TEST_CASE("an rgb must be a list of exactly 3 numbers in range", "[generators][spec]") {
    const std::string head = "sensor:\n  optics:\n";
    CHECK(error_of(head + "    coating_albedo: [0.5, 0.5]\n") ==
          "bad.yaml:3:21: sensor.optics.coating_albedo: value '[0.5, 0.5]' has 2 items; "
          "allowed: list of 3 numbers, each in [0, 1]");
    CHECK(error_of(head + "    inner_marker_absorption_per_mm: [1, 2, 3, 4]\n") ==
          "bad.yaml:3:37: sensor.optics.inner_marker_absorption_per_mm: value '[1, 2, 3, 4]' "
          "has 4 items; allowed: list of 3 numbers, each in [0, 100] (1/mm)");
    CHECK(error_of(head + "    coating_albedo: 0.5\n") ==
          "bad.yaml:3:21: sensor.optics.coating_albedo: value '0.5' is a single value, not a "
          "list; allowed: list of 3 numbers, each in [0, 1]");
    CHECK(error_of(head + "    outer_marker_albedo: [0.1, 1.5, 0.2]\n") ==
          "bad.yaml:3:32: sensor.optics.outer_marker_albedo[1]: value '1.5' is out of range; "
          "allowed: list of 3 numbers, each in [0, 1]");
    CHECK(error_of(head + "    outer_marker_albedo: [0.1, red, 0.2]\n") ==
          "bad.yaml:3:32: sensor.optics.outer_marker_albedo[1]: value 'red' is not a number; "
          "allowed: list of 3 numbers, each in [0, 1]");
}

TEST_CASE("an empty spec or a top level that is not a mapping is rejected", "[generators][spec]") {
    const std::string allowed = "allowed: a mapping with keys at the top level: name, seed, "
                                "sensor, objects, friction, fingers, protocol, sampling, splits, "
                                "render, outputs";
    CHECK(error_of("") == "bad.yaml:1:1: spec is empty; " + allowed);
    CHECK(error_of("# only a comment\n\n") == "bad.yaml:1:1: spec is empty; " + allowed);
    CHECK(error_of("- name\n- seed\n") ==
          "bad.yaml:1:1: (top level): value '[name, seed]' is a list, not a mapping; " + allowed);
    CHECK_THAT(error_of("seed: 1\n---\nseed: 2\n"),
               StartsWith("bad.yaml:3:1: a second YAML document"));
}

TEST_CASE("a spec that enables no output is rejected", "[generators][spec]") {
    CHECK(error_of("name: x\noutputs:\n  images: false\n  labels: false\n  markers: false\n") ==
          "bad.yaml:2:1: outputs: value '{images: false, labels: false, markers: false, exr: "
          "false, marker_ids: false, variance: false, strain: false}' "
          "enables no output; allowed: at least one of outputs.images, outputs.labels, "
          "outputs.markers, outputs.exr, outputs.strain is true");
    CHECK_FALSE(parse_spec("outputs: {images: false, labels: false}\n", "ok.yaml").outputs.images);
}

TEST_CASE("the camera keys reach the renderer's camera", "[generators][spec]") {
    using chromasim::render::CameraModel;
    constexpr double kHalfFov_rad = 84.0 * std::numbers::pi / 180.0;
    SECTION("equidistant at the dome centre by default") {
        const chromasim::render::CameraParams c = camera_params(parse_spec("name: x\n", "ok.yaml"));
        CHECK(c.model == CameraModel::equidistant);
        CHECK(c.half_fov_deg == 84.0);
        CHECK(c.position_mm == chromasim::render::Vec3::Zero());
        CHECK((c.roll_deg == 0.0 && c.pitch_deg == 0.0 && c.yaw_deg == 0.0));
    }
    SECTION("Kannala-Brandt: a 0 takes the equidistant camera's value") {
        const Spec spec = parse_spec("render: {width_px: 200, height_px: 160}\n"
                                     "sensor:\n  camera:\n    model: kannala_brandt\n"
                                     "    fx_px: 300\n    cy_px: 120.25\n    k1: 0.02\n"
                                     "    k4: -0.001\n    position_mm: [0.5, -1, 2]\n"
                                     "    yaw_deg: 30\n",
                                     "ok.yaml");
        const chromasim::render::CameraParams c = camera_params(spec);
        CHECK(c.model == CameraModel::kannala_brandt);
        CHECK(c.fx_px == 300.0);
        CHECK(c.fy_px == Approx(80.0 / kHalfFov_rad).epsilon(1e-14)); // min(w, h) / 2 / half_fov
        CHECK(c.cx_px == 99.5); // the image centre, OpenCV convention
        CHECK(c.cy_px == 120.25);
        CHECK((c.k1 == 0.02 && c.k2 == 0.0 && c.k3 == 0.0 && c.k4 == -0.001));
        CHECK(c.position_mm == chromasim::render::Vec3(0.5, -1.0, 2.0));
        CHECK(c.yaw_deg == 30.0);
    }
    SECTION("a position is a list of 3 numbers") {
        CHECK(error_of("sensor:\n  camera:\n    position_mm: [0, 1]\n") ==
              "bad.yaml:3:18: sensor.camera.position_mm: value '[0, 1]' has 2 items; allowed: "
              "list of 3 numbers, each in [-10, 10] (mm)");
    }
    SECTION("a distortion that folds back within the field is rejected before any work") {
        CHECK_THAT(error_of("sensor:\n  camera: {model: kannala_brandt, k1: -0.5}\n"),
                   StartsWith("bad.yaml:2:3: sensor.camera: value '{half_fov_deg: 84.0, model: "
                              "kannala_brandt, fx_px: 0.0, ") &&
                       Contains("k1: -0.5, ") &&
                       Contains("' has k1..k4 whose theta_d(theta) stops increasing before "
                                "half_fov_deg, so pixels cannot be mapped back to rays; allowed: "
                                "k1..k4 with 1 + 3 k1 t^2 + 5 k2 t^4"));
        // The same lens over a field it covers, and the equidistant model, which ignores k.
        CHECK_NOTHROW(parse_spec("sensor:\n  camera: {model: kannala_brandt, k1: -0.5, "
                                 "half_fov_deg: 40}\n",
                                 "ok.yaml"));
        CHECK_NOTHROW(parse_spec("sensor:\n  camera: {k1: -0.5}\n", "ok.yaml"));
    }
}

TEST_CASE("the render.sensor keys reach the sensor model", "[generators][spec]") {
    using chromasim::render::Vignetting;
    SECTION("off by default, IMX392-class values when on") {
        const Spec spec = parse_spec("name: x\n", "ok.yaml");
        CHECK_FALSE(spec.render.sensor.enabled);
        const chromasim::render::SensorParams p = sensor_params(spec);
        CHECK(p.full_well_e == 10000.0);
        CHECK(p.read_noise_e == 2.3);
        CHECK(p.adc_bits == 12);
        CHECK(p.vignetting == Vignetting::polynomial);
        CHECK(p.vignetting_k1 == -0.3);
    }
    SECTION("every key is passed on") {
        const chromasim::render::SensorParams p = sensor_params(
            parse_spec("render:\n  sensor:\n    enabled: true\n    seed: 9\n    gain: 2.5\n"
                       "    full_well_e: 6000\n    read_noise_e: 4\n    adc_bits: 10\n"
                       "    shot_noise: false\n    vignetting: {model: cos4, k1: 0.1, k2: -0.2}\n",
                       "ok.yaml"));
        CHECK(p.seed == 9);
        CHECK(p.gain == 2.5);
        CHECK(p.full_well_e == 6000.0);
        CHECK(p.read_noise_e == 4.0);
        CHECK(p.adc_bits == 10);
        CHECK_FALSE(p.shot_noise);
        CHECK(p.vignetting == Vignetting::cos4);
        CHECK(p.vignetting_k1 == 0.1);
        CHECK(p.vignetting_k2 == -0.2);
    }
    SECTION("out of range values are rejected with what is allowed") {
        CHECK(error_of("render:\n  sensor:\n    adc_bits: 20\n") ==
              "bad.yaml:3:15: render.sensor.adc_bits: value '20' is out of range; allowed: "
              "integer in [1, 16] (bit)");
        CHECK_THAT(error_of("render:\n  sensor:\n    full_well_e: -5\n"),
                   Contains("render.sensor.full_well_e: value '-5' is out of range"));
    }
}

TEST_CASE("render.quality and the render.fast keys reach the renderer's settings",
          "[generators][spec]") {
    using chromasim::render::RenderSettings;
    SECTION("the defaults") {
        const Spec spec = parse_spec("render: {integrator: fast}\n", "ok.yaml");
        const RenderSettings r = render_settings(spec);
        CHECK(r.integrator == chromasim::render::Integrator::fast);
        CHECK(r.shadow_filter_px == 1.0);
        CHECK(r.shadow_filter_rim_px == 0.5);
        CHECK(r.reflection_samples_per_pixel == 4);
        CHECK(r.rim_samples_per_pixel == 6);
        CHECK(r.reflected_led_samples_per_pixel == 32);
        CHECK(r.shadow_rays_per_pixel == 0);
        CHECK(r.fast_wavelengths == 0); // auto: 16 at 1 spp, else 8
        CHECK(chromasim::render::fast_wavelengths_of(r) == 8);
        const chromasim::render::LightCacheSettings c = light_cache_settings(spec);
        CHECK(c.paths_per_vertex == 1024);
        CHECK(c.refresh_threshold == 1.0);
    }
    SECTION("each preset, and the expert keys") {
        const Spec high = parse_spec("render:\n  quality: high\n  samples_per_pixel: 3\n  fast:\n"
                                     "    shadow_filter_px: 1.5\n    paths_per_vertex: 256\n"
                                     "    refresh_threshold: 0.5\n",
                                     "ok.yaml");
        const RenderSettings r = render_settings(high);
        CHECK(r.samples_per_pixel == 3);
        CHECK(r.shadow_filter_px == 1.5);
        CHECK(r.rim_samples_per_pixel == 12);
        CHECK(r.reflection_samples_per_pixel == 8);
        CHECK(r.reflected_led_samples_per_pixel == 64);
        CHECK(r.shadow_rays_per_pixel == 6); // 2 a sample
        CHECK(r.fast_wavelengths == 16);
        CHECK(light_cache_settings(high).paths_per_vertex == 256);
        CHECK(light_cache_settings(high).refresh_threshold == 0.5);
        const RenderSettings d =
            render_settings(parse_spec("render: {quality: draft}\n", "ok.yaml"));
        CHECK(d.rim_samples_per_pixel == 0);
        CHECK(d.reflection_samples_per_pixel == 0);
        CHECK(d.reflected_led_samples_per_pixel == 16);
    }
    SECTION("bad values, and a key the preset replaced, are refused with what is allowed") {
        CHECK_THAT(error_of("render:\n  quality: best\n"),
                   StartsWith("bad.yaml:2:12: render.quality: value 'best'") &&
                       EndsWith("allowed: one of draft, default, high"));
        CHECK_THAT(error_of("render:\n  fast:\n    edge_samples_per_pixel: 6\n"),
                   StartsWith("bad.yaml:3:5: render.fast.edge_samples_per_pixel: unknown key") &&
                       Contains("render.quality sets it now"));
        // A renamed choice: the message names the new one.
        CHECK(error_of("render:\n  integrator: direct\n") ==
              "bad.yaml:2:15: render.integrator: value 'direct' is now called 'preview' (the "
              "same choice, renamed); allowed: one of preview, path, fast");
        CHECK(error_of("render:\n  fast:\n    refresh_threshold: -2\n") ==
              "bad.yaml:3:24: render.fast.refresh_threshold: value '-2' is out of range; "
              "allowed: number in [0, 10]");
    }
}

TEST_CASE("a spec file that cannot be read names its path", "[generators][spec]") {
    const std::filesystem::path missing = repo_file("datasets_spec/does_not_exist.yaml");
    try {
        load_spec(missing);
        FAIL("no SpecError");
    } catch (const SpecError& e) {
        CHECK(std::string(e.what()) ==
              missing.string() + ": cannot read spec file: No such file or directory");
    }
    CHECK_THROWS_WITH(load_spec(repo_file("datasets_spec")), Contains("is a directory"));
}

TEST_CASE("the resolved YAML parses back to the same spec", "[generators][spec]") {
    const Spec spec = load_spec(repo_file("datasets_spec/quickstart.yaml"));
    const Spec again = parse_spec(spec.resolved_yaml, "resolved.yaml");
    require_same_values(spec, again);
    CHECK(again.resolved_yaml == spec.resolved_yaml);

    // Values that only survive with shortest-round-trip printing and careful quoting.
    const Spec odd = parse_spec("name: \"a: b # \\\"c\\\" \\\\ \\t\"\n"
                                "sensor:\n  materials: {coating: {E_MPa: 0.30000000000000004}}\n"
                                "render: {exposure: 1e-300}\nprotocol:\n  "
                                "load_direction_deg: -0.1\n",
                                "odd.yaml");
    CHECK(odd.name == "a: b # \"c\" \\ \t");
    const Spec odd_again = parse_spec(odd.resolved_yaml, "resolved.yaml");
    require_same_values(odd, odd_again);
    CHECK(odd_again.sensor.coating.E_MPa == 0.30000000000000004);
    CHECK(odd_again.resolved_yaml == odd.resolved_yaml);
}

TEST_CASE("the resolved YAML ignores key order and comments", "[generators][spec]") {
    const Spec a = load_spec(repo_file("datasets_spec/quickstart.yaml"));
    const Spec b = parse_spec(quickstart_reordered, "reordered.yaml");
    CHECK(b.resolved_yaml == a.resolved_yaml);
    CHECK_THAT(a.resolved_yaml, Contains("\nobjects:\n  - name: \"flat\"\n    shape: flat\n"));
    CHECK_THAT(a.resolved_yaml, Contains("\n  grip_N: [1.0]\n"));
    const Spec c = parse_spec(std::string(quickstart_reordered) + "  led: {count: 5}\n", "c.yaml");
    CHECK(c.resolved_yaml != a.resolved_yaml);
}

TEST_CASE("numbers print in the shortest text that reads back exactly", "[generators][spec]") {
    CHECK(format_number(35.0) == "35.0");
    CHECK(format_number(-1.0) == "-1.0");
    CHECK(format_number(0.8) == "0.8");
    CHECK(format_number(0.1 + 0.2) == "0.30000000000000004");
    CHECK(format_number(1e-7) == "1e-07");
}

TEST_CASE("edit distance counts a swap of neighbours as one edit", "[generators][spec]") {
    CHECK(edit_distance("coating", "coating") == 0);
    CHECK(edit_distance("coatng", "coating") == 1);
    CHECK(edit_distance("cotaing", "coating") == 1);
    CHECK(edit_distance("", "abc") == 3);
    CHECK(closest_match("widht_px", {"width_px", "height_px"}) == "width_px");
    CHECK(closest_match("x", {"nu", "mu"}).empty()); // nothing in common is no suggestion
    CHECK(closest_match("colour", {"count", "z_mm"}).empty());
}

TEST_CASE("docs/SPEC.md holds the current schema table", "[generators][spec]") {
    std::ifstream in(repo_file("docs/SPEC.md"));
    REQUIRE(in);
    std::ostringstream doc;
    doc << in.rdbuf();
    // On failure: chromasim spec-doc > docs/SPEC.md
    CHECK_THAT(doc.str(), Contains(schema_markdown()));
}

TEST_CASE("every shipped spec in datasets_spec/ validates", "[generators][spec]") {
    int specs = 0;
    for (const auto& file : std::filesystem::directory_iterator(repo_file("datasets_spec"))) {
        if (file.path().extension() != ".yaml") continue;
        INFO(file.path());
        CHECK_NOTHROW(load_spec(file.path()));
        ++specs;
    }
    CHECK(specs >= 5); // quickstart, seed000_train, seed000_validation, seed001, unseen
}

TEST_CASE("a factor is a number, a non-empty list or {min, max} in range", "[generators][spec]") {
    SECTION("the three forms") {
        const Spec s = parse_spec("protocol:\n  grip_N: 2\n  load_rate_N_per_s: [0.5, 1]\n"
                                  "  target_load_N: {min: 2, max: 3}\n",
                                  "ok.yaml");
        CHECK(s.protocol.grip_N == Factor{{2.0}});
        CHECK(s.protocol.load_rate_N_per_s == Factor{{0.5, 1.0}});
        CHECK(s.protocol.target_load_N == Factor{{}, true, 2.0, 3.0});
        const Spec again = parse_spec(s.resolved_yaml, "resolved.yaml");
        require_same_values(s, again);
        CHECK_THAT(s.resolved_yaml, Contains("  target_load_N: {min: 2.0, max: 3.0}\n"));
    }
    const std::string allowed = "allowed: a number, a non-empty list of numbers, or {min, max} "
                                "with min <= max, each in (0, 50] (N)";
    CHECK(error_of("protocol:\n  grip_N: []\n") ==
          "bad.yaml:2:11: protocol.grip_N: value '[]' is an empty list; " + allowed);
    CHECK(error_of("protocol:\n  grip_N: [1, 0]\n") ==
          "bad.yaml:2:15: protocol.grip_N[1]: value '0' is out of range; " + allowed);
    CHECK(error_of("protocol:\n  grip_N: {min: 3, max: 2}\n") ==
          "bad.yaml:2:11: protocol.grip_N: value '{min: 3, max: 2}' has min above max; " + allowed);
    CHECK(error_of("protocol:\n  grip_N: {min: 1}\n") ==
          "bad.yaml:2:11: protocol.grip_N: value '{min: 1}' has no max; " + allowed);
    CHECK(error_of("protocol:\n  grip_N: {min: 1, max: 2, step: 1}\n") ==
          "bad.yaml:2:28: protocol.grip_N.step: value 'step' is not a key of a range; " + allowed);
    CHECK(error_of("protocol:\n  grip_N: {min: 1, max: 60}\n") ==
          "bad.yaml:2:25: protocol.grip_N.max: value '60' is out of range; " + allowed);
    CHECK(error_of("protocol:\n  grip_N: {min: 1, min: 2, max: 3}\n") ==
          "bad.yaml:2:20: protocol.grip_N.min: value 'min' is given twice; " + allowed);
}

TEST_CASE("lists of mappings: items replace the default list, errors name the item",
          "[generators][spec]") {
    const Spec s = parse_spec("objects:\n  - {name: a}\n  - {name: b, shape: sphere}\n"
                              "friction:\n  - {name: dry, mu: {min: 1, max: 1.2}}\n",
                              "ok.yaml");
    REQUIRE(s.objects.size() == 2);
    CHECK(s.objects[0].shape == "flat"); // item defaults
    CHECK(s.objects[1].radius_mm == 45.0);
    CHECK(s.friction[0].name == "dry");
    const std::string keys = "name, shape, radius_mm, mesh_file, offset_x_mm, offset_y_mm, "
                             "roll_deg, pitch_deg, yaw_deg";
    CHECK(error_of("objects: []\n") == "bad.yaml:1:10: objects: value '[]' is an empty list; "
                                       "allowed: a non-empty list of mappings with keys " +
                                           keys);
    CHECK(error_of("objects: {name: x}\n") ==
          "bad.yaml:1:10: objects: value '{name: x}' is a mapping, not a list; allowed: a "
          "non-empty list of mappings with keys " +
              keys);
    CHECK(error_of("objects:\n  - flat\n") ==
          "bad.yaml:2:5: objects[0]: value 'flat' is a single value, not a mapping; allowed: a "
          "non-empty list of mappings with keys " +
              keys);
    CHECK(error_of("objects:\n  - {name: a}\n  - {name: b, shap: flat}\n") ==
          "bad.yaml:3:15: objects[1].shap: unknown key 'shap' (did you mean 'shape'?); allowed "
          "keys in an item of 'objects': " +
              keys);
    CHECK(error_of("objects:\n  - {name: a, shape: cube}\n") ==
          "bad.yaml:2:22: objects[0].shape: value 'cube' is not one of the allowed values; "
          "allowed: one of flat, sphere, mesh");
}

TEST_CASE("cross-key rules of the trial keys", "[generators][spec]") {
    CHECK(error_of("friction:\n  - {name: dry, mu: 1}\n  - {name: dry, mu: 0.5}\n") ==
          "bad.yaml:3:6: friction[1].name: value '\"dry\"' is the name of an earlier item of "
          "friction; allowed: a name used once in friction");
    CHECK(
        error_of("splits:\n  - {name: train, fraction: 0.8}\n  - {name: test, fraction: 0.1}\n") ==
        "bad.yaml:1:1: splits: value '[{name: \"train\", fraction: 0.8}, {name: \"test\", "
        "fraction: 0.1}]' has fractions whose sum is not 1; allowed: splits[].fraction summing "
        "to 1 (within 1e-9), e.g. train 0.8, test 0.2");
    CHECK(error_of("protocol:\n  slide: {start_mm: 2, end_mm: 1}\n") ==
          "bad.yaml:2:24: protocol.slide.end_mm: value '1.0' is below protocol.slide.start_mm; "
          "allowed: protocol.slide.end_mm >= protocol.slide.start_mm");
    CHECK_THAT(error_of("protocol:\n  frame_rate_Hz: 10000\n  load_rate_N_per_s: 0.001\n"),
               StartsWith("bad.yaml:2:3: protocol.frame_rate_Hz: value '10000.0' with the "
                          "grasp, hold and load durations plans a trial longer than 1000000 "
                          "frames"));
    // A rule about one item points at that item's key.
    CHECK_THAT(error_of("objects:\n  - {name: a}\n  - {name: b, shape: flat, roll_deg: 32}\n"),
               StartsWith("bad.yaml:3:5: objects[1].pitch_deg: value '0.0' with roll_deg tilts "
                          "the flat object"));
    // LEDs under the rim must lie beside the lens barrel; above it the barrel cannot hide them.
    CHECK_THAT(error_of("sensor:\n  camera: {lens_radius_mm: 9}\n"),
               StartsWith("bad.yaml:2:12: sensor.camera.lens_radius_mm: value '9.0' puts the lens "
                          "barrel over the LEDs"));
    CHECK_NOTHROW(
        parse_spec("sensor:\n  camera: {lens_radius_mm: 9}\n  led: {z_mm: 1}\n", "ok.yaml"));
    CHECK(error_of("fingers: {count: 3}\n") ==
          "bad.yaml:1:18: fingers.count: value '3' is out of range; allowed: integer in [1, 2]");
    CHECK(error_of("sampling: {method: grid}\n") ==
          "bad.yaml:1:20: sampling.method: value 'grid' is not one of the allowed values; "
          "allowed: one of full_grid, random, latin_hypercube");
}

// A quote never closed, a mesh or spectra that cannot be read, a rule about a key left out.
TEST_CASE("validate is as strict as generate and places each error at its line:col",
          "[generators][spec]") {
    // yaml-cpp would let the name swallow the lines up to the next quote.
    CHECK(error_of("name: \"quick\nseed: 1\nrender: {width_px: 64}\n") ==
          "bad.yaml:1:7: malformed YAML: the double-quoted value opened here is not closed on "
          "its line; allowed: a quoted value that ends on the line it starts");
    CHECK_THAT(error_of("seed: 1\nobjects:\n  - {name: 'flat, shape: flat}\n"),
               StartsWith("bad.yaml:3:12: malformed YAML: the single-quoted value"));
    // Quotes that close, quotes inside plain scalars, comments and block scalars pass.
    CHECK_NOTHROW(parse_spec("name: \"a \\\" b\"  # it's \"\nobjects: [{name: 'it''s'}]\n"
                             "friction: [{name: seed's, mu: 0.5}]\n",
                             "ok.yaml"));
    // A cross-key rule about a key left out points at its section, or the file's start.
    CHECK_THAT(error_of("protocol:\n  type: slide\n  slide:\n    start_mm: 30\n"),
               StartsWith("bad.yaml:3:3: protocol.slide.end_mm: value '6.0' is below"));
    CHECK_THAT(error_of("name: x\noutputs: {marker_ids: true}\n"),
               StartsWith("bad.yaml:2:1: outputs.exr: value 'false' is false while"));
    // Files are read as generate reads them: a mesh that is not glTF, spectra that are missing.
    const ScratchDir dir("strict_files");
    dir.write("not.glb", "not a glTF file");
    const std::filesystem::path mesh_spec = dir.write(
        "mesh.yaml", "name: m\nobjects:\n  - {name: a, shape: mesh, mesh_file: not.glb}\n");
    CHECK_THROWS_WITH(load_spec(mesh_spec),
                      Catch::Contains("mesh.yaml:3:") &&
                          Catch::Contains("objects[0].mesh_file: value '\"not.glb\"' is not a "
                                          "usable object mesh ("));
    std::filesystem::create_directories(dir.path / "no_spectra");
    const std::filesystem::path spectra_spec =
        dir.write("spectra.yaml", "name: s\nsensor:\n  optics:\n    spectra_dir: no_spectra\n");
    CHECK_THROWS_WITH(load_spec(spectra_spec),
                      Catch::Contains("spectra.yaml:4:") &&
                          Catch::Contains("sensor.optics.spectra_dir") &&
                          Catch::Contains("holds spectra that cannot be used ("));
}

// Validate is as strict as generate: text that would fail the manifest's JSON (not UTF-8) at
// the end of a run, or split a labels.csv cell or a folder name, is refused before any work.
TEST_CASE("text that would break the manifest, a CSV cell or a folder is refused",
          "[generators][spec]") {
    CHECK(error_of("name: caf\xe9\n") ==
          "bad.yaml:1:10: malformed text: byte 0xE9 is not UTF-8; allowed: UTF-8 text without "
          "control characters (save the file as UTF-8)");
    CHECK_THAT(error_of("seed: 1\nname: a\x01" "b\n"),
               StartsWith("bad.yaml:2:8: malformed text: byte 0x01 is a control character"));
    CHECK(parse_spec("name: caf\xc3\xa9\n", "ok.yaml").name == "caf\xc3\xa9");
    CHECK(error_of("objects: [{name: \"fl,at\", shape: flat}]\n") ==
          "bad.yaml:1:12: objects[0].name: value '\"fl,at\"' holds a comma, a quote, a slash or "
          "a backslash; allowed: text of at most 100 bytes without commas, quotes, slashes, "
          "backslashes or control characters (it is a labels.csv cell, and a split's name is a "
          "folder's)");
    CHECK_THAT(error_of("friction: [{name: \"a\\nb\", mu: 0.5}]\n"),
               Contains("friction[0].name: value '\"a\\x0ab\"' holds a control character"));
    CHECK_THAT(error_of("splits: [{name: .., fraction: 1.0}]\n"),
               Contains("names a folder's own or parent folder"));
    CHECK_THAT(error_of("splits: [{name: " + std::string(101, 'a') + ", fraction: 1.0}]\n"),
               Contains("is longer than 100 bytes"));
}
