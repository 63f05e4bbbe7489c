#include "generators/plan/sensor_variants.hpp"

#include "generators/plan/stream.hpp"
#include "generators/spec/spec_schema.hpp"
#include "generators/spec/stage_params.hpp"

namespace chromasim::generators {

namespace {

/// Streams of the sensors' draws and of each trial's pick among them (plan.cpp has the others).
constexpr std::uint64_t kSensorStream = 300, kSensorPickStream = 301, kLedGainStream = 302;

constexpr std::string_view kGainKey = "sensor.led.gains[";

SensorVariant draw_variant(const Spec& spec, int id) {
    SensorVariant v;
    v.id = id;
    Stream stream(trial_seed(spec.seed, kSensorStream, std::uint64_t(id)));
    Stream gains(trial_seed(spec.seed, kLedGainStream, std::uint64_t(id)));
    for (const auto& [key, factor] : sensor_draws(spec)) {
        const bool gain = key.starts_with(kGainKey);
        v.values.emplace_back(key, draw(factor, (gain ? gains : stream).uniform()));
    }
    return v;
}

} // namespace

std::vector<std::pair<std::string, Factor>> sensor_draws(const Spec& spec) {
    std::vector<std::pair<std::string, Factor>> out(spec.varied.begin(), spec.varied.end());
    const double t = spec.sensor.led_gain_tolerance;
    if (!(t > 0)) return out;
    const std::vector<double> gains = led_gains(spec);
    for (std::size_t k = 0; k < gains.size(); ++k) {
        Factor f;
        f.is_range = true;
        f.min = gains[k] * (1.0 - t);
        f.max = gains[k] * (1.0 + t);
        out.emplace_back(std::string(kGainKey) + std::to_string(k) + "]", f);
    }
    return out;
}

std::string what_varies(const Spec& spec) {
    if (spec.varied.empty())
        return spec.sensor.led_gain_tolerance > 0 ? "sensor.led.gain_tolerance"
                                                  : "sensor.optics.marker_jitter_mm";
    return spec.varied.begin()->first + (spec.varied.size() > 1 ? ", ..." : "");
}

void assign_sensors(const Spec& spec, Plan& plan, std::size_t cells) {
    if (!varies_sensor(spec)) return;
    const int variants = spec.sampling.sensor_variants;
    const std::size_t count = variants > 0 ? std::size_t(variants) : plan.trials.size();
    const bool crossed = spec.sampling.sensor_assignment == "crossed";
    plan.sensors.reserve(count);
    for (std::size_t v = 0; v < count; ++v)
        plan.sensors.push_back(draw_variant(spec, int(v)));
    for (TrialPlan& trial : plan.trials) {
        const auto k = std::size_t(trial.id);
        if (variants == 0) {
            trial.sensor = trial.id;
        } else if (crossed) {
            trial.sensor = int(k / cells % count);
        } else {
            Stream stream(trial_seed(spec.seed, kSensorPickStream, k));
            trial.sensor = int(pick(count, stream.uniform()));
        }
    }
}

Spec sensor_spec(const Spec& spec, const SensorVariant& variant) {
    Spec out = spec;
    if (spec.sensor.led_gain_tolerance > 0) {
        out.sensor.led_gains = led_gains(spec);
        out.sensor.led_gain_tolerance = 0;
    }
    for (const auto& [key, value] : variant.values) {
        if (key.starts_with(kGainKey))
            out.sensor.led_gains.at(std::stoul(key.substr(kGainKey.size()))) = value;
        else
            set_varied_value(out, key, value);
    }
    out.sensor.variant = variant.id;
    out.resolved_yaml = resolved_spec_yaml(out);
    return out;
}

} // namespace chromasim::generators
