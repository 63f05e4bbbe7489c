// Neo-Hookean energy: small-strain limit against assemble_stiffness, derivatives by finite
// differences, frame invariance, closed forms for homogeneous stretches, inversion, and the
// positive semi-definite projection of the Hessian.
#include "mechanics/dome_geometry.hpp"
#include "mechanics/linear_elasticity.hpp"
#include "mechanics/neo_hookean.hpp"
#include "mechanics/tetgen_adapter.hpp"

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <catch2/catch.hpp>
#include <tbb/global_control.h>

#include <cmath>
#include <limits>
#include <random>

using namespace chromasim::mechanics;

namespace {

/// TetGen box [0, L0] x [0, L1] x [0, L2] mm; two regions (split at x = L0 / 2) if asked.
TetMesh box_mesh(double max_volume_mm3, bool two_regions) {
    const double L[3] = {1.0, 0.8, 0.6};
    Plc plc;
    plc.points.resize(8, 3);
    for (int i = 0; i < 8; ++i)
        plc.points.row(i) << (i & 1) * L[0], ((i >> 1) & 1) * L[1], ((i >> 2) & 1) * L[2];
    plc.facets = {{0, 1, 3, 2}, {4, 5, 7, 6}, {0, 1, 5, 4},
                  {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 3, 7, 5}};
    plc.regions.push_back({Eigen::Vector3d(0.5, 0.4, 0.3), 1});
    TetgenOptions options;
    options.max_volume_mm3 = max_volume_mm3;
    options.preserve_surface = false;
    TetMesh mesh = tetrahedralize(plc, options);
    if (two_regions)
        for (int t = 0; t < mesh.T.rows(); ++t)
            mesh.region(t) =
                mesh.V.row(mesh.T(t, 0)).x() + mesh.V.row(mesh.T(t, 1)).x() < L[0] ? 1 : 2;
    return mesh;
}

/// Unit cube split into 6 tets around its diagonal (Kuhn), positively oriented.
TetMesh cube_mesh() {
    TetMesh mesh;
    mesh.V.resize(8, 3);
    for (int i = 0; i < 8; ++i)
        mesh.V.row(i) << (i & 1), ((i >> 1) & 1), ((i >> 2) & 1);
    const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    mesh.T.resize(6, 4);
    for (int k = 0; k < 6; ++k) {
        const int v1 = 1 << perms[k][0], v2 = v1 | (1 << perms[k][1]);
        mesh.T.row(k) << 0, v1, v2, 7;
        if (tet_volume(mesh, k) < 0) std::swap(mesh.T(k, 1), mesh.T(k, 2));
    }
    mesh.region = Eigen::VectorXi::Ones(6);
    return mesh;
}

/// Displacement of the affine map x = A X + b.
Eigen::VectorXd affine(const TetMesh& mesh, const Eigen::Matrix3d& A,
                       const Eigen::Vector3d& b = Eigen::Vector3d::Zero()) {
    Eigen::VectorXd u(3 * mesh.V.rows());
    for (Eigen::Index v = 0; v < mesh.V.rows(); ++v) {
        const Eigen::Vector3d X = mesh.V.row(v).transpose();
        u.segment<3>(3 * v) = A * X + b - X;
    }
    return u;
}

/// Moderate random deformation: an affine part with |grad u| about 0.1 plus nodal noise.
Eigen::VectorXd random_deformation(const TetMesh& mesh, unsigned seed) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> normal;
    Eigen::Matrix3d A;
    for (int k = 0; k < 9; ++k)
        A(k / 3, k % 3) = (k % 4 == 0 ? 1.0 : 0.0) + 0.1 * normal(rng);
    Eigen::VectorXd u = affine(mesh, A);
    for (Eigen::Index i = 0; i < u.size(); ++i)
        u(i) += 0.004 * normal(rng);
    return u;
}

double lame_mu(const Material& m) {
    return m.E_MPa / (2 * (1 + m.nu));
}
double bulk(const Material& m) {
    return m.E_MPa / (3 * (1 - 2 * m.nu));
}

/// Closed form of the energy density for F = diag(l).
double density(const Material& m, const Eigen::Vector3d& l) {
    const double J = l.prod();
    return lame_mu(m) / 2 * (std::pow(J, -2.0 / 3.0) * l.squaredNorm() - 3) +
           bulk(m) / 2 * (J - 1) * (J - 1);
}

