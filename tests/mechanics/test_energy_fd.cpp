// Finite-difference checks: the assembled stiffness is the Hessian of an elastic energy
// computed independently, tet by tet, from strains (and, for average nodal pressure, from the
// nodal divergence), and K u is its gradient.
#include "mechanics/linear_elasticity.hpp"
#include "mechanics/tetgen_adapter.hpp"

#include <Eigen/Dense>
#include <catch2/catch.hpp>

#include <map>
#include <random>

using namespace chromasim::mechanics;

namespace {

TetMesh two_region_box() {
    Plc plc;
    plc.points.resize(8, 3);
    for (int i = 0; i < 8; ++i)
        plc.points.row(i) << (i & 1) * 1.0, ((i >> 1) & 1) * 0.8, ((i >> 2) & 1) * 0.6;
    plc.facets = {{0, 1, 3, 2}, {4, 5, 7, 6}, {0, 1, 5, 4},
                  {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 3, 7, 5}};
    plc.regions.push_back({Eigen::Vector3d(0.5, 0.4, 0.3), 1});
    TetgenOptions options;
    options.max_volume_mm3 = 0.01;
    options.preserve_surface = false;
    TetMesh mesh = tetrahedralize(plc, options);
    for (int t = 0; t < mesh.T.rows(); ++t) // two materials: split at x = 0.5
        mesh.region(t) = mesh.V.row(mesh.T(t, 0)).x() + mesh.V.row(mesh.T(t, 1)).x() < 1.0 ? 1 : 2;
    return mesh;
}

/// Displacement gradient of tet t under u (3 #V).
Eigen::Matrix3d displacement_gradient(const TetMesh& mesh, int t, const Eigen::VectorXd& u,
                                      double& volume) {
    Eigen::Matrix3d X, U;
    for (int k = 0; k < 3; ++k) {
        X.col(k) = (mesh.V.row(mesh.T(t, k + 1)) - mesh.V.row(mesh.T(t, 0))).transpose();
        U.col(k) = u.segment<3>(3 * mesh.T(t, k + 1)) - u.segment<3>(3 * mesh.T(t, 0));
    }
    volume = X.determinant() / 6;
    return U * X.inverse();
}

/// Small-strain energy (N mm): per tet mu eps_dev : eps_dev, plus the volumetric part
/// kappa/2 tr(eps)^2 per tet (element) or per (node, region) of the averaged divergence.
double energy(const TetMesh& mesh, const std::vector<Material>& mats, const Eigen::VectorXd& u,
              Volumetric volumetric) {
    double W = 0;
    std::map<std::pair<int, int>, std::pair<double, double>> nodal; // (V_n, sum V_e/4 div)
    for (int t = 0; t < mesh.T.rows(); ++t) {
        const Material& m = mats[std::size_t(mesh.region(t) - 1)];
        const double mu = m.E_MPa / (2 * (1 + m.nu));
        const double kappa = m.E_MPa / (3 * (1 - 2 * m.nu));
        double V = 0;
        const Eigen::Matrix3d G = displacement_gradient(mesh, t, u, V);
        const Eigen::Matrix3d eps = 0.5 * (G + G.transpose());
        const double tr = eps.trace();
        const Eigen::Matrix3d dev = eps - tr / 3 * Eigen::Matrix3d::Identity();
        W += V * mu * (dev.array() * dev.array()).sum();
        if (volumetric == Volumetric::element) {
            W += V * kappa / 2 * tr * tr;
        } else {
            for (int a = 0; a < 4; ++a) {
                auto& acc = nodal[{mesh.T(t, a), mesh.region(t)}];
                acc.first += V / 4;
                acc.second += V / 4 * tr;
            }
        }
    }
    for (const auto& [key, acc] : nodal) {
        const Material& m = mats[std::size_t(key.second - 1)];
        const double kappa = m.E_MPa / (3 * (1 - 2 * m.nu));
        const double div = acc.second / acc.first;
        W += acc.first * kappa / 2 * div * div;
    }
    return W;
}

} // namespace

TEST_CASE("stiffness is the Hessian of the strain energy (finite differences)",
          "[mechanics][fem][fd]") {
    const TetMesh mesh = two_region_box();
    const std::vector<Material> mats{{1.0, 0.45}, {0.2, 0.499}};
    const Volumetric volumetric = GENERATE(Volumetric::element, Volumetric::nodal_average);
    INFO("volumetric " << int(volumetric));
    const Eigen::SparseMatrix<double> K = assemble_stiffness(mesh, mats, volumetric);
    std::mt19937 rng(7);
    std::normal_distribution<double> normal;
    Eigen::VectorXd u(3 * mesh.V.rows()), v(3 * mesh.V.rows());
    for (Eigen::Index i = 0; i < u.size(); ++i) {
        u(i) = 1e-2 * normal(rng);
        v(i) = normal(rng);
    }
    // Energy: quadratic, so 1/2 u'Ku matches exactly.
    const double W = energy(mesh, mats, u, volumetric);
    CHECK(elastic_energy(K, u) == Approx(W).epsilon(1e-10));
    // Gradient: central difference of W along v equals (K u) . v.
    const double h = 1e-4;
    const double dW =
        (energy(mesh, mats, u + h * v, volumetric) - energy(mesh, mats, u - h * v, volumetric)) /
        (2 * h);
    CHECK(dW == Approx((K * u).dot(v)).epsilon(1e-7));
    // Hessian: the second central difference of W along v equals v'Kv.
    const double d2W = (energy(mesh, mats, u + h * v, volumetric) - 2 * W +
                        energy(mesh, mats, u - h * v, volumetric)) /
                       (h * h);
    CHECK(d2W == Approx(v.dot(K * v)).epsilon(1e-5));
}
