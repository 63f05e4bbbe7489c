#pragma once
/// Compressible neo-Hookean hyperelasticity on quadratic (10-node) tetrahedra: the energy of
/// neo_hookean.hpp with Volumetric::element, integrated at the 4 quadrature points of each
/// tet (quadratic_tets.hpp) instead of once per linear tet:
///
///   W(u) = sum_(t, q) w_tq [ mu_t/2 (J^(-2/3) I1 - 3) + kappa_t/2 (J - 1)^2 ](F_tq),
///   F_tq = I + sum_i u_i (grad N_i)^T at quadrature point q of tet t.
///
/// The same law as CalculiX's *HYPERELASTIC, NEO HOOKE on C3D10 up to the volumetric term
/// (CalculiX: kappa/2 (J - 1)^2 too, with D1 = 2 / kappa). At u = 0 the Hessian equals
/// assemble_quadratic_stiffness (tests/mechanics/test_quadratic_tets.cpp). Methods are const,
/// run in parallel (TBB), and give the same bits whatever the number of threads: each tet
/// writes its terms to its own place and they are summed in tet order.
#include "mechanics/linear_elasticity.hpp"
#include "mechanics/quadratic_tets.hpp"
#include "mechanics/tet_mesh.hpp"

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <vector>

namespace chromasim::mechanics {

class NeoHookeanQuadratic {
public:
    /// `mesh` must be quadratic; `materials[region(t) - 1]` per tet. Throws
    /// std::runtime_error for a tet without a material or whose map folds.
    NeoHookeanQuadratic(const TetMesh& mesh, const std::vector<Material>& materials);

    /// Energy (N mm) at `u` (3 #V, mm), or +infinity if J <= 0 at any quadrature point.
    double energy(const Eigen::VectorXd& u) const;
    /// Gradient (N), 3 #V: the internal nodal forces. Throws std::domain_error if J <= 0 at a
    /// quadrature point.
    Eigen::VectorXd gradient(const Eigen::VectorXd& u) const;
    /// The gradient and min_jacobian(u) in one pass over the quadrature points: `min_jacobian`
    /// is set, and the gradient is empty where it is <= 0 (no throw).
    Eigen::VectorXd gradient(const Eigen::VectorXd& u, double& min_jacobian) const;
    /// Hessian (N/mm), 3 #V x 3 #V, symmetric. With `project_psd`, each quadrature point's
    /// 9 x 9 tangent in F has its negative eigenvalues clamped to zero, so the matrix is
    /// positive semi-definite. Throws std::domain_error if J <= 0 at a quadrature point.
    Eigen::SparseMatrix<double> hessian(const Eigen::VectorXd& u, bool project_psd) const;
    /// Smallest J over the quadrature points at u.
    double min_jacobian(const Eigen::VectorXd& u) const;
    int dofs() const { return 3 * m_nodes; }

private:
    Eigen::Matrix3d displacement_gradient(const Eigen::VectorXd& u, int t, int q) const;

    int m_nodes = 0;
    Tets10 m_T;
    QuadraticGeometry m_geometry;
    std::vector<double> m_mu, m_kappa; ///< per tet (MPa)
};

} // namespace chromasim::mechanics
