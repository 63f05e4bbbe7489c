#include "mechanics/contact.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>

namespace chromasim::mechanics {

double safety_margin(double mu, double normal_force_N, double tangential_force_N) {
    const double strength = mu * normal_force_N;
    if (!(strength > 0)) return 0.0;
    return std::clamp((strength - tangential_force_N) / strength, 0.0, 1.0);
}

namespace {

using RowForces = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

/// Normal-direction system with prescribed force direction per unit normal force:
/// F_j = lambda_j * (tx, ty, -1). Unknowns (lambda_A, d). tx = ty = 0 is frictionless.
bool solve_directed(const Eigen::MatrixXd& C, const Eigen::VectorXd& gap, const std::vector<int>& A,
                    const Eigen::Vector2d& t, double P, RowForces& F, double& d) {
    const int m = int(A.size());
    Eigen::MatrixXd M = Eigen::MatrixXd::Zero(m + 1, m + 1);
    Eigen::VectorXd rhs(m + 1);
    for (int i = 0; i < m; ++i) {
        for (int j = 0; j < m; ++j) {
            const int zi = 3 * A[i] + 2, cj = 3 * A[j];
            M(i, j) = C(zi, cj) * t.x() + C(zi, cj + 1) * t.y() - C(zi, cj + 2);
        }
        M(i, m) = 1.0;
        rhs(i) = gap(A[i]);
        M(m, i) = 1.0;
    }
    rhs(m) = P;
    const Eigen::FullPivLU<Eigen::MatrixXd> lu(M);
    if (!lu.isInvertible()) return false;
    const Eigen::VectorXd x = lu.solve(rhs);
    F.setZero();
    for (int j = 0; j < m; ++j)
        F.row(A[j]) << x(j) * t.x(), x(j) * t.y(), -x(j);
    d = x(m);
    return true;
}

/// Tied tangential system: u_t,i - u0_t,i = s for i in A, normal as above, sum F_t = Q.
/// Unknowns (F_A (3m), s_x, s_y, d).
bool solve_tied(const Eigen::MatrixXd& C, const Eigen::VectorXd& gap, const std::vector<int>& A,
                const Eigen::VectorXd& u0, const Eigen::Vector2d& Q, double P, RowForces& F,
                double& d) {
    const int m = int(A.size()), n = 3 * m + 3;
    Eigen::MatrixXd M = Eigen::MatrixXd::Zero(n, n);
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(n);
    for (int i = 0; i < m; ++i)
        for (int k = 0; k < 3; ++k) {
            const int row = 3 * i + k;
            for (int j = 0; j < m; ++j)
                for (int l = 0; l < 3; ++l)
                    M(row, 3 * j + l) = C(3 * A[i] + k, 3 * A[j] + l);
            M(row, 3 * m + k) = k == 2 ? 1.0 : -1.0;
            rhs(row) = k == 2 ? gap(A[i]) : u0(3 * A[i] + k);
            M(3 * m + k, row) = 1.0;
        }
    rhs(3 * m + 0) = Q.x();
    rhs(3 * m + 1) = Q.y();
    rhs(3 * m + 2) = -P;
    const Eigen::FullPivLU<Eigen::MatrixXd> lu(M);
    if (!lu.isInvertible()) return false;
    const Eigen::VectorXd x = lu.solve(rhs);
    F.setZero();
    for (int j = 0; j < m; ++j)
        F.row(A[j]) = x.segment<3>(3 * j).transpose();
    d = x(3 * m + 2);
    return true;
}

/// One active-set loop: solve on A, drop nodes pulling on the object, add penetrating nodes.
template <class Solve>
bool active_set(const Eigen::MatrixXd& C, const Eigen::VectorXd& gap, std::vector<int>& A,
                Solve&& solve, RowForces& F, double& d, int max_iterations, int& iterations,
                std::string& status) {
    const int n = int(gap.size());
    for (int it = 0; it < max_iterations; ++it) {
        ++iterations;
        if (!solve(A, F, d)) {
            status = "singular";
            return false;
        }
        // Drop nodes with a tensile (negative) normal reaction.
        std::vector<int> kept;
        for (int j : A)
            if (-F(j, 2) >= 0.0) kept.push_back(j);
        if (kept.size() != A.size() && !kept.empty()) {
            A = std::move(kept);
            continue;
        }
        // Add nodes that penetrate the object: z-gap after deformation below zero.
        const Eigen::VectorXd u = C * Eigen::Map<const Eigen::VectorXd>(F.data(), 3 * n);
        const double tol = 1e-9 * std::max(1.0, std::abs(d));
        bool added = false;
        for (int i = 0; i < n; ++i)
            if (std::find(A.begin(), A.end(), i) == A.end() && gap(i) - d - u(3 * i + 2) < -tol) {
                A.push_back(i);
                added = true;
            }
        if (!added) return true;
        std::sort(A.begin(), A.end());
    }
    status = "max_iterations";
    return false;
}

} // namespace

ContactSolution solve_flat_contact(const Eigen::MatrixXd& C, const Eigen::VectorXd& gap_mm,
                                   const ContactLoad& load, int max_iterations) {
    const int n = int(gap_mm.size());
    ContactSolution sol;
    sol.forces_N = RowForces::Zero(n, 3);
    Eigen::Index first = 0;
    gap_mm.minCoeff(&first);
    std::vector<int> A{int(first)};
    const double P = load.normal_force_N;

    // 1. Frictionless normal problem (also the reference state of the tangential step).
    auto frictionless = [&](const std::vector<int>& act, RowForces& F, double& d) {
        return solve_directed(C, gap_mm, act, Eigen::Vector2d::Zero(), P, F, d);
    };
    sol.converged = active_set(C, gap_mm, A, frictionless, sol.forces_N, sol.indentation_mm,
                               max_iterations, sol.iterations, sol.status);
    const double Q = load.tangential_force_N.norm();
    if (sol.converged && Q > 0) {
        const Eigen::Vector2d dir = load.tangential_force_N / Q;
        sol.sliding = Q >= load.mu * P;
        if (sol.sliding) {
            // 2a. Full slip: every contact force leans by mu along the pull.
            const Eigen::Vector2d t = load.mu * dir;
            auto slide = [&](const std::vector<int>& act, RowForces& F, double& d) {
                return solve_directed(C, gap_mm, act, t, P, F, d);
            };
            sol.converged = active_set(C, gap_mm, A, slide, sol.forces_N, sol.indentation_mm,
                                       max_iterations, sol.iterations, sol.status);
        } else {
            // 2b. Stick: the patch moves as one relative to the frictionless state.
            const Eigen::VectorXd u0 =
                C * Eigen::Map<const Eigen::VectorXd>(sol.forces_N.data(), 3 * n);
            auto tied = [&](const std::vector<int>& act, RowForces& F, double& d) {
                return solve_tied(C, gap_mm, act, u0, load.tangential_force_N, P, F, d);
            };
            sol.converged = active_set(C, gap_mm, A, tied, sol.forces_N, sol.indentation_mm,
                                       max_iterations, sol.iterations, sol.status);
        }
    }
    sol.active = A;
    sol.normal_force_N = -sol.forces_N.col(2).sum();
    sol.tangential_force_N = sol.forces_N.leftCols<2>().colwise().sum().transpose();
    sol.gamma = sol.sliding
                    ? 0.0
                    : safety_margin(load.mu, sol.normal_force_N, sol.tangential_force_N.norm());
    return sol;
}

} // namespace chromasim::mechanics
