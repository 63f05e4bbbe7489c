#pragma once
/// Spectra for the spectral renderer: values on one fixed wavelength grid, read from CSV files
/// (assets/spectra/README.md), hero-wavelength sampling (Wilkie et al. 2014, "Hero Wavelength
/// Spectral Sampling", EGSR), and the reduction of spectral radiance to white-balanced
/// camera RGB, exact (quadrature) or as the Monte Carlo estimator of a hero sample.
///
/// Why spectral: colour mixing in the sensor is a product per wavelength (SENSOR.md, "How the
/// colour mixing works"); a product of per-channel RGB transmittances is only an
/// approximation. `rgb_of_filter_pair` measures how far off it is.
///
/// Units: wavelength in nm; absorption coefficients in 1/mm; path lengths in mm; emission and
/// camera sensitivity are relative (only ratios matter, the white balance removes the scale).
#include <Eigen/Core>

#include <array>
#include <cmath>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace chromasim::render {

/// The wavelength grid, 380 to 730 nm every 1 nm (351 values).
/// Range: the IR-cut camera responds to nothing above about 700 nm and the white LED emits
/// nothing below about 410 nm, so both ends carry (almost) no signal and clamping outside the
/// range loses nothing. Step: 1 nm represents every file tabulated at whole nanometres
/// (5 nm CIE-style tables, 1 nm spectrometer exports) exactly as the piecewise-linear curve
/// through its rows, so resampling changes no data; a lookup costs the same at any step and
/// a spectrum takes 2.8 KB. Trapezoid quadrature on this grid differs from the exact integral
/// of products of the piecewise-linear curves by less than 5e-4 relative for the shipped
/// spectra (tests/render/test_spectrum.cpp), an eighth of one 8-bit grey level.
inline constexpr double kLambdaMin_nm = 380.0;
inline constexpr double kLambdaMax_nm = 730.0;
inline constexpr double kLambdaStep_nm = 1.0;
inline constexpr double kLambdaRange_nm = kLambdaMax_nm - kLambdaMin_nm;
inline constexpr int kSpectrumSamples = 351; ///< (max - min) / step + 1

/// A spectral quantity on the grid: values[k] at kLambdaMin_nm + k * kLambdaStep_nm.
struct Spectrum {
    std::array<double, kSpectrumSamples> values{};

    /// Wavelength of grid point k, nm.
    static constexpr double wavelength_nm(int k) { return kLambdaMin_nm + k * kLambdaStep_nm; }
    /// The same value at every wavelength (a grey albedo, a neutral filter).
    static Spectrum constant(double value);

    /// Linear interpolation between grid points; clamped to the end values outside
    /// [kLambdaMin_nm, kLambdaMax_nm] (and for NaN, which maps to the first value).
    double at(double lambda_nm) const;
    /// `at` for the 4 wavelengths of a hero sample.
    Eigen::Array4d at(const Eigen::Array4d& lambda_nm) const;
    /// `at` for any fixed number of wavelengths.
    template <int N>
    Eigen::Array<double, N, 1> at_each(const Eigen::Array<double, N, 1>& lambda_nm) const {
        Eigen::Array<double, N, 1> out;
        for (int j = 0; j < N; ++j)
            out[j] = at(lambda_nm[j]);
        return out;
    }
};

/// Product per wavelength (filters in series, emission times reflectance).
Spectrum operator*(const Spectrum& a, const Spectrum& b);
/// Trapezoid rule over the grid: integral of the value over 380..730 nm, value x nm.
double integrate(const Spectrum& s);
/// Beer-Lambert transmittance exp(-absorption_per_mm * path_mm) per wavelength.
/// Pre-condition: path_mm >= 0.
Spectrum transmittance(const Spectrum& absorption_per_mm, double path_mm);

// ---- Spectrum files -------------------------------------------------------------------------

/// What a spectrum file holds. It fixes the columns after `wavelength_nm` and the values
/// allowed:
///   relative_emission:  header `wavelength_nm,relative_emission`, values >= 0
///   camera_rgb:         header `wavelength_nm,r,g,b`, values >= 0 (relative sensitivity)
///   absorption_per_mm:  header `wavelength_nm,absorption_per_mm`, values >= 0 (1/mm)
///   albedo:             header `wavelength_nm,albedo`, values in [0, 1]
/// The column names carry the quantity so that an albedo file given where an absorption
/// spectrum belongs is rejected rather than misread.
enum class SpectrumQuantity { relative_emission, camera_rgb, absorption_per_mm, albedo };

