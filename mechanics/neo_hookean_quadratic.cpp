#include "mechanics/neo_hookean_quadratic.hpp"

#include "mechanics/neo_hookean_law.hpp"

#include <Eigen/Dense>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace chromasim::mechanics {

namespace {

using namespace neo_hookean_law;
using Vector30d = Eigen::Matrix<double, 30, 1>;

template <class Body> void parallel_for_each(Eigen::Index n, Body&& body) {
    tbb::parallel_for(tbb::blocked_range<Eigen::Index>(0, n), [&](const auto& range) {
        for (Eigen::Index i = range.begin(); i != range.end(); ++i)
            body(i);
    });
}

void require_positive(double jm1) {
    if (!(1 + jm1 > 0))
        throw std::domain_error("neo-Hookean: J <= 0 at a quadrature point (inverted element)");
}

/// w B^T A B for one quadrature point, B = dvec(F)/dx: block (a, b) is
/// sum_jl G(a, j) G(b, l) A_jl with A_jl the 3 x 3 blocks of A.
void add_point_matrix(const Matrix9d& A, const Gradients10& G, double w, Matrix30d& K) {
    Eigen::Matrix<double, 30, 9> GA;
    for (int a = 0; a < 10; ++a)
        GA.middleRows<3>(3 * a) = G(a, 0) * A.middleRows<3>(0) + G(a, 1) * A.middleRows<3>(3) +
                                  G(a, 2) * A.middleRows<3>(6);
    for (int b = 0; b < 10; ++b)
        K.middleCols<3>(3 * b) +=
            w * (G(b, 0) * GA.middleCols<3>(0) + G(b, 1) * GA.middleCols<3>(3) +
                 G(b, 2) * GA.middleCols<3>(6));
}

/// Clamps the negative eigenvalues of a symmetric 9 x 9 matrix to zero.
void project_to_psd(Matrix9d& A) {
    const Eigen::SelfAdjointEigenSolver<Matrix9d> eig(A);
    if (eig.eigenvalues()(0) >= 0) return;
    A = eig.eigenvectors() * eig.eigenvalues().cwiseMax(0.0).asDiagonal() *
        eig.eigenvectors().transpose();
}

} // namespace

NeoHookeanQuadratic::NeoHookeanQuadratic(const TetMesh& mesh,
                                         const std::vector<Material>& materials)
    : m_nodes(int(mesh.V.rows())), m_T(mesh.T10), m_geometry(quadratic_geometry(mesh)) {
    const Eigen::Index tets = m_T.rows();
    m_mu.resize(std::size_t(tets));
    m_kappa.resize(std::size_t(tets));
    for (Eigen::Index t = 0; t < tets; ++t) {
        const int r = mesh.region(t) - 1;
        if (r < 0 || r >= int(materials.size()))
            throw std::runtime_error("neo-Hookean: tet region without material");
        const Material& m = materials[std::size_t(r)];
        m_mu[std::size_t(t)] = m.E_MPa / (2 * (1 + m.nu));
        m_kappa[std::size_t(t)] = m.E_MPa / (3 * (1 - 2 * m.nu));
    }
}

Eigen::Matrix3d NeoHookeanQuadratic::displacement_gradient(const Eigen::VectorXd& u, int t,
                                                           int q) const {
    const Gradients10& G = m_geometry.gradients[std::size_t(4 * t + q)];
    Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
    for (int i = 0; i < 10; ++i)
        H.noalias() += u.segment<3>(3 * m_T(t, i)) * G.row(i);
    return H;
}

double NeoHookeanQuadratic::energy(const Eigen::VectorXd& u) const {
    std::vector<double> per_tet(std::size_t(m_T.rows()));
    parallel_for_each(m_T.rows(), [&](Eigen::Index t) {
        double e = 0;
        for (int q = 0; q < 4; ++q) {
            const Kinematics k = from_displacement_gradient(displacement_gradient(u, int(t), q));
            if (!(1 + k.jm1 > 0)) {
                e = std::numeric_limits<double>::infinity();
                break;
            }
            const std::size_t i = std::size_t(t);
            e += m_geometry.weight[std::size_t(4 * t + q)] *
                 (isochoric_density(k, m_mu[i]) + 0.5 * m_kappa[i] * k.jm1 * k.jm1);
        }
        per_tet[std::size_t(t)] = e;
    });
    double total = 0;
    for (double e : per_tet)
        total += e;
    return total;
}

