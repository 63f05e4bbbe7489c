#include "mechanics/hertz.hpp"

#include <Eigen/Dense>

#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>

namespace chromasim::mechanics {

HertzSolution hertz(double P, double R, double E, double nu) {
    const double E_star = E / (1 - nu * nu);
    HertzSolution h;
    h.a_mm = std::cbrt(3 * P * R / (4 * E_star));
    h.delta_mm = h.a_mm * h.a_mm / R;
    h.p0_MPa = 3 * P / (2 * std::numbers::pi * h.a_mm * h.a_mm);
    return h;
}

double mindlin_stick_radius(double a, double Q, double mu, double P) {
    const double ratio = Q / (mu * P);
    return ratio >= 1 ? 0.0 : a * std::cbrt(1 - ratio);
}

double boussinesq_axis_displacement(double P, double E, double nu, double z) {
    return P * (1 + nu) * (3 - 2 * nu) / (2 * std::numbers::pi * E * z);
}

ContactFit fit_hertz_profile(const Points& X, const std::vector<double>& area,
                             const ContactSolution& contact) {
    ContactFit fit;
    double total_area = 0;
    for (int j : contact.active)
        total_area += area[std::size_t(j)];
    fit.area_radius_mm = std::sqrt(total_area / std::numbers::pi);
    // Rows (1, r^2) -> p^2, over the inner contact nodes (edge nodes' tributary areas straddle
    // the contact boundary and understate their pressure).
    std::vector<std::array<double, 2>> rows;
    std::vector<double> rhs;
    for (int j : contact.active) {
        const double r2 = X(j, 0) * X(j, 0) + X(j, 1) * X(j, 1);
        if (r2 > std::pow(0.85 * fit.area_radius_mm, 2)) continue;
        const double p = -contact.forces_N(j, 2) / area[std::size_t(j)];
        rows.push_back({1.0, r2});
        rhs.push_back(p * p);
    }
    fit.nodes_used = int(rows.size());
    if (rows.size() < 3) return fit;
    Eigen::MatrixXd A(rows.size(), 2);
    Eigen::VectorXd b(rows.size());
    for (std::size_t i = 0; i < rows.size(); ++i) {
        A.row(Eigen::Index(i)) << rows[i][0], rows[i][1];
        b(Eigen::Index(i)) = rhs[i];
    }
    const Eigen::Vector2d c = A.colPivHouseholderQr().solve(b);
    if (c(0) > 0 && c(1) < 0) {
        fit.p0_MPa = std::sqrt(c(0));
        fit.a_mm = std::sqrt(-c(0) / c(1));
    }
    return fit;
}

double fit_mindlin_stick_radius(const Points& X, const std::vector<double>& area,
                                const ContactSolution& contact, double a, double p0, double mu) {
    std::vector<std::pair<double, double>> samples; // (r, measured traction)
    for (int j : contact.active) {
        const double r = std::hypot(X(j, 0), X(j, 1));
        if (r > 0.85 * a) continue;
        samples.emplace_back(r, contact.forces_N.row(j).head<2>().norm() / area[std::size_t(j)]);
    }
    auto model = [&](double r, double c) {
        const double outer = std::sqrt(std::max(0.0, a * a - r * r));
        const double inner = r < c ? std::sqrt(c * c - r * r) : 0.0;
        return mu * p0 / a * (outer - inner);
    };
    double best_c = 0, best_sse = std::numeric_limits<double>::infinity();
    for (int k = 0; k <= 1000; ++k) {
        const double c = a * k / 1000.0;
        double sse = 0;
        for (const auto& [r, q] : samples)
            sse += std::pow(q - model(r, c), 2);
        if (sse < best_sse) {
            best_sse = sse;
            best_c = c;
        }
    }
    return best_c;
}

double stick_area_radius(const std::vector<double>& area, const ContactSolution& contact) {
    double total = 0;
    for (int j : contact.active)
        total += area[std::size_t(j)];
    for (int j : contact.slipping)
        total -= area[std::size_t(j)];
    return std::sqrt(std::max(0.0, total) / std::numbers::pi);
}

} // namespace chromasim::mechanics