Eigen::MatrixXd dense_fd_hessian(const NeoHookean& nh, const Eigen::VectorXd& u, double h) {
    Eigen::MatrixXd H(u.size(), u.size());
    for (Eigen::Index i = 0; i < u.size(); ++i) {
        Eigen::VectorXd up = u, um = u;
        up(i) += h;
        um(i) -= h;
        H.col(i) = (nh.gradient(up) - nh.gradient(um)) / (2 * h);
    }
    return H;
}

double min_eigenvalue(const Eigen::SparseMatrix<double>& H) {
    const Eigen::MatrixXd D(H);
    return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(D).eigenvalues()(0);
}

const std::vector<Material> kMaterials{{1.0, 0.45}, {0.2, 0.499}};

} // namespace

TEST_CASE("neo-Hookean Hessian at rest equals the linear stiffness", "[mechanics][neo_hookean]") {
    const TetMesh mesh = box_mesh(0.002, true);
    const Volumetric volumetric = GENERATE(Volumetric::element, Volumetric::nodal_average);
    INFO("volumetric " << int(volumetric));
    const NeoHookean nh(mesh, kMaterials, volumetric);
    const Eigen::SparseMatrix<double> K = assemble_stiffness(mesh, kMaterials, volumetric);
    const Eigen::VectorXd zero = Eigen::VectorXd::Zero(3 * mesh.V.rows());
    for (bool project : {false, true}) {
        INFO("project_psd " << project);
        const Eigen::SparseMatrix<double> H = nh.hessian(zero, project);
        CHECK(H.nonZeros() == nh.hessian_pattern().nonZeros());
        const Eigen::SparseMatrix<double> diff = H - K;
        CHECK(diff.norm() < 1e-9 * K.norm());
        CHECK(diff.coeffs().cwiseAbs().maxCoeff() < 1e-9 * K.coeffs().cwiseAbs().maxCoeff());
    }
    CHECK(nh.energy(zero) == 0.0);
    CHECK(nh.gradient(zero).cwiseAbs().maxCoeff() < 1e-12);
    CHECK(nh.min_jacobian(zero) == Approx(1.0).epsilon(1e-14));
    // Small strain: the energy approaches 1/2 u^T K u (the cubic remainder scales with |u|).
    const Eigen::VectorXd u = 1e-5 * random_deformation(mesh, 3);
    CHECK(nh.energy(u) == Approx(elastic_energy(K, u)).epsilon(1e-4));
}

TEST_CASE("neo-Hookean gradient and Hessian match finite differences", "[mechanics][neo_hookean]") {
    const TetMesh mesh = box_mesh(0.01, true);
    const Volumetric volumetric = GENERATE(Volumetric::element, Volumetric::nodal_average);
    INFO("volumetric " << int(volumetric) << ", " << mesh.T.rows() << " tets");
    const NeoHookean nh(mesh, kMaterials, volumetric);
    const Eigen::VectorXd u = random_deformation(mesh, 11);
    REQUIRE(nh.min_jacobian(u) > 0.5);
    const double h = 1e-6;
    const Eigen::VectorXd g = nh.gradient(u);
    Eigen::VectorXd g_fd(u.size());
    for (Eigen::Index i = 0; i < u.size(); ++i) {
        Eigen::VectorXd up = u, um = u;
        up(i) += h;
        um(i) -= h;
        g_fd(i) = (nh.energy(up) - nh.energy(um)) / (2 * h);
    }
    CHECK((g_fd - g).norm() < 1e-6 * g.norm());
    const Eigen::MatrixXd H(nh.hessian(u, false));
    CHECK((H - H.transpose()).norm() < 1e-12 * H.norm());
    const Eigen::MatrixXd H_fd = dense_fd_hessian(nh, u, h);
    CHECK((H_fd - H).norm() < 1e-6 * H.norm());
}