/// A spectrum file that cannot be used. what() is "FILE:LINE: problem; what is allowed".
class SpectrumError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

/// Parses the text of a spectrum CSV (format in assets/spectra/README.md): one header line,
/// then rows `wavelength_nm,value[,value...]` with strictly increasing wavelengths that cover
/// 380..730 nm; blank lines, lines starting with '#', a UTF-8 byte-order mark and CRLF line
/// ends are accepted. Rows may be at any spacing; each grid point takes the linear
/// interpolation of the two rows around it. `source_name` names the file in messages.
/// Returns one Spectrum per value column, in header order (3 for camera_rgb, else 1).
/// Throws SpectrumError naming source_name:line.
std::vector<Spectrum> parse_spectrum_csv(std::string_view text, const std::string& source_name,
                                         SpectrumQuantity quantity);
/// Reads `file` and parses it as above. Throws SpectrumError if it cannot be read.
std::vector<Spectrum> read_spectrum_csv(const std::filesystem::path& file,
                                        SpectrumQuantity quantity);

// ---- Camera response ------------------------------------------------------------------------

/// Camera r, g, b sensitivities with the LED emission that sets their white balance:
///   rgb_c = integral(s_c * L) / integral(s_c * E)   (over 380..730 nm)
/// for a spectral radiance L, with s_c the sensitivity of channel c and E the LED emission.
/// So the LED seen on a perfect white diffuser (L = E, albedo 1, unit geometry) is exactly
/// (1, 1, 1), as the RGB renderer's `led_rgb` (1, 1, 1) on albedo 1; the scale of E and s_c
/// drops out. Both integrals are the trapezoid rule on the grid.
class CameraResponse {
public:
    /// Throws SpectrumError if a channel sees none of the LED's light (a zero integral), which
    /// would make its white balance infinite.
    CameraResponse(const std::array<Spectrum, 3>& sensitivity, const Spectrum& led_emission);

    /// r, g, b sensitivities (relative).
    const std::array<Spectrum, 3>& sensitivity() const { return m_sensitivity; }
    /// Relative spectral emission of every LED.
    const Spectrum& led_emission() const { return m_led_emission; }
    /// integral(s_c * E) per channel, relative units x nm: the white-balance divisors.
    const Eigen::Array3d& white_integral() const { return m_white_integral; }
    /// Camera RGB (white balanced) of any spectral radiance L given on the grid, by
    /// quadrature: integral(s_c * L) / integral(s_c * E).
    Eigen::Array3d rgb_of_radiance(const Spectrum& radiance) const;

private:
    std::array<Spectrum, 3> m_sensitivity;
    Spectrum m_led_emission;
    Eigen::Array3d m_white_integral;
};

// ---- Hero-wavelength sampling ---------------------------------------------------------------

/// Per-wavelength values of one hero sample (radiance, throughput, transmittance).
using SpectralValues = Eigen::Array4d;

/// Four wavelengths that travel along one path: a hero wavelength lambda_0 uniform over the
/// range and three more rotated by a quarter of the range each (Wilkie et al. 2014), so they
/// stratify the range. Every one is marginally uniform: pdf 1/350 per nm.
/// The chromasim optics are not dispersive (one refractive index for all wavelengths), so all
/// four follow the same path and carry their own throughput in a SpectralValues. A renderer
/// that adds dispersion must terminate the secondary wavelengths at the dispersive event.
struct SpectralSample {
    Eigen::Array4d lambda_nm;
    /// Probability density of each wavelength, 1/nm.
    static constexpr double pdf_per_nm = 1.0 / kLambdaRange_nm;
};

/// Maps one uniform number u in [0, 1) to the sample
///   lambda_j = kLambdaMin_nm + frac(u + j / 4) * kLambdaRange_nm,   j = 0..3,
/// so lambda_0 = 380 + 350 u and every lambda lies in [380, 730]. u = 1 wraps to u = 0.
SpectralSample sample_hero_wavelengths(double u);

