#pragma once
/// Compressible neo-Hookean hyperelasticity on linear tetrahedra (units: mm, N, MPa = N/mm^2):
/// energy, gradient and Hessian of the large-deformation counterpart of linear_elasticity.hpp.
///
/// With x = X + u the deformed positions, F_e the (constant) deformation gradient of tet e,
/// J_e = det F_e and I1_e = tr(F_e^T F_e), the energy is split into an isochoric and a
/// volumetric part, exactly as assemble_stiffness splits its deviatoric and volumetric parts:
///
///   W(u) = sum_e V_e mu_e/2 (J_e^(-2/3) I1_e - 3)  +  W_vol,
///   W_vol = sum_e V_e kappa_e/2 (J_e - 1)^2                  (Volumetric::element)
///   W_vol = sum_(a,r) V_ar kappa_r/2 (J_ar - 1)^2            (Volumetric::nodal_average)
///
/// with mu = E / (2 (1 + nu)), kappa = E / (3 (1 - 2 nu)) = lambda + 2 mu / 3 (the moduli of
/// linear_elasticity.cpp), V_e the reference volume of tet e and, for each (node a, region r)
/// pair, V_ar = sum of V_e / 4 over the tets e of region r around node a and
/// J_ar = (sum of V_e J_e / 4 over the same tets) / V_ar: the deformed over the reference
/// volume of the node's share of the region (Bonet and Burton 1998, average nodal pressure).
///
/// Why U(J) = kappa/2 (J - 1)^2 and not kappa/2 (ln J)^2: J is a cubic polynomial of the
/// positions and J_ar is linear in the J_e, so U stays a polynomial with a constant second
/// derivative kappa (its pressure kappa (J - 1) is bounded, no log-driven stiffening that the
/// Newton line search would have to fight), and it is convex in J (ln^2 is not for J > e).
/// Inversion is kept out by the isochoric term and by energy() returning +infinity.
///
/// At small strain the isochoric part is mu dev(eps) : dev(eps) per element and the volumetric
/// part kappa/2 (div u)^2 per element or per (node, region): the Hessian at u = 0 equals
/// assemble_stiffness(mesh, materials, volumetric) (tests/mechanics/test_neo_hookean.cpp).
///
/// Vectors u and gradients are 3 #V long, dofs ordered (x0, y0, z0, x1, ...) as in
/// assemble_stiffness. Every method is const and keeps no state between calls: one object may
/// be used from several threads at once. Each call runs in parallel (TBB) and its result is the
/// same, bit for bit, whatever the number of threads: every tet and every (node, region) pair
/// writes its terms to a fixed place, and each entry sums its terms in a fixed order.
#include "mechanics/linear_elasticity.hpp"
#include "mechanics/tet_mesh.hpp"

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <vector>

namespace chromasim::mechanics {

/// The neo-Hookean energy of a tet mesh (see the top of this file), built once per mesh and
/// evaluated at any displacement: plain arrays per tet, no virtual call per element.
class NeoHookean {
public:
    /// Precomputes the reference data of every tet (inverse edge matrix, volume, moduli), the
    /// (node, region) stencil for nodal averaging and the sparsity pattern of the Hessian.
    /// `materials[region(t) - 1]` per tet. Throws std::runtime_error for a tet without a
    /// material or with a non-positive reference volume.
    NeoHookean(const TetMesh& mesh, const std::vector<Material>& materials,
               Volumetric volumetric = Volumetric::element);

    /// Energy (N mm) at the displacement `u` (3 #V, mm), or +infinity if any tet has
    /// J <= 0 (so that a line search rejects the step).
    double energy(const Eigen::VectorXd& u) const;

    /// Gradient of the energy (N), 3 #V: the internal nodal forces. Pre-condition:
    /// min_jacobian(u) > 0, else throws std::domain_error.
    Eigen::VectorXd gradient(const Eigen::VectorXd& u) const;

    /// Hessian of the energy (N/mm), 3 #V x 3 #V, symmetric, compressed column-major, on the
    /// fixed sparsity pattern hessian_pattern(). With `project_psd`, the 12 x 12 block of each
    /// tet (isochoric part plus the J-curvature of the volumetric part) has its negative
    /// eigenvalues clamped to zero (as in IPC and PolyFEM). A block is left as is when its
    /// 9 x 9 Hessian in F is positive definite up to a relative 1e-12 (then the block is
    /// positive semi-definite), so that near rest few blocks pay for an eigen-decomposition.
    /// The other volumetric terms are rank-one outer products with positive weights, so the
    /// whole matrix is then positive semi-definite and Newton gets a descent direction.
    /// Pre-condition: min_jacobian(u) > 0, else throws std::domain_error.
    Eigen::SparseMatrix<double> hessian(const Eigen::VectorXd& u, bool project_psd) const;

