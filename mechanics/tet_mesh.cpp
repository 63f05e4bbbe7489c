#include "mechanics/tet_mesh.hpp"

#include "mechanics/quadratic_tets.hpp"

#include <Eigen/Dense>
#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <map>

namespace chromasim::mechanics {

double tet_volume(const TetMesh& mesh, int t) {
    const Eigen::Vector3d a = mesh.V.row(mesh.T(t, 0));
    const Eigen::Vector3d e1 = mesh.V.row(mesh.T(t, 1)).transpose() - a;
    const Eigen::Vector3d e2 = mesh.V.row(mesh.T(t, 2)).transpose() - a;
    const Eigen::Vector3d e3 = mesh.V.row(mesh.T(t, 3)).transpose() - a;
    return e1.dot(e2.cross(e3)) / 6.0;
}

double mesh_volume(const TetMesh& mesh, int region) {
    double sum = 0.0;
    if (mesh.quadratic()) {
        const QuadraticGeometry g = quadratic_geometry(mesh);
        for (int t = 0; t < mesh.T10.rows(); ++t)
            if (region < 0 || mesh.region(t) == region)
                for (int q = 0; q < 4; ++q)
                    sum += g.weight[std::size_t(4 * t + q)];
        return sum;
    }
    for (int t = 0; t < mesh.T.rows(); ++t)
        if (region < 0 || mesh.region(t) == region) sum += tet_volume(mesh, t);
    return sum;
}

Eigen::Vector4d barycentric(const TetMesh& mesh, int t, const Eigen::Vector3d& p) {
    const Eigen::Vector3d a = mesh.V.row(mesh.T(t, 0));
    Eigen::Matrix3d E;
    for (int k = 0; k < 3; ++k)
        E.col(k) = mesh.V.row(mesh.T(t, k + 1)).transpose() - a;
    const Eigen::Vector3d l = E.partialPivLu().solve(p - a);
    return {1.0 - l.sum(), l(0), l(1), l(2)};
}

Triangles interface_faces(const TetMesh& mesh, int a, int b) {
    // Every tet face keyed by its sorted vertices; the local face order below lists each face
    // counter-clockwise seen from outside the (positively oriented) tet.
    static constexpr int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
    struct Owner {
        int tet;
        int local;
    };
    std::map<std::array<int, 3>, std::vector<Owner>> faces;
    for (int t = 0; t < mesh.T.rows(); ++t)
        for (int f = 0; f < 4; ++f) {
            std::array<int, 3> key{mesh.T(t, kFace[f][0]), mesh.T(t, kFace[f][1]),
                                   mesh.T(t, kFace[f][2])};
            std::sort(key.begin(), key.end());
            faces[key].push_back({t, f});
        }
    std::vector<Eigen::Vector3i> out;
    for (const auto& [key, owners] : faces) {
        const Owner* in_a = nullptr;
        for (const Owner& o : owners)
            if (mesh.region(o.tet) == a) in_a = &o;
        if (!in_a) continue;
        const bool is_boundary = owners.size() == 1;
        const bool is_interface =
            owners.size() == 2 && b >= 0 &&
            mesh.region(owners[0].tet) + mesh.region(owners[1].tet) == a + b && a != b;
        if ((b < 0 && !is_boundary) || (b >= 0 && !is_interface)) continue;
        const int* lf = kFace[in_a->local];
        out.emplace_back(mesh.T(in_a->tet, lf[0]), mesh.T(in_a->tet, lf[1]),
                         mesh.T(in_a->tet, lf[2]));
    }
    Triangles F(out.size(), 3);
    for (std::size_t i = 0; i < out.size(); ++i)
        F.row(i) = out[i].transpose();
    return F;
}

TetLocator::TetLocator(const TetMesh& mesh, double cell_mm) : m_mesh(mesh), m_cell(cell_mm) {
    const Eigen::Vector3d lo = mesh.V.colwise().minCoeff().transpose();
    const Eigen::Vector3d hi = mesh.V.colwise().maxCoeff().transpose();
    m_origin = lo.array() - 1e-6;
    for (int k = 0; k < 3; ++k)
        m_dims(k) = int((hi(k) - m_origin(k)) / m_cell) + 1;
    m_cells.resize(std::size_t(m_dims.prod()));
    for (int t = 0; t < mesh.T.rows(); ++t) {
        Eigen::Vector3d tlo = mesh.V.row(mesh.T(t, 0)), thi = tlo;
        for (int k = 1; k < 4; ++k) {
            tlo = tlo.cwiseMin(mesh.V.row(mesh.T(t, k)).transpose());
            thi = thi.cwiseMax(mesh.V.row(mesh.T(t, k)).transpose());
        }
        const Eigen::Vector3i a = ((tlo - m_origin) / m_cell).cast<int>();
        const Eigen::Vector3i b = ((thi - m_origin) / m_cell).cast<int>();
        for (int i = a(0); i <= b(0); ++i)
            for (int j = a(1); j <= b(1); ++j)
                for (int k = a(2); k <= b(2); ++k)
                    m_cells[std::size_t((k * m_dims(1) + j) * m_dims(0) + i)].push_back(t);
    }
}

const std::vector<int>& TetLocator::cell(const Eigen::Vector3d& p) const {
    const Eigen::Vector3d q = (p - m_origin) / m_cell;
    for (int k = 0; k < 3; ++k)
        if (q(k) < 0 || q(k) >= m_dims(k)) return m_empty;
    const Eigen::Vector3i c = q.cast<int>();
    return m_cells[std::size_t((c(2) * m_dims(1) + c(1)) * m_dims(0) + c(0))];
}

int TetLocator::locate(const Eigen::Vector3d& p, double tolerance) const {
    int best = -1;
    double best_min = -tolerance;
    for (int t : cell(p)) {
        const double m = barycentric(m_mesh, t, p).minCoeff();
        if (m >= best_min) {
            best_min = m;
            best = t;
        }
    }
    return best;
}

std::vector<int> TetLocator::containing(const Eigen::Vector3d& p, double tolerance) const {
    std::vector<int> out;
    for (int t : cell(p))
        if (barycentric(m_mesh, t, p).minCoeff() >= -tolerance) out.push_back(t);
    return out;
}

} // namespace chromasim::mechanics
