#include "generators/plan/sensor_variants.hpp"

#include "generators/plan/stream.hpp"
#include "generators/spec/spec_schema.hpp"
#include "generators/spec/stage_params.hpp"

namespace chromasim::generators {

namespace {

/// Streams of the sensors' draws and of each trial's pick among them (plan.cpp has the others).
constexpr std::uint64_t kSensorStream = 300, kSensorPickStream = 301, kLedGainStream = 302,
                        kCameraStream = 303;

constexpr std::string_view kGainKey = "sensor.led.gains[", kCameraKey = "sensor.camera.position_mm[";

/// The uniform range [lo, hi].
Factor range(double lo, double hi) {
    Factor f;
    f.is_range = true;
    f.min = lo;
    f.max = hi;
    return f;
}

SensorVariant draw_variant(const Spec& spec, int id) {
    SensorVariant v;
    v.id = id;
    Stream stream(trial_seed(spec.seed, kSensorStream, std::uint64_t(id)));
    Stream gains(trial_seed(spec.seed, kLedGainStream, std::uint64_t(id)));
    Stream camera(trial_seed(spec.seed, kCameraStream, std::uint64_t(id)));
    for (const auto& [key, factor] : sensor_draws(spec)) {
        Stream& from = key.starts_with(kGainKey)     ? gains
                       : key.starts_with(kCameraKey) ? camera
                                                     : stream;
        v.values.emplace_back(key, draw(factor, from.uniform()));
    }
    return v;
}

} // namespace

std::vector<std::pair<std::string, Factor>> sensor_draws(const Spec& spec) {
    std::vector<std::pair<std::string, Factor>> out(spec.varied.begin(), spec.varied.end());
    const double t = spec.sensor.led_gain_tolerance;
    if (t > 0) {
        const std::vector<double> gains = led_gains(spec);
        for (std::size_t k = 0; k < gains.size(); ++k)
            out.emplace_back(std::string(kGainKey) + std::to_string(k) + "]",
                             range(gains[k] * (1.0 - t), gains[k] * (1.0 + t)));
    }
    const double d = spec.sensor.camera_position_tolerance_mm;
    if (d > 0)
        for (std::size_t i = 0; i < 3; ++i) {
            const double p = spec.sensor.camera_position_mm[i];
            out.emplace_back(std::string(kCameraKey) + std::to_string(i) + "]",
                             range(p - d, p + d));
        }
    return out;
}

std::string what_varies(const Spec& spec) {
    if (spec.varied.empty())
        return spec.sensor.led_gain_tolerance > 0             ? "sensor.led.gain_tolerance"
               : spec.sensor.camera_position_tolerance_mm > 0 ? "sensor.camera.position_tolerance_mm"
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
    out.sensor.camera_position_tolerance_mm = 0;
    for (const auto& [key, value] : variant.values) {
        if (key.starts_with(kGainKey))
            out.sensor.led_gains.at(std::stoul(key.substr(kGainKey.size()))) = value;
        else if (key.starts_with(kCameraKey))
            out.sensor.camera_position_mm.at(std::stoul(key.substr(kCameraKey.size()))) = value;
        else
            set_varied_value(out, key, value);
    }
    out.sensor.variant = variant.id;
    out.resolved_yaml = resolved_spec_yaml(out);
    return out;
}

} // namespace chromasim::generators
