#include "generators/plan/plan.hpp"

#include "generators/plan/sensor_variants.hpp"
#include "generators/plan/stream.hpp"
#include "mechanics/contact.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

namespace chromasim::generators {

namespace {

/// Streams of a plan: each trial's own, one per Latin hypercube factor, the split shuffle.
constexpr std::uint64_t kTrialStream = 0, kLhsStream = 100, kSplitStream = 200;

/// A uniform permutation of 0 .. n-1 (Fisher-Yates).
std::vector<std::size_t> shuffled(std::size_t n, Stream stream) {
    std::vector<std::size_t> p(n);
    for (std::size_t i = 0; i < n; ++i)
        p[i] = i;
    for (std::size_t i = n; i > 1; --i)
        std::swap(p[i - 1], p[pick(i, stream.uniform())]);
    return p;
}

/// The factors of a trial, in the order they take their uniforms from the trial's stream.
enum FactorId : std::size_t { kObject, kFriction, kMu, kGrip, kRate, kTarget, kFactors };
using Uniforms = std::array<double, kFactors>;

/// Values each factor contributes to the full grid: the list's length (objects, friction,
/// listed values); 1 for a range and for mu (drawn within its friction condition).
std::array<std::size_t, kFactors> grid_sizes(const Spec& spec) {
    const auto values = [](const Factor& f) { return f.is_range ? 1 : f.values.size(); };
    const Spec::Protocol& p = spec.protocol;
    return {spec.objects.size(), spec.friction.size(),        1,
            values(p.grip_N),    values(p.load_rate_N_per_s), values(p.target_load_N)};
}

std::size_t grid_cells(const Spec& spec) {
    std::size_t cells = 1;
    for (const std::size_t n : grid_sizes(spec))
        cells *= n;
    return cells;
}

/// Trials of the plan: a full grid's cells, times its sensors when they are crossed with it,
/// times its repetitions.
std::size_t trial_count(const Spec& spec) {
    if (spec.sampling.method != "full_grid") return std::size_t(spec.sampling.trials);
    const bool crossed = spec.sampling.sensor_assignment == "crossed" && varies_sensor(spec);
    return grid_cells(spec) * (crossed ? std::size_t(spec.sampling.sensor_variants) : 1) *
           std::size_t(spec.sampling.repetitions);
}

/// Full grid: the gridded factors' uniforms land on their cell's value (the last factor
/// varies fastest; trial k is in cell k mod cells, so repetitions append trials).
void place_in_grid(const Spec& spec, std::size_t trial, Uniforms& u) {
    const auto sizes = grid_sizes(spec);
    std::size_t cell = trial;
    for (std::size_t f = kFactors; f-- > 0;) {
        if (sizes[f] == 1) continue; // a range, or mu: keeps its draw
        const std::size_t value = cell % sizes[f];
        cell /= sizes[f];
        u[f] = (double(value) + 0.5) / double(sizes[f]);
    }
}

} // namespace

FingerSetup grasp_finger(const Spec& spec, const Spec::Object& object, double mu, int finger) {
    const double mirror = finger == 0 ? 1.0 : -1.0;
    FingerSetup s;
    s.name = finger == 0 ? "left" : "right";
    s.mu = mu;
    s.direction_deg = spec.protocol.load_direction_deg + (finger == 0 ? 0.0 : 180.0);
    s.offset_mm = mirror * Eigen::Vector2d(object.offset_x_mm, object.offset_y_mm);
    s.yaw_deg = object.yaw_deg + (finger == 0 ? 0.0 : (object.yaw_deg > 0 ? -180.0 : 180.0));
    return s;
}

Eigen::Vector2d load_direction(const FingerSetup& f) {
    const double a = f.direction_deg * std::numbers::pi / 180.0;
    return {std::cos(a), std::sin(a)};
}

namespace {

/// One fingertip's setup with the spec's per-finger jitter of mu and of the object's offset.
FingerSetup finger_setup(const Spec& spec, const Spec::Object& object, double mu, int finger,
                         Stream& stream) {
    const double u_mu = stream.uniform(), u_x = stream.uniform(), u_y = stream.uniform();
    const double j = spec.fingers.offset_jitter_mm;
    FingerSetup s = grasp_finger(spec, object, mu, finger);
    s.mu = mu * (1.0 + spec.fingers.mu_jitter * (2.0 * u_mu - 1.0));
    s.offset_mm += j * Eigen::Vector2d(2.0 * u_x - 1.0, 2.0 * u_y - 1.0);
    return s;
}

/// A frame at grip force `grip_N` on every finger and no load.
FramePlan pressed(const TrialPlan& trial, int index, double time_s, Phase phase, double grip_N) {
    FramePlan f{index, time_s, phase, 0.0, 0.0, {}};
    for (const FingerSetup& s : trial.fingers)
        f.fingers.push_back({grip_N, {0, 0}, false, {0, 0}, s.mu});
    return f;
}

/// Grasp then hold frames; returns the time of the last one.
double grasp_and_hold(const Spec& spec, TrialPlan& trial) {
    const double dt = 1.0 / spec.protocol.frame_rate_Hz;
    const int grasp = int(std::lround(spec.protocol.grasp_s / dt));
    const int hold = int(std::lround(spec.protocol.hold_s / dt));
    for (int k = 1; k <= grasp; ++k)
        trial.frames.push_back(pressed(trial, int(trial.frames.size()), k * dt, Phase::grasp,
                                       k == grasp ? trial.grip_N : trial.grip_N * k / grasp));
    for (int k = 1; k <= hold; ++k)
        trial.frames.push_back(
            pressed(trial, int(trial.frames.size()), (grasp + k) * dt, Phase::hold, trial.grip_N));
    return (grasp + hold) * dt;
}

/// Load frames: the ramp to the target load, ended slip_frames frames after the first slip.
void load_ramp(const Spec& spec, TrialPlan& trial, double t0) {
    const double dt = 1.0 / spec.protocol.frame_rate_Hz;
    const double share = 1.0 / double(trial.fingers.size());
    int slipping_frames = 0;
    for (int k = 1;; ++k) {
        const double load = std::min(trial.rate_N_per_s * k * dt, trial.target_load_N);
        FramePlan f =
            pressed(trial, int(trial.frames.size()), t0 + k * dt, Phase::load, trial.grip_N);
        f.load_N = load;
        bool slips = false;
        for (std::size_t i = 0; i < trial.fingers.size(); ++i) {
            const double q = load * share;
            f.fingers[i].tangential_force_N = q * load_direction(trial.fingers[i]);
            slips = slips || mechanics::gross_slip(trial.fingers[i].mu, trial.grip_N, q);
        }
        if (slips) {
            if (++slipping_frames > spec.protocol.slip_frames) return;
            f.phase = Phase::slip;
            if (trial.first_slip_frame < 0) trial.first_slip_frame = f.index;
        }
        trial.frames.push_back(std::move(f));
        if (load >= trial.target_load_N) return;
    }
}

/// Slide frames: the object's travel, evenly spaced from start to end.
void slide(const Spec& spec, TrialPlan& trial, double t0) {
    const Spec::Protocol& p = spec.protocol;
    for (int k = 0; k < p.slide_frames; ++k) {
        const double s = p.slide_frames > 1 ? double(k) / (p.slide_frames - 1) : 0.0;
        const double travel = p.slide_start_mm + s * (p.slide_end_mm - p.slide_start_mm);
        FramePlan f = pressed(trial, int(trial.frames.size()), t0 + travel / p.slide_speed_mm_per_s,
                              Phase::slide, trial.grip_N);
        f.travel_mm = travel;
        for (std::size_t i = 0; i < trial.fingers.size(); ++i) {
            f.fingers[i].displacement_control = true;
            f.fingers[i].travel_mm = travel * load_direction(trial.fingers[i]);
        }
        trial.frames.push_back(std::move(f));
    }
}

/// Trial `k` from its uniforms (already placed in the grid or the strata).
TrialPlan make_trial(const Spec& spec, std::size_t k, const Uniforms& u, Stream& stream) {
    TrialPlan t;
    t.id = int(k);
    t.object = int(pick(spec.objects.size(), u[kObject]));
    t.friction = int(pick(spec.friction.size(), u[kFriction]));
    t.mu = draw(spec.friction[std::size_t(t.friction)].mu, u[kMu]);
    t.grip_N = draw(spec.protocol.grip_N, u[kGrip]);
    t.rate_N_per_s = draw(spec.protocol.load_rate_N_per_s, u[kRate]);
    t.target_load_N = draw(spec.protocol.target_load_N, u[kTarget]);
    for (int finger = 0; finger < 2; ++finger) { // always two draws: the same stream for 1 or 2
        FingerSetup s =
            finger_setup(spec, spec.objects[std::size_t(t.object)], t.mu, finger, stream);
        if (finger < spec.fingers.count) t.fingers.push_back(std::move(s));
    }
    const double t0 = grasp_and_hold(spec, t);
    if (spec.protocol.type == "slide")
        slide(spec, t, t0);
    else
        load_ramp(spec, t, t0);
    return t;
}

/// The split of every trial: a seeded shuffle, cut at the rounded cumulative fractions.
void assign_splits(const Spec& spec, Plan& plan) {
    const std::size_t n = plan.trials.size();
    const std::vector<std::size_t> order =
        shuffled(n, Stream(trial_seed(spec.seed, kSplitStream, 0)));
    std::size_t position = 0;
    double cumulative = 0.0;
    for (std::size_t s = 0; s < spec.splits.size(); ++s) {
        cumulative += spec.splits[s].fraction;
        const std::size_t end =
            s + 1 == spec.splits.size() ? n : std::min(n, std::size_t(std::lround(cumulative * n)));
        for (; position < end; ++position)
            plan.trials[order[position]].split = spec.splits[s].name;
    }
}

} // namespace

const char* phase_name(Phase phase) {
    switch (phase) {
    case Phase::grasp:
        return "grasp";
    case Phase::hold:
        return "hold";
    case Phase::load:
        return "load";
    case Phase::slip:
        return "slip";
    case Phase::slide:
        return "slide";
    }
    return "?";
}

bool FingerLoad::operator==(const FingerLoad& o) const {
    return normal_force_N == o.normal_force_N && tangential_force_N == o.tangential_force_N &&
           displacement_control == o.displacement_control && travel_mm == o.travel_mm && mu == o.mu;
}

std::string Shard::text() const {
    return sharded() ? std::to_string(index) + "/" + std::to_string(count) : std::string();
}

Shard parse_shard(const std::string& text) {
    const auto bad = [&](const std::string& problem) {
        return SpecError("--shard: value '" + text + "' " + problem +
                         "; allowed: K/N with integers 1 <= K <= N (shard K of N, e.g. 2/8)");
    };
    // Digits only: std::stoi would take "+1", " 1" or "1x".
    const auto number = [&](const std::string& digits) {
        if (digits.empty() || digits.size() > 9 ||
            digits.find_first_not_of("0123456789") != std::string::npos)
            throw bad("is not of the form K/N");
        return std::stoi(digits);
    };
    const std::size_t slash = text.find('/');
    if (slash == std::string::npos) throw bad("is not of the form K/N");
    Shard shard;
    shard.index = number(text.substr(0, slash));
    shard.count = number(text.substr(slash + 1));
    if (shard.count < 1) throw bad("has N < 1");
    if (shard.index < 1 || shard.index > shard.count) throw bad("has K outside 1..N");
    return shard;
}

std::size_t Plan::frame_count() const {
    std::size_t n = 0;
    for (const TrialPlan& t : trials)
        n += t.frames.size();
    return n;
}

std::uint64_t trial_seed(std::uint64_t seed, std::uint64_t stream, std::uint64_t trial) {
    // splitmix64's finalizer over a combination of the three (Steele, Lea, Flood 2014).
    std::uint64_t z = seed * 0x9E3779B97F4A7C15ull + stream * 0xD1B54A32D192ED03ull + trial;
    for (int round = 0; round < 2; ++round) {
        z += 0x9E3779B97F4A7C15ull;
        z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
        z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
        z ^= z >> 31;
    }
    return z;
}

Plan make_plan(const Spec& spec) {
    const std::size_t n = trial_count(spec);
    // Latin hypercube: per factor, a permutation of the strata (joint over all trials).
    std::vector<std::vector<std::size_t>> strata;
    if (spec.sampling.method == "latin_hypercube")
        for (std::size_t f = 0; f < kFactors; ++f)
            strata.push_back(shuffled(n, Stream(trial_seed(spec.seed, kLhsStream + f, 0))));
    Plan plan;
    plan.trials.reserve(n);
    for (std::size_t k = 0; k < n; ++k) {
        Stream stream(trial_seed(spec.seed, kTrialStream, k));
        Uniforms u;
        for (double& x : u)
            x = stream.uniform();
        if (spec.sampling.method == "full_grid") place_in_grid(spec, k, u);
        if (!strata.empty())
            for (std::size_t f = 0; f < kFactors; ++f)
                u[f] = (double(strata[f][k]) + u[f]) / double(n);
        plan.trials.push_back(make_trial(spec, k, u, stream));
    }
    assign_splits(spec, plan);
    assign_sensors(spec, plan, spec.sampling.method == "full_grid" ? grid_cells(spec) : 1);
    return plan;
}

} // namespace chromasim::generators
