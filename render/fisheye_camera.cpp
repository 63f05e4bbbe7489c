#include "render/fisheye_camera.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <stdexcept>
#include <string>

namespace chromasim::render {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

/// half_fov_deg in radians, rounded as the equidistant camera rounds it (the same images bit
/// for bit).
double half_fov_rad_of(const CameraParams& p) {
    return p.half_fov_deg * std::numbers::pi / 180.0;
}

/// Shortest text that reads back to `x` ("84", "0.25", "-1e-07", "nan").
std::string text(double x) {
    char buf[64];
    const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, x);
    (void)ec; // 64 chars always suffice for a double
    return std::string(buf, end);
}

/// `x` to 4 significant digits ("84", "46.78", "-2.215"), for values that are reports, not
/// inputs to copy back.
std::string rounded(double x) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.4g", x);
    return buf;
}

[[noreturn]] void invalid(const std::string& what, double value, const std::string& allowed) {
    throw std::invalid_argument("CameraParams: " + what + " = " + text(value) +
                                " is invalid; allowed: " + allowed);
}

void validate_common(const CameraParams& p) {
    if (p.width_px < 1 || p.height_px < 1) {
        throw std::invalid_argument("CameraParams: image size " + std::to_string(p.width_px) +
                                    " x " + std::to_string(p.height_px) +
                                    " px is invalid; allowed: width_px, height_px >= 1");
    }
    if (!(p.half_fov_deg > 0.0 && p.half_fov_deg <= 180.0))
        invalid("half_fov_deg", p.half_fov_deg, "(0, 180] degrees");
    const char* axes[3] = {"position_mm.x", "position_mm.y", "position_mm.z"};
    for (int i = 0; i < 3; ++i)
        if (!std::isfinite(p.position_mm[i]))
            invalid(axes[i], p.position_mm[i], "a finite number (mm, dome frame)");
    for (const auto& [name, angle] :
         {std::pair{"roll_deg", p.roll_deg}, std::pair{"pitch_deg", p.pitch_deg},
          std::pair{"yaw_deg", p.yaw_deg}})
        if (!std::isfinite(angle)) invalid(name, angle, "a finite angle (degrees)");
}

void validate_kannala_brandt(const CameraParams& p) {
    if (!(std::isfinite(p.fx_px) && p.fx_px > 0.0))
        invalid("fx_px", p.fx_px, "a finite focal length > 0 (px, OpenCV's K(0, 0))");
    if (!(std::isfinite(p.fy_px) && p.fy_px > 0.0))
        invalid("fy_px", p.fy_px, "a finite focal length > 0 (px, OpenCV's K(1, 1))");
    if (!std::isfinite(p.cx_px))
        invalid("cx_px", p.cx_px, "a finite number (px, OpenCV's K(0, 2))");
    if (!std::isfinite(p.cy_px))
        invalid("cy_px", p.cy_px, "a finite number (px, OpenCV's K(1, 2))");
    const double k[4] = {p.k1, p.k2, p.k3, p.k4};
    for (int i = 0; i < 4; ++i)
        if (!std::isfinite(k[i]))
            invalid("k" + std::to_string(i + 1), k[i],
                    "a finite distortion coefficient (OpenCV's D[" + std::to_string(i) + "])");
    const SlopeMinimum m = kannala_brandt_min_slope(p.k1, p.k2, p.k3, p.k4, half_fov_rad_of(p));
    if (!(m.slope > 0.0)) {
        const std::string ks =
            text(p.k1) + ", " + text(p.k2) + ", " + text(p.k3) + ", " + text(p.k4);
        const std::string where = rounded(m.slope) + " at theta = " + rounded(m.theta_rad / kDeg) +
                                  " deg (half_fov_deg = " + text(p.half_fov_deg) + ")";
        const std::string allowed =
            "coefficients with 1 + 3 k1 t^2 + 5 k2 t^4 + 7 k3 t^6 + 9 k4 t^8 > 0 for every t "
            "(rad) in [0, half_fov], or a smaller half_fov_deg (the field the calibration covers)";
        throw std::invalid_argument(
            "CameraParams: k1..k4 = (" + ks +
            ") make theta_d(theta) stop increasing within the field: its "
            "slope d theta_d / d theta falls to " +
            where + ", so pixels cannot be mapped back to rays; allowed: " + allowed);
    }
}

