#pragma once
/// Surface strain on a regular grid over the contact, as seed 001 (eq. 3) measures it on skin
/// seen through a glass plate: eps_xx = du/dx + 0.5 ((du/dx)^2 + (dv/dx)^2), with (u, v) the
/// in-plane (x, y) displacement of the outer surface as a function of the undeformed in-plane
/// position (x, y). The surface is piecewise linear (the FE mesh's outer triangles), so du/dx
/// is the exact gradient of the triangle holding the grid point, projected on the x-y plane.
#include "mechanics/tet_mesh.hpp"

#include <vector>

namespace chromasim::mechanics {

/// The grid: nx points along x by ny along y, centred on the axis, spanning
/// [-half_width_x, half_width_x] x [-half_width_y, half_width_y] (mm). Defaults follow the
/// seed's 101 x 76 aspect over the dome's contact zone (up to about 5.8 mm radius at 3.2 N).
struct StrainGridSpec {
    int nx = 101, ny = 76;
    double half_width_x_mm = 5.6, half_width_y_mm = 4.2;
};

/// eps_xx on the grid, row-major: value(iy, ix) at x = -half_x + ix dx, y = -half_y + iy dy.
struct StrainGrid {
    int nx = 0, ny = 0;
    double x0_mm = 0, y0_mm = 0, dx_mm = 0, dy_mm = 0;
    std::vector<double> eps_xx;
    double value(int iy, int ix) const { return eps_xx[std::size_t(iy) * std::size_t(nx) + ix]; }
};

/// Precomputed sampling of a surface patch on a grid: the triangle holding each grid point
/// (in the x-y projection of the undeformed surface) and the x-derivatives of its shape
/// functions. Building costs O(#F + grid); sampling a frame costs O(grid).
class SurfaceStrainSampler {
public:
    /// `X`: positions (mm) of the patch's nodes; `F`: its triangles in those local indices;
    /// the patch must be a graph over the x-y plane (no fold) and cover the grid. Throws
    /// std::invalid_argument naming the first grid point outside the patch.
    SurfaceStrainSampler(const Points& X, const Triangles& F, const StrainGridSpec& spec);
    /// eps_xx of the displacement `u` (#X x 3, mm) of the patch's nodes. Thread safe.
    StrainGrid sample(const Points& u) const;
    const StrainGridSpec& spec() const { return m_spec; }

private:
    StrainGridSpec m_spec;
    std::vector<Eigen::Vector3i> m_nodes; ///< per grid point, the triangle's three nodes
    std::vector<Eigen::Vector3d> m_dNdx;  ///< per grid point, d N_k / dx of those nodes
};

} // namespace chromasim::mechanics
