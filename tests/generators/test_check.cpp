// `chromasim check` and the friction limit end to end: a spec whose load steps land exactly on
// mu f_n writes physical labels that check passes; a dataset with an impossible row is refused
// with its line; bad input (no dataset, a newer version) is an error that writes nothing.
#include "generators/output/check.hpp"

#include "run_chromasim.hpp"
#include "scratch_dir.hpp"
#include "test_files.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using namespace chromasim::generators;
using chromasim::generators::test::read_csv;

namespace {

/// Two fingertips, grip 1.5 N, mu 1.1, 0.11 N per finger per frame: frame 20's share is
/// 15 x 0.11 = 1.65 N = mu f_n, equal only up to rounding. A flat and a 45 mm sphere.
const char* kLimitSpec = R"(name: limit
seed: 3
objects:
  - {name: flat, shape: flat}
  - {name: curved, shape: sphere, radius_mm: 45}
friction:
  - {name: high, mu: 1.1}
fingers: {count: 2}
protocol:
  type: grasp_load
  frame_rate_Hz: 16
  grip_N: 1.5
  grasp_s: 0.25
  hold_s: 0.125
  load_rate_N_per_s: 3.52
  target_load_N: 4.0
  slip_frames: 3
splits:
  - {name: train, fraction: 1.0}
outputs: {images: false, labels: true, markers: true}
)";

/// Generates kLimitSpec's dataset (its first `trials`, 0: all) into DIR/out; returns DIR/out.
fs::path generate_limit(const ScratchDir& dir, int trials = 0) {
    const fs::path spec = dir.write("limit.yaml", kLimitSpec);
    const fs::path out = dir.path / "out";
    const Run gen = run_chromasim(
        dir, "generate " + spec.string() + " -o " + out.string() + " --no-cache -q" +
                 (trials > 0 ? " --max-trials " + std::to_string(trials) : std::string()));
    INFO(gen.output);
    REQUIRE(gen.code == 0);
    return out;
}

} // namespace

// The slip frames hold the travel at slip onset and the objects stay apart.
TEST_CASE("load steps landing on mu f_n give converged physical frames and check finds nothing",
          "[generators][check]") {
    ScratchDir dir("check_limit");
    const fs::path out = generate_limit(dir);
    const auto rows = read_csv(out / "labels.csv");
    REQUIRE(rows.size() == 46);
    std::map<std::string, double> onset; // object -> the left finger's travel at slip onset
    for (const auto& row : rows)
        for (const char* f : {"left_", "right_"}) {
            const auto v = [&](const char* c) { return std::stod(row.at(std::string(f) + c)); };
            INFO("trial " << row.at("trial") << " frame " << row.at("frame") << " " << f);
            CHECK(row.at(std::string(f) + "converged") == "1");
            CHECK(row.at(std::string(f) + "status") == "ok");
            CHECK(std::abs(v("object_travel_x_mm")) < 3.0); // Mindlin-like: about 1.5 mm here
            CHECK(v("indentation_mm") > 0.4);
            CHECK(v("indentation_mm") < 2.0);
            if (row.at("frame") == "20") { // the share is mu f_n up to rounding: it slides
                CHECK(row.at("phase") == "slip");
                CHECK(v("sliding") == 1);
                CHECK(v("gamma") == 0);
                CHECK(v("tangential_force_N") == Approx(1.65).epsilon(1e-9));
                if (f == std::string("left_")) onset[row.at("object")] = v("object_travel_x_mm");
            }
            if (row.at("phase") == "slip" && f == std::string("left_"))
                CHECK(v("object_travel_x_mm") == Approx(onset.at(row.at("object"))));
        }
    // A flat and a sphere sliding on the dome are two different fields.
    CHECK(std::abs(onset.at("flat") - onset.at("curved")) > 0.01);
    const Run check = run_chromasim(dir, "check " + out.string());
    INFO(check.output);
    CHECK(check.code == 0);
    CHECK_THAT(check.output, Catch::Contains("0 impossible or inconsistent value(s)"));
}

TEST_CASE("check names the rows of an impossible dataset, refuses a missing or newer one, and "
          "writes nothing",
          "[generators][check]") {
    ScratchDir dir("check_bad");
    const fs::path out = generate_limit(dir, 1);
    // The labels an older version wrote at the limit: travel 788062 mm, converged, status ok.
    std::string labels = read_file(out / "labels.csv");
    const auto rows = read_csv(out / "labels.csv");
    const std::string travel = rows.at(20).at("left_object_travel_x_mm");
    const std::size_t at = labels.find("," + travel + ",");
    REQUIRE(at != std::string::npos);
    labels.replace(at + 1, travel.size(), "788062");
    std::ofstream(out / "labels.csv", std::ios::binary) << labels;
    const auto before = tree(dir.path);
    const Run bad = run_chromasim(dir, "check " + out.string());
    INFO(bad.output);
    CHECK(bad.code == 1);
    CHECK_THAT(bad.output, Catch::Contains("labels.csv:22: trial 0 frame 20 left: "
                                           "left_object_travel_x_mm = 788062"));
    const CheckReport report = check_dataset(out);
    CHECK(report.findings_total == 1);
    CHECK(report.label_rows == 23);

    const Run missing = run_chromasim(dir, "check " + (dir.path / "nowhere").string());
    CHECK(missing.code == 2);
    CHECK_THAT(missing.output, Catch::Contains("no such dataset folder"));
    std::string manifest = read_file(out / "manifest.json");
    const std::size_t v = manifest.find("\"chromasim_version\": \"");
    REQUIRE(v != std::string::npos);
    manifest.replace(v, manifest.find('"', v + 22) - v + 1, "\"chromasim_version\": \"99.0.0\"");
    std::ofstream(out / "manifest.json", std::ios::binary) << manifest;
    const Run newer = run_chromasim(dir, "check " + out.string());
    CHECK(newer.code == 2);
    CHECK_THAT(newer.output, Catch::Contains("written by chromasim 99.0.0, newer than this"));
    auto after = tree(dir.path);
    after.erase("run.log");
    auto expected = before;
    expected.erase("run.log");
    expected["out/manifest.json"] = after.at("out/manifest.json");
    CHECK(after == expected);
}
