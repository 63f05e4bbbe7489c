#include "mechanics/quadratic_tets.hpp"

#include <Eigen/Dense>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <unordered_map>

namespace chromasim::mechanics {

namespace {

std::uint64_t edge_key(int a, int b) {
    return (std::uint64_t(std::uint32_t(std::min(a, b))) << 32) | std::uint32_t(std::max(a, b));
}

/// The edge node of every edge of a quadratic mesh, keyed by its sorted corners.
std::unordered_map<std::uint64_t, int> edge_nodes(const TetMesh& mesh) {
    std::unordered_map<std::uint64_t, int> node_of;
    node_of.reserve(std::size_t(mesh.T10.rows()) * 2);
    for (Eigen::Index t = 0; t < mesh.T10.rows(); ++t)
        for (int e = 0; e < 6; ++e)
            node_of.emplace(edge_key(mesh.T10(t, kTetEdges[e][0]), mesh.T10(t, kTetEdges[e][1])),
                            mesh.T10(t, 4 + e));
    return node_of;
}

} // namespace

void make_quadratic(TetMesh& mesh, const EdgeNodePlacement& place) {
    if (mesh.quadratic()) return;
    const Eigen::Index corners = mesh.V.rows();
    std::unordered_map<std::uint64_t, int> node_of;
    node_of.reserve(std::size_t(mesh.T.rows()) * 2);
    std::vector<Eigen::Vector3d> added;
    mesh.T10.resize(mesh.T.rows(), 10);
    for (Eigen::Index t = 0; t < mesh.T.rows(); ++t) {
        mesh.T10.row(t).head<4>() = mesh.T.row(t);
        for (int e = 0; e < 6; ++e) {
            const int a = mesh.T(t, kTetEdges[e][0]), b = mesh.T(t, kTetEdges[e][1]);
            const auto [it, inserted] =
                node_of.emplace(edge_key(a, b), int(corners) + int(added.size()));
            if (inserted)
                added.push_back(place ? place(a, b)
                                      : Eigen::Vector3d(0.5 * (mesh.V.row(a) + mesh.V.row(b))));
            mesh.T10(t, 4 + e) = it->second;
        }
    }
    mesh.V.conservativeResize(corners + Eigen::Index(added.size()), 3);
    for (std::size_t i = 0; i < added.size(); ++i)
        mesh.V.row(corners + Eigen::Index(i)) = added[i].transpose();
}

TetMesh linear_part(const TetMesh& mesh) {
    if (!mesh.quadratic()) return mesh;
    TetMesh linear;
    linear.V = mesh.V.topRows(mesh.T.maxCoeff() + 1);
    linear.T = mesh.T;
    linear.region = mesh.region;
    return linear;
}

Triangles split_faces(const TetMesh& mesh, const Triangles& F) {
    if (!mesh.quadratic()) return F;
    const std::unordered_map<std::uint64_t, int> node_of = edge_nodes(mesh);
    auto mid = [&](int a, int b) {
        const auto it = node_of.find(edge_key(a, b));
        if (it == node_of.end())
            throw std::invalid_argument("split_faces: " + std::to_string(a) + "-" +
                                        std::to_string(b) + " is not an edge of the mesh");
        return it->second;
    };
    Triangles out(4 * F.rows(), 3);
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        const int a = F(f, 0), b = F(f, 1), c = F(f, 2);
        const int ab = mid(a, b), bc = mid(b, c), ca = mid(c, a);
        out.row(4 * f + 0) << a, ab, ca;
        out.row(4 * f + 1) << ab, b, bc;
        out.row(4 * f + 2) << ca, bc, c;
        out.row(4 * f + 3) << ab, bc, ca;
    }
    return out;
}

Vector10d shape10(const Eigen::Vector4d& L) {
    Vector10d N;
    for (int a = 0; a < 4; ++a)
        N(a) = L(a) * (2 * L(a) - 1);
    for (int e = 0; e < 6; ++e)
        N(4 + e) = 4 * L(kTetEdges[e][0]) * L(kTetEdges[e][1]);
    return N;
}

