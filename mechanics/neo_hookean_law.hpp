#pragma once
/// The compressible neo-Hookean law at one material point, shared by the linear and the
/// quadratic tets (neo_hookean.hpp, neo_hookean_quadratic.hpp): the isochoric density
/// psi = mu/2 (J^(-2/3) I1 - 3), its first Piola-Kirchhoff stress and its second derivative in
/// vec(F) (column-major), written so that small strains lose no digits.
#include <Eigen/Core>

namespace chromasim::mechanics::neo_hookean_law {

using Matrix9d = Eigen::Matrix<double, 9, 9>;

/// Deformation of one tet, with J - 1 and I1 - 3 computed from the displacement gradient H so
/// that small strains lose no digits to cancellation against 1 and 3.
struct Kinematics {
    Eigen::Matrix3d F;
    double jm1;  ///< J - 1 = tr H + I2(H) + det H
    double i1m3; ///< I1 - 3 = 2 tr H + |H|^2
};

/// cof F = J F^-T.
Eigen::Matrix3d cofactor(const Eigen::Matrix3d& F);

/// F = I + H from the displacement gradient H.
Kinematics from_displacement_gradient(const Eigen::Matrix3d& H);

/// mu/2 (J^(-2/3) I1 - 3) (MPa).
double isochoric_density(const Kinematics& k, double mu);

/// First Piola-Kirchhoff stress (MPa) of the isochoric part plus the pressure p: dpsi/dF + p
/// dJ/dF.
Eigen::Matrix3d first_piola(const Kinematics& k, double mu, double p);

/// d^2/dF^2 of psi + p J (p held fixed) + bulk/2 (J - 1)^2 about the current J, in vec(F).
Matrix9d stress_derivative(const Kinematics& k, double mu, double p, double bulk);

/// Whether a 9 x 9 tangent may have a negative eigenvalue: Cholesky of A shifted by a relative
/// 1e-12 fails. A cheap test that spares most eigen-decompositions near rest.
bool may_be_indefinite(const Matrix9d& A);

} // namespace chromasim::mechanics::neo_hookean_law
