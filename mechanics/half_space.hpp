#pragma once
/// Displacements of an elastic half-space under a point force on its surface (Boussinesq for
/// the normal component, Cerruti for the tangential ones; Johnson, Contact Mechanics, 3.2):
/// the far field that lets a finite block stand in for the half-space Hertz and Mindlin
/// assume (block_model.hpp).
#include <Eigen/Core>

namespace chromasim::mechanics {

/// The 3 x 3 matrix G(X) with u(X) = G(X) F: displacement (mm) at X (mm, z <= 0, X != 0) of
/// the half-space z <= 0 (Young's modulus E_MPa, Poisson's ratio nu in [0, 0.5)) under a force
/// F (N) applied at the origin of its surface, in the same x, y, z axes: F = (0, 0, -P)
/// presses into it (Boussinesq), F = (Q, 0, 0) drags its surface along +x (Cerruti).
/// Displacements vanish at infinity (they fall off as 1 / |X|).
Eigen::Matrix3d half_space_green(const Eigen::Vector3d& X, double E_MPa, double nu);

} // namespace chromasim::mechanics