TEST_CASE("neo-Hookean rigid motion: no energy, no force, rotated stiffness",
          "[mechanics][neo_hookean]") {
    const TetMesh mesh = box_mesh(0.01, true);
    const Volumetric volumetric = GENERATE(Volumetric::element, Volumetric::nodal_average);
    INFO("volumetric " << int(volumetric));
    const NeoHookean nh(mesh, kMaterials, volumetric);
    const Eigen::Matrix3d R =
        Eigen::AngleAxisd(M_PI / 6, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    const Eigen::VectorXd u = affine(mesh, R, Eigen::Vector3d(0.3, -0.2, 0.5));
    // Reference: a 10 % uniaxial stretch of the same body.
    const Eigen::VectorXd u_ref = affine(mesh, Eigen::Vector3d(1.1, 1, 1).asDiagonal());
    const double W_ref = nh.energy(u_ref);
    CHECK(std::abs(nh.energy(u)) < 1e-9 * W_ref);
    CHECK(nh.gradient(u).norm() < 1e-9 * nh.gradient(u_ref).norm());
    CHECK(nh.min_jacobian(u) == Approx(1.0).epsilon(1e-12));
    // Objectivity: H(R x) = R H(x) R^T, blockwise.
    const Eigen::Index n = mesh.V.rows();
    std::vector<Eigen::Triplet<double>> trips;
    for (Eigen::Index v = 0; v < n; ++v)
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
                trips.emplace_back(int(3 * v + i), int(3 * v + j), R(i, j));
    Eigen::SparseMatrix<double> Rb(3 * n, 3 * n);
    Rb.setFromTriplets(trips.begin(), trips.end());
    const Eigen::SparseMatrix<double> K = nh.hessian(Eigen::VectorXd::Zero(3 * n), false);
    const Eigen::SparseMatrix<double> rotated =
        Rb * K * Eigen::SparseMatrix<double>(Rb.transpose());
    CHECK((nh.hessian(u, false) - rotated).norm() < 1e-9 * K.norm());
}

TEST_CASE("neo-Hookean homogeneous stretch: closed-form energy and face force",
          "[mechanics][neo_hookean]") {
    const Volumetric volumetric = GENERATE(Volumetric::element, Volumetric::nodal_average);
    INFO("volumetric " << int(volumetric));
    const Eigen::Vector3d l(1.3, 0.9, 1.05);
    SECTION("single tet") {
        TetMesh tet;
        tet.V.resize(4, 3);
        tet.V << 0, 0, 0, 1.3, 0.1, 0, 0.2, 0.9, 0.1, 0.1, 0.3, 1.1;
        tet.T.resize(1, 4);
        tet.T << 0, 1, 2, 3;
        tet.region = Eigen::VectorXi::Ones(1);
        const NeoHookean nh(tet, kMaterials, volumetric);
        const Eigen::VectorXd u = affine(tet, l.asDiagonal(), Eigen::Vector3d(1, 2, 3));
        CHECK(nh.energy(u) ==
              Approx(tet_volume(tet, 0) * density(kMaterials[0], l)).epsilon(1e-12));
        CHECK(nh.min_jacobian(u) == Approx(l.prod()).epsilon(1e-14));
    }
    SECTION("two-material box") {
        const TetMesh mesh = box_mesh(0.01, true);
        const NeoHookean nh(mesh, kMaterials, volumetric);
        const Eigen::VectorXd u = affine(mesh, l.asDiagonal());
        const double W = mesh_volume(mesh, 1) * density(kMaterials[0], l) +
                         mesh_volume(mesh, 2) * density(kMaterials[1], l);
        CHECK(nh.energy(u) == Approx(W).epsilon(1e-12));
    }
    SECTION("uniaxial stretch of a one-material box: free interior, P11 times the face area") {
        const TetMesh mesh = box_mesh(0.002, false);
        const Material m = kMaterials[0];
        const NeoHookean nh(mesh, {m}, volumetric);
        const double s = 1.2;
        const Eigen::VectorXd g = nh.gradient(affine(mesh, Eigen::Vector3d(s, 1, 1).asDiagonal()));
        // P11 = dW/ds for F = diag(s, 1, 1).
        const double P11 =
            lame_mu(m) * std::pow(s, -2.0 / 3.0) * (s - (s * s + 2) / (3 * s)) + bulk(m) * (s - 1);
        double face_force = 0, interior = 0;
        int interior_nodes = 0;
        for (Eigen::Index v = 0; v < mesh.V.rows(); ++v) {
            const Eigen::Vector3d X = mesh.V.row(v).transpose();
            const bool boundary = (X.array().abs() < 1e-12).any() ||
                                  std::abs(X.x() - 1.0) < 1e-12 || std::abs(X.y() - 0.8) < 1e-12 ||
                                  std::abs(X.z() - 0.6) < 1e-12;
            if (!boundary) {
                ++interior_nodes;
                interior = std::max(interior, g.segment<3>(3 * v).norm());
            }
            if (std::abs(X.x() - 1.0) < 1e-12) face_force += g(3 * v);
        }
        REQUIRE(interior_nodes > 10);
        CHECK(face_force == Approx(P11 * 0.8 * 0.6).epsilon(1e-10));
        CHECK(interior < 1e-10 * std::abs(face_force));
    }
}

TEST_CASE("neo-Hookean inverted element: infinite energy, J <= 0", "[mechanics][neo_hookean]") {
    const Volumetric volumetric = GENERATE(Volumetric::element, Volumetric::nodal_average);
    INFO("volumetric " << int(volumetric));
    TetMesh tet;
    tet.V.resize(4, 3);
    tet.V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
    tet.T.resize(1, 4);
    tet.T << 0, 1, 2, 3;
    tet.region = Eigen::VectorXi::Ones(1);
    const NeoHookean nh(tet, kMaterials, volumetric);
    Eigen::VectorXd u = Eigen::VectorXd::Zero(12);
    u(11) = -1.5; // apex through the opposite face: J = -0.5
    CHECK(nh.energy(u) == std::numeric_limits<double>::infinity());
    CHECK(nh.min_jacobian(u) == Approx(-0.5).epsilon(1e-14));
    CHECK_THROWS_AS(nh.gradient(u), std::domain_error);
    CHECK_THROWS_AS(nh.hessian(u, true), std::domain_error);
    u(11) = -1.0; // flat: J = 0
    CHECK(nh.energy(u) == std::numeric_limits<double>::infinity());
    CHECK(nh.min_jacobian(u) <= 0);
    u(11) = -0.9; // squashed but valid: finite
    CHECK(std::isfinite(nh.energy(u)));
    // One interior node of a box pushed far away inverts the tets around it.
    const TetMesh mesh = box_mesh(0.01, true);
    const NeoHookean box(mesh, kMaterials, volumetric);
    Eigen::Index interior = 0; // the node nearest the centre
    (mesh.V.rowwise() - Eigen::RowVector3d(0.5, 0.4, 0.3)).rowwise().norm().minCoeff(&interior);
    Eigen::VectorXd v = Eigen::VectorXd::Zero(3 * mesh.V.rows());
    v.segment<3>(3 * interior) << 2.0, 2.0, 2.0;
    CHECK(box.min_jacobian(v) <= 0);
    CHECK(box.energy(v) == std::numeric_limits<double>::infinity());
}

TEST_CASE("neo-Hookean projected Hessian is positive semi-definite under strong compression",
          "[mechanics][neo_hookean]") {
    const Volumetric volumetric = GENERATE(Volumetric::element, Volumetric::nodal_average);
    INFO("volumetric " << int(volumetric));
    const TetMesh mesh = cube_mesh();
    const NeoHookean nh(mesh, {Material{1.0, 0.45}}, volumetric);
    Eigen::Matrix3d A = Eigen::Vector3d(0.5, 0.7, 0.6).asDiagonal();
    A(0, 1) = 0.2;
    Eigen::VectorXd u = affine(mesh, A);
    u(3 * 5 + 2) += 0.05; // not quite homogeneous
    REQUIRE(nh.min_jacobian(u) > 0);
    const Eigen::SparseMatrix<double> H = nh.hessian(u, false);
    const Eigen::SparseMatrix<double> Hp = nh.hessian(u, true);
    const double scale = Eigen::MatrixXd(H).norm();
    CHECK(min_eigenvalue(H) < -1e-3 * scale);
    CHECK(min_eigenvalue(Hp) > -1e-12 * scale);
    CHECK((Eigen::MatrixXd(Hp) - Eigen::MatrixXd(Hp).transpose()).norm() < 1e-12 * scale);
    // The projection leaves a state that is already convex alone (the rest state).
    const Eigen::VectorXd zero = Eigen::VectorXd::Zero(u.size());
    CHECK((nh.hessian(zero, true) - nh.hessian(zero, false)).norm() < 1e-12 * scale);
}

TEST_CASE("neo-Hookean results do not depend on the thread count", "[mechanics][neo_hookean]") {
    const TetMesh mesh = box_mesh(0.003, true);
    const Volumetric volumetric = GENERATE(Volumetric::element, Volumetric::nodal_average);
    INFO("volumetric " << int(volumetric));
    const NeoHookean nh(mesh, kMaterials, volumetric);
    const Eigen::VectorXd u = random_deformation(mesh, 5);
    const double W = nh.energy(u);
    const Eigen::VectorXd g = nh.gradient(u);
    Eigen::SparseMatrix<double> H = nh.hessian(u, true);
    const Eigen::SparseMatrix<double> H_many = H;
    {
        const tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
        CHECK(nh.energy(u) == W);
        CHECK(nh.gradient(u) == g);
        nh.hessian(u, true, H); // in place, on the same pattern
        CHECK(H.nonZeros() == H_many.nonZeros());
        CHECK(Eigen::Map<const Eigen::VectorXd>(H.valuePtr(), H.nonZeros()) ==
              Eigen::Map<const Eigen::VectorXd>(H_many.valuePtr(), H_many.nonZeros()));
    }
}
