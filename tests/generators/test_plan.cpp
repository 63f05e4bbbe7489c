// The plan of trials: sampling (full grid, random, Latin hypercube), splits, the trial
// timelines (grasp, hold, load, slip; slide) and their determinism. Pure data: no mechanics.
#include "generators/plan/plan.hpp"
#include "generators/spec/spec.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <string>

using namespace chromasim::generators;

namespace {

Spec spec_of(const std::string& yaml) {
    return parse_spec(yaml, "plan.yaml");
}

/// Every field of two trials agrees, split aside (the split depends on the trial count).
void require_same_trial(const TrialPlan& a, const TrialPlan& b) {
    CHECK(a.id == b.id);
    CHECK(a.object == b.object);
    CHECK(a.friction == b.friction);
    CHECK(a.mu == b.mu);
    CHECK(a.grip_N == b.grip_N);
    CHECK(a.rate_N_per_s == b.rate_N_per_s);
    CHECK(a.target_load_N == b.target_load_N);
    CHECK(a.first_slip_frame == b.first_slip_frame);
    REQUIRE(a.fingers.size() == b.fingers.size());
    for (std::size_t f = 0; f < a.fingers.size(); ++f) {
        CHECK(a.fingers[f].mu == b.fingers[f].mu);
        CHECK(a.fingers[f].offset_mm == b.fingers[f].offset_mm);
        CHECK(a.fingers[f].direction_deg == b.fingers[f].direction_deg);
    }
    REQUIRE(a.frames.size() == b.frames.size());
    for (std::size_t k = 0; k < a.frames.size(); ++k) {
        CHECK(a.frames[k].time_s == b.frames[k].time_s);
        CHECK(a.frames[k].phase == b.frames[k].phase);
        CHECK(a.frames[k].fingers == b.frames[k].fingers);
    }
}

const std::string kFactors = "objects: [{name: flat}, {name: curved, shape: sphere}]\n"
                             "friction: [{name: high, mu: 1.1}, {name: low, mu: {min: 0.4, "
                             "max: 0.6}}]\n"
                             "fingers: {mu_jitter: 0.05, offset_jitter_mm: 0.5}\n"
                             "protocol: {grip_N: {min: 1, max: 2.5}, load_rate_N_per_s: [0.5, 1], "
                             "target_load_N: {min: 2, max: 3}, frame_rate_Hz: 5, "
                             "grasp_s: 0.4, hold_s: 0.4}\n";

} // namespace

TEST_CASE("the same spec and seed give the same plan, another seed another one",
          "[generators][plan]") {
    const Spec spec = spec_of(kFactors + "sampling: {method: random, trials: 12}\n");
    const Plan a = make_plan(spec), b = make_plan(spec);
    REQUIRE(a.trials.size() == 12);
    for (std::size_t k = 0; k < a.trials.size(); ++k) {
        require_same_trial(a.trials[k], b.trials[k]);
        CHECK(a.trials[k].split == b.trials[k].split);
    }
    const Plan c =
        make_plan(spec_of(kFactors + "seed: 2\nsampling: {method: random, trials: 12}\n"));
    int differ = 0;
    for (std::size_t k = 0; k < a.trials.size(); ++k)
        differ += a.trials[k].grip_N != c.trials[k].grip_N;
    CHECK(differ == 12); // a continuous draw: equal only by accident
    CHECK(trial_seed(1, 0, 5) != trial_seed(1, 0, 6));
    CHECK(trial_seed(1, 0, 5) != trial_seed(2, 0, 5));
    CHECK(trial_seed(1, 0, 5) != trial_seed(1, 1, 5));
}

