#pragma once
/// Small-strain isotropic linear elasticity on linear tetrahedra (units: mm, N, MPa = N/mm^2).
#include "mechanics/tet_mesh.hpp"

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <vector>

namespace chromasim::mechanics {

/// Isotropic material of one region.
struct Material {
    double E_MPa = 1.0; ///< Young's modulus
    double nu = 0.45;   ///< Poisson's ratio, [0, 0.5)
};

using Matrix12d = Eigen::Matrix<double, 12, 12>;

/// Element stiffness (N/mm) of a linear tet with vertices X (4 x 3, mm): vol * B^T D B, dofs
/// ordered (x0, y0, z0, x1, ...).
Matrix12d tet_stiffness(const Eigen::Matrix<double, 4, 3>& X, const Material& material);

/// How the volumetric part of the strain energy, kappa/2 (div u)^2, is integrated.
enum class Volumetric {
    /// Per element: the standard linear tet. Locks (too stiff) as nu approaches 0.5.
    element,
    /// Average nodal pressure (Bonet and Burton 1998): div u is averaged, volume-weighted,
    /// over the tets around each node (separately per region, so that layers with different
    /// bulk moduli do not mix), and the volumetric energy is integrated at the nodes. Linear
    /// fields stay exact (patch test); volumetric locking is relieved. Wider stencil: K has
    /// more non-zeros and costs more to factorize.
    nodal_average,
};

/// Global stiffness (3 #V x 3 #V, N/mm) with the material of each tet picked by its region:
/// `materials[region(t) - 1]`. A quadratic mesh gets assemble_quadratic_stiffness
/// (quadratic_tets.hpp), whatever `volumetric`.
Eigen::SparseMatrix<double> assemble_stiffness(const TetMesh& mesh,
                                               const std::vector<Material>& materials,
                                               Volumetric volumetric = Volumetric::element);

/// The rows and columns of K whose dofs are kept: `index_of_dof[d]` is the new index of dof d,
/// -1 where dof d is removed (clamped); `kept` is the number of kept dofs.
Eigen::SparseMatrix<double> restrict_dofs(const Eigen::SparseMatrix<double>& K,
                                          const std::vector<int>& index_of_dof, int kept);

/// Elastic energy 1/2 u^T K u (N mm) of a displacement field (3 #V, mm): for tests.
double elastic_energy(const Eigen::SparseMatrix<double>& K, const Eigen::VectorXd& u);

} // namespace chromasim::mechanics