Eigen::VectorXd NeoHookeanQuadratic::gradient(const Eigen::VectorXd& u) const {
    double lowest = 0;
    Eigen::VectorXd g = gradient(u, lowest);
    require_positive(lowest - 1);
    return g;
}

Eigen::VectorXd NeoHookeanQuadratic::gradient(const Eigen::VectorXd& u,
                                              double& min_jacobian) const {
    std::vector<Vector30d> per_tet(std::size_t(m_T.rows()));
    std::vector<double> lowest(std::size_t(m_T.rows()));
    parallel_for_each(m_T.rows(), [&](Eigen::Index t) {
        Vector30d g = Vector30d::Zero();
        const std::size_t i = std::size_t(t);
        double j_min = std::numeric_limits<double>::infinity();
        for (int q = 0; q < 4; ++q) {
            const Kinematics k = from_displacement_gradient(displacement_gradient(u, int(t), q));
            const double J = 1 + k.jm1;
            if (!(J > 0)) { // inverted (or NaN): no gradient
                j_min = std::isnan(J) ? -std::numeric_limits<double>::infinity() : J;
                break;
            }
            j_min = std::min(j_min, J);
            const Gradients10& G = m_geometry.gradients[std::size_t(4 * t + q)];
            const Eigen::Matrix3d P = m_geometry.weight[std::size_t(4 * t + q)] *
                                      first_piola(k, m_mu[i], m_kappa[i] * k.jm1);
            for (int a = 0; a < 10; ++a)
                g.segment<3>(3 * a).noalias() += P * G.row(a).transpose();
        }
        per_tet[i] = g;
        lowest[i] = j_min;
    });
    min_jacobian = *std::min_element(lowest.begin(), lowest.end());
    if (!(min_jacobian > 0)) return {};
    Eigen::VectorXd out = Eigen::VectorXd::Zero(dofs());
    for (Eigen::Index t = 0; t < m_T.rows(); ++t)
        for (int a = 0; a < 10; ++a)
            out.segment<3>(3 * m_T(t, a)) += per_tet[std::size_t(t)].segment<3>(3 * a);
    return out;
}

Eigen::SparseMatrix<double> NeoHookeanQuadratic::hessian(const Eigen::VectorXd& u,
                                                         bool project_psd) const {
    std::vector<Matrix30d> per_tet(std::size_t(m_T.rows()));
    parallel_for_each(m_T.rows(), [&](Eigen::Index t) {
        Matrix30d& K = per_tet[std::size_t(t)];
        K.setZero();
        const std::size_t i = std::size_t(t);
        for (int q = 0; q < 4; ++q) {
            const Kinematics k = from_displacement_gradient(displacement_gradient(u, int(t), q));
            require_positive(k.jm1);
            Matrix9d A = stress_derivative(k, m_mu[i], m_kappa[i] * k.jm1, m_kappa[i]);
            if (project_psd && may_be_indefinite(A)) project_to_psd(A);
            add_point_matrix(A, m_geometry.gradients[std::size_t(4 * t + q)],
                             m_geometry.weight[std::size_t(4 * t + q)], K);
        }
    });
    return sum_element_matrices(m_T, m_nodes, per_tet);
}

double NeoHookeanQuadratic::min_jacobian(const Eigen::VectorXd& u) const {
    std::vector<double> per_tet(std::size_t(m_T.rows()));
    parallel_for_each(m_T.rows(), [&](Eigen::Index t) {
        double lowest = std::numeric_limits<double>::infinity();
        for (int q = 0; q < 4; ++q)
            lowest = std::min(
                lowest, 1 + from_displacement_gradient(displacement_gradient(u, int(t), q)).jm1);
        per_tet[std::size_t(t)] = lowest;
    });
    return *std::min_element(per_tet.begin(), per_tet.end());
}

} // namespace chromasim::mechanics
