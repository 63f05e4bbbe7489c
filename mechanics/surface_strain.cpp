#include "mechanics/surface_strain.hpp"

#include <Eigen/Dense>

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace chromasim::mechanics {

SurfaceStrainSampler::SurfaceStrainSampler(const Points& X, const Triangles& F,
                                           const StrainGridSpec& spec)
    : m_spec(spec) {
    if (spec.nx < 2 || spec.ny < 2 || !(spec.half_width_x_mm > 0) || !(spec.half_width_y_mm > 0))
        throw std::invalid_argument("strain grid: needs nx, ny >= 2 and positive half widths");
    const double dx = 2 * spec.half_width_x_mm / (spec.nx - 1);
    const double dy = 2 * spec.half_width_y_mm / (spec.ny - 1);
    const std::size_t count = std::size_t(spec.nx) * std::size_t(spec.ny);
    m_nodes.assign(count, Eigen::Vector3i(-1, -1, -1));
    m_dNdx.assign(count, Eigen::Vector3d::Zero());
    std::vector<double> best(count, -1.0); // largest minimum barycentric coordinate so far
    // Scan each triangle's grid points (its x-y bounding box), keep the best holder per point
    // so that points on shared edges get one definite triangle.
    for (int f = 0; f < F.rows(); ++f) {
        Eigen::Matrix<double, 3, 2> p;
        for (int k = 0; k < 3; ++k)
            p.row(k) = X.row(F(f, k)).head<2>();
        Eigen::Matrix2d J;
        J.col(0) = (p.row(1) - p.row(0)).transpose();
        J.col(1) = (p.row(2) - p.row(0)).transpose();
        const double det = J.determinant();
        if (std::abs(det) < 1e-14) continue; // edge-on in projection: no area to sample
        const Eigen::Matrix2d Jinv = J.inverse();
        // Shape functions N1 = xi, N2 = eta, N0 = 1 - xi - eta; gradients from Jinv's rows.
        const Eigen::Vector3d dNdx(-Jinv(0, 0) - Jinv(1, 0), Jinv(0, 0), Jinv(1, 0));
        const Eigen::Vector2d lo = p.colwise().minCoeff(), hi = p.colwise().maxCoeff();
        const int ix0 = std::max(0, int(std::ceil((lo.x() + spec.half_width_x_mm) / dx - 1e-9)));
        const int ix1 =
            std::min(spec.nx - 1, int(std::floor((hi.x() + spec.half_width_x_mm) / dx + 1e-9)));
        const int iy0 = std::max(0, int(std::ceil((lo.y() + spec.half_width_y_mm) / dy - 1e-9)));
        const int iy1 =
            std::min(spec.ny - 1, int(std::floor((hi.y() + spec.half_width_y_mm) / dy + 1e-9)));
        for (int iy = iy0; iy <= iy1; ++iy)
            for (int ix = ix0; ix <= ix1; ++ix) {
                const Eigen::Vector2d q(-spec.half_width_x_mm + ix * dx,
                                        -spec.half_width_y_mm + iy * dy);
                const Eigen::Vector2d l = Jinv * (q - p.row(0).transpose());
                const double b = std::min({1 - l.x() - l.y(), l.x(), l.y()});
                const std::size_t i = std::size_t(iy) * std::size_t(spec.nx) + std::size_t(ix);
                if (b < -1e-9 || b <= best[i]) continue;
                best[i] = b;
                m_nodes[i] = Eigen::Vector3i(F(f, 0), F(f, 1), F(f, 2));
                m_dNdx[i] = dNdx;
            }
    }
    for (std::size_t i = 0; i < count; ++i)
        if (m_nodes[i].x() < 0) {
            std::ostringstream msg;
            msg << "strain grid point (" << -spec.half_width_x_mm + double(i % spec.nx) * dx << ", "
                << -spec.half_width_y_mm + double(i / spec.nx) * dy
                << ") mm lies outside the sampled surface patch; reduce the grid's half widths";
            throw std::invalid_argument(msg.str());
        }
}

StrainGrid SurfaceStrainSampler::sample(const Points& u) const {
    StrainGrid g;
    g.nx = m_spec.nx;
    g.ny = m_spec.ny;
    g.dx_mm = 2 * m_spec.half_width_x_mm / (m_spec.nx - 1);
    g.dy_mm = 2 * m_spec.half_width_y_mm / (m_spec.ny - 1);
    g.x0_mm = -m_spec.half_width_x_mm;
    g.y0_mm = -m_spec.half_width_y_mm;
    g.eps_xx.resize(m_nodes.size());
    for (std::size_t i = 0; i < m_nodes.size(); ++i) {
        double dudx = 0, dvdx = 0;
        for (int k = 0; k < 3; ++k) {
            dudx += m_dNdx[i](k) * u(m_nodes[i](k), 0);
            dvdx += m_dNdx[i](k) * u(m_nodes[i](k), 1);
        }
        g.eps_xx[i] = dudx + 0.5 * (dudx * dudx + dvdx * dvdx);
    }
    return g;
}

} // namespace chromasim::mechanics
