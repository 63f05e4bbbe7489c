#include "mechanics/linear_elasticity.hpp"

#include "mechanics/quadratic_tets.hpp"

#include <Eigen/Dense>
#include <tbb/parallel_for.h>

#include <stdexcept>

namespace chromasim::mechanics {

namespace {

double bulk_modulus(const Material& m) {
    return m.E_MPa / (3 * (1 - 2 * m.nu));
}

/// Shape-function gradients (rows, 4 x 3) and volume of a linear tet.
struct TetGradients {
    Eigen::Matrix<double, 4, 3> G;
    double volume;
};

TetGradients tet_gradients(const Eigen::Matrix<double, 4, 3>& X) {
    Eigen::Matrix3d E;
    for (int k = 0; k < 3; ++k)
        E.col(k) = (X.row(k + 1) - X.row(0)).transpose();
    TetGradients g;
    g.volume = E.determinant() / 6.0;
    if (!(g.volume > 0)) throw std::runtime_error("tet_stiffness: degenerate or inverted tet");
    const Eigen::Matrix3d Einv = E.inverse();
    g.G.bottomRows<3>() = Einv;
    g.G.row(0) = -Einv.colwise().sum();
    return g;
}

/// Strain-displacement matrix in Voigt order (xx, yy, zz, yz, xz, xy), engineering shear.
Eigen::Matrix<double, 6, 12> strain_matrix(const Eigen::Matrix<double, 4, 3>& G) {
    Eigen::Matrix<double, 6, 12> B = Eigen::Matrix<double, 6, 12>::Zero();
    for (int a = 0; a < 4; ++a) {
        const double gx = G(a, 0), gy = G(a, 1), gz = G(a, 2);
        B(0, 3 * a + 0) = gx;
        B(1, 3 * a + 1) = gy;
        B(2, 3 * a + 2) = gz;
        B(3, 3 * a + 1) = gz;
        B(3, 3 * a + 2) = gy;
        B(4, 3 * a + 0) = gz;
        B(4, 3 * a + 2) = gx;
        B(5, 3 * a + 0) = gy;
        B(5, 3 * a + 1) = gx;
    }
    return B;
}

/// The deviatoric part of the isotropic elasticity matrix: D = D_dev + kappa m m^T.
Eigen::Matrix<double, 6, 6> deviatoric_matrix(const Material& m) {
    const double mu = m.E_MPa / (2 * (1 + m.nu));
    Eigen::Matrix<double, 6, 6> D = Eigen::Matrix<double, 6, 6>::Zero();
    D.topLeftCorner<3, 3>().setConstant(-2.0 * mu / 3.0);
    D.topLeftCorner<3, 3>().diagonal().array() += 2 * mu;
    D.bottomRightCorner<3, 3>().diagonal().setConstant(mu);
    return D;
}

Eigen::Matrix<double, 6, 6> elasticity_matrix(const Material& m) {
    const double lambda = m.E_MPa * m.nu / ((1 + m.nu) * (1 - 2 * m.nu));
    const double mu = m.E_MPa / (2 * (1 + m.nu));
    Eigen::Matrix<double, 6, 6> D = Eigen::Matrix<double, 6, 6>::Zero();
    D.topLeftCorner<3, 3>().setConstant(lambda);
    D.topLeftCorner<3, 3>().diagonal().array() += 2 * mu;
    D.bottomRightCorner<3, 3>().diagonal().setConstant(mu);
    return D;
}

} // namespace

Matrix12d tet_stiffness(const Eigen::Matrix<double, 4, 3>& X, const Material& material) {
    const TetGradients g = tet_gradients(X);
    const Eigen::Matrix<double, 6, 12> B = strain_matrix(g.G);
    return g.volume * B.transpose() * elasticity_matrix(material) * B;
}

namespace {

Eigen::Matrix<double, 4, 3> tet_points(const TetMesh& mesh, int t) {
    Eigen::Matrix<double, 4, 3> X;
    for (int k = 0; k < 4; ++k)
        X.row(k) = mesh.V.row(mesh.T(t, k));
    return X;
}

const Material& material_of(const TetMesh& mesh, int t, const std::vector<Material>& materials) {
    const int region = mesh.region(t);
    if (region < 1 || region > int(materials.size()))
        throw std::runtime_error("assemble_stiffness: tet region without material");
    return materials[std::size_t(region - 1)];
}

/// Element matrices (full, or deviatoric only) gathered as triplets, in parallel. Each tet
/// writes its 144 entries at a fixed place, so the sum (and the result, bit for bit) does not
/// depend on the thread count or scheduling.
Eigen::SparseMatrix<double> assemble_elements(const TetMesh& mesh,
                                              const std::vector<Material>& materials,
                                              bool deviatoric_only) {
    std::vector<Eigen::Triplet<double>> triplets(std::size_t(mesh.T.rows()) * 144);
    tbb::parallel_for(tbb::blocked_range<int>(0, int(mesh.T.rows())), [&](const auto& range) {
        for (int t = range.begin(); t != range.end(); ++t) {
            const Material& m = material_of(mesh, t, materials);
            const TetGradients g = tet_gradients(tet_points(mesh, t));
            const Eigen::Matrix<double, 6, 12> B = strain_matrix(g.G);
            const Matrix12d Ke = g.volume * B.transpose() *
                                 (deviatoric_only ? deviatoric_matrix(m) : elasticity_matrix(m)) *
                                 B;
            auto* out = triplets.data() + std::size_t(t) * 144;
            for (int a = 0; a < 4; ++a)
                for (int b = 0; b < 4; ++b)
                    for (int i = 0; i < 3; ++i)
                        for (int j = 0; j < 3; ++j)
                            *out++ = {3 * mesh.T(t, a) + i, 3 * mesh.T(t, b) + j,
                                      Ke(3 * a + i, 3 * b + j)};
        }
    });
    const Eigen::Index n = 3 * mesh.V.rows();
    Eigen::SparseMatrix<double> K(n, n);
    K.setFromTriplets(triplets.begin(), triplets.end());
    return K;
}

/// Volumetric stiffness with average nodal pressure: rows of D are the averaged divergence
/// operators b_(n,r) of each (node, region) pair; K_vol = D^T diag(kappa_r V_(n,r)) D.
Eigen::SparseMatrix<double> nodal_volumetric(const TetMesh& mesh,
                                             const std::vector<Material>& materials) {
    const int regions = int(materials.size());
    auto key = [&](int node, int region) { return node * regions + (region - 1); };
    const int rows = int(mesh.V.rows()) * regions;
    std::vector<double> volume(std::size_t(rows), 0.0);
    std::vector<Eigen::Triplet<double>> w; // unnormalised rows: sum of V_e / 4 * div_e
    w.reserve(std::size_t(mesh.T.rows()) * 48);
    for (int t = 0; t < mesh.T.rows(); ++t) {
        material_of(mesh, t, materials);
        const TetGradients g = tet_gradients(tet_points(mesh, t));
        for (int a = 0; a < 4; ++a) {
            const int row = key(mesh.T(t, a), mesh.region(t));
            volume[std::size_t(row)] += g.volume / 4;
            for (int b = 0; b < 4; ++b)
                for (int k = 0; k < 3; ++k)
                    w.emplace_back(row, 3 * mesh.T(t, b) + k, g.volume / 4 * g.G(b, k));
        }
    }
    Eigen::SparseMatrix<double, Eigen::RowMajor> D(rows, 3 * mesh.V.rows());
    D.setFromTriplets(w.begin(), w.end());
    Eigen::VectorXd weight = Eigen::VectorXd::Zero(rows);
    for (int r = 0; r < rows; ++r)
        if (volume[std::size_t(r)] > 0) {
            D.row(r) /= volume[std::size_t(r)];
            weight(r) = bulk_modulus(materials[std::size_t(r % regions)]) * volume[std::size_t(r)];
        }
    return Eigen::SparseMatrix<double>(D.transpose() * weight.asDiagonal() * D);
}

} // namespace

Eigen::SparseMatrix<double> assemble_stiffness(const TetMesh& mesh,
                                               const std::vector<Material>& materials,
                                               Volumetric volumetric) {
    if (mesh.quadratic()) return assemble_quadratic_stiffness(mesh, materials);
    if (volumetric == Volumetric::element) return assemble_elements(mesh, materials, false);
    return assemble_elements(mesh, materials, true) + nodal_volumetric(mesh, materials);
}

Eigen::SparseMatrix<double> restrict_dofs(const Eigen::SparseMatrix<double>& K,
                                          const std::vector<int>& index_of_dof, int kept) {
    std::vector<Eigen::Triplet<double>> trips;
    trips.reserve(std::size_t(K.nonZeros()));
    for (int c = 0; c < K.outerSize(); ++c)
        for (Eigen::SparseMatrix<double>::InnerIterator it(K, c); it; ++it)
            if (index_of_dof[it.row()] >= 0 && index_of_dof[it.col()] >= 0)
                trips.emplace_back(index_of_dof[it.row()], index_of_dof[it.col()], it.value());
    Eigen::SparseMatrix<double> R(kept, kept);
    R.setFromTriplets(trips.begin(), trips.end());
    return R;
}

double elastic_energy(const Eigen::SparseMatrix<double>& K, const Eigen::VectorXd& u) {
    return 0.5 * u.dot(K * u);
}

} // namespace chromasim::mechanics
