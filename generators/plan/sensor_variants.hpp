#pragma once
/// A randomized sensor: the `varied` keys a spec writes as a list or a range (Spec::varied)
/// drawn into a few sensors, each with its own marker jitter, and the sensor of each trial.
///
/// Sensor v draws every varied key, in key order, from its own stream (spec.seed, v): a list's
/// item or a uniform value in the range; then each LED's gain (sensor.led.gain_tolerance)
/// and the camera's position (sensor.camera.position_tolerance_mm), each from a stream of
/// its own. With sampling.sensor_variants = K > 0, trial k uses
/// sensor pick(K, u) for a uniform u of its own stream (spec.seed, k), or, crossed, the sensor
/// of its block of grid cells: neither depends on the other trials, so a slice of a plan keeps
/// its sensors. With K = 0 every trial has a sensor of
/// its own (sensor k for trial k). Each sensor costs a mechanics precompute and a light cache,
/// which the caches keep; K bounds that cost.
#include "generators/plan/plan.hpp"
#include "generators/spec/spec.hpp"

#include <string>

namespace chromasim::generators {

/// Whether `spec` draws its sensors: it writes a `varied` key as a list or a range, or jitters
/// its markers (each sensor its own layout), and is not already one sensor (sensor_spec).
inline bool varies_sensor(const Spec& spec) {
    return !spec.varied.empty() ||
           ((spec.sensor.marker_jitter_mm > 0 || spec.sensor.led_gain_tolerance > 0 ||
             spec.sensor.camera_position_tolerance_mm > 0) &&
            spec.sensor.variant < 0);
}

/// What a sensor draws, in draw order, each with the values it may take: the varied keys
/// (Spec::varied), then with sensor.led.gain_tolerance t > 0 each LED's gain,
/// "sensor.led.gains[k]", within gains[k] (1 +- t), then with
/// sensor.camera.position_tolerance_mm d > 0 "sensor.camera.position_mm[i]" within
/// position_mm[i] +- d. sensors.csv has these columns.
std::vector<std::pair<std::string, Factor>> sensor_draws(const Spec& spec);

/// What makes `spec` vary its sensor, for messages: its first varied key (", ..." when there
/// are more), sensor.led.gain_tolerance, sensor.camera.position_tolerance_mm or
/// sensor.optics.marker_jitter_mm.
std::string what_varies(const Spec& spec);

/// Draws the plan's sensors and gives every trial its own (TrialPlan::sensor); a spec that
/// varies nothing leaves the plan as it is. Crossed sensors (sampling.sensor_assignment) run
/// each block of `cells` trials (a full grid's cells) on the next sensor: trial k uses sensor
/// (k div cells) mod K, so every repetition holds every cell on every sensor.
void assign_sensors(const Spec& spec, Plan& plan, std::size_t cells);

/// `spec` with `variant`'s draws in its fields (Spec::varied left empty, resolved_yaml that
/// one sensor's): the spec of the sensor that makes the trials of that variant.
Spec sensor_spec(const Spec& spec, const SensorVariant& variant);

} // namespace chromasim::generators
