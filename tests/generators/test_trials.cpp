// Trials end to end: the plan's loads reach the mechanics per fingertip, hold frames are not
// solved (or rendered) again, Gamma and the forces in labels.csv follow the requested loads,
// slip ends a trial, and slices of the shipped seed specs run.
#include "generators/pipeline/generate.hpp"
#include "generators/plan/plan.hpp"
#include "generators/spec/spec.hpp"

#include "test_files.hpp"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <vector>

#include <unistd.h>

namespace fs = std::filesystem;
using namespace chromasim::generators;
using namespace chromasim::generators::test;

namespace {

/// A dataset generated into a fresh folder, removed at the end.
struct Run {
    Spec spec;
    Plan plan;
    fs::path out;
    GenerateReport report;
    Run(Spec s, const std::string& name, int max_trials = 0)
        : spec(std::move(s)), plan(make_plan(spec)), out(fresh_dir(name)) {
        GenerateOptions options;
        options.out_dir = out;
        options.quiet = true;
        options.max_trials = max_trials;
        std::ostringstream log;
        report = generate(spec, options, log);
    }
    ~Run() {
        std::error_code ec;
        fs::remove_all(out, ec);
    }
    Run(const Run&) = delete;
    Run& operator=(const Run&) = delete;
};

} // namespace

TEST_CASE("hold frames are not solved again, and their images are the previous frame's",
          "[generators][trials]") {
    const Run run(parse_spec("name: hold\nfriction: [{mu: 0.8}]\n"
                             "protocol: {frame_rate_Hz: 10, grip_N: 1.0, grasp_s: 0.2, hold_s: "
                             "0.3, load_rate_N_per_s: 2, target_load_N: 0.6}\n"
                             "render: {width_px: 32, height_px: 32, samples_per_pixel: 1}\n"
                             "outputs: {markers: false}\n",
                             "hold.yaml"),
                  "hold");
    const TrialPlan& t = run.plan.trials.at(0);
    REQUIRE(t.frames.size() == 2 + 3 + 3);
    // Finger-frames whose load differs from the finger's previous frame: grasp and load.
    int changed = 0;
    for (std::size_t k = 0; k < t.frames.size(); ++k)
        for (std::size_t f = 0; f < 2; ++f)
            changed += k == 0 || !(t.frames[k].fingers[f] == t.frames[k - 1].fingers[f]);
    CHECK(changed == (2 + 3) * 2);
    CHECK(run.report.solves == changed);
    CHECK(run.report.reused_solves == 3 * 2);
    CHECK(run.report.renders == changed);
    CHECK(run.report.images == 8 * 2);
    const auto rows = read_csv(run.out / "labels.csv");
    REQUIRE(rows.size() == 8);
    for (std::size_t k = 2; k < 5; ++k) {
        INFO("hold frame " << k);
        CHECK(rows[k].at("phase") == "hold");
        for (const std::string finger : {"left", "right"}) {
            CHECK(rows[k].at(finger + "_reused") == "1");
            CHECK(rows[k].at(finger + "_normal_force_N") == rows[1].at(finger + "_normal_force_N"));
            CHECK(rows[k].at(finger + "_indentation_mm") == rows[1].at(finger + "_indentation_mm"));
            // The scene did not move: the same image, byte for byte.
            CHECK(file_bytes(run.out / rows[k].at(finger + "_image")) ==
                  file_bytes(run.out / rows[1].at(finger + "_image")));
        }
    }
    CHECK(rows[5].at("left_reused") == "0");
    CHECK(file_bytes(run.out / rows[5].at("left_image")) !=
          file_bytes(run.out / rows[4].at("left_image")));
}

