#pragma once
/// Plain data that render takes from the rest of chromasim. Nothing here knows about FEM:
/// generators fills these structs from the mechanics results (docs/ARCHITECTURE.md).
///
/// Frame convention: millimetres, camera frame. The camera sits at the origin (the dome
/// centre) and looks along +z; the dome apex is at (0, 0, 13.2) when undeformed; the coating's inner face, which the camera
/// sees, at (0, 0, 12.7).
#include <Eigen/Core>

#include <cstdint>
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
    /// All marker discs of the inner (magenta filter) layer, each a triangle fan of
    /// `triangles_per_marker` consecutive triangles: marker index = triangle /
    /// triangles_per_marker.
    SurfaceMesh inner_markers;
    /// Same for the outer (cyan, scattering) layer.
    SurfaceMesh outer_markers;
    int triangles_per_marker = 0;
};

/// Equidistant fisheye camera at the origin looking along +z: a ray at polar angle theta lands
/// at radius r = theta / half_fov * min(width, height) / 2 pixels from the image centre.
struct CameraParams {
    int width_px = 256;
    int height_px = 256;
    double half_fov_deg = 84.0; ///< polar angle at the edge of the image circle
};

/// Linear-RGB optical properties. Values are [G] defaults documented in the spec schema.
struct OpticsParams {
    Vec3 coating_albedo{0.85, 0.85, 0.85};              ///< Lambertian white coating
    Vec3 inner_marker_absorption_per_mm{0.2, 3.0, 0.3}; ///< magenta filter (absorbs green)
    Vec3 outer_marker_absorption_per_mm{3.0, 0.3, 0.2}; ///< cyan dye (absorbs red)
    Vec3 outer_marker_albedo{0.10, 0.70, 0.75};         ///< cyan diffuse scattering
    double outer_marker_scatter_fraction = 0.5; ///< share of light an outer marker scatters back
    double marker_thickness_mm = 0.5;           ///< Beer-Lambert path = thickness / |cos|
    int led_count = 6;                          ///< point LEDs evenly on a ring
    double led_ring_radius_mm = 10.0;
    double led_z_mm = -1.0;      ///< ring height; the dome rim is the plane z = 0
    Vec3 led_rgb{1.0, 1.0, 1.0}; ///< relative emission per LED (white)
    double exposure = 1.0;       ///< multiplies the auto exposure (undeformed apex -> 0.8)
};

struct RenderSettings {
    int samples_per_pixel = 4; ///< stratified jittered samples for anti-aliasing
    std::uint64_t seed = 1;    ///< same seed, same frame -> identical image
};

/// Linear RGB image, row-major, top row first, 3 floats per pixel.
struct Image {
    int width = 0;
    int height = 0;
    std::vector<float> rgb;
    float* pixel(int x, int y) { return rgb.data() + 3 * (std::size_t(y) * width + x); }
    const float* pixel(int x, int y) const { return rgb.data() + 3 * (std::size_t(y) * width + x); }
};

} // namespace chromasim::render