/// theta_d(theta) / theta = 1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8, Horner in
/// s = theta^2.
double kb_factor(const double k[4], double s) {
    return 1.0 + s * (k[0] + s * (k[1] + s * (k[2] + s * k[3])));
}

/// d theta_d / d theta at s = theta^2.
double kb_slope(const double k[4], double s) {
    return 1.0 + s * (3.0 * k[0] + s * (5.0 * k[1] + s * (7.0 * k[2] + s * 9.0 * k[3])));
}

/// R = Rz(yaw) Ry(pitch) Rx(roll), the convention of mechanics' object poses.
Eigen::Matrix3d rotation_from_roll_pitch_yaw_deg(double roll_deg, double pitch_deg,
                                                 double yaw_deg) {
    return (Eigen::AngleAxisd(yaw_deg * kDeg, Eigen::Vector3d::UnitZ()) *
            Eigen::AngleAxisd(pitch_deg * kDeg, Eigen::Vector3d::UnitY()) *
            Eigen::AngleAxisd(roll_deg * kDeg, Eigen::Vector3d::UnitX()))
        .toRotationMatrix();
}

} // namespace

SlopeMinimum kannala_brandt_min_slope(double k1, double k2, double k3, double k4,
                                      double max_theta_rad) {
    const double k[4] = {k1, k2, k3, k4};
    const double s_max = max_theta_rad * max_theta_rad;
    // The slope is a quartic in s = theta^2: its minimum over [0, s_max] lies at an end or at
    // a root of its derivative 3 k1 + 10 k2 s + 21 k3 s^2 + 36 k4 s^3, found as eigenvalues of
    // the companion matrix. Evaluating at the clamped real part of every eigenvalue, complex
    // ones included, only adds points of the interval, so near-double roots are safe too.
    SlopeMinimum best{kb_slope(k, 0.0), 0.0};
    const auto consider = [&](double s) {
        s = std::clamp(s, 0.0, s_max);
        const double slope = kb_slope(k, s);
        if (!(slope >= best.slope)) best = {slope, std::sqrt(s)}; // NaN slopes win: invalid
    };
    consider(s_max);
    const double c[4] = {3.0 * k1, 10.0 * k2, 21.0 * k3, 36.0 * k4};
    int degree = 3;
    while (degree > 0 && c[degree] == 0.0)
        --degree;
    if (degree > 0) {
        Eigen::MatrixXd companion = Eigen::MatrixXd::Zero(degree, degree);
        for (int i = 0; i < degree; ++i) {
            if (i > 0) companion(i, i - 1) = 1.0;
            companion(i, degree - 1) = -c[i] / c[degree];
        }
        const Eigen::VectorXcd roots =
            Eigen::EigenSolver<Eigen::MatrixXd>(companion, false).eigenvalues();
        for (Eigen::Index i = 0; i < roots.size(); ++i)
            consider(roots[i].real());
    }
    return best;
}

CameraParams with_equidistant_intrinsics(CameraParams params) {
    const double focal_px =
        0.5 * std::min(params.width_px, params.height_px) / half_fov_rad_of(params);
    params.model = CameraModel::kannala_brandt;
    params.fx_px = params.fy_px = focal_px;
    params.cx_px = 0.5 * params.width_px - 0.5; // OpenCV: first pixel centre at 0
    params.cy_px = 0.5 * params.height_px - 0.5;
    return params;
}

