#pragma once
/// Geometry of the ChromaTouch dome (SENSOR.md section 1): layer radii, marker pattern, and the
/// piecewise linear complex of the layered hemispherical shell that TetGen meshes.
#include "mechanics/tet_mesh.hpp"

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace chromasim::mechanics {

/// Region attributes of the four solid layers, innermost first.
enum Layer : int { kInnerMarkerLayer = 1, kClearLayer = 2, kOuterMarkerLayer = 3, kCoating = 4 };
inline constexpr int kLayerCount = 4;
/// Region attribute of the soft fill inside the inner layer (meshed only when asked for).
inline constexpr int kFill = 5;

/// Dimensions of the dome. The dome is a hemisphere about +z, centred at the origin, clamped
/// at its rim in the plane z = 0. The interior (r < inner radius) is meshed only for a soft
/// fill (region kFill, bonded to the inner layer, its base in z = 0 clamped); a hollow or
/// rigid-core interior is not meshed (DomeModelOptions::interior).
struct DomeParams {
    /// Interface radii in mm, innermost first: 5 spheres bounding the 4 layers [K].
    std::array<double, kLayerCount + 1> radii_mm{10.5, 11.0, 12.2, 12.7, 13.2};
    /// Marker rings: polar angle step and number of rings (apex marker not counted) [K].
    double ring_step_deg = 12.5;
    int ring_count = 5;
    double marker_radius_mm = 0.5; ///< disc radius (diameter 1.0 mm) [K]
    /// Disc thickness [K]: 0.5 mm, the whole thickness of both marker layers. The faces are
    /// kept inside the meshed layer (marker_discs' margin), so every face point has a tet of
    /// its own layer and the outer faces stay off the rendered coating.
    double marker_thickness_mm = 0.5;
    int marker_rim_points = 12; ///< polygon resolution of each disc's rim
    /// Printing tolerance: each marker's centre moves within its layer's sphere by an offset
    /// drawn uniformly in a disc of this radius (mm), independently per marker and layer, from
    /// `marker_jitter_seed` (0 mm: the CAD's layout).
    double marker_jitter_mm = 0.0;
    std::uint64_t marker_jitter_seed = 0;
};

/// Mesh resolution: named levels map to a target surface edge length and a tet volume bound.
struct MeshLevel {
    std::string name;
    double edge_mm;        ///< target edge length of the surface triangulation
    double max_volume_mm3; ///< TetGen -a bound
    /// Local refinement where contact happens: edge length within `contact_angle_deg` of the
    /// apex (equal to edge_mm: uniform). Beyond, the edge grows by 25 % of the distance
    /// travelled until it reaches edge_mm; the interior follows (TetGen sizing at the points).
    double contact_edge_mm = 0;
    double contact_angle_deg = 40;
};
/// The named level: uniform "very_coarse" (2 mm), "coarse" (1.2 mm), "medium" (0.8 mm),
/// "fine" (0.5 mm), or locally refined "refined" (0.5 mm over the contact cap, 1.2 mm far
/// from it) and "reference" (0.3 mm over the contact cap, 0.8 mm far); throws
/// std::invalid_argument otherwise.
MeshLevel mesh_level(const std::string& name);

/// Unit directions of the markers of layer `layer` (0 inner, 1 outer): apex + rings
/// k = 1..ring_count at polar angle k * step with round(6 sin(k step) / sin(step)) markers each
/// (82 for the default) [K], each moved by the layer's jitter (DomeParams::marker_jitter_mm).
std::vector<Eigen::Vector3d> marker_directions(const DomeParams& dome, int layer = 0);

/// The marker discs of both layers as closed thin volumes, undeformed: spherical-shell
/// sectors (the rims lie on spheres about the dome centre, like the layers). Per marker,
/// three rings of 1 + rim points (the centre, then the rim counter-clockwise about the
/// outward radial direction n): mid-thickness, inner face (towards the dome centre), outer
/// face, so #markers * 3 (1 + rim) rows (mm). Inner layer's markers first. Row
/// `marker * points_per_marker` is the marker's centre (markers.csv).
struct MarkerDiscs {
    Points points;
    int markers_per_layer = 0;
    int points_per_marker = 0; ///< 3 (1 + rim_points)
    int rim_points = 0;
    std::vector<double> thickness_mm; ///< face-to-face thickness of each marker as built
    /// First row of ring `ring` (0 mid, 1 inner face, 2 outer face) of marker `m` (0-based
    /// over both layers).
    int ring_row(int m, int ring) const { return m * points_per_marker + ring * (1 + rim_points); }
};
/// Each face of marker m stays `margin_mm[m]` inside its layer (5 um for all when empty): its
/// thickness is min(marker_thickness_mm, layer - 2 margin). marker_face_margins_mm gives the
/// margins for a mesh (its faceted interfaces sag between vertices).
MarkerDiscs marker_discs(const DomeParams& dome, const std::vector<double>& margin_mm = {});

/// Per marker (both layers, MarkerDiscs order), the margin that keeps its faces inside the
/// faceted layer of `mesh`: the deepest sag below the spheres (facet plane to sphere) of the
/// layer's two interfaces within 1 mm of the marker's rim, plus 5 um. A quadratic mesh's
/// faces count as their four sub-triangles through the edge nodes (split_faces).
std::vector<double> marker_face_margins_mm(const DomeParams& dome, const TetMesh& mesh);

/// The layered hemispherical shell as a PLC: five concentric hemispheres sharing one
/// angular triangulation (edge about `edge_mm` on the outer sphere), annular rim facets in
/// z = 0 between them, and one region seed per layer. With `fill`, also the disk in z = 0
/// inside the inner rim (concentric rings about `edge_mm` apart) and a region seed kFill
/// inside the inner hemisphere.
Plc dome_plc(const DomeParams& dome, double edge_mm, bool fill = false);
/// The same for a mesh level: uniform, or graded from level.contact_edge_mm over the contact
/// cap to level.edge_mm, with the local edge length as each point's size.
Plc dome_plc(const DomeParams& dome, const MeshLevel& level, bool fill = false);

/// Analytic volume of layer `layer` (1..4; kFill: the inner hemisphere), or of the whole
/// shell for layer = -1, in mm^3.
double dome_layer_volume(const DomeParams& dome, int layer = -1);

/// Makes a dome mesh quadratic (quadratic_tets.hpp): the node of every edge of a boundary or
/// interface face whose corners lie on one of the dome's spheres goes onto that sphere (the
/// element follows the curved layer), every other edge node to its edge's midpoint. A tet
/// that this would bring near folding (jacobian_ratio below 0.2) keeps straight edges.
void make_dome_quadratic(const DomeParams& dome, TetMesh& mesh);

} // namespace chromasim::mechanics
