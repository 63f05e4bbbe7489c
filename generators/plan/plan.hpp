#pragma once
/// A spec turned into the trials and frames to simulate: plain data, no work done yet.
///
/// make_plan draws every trial from its own random stream, seeded by (spec.seed, trial index):
/// trial k's object, friction, grip, rate, target load and per-finger jitter do not depend on
/// any other trial, so a slice of a plan (generate --max-trials) or a grid with more
/// repetitions holds the same trials. Two things are joint by nature and depend on the trial
/// count: the Latin hypercube strata and the split assignment (a seeded shuffle of all trials).
#include "generators/spec/spec.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <string>
#include <vector>

namespace chromasim::generators {

/// What a frame of a trial does.
enum class Phase {
    grasp, ///< the grip force ramps up from first touch
    hold,  ///< grip force held, no load
    load,  ///< the tangential load ramps, no finger slips
    slip,  ///< the load ramps and at least one finger's load reached mu f_n: it slips
    slide, ///< the object slides under displacement control (protocol.type slide)
};

/// "grasp", "hold", "load", "slip", "slide".
const char* phase_name(Phase phase);

/// One fingertip's requested load in one frame, in that fingertip's own frame.
struct FingerLoad {
    double normal_force_N = 0.0;              ///< grip force
    Eigen::Vector2d tangential_force_N{0, 0}; ///< requested load (x, y), force control
    bool displacement_control = false;        ///< the object's travel is prescribed
    Eigen::Vector2d travel_mm{0, 0};          ///< requested travel (x, y), displacement control
    double mu = 0.0;                          ///< Coulomb coefficient of this finger
    /// Same requested load: a frame equal to the previous one is not solved again.
    bool operator==(const FingerLoad& o) const;
};

struct FramePlan {
    int index = 0;       ///< frame index within its trial, from 0
    double time_s = 0.0; ///< from first touch; frames at 1 / frame_rate_Hz (slide: travel/speed)
    Phase phase = Phase::grasp;
    double load_N = 0.0;             ///< total requested tangential load, all fingers (grasp_load)
    double travel_mm = 0.0;          ///< the object's requested travel (slide)
    std::vector<FingerLoad> fingers; ///< one per fingertip, TrialPlan::fingers order
};

/// A fingertip's view of its trial.
struct FingerSetup {
    std::string name;                ///< "left" or "right"
    double mu = 0.0;                 ///< the trial's mu with this finger's jitter
    double direction_deg = 0.0;      ///< load (or slide) direction in this finger's x-y plane
    Eigen::Vector2d offset_mm{0, 0}; ///< object offset in this finger's frame (mirror, jitter)
    double yaw_deg = 0.0;            ///< object yaw in this finger's frame (mirror)
};

/// Finger `finger` (0 left, 1 right) of a grasp of `object` at friction `mu`, without the
/// spec's jitter: the right finger sees the object mirrored and turned 180 deg about its z
/// axis, and its load points the opposite way (protocol.load_direction_deg + 180 deg).
FingerSetup grasp_finger(const Spec& spec, const Spec::Object& object, double mu, int finger);
/// The unit vector of `finger`'s load direction in its x-y plane.
Eigen::Vector2d load_direction(const FingerSetup& finger);

/// One sensor a trial can use: a draw of every key the spec varies (Spec::varied).
struct SensorVariant {
    int id = 0; ///< index into Plan::sensors
    std::vector<std::pair<std::string, double>> values; ///< Spec::varied's keys, in its order
};

struct TrialPlan {
    int id = 0;        ///< trial index in the plan, from 0
    std::string split; ///< splits[].name
    int object = 0;    ///< index into Spec::objects
    int friction = 0;  ///< index into Spec::friction
    double mu = 0.0;   ///< the trial's mu, before per-finger jitter
    double grip_N = 0.0, rate_N_per_s = 0.0, target_load_N = 0.0;
    std::vector<FingerSetup> fingers;
    std::vector<FramePlan> frames;
    int first_slip_frame = -1; ///< first frame of phase slip; -1 when no finger slips
    int sensor = -1; ///< index into Plan::sensors; -1: the spec's own sensor (nothing varies)
};

struct Plan {
    std::vector<TrialPlan> trials;
    /// The sensors drawn from a spec that varies its sensor (empty when it does not).
    std::vector<SensorVariant> sensors;
    /// Frames over all trials (one frame holds one image per fingertip).
    std::size_t frame_count() const;
};

/// The trials of a validated spec (sampling.method, splits), each with its timeline:
/// - grasp_load: grasp frames (grip ramps linearly over protocol.grasp_s), hold frames
///   (protocol.hold_s), then load frames: the total load L = rate t ramps until the target
///   load; each finger carries L / fingers along its direction. A finger whose load reaches
///   mu f_n (its own mu) slips; from the first such frame the trial keeps
///   protocol.slip_frames frames (phase slip), then ends. It also ends at the frame that
///   reaches the target load (that frame's load is the target).
/// - slide: grasp and hold frames as above, then protocol.slide.frames frames at travels
///   evenly spaced from start_mm to end_mm under displacement control.
/// Frame times are k / frame_rate_Hz, k = 1, 2, ... (slide frames: the hold's end plus
/// travel / speed). A spec that varies its sensor also gets its sensors (sensor_variants.hpp).
/// Pure and deterministic: equal specs give equal plans.
Plan make_plan(const Spec& spec);

/// One part of a sharded run (`generate --shard K/N`): shard `index` of `count`. Trial t of
/// the plan (or of its slice) belongs to shard (t mod count) + 1: round robin, so every shard
/// holds floor(T/N) or ceil(T/N) trials whatever their lengths, and a shard's trials are
/// spread over the whole plan (its objects, frictions and splits) rather than one block of it.
/// `count` 0: not sharded, every trial.
struct Shard {
    int index = 0; ///< K, from 1
    int count = 0; ///< N; 0: not sharded
    bool sharded() const { return count > 0; }
    bool owns(int trial) const { return count == 0 || trial % count == index - 1; }
    std::string text() const; ///< "K/N" (empty when not sharded)
    bool operator==(const Shard&) const = default;
};

/// Parses the argument of `--shard`, "K/N" with integers 1 <= K <= N. Throws SpecError naming
/// `--shard`, the value and what is allowed.
Shard parse_shard(const std::string& text);

/// The seed of trial `trial`'s random stream `stream` (a splitmix64 mix of the three).
std::uint64_t trial_seed(std::uint64_t seed, std::uint64_t stream, std::uint64_t trial);

} // namespace chromasim::generators