FisheyeCamera::FisheyeCamera(const CameraParams& params)
    : m_model(params.model), m_width_px(params.width_px), m_height_px(params.height_px),
      m_half_fov_rad(half_fov_rad_of(params)) {
    validate_common(params);
    if (m_model == CameraModel::equidistant) {
        m_circle_radius_px = 0.5 * std::min(params.width_px, params.height_px);
        m_circle_radius_y_px = m_circle_radius_px;
        m_centre_px = Eigen::Vector2d(0.5 * params.width_px, 0.5 * params.height_px);
    } else {
        validate_kannala_brandt(params);
        m_focal_px = Eigen::Vector2d(params.fx_px, params.fy_px);
        m_k[0] = params.k1, m_k[1] = params.k2, m_k[2] = params.k3, m_k[3] = params.k4;
        m_theta_d_max = m_half_fov_rad * kb_factor(m_k, m_half_fov_rad * m_half_fov_rad);
        m_circle_radius_px = params.fx_px * m_theta_d_max;
        m_circle_radius_y_px = params.fy_px * m_theta_d_max;
        m_centre_px = Eigen::Vector2d(params.cx_px + 0.5, params.cy_px + 0.5); // see header
    }
    m_rotation =
        rotation_from_roll_pitch_yaw_deg(params.roll_deg, params.pitch_deg, params.yaw_deg);
    m_origin_mm = params.position_mm;
    m_posed = !(m_rotation == Eigen::Matrix3d::Identity() && m_origin_mm == Vec3::Zero());
}

std::optional<Vec3> FisheyeCamera::direction(const Eigen::Vector2d& pixel_px) const {
    const auto d = camera_direction(pixel_px);
    if (!d || !m_posed) return d;
    return Vec3(m_rotation * *d);
}

std::optional<Eigen::Vector2d> FisheyeCamera::project(const Vec3& p_mm) const {
    if (!m_posed) return camera_project(p_mm);
    return camera_project(m_rotation.transpose() * (p_mm - m_origin_mm));
}

double FisheyeCamera::field_coverage(int x, int y) const {
    // In units of the semi-axes the field is the unit disc and the pixel a rectangle
    // [u0, u1] x [v0, v1]. (The open and closed squares have the same area.)
    const double a = m_circle_radius_px, b = m_circle_radius_y_px;
    const double u0 = (x - m_centre_px.x()) / a, u1 = (x + 1 - m_centre_px.x()) / a;
    const double v0 = (y - m_centre_px.y()) / b, v1 = (y + 1 - m_centre_px.y()) / b;
    const auto square = [](double t) { return t * t; };
    // The rectangle's nearest and farthest points from the centre.
    const double near2 = square(std::clamp(0.0, u0, u1)) + square(std::clamp(0.0, v0, v1));
    if (near2 > 1.0) return 0.0;
    const double far2 = std::max(square(u0), square(u1)) + std::max(square(v0), square(v1));
    if (far2 <= 1.0) return 1.0;
    // The area: the integral over u of the chord [max(v0, -h), min(v1, h)], h = sqrt(1 - u^2),
    // piece by piece between the u where h crosses v0 or v1 (and +-1); on each piece the
    // chord's ends are each a constant or +-h, whose integral is H(u) = (u h + asin u) / 2.
    const auto h = [](double u) { return std::sqrt(std::max(0.0, 1.0 - u * u)); };
    const auto H = [&](double u) {
        const double c = std::clamp(u, -1.0, 1.0);
        return 0.5 * (c * h(c) + std::asin(c));
    };
    // Unused cuts stay at u1: empty pieces.
    std::array<double, 8> cuts{u0, -1.0, 1.0, u1, u1, u1, u1, u1};
    for (std::size_t i = 0; i < 2; ++i) {
        const double v = i == 0 ? v0 : v1;
        if (std::abs(v) < 1.0) cuts[3 + 2 * i] = -h(v), cuts[4 + 2 * i] = h(v);
    }
    std::sort(cuts.begin(), cuts.end());
    double area = 0.0;
    for (std::size_t i = 0; i + 1 < cuts.size(); ++i) {
        const double lo = std::max(cuts[i], u0), hi = std::min(cuts[i + 1], u1);
        if (!(hi > lo)) continue;
        const double mid = h(0.5 * (lo + hi));
        const bool top_h = mid < v1;     // the chord's upper end at +h, else at v1
        const bool bottom_h = -mid > v0; // its lower end at -h, else at v0
        if (!((top_h ? mid : v1) > (bottom_h ? -mid : v0))) continue; // no chord here
        const double top = top_h ? H(hi) - H(lo) : v1 * (hi - lo);
        const double bottom = bottom_h ? -(H(hi) - H(lo)) : v0 * (hi - lo);
        area += top - bottom;
    }
    return std::clamp(area * a * b, 0.0, 1.0);
}

