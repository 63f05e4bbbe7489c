#include "render/sensor_model.hpp"

#include "render/sampling.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace chromasim::render {

namespace {

/// Shortest text that reads back to `x` ("-5", "1e+07"), as the spec schema prints ranges.
std::string text(double x) {
    char buf[64];
    const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, x);
    (void)ec; // 64 chars always suffice for a double
    return std::string(buf, end);
}

/// Throws unless lo (<) x <= hi; `lo_open` makes the lower end exclusive.
void check_range(const char* name, double x, double lo, double hi, bool lo_open, const char* unit) {
    const bool ok = std::isfinite(x) && (lo_open ? x > lo : x >= lo) && x <= hi;
    if (!ok)
        throw std::invalid_argument(std::string("SensorParams: ") + name + " = " + text(x) +
                                    " is out of range; allowed: " + (lo_open ? "(" : "[") +
                                    text(lo) + ", " + text(hi) + "]" + unit);
}

void validate(const SensorParams& p) {
    check_range("gain", p.gain, 0.0, kSensorMaxGain, true, "");
    check_range("full_well_e", p.full_well_e, 0.0, kSensorMaxFullWellE, true, " (electrons)");
    check_range("read_noise_e", p.read_noise_e, 0.0, kSensorMaxReadNoiseE, false, " (electrons)");
    if (p.adc_bits < kSensorMinAdcBits || p.adc_bits > kSensorMaxAdcBits)
        throw std::invalid_argument("SensorParams: adc_bits = " + std::to_string(p.adc_bits) +
                                    " is out of range; allowed: integer in [" +
                                    std::to_string(kSensorMinAdcBits) + ", " +
                                    std::to_string(kSensorMaxAdcBits) + "]");
    check_range("vignetting_k1", p.vignetting_k1, -kSensorMaxVignettingCoeff,
                kSensorMaxVignettingCoeff, false, "");
    check_range("vignetting_k2", p.vignetting_k2, -kSensorMaxVignettingCoeff,
                kSensorMaxVignettingCoeff, false, "");
}

/// Standard normals from a pixel's stream, two per Box-Muller draw (its cos and sin halves);
/// 1 - u keeps the log finite.
class NormalStream {
public:
    explicit NormalStream(detail::PixelRng& rng) : m_rng(rng) {}
    double next() {
        if (m_has_spare) {
            m_has_spare = false;
            return m_spare;
        }
        const double r = std::sqrt(-2.0 * std::log(1.0 - m_rng.uniform()));
        const double phi = 2.0 * std::numbers::pi * m_rng.uniform();
        m_spare = r * std::sin(phi);
        m_has_spare = true;
        return r * std::cos(phi);
    }

private:
    detail::PixelRng& m_rng;
    double m_spare = 0.0;
    bool m_has_spare = false;
};

/// Photo-electrons of mean `lambda` >= 0: Poisson by inversion below the threshold, else the
/// normal approximation clamped at 0 (sensor_model.hpp).
double shot_electrons(double lambda, detail::PixelRng& rng, NormalStream& normal) {
    if (lambda <= 0.0) return 0.0;
    if (lambda >= kPoissonNormalThreshold)
        return std::max(0.0, lambda + std::sqrt(lambda) * normal.next());
    const double u = rng.uniform();
    double p = std::exp(-lambda), cdf = p;
    int k = 0;
    // The tail beyond k = 1000 is below 1e-300 for lambda < 64: the bound only guards rounding.
    while (u >= cdf && k < 1000) {
        ++k;
        p *= lambda / k;
        cdf += p;
    }
    return double(k);
}

} // namespace

double relative_illumination(const SensorParams& params, double theta_rad, double half_fov_rad) {
    switch (params.vignetting) {
    case Vignetting::none:
        return 1.0;
    case Vignetting::cos4: {
        const double c = std::max(0.0, std::cos(theta_rad));
        return (c * c) * (c * c);
    }
    case Vignetting::polynomial: {
        const double t2 = (theta_rad / half_fov_rad) * (theta_rad / half_fov_rad);
        return std::max(0.0, 1.0 + t2 * (params.vignetting_k1 + t2 * params.vignetting_k2));
    }
    }
    return 1.0;
}

SensorModel::SensorModel(const CameraParams& camera_params, const SensorParams& params)
    : m_params(params), m_width(camera_params.width_px), m_height(camera_params.height_px) {
    validate(params);
    const FisheyeCamera camera(camera_params);
    const Vec3 axis = camera.rotation().col(2);
    m_relative_illumination.resize(std::size_t(m_width) * std::size_t(m_height));
    const double half_fov = camera.half_fov_rad();
    for (int y = 0; y < m_height; ++y)
        for (int x = 0; x < m_width; ++x) {
            const auto d = camera.direction({x + 0.5, y + 0.5});
            // A centre outside the field: the edge's value (see sensor_model.hpp).
            const double theta = d ? std::acos(std::clamp(d->dot(axis), -1.0, 1.0)) : half_fov;
            m_relative_illumination[std::size_t(y) * std::size_t(m_width) + std::size_t(x)] =
                float(render::relative_illumination(params, theta, half_fov));
        }
}

Image SensorModel::capture(const Image& linear, std::uint64_t frame_index) const {
    if (linear.width != m_width || linear.height != m_height ||
        linear.rgb.size() != 3 * std::size_t(m_width) * std::size_t(m_height))
        throw std::invalid_argument("SensorModel::capture: image of " +
                                    std::to_string(linear.width) + " x " +
                                    std::to_string(linear.height) + " px; allowed: the camera's " +
                                    std::to_string(m_width) + " x " + std::to_string(m_height));
    Image out;
    out.width = m_width;
    out.height = m_height;
    out.rgb.resize(linear.rgb.size());
    const SensorParams& p = m_params;
    const double max_code = std::ldexp(1.0, p.adc_bits) - 1.0;
    const double codes_per_electron = max_code / p.full_well_e;
    // One stream per (seed, frame): frames of one seed differ, and each pixel's stream below
    // depends only on it and the pixel index.
    const std::uint64_t frame_seed =
        detail::mix64(p.seed ^ detail::mix64(frame_index + 0xD1B54A32D192ED03ull));
    tbb::parallel_for(tbb::blocked_range<int>(0, m_height), [&](const auto& rows) {
        for (int y = rows.begin(); y < rows.end(); ++y)
            for (int x = 0; x < m_width; ++x) {
                const std::size_t pixel = std::size_t(y) * std::size_t(m_width) + std::size_t(x);
                detail::PixelRng rng(frame_seed, pixel);
                NormalStream normal(rng);
                const double scale = p.gain * m_relative_illumination[pixel] * p.full_well_e;
                for (std::size_t c = 0; c < 3; ++c) {
                    const double v = linear.rgb[3 * pixel + c];
                    // NaN -> 0; infinity -> a finite mean that saturates the pixel.
                    const double lambda = v > 0.0 ? std::min(v * scale, 1e300) : 0.0;
                    double e = p.shot_noise ? shot_electrons(lambda, rng, normal) : lambda;
                    e = std::min(e, p.full_well_e);
                    if (p.read_noise_e > 0.0) e += p.read_noise_e * normal.next();
                    const double code =
                        std::clamp(std::round(e * codes_per_electron), 0.0, max_code);
                    out.rgb[3 * pixel + c] = float(code / max_code);
                }
            }
    });
    return out;
}

} // namespace chromasim::render
