// Spectra on the 1 nm grid, their CSV reader, hero-wavelength sampling and camera RGB.
//
// CSV reader: hand-written. Debian 12 packages two C/C++ CSV libraries: libcsv-dev (a C
// tokenizer driven by callbacks) and libfccp-dev (Ben Strasser's fast-cpp-csv-parser, a 2016
// snapshot whose column count is a template parameter). Neither checks what matters here
// (numbers, increasing wavelengths, value ranges, coverage of the grid) or words its errors
// as FILE:LINE plus what is allowed, and the files are two or four numeric columns without
// quoting, so a tokenizer would save about ten lines while adding a dependency and an adapter.
// Numbers are parsed with std::from_chars: locale independent and it rejects trailing junk.
#include "render/spectrum.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>
#include <system_error>

namespace chromasim::render {

// ---- Spectrum -------------------------------------------------------------------------------

Spectrum Spectrum::constant(double value) {
    Spectrum s;
    s.values.fill(value);
    return s;
}

double Spectrum::at(double lambda_nm) const {
    const double x = (lambda_nm - kLambdaMin_nm) / kLambdaStep_nm;
    if (!(x > 0.0)) return values.front(); // below the range, or NaN
    if (x >= kSpectrumSamples - 1) return values.back();
    const int k = int(x);
    const double t = x - k;
    return values[k] + t * (values[k + 1] - values[k]);
}

Eigen::Array4d Spectrum::at(const Eigen::Array4d& lambda_nm) const {
    return {at(lambda_nm[0]), at(lambda_nm[1]), at(lambda_nm[2]), at(lambda_nm[3])};
}

Spectrum operator*(const Spectrum& a, const Spectrum& b) {
    Spectrum s;
    for (int k = 0; k < kSpectrumSamples; ++k)
        s.values[k] = a.values[k] * b.values[k];
    return s;
}

double integrate(const Spectrum& s) {
    double sum = 0.0;
    for (int k = 0; k < kSpectrumSamples; ++k)
        sum += s.values[k];
    return kLambdaStep_nm * (sum - 0.5 * (s.values.front() + s.values.back()));
}

Spectrum transmittance(const Spectrum& absorption_per_mm, double path_mm) {
    Spectrum s;
    for (int k = 0; k < kSpectrumSamples; ++k)
        s.values[k] = std::exp(-absorption_per_mm.values[k] * path_mm);
    return s;
}

// ---- CSV ------------------------------------------------------------------------------------

namespace {

/// Columns and allowed values of one SpectrumQuantity.
struct QuantityRules {
    std::vector<std::string> columns; ///< after wavelength_nm
    double max_value;                 ///< values must lie in [0, max_value]
    const char* what;                 ///< the values' meaning, unit and range, for messages
    const char* hint;                 ///< how to fix a value out of range
};

QuantityRules rules_of(SpectrumQuantity quantity) {
    constexpr double inf = HUGE_VAL;
    switch (quantity) {
    case SpectrumQuantity::relative_emission:
        return {{"relative_emission"},
                inf,
                "relative emission (>= 0, any scale)",
                "clip measurement noise below zero to 0"};
    case SpectrumQuantity::camera_rgb:
        return {{"r", "g", "b"},
                inf,
                "relative r, g, b sensitivities (>= 0, any scale)",
                "clip measurement noise below zero to 0"};
    case SpectrumQuantity::absorption_per_mm:
        return {{"absorption_per_mm"},
                inf,
                "absorption coefficient in 1/mm (>= 0)",
                "0 means clear; a spectrometer's absorbance A over a path d mm gives "
                "ln(10) A / d"};
    case SpectrumQuantity::albedo:
        return {{"albedo"},
                1.0,
                "diffuse albedo in [0, 1]",
                "a measured reflectance factor in percent must be divided by 100"};
    }
    throw std::logic_error("rules_of: unknown SpectrumQuantity");
}

std::string_view trim(std::string_view s) {
    const auto first = s.find_first_not_of(" \t\r");
    if (first == std::string_view::npos) return {};
    const auto last = s.find_last_not_of(" \t\r");
    return s.substr(first, last - first + 1);
}

std::vector<std::string_view> split_fields(std::string_view line) {
    std::vector<std::string_view> fields;
    std::size_t start = 0;
    while (true) {
        const auto comma = line.find(',', start);
        fields.push_back(trim(line.substr(start, comma - start)));
        if (comma == std::string_view::npos) return fields;
        start = comma + 1;
    }
}

std::string join(const std::vector<std::string>& names) {
    std::string out = "wavelength_nm";
    for (const auto& n : names)
        out += "," + n;
    return out;
}

std::string format_number(double v) {
    std::ostringstream text;
    text << v;
    return text.str();
}

/// Error at source:line.
class Reporter {
public:
    explicit Reporter(const std::string& source) : m_source(source) {}
    [[noreturn]] void fail(int line, const std::string& problem) const {
        throw SpectrumError(m_source + ":" + std::to_string(line) + ": " + problem);
    }

private:
    const std::string& m_source;
};

/// The header must be exactly `header`; names what is missing or extra.
void check_header(const std::vector<std::string_view>& names,
                  const std::vector<std::string>& header, const QuantityRules& rules, int line,
                  const Reporter& report) {
    if (std::equal(names.begin(), names.end(), header.begin(), header.end())) return;
    std::string problem;
    for (const auto& h : header) {
        if (std::find(names.begin(), names.end(), h) == names.end())
            problem += "missing column '" + h + "'; ";
    }
    for (const auto& n : names) {
        if (std::find(header.begin(), header.end(), n) == header.end())
            problem += "unexpected column '" + std::string(n) + "'; ";
    }
    if (problem.empty()) problem = "columns in the wrong order; ";
    report.fail(line, problem + "this file must start with the header '" + join(rules.columns) +
                          "' (wavelength in nm, then " + rules.what + ")");
}

/// One data row: its line and its numbers (wavelength first).
struct Row {
    int line;
    std::vector<double> numbers;
};

/// Parses a data line into numbers and checks each against the rules.
Row parse_row(std::string_view text, int line, const std::vector<std::string>& header,
              const QuantityRules& rules, const Reporter& report) {
    const auto fields = split_fields(text);
    if (fields.size() != header.size())
        report.fail(line, std::to_string(fields.size()) + " field(s), the header has " +
                              std::to_string(header.size()) + " (" + join(rules.columns) +
                              "); every row needs a wavelength and " +
                              std::to_string(rules.columns.size()) + " value(s)");
    Row row{line, std::vector<double>(fields.size())};
    for (std::size_t i = 0; i < fields.size(); ++i) {
        const std::string_view f = fields[i];
        double v = 0.0;
        const auto [end, ec] = std::from_chars(f.data(), f.data() + f.size(), v);
        if (f.empty() || ec != std::errc() || end != f.data() + f.size())
            report.fail(line, "column '" + header[i] + "': '" + std::string(f) +
                                  "' is not a number; write a decimal number such as 0.85 "
                                  "or 1.5e-3");
        if (!std::isfinite(v))
            report.fail(line, "column '" + header[i] + "': '" + std::string(f) +
                                  "' is not finite; every value must be a finite number");
        row.numbers[i] = v;
    }
    for (std::size_t i = 1; i < fields.size(); ++i) {
        const double v = row.numbers[i];
        if (v < 0.0 || v > rules.max_value)
            report.fail(line, "column '" + header[i] + "': " + std::string(fields[i]) + " at " +
                                  std::string(fields[0]) +
                                  " nm is outside the allowed range; allowed: " + rules.what +
                                  " (" + rules.hint + ")");
    }
    return row;
}

/// Checks that the rows cover the grid and increase strictly.
void check_wavelengths(const std::vector<Row>& rows, int header_line, const Reporter& report) {
    if (rows.size() < 2)
        report.fail(header_line, "need at least 2 data rows after the header, found " +
                                     std::to_string(rows.size()));
    for (std::size_t i = 1; i < rows.size(); ++i) {
        if (!(rows[i].numbers[0] > rows[i - 1].numbers[0]))
            report.fail(rows[i].line,
                        "wavelength " + format_number(rows[i].numbers[0]) +
                            " nm does not increase (line " + std::to_string(rows[i - 1].line) +
                            " has " + format_number(rows[i - 1].numbers[0]) +
                            " nm); rows must be sorted by strictly increasing wavelength");
    }
    const std::string grid = "the data must cover " + format_number(kLambdaMin_nm) + " to " +
                             format_number(kLambdaMax_nm) +
                             " nm (render/spectrum.hpp); extend the measurement or pad the "
                             "ends with explicit rows";
    if (rows.front().numbers[0] > kLambdaMin_nm)
        report.fail(rows.front().line,
                    "first wavelength " + format_number(rows.front().numbers[0]) + " nm is above " +
                        format_number(kLambdaMin_nm) + " nm; " + grid);
    if (rows.back().numbers[0] < kLambdaMax_nm)
        report.fail(rows.back().line, "last wavelength " + format_number(rows.back().numbers[0]) +
                                          " nm is below " + format_number(kLambdaMax_nm) + " nm; " +
                                          grid);
}

/// Linear interpolation of column `column` of the rows at every grid wavelength.
Spectrum resample(const std::vector<Row>& rows, std::size_t column) {
    Spectrum s;
    std::size_t i = 0; // rows[i] <= lambda < rows[i + 1] (or the last segment)
    for (int k = 0; k < kSpectrumSamples; ++k) {
        const double lambda = Spectrum::wavelength_nm(k);
        while (i + 2 < rows.size() && rows[i + 1].numbers[0] <= lambda)
            ++i;
        const double l0 = rows[i].numbers[0], l1 = rows[i + 1].numbers[0];
        const double v0 = rows[i].numbers[column], v1 = rows[i + 1].numbers[column];
        s.values[k] = v0 + (lambda - l0) / (l1 - l0) * (v1 - v0);
    }
    return s;
}

} // namespace

std::vector<Spectrum> parse_spectrum_csv(std::string_view text, const std::string& source_name,
                                         SpectrumQuantity quantity) {
    const QuantityRules rules = rules_of(quantity);
    const Reporter report(source_name);
    std::vector<std::string> header = {"wavelength_nm"};
    header.insert(header.end(), rules.columns.begin(), rules.columns.end());

    if (text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3); // UTF-8 byte-order mark
    int header_line = 0;
    std::vector<Row> rows;
    int line = 0;
    for (std::size_t start = 0; start <= text.size();) {
        const auto end = std::min(text.find('\n', start), text.size());
        const std::string_view content = trim(text.substr(start, end - start));
        start = end + 1;
        ++line;
        if (content.empty() || content.front() == '#') continue;
        if (header_line == 0) {
            header_line = line;
            check_header(split_fields(content), header, rules, line, report);
            continue;
        }
        rows.push_back(parse_row(content, line, header, rules, report));
    }
    if (header_line == 0)
        report.fail(line, "no header and no data; expected the header '" + join(rules.columns) +
                              "' followed by rows covering 380 to 730 nm of " + rules.what);
    check_wavelengths(rows, header_line, report);

    std::vector<Spectrum> spectra;
    for (std::size_t c = 1; c < header.size(); ++c)
        spectra.push_back(resample(rows, c));
    return spectra;
}

std::vector<Spectrum> read_spectrum_csv(const std::filesystem::path& file,
                                        SpectrumQuantity quantity) {
    std::ifstream in(file, std::ios::binary);
    if (!in)
        throw SpectrumError(file.string() + ": cannot open the spectrum file; check the path "
                                            "(relative paths start at the working directory)");
    std::ostringstream text;
    text << in.rdbuf();
    return parse_spectrum_csv(text.str(), file.string(), quantity);
}

// ---- Camera response ------------------------------------------------------------------------

CameraResponse::CameraResponse(const std::array<Spectrum, 3>& sensitivity,
                               const Spectrum& led_emission)
    : m_sensitivity(sensitivity), m_led_emission(led_emission) {
    constexpr const char* names[3] = {"r", "g", "b"};
    for (int c = 0; c < 3; ++c) {
        m_white_integral[c] = integrate(m_sensitivity[c] * m_led_emission);
        if (!(m_white_integral[c] > 0.0))
            throw SpectrumError(std::string("camera channel ") + names[c] +
                                " sees none of the LED's light (integral of sensitivity x "
                                "emission over 380..730 nm is " +
                                format_number(m_white_integral[c]) +
                                "); every channel must overlap the LED spectrum");
    }
}

Eigen::Array3d CameraResponse::rgb_of_radiance(const Spectrum& radiance) const {
    Eigen::Array3d rgb;
    for (int c = 0; c < 3; ++c)
        rgb[c] = integrate(m_sensitivity[c] * radiance) / m_white_integral[c];
    return rgb;
}

// ---- Hero-wavelength sampling ---------------------------------------------------------------

SpectralSample sample_hero_wavelengths(double u) {
    SpectralSample sample;
    for (int j = 0; j < 4; ++j) {
        double x = u + 0.25 * j;
        x -= std::floor(x); // rotate into [0, 1): the other three are the hero shifted by j/4
        sample.lambda_nm[j] = kLambdaMin_nm + x * kLambdaRange_nm;
    }
    return sample;
}

Eigen::Array3d camera_rgb(const CameraResponse& camera, const SpectralSample& sample,
                          const SpectralValues& radiance) {
    Eigen::Array3d sum = Eigen::Array3d::Zero();
    for (int c = 0; c < 3; ++c)
        sum[c] = (camera.sensitivity()[c].at(sample.lambda_nm) * radiance).sum();
    // (1/4) sum / pdf, then the white balance.
    return sum / (4.0 * SpectralSample::pdf_per_nm) / camera.white_integral();
}

WavelengthSampler::WavelengthSampler(const Spectrum& weight, double uniform_share) {
    if (!(uniform_share >= 0.0 && uniform_share <= 1.0))
        throw std::invalid_argument("WavelengthSampler: uniform_share = " +
                                    std::to_string(uniform_share) + "; allowed: [0, 1]");
    double total = 0.0;
    for (int k = 0; k + 1 < kSpectrumSamples; ++k) {
        const double w = 0.5 * (weight.values[std::size_t(k)] + weight.values[std::size_t(k) + 1]);
        if (!(w >= 0.0) || !std::isfinite(w))
            throw std::invalid_argument("WavelengthSampler: weights must be finite and >= 0");
        m_pdf[std::size_t(k)] = w;
        total += w * kLambdaStep_nm;
    }
    if (!(total > 0.0) && uniform_share < 1.0)
        throw std::invalid_argument("WavelengthSampler: the weight is zero everywhere");
    m_cdf[0] = 0.0;
    for (int k = 0; k + 1 < kSpectrumSamples; ++k) {
        double& p = m_pdf[std::size_t(k)];
        p = (1.0 - uniform_share) * (total > 0.0 ? p / total : 0.0) +
            uniform_share / kLambdaRange_nm;
        m_cdf[std::size_t(k) + 1] = m_cdf[std::size_t(k)] + p * kLambdaStep_nm;
    }
    // Round-off: make the CDF end at exactly 1.
    for (double& c : m_cdf)
        c /= m_cdf.back();
}

void WavelengthSampler::invert(double x, double& lambda_nm, double& pdf_per_nm) const {
    // The interval k with cdf[k] <= x < cdf[k + 1], then linear inside it.
    const auto it = std::upper_bound(m_cdf.begin(), m_cdf.end(), x);
    const std::size_t k = std::min<std::size_t>(
        std::size_t(std::max<std::ptrdiff_t>(it - m_cdf.begin() - 1, 0)), m_pdf.size() - 1);
    const double span = m_cdf[k + 1] - m_cdf[k];
    const double f = span > 0.0 ? std::clamp((x - m_cdf[k]) / span, 0.0, 1.0) : 0.0;
    lambda_nm = Spectrum::wavelength_nm(int(k)) + f * kLambdaStep_nm;
    pdf_per_nm = m_pdf[k];
}

WeightedSpectralSample WavelengthSampler::sample(double u) const {
    WeightedSpectralSample s;
    sample<4>(u, s.lambda_nm, s.pdf_per_nm);
    return s;
}

double WavelengthSampler::pdf(double lambda_nm) const {
    if (!(lambda_nm >= kLambdaMin_nm && lambda_nm <= kLambdaMax_nm)) return 0.0;
    const auto k = std::min<std::size_t>(std::size_t((lambda_nm - kLambdaMin_nm) / kLambdaStep_nm),
                                         m_pdf.size() - 1);
    return m_pdf[k];
}

Spectrum camera_weight(const CameraResponse& camera) {
    Spectrum w;
    for (int c = 0; c < 3; ++c) {
        const Spectrum part = camera.sensitivity()[std::size_t(c)] * camera.led_emission();
        for (int k = 0; k < kSpectrumSamples; ++k)
            w.values[std::size_t(k)] += part.values[std::size_t(k)] / camera.white_integral()[c];
    }
    return w;
}

Eigen::Array3d camera_rgb(const CameraResponse& camera, const WeightedSpectralSample& sample,
                          const SpectralValues& radiance) {
    Eigen::Array3d sum = Eigen::Array3d::Zero();
    const Eigen::Array4d weighted = radiance / sample.pdf_per_nm;
    for (int c = 0; c < 3; ++c)
        sum[c] = (camera.sensitivity()[std::size_t(c)].at(sample.lambda_nm) * weighted).sum();
    return sum / 4.0 / camera.white_integral();
}

// ---- RGB reductions -------------------------------------------------------------------------

Eigen::Array3d rgb_of_reflectance(const CameraResponse& camera, const Spectrum& albedo) {
    // E * 1 == E exactly, so a perfect white gives exactly (1, 1, 1).
    return camera.rgb_of_radiance(camera.led_emission() * albedo);
}

Eigen::Array3d rgb_of_transmittance(const CameraResponse& camera, const Spectrum& absorption_per_mm,
                                    double path_mm) {
    return rgb_of_reflectance(camera, transmittance(absorption_per_mm, path_mm));
}

Eigen::Array3d rgb_absorption_per_mm(const CameraResponse& camera,
                                     const Spectrum& absorption_per_mm, double path_mm) {
    return -rgb_of_transmittance(camera, absorption_per_mm, path_mm).log() / path_mm;
}

FilterPairRgb rgb_of_filter_pair(const CameraResponse& camera, const Spectrum& a_per_mm,
                                 double a_path_mm, const Spectrum& b_per_mm, double b_path_mm) {
    const Spectrum ta = transmittance(a_per_mm, a_path_mm);
    const Spectrum tb = transmittance(b_per_mm, b_path_mm);
    return {rgb_of_reflectance(camera, ta * tb),
            rgb_of_reflectance(camera, ta) * rgb_of_reflectance(camera, tb)};
}

// ---- The sensor's spectra -------------------------------------------------------------------

SensorSpectraFiles SensorSpectraFiles::in_directory(const std::filesystem::path& directory) {
    return {directory / "led_white.csv",
            directory / "camera_rgb.csv",
            directory / "inner_marker_magenta.csv",
            directory / "outer_marker_cyan.csv",
            directory / "outer_marker_cyan_albedo.csv",
            directory / "coating_white.csv"};
}

namespace {

/// The camera response, with the two files named if they do not fit together.
CameraResponse camera_response(const SensorSpectraFiles& files,
                               const std::array<Spectrum, 3>& sensitivity, const Spectrum& led) {
    try {
        return CameraResponse(sensitivity, led);
    } catch (const SpectrumError& e) {
        throw SpectrumError(files.camera.string() + " with " + files.led.string() + ": " +
                            e.what());
    }
}

} // namespace

SensorSpectra load_sensor_spectra(const SensorSpectraFiles& files) {
    using Q = SpectrumQuantity;
    const Spectrum led = read_spectrum_csv(files.led, Q::relative_emission).front();
    const std::vector<Spectrum> rgb = read_spectrum_csv(files.camera, Q::camera_rgb);
    return {camera_response(files, {rgb[0], rgb[1], rgb[2]}, led),
            read_spectrum_csv(files.inner_marker_absorption, Q::absorption_per_mm).front(),
            read_spectrum_csv(files.outer_marker_absorption, Q::absorption_per_mm).front(),
            read_spectrum_csv(files.outer_marker_albedo, Q::albedo).front(),
            read_spectrum_csv(files.coating_albedo, Q::albedo).front()};
}

} // namespace chromasim::render