TEST_CASE("trial k's content does not depend on the trial count", "[generators][plan]") {
    SECTION("random") {
        const Plan few = make_plan(spec_of(kFactors + "sampling: {method: random, trials: 5}\n"));
        const Plan many = make_plan(spec_of(kFactors + "sampling: {method: random, trials: 40}\n"));
        for (std::size_t k = 0; k < few.trials.size(); ++k)
            require_same_trial(few.trials[k], many.trials[k]);
    }
    SECTION("full grid: more repetitions append trials") {
        const Plan one = make_plan(spec_of(kFactors + "sampling: {repetitions: 1}\n"));
        const Plan three = make_plan(spec_of(kFactors + "sampling: {repetitions: 3}\n"));
        REQUIRE(three.trials.size() == 3 * one.trials.size());
        for (std::size_t k = 0; k < one.trials.size(); ++k)
            require_same_trial(one.trials[k], three.trials[k]);
    }
}

TEST_CASE("a full grid crosses every listed value, repetitions times, and draws ranges",
          "[generators][plan]") {
    const Spec spec = spec_of("objects: [{name: flat}, {name: curved, shape: sphere}]\n"
                              "friction: [{name: h, mu: 1.1}, {name: m, mu: 0.8}, "
                              "{name: l, mu: 0.5}]\n"
                              "protocol: {grip_N: [1.0, 1.5, 2.0, 2.5], load_rate_N_per_s: "
                              "[0.5, 1.0], target_load_N: {min: 2, max: 3}, hold_s: 0, "
                              "frame_rate_Hz: 10}\n"
                              "sampling: {method: full_grid, repetitions: 2}\n");
    const Plan plan = make_plan(spec);
    REQUIRE(plan.trials.size() == 2 * 3 * 4 * 2 * 2); // seed 000's 96 trials
    std::map<std::tuple<int, int, double, double>, int> cells;
    std::set<double> targets;
    for (const TrialPlan& t : plan.trials) {
        ++cells[{t.object, t.friction, t.grip_N, t.rate_N_per_s}];
        CHECK(t.mu == spec.friction[std::size_t(t.friction)].mu.values[0]);
        CHECK(t.target_load_N >= 2.0);
        CHECK(t.target_load_N <= 3.0);
        targets.insert(t.target_load_N);
    }
    CHECK(cells.size() == 48);
    for (const auto& [cell, count] : cells)
        CHECK(count == 2);
    CHECK(targets.size() == 96); // drawn per trial
    // Every (object, friction) condition 16 times, as in seed 000.
    std::map<std::pair<int, int>, int> conditions;
    for (const TrialPlan& t : plan.trials)
        ++conditions[{t.object, t.friction}];
    for (const auto& [condition, count] : conditions)
        CHECK(count == 16);
}

TEST_CASE("a Latin hypercube uses each stratum of each factor exactly once", "[generators][plan]") {
    const int n = 50;
    const Plan plan =
        make_plan(spec_of(kFactors + "sampling: {method: latin_hypercube, trials: 50}\n"));
    REQUIRE(plan.trials.size() == std::size_t(n));
    std::vector<int> grip(n, 0), target(n, 0), low_mu_strata;
    std::map<int, int> objects, rates;
    for (const TrialPlan& t : plan.trials) {
        ++grip[std::size_t(std::floor((t.grip_N - 1.0) / 1.5 * n))];
        ++target[std::size_t(std::floor((t.target_load_N - 2.0) / 1.0 * n))];
        ++objects[t.object];
        ++rates[int(t.rate_N_per_s * 10)];
    }
    for (int s = 0; s < n; ++s) {
        INFO("stratum " << s);
        CHECK(grip[std::size_t(s)] == 1);
        CHECK(target[std::size_t(s)] == 1);
    }
    // Lists and categories: the strata split evenly over their values.
    CHECK(objects[0] == 25);
    CHECK(objects[1] == 25);
    CHECK(rates[5] == 25);
    CHECK(rates[10] == 25);
}

