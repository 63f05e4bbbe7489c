#include "generators/output/sensor_table.hpp"

#include "generators/plan/sensor_variants.hpp"
#include "generators/spec/spec_schema.hpp"

namespace chromasim::generators {

std::string sensors_header(const Spec& spec) {
    std::string header = "split,trial,sensor";
    for (const auto& [key, factor] : sensor_draws(spec))
        header += "," + key;
    return header;
}

std::string sensors_row(const TrialPlan& trial, const SensorVariant& sensor) {
    std::string row = trial.split + "," + std::to_string(trial.id) + "," + std::to_string(sensor.id);
    for (const auto& [key, value] : sensor.values)
        row += "," + format_number(value);
    return row + "\n";
}

} // namespace chromasim::generators
