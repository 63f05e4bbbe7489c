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

/// Frictionless normal system: F_j = (0, 0, -lambda_j). Unknowns (lambda_A, d).
bool solve_normal(const Eigen::MatrixXd& C, const Eigen::VectorXd& gap, const std::vector<int>& A,
                  double P, RowForces& F, double& d) {
    const int m = int(A.size());
    Eigen::MatrixXd M = Eigen::MatrixXd::Zero(m + 1, m + 1);
    Eigen::VectorXd rhs(m + 1);
    for (int i = 0; i < m; ++i) {
        for (int j = 0; j < m; ++j)
            M(i, j) = -C(3 * A[i] + 2, 3 * A[j] + 2);
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
        F(A[j], 2) = -x(j);
    d = x(m);
    return true;
}

/// Tied tangential tractions on the contact set A: C_tt t = s on every node of A (the same
/// tangential offset), sum t = Q. Unknowns (t_A (2m), s_x, s_y); writes F's x, y columns.
bool solve_tied(const Eigen::MatrixXd& C, const std::vector<int>& A, const Eigen::Vector2d& Q,
                RowForces& F) {
    const int m = int(A.size()), n = 2 * m + 2;
    Eigen::MatrixXd M = Eigen::MatrixXd::Zero(n, n);
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(n);
    for (int i = 0; i < m; ++i)
        for (int k = 0; k < 2; ++k) {
            const int row = 2 * i + k;
            for (int j = 0; j < m; ++j)
                for (int l = 0; l < 2; ++l)
                    M(row, 2 * j + l) = C(3 * A[i] + k, 3 * A[j] + l);
            M(row, 2 * m + k) = -1.0;
            M(2 * m + k, row) = 1.0;
        }
    rhs(2 * m + 0) = Q.x();
    rhs(2 * m + 1) = Q.y();
    const Eigen::FullPivLU<Eigen::MatrixXd> lu(M);
    if (!lu.isInvertible()) return false;
    const Eigen::VectorXd x = lu.solve(rhs);
    for (int j = 0; j < m; ++j)
        F.row(A[j]).head<2>() = x.segment<2>(2 * j).transpose();
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

    // 1. Frictionless normal problem: contact set, normal forces, indentation.
    auto normal = [&](const std::vector<int>& act, RowForces& F, double& d) {
        return solve_normal(C, gap_mm, act, P, F, d);
    };
    sol.converged = active_set(C, gap_mm, A, normal, sol.forces_N, sol.indentation_mm,
                               max_iterations, sol.iterations, sol.status);
    sol.active = A;

    // 2. Tangential tractions on that contact set: tied below mu P, full slip at or above.
    const double Q = load.tangential_force_N.norm();
    if (sol.converged && Q > 0) {
        sol.sliding = Q >= load.mu * P;
        if (sol.sliding) {
            const Eigen::Vector2d t = load.mu * load.tangential_force_N / Q;
            for (int j : A)
                sol.forces_N.row(j).head<2>() = -sol.forces_N(j, 2) * t.transpose();
        } else if (!solve_tied(C, A, load.tangential_force_N, sol.forces_N)) {
            sol.converged = false;
            sol.status = "singular";
        }
    }
    sol.normal_force_N = -sol.forces_N.col(2).sum();
    sol.tangential_force_N = sol.forces_N.leftCols<2>().colwise().sum().transpose();
    sol.gamma = sol.sliding
                    ? 0.0
                    : safety_margin(load.mu, sol.normal_force_N, sol.tangential_force_N.norm());
    return sol;
}

} // namespace chromasim::mechanics