TEST_CASE("random sampling draws lists uniformly and ranges within bounds", "[generators][plan]") {
    const Plan plan = make_plan(spec_of(kFactors + "sampling: {method: random, trials: 4000}\n"));
    int curved = 0, low = 0;
    for (const TrialPlan& t : plan.trials) {
        curved += t.object == 1;
        low += t.friction == 1;
        CHECK((t.rate_N_per_s == 0.5 || t.rate_N_per_s == 1.0));
        CHECK(t.grip_N >= 1.0);
        CHECK(t.grip_N <= 2.5);
        if (t.friction == 1) {
            CHECK(t.mu >= 0.4);
            CHECK(t.mu <= 0.6);
        }
    }
    // Binomial(4000, 1/2): standard deviation 31.6; 4 sigma.
    CHECK(std::abs(curved - 2000) < 127);
    CHECK(std::abs(low - 2000) < 127);
}

TEST_CASE("splits take their fractions of the trials by a seeded shuffle", "[generators][plan]") {
    const std::string base = "sampling: {method: random, trials: 96}\n";
    const Plan plan = make_plan(
        spec_of(base + "splits: [{name: train, fraction: 0.8}, {name: test, fraction: 0.2}]\n"));
    std::map<std::string, int> count;
    for (const TrialPlan& t : plan.trials)
        ++count[t.split];
    CHECK(count["train"] == 77); // round(0.8 * 96)
    CHECK(count["test"] == 19);
    // Shuffled, not the first 77: some test trial lies among the first 77 ids.
    bool interleaved = false;
    for (int k = 0; k < 77; ++k)
        interleaved = interleaved || plan.trials[std::size_t(k)].split == "test";
    CHECK(interleaved);
    const Plan three = make_plan(spec_of(base + "splits: [{name: a, fraction: 0.5}, {name: b, "
                                                "fraction: 0.25}, {name: c, fraction: 0.25}]\n"));
    count.clear();
    for (const TrialPlan& t : three.trials)
        ++count[t.split];
    CHECK(count == std::map<std::string, int>{{"a", 48}, {"b", 24}, {"c", 24}});
    for (const TrialPlan& t : make_plan(spec_of(base)).trials)
        CHECK(t.split == "all"); // the default single split
}

TEST_CASE("a grasp_load trial: grasp ramp, hold at the grip force, load ramp to the target",
          "[generators][plan]") {
    const Spec spec = spec_of("friction: [{mu: 2.0}]\n"
                              "protocol: {frame_rate_Hz: 10, grip_N: 1.0, grasp_s: 0.3, hold_s: "
                              "0.2, load_rate_N_per_s: 1.0, target_load_N: 0.45}\n");
    const Plan plan = make_plan(spec);
    REQUIRE(plan.trials.size() == 1);
    const TrialPlan& t = plan.trials[0];
    REQUIRE(t.frames.size() == 3 + 2 + 5);
    REQUIRE(t.fingers.size() == 2);
    CHECK(t.fingers[0].name == "left");
    CHECK(t.fingers[1].name == "right");
    CHECK(t.fingers[1].direction_deg == 180.0); // mirrored
    const double grasp[3] = {1.0 / 3, 2.0 / 3, 1.0};
    for (std::size_t k = 0; k < t.frames.size(); ++k) {
        const FramePlan& f = t.frames[k];
        INFO("frame " << k);
        CHECK(f.index == int(k));
        CHECK(f.time_s == Approx(0.1 * double(k + 1)));
        for (const FingerLoad& l : f.fingers) {
            CHECK(l.mu == 2.0);
            CHECK(l.normal_force_N == Approx(k < 3 ? grasp[k] : 1.0));
        }
        if (k < 3) CHECK(f.phase == Phase::grasp);
        if (k == 3 || k == 4) {
            CHECK(f.phase == Phase::hold);
            CHECK(f.fingers == t.frames[k - 1].fingers); // held: nothing to solve again
        }
        if (k >= 5) {
            CHECK(f.phase == Phase::load);
            const double load = std::min(0.1 * double(k - 4), 0.45);
            CHECK(f.load_N == Approx(load));
            // Each finger carries half, along its own direction.
            CHECK(f.fingers[0].tangential_force_N.x() == Approx(load / 2));
            CHECK(f.fingers[1].tangential_force_N.x() == Approx(-load / 2));
            CHECK(f.fingers[1].tangential_force_N.y() == Approx(0).margin(1e-12));
        }
    }
    CHECK(t.frames.back().load_N == 0.45); // the last frame reaches the target exactly
    CHECK(t.first_slip_frame == -1);
}

