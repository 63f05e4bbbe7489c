#pragma once
/// The fisheye camera: the equidistant lens at the dome centre (SENSOR.md 1, the default) or
/// OpenCV's Kannala-Brandt model at any pose, pixel <-> direction.
#include "render/scene_data.hpp"

#include <Eigen/Core>

#include <optional>

namespace chromasim::render {

/// Maps pixels to viewing directions and back. Image axes: x to the right, y down (top row
/// first); camera axes: +x along the image x axis, +y along the image y axis, +z forward (the
/// optical axis). A direction at polar angle theta (from +z) and azimuth phi (from +x towards
/// +y) lands, in chromasim's continuous pixel coordinates (pixel (i, j) covers
/// [i, i+1) x [j, j+1)):
///   - equidistant: at radius r = theta / half_fov * min(w, h) / 2 px from (w/2, h/2), at angle
///     phi; the image circle is r <= min(w, h) / 2;
///   - Kannala-Brandt (OpenCV's cv::fisheye, skew 0): theta_d = theta (1 + k1 theta^2 +
///     k2 theta^4 + k3 theta^6 + k4 theta^8), (x_d, y_d) = theta_d (cos phi, sin phi) (OpenCV
///     writes it theta_d / r (a, b) with (a, b) = (x / z, y / z)), and
///     (u, v) = (fx x_d + cx + 0.5, fy y_d + cy + 0.5): OpenCV puts pixel centres at integers,
///     chromasim at half-integers, so cx, cy from cv::fisheye::calibrate are used unchanged.
///     Rays with theta > half_fov are not imaged.
/// The pose (CameraParams::position_mm and roll, pitch, yaw) places the camera in the dome
/// frame: direction() returns dome-frame directions of rays that start at origin_mm(), and
/// project() takes dome-frame points. The default pose is the identity at the dome centre.
/// Points with z <= 0 in the camera frame are handled (theta from atan2, not atan(r) as in
/// OpenCV), so a field wider than 90 deg works.
class FisheyeCamera {
public:
    /// Throws std::invalid_argument, naming the parameter and the allowed values, on sizes
    /// < 1, half_fov_deg outside (0, 180], a non-finite pose, and for Kannala-Brandt on
    /// fx_px or fy_px not finite and > 0, non-finite cx_px, cy_px or k1..k4, or k1..k4 whose
    /// theta_d(theta) does not increase over [0, half_fov] (kannala_brandt_min_slope).
    explicit FisheyeCamera(const CameraParams& params);

    /// Unit direction (dome frame) seen at continuous pixel coordinates `pixel_px`; nullopt
    /// outside the field (beyond the image circle, theta > half_fov): no light from there (the
    /// renderer draws such a sample anew in a pixel the circle's edge crosses).
    std::optional<Vec3> direction(const Eigen::Vector2d& pixel_px) const;

    /// The share of pixel (x, y) (the square [x, x+1) x [y, y+1)) inside the field, in [0, 1]:
    /// 1 exactly where the whole square is inside, 0 where none of it is, else the area of
    /// the square within the image circle (an ellipse of semi-axes fx theta_d(half_fov) and
    /// fy theta_d(half_fov) for Kannala-Brandt), in closed form (round-off only). The
    /// renderer weights a rim pixel's samples with it (render/renderer.cpp).
    double field_coverage(int x, int y) const;

    /// Continuous pixel coordinates of a point (mm, dome frame); nullopt for the camera
    /// position itself and for points whose polar angle exceeds half_fov.
    std::optional<Eigen::Vector2d> project(const Vec3& p_mm) const;

    /// Where every ray starts: the camera position in the dome frame, mm.
    const Vec3& origin_mm() const { return m_origin_mm; }
    /// Camera-to-dome rotation: its columns are the camera's x, y, z axes in the dome frame.
    const Eigen::Matrix3d& rotation() const { return m_rotation; }

    CameraModel model() const { return m_model; }
    int width_px() const { return m_width_px; }
    int height_px() const { return m_height_px; }
    /// Polar angle of the edge of the field, rad.
    double half_fov_rad() const { return m_half_fov_rad; }
    /// Radius of the image circle along the image x axis, px: min(width, height) / 2
    /// (equidistant), fx theta_d(half_fov) (Kannala-Brandt).
    double circle_radius_px() const { return m_circle_radius_px; }
    /// Where the optical axis meets the image, chromasim pixel coordinates: (width/2, height/2)
    /// (equidistant), (cx + 0.5, cy + 0.5) (Kannala-Brandt).
    const Eigen::Vector2d& centre_px() const { return m_centre_px; }

private:
    std::optional<Vec3> camera_direction(const Eigen::Vector2d& pixel_px) const;
    std::optional<Eigen::Vector2d> camera_project(const Vec3& p_camera_mm) const;
    /// theta (rad) with theta_d(theta) = theta_d_rad, for theta_d_rad in [0, m_theta_d_max].
    double kb_theta(double theta_d_rad) const;

    CameraModel m_model;
    int m_width_px;
    int m_height_px;
    double m_half_fov_rad;
    double m_circle_radius_px;
    double m_circle_radius_y_px; ///< along the image y axis (fy theta_d(half_fov))
    Eigen::Vector2d m_centre_px;
    // Kannala-Brandt.
    Eigen::Vector2d m_focal_px{1.0, 1.0};
    double m_k[4] = {0.0, 0.0, 0.0, 0.0};
    double m_theta_d_max = 0.0; ///< theta_d(half_fov), rad: the edge of the field
    // Pose; skipped when the identity at the origin (keeps default images bit for bit).
    bool m_posed = false;
    Eigen::Matrix3d m_rotation = Eigen::Matrix3d::Identity();
    Vec3 m_origin_mm = Vec3::Zero();
};

/// The Kannala-Brandt intrinsics (OpenCV convention) of the equidistant camera of `params`'s
/// image size and half field: fx = fy = min(width, height) / 2 / half_fov (rad),
/// cx = width / 2 - 0.5, cy = height / 2 - 0.5. With k1..k4 = 0 the Kannala-Brandt camera
/// then images exactly as the equidistant one. Returns `params` with model kannala_brandt and
/// these four values; everything else is unchanged.
CameraParams with_equidistant_intrinsics(CameraParams params);

/// The smallest slope d theta_d / d theta = 1 + 3 k1 theta^2 + 5 k2 theta^4 + 7 k3 theta^6 +
/// 9 k4 theta^8 of the Kannala-Brandt polynomial over theta in [0, max_theta_rad], and the
/// theta (rad) where it occurs. theta_d is invertible over that range (as direction() needs)
/// exactly when the slope is > 0.
struct SlopeMinimum {
    double slope;
    double theta_rad;
};
SlopeMinimum kannala_brandt_min_slope(double k1, double k2, double k3, double k4,
                                      double max_theta_rad);

} // namespace chromasim::render
