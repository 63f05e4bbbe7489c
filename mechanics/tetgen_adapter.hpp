#pragma once
/// The one door to TetGen (libtet, library API through tetgenio).
#include "mechanics/tet_mesh.hpp"

#include <string>

namespace chromasim::mechanics {

/// Quality controls passed to TetGen.
struct TetgenOptions {
    double max_volume_mm3 = 1.0;    ///< -a: upper bound on every tet's volume
    double radius_edge_ratio = 2.0; ///< -q: upper bound on circumradius / shortest edge
    double min_dihedral_deg = 0.0;  ///< -q ratio/angle: lower bound on dihedral angles (0: off)
    bool preserve_surface = true;   ///< -Y: no Steiner point on any facet (curved surfaces
                                    ///< keep every node on the true surface)
    /// -i: extra points (mm) inserted into the mesh, e.g. a fine grid where contact happens
    /// (local refinement). Points outside the PLC are ignored by TetGen.
    Points extra_points;
    /// -m: the PLC's point_size_mm are a sizing function (set by tetrahedralize when the PLC
    /// has sizes; recorded here so that tetgen_switches names it).
    bool sized = false;
};

/// Tetrahedralizes a PLC with quality switches on and one region attribute per tet.
/// Throws std::runtime_error naming TetGen's error when the PLC is invalid.
TetMesh tetrahedralize(const Plc& plc, const TetgenOptions& options);

/// The TetGen switch string used for `options` (recorded in cache keys and logs).
std::string tetgen_switches(const TetgenOptions& options);

} // namespace chromasim::mechanics
