#include "render/fisheye_camera.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace chromasim::render {

namespace {

const CameraParams& validated(const CameraParams& params) {
    if (params.width_px < 1 || params.height_px < 1) {
        throw std::invalid_argument("CameraParams: image size " + std::to_string(params.width_px) +
                                    " x " + std::to_string(params.height_px) +
                                    " px is invalid; allowed: width_px, height_px >= 1");
    }
    if (!(params.half_fov_deg > 0.0 && params.half_fov_deg <= 180.0)) {
        throw std::invalid_argument(
            "CameraParams: half_fov_deg = " + std::to_string(params.half_fov_deg) +
            " is invalid; allowed: (0, 180] degrees");
    }
    return params;
}

} // namespace

FisheyeCamera::FisheyeCamera(const CameraParams& params)
    : m_width_px(validated(params).width_px), m_height_px(params.height_px),
      m_half_fov_rad(params.half_fov_deg * std::numbers::pi / 180.0),
      m_circle_radius_px(0.5 * std::min(params.width_px, params.height_px)),
      m_centre_px(0.5 * params.width_px, 0.5 * params.height_px) {}

std::optional<Vec3> FisheyeCamera::direction(const Eigen::Vector2d& pixel_px) const {
    const Eigen::Vector2d offset = pixel_px - m_centre_px;
    const double r_px = offset.norm();
    if (r_px > m_circle_radius_px) return std::nullopt;
    const double theta = r_px / m_circle_radius_px * m_half_fov_rad;
    const double phi = std::atan2(offset.y(), offset.x());
    const double sin_theta = std::sin(theta);
    return Vec3(sin_theta * std::cos(phi), sin_theta * std::sin(phi), std::cos(theta));
}

std::optional<Eigen::Vector2d> FisheyeCamera::project(const Vec3& p_mm) const {
    const double rho = std::hypot(p_mm.x(), p_mm.y());
    if (rho == 0.0 && p_mm.z() == 0.0) return std::nullopt;
    const double theta = std::atan2(rho, p_mm.z());
    if (theta > m_half_fov_rad) return std::nullopt;
    const double r_px = theta / m_half_fov_rad * m_circle_radius_px;
    const double phi = std::atan2(p_mm.y(), p_mm.x());
    return Eigen::Vector2d(m_centre_px.x() + r_px * std::cos(phi),
                           m_centre_px.y() + r_px * std::sin(phi));
}

} // namespace chromasim::render
