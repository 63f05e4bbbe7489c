#pragma once
/// `chromasim verify render`: the renderer against analytic references (render issue keys),
/// printed as a table and optionally written as JSON.
#include <iosfwd>
#include <string>
#include <vector>

namespace chromasim::generators {

struct RenderVerifyCase {
    std::string key;  ///< fisheye_projection, filter_product, determinism, convergence_slope
    std::string mode; ///< spectral | rgb, or the camera model
    double measured = 0, reference = 0;
    double error = 0;      ///< measured - reference, or relative where `relative`
    double target = 0;     ///< |error| allowed
    bool relative = false; ///< error is (measured - reference) / reference
    double seconds = 0;    ///< run time of the case
    std::string unit, note;
};

/// Renders the coarse dome (undeformed unless stated) and checks: each undeformed inner
/// marker's image centroid against the analytic projection of its centre (equidistant and a
/// Kannala-Brandt camera, 896 px, within 0.5 px); a pixel through a magenta and a cyan filter
/// against the spectral product of their transmittances (1 %); identical bytes with 1 and 2
/// threads; the slope of log RMSE against log spp (-0.5 +- 0.1, report).
std::vector<RenderVerifyCase> verify_render();

void print_render_verify_table(const std::vector<RenderVerifyCase>& cases, std::ostream& out);
void write_render_verify_json(const std::vector<RenderVerifyCase>& cases, std::ostream& out);

} // namespace chromasim::generators