Gradients10 shape10_derivatives(const Eigen::Vector4d& L) {
    // dN/dL_k first (10 x 4), then along L_k - L_0 for k = 1..3.
    Eigen::Matrix<double, 10, 4> dL = Eigen::Matrix<double, 10, 4>::Zero();
    for (int a = 0; a < 4; ++a)
        dL(a, a) = 4 * L(a) - 1;
    for (int e = 0; e < 6; ++e) {
        const int i = kTetEdges[e][0], j = kTetEdges[e][1];
        dL(4 + e, i) = 4 * L(j);
        dL(4 + e, j) = 4 * L(i);
    }
    return dL.rightCols<3>().colwise() - dL.col(0);
}

const std::array<Eigen::Vector4d, 4>& tet_quadrature_points() {
    static const std::array<Eigen::Vector4d, 4> points = [] {
        constexpr double a = 0.5854101966249685, b = 0.1381966011250105;
        return std::array<Eigen::Vector4d, 4>{
            Eigen::Vector4d(a, b, b, b), Eigen::Vector4d(b, a, b, b), Eigen::Vector4d(b, b, a, b),
            Eigen::Vector4d(b, b, b, a)};
    }();
    return points;
}

QuadraticGeometry quadratic_geometry(const TetMesh& mesh) {
    if (!mesh.quadratic()) throw std::invalid_argument("quadratic_geometry: a linear mesh");
    const Eigen::Index tets = mesh.T10.rows();
    QuadraticGeometry g;
    g.gradients.resize(std::size_t(4 * tets));
    g.weight.resize(std::size_t(4 * tets));
    std::array<Gradients10, 4> dN;
    for (int q = 0; q < 4; ++q)
        dN[std::size_t(q)] = shape10_derivatives(tet_quadrature_points()[std::size_t(q)]);
    for (Eigen::Index t = 0; t < tets; ++t) {
        Eigen::Matrix<double, 10, 3> X;
        for (int i = 0; i < 10; ++i)
            X.row(i) = mesh.V.row(mesh.T10(t, i));
        for (int q = 0; q < 4; ++q) {
            const Eigen::Matrix3d J = X.transpose() * dN[std::size_t(q)]; // dx/dxi
            const double det = J.determinant();
            if (!(det > 0))
                throw std::runtime_error("quadratic tet " + std::to_string(t) + " folds (det J = " +
                                         std::to_string(det) + " at a quadrature point)");
            const std::size_t k = std::size_t(4 * t + q);
            g.gradients[k] = dN[std::size_t(q)] * J.inverse();
            g.weight[k] = det / 24.0;
        }
    }
    return g;
}

double jacobian_ratio(const TetMesh& mesh, int t) {
    static const std::vector<Eigen::Vector4d> points = [] {
        std::vector<Eigen::Vector4d> p(tet_quadrature_points().begin(),
                                       tet_quadrature_points().end());
        for (int a = 0; a < 4; ++a)
            p.push_back(Eigen::Vector4d::Unit(a));
        for (const auto& e : kTetEdges)
            p.push_back(0.5 * (Eigen::Vector4d::Unit(e[0]) + Eigen::Vector4d::Unit(e[1])));
        return p;
    }();
    Eigen::Matrix<double, 10, 3> X;
    for (int i = 0; i < 10; ++i)
        X.row(i) = mesh.V.row(mesh.T10(t, i));
    Eigen::Matrix3d E;
    for (int k = 0; k < 3; ++k)
        E.col(k) = (X.row(k + 1) - X.row(0)).transpose();
    const double straight = E.determinant();
    double lowest = std::numeric_limits<double>::infinity();
    for (const Eigen::Vector4d& L : points)
        lowest = std::min(lowest, (X.transpose() * shape10_derivatives(L)).determinant());
    return lowest / straight;
}

