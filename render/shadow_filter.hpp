#pragma once
/// The fast integrator's shadow filter (RenderSettings::shadow_filter_px): the ratio estimator
/// of Heitz, Hill and McGuire, "Combining analytic direct illumination and stochastic
/// shadows" (I3D 2018), in the image.
///
/// A pixel's value is A + S: S the LEDs' direct light with the shadow rays' transmittance
/// (noisy: one shadow ray per sample), A the rest. U is the same direct light with every
/// transmittance 1 (no shadow-ray noise; the light cache's unshadowed G_k). The filter writes
///     A + U R,   R = sum_q w_q S_q / sum_q w_q U_q,
/// per channel, over the pixels q within 3 sigma, w_q = exp(-d^2 / (2 sigma^2)) (separable;
/// pixels off the image count for nothing). Where the fraction of the light that gets through
/// the shadows is the same over the neighbourhood, R is that fraction with the noise of all
/// the neighbourhood's shadow rays; where it changes, R blurs it by about sigma.
#include <span>

namespace chromasim::render::detail {

/// Filters the row-major RGB image `rgb` (width x height, 3 floats a pixel) in place: each
/// pixel's A + S becomes A + U R (above). `lit`, `shadowed`: each pixel's U and S, in the
/// image's units. Pixels whose neighbourhood has no unshadowed direct light (sum w U <= 0 in a
/// channel) keep that channel. Deterministic: the same bytes on any number of threads.
/// Throws std::invalid_argument on mismatched sizes or sigma_px outside (0, kMaxShadowFilterPx].
void shadow_filter(int width, int height, std::span<float> rgb, std::span<const float> lit,
                   std::span<const float> shadowed, double sigma_px);

} // namespace chromasim::render::detail
