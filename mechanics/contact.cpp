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

Eigen::VectorXd
object_gap(const ObjectShape& object,
           const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>& X) {
    constexpr double kUnreachable_mm = 1e3;
    const Eigen::Index n = X.rows();
    Eigen::VectorXd h = Eigen::VectorXd::Zero(n); // object surface height above its lowest point
    if (object.kind == ObjectShape::Kind::sphere) {
        const double R = object.radius_mm;
        for (Eigen::Index i = 0; i < n; ++i) {
            const double r2 = X(i, 0) * X(i, 0) + X(i, 1) * X(i, 1);
            h(i) = r2 < R * R ? R - std::sqrt(R * R - r2) : kUnreachable_mm;
        }
    }
    const Eigen::VectorXd g = h - X.col(2);
    return g.array() - g.minCoeff();
}

namespace {

using RowForces = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

/// Frictionless normal system: F_j = (0, 0, -lambda_j), C_zz lambda = d - gap on A,
/// sum lambda = P. C_zz restricted to A is symmetric positive definite (a compliance), so
/// eliminate d: lambda = C^-1 (d 1 - gap), d = (P + 1' C^-1 gap) / (1' C^-1 1).
bool solve_normal(const Eigen::MatrixXd& C, const Eigen::VectorXd& gap, const std::vector<int>& A,
                  double P, RowForces& F, double& d) {
    const int m = int(A.size());
    Eigen::MatrixXd Czz(m, m);
    Eigen::VectorXd g(m);
    for (int i = 0; i < m; ++i) {
        for (int j = 0; j < m; ++j)
            Czz(i, j) = C(3 * A[i] + 2, 3 * A[j] + 2);
        g(i) = gap(A[i]);
    }
    const Eigen::LLT<Eigen::MatrixXd> llt(Czz);
    if (llt.info() != Eigen::Success) return false;
    const Eigen::VectorXd c1 = llt.solve(Eigen::VectorXd::Ones(m));
    const Eigen::VectorXd cg = llt.solve(g);
    d = (P + cg.sum()) / c1.sum();
    const Eigen::VectorXd lambda = d * c1 - cg;
    F.setZero();
    for (int j = 0; j < m; ++j)
        F(A[j], 2) = -lambda(j);
    return std::isfinite(d);
}

/// The tangential (x, y) block of C between candidate sets `rows` and `cols`.
Eigen::MatrixXd tangential_block(const Eigen::MatrixXd& C, const std::vector<int>& rows,
                                 const std::vector<int>& cols) {
    Eigen::MatrixXd B(2 * rows.size(), 2 * cols.size());
    for (std::size_t i = 0; i < rows.size(); ++i)
        for (std::size_t j = 0; j < cols.size(); ++j)
            B.block<2, 2>(2 * Eigen::Index(i), 2 * Eigen::Index(j)) =
                C.block<2, 2>(3 * rows[i], 3 * cols[j]);
    return B;
}

Eigen::VectorXd stacked_tangential(const RowForces& F, const std::vector<int>& nodes) {
    Eigen::VectorXd t(2 * nodes.size());
    for (std::size_t j = 0; j < nodes.size(); ++j)
        t.segment<2>(2 * Eigen::Index(j)) = F.row(nodes[j]).head<2>().transpose();
    return t;
}

/// Stick set S shares one tangential offset s from the frictionless state; slip set L carries
/// mu lambda along q: C_SS t_S + C_SL t_L = E s, sum t_S = Q - sum t_L. With C_SS SPD,
/// t_S = C_SS^-1 (E s - C_SL t_L) and s solves a 2 x 2 system. Writes t_S into F; returns s.
bool solve_stick_set(const Eigen::MatrixXd& C, const std::vector<int>& S, const std::vector<int>& L,
                     const Eigen::Vector2d& Q, RowForces& F, Eigen::Vector2d& s) {
    const Eigen::Index m = Eigen::Index(S.size());
    Eigen::MatrixXd E = Eigen::MatrixXd::Zero(2 * m, 2);
    for (Eigen::Index i = 0; i < m; ++i)
        E.block<2, 2>(2 * i, 0).setIdentity();
    const Eigen::LLT<Eigen::MatrixXd> llt(tangential_block(C, S, S));
    if (llt.info() != Eigen::Success) return false;
    const Eigen::VectorXd tL = stacked_tangential(F, L);
    const Eigen::VectorXd r = L.empty()
                                  ? Eigen::VectorXd::Zero(2 * m)
                                  : Eigen::VectorXd(llt.solve(tangential_block(C, S, L) * tL));
    const Eigen::MatrixXd CE = llt.solve(E);
    Eigen::Vector2d rhs = Q + E.transpose() * r;
    for (std::size_t j = 0; j < L.size(); ++j)
        rhs -= tL.segment<2>(2 * Eigen::Index(j));
    s = (E.transpose() * CE).ldlt().solve(rhs);
    const Eigen::VectorXd tS = CE * s - r;
    for (Eigen::Index j = 0; j < m; ++j)
        F.row(S[std::size_t(j)]).head<2>() = tS.segment<2>(2 * j).transpose();
    return tS.allFinite();
}

/// Cattaneo-Mindlin partial slip under a tangential load Q < mu P, applied monotonically
/// along q = Q / |Q| with the normal forces unchanged (Goodman). Nodes whose stick traction
/// would exceed mu lambda slip (traction mu lambda q); the slip set only grows, as under a
/// monotonic load, so the loop ends after at most #A rounds. `slipping` receives the nodes
/// of A that slip.
bool solve_partial_slip(const Eigen::MatrixXd& C, const std::vector<int>& A,
                        const Eigen::Vector2d& Q, double mu, RowForces& F,
                        std::vector<int>& slipping, int& iterations) {
    const Eigen::Vector2d q = Q.normalized();
    std::vector<bool> slip(A.size(), false);
    for (std::size_t round = 0; round <= A.size(); ++round) {
        ++iterations;
        std::vector<int> S, L;
        for (std::size_t k = 0; k < A.size(); ++k) {
            (slip[k] ? L : S).push_back(A[k]);
            if (slip[k]) F.row(A[k]).head<2>() = mu * -F(A[k], 2) * q.transpose();
        }
        Eigen::Vector2d s;
        if (S.empty() || !solve_stick_set(C, S, L, Q, F, s)) return false;
        bool changed = false;
        for (std::size_t k = 0; k < A.size(); ++k)
            if (!slip[k] && F.row(A[k]).head<2>().norm() > mu * -F(A[k], 2) * (1 + 1e-9))
                slip[k] = changed = true;
        if (!changed) {
            slipping = L;
            return true;
        }
    }
    return false;
}

/// Active set on the frictionless normal problem: solve on A, drop nodes pulling on the
/// object, add every node that penetrates it; until neither happens.
bool normal_active_set(const Eigen::MatrixXd& C, const Eigen::VectorXd& gap, double P,
                       std::vector<int>& A, RowForces& F, double& d, int max_iterations,
                       int& iterations, std::string& status) {
    const int n = int(gap.size());
    std::vector<bool> in_A(std::size_t(n), false);
    for (int it = 0; it < max_iterations; ++it) {
        ++iterations;
        if (!solve_normal(C, gap, A, P, F, d)) {
            status = "singular";
            return false;
        }
        std::vector<int> kept;
        for (int j : A)
            if (-F(j, 2) >= 0.0) kept.push_back(j);
        if (kept.size() != A.size() && !kept.empty()) {
            A = std::move(kept);
            continue;
        }
        std::fill(in_A.begin(), in_A.end(), false);
        for (int j : A)
            in_A[std::size_t(j)] = true;
        // Normal displacement of every candidate under the current forces (z rows only).
        Eigen::VectorXd uz = Eigen::VectorXd::Zero(n);
        for (int j : A)
            for (int i = 0; i < n; ++i)
                uz(i) += C(3 * i + 2, 3 * j + 2) * F(j, 2);
        const double tol = 1e-9 * std::max(1.0, std::abs(d));
        bool added = false;
        for (int i = 0; i < n; ++i)
            if (!in_A[std::size_t(i)] && gap(i) - d - uz(i) < -tol) {
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

ContactSolution solve_contact(const Eigen::MatrixXd& C, const Eigen::VectorXd& gap_mm,
                              const ContactLoad& load, int max_iterations) {
    const int n = int(gap_mm.size());
    ContactSolution sol;
    sol.forces_N = RowForces::Zero(n, 3);
    Eigen::Index first = 0;
    gap_mm.minCoeff(&first);
    std::vector<int> A{int(first)};
    const double P = load.normal_force_N;

    // 1. Frictionless normal problem: contact set, normal forces, indentation.
    sol.converged = normal_active_set(C, gap_mm, P, A, sol.forces_N, sol.indentation_mm,
                                      max_iterations, sol.iterations, sol.status);
    sol.active = A;

    // 2. Tangential tractions on that contact set: partial slip below mu P, full slip at or
    //    above.
    const double Q = load.tangential_force_N.norm();
    if (sol.converged && Q > 0) {
        sol.sliding = Q >= load.mu * P;
        if (sol.sliding) {
            const Eigen::Vector2d t = load.mu * load.tangential_force_N / Q;
            for (int j : A)
                sol.forces_N.row(j).head<2>() = -sol.forces_N(j, 2) * t.transpose();
            sol.slipping = A;
        } else if (!solve_partial_slip(C, A, load.tangential_force_N, load.mu, sol.forces_N,
                                       sol.slipping, sol.iterations)) {
            sol.converged = false;
            sol.status = "stick_slip_not_converged";
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