/// Monte Carlo estimate of the white-balanced camera RGB of spectral radiance `radiance`
/// (L(lambda_j) for the wavelengths of `sample`):
///   rgb_c = (1/4) sum_j s_c(lambda_j) L(lambda_j) / pdf  /  integral(s_c * E).
/// Its expectation over u is the quadrature value `rgb_of_radiance` (up to the trapezoid
/// rule's error on the grid), e.g. (1, 1, 1) for L = E.
Eigen::Array3d camera_rgb(const CameraResponse& camera, const SpectralSample& sample,
                          const SpectralValues& radiance);

/// Four hero wavelengths drawn with a non-uniform density, and that density (1/nm) at each.
struct WeightedSpectralSample {
    Eigen::Array4d lambda_nm;
    Eigen::Array4d pdf_per_nm;
};

/// Hero wavelengths in proportion to a weight spectrum, mixed with a uniform share so that
/// every wavelength keeps a density of at least uniform_share / 350 nm (unbiased wherever the
/// weight is small): lambda_j = CDF^-1(frac(u + j / 4)), so the four stratify the CDF and each
/// is marginally distributed with the same density. The density is constant over each 1 nm
/// interval of the grid (the interval's mean weight).
class WavelengthSampler {
public:
    /// Throws std::invalid_argument for a negative or all-zero weight or a share outside
    /// [0, 1] (1: uniform).
    explicit WavelengthSampler(const Spectrum& weight, double uniform_share = 0.1);
    WeightedSpectralSample sample(double u) const;
    /// N wavelengths lambda_j = CDF^-1(frac(u + j / N)) and their densities.
    template <int N>
    void sample(double u, Eigen::Array<double, N, 1>& lambda_nm,
                Eigen::Array<double, N, 1>& pdf_per_nm) const {
        for (int j = 0; j < N; ++j) {
            double x = u + double(j) / N;
            x -= std::floor(x);
            invert(x, lambda_nm[j], pdf_per_nm[j]);
        }
    }
    /// Density (1/nm) at lambda_nm (0 outside the grid).
    double pdf(double lambda_nm) const;

private:
    void invert(double x, double& lambda_nm, double& pdf_per_nm) const;
    std::array<double, kSpectrumSamples> m_cdf{};     ///< at the grid points, 0 .. 1
    std::array<double, kSpectrumSamples - 1> m_pdf{}; ///< per 1 nm interval, 1/nm
};

/// The weight for camera images of LED light: sum over channels of s_c E / integral(s_c E),
/// so each white-balanced channel gets the same share of the wavelengths.
Spectrum camera_weight(const CameraResponse& camera);

/// camera_rgb for a weighted sample: (1/4) sum_j s_c(lambda_j) L(lambda_j) / pdf_j, white
/// balanced.
Eigen::Array3d camera_rgb(const CameraResponse& camera, const WeightedSpectralSample& sample,
                          const SpectralValues& radiance);
/// The same for N wavelengths: (1/N) sum_j s_c(lambda_j) L_j / pdf_j, white balanced.
template <int N>
Eigen::Array3d camera_rgb(const CameraResponse& camera, const Eigen::Array<double, N, 1>& lambda_nm,
                          const Eigen::Array<double, N, 1>& pdf_per_nm,
                          const Eigen::Array<double, N, 1>& radiance) {
    const Eigen::Array<double, N, 1> weighted = radiance / pdf_per_nm;
    Eigen::Array3d sum;
    for (int c = 0; c < 3; ++c)
        sum[c] = (camera.sensitivity()[std::size_t(c)].at_each(lambda_nm) * weighted).sum();
    return sum / double(N) / camera.white_integral();
}

