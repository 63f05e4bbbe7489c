// Tests of the camera sensor model (render/sensor_model.hpp) against analytic answers: the
// noise-free chain (gain, clip, quantization), the statistics of shot, read and quantization
// noise on flat images, the vignetting models at known field angles, determinism, and the
// checks on bad parameters.
#include "render/sensor_model.hpp"

#include <catch2/catch.hpp>
#include <tbb/global_control.h>

#include <cmath>
#include <numbers>
#include <stdexcept>
#include <vector>

using namespace chromasim::render;
using Catch::Matchers::Contains;

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

/// The default equidistant camera (84 deg half field) of size n x n.
CameraParams square_camera(int n) {
    CameraParams c;
    c.width_px = c.height_px = n;
    return c;
}

Image flat_image(int w, int h, float value) {
    Image img;
    img.width = w;
    img.height = h;
    img.rgb.assign(3 * std::size_t(w) * std::size_t(h), value);
    return img;
}

/// A sensor without noise or vignetting.
SensorParams noiseless() {
    SensorParams p;
    p.shot_noise = false;
    p.read_noise_e = 0.0;
    p.vignetting = Vignetting::none;
    return p;
}

/// Sample mean and variance, in electrons, of every channel of every pixel.
struct Moments {
    double mean = 0, variance = 0;
    std::size_t n = 0;
};
Moments electron_moments(const SensorModel& sensor, const Image& out) {
    const double scale = sensor.params().full_well_e; // output 1.0 = code 2^bits - 1 = full well
    std::vector<double> e;
    for (float v : out.rgb)
        e.push_back(scale * v);
    Moments m;
    m.n = e.size();
    for (double v : e)
        m.mean += v;
    m.mean /= double(m.n);
    for (double v : e)
        m.variance += (v - m.mean) * (v - m.mean);
    m.variance /= double(m.n - 1);
    return m;
}

/// Checks the sample moments of a flat input of `lambda` mean electrons against
/// mean = lambda, variance = `expected_variance`, each within 5 standard errors: sqrt(var / n)
/// for the mean, var sqrt(2 / n) for the variance (near-Gaussian samples).
void check_moments(const SensorParams& p, double lambda, double expected_variance) {
    const int n = 256;
    const SensorModel sensor(square_camera(n), p);
    const Image out = sensor.capture(flat_image(n, n, float(lambda / p.full_well_e)), 0);
    const Moments m = electron_moments(sensor, out);
    REQUIRE(m.n == std::size_t(3 * n * n));
    INFO("lambda " << lambda << " e-, mean " << m.mean << ", variance " << m.variance
                   << ", expected " << expected_variance << ", n " << m.n);
    CHECK(std::abs(m.mean - lambda) < 5.0 * std::sqrt(expected_variance / double(m.n)));
    CHECK(std::abs(m.variance - expected_variance) <
          5.0 * expected_variance * std::sqrt(2.0 / double(m.n)));
}

} // namespace

TEST_CASE("without noise the sensor records gain times the input, clipped and quantized",
          "[render][sensor]") {
    SensorParams p = noiseless();
    p.gain = 1.7;
    const int n = 64;
    const SensorModel sensor(square_camera(n), p);
    // A ramp from below 0 to beyond saturation, different per channel.
    Image in = flat_image(n, n, 0.0f);
    for (std::size_t i = 0; i < in.rgb.size(); ++i)
        in.rgb[i] = float(-0.1 + 0.8 * double(i) / double(in.rgb.size()));
    const Image out = sensor.capture(in, 0);
    REQUIRE(out.width == n);
    REQUIRE(out.height == n);
    const double max_code = 4095.0;
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x)
            for (int c = 0; c < 3; ++c) {
                const double v = out.pixel(x, y)[c];
                // On the 12-bit code grid.
                CHECK(std::abs(v * max_code - std::round(v * max_code)) < 1e-3);
                const double expected = std::clamp(1.7 * in.pixel(x, y)[c], 0.0, 1.0);
                CHECK(std::abs(v - expected) <= 0.5 / max_code + 1e-7);
            }
}

TEST_CASE("flat images: mean and variance follow the Poisson + Gaussian + quantization model",
          "[render][sensor]") {
    SensorParams p;
    p.vignetting = Vignetting::none;
    SECTION("shot noise dominates: IMX392-class defaults, half full well") {
        // Variance in electrons: lambda + read^2 + LSB^2 / 12, LSB = 1e4 / 4095 e-.
        const double lsb = p.full_well_e / 4095.0;
        check_moments(p, 5000.0, 5000.0 + 2.3 * 2.3 + lsb * lsb / 12.0);
    }
    SECTION("read and quantization noise alone: 1 e- per code, read noise 1 e-") {
        p.shot_noise = false;
        p.full_well_e = 4095.0; // one electron per code of the 12-bit ADC
        p.read_noise_e = 1.0;
        check_moments(p, 2000.3, 1.0 + 1.0 / 12.0); // quantization is 8 % of it
    }
    SECTION("Poisson above the normal threshold: 1 e- per code, no read noise") {
        p.full_well_e = 4095.0;
        p.read_noise_e = 0.0;
        check_moments(p, 100.0, 100.0 + 1.0 / 12.0); // continuous normal draw, then rounded
    }
}