std::optional<Vec3> FisheyeCamera::camera_direction(const Eigen::Vector2d& pixel_px) const {
    const Eigen::Vector2d offset = pixel_px - m_centre_px;
    if (m_model == CameraModel::equidistant) {
        const double r_px = offset.norm();
        if (r_px > m_circle_radius_px) return std::nullopt;
        if (r_px == 0.0) return Vec3(0.0, 0.0, 1.0);
        // (cos phi, sin phi) is the offset over its length: no atan2, sin and cos per ray.
        const double theta = r_px / m_circle_radius_px * m_half_fov_rad;
        const double sin_theta_over_r = std::sin(theta) / r_px;
        return Vec3(sin_theta_over_r * offset.x(), sin_theta_over_r * offset.y(), std::cos(theta));
    }
    const Eigen::Vector2d distorted = offset.cwiseQuotient(m_focal_px); // (x_d, y_d)
    const double theta_d = distorted.norm();
    if (theta_d > m_theta_d_max) return std::nullopt;
    if (theta_d == 0.0) return Vec3(0.0, 0.0, 1.0);
    const double theta = kb_theta(theta_d);
    const double scale = std::sin(theta) / theta_d;
    return Vec3(scale * distorted.x(), scale * distorted.y(), std::cos(theta));
}

std::optional<Eigen::Vector2d> FisheyeCamera::camera_project(const Vec3& p_mm) const {
    const double rho = std::hypot(p_mm.x(), p_mm.y());
    if (rho == 0.0 && p_mm.z() == 0.0) return std::nullopt;
    const double theta = std::atan2(rho, p_mm.z());
    if (theta > m_half_fov_rad) return std::nullopt;
    if (m_model == CameraModel::equidistant) {
        const double r_px = theta / m_half_fov_rad * m_circle_radius_px;
        const double phi = std::atan2(p_mm.y(), p_mm.x());
        return Eigen::Vector2d(m_centre_px.x() + r_px * std::cos(phi),
                               m_centre_px.y() + r_px * std::sin(phi));
    }
    const double theta_d = theta * kb_factor(m_k, theta * theta);
    // On the axis (rho = 0) any azimuth will do: theta_d is 0 there, or pi straight back.
    const Eigen::Vector2d distorted =
        rho > 0.0 ? Eigen::Vector2d(theta_d / rho * p_mm.x(), theta_d / rho * p_mm.y())
                  : Eigen::Vector2d(theta_d, 0.0);
    return Eigen::Vector2d(m_centre_px + m_focal_px.cwiseProduct(distorted));
}

double FisheyeCamera::kb_theta(double theta_d_rad) const {
    // Newton on f(theta) = theta_d(theta) - theta_d_rad, kept inside a bisection bracket. The
    // constructor checked that theta_d increases over [0, half_fov], so the root is unique
    // and the bracket [0, half_fov] holds it.
    double lo = 0.0, hi = m_half_fov_rad;
    double theta = std::min(theta_d_rad, m_half_fov_rad); // exact when k = 0
    for (int iteration = 0; iteration < 100; ++iteration) {
        const double s = theta * theta;
        const double f = theta * kb_factor(m_k, s) - theta_d_rad;
        if (f == 0.0) break;
        (f > 0.0 ? hi : lo) = theta;
        double next = theta - f / kb_slope(m_k, s);
        if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
        const bool converged = std::abs(next - theta) <= 1e-15 * std::max(theta, 1e-300);
        theta = next;
        if (converged || hi - lo <= 0.0) break;
    }
    return theta;
}

} // namespace chromasim::render
