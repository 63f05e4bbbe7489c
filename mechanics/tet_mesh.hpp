#pragma once
/// Tetrahedral meshes and the piecewise linear complexes they are made from (plain data).
#include <Eigen/Core>
#include <Eigen/Geometry>

#include <vector>

namespace chromasim::mechanics {

/// #V x 3 positions in mm, row-major.
using Points = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
/// #T x 4 vertex indices of linear tetrahedra (positive orientation after meshing).
using Tets = Eigen::Matrix<int, Eigen::Dynamic, 4, Eigen::RowMajor>;
/// #T x 10 node indices of quadratic tetrahedra: the 4 corners, then the nodes of edges
/// (0,1), (1,2), (2,0), (0,3), (1,3), (2,3) (CalculiX's and Abaqus' C3D10 order).
using Tets10 = Eigen::Matrix<int, Eigen::Dynamic, 10, Eigen::RowMajor>;
/// #F x 3 vertex indices of triangles.
using Triangles = Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>;

/// A piecewise linear complex: the input of the tetrahedral mesher.
struct Plc {
    Points points;
    std::vector<std::vector<int>> facets; ///< each a planar polygon (point indices)
    std::vector<int> facet_markers;       ///< one per facet, copied nowhere yet: for debugging
    /// Optional target edge length (mm) at each point: the mesher grades the interior between
    /// them (local refinement). Empty: one global volume bound only.
    std::vector<double> point_size_mm;
    struct Region {
        Eigen::Vector3d seed_mm; ///< a point strictly inside the region
        int attribute;           ///< region id copied to every tet in the region
    };
    std::vector<Region> regions;
};

/// Output of the mesher: linear tets with a region attribute each. A quadratic mesh
/// (quadratic_tets.hpp) also has T10: V then holds the corners first and the edge nodes after
/// them, and T keeps the corners (faces, regions and point location use them).
struct TetMesh {
    Points V;
    Tets T;
    Eigen::VectorXi region; ///< #T region attribute (the Plc::Region::attribute)
    Tets10 T10;             ///< empty for linear tets
    bool quadratic() const { return T10.rows() > 0; }
};

/// Signed volume of tet t (mm^3), positive for the orientation the mesher guarantees.
double tet_volume(const TetMesh& mesh, int t);
/// Sum of tet volumes (mm^3), optionally only those with the given region attribute; a
/// quadratic mesh's curved tets by their quadrature.
double mesh_volume(const TetMesh& mesh, int region = -1);

/// Barycentric coordinates of p in tet t (sum to 1; all >= 0 inside).
Eigen::Vector4d barycentric(const TetMesh& mesh, int t, const Eigen::Vector3d& p);

/// Faces between a tet of region `a` and a tet of region `b` (b = -1: boundary faces of
/// region a tets), oriented with their normal pointing out of region `a`.
Triangles interface_faces(const TetMesh& mesh, int a, int b);

/// Tributary area (mm^2) of every node over the faces F whose three vertices satisfy
/// `on_surface(position)`: a third of each such triangle's area per vertex (#V entries).
template <class Pred>
std::vector<double> tributary_areas(const TetMesh& mesh, const Triangles& F, Pred&& on_surface) {
    std::vector<double> area(std::size_t(mesh.V.rows()), 0.0);
    for (int f = 0; f < F.rows(); ++f) {
        const Eigen::Vector3d a = mesh.V.row(F(f, 0)), b = mesh.V.row(F(f, 1)),
                              c = mesh.V.row(F(f, 2));
        if (!on_surface(a) || !on_surface(b) || !on_surface(c)) continue;
        const Eigen::Vector3d e1 = b - a, e2 = c - a;
        const double third = e1.cross(e2).norm() / 6.0;
        for (int k = 0; k < 3; ++k)
            area[std::size_t(F(f, k))] += third;
    }
    return area;
}

/// Finds the tet containing a point with a uniform grid over tet bounding boxes.
class TetLocator {
public:
    explicit TetLocator(const TetMesh& mesh, double cell_mm = 1.5);
    /// Tet containing p (the one with the largest minimum barycentric coordinate among the
    /// candidates), or -1 if p is outside the mesh by more than `tolerance` in barycentric terms.
    int locate(const Eigen::Vector3d& p, double tolerance = 1e-9) const;
    /// Every tet whose barycentric coordinates of p are all >= -tolerance.
    std::vector<int> containing(const Eigen::Vector3d& p, double tolerance) const;

private:
    const std::vector<int>& cell(const Eigen::Vector3d& p) const;
    const TetMesh& m_mesh;
    Eigen::Vector3d m_origin;
    double m_cell;
    Eigen::Vector3i m_dims;
    std::vector<std::vector<int>> m_cells;
    std::vector<int> m_empty;
};

} // namespace chromasim::mechanics
