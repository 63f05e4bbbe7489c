#include "mechanics/half_space.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <numbers>

using namespace chromasim::mechanics;

namespace {

constexpr double kE = 1.0, kNu = 0.3;

/// Stress (MPa) at X under force F, from central differences of the displacement.
Eigen::Matrix3d stress(const Eigen::Vector3d& X, const Eigen::Vector3d& F, double h) {
    Eigen::Matrix3d grad; // grad(i, j) = d u_i / d x_j
    for (int j = 0; j < 3; ++j) {
        const Eigen::Vector3d dx = h * Eigen::Vector3d::Unit(j);
        grad.col(j) =
            (half_space_green(X + dx, kE, kNu) * F - half_space_green(X - dx, kE, kNu) * F) /
            (2 * h);
    }
    const Eigen::Matrix3d eps = 0.5 * (grad + grad.transpose());
    const double G = kE / (2 * (1 + kNu)), lambda = kE * kNu / ((1 + kNu) * (1 - 2 * kNu));
    return lambda * eps.trace() * Eigen::Matrix3d::Identity() + 2 * G * eps;
}

} // namespace

// The stresses also balance the applied force and give the familiar surface values.
TEST_CASE("half-space point force: equilibrium inside and no traction on the surface",
          "[mechanics][half_space]") {
    for (const Eigen::Vector3d& F :
         {Eigen::Vector3d(0, 0, -1), Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0, 1, 0)}) {
        INFO("force " << F.transpose());
        // div sigma = 0 at interior points (nested central differences).
        for (const Eigen::Vector3d& X :
             {Eigen::Vector3d(1.0, 0.5, -2.0), Eigen::Vector3d(-2.0, 1.5, -0.7),
              Eigen::Vector3d(0.3, -1.2, -3.0)}) {
            const double h = 1e-3, scale = stress(X, F, 1e-5).norm() / X.norm();
            Eigen::Vector3d div = Eigen::Vector3d::Zero();
            for (int j = 0; j < 3; ++j) {
                const Eigen::Vector3d dx = h * Eigen::Vector3d::Unit(j);
                div += (stress(X + dx, F, 1e-5) - stress(X - dx, F, 1e-5)).col(j) / (2 * h);
            }
            CHECK(div.norm() < 1e-4 * scale);
        }
        // Traction-free surface away from the load: sigma_xz = sigma_yz = sigma_zz = 0.
        for (const Eigen::Vector3d& X :
             {Eigen::Vector3d(1.0, 0.5, -1e-4), Eigen::Vector3d(-2.0, -1.0, -1e-4)}) {
            const Eigen::Matrix3d s = stress(X, F, 1e-5);
            CHECK(s.col(2).norm() < 1e-3 * s.norm());
        }
        // Force balance of a hemisphere of radius R around the load: the traction of the
        // outside on it cancels F (midpoint rule on the hemisphere).
        const double R = 5.0;
        const int nt = 120, np = 240;
        Eigen::Vector3d total = F;
        for (int i = 0; i < nt; ++i)
            for (int k = 0; k < np; ++k) {
                const double theta = 0.5 * std::numbers::pi * (i + 0.5) / nt; // from -z
                const double phi = 2 * std::numbers::pi * (k + 0.5) / np;
                const Eigen::Vector3d n(std::sin(theta) * std::cos(phi),
                                        std::sin(theta) * std::sin(phi), -std::cos(theta));
                const double dA = R * R * std::sin(theta) * (0.5 * std::numbers::pi / nt) *
                                  (2 * std::numbers::pi / np);
                total += stress(R * n, F, 1e-5) * n * dA;
            }
        CHECK(total.norm() < 2e-3 * F.norm());
    }
    // Surface values (Johnson 3.2): under P the surface sinks by (1 - nu^2) P / (pi E r) and
    // moves towards the load by (1 - 2 nu)(1 + nu) P / (2 pi E r).
    const double r = 2.0;
    const Eigen::Vector3d u = half_space_green({r, 0, 0}, kE, kNu) * Eigen::Vector3d(0, 0, -1);
    CHECK(u.z() == Approx(-(1 - kNu * kNu) / (std::numbers::pi * kE * r)).epsilon(1e-12));
    CHECK(u.x() ==
          Approx(-(1 - 2 * kNu) * (1 + kNu) / (2 * std::numbers::pi * kE * r)).epsilon(1e-12));
    CHECK(u.y() == 0.0);
    // Reciprocity (Betti) between two surface points A and B: G(B - A) = G(A - B)^T.
    const Eigen::Vector3d d(1.3, -0.4, 0.0);
    CHECK((half_space_green(d, kE, kNu) - half_space_green(-d, kE, kNu).transpose()).norm() <
          1e-12 * half_space_green(d, kE, kNu).norm());
    CHECK_THROWS_AS(half_space_green({1, 0, 0.1}, kE, kNu), std::invalid_argument);
}
