#pragma once
/// Rigid objects given as triangle surfaces (loaded from glTF by generators/gltf_io), placed by
/// a pose, and seen from below as a height field: for a vertical line through (x, y), the
/// lowest z at which it meets the posed surface. That underside is what the dome touches when
/// the object approaches along -z (see contact.hpp, object_gap).
///
/// Units: millimetres. Frames: the object's own frame (the surface's V) and the sensor frame
/// (docs/ARCHITECTURE.md "Coordinates and units"); a Pose maps the first to the second.
#include "mechanics/tet_mesh.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <optional>
#include <vector>

namespace chromasim::mechanics {

/// A triangle surface in mm: V (#V x 3 positions), F (#F x 3 vertex indices). Need not be
/// closed or consistently oriented; unreferenced vertices are allowed and ignored.
struct TriangleSurface {
    Points V;
    Triangles F;
};

/// A surface from vertex and triangle lists (no validation: see validate_surface).
TriangleSurface triangle_surface(const std::vector<Eigen::Vector3d>& vertices,
                                 const std::vector<Eigen::Vector3i>& triangles);

/// Rigid placement of an object: sensor-frame position x = rotation * p + translation_mm for a
/// point p of the object's frame.
struct Pose {
    Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity(); ///< proper rotation (det +1)
    Eigen::Vector3d translation_mm = Eigen::Vector3d::Zero();
};

/// Rotation from roll, pitch and yaw in degrees, the ROS / aerospace convention: rotate about
/// the fixed x axis by roll, then about the fixed y axis by pitch, then about the fixed z axis
/// by yaw, i.e. R = Rz(yaw) * Ry(pitch) * Rx(roll) (the same as intrinsic z, y', x'').
/// Positive angles turn counter-clockwise when looking down the axis towards the origin.
Eigen::Matrix3d rotation_from_roll_pitch_yaw_deg(double roll_deg, double pitch_deg, double yaw_deg);

/// True if the triangle (a, b, c) has no usable area: twice its area is at most 1e-12 times
/// its longest edge squared (repeated or collinear vertices, up to rounding).
bool is_degenerate_triangle(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                            const Eigen::Vector3d& c);

/// Checks a surface: at least one triangle, every coordinate finite, every index in
/// [0, #V), no degenerate triangle (is_degenerate_triangle). Throws std::invalid_argument
/// naming the first offending vertex or triangle and what is allowed.
void validate_surface(const TriangleSurface& surface);

/// Checks a pose: finite entries, rotation orthonormal (|R^T R - I| <= 1e-9) with det +1.
/// Throws std::invalid_argument saying what is wrong.
void validate_pose(const Pose& pose);

/// The surface with every vertex mapped to the sensor frame by `pose` (F unchanged).
TriangleSurface posed_surface(const TriangleSurface& surface, const Pose& pose);

/// Lower cap of a sphere of radius `radius_mm` touching the origin from above: centre at
/// (0, 0, radius_mm), lowest point at the origin, polar angles in [0, cap_angle_deg] measured
/// from the bottom pole (180 gives the closed sphere). Vertices lie on the sphere, in rings of
/// constant polar angle with about `edge_mm` between neighbours; triangles face outwards.
/// Throws std::invalid_argument for a non-positive radius or edge or an angle outside (0, 180].
TriangleSurface make_sphere_cap(double radius_mm, double cap_angle_deg, double edge_mm);

/// Flat rectangular plate in z = 0 centred at the origin, `width_mm` along x, `depth_mm` along
/// y, split into `divisions` x `divisions` squares of two triangles each, facing -z.
/// Throws std::invalid_argument for non-positive sizes or divisions.
TriangleSurface make_plate(double width_mm, double depth_mm, int divisions = 1);

/// Where a vertical line meets a posed surface lowest.
struct HeightHit {
    double z_mm;  ///< lowest z of the intersection, sensor frame
    int triangle; ///< the triangle (row of F) it lies on
};

/// The underside of a posed rigid surface as a height field z(x, y), answered through a
/// uniform 2-D grid over the triangles' x-y bounding boxes.
///
/// - Build: O(#F) for meshes of comparable triangle sizes. The cell side is the mean x-y
///   bounding-box side of the triangles (about four cells per triangle, a few triangles per
///   cell), enlarged if needed so that there are at most 4 #F + 64 cells.
/// - Query: visits the triangles of one cell, no allocation; const queries may run
///   concurrently from any number of threads (no mutable state).
/// - Edges and vertices: a line counts as meeting a triangle if, in the x-y projection, it
///   lies on the inner side of each edge's line or less than tolerance_mm() beyond it (and
///   inside the triangle's bounding box grown by tolerance_mm()). tolerance_mm is 1e-9 times
///   the x-y size of the posed surface plus its distance from the z axis, some 1e6 times the
///   rounding error of the edge tests. A line exactly on a shared edge or vertex thus meets
///   every triangle around it and rounding cannot open a gap between neighbours; the
///   barycentric weights are clamped to the triangle before interpolating z, so a line just
///   outside a triangle gets a z on its edge, never an extrapolated one.
/// - Vertical triangles (x-y projection narrower than the tolerance) are left out: a vertical
///   line meets them only along an edge, which a non-vertical neighbour carries in a closed
///   surface. A surface that is vertical everywhere is rejected.
///
/// Errors: the constructor throws std::invalid_argument for an invalid surface or pose
/// (validate_surface, validate_pose) or a surface with no non-vertical triangle.
class MeshHeightField {
public:
    explicit MeshHeightField(const TriangleSurface& surface, const Pose& pose = {});

