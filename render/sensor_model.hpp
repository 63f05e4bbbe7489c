#pragma once
/// The camera sensor: turns the renderer's noise-free linear RGB (relative radiance, the
/// exposure reference at about 0.8) into what a camera records, linear values on the ADC's code
/// grid in [0, 1]. Optional (render.sensor.enabled); the sRGB encoding of the PNG stays in the
/// PNG writer (generators/io/image_io.cpp), the one place of the sRGB curve.
///
/// Per pixel and channel, in this order:
///   1. exposure: s = gain * value (a longer exposure or brighter LEDs: more photo-electrons);
///   2. vignetting: s *= RI(theta), the relative illumination at the field angle theta of the
///      pixel centre (the angle between its ray and the optical axis, from FisheyeCamera):
///        none:       RI = 1,
///        cos4:       RI = cos^4 theta (natural vignetting of a rectilinear lens; far too
///                    strong for a fisheye near 90 deg, kept as the textbook reference),
///        polynomial: RI = max(0, 1 + k1 t^2 + k2 t^4), t = theta / half_fov (for the
///                    equidistant lens t is the image radius over the image circle's radius);
///      a pixel whose centre lies outside the field takes the RI of the field's edge (the
///      renderer already leaves what lies outside black; a pixel across the edge keeps the
///      light of its part inside);
///   3. shot noise: mean photo-electrons lambda = max(s, 0) * full_well_e (s = 1 fills the
///      well), drawn Poisson(lambda): by inversion (sequential search, integer electrons) for
///      lambda < kPoissonNormalThreshold, by the normal approximation N(lambda, lambda)
///      (continuous electrons, clamped at 0) above it; exactly lambda when shot noise is off;
///   4. the pixel saturates at full_well_e electrons;
///   5. read noise: + N(0, read_noise_e^2) electrons;
///   6. ADC: code = round(e / full_well_e * (2^adc_bits - 1)) clamped to [0, 2^adc_bits - 1]
///      (full well = the largest code, no black-level offset), output = code /
///      (2^adc_bits - 1).
/// In electrons the output's variance for a flat input is lambda + read_noise_e^2 + LSB^2 / 12
/// (LSB = full_well_e / (2^adc_bits - 1) electrons) as long as neither clip is reached.
///
/// Randomness: each pixel draws from its own SplitMix64 stream (render/sampling.hpp) seeded by
/// (seed, frame index, pixel index); its channels draw in order R, G, B. The output depends on
/// neither the thread count nor the order of work, and frames of one seed differ.
#include "render/fisheye_camera.hpp"
#include "render/scene_data.hpp"

#include <cstdint>
#include <vector>

namespace chromasim::render {

enum class Vignetting {
    none,       ///< RI = 1
    cos4,       ///< RI = cos^4 theta
    polynomial, ///< RI = max(0, 1 + k1 t^2 + k2 t^4), t = theta / half_fov
};

/// Sensor parameters. Defaults: typical values for the ChromaTouch camera's sensor class (Basler
/// dart daA1920-160uc, Sony IMX392; SENSOR.md 1), [G], to be replaced by a user's measurements
/// (photon transfer curve, flat field).
struct SensorParams {
    double gain = 1.0;          ///< exposure multiplier on the linear input, > 0
    double full_well_e = 1.0e4; ///< electrons at input 1.0 (and the saturation level), > 0
    double read_noise_e = 2.3;  ///< standard deviation of the read noise, electrons, >= 0
    int adc_bits = 12;          ///< ADC bit depth
    bool shot_noise = true;     ///< Poisson photon noise; false: exactly the mean electrons
    Vignetting vignetting = Vignetting::polynomial;
    double vignetting_k1 = -0.3; ///< polynomial only: RI = 0.7 at the field's edge (assumed)
    double vignetting_k2 = 0.0;  ///< polynomial only
    std::uint64_t seed = 1;      ///< the sensor's own seed (independent of the renderer's)
};

/// Allowed values, checked by SensorModel and by the spec schema (render.sensor.*).
inline constexpr double kSensorMaxGain = 100.0;         ///< gain in (0, 100]
inline constexpr double kSensorMaxFullWellE = 1.0e7;    ///< full_well_e in (0, 1e7]
inline constexpr double kSensorMaxReadNoiseE = 1.0e4;   ///< read_noise_e in [0, 1e4]
inline constexpr int kSensorMinAdcBits = 1;             ///< adc_bits in [1, 16]
inline constexpr int kSensorMaxAdcBits = 16;            ///<
inline constexpr double kSensorMaxVignettingCoeff = 10; ///< k1, k2 in [-10, 10]
/// Mean electron count from which shot noise is drawn from the normal approximation (skewness
/// 1 / sqrt(lambda) <= 0.125 there) instead of by Poisson inversion.
inline constexpr double kPoissonNormalThreshold = 64.0;

/// Relative illumination at field angle `theta_rad` of a camera whose field ends at
/// `half_fov_rad` (the formulas at the top of this file).
double relative_illumination(const SensorParams& params, double theta_rad, double half_fov_rad);

/// A sensor behind one camera: the parameters, checked, and the relative illumination of every
/// pixel, computed once (it does not change between frames).
class SensorModel {
public:
    /// Throws std::invalid_argument naming the parameter, its value and the allowed range on
    /// gain outside (0, 100], full_well_e outside (0, 1e7], read_noise_e outside [0, 1e4],
    /// adc_bits outside [1, 16], vignetting_k1/k2 outside [-10, 10] (or not finite); and as
    /// FisheyeCamera does on bad camera parameters.
    SensorModel(const CameraParams& camera, const SensorParams& params);

    /// What the sensor records of `linear` (the renderer's image, the camera's size) in frame
    /// `frame_index`: RGB on the ADC's code grid in [0, 1], linear; no extra channels.
    /// Throws std::invalid_argument if the image's size is not the camera's.
    Image capture(const Image& linear, std::uint64_t frame_index) const;

    /// Relative illumination of pixel (x, y) (its centre's field angle).
    float relative_illumination(int x, int y) const {
        return m_relative_illumination[std::size_t(y) * std::size_t(m_width) + std::size_t(x)];
    }
    const SensorParams& params() const { return m_params; }

private:
    SensorParams m_params;
    int m_width, m_height;
    std::vector<float> m_relative_illumination; ///< per pixel, row-major
};

} // namespace chromasim::render
