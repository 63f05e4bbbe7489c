#pragma once
/// Quadratic (10-node) tetrahedra: the edge nodes of a linear mesh, the shape functions, the
/// quadrature and the small-strain stiffness (units: mm, N, MPa).
///
/// Why: a hollow layered shell bends as a whole, and linear tets are too stiff in bending.
/// On the dome, CalculiX's C3D10 with a 2 mm edge is within about 1 % of its converged
/// indentation where C3D4 with a 1.2 mm edge is 9 % short (docs/VALIDATION.md).
///
/// The elements are isoparametric: x(L) = sum_i N_i(L) X_i over the 10 nodes, with L the
/// barycentric coordinates of the straight tet and, in C3D10's node order (tet_mesh.hpp),
///   N_a = L_a (2 L_a - 1) at the corners,  N_ab = 4 L_a L_b at the edge nodes.
/// An edge node placed off the straight edge (on a sphere) curves the element. Integrals use
/// the 4-point rule exact for quadratics (weights V/4 at L = (a, b, b, b) and its
/// permutations), which is exact for the stiffness of a straight element, as C3D10's.
#include "mechanics/linear_elasticity.hpp"
#include "mechanics/tet_mesh.hpp"

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <array>
#include <functional>
#include <vector>

namespace chromasim::mechanics {

/// Local corner pairs of the 6 edge nodes, in C3D10's order.
inline constexpr int kTetEdges[6][2] = {{0, 1}, {1, 2}, {2, 0}, {0, 3}, {1, 3}, {2, 3}};

/// Where the node of the edge between corners a and b (indices into V) goes (mm).
using EdgeNodePlacement = std::function<Eigen::Vector3d(int a, int b)>;

/// Makes `mesh` quadratic: one node per edge (its midpoint, or `place(a, b)`), appended to V
/// after the corners, and T10. Edge nodes are numbered in the order their edges first appear
/// in T, so the result depends only on the linear mesh. No-op on a quadratic mesh.
void make_quadratic(TetMesh& mesh, const EdgeNodePlacement& place = {});

/// The corners-only mesh of a quadratic one (V's corner rows, T, region); a linear mesh as is.
TetMesh linear_part(const TetMesh& mesh);

/// Triangles F (corner indices, faces of the tets) of a quadratic mesh split into 4 each
/// through their edge nodes, with F's orientation: (a, ab, ca), (ab, b, bc), (ca, bc, c),
/// (ab, bc, ca). F as is on a linear mesh. Throws std::invalid_argument for a triangle
/// whose edge is not an edge of the mesh.
Triangles split_faces(const TetMesh& mesh, const Triangles& F);

using Vector10d = Eigen::Matrix<double, 10, 1>;
using Gradients10 = Eigen::Matrix<double, 10, 3>; ///< one row per node

/// The 10 shape functions at barycentric coordinates L.
Vector10d shape10(const Eigen::Vector4d& L);
/// Their derivatives along the 3 reference directions L_k - L_0 (k = 1, 2, 3), as 10 x 3.
Gradients10 shape10_derivatives(const Eigen::Vector4d& L);

/// The 4 quadrature points (barycentric coordinates); each weighs a quarter of the volume.
const std::array<Eigen::Vector4d, 4>& tet_quadrature_points();

/// Per tet and quadrature point (4 t + q): the shape-function gradients in x (1/mm) and the
/// point's weight |det J| / 24 (mm^3). Throws std::runtime_error naming the first tet whose
/// map folds (det J <= 0 at a quadrature point).
struct QuadraticGeometry {
    std::vector<Gradients10> gradients;
    std::vector<double> weight;
};
QuadraticGeometry quadratic_geometry(const TetMesh& mesh);

/// How far tet t's curved map is from folding: the smallest det J over its corners, edge
/// midpoints and quadrature points over the straight tet's det J (1 for straight edges, <= 0
/// where the map folds).
double jacobian_ratio(const TetMesh& mesh, int t);

/// The barycentric coordinates L at which tet t's curved map reaches p (Newton's method from
/// the straight tet's coordinates); the straight tet's on a linear mesh.
Eigen::Vector4d natural_coordinates(const TetMesh& mesh, int t, const Eigen::Vector3d& p);

/// The nodes and weights that interpolate a field at barycentric coordinates L of tet t:
/// the 10 shape functions on a quadratic mesh, L on the 4 corners on a linear one. Returns
/// the node count (4 or 10).
int interpolation_stencil(const TetMesh& mesh, int t, const Eigen::Vector4d& L,
                          std::array<int, 10>& nodes, std::array<double, 10>& weights);

/// 30 x 30 element matrices (dofs x0, y0, z0, x1, ... of the 10 nodes), one per tet of T10,
/// summed into a 3 #V x 3 #V sparse matrix in tet order.
using Matrix30d = Eigen::Matrix<double, 30, 30>;
Eigen::SparseMatrix<double> sum_element_matrices(const Tets10& T10, Eigen::Index nodes,
                                                 const std::vector<Matrix30d>& element);

/// Small-strain stiffness (3 #V x 3 #V, N/mm) of a quadratic mesh: the sum over quadrature
/// points of w [lambda g_a g_b^T + mu (g_b g_a^T + (g_a . g_b) I)], materials by region as
/// assemble_stiffness. No volumetric averaging: quadratic tets do not lock at nu = 0.45.
Eigen::SparseMatrix<double> assemble_quadratic_stiffness(const TetMesh& mesh,
                                                         const std::vector<Material>& materials);

} // namespace chromasim::mechanics