TEST_CASE("labels follow the requested loads (each finger's f_n, f_t, mu f_n and Gamma) and "
          "slip ends the trial",
          "[generators][trials]") {
    // mu about 0.6 per finger (5 % jitter), grip 1 N: a finger slips once its half of the load
    // reaches its own mu f_n, about 0.6 N: the total load ramps by 0.4 N per frame to 2 N.
    const Run run(parse_spec("name: gamma\nfriction: [{mu: 0.6}]\n"
                             "fingers: {mu_jitter: 0.05}\n"
                             "protocol: {frame_rate_Hz: 10, grip_N: 1.0, grasp_s: 0.1, hold_s: 0, "
                             "load_rate_N_per_s: 4, target_load_N: 2, slip_frames: 2}\n"
                             "outputs: {images: false, markers: false}\n",
                             "gamma.yaml"),
                  "gamma");
    const TrialPlan& t = run.plan.trials.at(0);
    const auto rows = read_csv(run.out / "labels.csv");
    REQUIRE(rows.size() == t.frames.size());
    REQUIRE(t.first_slip_frame > 0);
    CHECK(t.frames.size() == std::size_t(t.first_slip_frame + 2)); // slip_frames 2, then the end
    CHECK(t.frames.back().load_N < 2.0);                           // ended by slip, not target
    int slip_rows = 0;
    for (std::size_t k = 0; k < rows.size(); ++k) {
        const CsvRow& r = rows[k];
        INFO("frame " << k);
        slip_rows += r.at("phase") == "slip";
        for (std::size_t f = 0; f < 2; ++f) {
            const std::string p = f == 0 ? "left_" : "right_";
            const FingerLoad& load = t.frames[k].fingers[f];
            const double mu = t.fingers[f].mu, q = load.tangential_force_N.norm();
            const double fn = num(r, p + "normal_force_N"), ft = num(r, p + "tangential_force_N");
            CHECK(num(r, p + "mu") == Approx(mu).epsilon(1e-8));
            CHECK(fn == Approx(1.0 * (k == 0 ? 1.0 : 1.0)).epsilon(1e-6));
            CHECK(num(r, p + "requested_tangential_force_N") == Approx(q).margin(1e-12));
            CHECK(q == Approx(t.frames[k].load_N / 2).margin(1e-12)); // each carries half
            CHECK(num(r, p + "frictional_strength_N") == Approx(mu * fn).epsilon(1e-8));
            const bool slips = q >= mu * 1.0;
            CHECK(num(r, p + "sliding") == (slips ? 1.0 : 0.0));
            // Transmitted force: the request while sticking, mu f_n once sliding.
            CHECK(ft == Approx(slips ? mu * fn : q).epsilon(1e-6).margin(1e-9));
            const double gamma = num(r, p + "gamma");
            CHECK(gamma == Approx(std::max(0.0, (mu * fn - ft) / (mu * fn))).margin(1e-6));
            CHECK(gamma == Approx(slips ? 0.0 : (mu - q) / mu).margin(1e-5));
            CHECK(r.at(p + "converged") == "1");
            if (k > 0 && !slips) CHECK(num(r, p + "stick_ratio") > 0.0);
        }
        // The right finger sees the load from the other side.
        if (k > 0) CHECK(num(r, "right_tangential_force_x_N") < 0.0);
    }
    CHECK(slip_rows == 2);
}

TEST_CASE("a slice of seed000_train runs: the first trials of the whole plan, both fingers",
          "[generators][trials]") {
    Spec spec = load_spec("datasets_spec/seed000_train.yaml");
    spec.outputs.images = false; // the mechanics and labels of the slice; images cost minutes
    spec.outputs.markers = false;
    const Run run(std::move(spec), "seed000", 2);
    CHECK(run.report.trials == 2);
    CHECK(run.report.planned_trials == 96);
    CHECK(run.report.flagged_frames == 0);
    const auto rows = read_csv(run.out / "labels.csv");
    REQUIRE(rows.size() == run.plan.trials[0].frames.size() + run.plan.trials[1].frames.size());
    CHECK(rows.front().at("split") == run.plan.trials[0].split);
    CHECK(rows.back().at("split") == run.plan.trials[1].split);
    CHECK(rows.back().at("trial") == "1");
    CHECK(num(rows.front(), "time_s") == Approx(0.01)); // 100 Hz
    for (const CsvRow& r : rows) {
        CHECK(r.at("left_converged") == "1");
        CHECK(r.at("right_converged") == "1");
    }
}

TEST_CASE("a slice of seed001_sliding runs: strain grids per frame, the plate ends sliding",
          "[generators][trials]") {
    const Run run(load_spec("datasets_spec/seed001_sliding.yaml"), "seed001", 1);
    CHECK(run.report.trials == 1);
    const auto rows = read_csv(run.out / "labels.csv");
    REQUIRE(rows.size() == 30);
    CHECK(num(rows.front(), "travel_mm") == Approx(0.05));
    CHECK(num(rows.back(), "travel_mm") == Approx(6.0));
    CHECK(num(rows.back(), "left_sliding") == 1.0);
    CHECK(num(rows.front(), "left_gamma") > 0.5);
    const fs::path strain = run.out / "strain" / "all" / "trial_000000" / "left.csv";
    std::ifstream in(strain);
    std::string line;
    int lines = 0;
    std::size_t columns = 0;
    while (std::getline(in, line)) {
        columns = std::size_t(std::count(line.begin(), line.end(), ',')) + 1;
        CHECK(columns == 1 + 101 * 76);
        ++lines;
    }
    CHECK(lines == 1 + 30); // header and one row per frame
    std::ifstream manifest_file(run.out / "manifest.json");
    const auto manifest = nlohmann::json::parse(manifest_file);
    CHECK(manifest["strain_grid"]["nx"] == 101);
    CHECK(manifest["strain_grid"]["ny"] == 76);
}
