#include "mechanics/half_space.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>

namespace chromasim::mechanics {

Eigen::Matrix3d half_space_green(const Eigen::Vector3d& X, double E_MPa, double nu) {
    // Johnson's formulas take the depth z positive into the solid; ours is -X.z().
    const double x = X.x(), y = X.y(), z = -X.z();
    const double rho = X.norm();
    if (!(z >= 0) || !(rho > 0))
        throw std::invalid_argument("half_space_green: the point must lie in z <= 0, not at the "
                                    "loaded origin");
    const double c = (1 + nu) / (2 * std::numbers::pi * E_MPa); // 1 / (4 pi G)
    const double m = 1 - 2 * nu;
    const double rho3 = rho * rho * rho, rz = rho + z;
    Eigen::Matrix3d G; // columns: force along x, y, z; rows: displacement x, y, z (ours)
    // Cerruti, force Q along x (Johnson eq. 3.86 with the depth axis into the solid).
    const auto cerruti = [&](double a, double b) { // a: along the force, b: across it
        const double ua = c * (1 / rho + a * a / rho3 + m * (1 / rz - a * a / (rho * rz * rz)));
        const double ub = c * (a * b / rho3 - m * a * b / (rho * rz * rz));
        const double uz = c * (a * z / rho3 + m * a / (rho * rz)); // into the solid
        return Eigen::Vector3d(ua, ub, uz);
    };
    const Eigen::Vector3d cx = cerruti(x, y), cy = cerruti(y, x);
    G.col(0) << cx(0), cx(1), -cx(2);
    G.col(1) << cy(1), cy(0), -cy(2);
    // Boussinesq, normal force P pressing into the solid (Johnson eq. 3.20): radial u_r
    // (outward) and u_z (into the solid). Our force F_z = -P, so the column is for P = -1.
    const double ur_over_r = c * (z / rho3 - m / (rho * rz)); // u_r / r, finite on the axis
    const double uz = c * (2 * (1 - nu) / rho + z * z / rho3);
    G.col(2) << -ur_over_r * x, -ur_over_r * y, uz;
    return G;
}

} // namespace chromasim::mechanics