/// The per-lane weights that turn the radiance at N wavelengths (drawn with densities
/// pdf_per_nm) into white-balanced camera RGB, self-normalised: row c is
///   w_cj = (s_c(lambda_j) / pdf_j) / sum_k s_c(lambda_k) E(lambda_k) / pdf_k,
/// so that for this very set the LED's own light (L = E: a perfect white) gives exactly 1 in
/// every channel. The plain weights, s_c / (N pdf_j integral(s_c E)), give 1 only on average
/// over sets: with the shipped spectra and 16 wavelengths a set's white is 1 +- 3.9 %, 0.5 %,
/// 4.5 % (R, G, B), noise in every pixel. Self-normalised, a grey is exact with any
/// set, and a coloured spectrum's error is what its colour adds. Its expectation over sets is
/// a ratio's, not the integral: over the renderer's 1024-set table, the shipped marker filters
/// come out within 7.6e-4 of white of the grid's trapezoid integral, where the plain
/// weights' table is off by 8.5e-4 to 1.0e-3, in blue (the quadrature errors of the table and
/// the trapezoid rule at the LED's narrow peak; the normalisation is exact on the white
/// whatever the rule) (tests/render/test_spectrum.cpp). A channel
/// the set does not see at all (the sum zero) gets zero weights.
template <int N>
Eigen::Matrix<double, 3, N> camera_rgb_weights(const CameraResponse& camera,
                                               const Eigen::Array<double, N, 1>& lambda_nm,
                                               const Eigen::Array<double, N, 1>& pdf_per_nm) {
    const Eigen::Array<double, N, 1> emission = camera.led_emission().at_each(lambda_nm);
    Eigen::Matrix<double, 3, N> weights;
    for (int c = 0; c < 3; ++c) {
        const Eigen::Array<double, N, 1> w =
            camera.sensitivity()[std::size_t(c)].at_each(lambda_nm) / pdf_per_nm;
        const double white = (w * emission).sum();
        weights.row(c) = (w * (white > 0.0 ? 1.0 / white : 0.0)).matrix().transpose();
    }
    return weights;
}

// ---- RGB reductions for the RGB mode and for validation --------------------------------------

/// Camera RGB of the LED light diffusely reflected by `albedo` (unit geometry), white
/// balanced: the RGB-mode albedo equivalent of an albedo spectrum. 1 for albedo 1.
Eigen::Array3d rgb_of_reflectance(const CameraResponse& camera, const Spectrum& albedo);
/// Camera RGB of the LED light after a Beer-Lambert filter of `path_mm` (then a perfect white
/// diffuser): the RGB-mode transmittance equivalent. Pre-condition: path_mm >= 0.
Eigen::Array3d rgb_of_transmittance(const CameraResponse& camera, const Spectrum& absorption_per_mm,
                                    double path_mm);
/// The RGB-mode absorption coefficients (1/mm) that give `rgb_of_transmittance` at this path:
/// -ln(T_c) / path_mm. They depend on the path (a spectral filter does not obey
/// Beer-Lambert per RGB channel), so quote the path with them. Pre-condition: path_mm > 0.
Eigen::Array3d rgb_absorption_per_mm(const CameraResponse& camera,
                                     const Spectrum& absorption_per_mm, double path_mm);

/// Two filters in series seen as camera RGB (LED light through both, then a perfect white
/// diffuser): `spectral` is the exact product per wavelength, integral(s_c E T_a T_b) /
/// integral(s_c E); `rgb_product` is the RGB approximation T_a,c * T_b,c of the two
/// filters' own camera RGB transmittances.
struct FilterPairRgb {
    Eigen::Array3d spectral;
    Eigen::Array3d rgb_product;
};
FilterPairRgb rgb_of_filter_pair(const CameraResponse& camera, const Spectrum& a_per_mm,
                                 double a_path_mm, const Spectrum& b_per_mm, double b_path_mm);

// ---- The sensor's spectra -------------------------------------------------------------------

/// The six spectrum files of one sensor (defaults: assets/spectra/).
struct SensorSpectraFiles {
    std::filesystem::path led;                     ///< relative_emission
    std::filesystem::path camera;                  ///< camera_rgb
    std::filesystem::path inner_marker_absorption; ///< absorption_per_mm, magenta filter
    std::filesystem::path outer_marker_absorption; ///< absorption_per_mm, cyan dye
    std::filesystem::path outer_marker_albedo;     ///< albedo, cyan dye
    std::filesystem::path coating_albedo;          ///< albedo, white coating

    /// The default file names (led_white.csv, camera_rgb.csv, inner_marker_magenta.csv,
    /// outer_marker_cyan.csv, outer_marker_cyan_albedo.csv, coating_white.csv) in `directory`.
    static SensorSpectraFiles in_directory(const std::filesystem::path& directory);
};

/// Every spectrum the renderer needs, read and checked.
struct SensorSpectra {
    CameraResponse camera;
    Spectrum inner_marker_absorption_per_mm;
    Spectrum outer_marker_absorption_per_mm;
    Spectrum outer_marker_albedo;
    Spectrum coating_albedo;
};

/// Reads the six files. Throws SpectrumError naming the first bad file and line.
SensorSpectra load_sensor_spectra(const SensorSpectraFiles& files);

} // namespace chromasim::render
