#pragma once
/// The fast integrator's shadow filter (RenderSettings::shadow_filter_px): the ratio estimator
/// of Heitz, Hill and McGuire, "Combining analytic direct illumination and stochastic
/// shadows" (I3D 2018), in the image, post-stratified by groups of LEDs.
///
/// A pixel's value is A + S: S the LEDs' direct light with the shadow rays' transmittance
/// (noisy: each shadow ray goes to one LED), A the rest. Per group g of LEDs
/// (FastIntegrator::shadow_groups, one per LED up to 8):
///   - U_g: the group's direct light with every transmittance 1 (the light cache's unshadowed
///     G_k; no shadow-ray noise);
///   - C_g: the same, from the shadow rays that went to the group only (each such ray's
///     share of the sum over all LEDs, so C_g is U_g's estimate by the LED draw);
///   - S_g: those rays' shadowed light (S = sum_g S_g).
/// The filter writes
///     A + sum_g U_g R_g,   R_g = sum_q w_q S_g,q / sum_q w_q C_g,q,
/// per channel, over the pixels q within 3 sigma, w_q = exp(-d^2 / (2 sigma^2)) (separable;
/// pixels off the image count for nothing). R_g is the mean transmittance towards the group's
/// LEDs among the neighbourhood's shadow rays that went there, so which LED each sample drew
/// adds no noise (with one group, R = sum S / sum U, it does: the samples' LEDs differ in their
/// shadows). Where the group's fraction is the same over the neighbourhood, R_g is that fraction;
/// where it changes (a shadow's edge), R_g blurs it by about sigma. A group none of whose shadow
/// rays is in the neighbourhood takes all groups' ratio, sum S / sum C; with none at all the
/// pixel keeps its own S_g.
///
/// The markers' rims (`rims`, a flag per pixel) may take a narrower sigma of their own
/// (RenderSettings::shadow_filter_rim_px): the LEDs sit beside the camera, so a marker's
/// shadow on the coating nearly coincides with its image, and pooling the transmittance over
/// a rim blurs it across the marker's edge (most of a wide filter's bias lies at the rims). A
/// rim pixel's sums are taken over the same window with the 2-D Gaussian of its own sigma (0:
/// the pixel alone); the other pixels' are as without rims, bit for bit.
#include <cstdint>
#include <span>

namespace chromasim::render::detail {

/// Filters the row-major RGB image `rgb` (width x height, 3 floats a pixel) in place: each
/// pixel's A + S becomes A + sum_g U_g R_g (above). `lit`, `chosen`, `shadowed`: each pixel's
/// U_g, C_g and S_g in the image's units, [(pixel * groups + g) * 3 + channel]. Deterministic:
/// the same bytes on any number of threads. Throws std::invalid_argument on mismatched sizes,
/// groups outside [1, kMaxShadowGroups], sigma_px outside (0, kMaxShadowFilterPx], `rims`
/// neither empty nor one flag a pixel, or rim_sigma_px outside [0, kMaxShadowFilterPx].
void shadow_filter(int width, int height, int groups, std::span<float> rgb,
                   std::span<const float> lit, std::span<const float> chosen,
                   std::span<const float> shadowed, double sigma_px,
                   std::span<const std::uint8_t> rims = {}, double rim_sigma_px = 0.0);

/// One group (C = U): A + U R, R = sum_q w_q S_q / sum_q w_q U_q; pixels whose neighbourhood
/// has no unshadowed direct light (sum w U <= 0 in a channel) keep that channel.
void shadow_filter(int width, int height, std::span<float> rgb, std::span<const float> lit,
                   std::span<const float> shadowed, double sigma_px);

} // namespace chromasim::render::detail
