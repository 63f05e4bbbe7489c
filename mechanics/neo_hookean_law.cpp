#include "mechanics/neo_hookean_law.hpp"

#include <Eigen/Dense>

#include <cmath>

namespace chromasim::mechanics::neo_hookean_law {

namespace {

using Vector9d = Eigen::Matrix<double, 9, 1>;

Eigen::Matrix3d cross_matrix(const Eigen::Vector3d& v) {
    Eigen::Matrix3d S;
    S << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
    return S;
}

/// Second derivative of det F in vec(F) (column-major): blocks -+[f_k]x off the diagonal.
Matrix9d det_hessian(const Eigen::Matrix3d& F) {
    const Eigen::Matrix3d S0 = cross_matrix(F.col(0)), S1 = cross_matrix(F.col(1)),
                          S2 = cross_matrix(F.col(2));
    Matrix9d H = Matrix9d::Zero();
    H.block<3, 3>(0, 3) = -S2;
    H.block<3, 3>(3, 0) = S2;
    H.block<3, 3>(0, 6) = S1;
    H.block<3, 3>(6, 0) = -S1;
    H.block<3, 3>(3, 6) = -S0;
    H.block<3, 3>(6, 3) = S0;
    return H;
}

/// Derivatives of the isochoric density psi(I1, J) = mu/2 (J^(-2/3) I1 - 3).
struct InvariantDerivatives {
    double i1, j, i1j, jj;
};

InvariantDerivatives invariant_derivatives(const Kinematics& k, double mu) {
    const double J = 1 + k.jm1, I1 = 3 + k.i1m3;
    const double jm23 = std::exp(-2.0 / 3.0 * std::log1p(k.jm1));
    return {0.5 * mu * jm23, -mu / 3 * I1 * jm23 / J, -mu / 3 * jm23 / J,
            5 * mu / 9 * I1 * jm23 / (J * J)};
}

} // namespace

/// cof F = J F^-T, column by column.
Eigen::Matrix3d cofactor(const Eigen::Matrix3d& F) {
    Eigen::Matrix3d C;
    C.col(0) = F.col(1).cross(F.col(2));
    C.col(1) = F.col(2).cross(F.col(0));
    C.col(2) = F.col(0).cross(F.col(1));
    return C;
}

Kinematics from_displacement_gradient(const Eigen::Matrix3d& H) {
    const double tr = H.trace();
    Kinematics k;
    k.F = Eigen::Matrix3d::Identity() + H;
    k.jm1 = tr + 0.5 * (tr * tr - (H * H).trace()) + H.determinant();
    k.i1m3 = 2 * tr + H.squaredNorm();
    return k;
}

/// mu/2 (J^(-2/3) I1 - 3) written as mu/2 J^(-2/3) ((I1 - 3) - 3 (J^(2/3) - 1)).
double isochoric_density(const Kinematics& k, double mu) {
    const double j23m1 = std::expm1(2.0 / 3.0 * std::log1p(k.jm1));
    return 0.5 * mu * (k.i1m3 - 3 * j23m1) / (1 + j23m1);
}

/// First Piola-Kirchhoff stress (MPa) of the isochoric part plus the pressure p: dpsi/dF + p
/// dJ/dF.
Eigen::Matrix3d first_piola(const Kinematics& k, double mu, double p) {
    const InvariantDerivatives d = invariant_derivatives(k, mu);
    return 2 * d.i1 * k.F + (d.j + p) * cofactor(k.F);
}

/// d^2/dF^2 of psi + p J (p held fixed) + bulk/2 (J - 1)^2 about the current J, in vec(F).
Matrix9d stress_derivative(const Kinematics& k, double mu, double p, double bulk) {
    const InvariantDerivatives d = invariant_derivatives(k, mu);
    const Eigen::Matrix3d C = cofactor(k.F);
    const Eigen::Map<const Vector9d> f(k.F.data()), c(C.data());
    Matrix9d A = (d.j + p) * det_hessian(k.F);
    A.diagonal().array() += 2 * d.i1;
    A.noalias() += 2 * d.i1j * (f * c.transpose() + c * f.transpose());
    A.noalias() += (d.jj + bulk) * (c * c.transpose());
    return A;
}

/// Whether the element block B^T A B can be negative: B = dvec(F)/dx maps R^12 onto R^9, so
/// the block is positive semi-definite exactly when A is. Cholesky of A shifted by a relative
/// 1e-12 is a cheap test that spares most eigen-decompositions near rest.
bool may_be_indefinite(const Matrix9d& A) {
    const double shift = 1e-12 * A.diagonal().cwiseAbs().maxCoeff();
    Matrix9d shifted = A;
    shifted.diagonal().array() += shift;
    return Eigen::LLT<Matrix9d>(shifted).info() != Eigen::Success;
}

} // namespace chromasim::mechanics::neo_hookean_law
