#pragma once
/// Plain data that render takes from the rest of chromasim. Nothing here knows about FEM:
/// generators fills these structs from the mechanics results (docs/ARCHITECTURE.md).
///
/// Frame convention: millimetres, camera frame. The camera sits at the origin (the dome
/// centre) and looks along +z; the dome apex is at (0, 0, 13.2) when undeformed; the coating's
/// inner face, which the camera sees, at (0, 0, 12.7).
#include <Eigen/Core>

#include "render/spectrum.hpp"

#include <cstdint>
#include <optional>
#include <vector>

namespace chromasim::render {

using Vec3 = Eigen::Vector3d;
/// #V x 3 vertex positions in mm, row-major so Embree can share the buffer.
using VertexArray = Eigen::Matrix<float, Eigen::Dynamic, 3, Eigen::RowMajor>;
/// #F x 3 vertex indices into a VertexArray, row-major.
using TriangleArray = Eigen::Matrix<std::uint32_t, Eigen::Dynamic, 3, Eigen::RowMajor>;

/// A triangle surface. Triangles are oriented so that their normal points towards the
/// camera (inwards, towards the dome centre) where that matters (the coating).
struct SurfaceMesh {
    VertexArray V;
    TriangleArray F;
};

/// One deformed sensor state, everything render needs to build its scene.
struct SensorFrame {
    /// Inner face of the white diffusing coating (the background the camera sees).
    SurfaceMesh coating;
    /// Inner surface of a hollow dome: the boundary between the air cavity (camera, LEDs) and
    /// the clear layers, normals towards the cavity. The path integrator refracts there; empty
    /// when the interior is index-matched (soft fill, rigid core) or the integrator ignores it.
    SurfaceMesh inner_surface;
    /// All markers of the inner (magenta filter) layer, each a closed thin volume (a prism
    /// deformed with the FE mesh) of `triangles_per_marker` consecutive triangles whose
    /// normals (by winding) point out of the volume: marker index = triangle /
    /// triangles_per_marker. Light inside a volume is absorbed over the distance it travels.
    SurfaceMesh inner_markers;
    /// Same for the outer (cyan, scattering) layer.
    SurfaceMesh outer_markers;
    int triangles_per_marker = 0;
};

/// Projection model of the fisheye camera (render/fisheye_camera.hpp has the formulas).
enum class CameraModel {
    /// r = theta / half_fov * min(width, height) / 2 px from the image centre: the ideal lens
    /// at the dome centre (SENSOR.md 1).
    equidistant,
    /// OpenCV's cv::fisheye model: fx, fy, cx, cy and k1..k4, as cv::fisheye::calibrate gives
    /// them.
    kannala_brandt,
};

/// The camera: its projection model, image size and pose in the dome frame. The defaults are
/// the equidistant fisheye at the origin looking along +z: a ray at polar angle theta lands at
/// radius r = theta / half_fov * min(width, height) / 2 pixels from the image centre.
///
/// Kannala-Brandt intrinsics follow OpenCV's cv::fisheye convention exactly (skew alpha = 0),
/// pixel centres at integer coordinates, so a calibration is pasted in unchanged; the camera
/// converts to chromasim's pixel coordinates (pixel (i, j) covers [i, i+1) x [j, j+1)) by
/// adding 0.5 px.
struct CameraParams {
    int width_px = 256;
    int height_px = 256;
    /// Polar angle of the edge of the field. Equidistant: also the scale (the image circle's
    /// edge). Kannala-Brandt: rays beyond it are not imaged, and theta_d(theta) must increase
    /// up to it.
    double half_fov_deg = 84.0;
    CameraModel model = CameraModel::equidistant;
    // Kannala-Brandt only (OpenCV's K and D): focal lengths and principal point in px.
    double fx_px = 0.0; ///< K(0, 0); > 0
    double fy_px = 0.0; ///< K(1, 1); > 0
    double cx_px = 0.0; ///< K(0, 2), OpenCV convention (centre of the first pixel = 0)
    double cy_px = 0.0; ///< K(1, 2), OpenCV convention
    /// D = (k1, k2, k3, k4): theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 +
    /// k4 theta^8), theta in radians.
    double k1 = 0.0, k2 = 0.0, k3 = 0.0, k4 = 0.0;
    /// Camera pose in the dome frame (both models): p_dome = position + R p_camera with
    /// R = Rz(yaw) Ry(pitch) Rx(roll), as mechanics' rotation_from_roll_pitch_yaw_deg (roll
    /// about x first, then pitch about y, then yaw about z, all fixed axes).
    Vec3 position_mm = Vec3::Zero();
    double roll_deg = 0.0, pitch_deg = 0.0, yaw_deg = 0.0;
};

/// Linear-RGB optical properties. The defaults are a simple test geometry, LEDs 1 mm under the
/// rim that light the dome directly and no lens barrel; a spec's defaults are the FUSE
/// sensor's (generators/spec/spec.hpp, docs/SPEC.md).
struct OpticsParams {
    Vec3 coating_albedo{0.85, 0.85, 0.85};              ///< Lambertian white coating
    Vec3 inner_marker_absorption_per_mm{0.2, 3.0, 0.3}; ///< magenta filter (absorbs green)
    Vec3 outer_marker_absorption_per_mm{3.0, 0.3, 0.2}; ///< cyan dye (absorbs red)
    Vec3 outer_marker_albedo{0.10, 0.70, 0.75};         ///< cyan diffuse scattering
    double outer_marker_scatter_fraction = 0.5; ///< share of light an outer marker scatters back
    int led_count = 6;                          ///< point LEDs evenly on a ring
    double led_ring_radius_mm = 10.0;
    double led_z_mm = -1.0; ///< the LEDs' emitting faces; the dome rim is the plane z = 0
    /// The path integrator's LEDs: Lambertian rectangles facing +z centred on the ring points,
    /// `led_width_mm` along the ring's tangent, `led_height_mm` along its radius (SMD 3528),
    /// radiance led / area so that far away each matches the preview's point LED.
    double led_width_mm = 3.5;
    double led_height_mm = 2.8;
    /// The rigid frame that clamps the dome covers the rim plane z = 0 from this radius outwards
    /// (the dome's inner radius): light crossing the plane there is absorbed, so LED light
    /// enters the dome only through the opening, and light in the layers does not leak out.
    double frame_inner_radius_mm = 10.5;
    /// The camera's lens barrel: a black cylinder about the z axis, of this radius, from the
    /// rim plane down (0: none). Light from LEDs below the rim passes beside it.
    double lens_radius_mm = 0.0;
    /// Refractive index of the clear layers at the inner surface (air / silicone boundary);
    /// the layers are index-matched among themselves (no other boundary refracts).
    double refractive_index = 1.4;
    Vec3 led_rgb{1.0, 1.0, 1.0}; ///< relative emission per LED (white)
    /// Each LED's intensity relative to led_rgb, in ring order (the first on +x); empty: all 1.
    std::vector<double> led_gain;
    double exposure = 1.0;       ///< multiplies the auto exposure (the reference -> 0.8)
    /// Spectral mode when set: every camera sample carries 16 hero wavelengths (the fast
    /// integrator: RenderSettings::fast_wavelengths); the coating,
    /// marker and LED spectra replace the RGB values above (the LED's relative intensity is
    /// the mean of led_rgb), and the camera's sensitivities turn radiance into white-balanced
    /// RGB. Unset: the RGB mode (a product per channel, an approximation of the spectral one).
    std::optional<SensorSpectra> spectra;
};

/// Light transport (render/renderer.cpp and render/path_integrator.hpp describe both).
enum class Integrator {
    /// A preview: the LEDs' direct light only, straight rays, no refraction; far off the path
    /// integrator.
    preview,
    /// Unbiased spectral path tracing: refraction and Fresnel at the inner surface, diffuse
    /// interreflection, area LEDs with next-event estimation through the interface and MIS.
    path,
    /// The path integrator's light transport with the smooth light cached per sensor on the
    /// coating (render/fast_integrator.hpp): needs Renderer::set_light_cache.
    fast,
};

/// Work of the fast integrator's per-sensor light cache (render/fast_integrator.hpp).
struct LightCacheSettings {
    int paths_per_vertex = 1024; ///< indirect light: paths per coating vertex (and height)
    int direct_samples = 16;     ///< unshadowed LED light: points per LED per coating vertex
    /// Indirect light: standard deviation of the Gaussian that smooths it over the coating,
    /// mm (0: none).
    double smoothing_mm = 0.75;
    /// Per frame, not part of the stored cache: re-estimate a vertex's unshadowed light from
    /// LED k on the frame's own geometry (`direct_samples` points on the LED, as the cache
    /// does at rest) where the point LED's light there changed by more than
    /// `refresh_threshold` (relative) from rest. Elsewhere the point LED's light is scaled by
    /// the area LED's ratio to it at rest, which goes stale where the surface bends.
    bool refresh_direct = true;
    double refresh_threshold = 1.0;
    /// Per frame, not part of the stored cache: skip the fast integrator's shadow rays that
    /// provably meet no marker, fold of the coating or the frame (each ray's path tested
    /// against the bounding balls of the markers near its triangle's paths, listed per
    /// frame), and start each shadow ray's refraction solve from a per-vertex guess (Newton).
    /// The culling is exact; the Newton solves stop within about 1e-5 rad of the full solve on
    /// average (kShadowStepTolerance, render/fast_common.hpp). Off: every shadow ray traced,
    /// its solve over the whole bracket, the reference the culling is tested against.
    bool cull_shadows = true;
};

/// The fast integrator's per-sensor light cache on the coating vertices (plain data, structure
/// of arrays; render/fast_integrator.hpp has the model). Built by Renderer::set_light_cache;
/// generators/pipeline/light_cache_store.hpp keeps it on disk.
struct LightCache {
    int vertices = 0;
    int leds = 0;
    int lanes = 0;             ///< 16 fixed wavelengths, 400 to 700 nm (spectral), or 4 (RGB)
    std::vector<float> direct; ///< G_k per unit LED emission, [vertex * leds + k], 1/mm^2
    /// E_ind / pi per unit LED emission at the coating, [vertex * lanes + j] (under an outer
    /// marker: above it, unfiltered).
    std::vector<float> indirect;
    /// The same above the outer marker layer (where its markers' inner faces are).
    std::vector<float> indirect_above;
    /// The same for a point LED at each LED's centre, at rest (led_flux_point): a frame's G_k
    /// is its point-LED flux through the deformed inner surface times |direct| / |point_rest|.
    std::vector<float> point_rest;
    /// The quadratic term of G_k along each coating edge, [edge * leds + k] * 3: the area
    /// LED's light at the edge's midpoint less the mean of its two ends' (edges numbered as
    /// coating_edges finds them). A sample adds it with the edge's quadratic bubble function.
    std::vector<float> direct_edge;
    std::vector<std::uint32_t> coating_triangles; ///< the coating's triangles (3 per), for checks
    double build_s = 0.0;                         ///< wall time of the build
};

struct RenderSettings {
    /// Samples per pixel, stratified over the pixel's samples: multi-jittered positions,
    /// wavelength strata, and (fast integrator) the shadow ray's LED and point on it from a
    /// scrambled Sobol set (render/sampling.hpp).
    int samples_per_pixel = 4;
    std::uint64_t seed = 1; ///< same seed, same frame -> identical image
    /// Extra channels, computed only when asked for (Image).
    bool marker_ids = false; ///< the marker seen through each pixel's centre, per layer
    bool variance = false;   ///< per-pixel variance estimate of the mean
    Integrator integrator = Integrator::preview;
    /// Fast integrator: the shadow filter's standard deviation, px; 0: none. The LEDs'
    /// direct light in a pixel is, per group of LEDs (one per LED up to kMaxShadowGroups),
    /// its unshadowed value (no noise from the shadow rays) times the fraction of the group's
    /// light that gets through the shadows, taken as a Gaussian-weighted ratio over the
    /// neighbouring pixels' shadow rays that went to the group (per channel; the ratio
    /// estimator of Heitz et al. 2018, post-stratified by LED: render/shadow_filter.hpp). It
    /// removes most of the shadow rays' noise where the shadows change slowly, and blurs their
    /// edges by about this much. The variance channel stays that of the unfiltered pixel.
    double shadow_filter_px = 0.0;
    /// Fast integrator, with the shadow filter and the markers' rims found
    /// (rim_samples_per_pixel above samples_per_pixel): the filter's standard deviation in
    /// the rims' pixels, px (0: each pools its own samples alone); none: shadow_filter_px
    /// there too. The LEDs sit beside the camera, so a marker's shadow on the coating nearly
    /// coincides with its image and the transmittance changes at a rim just as the view
    /// does: pooled over shadow_filter_px it is blurred across the edge, a bias that a
    /// narrower filter on the rims avoids while the rest of the image takes a wider one.
    std::optional<double> shadow_filter_rim_px{};
    /// Fast integrator: the fewest shadow rays a pixel traces from its samples' coating hits,
    /// spread evenly over its samples, at least one and at most
    /// detail::kMaxShadowRaysPerSample (4) a sample, their LED points stratified over the
    /// pixel's rays; a sample with several takes their mean. 0 (or at most the pixel's sample
    /// count): one a sample. The pixels with few samples (the bulk of the image) then trace
    /// more, where the shadow rays' noise is most of the error, without more camera samples;
    /// those with many (the markers' rims, the mirrored pixels) keep one a sample.
    int shadow_rays_per_pixel = 0;
    /// Fast integrator: samples per pixel in the pixels where the inner surface mirrors an
    /// LED (the bright streaks near the rim) and in their 8 neighbours; where it is at most
    /// samples_per_pixel (0 included), none take more. Which pixels: the ray through the
    /// pixel's centre, reflected off the inner surface it meets first, crosses the LEDs' plane
    /// within kReflectionMargin_mm of an LED plus half the largest distance to its 4
    /// neighbours' crossings (the pixel's reach there). A deterministic choice (no sample decides
    /// it), so each pixel stays an unbiased estimate: such a pixel is exactly the pixel of a render
    /// at this many samples per pixel. The LEDs' images in the inner surface cover about 1 %
    /// of the pixels but hold a large share of the squared error at a few samples per pixel.
    /// With reflected_led_samples_per_pixel the same pixels are chosen whatever this count.
    int reflection_samples_per_pixel = 0;
    /// Fast integrator: samples per pixel in the pixels on a marker's rim: those whose 4
    /// corners do not all show the same markers (per layer, the first marker along the camera
    /// ray refracted at the inner surface, as the samples see it:
    /// FastIntegrator::marker_ids16). Where it is at most samples_per_pixel (0 included), none
    /// take more; a pixel that also mirrors an LED takes reflection_samples_per_pixel. As for
    /// that: a choice from the frame's geometry, made before any sample, so each pixel is
    /// exactly the pixel of a render at its count. The markers' rims hold most of the image's
    /// error at a few samples per pixel.
    int rim_samples_per_pixel = 0;
    /// Fast integrator: in the pixels where an LED is mirrored (those of
    /// reflection_samples_per_pixel), the LEDs seen by reflection in the inner surface are
    /// estimated apart, from this many camera rays per pixel (stratified over the pixel, a
    /// stream of their own) that go only as far as the reflection: the camera ray to the
    /// inner surface and, where it crosses an LED, its reflection to the next surface (from a
    /// camera in the cavity both against the inner surface alone), no shading
    /// (FastIntegrator::reflected_leds16). The pixel's samples then leave
    /// that term out; the pixel stays an unbiased estimate (the sum of two). The LEDs' images
    /// in the inner surface are small and bright (pixels up to 1.7 times white at 224 px), so
    /// their edges hold most of those pixels' noise; 32 of these rays cost about as much as 4
    /// samples.
    /// 0: the term stays in the samples. A mirrored pixel takes at least samples_per_pixel
    /// samples.
    int reflected_led_samples_per_pixel = 0;
    /// Fast integrator: the most memory (MiB) the camera samples may keep from one render to
    /// the next. A pixel's samples at each of its counts (samples_per_pixel, the rims', the
    /// mirrored pixels', the LED rays': each sample's direction and hero-wavelength set, each
    /// shadow ray's uniforms) depend only on the seed, the counts and the shadow rays, not on
    /// the frame, and a dataset renders every frame with its spec's seed, so they are drawn
    /// the first time and read back after: 8 bytes a number and 8 bytes a pixel per count for
    /// the index (8.6 MiB at 224 px with the shipped specs, 72 MiB at 896 px). Beyond the
    /// budget, or at 0, renders draw them anew: the same samples, the same bytes; so does a
    /// render that finds another thread's render of the same renderer using them (it does
    /// not wait).
    double camera_cache_mb = 128.0;
    /// Fast integrator, spectral mode: the hero wavelengths a camera sample carries, 8 or 16
    /// (the preview and path integrators always carry 16); 0: 16 at one sample per pixel, 8
    /// from 2 on (fast_wavelengths_of). A pixel's samples split the wavelengths' strata, so
    /// 2 samples of 8 are about as noisy in colour as one of 16; one sample of 8 is not. The
    /// rays do not depend on the wavelength, so the lanes cost arithmetic, not rays: from 2
    /// spp on, 8 take about 5 % off a render for a few hundredths of a percent of white more
    /// error; at 1 spp they save little and add much more colour noise. The light cache is
    /// the same for both (its own 16 fixed wavelengths).
    int fast_wavelengths = 0;
};
/// The hero wavelengths a fast-integrator sample carries with these settings
/// (RenderSettings::fast_wavelengths; 0: 16 at samples_per_pixel 1, else 8).
inline int fast_wavelengths_of(const RenderSettings& settings) {
    return settings.fast_wavelengths > 0     ? settings.fast_wavelengths
           : settings.samples_per_pixel >= 2 ? 8
                                             : 16;
}
/// RenderSettings::reflection_samples_per_pixel: how far from an LED's rectangle on the LEDs'
/// plane a pixel centre's mirrored ray may cross and still count, mm.
inline constexpr double kReflectionMargin_mm = 0.25;
/// The largest RenderSettings::shadow_filter_px, px.
inline constexpr double kMaxShadowFilterPx = 8.0;
/// The most groups of LEDs the shadow filter keeps apart (render/shadow_filter.hpp; LEDs
/// beyond are grouped: detail::shadow_group).
inline constexpr int kMaxShadowGroups = 8;

/// Linear RGB image, row-major, top row first, 3 floats per pixel; extra channels are empty
/// unless RenderSettings asked for them.
struct Image {
    int width = 0;
    int height = 0;
    std::vector<float> rgb;
    /// Per pixel: the marker (index within its layer) whose volume the ray through the pixel's
    /// centre meets first in each layer, before the coating (refracted at the inner surface as
    /// the path and fast integrators' samples are; straight for the preview integrator); -1 for
    /// none.
    std::vector<std::int32_t> inner_marker_id, outer_marker_id;
    /// Per pixel and channel: the sample variance over the pixel's samples divided by their
    /// number, the variance of the mean as if the samples were independent (stratification
    /// makes the true one smaller).
    std::vector<float> variance;
    /// Image value per unit of scene radiance: rgb / image_per_radiance is radiance in the
    /// LEDs' units (in RGB mode an LED's face has radiance led_rgb / (led_width_mm x
    /// led_height_mm)); 0: not known.
    double image_per_radiance = 0.0;
    float* pixel(int x, int y) { return rgb.data() + 3 * (std::size_t(y) * width + x); }
    const float* pixel(int x, int y) const { return rgb.data() + 3 * (std::size_t(y) * width + x); }
};

} // namespace chromasim::render
