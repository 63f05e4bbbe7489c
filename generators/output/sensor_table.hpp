#pragma once
/// sensors.csv: which sensor made each trial's images, and that sensor's drawn values, in a
/// dataset whose spec varies its sensor (plan/sensor_variants.hpp). One row per trial; the
/// values are written as the shortest text that reads back to the same double, so `check` can
/// compare them with the plan's draws exactly.
#include "generators/plan/plan.hpp"
#include "generators/spec/spec.hpp"

#include <string>

namespace chromasim::generators {

/// The header: split, trial, sensor, then what a sensor draws (sensor_draws), in order.
std::string sensors_header(const Spec& spec);

/// Trial `trial`'s row, ending in a newline.
std::string sensors_row(const TrialPlan& trial, const SensorVariant& sensor);

} // namespace chromasim::generators