Eigen::Vector4d natural_coordinates(const TetMesh& mesh, int t, const Eigen::Vector3d& p) {
    Eigen::Vector4d L = barycentric(mesh, t, p);
    if (!mesh.quadratic()) return L;
    Eigen::Matrix<double, 10, 3> X;
    for (int i = 0; i < 10; ++i)
        X.row(i) = mesh.V.row(mesh.T10(t, i));
    for (int it = 0; it < 20; ++it) {
        const Eigen::Vector3d residual = X.transpose() * shape10(L) - p;
        const Eigen::Vector3d step =
            (X.transpose() * shape10_derivatives(L)).partialPivLu().solve(residual);
        L.tail<3>() -= step;
        L(0) = 1 - L.tail<3>().sum();
        if (step.cwiseAbs().maxCoeff() < 1e-13) break;
    }
    return L;
}

int interpolation_stencil(const TetMesh& mesh, int t, const Eigen::Vector4d& L,
                          std::array<int, 10>& nodes, std::array<double, 10>& weights) {
    if (!mesh.quadratic()) {
        for (int a = 0; a < 4; ++a) {
            nodes[std::size_t(a)] = mesh.T(t, a);
            weights[std::size_t(a)] = L(a);
        }
        return 4;
    }
    const Vector10d N = shape10(L);
    for (int i = 0; i < 10; ++i) {
        nodes[std::size_t(i)] = mesh.T10(t, i);
        weights[std::size_t(i)] = N(i);
    }
    return 10;
}

Eigen::SparseMatrix<double> sum_element_matrices(const Tets10& T10, Eigen::Index nodes,
                                                 const std::vector<Matrix30d>& element) {
    std::vector<Eigen::Triplet<double>> trips;
    trips.reserve(element.size() * 900);
    for (Eigen::Index t = 0; t < T10.rows(); ++t)
        for (int b = 0; b < 30; ++b)
            for (int a = 0; a < 30; ++a)
                trips.emplace_back(3 * T10(t, a / 3) + a % 3, 3 * T10(t, b / 3) + b % 3,
                                   element[std::size_t(t)](a, b));
    Eigen::SparseMatrix<double> K(3 * nodes, 3 * nodes);
    K.setFromTriplets(trips.begin(), trips.end());
    return K;
}

namespace {

/// sum_q w_q [lambda g_a g_b^T + mu (g_b g_a^T + (g_a . g_b) I)] over a tet's points.
Matrix30d element_stiffness(const QuadraticGeometry& g, Eigen::Index t, const Material& m) {
    const double mu = m.E_MPa / (2 * (1 + m.nu));
    const double lambda = m.E_MPa * m.nu / ((1 + m.nu) * (1 - 2 * m.nu));
    Matrix30d K = Matrix30d::Zero();
    for (int q = 0; q < 4; ++q) {
        const Gradients10& G = g.gradients[std::size_t(4 * t + q)];
        const double w = g.weight[std::size_t(4 * t + q)];
        const Eigen::Matrix<double, 10, 10> GG = G * G.transpose();
        for (int a = 0; a < 10; ++a)
            for (int b = 0; b < 10; ++b) {
                const Eigen::Vector3d ga = G.row(a), gb = G.row(b);
                K.block<3, 3>(3 * a, 3 * b) +=
                    w * (lambda * ga * gb.transpose() + mu * gb * ga.transpose() +
                         mu * GG(a, b) * Eigen::Matrix3d::Identity());
            }
    }
    return K;
}

} // namespace

Eigen::SparseMatrix<double> assemble_quadratic_stiffness(const TetMesh& mesh,
                                                         const std::vector<Material>& materials) {
    for (Eigen::Index t = 0; t < mesh.region.size(); ++t)
        if (mesh.region(t) < 1 || mesh.region(t) > int(materials.size()))
            throw std::runtime_error("assemble_quadratic_stiffness: tet region without material");
    const QuadraticGeometry g = quadratic_geometry(mesh);
    std::vector<Matrix30d> element(std::size_t(mesh.T10.rows()));
    tbb::parallel_for(tbb::blocked_range<Eigen::Index>(0, mesh.T10.rows()), [&](const auto& r) {
        for (Eigen::Index t = r.begin(); t != r.end(); ++t)
            element[std::size_t(t)] =
                element_stiffness(g, t, materials[std::size_t(mesh.region(t) - 1)]);
    });
    return sum_element_matrices(mesh.T10, mesh.V.rows(), element);
}

} // namespace chromasim::mechanics