    /// Lowest z (mm) at which the vertical line through (x_mm, y_mm) meets the posed surface,
    /// and the triangle there; nullopt if it misses the surface.
    std::optional<HeightHit> hit(double x_mm, double y_mm) const;

    /// Lowest z (mm) of the vertical line through (x_mm, y_mm), nullopt on a miss.
    std::optional<double> lowest_z(double x_mm, double y_mm) const {
        const auto h = hit(x_mm, y_mm);
        return h ? std::optional<double>(h->z_mm) : std::nullopt;
    }

    /// lowest_z for every row (x, y, ignored z) of X (n x 3, mm); +infinity where it misses.
    Eigen::VectorXd lowest_z_all(const Eigen::Ref<const Points>& X) const;

    /// A vertex of the posed surface with the least z (the first one if several tie), in mm.
    const Eigen::Vector3d& lowest_point() const { return m_lowest; }
    /// Axis-aligned bounds (mm) of the posed surface's referenced vertices.
    const Eigen::AlignedBox3d& bounds() const { return m_bounds; }
    /// The posed surface (sensor frame, mm).
    const TriangleSurface& surface() const { return m_surface; }
    /// Distance (mm) within which a line counts as meeting a triangle (see above).
    double tolerance_mm() const { return m_tolerance; }
    /// The grid, for benchmarks and tests: cells along x and y, the cell side (mm) and the
    /// x-y box it covers (mm; beyond it every line misses).
    Eigen::Vector2i grid_cells() const { return {m_nx, m_ny}; }
    double cell_mm() const { return m_cell; }
    const Eigen::AlignedBox2d& grid_box() const { return m_grid_box; }

private:
    /// x-y projection of a non-vertical triangle, counter-clockwise, with the vertex heights
    /// and, per edge, the tolerance times its length (the edge functions' allowed deficit).
    struct ProjectedTriangle {
        double ax, ay, bx, by, cx, cy;
        double za, zb, zc;
        double slack_a, slack_b, slack_c; ///< for the edges opposite a, b and c
        double x0, y0, x1, y1;            ///< x-y bounding box grown by the tolerance
        int index;                        ///< row of F
    };

    void measure();                                        ///< bounds, lowest point, tolerance
    std::optional<ProjectedTriangle> project(int f) const; ///< nullopt if vertical
    void build_grid();
    int cell_x(double x) const;
    int cell_y(double y) const;

    TriangleSurface m_surface;
    std::vector<ProjectedTriangle> m_triangles;
    std::vector<int> m_cell_start;     ///< CSR: triangles of cell c are
    std::vector<int> m_cell_triangles; ///< m_cell_triangles[m_cell_start[c], m_cell_start[c+1])
    Eigen::AlignedBox2d m_grid_box;    ///< union of the triangles' boxes grown by the tolerance
    double m_cell = 1.0;
    int m_nx = 1, m_ny = 1;
    double m_tolerance = 0.0;
    Eigen::Vector3d m_lowest = Eigen::Vector3d::Zero();
    Eigen::AlignedBox3d m_bounds;
};

} // namespace chromasim::mechanics