TEST_CASE("small means draw exact Poisson counts (chi-square against the pmf)",
          "[render][sensor]") {
    SensorParams p;
    p.vignetting = Vignetting::none;
    p.full_well_e = 4095.0; // one electron per code: the output is the electron count
    p.read_noise_e = 0.0;
    const double lambda = 3.0;
    const int n = 128;
    const SensorModel sensor(square_camera(n), p);
    const Image out = sensor.capture(flat_image(n, n, float(lambda / p.full_well_e)), 7);
    const int bins = 11; // 0..9 and >= 10
    std::vector<double> observed(bins, 0.0);
    double total = 0;
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            for (int c = 0; c < 3; ++c) {
                const double k = out.pixel(x, y)[c] * 4095.0;
                REQUIRE(std::abs(k - std::round(k)) < 1e-3);
                observed[std::min(bins - 1, int(std::round(k)))] += 1;
                total += 1;
            }
        }
    double chi2 = 0, pmf = std::exp(-lambda), cdf = 0;
    for (int k = 0; k < bins; ++k) {
        const double prob = k < bins - 1 ? pmf : 1.0 - cdf;
        chi2 += (observed[k] - total * prob) * (observed[k] - total * prob) / (total * prob);
        cdf += pmf;
        pmf *= lambda / (k + 1);
    }
    INFO("chi2 " << chi2 << " over " << total << " samples");
    CHECK(chi2 < 29.59); // chi-square, 10 degrees of freedom, p = 0.001
}

TEST_CASE("vignetting follows its model at known field angles", "[render][sensor]") {
    const int n = 200;
    const CameraParams camera = square_camera(n); // equidistant: theta = r / 100 px * 84 deg
    const double half_fov = 84.0 * kDeg;
    SensorParams p = noiseless();
    p.adc_bits = 16;
    const double lsb = 1.0 / 65535.0;
    for (const Vignetting model : {Vignetting::cos4, Vignetting::polynomial}) {
        p.vignetting = model;
        p.vignetting_k1 = -0.3;
        p.vignetting_k2 = -0.1;
        const SensorModel sensor(camera, p);
        const Image out = sensor.capture(flat_image(n, n, 0.5f), 0);
        // Pixels right of the image centre (100, 100): their centres are (k + 0.5, 0.5) px off.
        for (const int k : {0, 35, 71, 95}) {
            const double theta = std::hypot(k + 0.5, 0.5) / 100.0 * half_fov;
            const double t = theta / half_fov;
            const double expected = model == Vignetting::cos4
                                        ? std::pow(std::cos(theta), 4)
                                        : 1.0 - 0.3 * t * t - 0.1 * t * t * t * t;
            INFO("model " << int(model) << ", theta " << theta / kDeg << " deg");
            CHECK(sensor.relative_illumination(100 + k, 100) == Approx(expected).epsilon(1e-6));
            CHECK(std::abs(out.pixel(100 + k, 100)[1] - 0.5 * expected) <= 0.5 * lsb + 1e-7);
        }
        // A corner pixel, outside the field: the edge's value, so that a pixel across the edge
        // keeps the light of its part inside.
        CHECK(sensor.relative_illumination(0, 0) ==
              Approx(relative_illumination(p, half_fov, half_fov)).epsilon(1e-6));
    }
    CHECK(relative_illumination(p, 84.0 * kDeg, half_fov) == Approx(0.6));
    p.vignetting_k1 = -2.0; // would go negative at the edge: clamped
    CHECK(relative_illumination(p, 84.0 * kDeg, half_fov) == 0.0);
    // The field angle is measured from the camera's own axis, whatever its pose.
    CameraParams posed = camera;
    posed.pitch_deg = 20.0;
    p.vignetting = Vignetting::cos4;
    const SensorModel tilted(posed, p);
    const double centre_theta = std::sqrt(0.5) / 100.0 * half_fov; // not 20 deg
    CHECK(tilted.relative_illumination(100, 100) == Approx(std::pow(std::cos(centre_theta), 4)));
}

TEST_CASE("sensor noise is deterministic per seed and frame, whatever the thread count",
          "[render][sensor]") {
    const int n = 48;
    SensorParams p;
    const Image in = flat_image(n, n, 0.3f);
    const std::vector<float> a = SensorModel(square_camera(n), p).capture(in, 3).rgb;
    std::vector<float> one_thread;
    {
        const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
        one_thread = SensorModel(square_camera(n), p).capture(in, 3).rgb;
    }
    CHECK(a == one_thread);
    CHECK(SensorModel(square_camera(n), p).capture(in, 4).rgb != a); // another frame
    p.seed = 2;
    CHECK(SensorModel(square_camera(n), p).capture(in, 3).rgb != a); // another seed
}

TEST_CASE("invalid sensor parameters are rejected with what is allowed", "[render][sensor]") {
    const CameraParams camera = square_camera(16);
    SensorParams p;
    p.full_well_e = -5.0;
    CHECK_THROWS_MATCHES(SensorModel(camera, p), std::invalid_argument,
                         Catch::Matchers::Message("SensorParams: full_well_e = -5 is out of "
                                                  "range; allowed: (0, 1e+07] (electrons)"));
    p = {};
    p.adc_bits = 17;
    CHECK_THROWS_MATCHES(SensorModel(camera, p), std::invalid_argument,
                         Catch::Matchers::Message("SensorParams: adc_bits = 17 is out of range; "
                                                  "allowed: integer in [1, 16]"));
    p = {};
    p.read_noise_e = -1.0;
    CHECK_THROWS_WITH(SensorModel(camera, p), Contains("read_noise_e = -1") && Contains("[0, "));
    p = {};
    p.gain = 0.0;
    CHECK_THROWS_WITH(SensorModel(camera, p), Contains("gain = 0") && Contains("(0, 100]"));
    p = {};
    p.vignetting_k1 = std::nan("");
    CHECK_THROWS_WITH(SensorModel(camera, p), Contains("vignetting_k1 = nan"));
    // An image of another size than the camera's.
    CHECK_THROWS_AS(SensorModel(camera, SensorParams{}).capture(flat_image(8, 8, 0.5f), 0),
                    std::invalid_argument);
}