TEST_CASE("slip ends the trial after slip_frames frames with a slipping finger",
          "[generators][plan]") {
    // mu f_n = 0.5 N per finger: the total load 1.0 N (0.5 each) slips at frame 10 of the ramp.
    for (const int slip_frames : {0, 1, 3}) {
        INFO("slip_frames " << slip_frames);
        const Spec spec = spec_of("friction: [{mu: 0.5}]\n"
                                  "protocol: {frame_rate_Hz: 10, grip_N: 1.0, grasp_s: 0, "
                                  "hold_s: 0, load_rate_N_per_s: 1.0, target_load_N: 3, "
                                  "slip_frames: " +
                                  std::to_string(slip_frames) + "}\n");
        const Plan plan = make_plan(spec);
        const TrialPlan& t = plan.trials.at(0);
        REQUIRE(t.frames.size() == std::size_t(9 + slip_frames));
        for (const FramePlan& f : t.frames) {
            const double q = f.fingers[0].tangential_force_N.norm();
            CHECK((f.phase == Phase::slip) == (q >= 0.5 * 1.0 - 1e-12));
        }
        CHECK(t.first_slip_frame == (slip_frames > 0 ? 9 : -1));
    }
}

TEST_CASE("per-finger jitter stays within its bounds and differs between fingers",
          "[generators][plan]") {
    const Plan plan =
        make_plan(spec_of("objects: [{shape: sphere, offset_x_mm: 1}]\nfriction: [{mu: 1.0}]\n"
                          "fingers: {mu_jitter: 0.1, offset_jitter_mm: 0.5}\n"
                          "protocol: {frame_rate_Hz: 10, hold_s: 0}\n"
                          "sampling: {method: random, trials: 200}\n"));
    int differ = 0;
    for (const TrialPlan& t : plan.trials) {
        for (const FingerSetup& f : t.fingers) {
            CHECK(f.mu >= 0.9);
            CHECK(f.mu <= 1.1);
            CHECK(std::abs(f.offset_mm.y()) <= 0.5);
        }
        // The right finger sees the object mirrored: its offset is about -1 mm.
        CHECK(std::abs(t.fingers[0].offset_mm.x() - 1.0) <= 0.5);
        CHECK(std::abs(t.fingers[1].offset_mm.x() + 1.0) <= 0.5);
        differ += t.fingers[0].mu != t.fingers[1].mu;
        for (const FramePlan& f : t.frames)
            CHECK(f.fingers[1].mu == t.fingers[1].mu);
    }
    CHECK(differ == 200);
}

TEST_CASE("a slide trial: travel evenly spaced from start to end under displacement control",
          "[generators][plan]") {
    const Spec spec = spec_of("fingers: {count: 1}\n"
                              "protocol: {type: slide, grip_N: 1.2, grasp_s: 0, hold_s: 0, "
                              "slide: {start_mm: 0.05, end_mm: 6, frames: 30, speed_mm_per_s: "
                              "10}}\n");
    const Plan plan = make_plan(spec);
    const TrialPlan& t = plan.trials.at(0);
    REQUIRE(t.frames.size() == 30);
    REQUIRE(t.fingers.size() == 1);
    for (std::size_t k = 0; k < 30; ++k) {
        const FramePlan& f = t.frames[k];
        const double travel = 0.05 + (6.0 - 0.05) * double(k) / 29;
        CHECK(f.phase == Phase::slide);
        CHECK(f.travel_mm == Approx(travel));
        CHECK(f.time_s == Approx(travel / 10));
        CHECK(f.fingers[0].displacement_control);
        CHECK(f.fingers[0].travel_mm.x() == Approx(travel));
        CHECK(f.fingers[0].normal_force_N == 1.2);
    }
}
