#pragma once
/// Equidistant fisheye camera at the origin looking along +z (the dome centre, SENSOR.md 1).
#include "render/scene_data.hpp"

#include <optional>

namespace chromasim::render {

/// Maps pixels to viewing directions and back. Image axes: x to the right, y down (top row
/// first); camera axes: +x along the image x axis, +y along the image y axis, +z forward.
/// Continuous pixel coordinates: pixel (i, j) covers [i, i+1) x [j, j+1), so the optical axis
/// meets the image at (width/2, height/2). A direction at polar angle theta (from +z) and
/// azimuth phi (from +x towards +y) lands at radius r = theta / half_fov * min(w, h) / 2 px
/// from that centre, at angle phi; the image circle is r <= min(w, h) / 2.
class FisheyeCamera {
public:
    /// Throws std::invalid_argument on sizes < 1 or half_fov_deg outside (0, 180].
    explicit FisheyeCamera(const CameraParams& params);

    /// Unit direction seen at continuous pixel coordinates `pixel_px`; nullopt outside the
    /// image circle (those samples stay black).
    std::optional<Vec3> direction(const Eigen::Vector2d& pixel_px) const;

    /// Continuous pixel coordinates of a point (mm, camera frame); nullopt for the origin
    /// itself and for points whose polar angle exceeds half_fov (outside the image circle).
    std::optional<Eigen::Vector2d> project(const Vec3& p_mm) const;

    int width_px() const { return m_width_px; }
    int height_px() const { return m_height_px; }
    /// Radius of the image circle, min(width, height) / 2 px.
    double circle_radius_px() const { return m_circle_radius_px; }
    /// Where the optical axis meets the image, (width/2, height/2) px.
    const Eigen::Vector2d& centre_px() const { return m_centre_px; }

private:
    int m_width_px;
    int m_height_px;
    double m_half_fov_rad;
    double m_circle_radius_px;
    Eigen::Vector2d m_centre_px;
};

} // namespace chromasim::render
