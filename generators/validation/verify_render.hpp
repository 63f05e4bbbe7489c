#pragma once
/// `chromasim verify render`: the renderer against analytic references (render issue keys),
/// printed as a table and optionally written as JSON.
#include "render/scene_data.hpp"

#include <cstdint>
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
/// threads; the slope of log RMSE against log spp (-0.5 +- 0.1) of both integrators; the
/// path integrator's integrating-sphere furnace per lane (0.5 %, render/furnace.hpp).
std::vector<RenderVerifyCase> verify_render();

/// The committed reference image (tests/data/reference_dome_path.exr): the undeformed coarse
/// dome of the default spec, spectral, path integrator, kReferenceDomeSize_px square, with the
/// variance channel. `chromasim verify render --write-reference FILE --reference-spp N`
/// writes it; tests/generators/test_reference_image.cpp compares a fresh render with it.
inline constexpr int kReferenceDomeSize_px = 64;
render::Image render_reference_dome(int samples_per_pixel, std::uint64_t seed);

void print_render_verify_table(const std::vector<RenderVerifyCase>& cases, std::ostream& out);
void write_render_verify_json(const std::vector<RenderVerifyCase>& cases, std::ostream& out);

} // namespace chromasim::generators