    /// Same, written into `H` without reallocating: `H` must be empty (it then takes the
    /// pattern) or a matrix returned earlier by this object.
    void hessian(const Eigen::VectorXd& u, bool project_psd, Eigen::SparseMatrix<double>& H) const;

    /// Smallest J over the tets and, for nodal_average, over the (node, region) pairs, at u.
    /// Energy and derivatives are defined where it is > 0.
    double min_jacobian(const Eigen::VectorXd& u) const;

    /// The sparsity pattern of the Hessian (all values zero); the same for every u.
    const Eigen::SparseMatrix<double>& hessian_pattern() const { return m_pattern; }

    /// 3 #V: the size of u, of the gradient and of the Hessian.
    int dofs() const { return 3 * m_nodes; }

private:
    /// J_e - 1 of every tet at u (accurate for small strain: no cancellation against 1).
    std::vector<double> element_jacobians_minus_one(const Eigen::VectorXd& u) const;
    /// The pressure that multiplies the J-curvature of each tet: kappa (J_e - 1) for
    /// element, the average of kappa (J_ar - 1) over the tet's four nodes for nodal_average.
    std::vector<double> element_pressures(const std::vector<double>& jm1) const;
    /// J_ar - 1 of every (node, region) pair from the J_e - 1 of the tets.
    std::vector<double> nodal_jacobians_minus_one(const std::vector<double>& jm1) const;
    /// Sums per-tet 12-vectors (tet-major) into nodal 3-vectors.
    Eigen::VectorXd gather_nodal(const std::vector<double>& per_tet) const;
    /// nodal_average: the factors h_ar = sqrt(kappa_r V_ar) dJ_ar/dx (3 per patch node) of the
    /// rank-one volumetric terms, from the per-tet gradients V_e dJ_e/dx (12 per tet).
    std::vector<double> patch_factors(const std::vector<double>& volume_gradients) const;
    /// Sums the terms of every 3 x 3 block into the values of H (which has the pattern).
    void sum_blocks(const std::vector<double>& blocks, const std::vector<double>& h,
                    Eigen::SparseMatrix<double>& H) const;
    void build_nodal_stencil(const std::vector<int>& region, int regions);
    void build_pattern();

    int m_nodes = 0;
    Volumetric m_volumetric;
    Tets m_T;
    // Per tet (structure of arrays).
    std::vector<Eigen::Matrix3d> m_Dm_inv; ///< inverse of the reference edge matrix (1/mm)
    std::vector<double> m_volume;          ///< reference volume (mm^3)
    std::vector<double> m_mu, m_kappa;     ///< shear and bulk moduli (MPa)
    /// Incidence, CSR by node: entries 4 t + a of the tets with T(t, a) = node, in tet order.
    std::vector<int> m_node_start, m_node_incidence;
    // Nodal averaging: one "patch" per (node, region) pair.
    std::vector<int> m_tet_patch;             ///< 4 per tet: patch of each of its nodes
    std::vector<double> m_patch_volume;       ///< V_ar (mm^3)
    std::vector<double> m_patch_kappa;        ///< kappa_r (MPa)
    std::vector<int> m_patch_start;           ///< CSR into m_patch_incidence (entries 4 t + a)
    std::vector<int> m_patch_incidence;       ///< tets of each patch, in tet order
    std::vector<int> m_patch_node_start;      ///< CSR into m_patch_nodes
    std::vector<int> m_patch_nodes;           ///< sorted nodes touched by each patch
    std::vector<int> m_patch_incidence_local; ///< 4 per incidence: local node index in patch
    // Hessian: fixed pattern, block (3 x 3) compressed columns, and gather lists per block.
    Eigen::SparseMatrix<double> m_pattern;
    std::vector<int> m_block_start; ///< per node (block column): first block, #V + 1
    /// Per block: CSR into m_element_terms, offsets of the 3 x 3 terms in the per-tet 12 x 12
    /// column-major buffer.
    std::vector<int> m_element_term_start, m_element_terms;
    /// Per block: CSR into m_rank_one_i and m_rank_one_j, indices into the per patch-node
    /// vectors h whose outer products h_i h_j^T add to the block (nodal_average).
    std::vector<int> m_rank_one_start, m_rank_one_i, m_rank_one_j;
};

} // namespace chromasim::mechanics
