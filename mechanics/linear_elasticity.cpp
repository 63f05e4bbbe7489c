#include "mechanics/linear_elasticity.hpp"

#include <Eigen/Dense>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <stdexcept>

namespace chromasim::mechanics {

namespace {

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
    // Shape function gradients: grad N_k for k = 1..3 are the rows of inv(E), E = [x1-x0 ...].
    Eigen::Matrix3d E;
    for (int k = 0; k < 3; ++k)
        E.col(k) = (X.row(k + 1) - X.row(0)).transpose();
    const double volume = E.determinant() / 6.0;
    if (!(volume > 0)) throw std::runtime_error("tet_stiffness: degenerate or inverted tet");
    const Eigen::Matrix3d Einv = E.inverse();
    Eigen::Matrix<double, 4, 3> G;
    G.bottomRows<3>() = Einv;
    G.row(0) = -Einv.colwise().sum();
    // Strain-displacement matrix in Voigt order (xx, yy, zz, yz, xz, xy), engineering shear.
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
    return volume * B.transpose() * elasticity_matrix(material) * B;
}

Eigen::SparseMatrix<double> assemble_stiffness(const TetMesh& mesh,
                                               const std::vector<Material>& materials) {
    using Triplet = Eigen::Triplet<double>;
    tbb::enumerable_thread_specific<std::vector<Triplet>> local;
    tbb::parallel_for(tbb::blocked_range<int>(0, int(mesh.T.rows())), [&](const auto& range) {
        auto& triplets = local.local();
        triplets.reserve(triplets.size() + std::size_t(range.size()) * 144);
        for (int t = range.begin(); t != range.end(); ++t) {
            const int region = mesh.region(t);
            if (region < 1 || region > int(materials.size()))
                throw std::runtime_error("assemble_stiffness: tet region without material");
            Eigen::Matrix<double, 4, 3> X;
            for (int k = 0; k < 4; ++k)
                X.row(k) = mesh.V.row(mesh.T(t, k));
            const Matrix12d Ke = tet_stiffness(X, materials[std::size_t(region - 1)]);
            for (int a = 0; a < 4; ++a)
                for (int b = 0; b < 4; ++b)
                    for (int i = 0; i < 3; ++i)
                        for (int j = 0; j < 3; ++j)
                            triplets.emplace_back(3 * mesh.T(t, a) + i, 3 * mesh.T(t, b) + j,
                                                  Ke(3 * a + i, 3 * b + j));
        }
    });
    std::vector<Triplet> all;
    for (auto& part : local)
        all.insert(all.end(), part.begin(), part.end());
    const Eigen::Index n = 3 * mesh.V.rows();
    Eigen::SparseMatrix<double> K(n, n);
    K.setFromTriplets(all.begin(), all.end());
    return K;
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
