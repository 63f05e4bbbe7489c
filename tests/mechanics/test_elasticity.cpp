#include "mechanics/elastic_body.hpp"
#include "mechanics/linear_elasticity.hpp"
#include "mechanics/tetgen_adapter.hpp"

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <Eigen/SparseCholesky>
#include <catch2/catch.hpp>

using namespace chromasim::mechanics;

namespace {

/// A unit-ish box [0,2]x[0,1]x[0,1.5] mm meshed by TetGen with quality (interior nodes).
TetMesh box_mesh() {
    Plc plc;
    plc.points.resize(8, 3);
    const double L[3] = {2.0, 1.0, 1.5};
    for (int i = 0; i < 8; ++i)
        plc.points.row(i) << (i & 1) * L[0], ((i >> 1) & 1) * L[1], ((i >> 2) & 1) * L[2];
    plc.facets = {{0, 1, 3, 2}, {4, 5, 7, 6}, {0, 1, 5, 4},
                  {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 3, 7, 5}};
    plc.regions.push_back({Eigen::Vector3d(1.0, 0.5, 0.7), 1});
    TetgenOptions options;
    options.max_volume_mm3 = 0.01;
    options.preserve_surface = false; // Steiner points on the faces too
    return tetrahedralize(plc, options);
}

bool on_box_boundary(const Eigen::Vector3d& x) {
    const double L[3] = {2.0, 1.0, 1.5};
    for (int k = 0; k < 3; ++k)
        if (std::abs(x(k)) < 1e-12 || std::abs(x(k) - L[k]) < 1e-12) return true;
    return false;
}

} // namespace

TEST_CASE("single tet stiffness: symmetric, rigid modes free, uniaxial strain energy",
          "[mechanics][fem]") {
    Eigen::Matrix<double, 4, 3> X;
    X << 0, 0, 0, 1.3, 0.1, 0, 0.2, 0.9, 0.1, 0.1, 0.3, 1.1;
    const Material m{2.0, 0.3};
    const Matrix12d K = tet_stiffness(X, m);
    CHECK((K - K.transpose()).norm() < 1e-12 * K.norm());
    // Rigid translations and an infinitesimal rotation produce no force.
    for (int k = 0; k < 3; ++k) {
        Eigen::Matrix<double, 12, 1> u = Eigen::Matrix<double, 12, 1>::Zero();
        for (int a = 0; a < 4; ++a)
            u(3 * a + k) = 1.0;
        CHECK((K * u).norm() < 1e-12 * K.norm());
    }
    Eigen::Matrix<double, 12, 1> rot;
    for (int a = 0; a < 4; ++a)
        rot.segment<3>(3 * a) = Eigen::Vector3d(0, 0, 1).cross(X.row(a).transpose());
    CHECK((K * rot).norm() < 1e-12 * K.norm());
    // u = eps * x e_x: energy density = 1/2 (lambda + 2 mu) eps^2 times the volume.
    const double eps = 1e-3;
    Eigen::Matrix<double, 12, 1> u = Eigen::Matrix<double, 12, 1>::Zero();
    for (int a = 0; a < 4; ++a)
        u(3 * a) = eps * X(a, 0);
    Eigen::Matrix3d E;
    for (int k = 0; k < 3; ++k)
        E.col(k) = (X.row(k + 1) - X.row(0)).transpose();
    const double vol = E.determinant() / 6;
    const double lambda = m.E_MPa * m.nu / ((1 + m.nu) * (1 - 2 * m.nu));
    const double mu = m.E_MPa / (2 * (1 + m.nu));
    CHECK(0.5 * u.dot(K * u) == Approx(0.5 * (lambda + 2 * mu) * eps * eps * vol).epsilon(1e-12));
}

TEST_CASE("patch test: a linear displacement field is reproduced to 1e-9", "[mechanics][fem]") {
    const TetMesh mesh = box_mesh();
    const Volumetric volumetric = GENERATE(Volumetric::element, Volumetric::nodal_average);
    INFO("volumetric " << int(volumetric));
    const auto K = assemble_stiffness(mesh, {Material{0.8, 0.4999}}, volumetric);
    const int n = int(mesh.V.rows());
    // u(x) = A x + b with a general A (stretch, shear, rotation-ish).
    Eigen::Matrix3d A;
    A << 1e-2, 3e-3, -2e-3, 1e-3, -5e-3, 4e-3, 2e-3, 1e-3, 7e-3;
    const Eigen::Vector3d b(0.1, -0.2, 0.05);
    std::vector<int> interior;
    Eigen::VectorXd u_exact(3 * n), u = Eigen::VectorXd::Zero(3 * n);
    std::vector<bool> fixed(std::size_t(3 * n), false);
    for (int v = 0; v < n; ++v) {
        const Eigen::Vector3d x = mesh.V.row(v);
        u_exact.segment<3>(3 * v) = A * x + b;
        if (on_box_boundary(x)) {
            for (int k = 0; k < 3; ++k)
                fixed[3 * v + k] = true;
            u.segment<3>(3 * v) = u_exact.segment<3>(3 * v);
        } else {
            interior.push_back(v);
        }
    }
    REQUIRE(interior.size() > 10);
    // Solve K_ii u_i = -K_ib u_b.
    std::vector<int> idx(std::size_t(3 * n), -1);
    int m = 0;
    for (int d = 0; d < 3 * n; ++d)
        if (!fixed[d]) idx[d] = m++;
    Eigen::VectorXd rhs = -(K * u);
    const Eigen::SparseMatrix<double> Kii = restrict_dofs(K, idx, m);
    Eigen::VectorXd r(m);
    for (int d = 0; d < 3 * n; ++d)
        if (idx[d] >= 0) r(idx[d]) = rhs(d);
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(Kii);
    REQUIRE(ldlt.info() == Eigen::Success);
    const Eigen::VectorXd ui = ldlt.solve(r);
    for (int d = 0; d < 3 * n; ++d)
        if (idx[d] >= 0) u(d) = ui(idx[d]);
    CHECK((u - u_exact).cwiseAbs().maxCoeff() < 1e-9);
    // And the residual force at interior nodes vanishes for the exact field.
    const Eigen::VectorXd f = K * u_exact;
    for (int v : interior)
        CHECK(f.segment<3>(3 * v).norm() < 1e-9);
}

TEST_CASE("nodal-average volumetric stiffness: same energy for uniform strain, softer in bending",
          "[mechanics][fem]") {
    const TetMesh mesh = box_mesh();
    const std::vector<Material> m{Material{1.0, 0.49}};
    const auto Ke = assemble_stiffness(mesh, m, Volumetric::element);
    const auto Kn = assemble_stiffness(mesh, m, Volumetric::nodal_average);
    CHECK((Eigen::MatrixXd(Kn) - Eigen::MatrixXd(Kn).transpose()).norm() < 1e-12 * Kn.norm());
    const int n = int(mesh.V.rows());
    Eigen::VectorXd uniform(3 * n), bend(3 * n);
    for (int v = 0; v < n; ++v) {
        const Eigen::Vector3d x = mesh.V.row(v);
        uniform.segment<3>(3 * v) = Eigen::Vector3d(1e-3 * x.x(), -2e-3 * x.y(), 5e-4 * x.z());
        // A quadratic (bending-like) field: div u varies in space.
        bend.segment<3>(3 * v) = Eigen::Vector3d(1e-2 * x.x() * x.z(), 0, -5e-3 * x.x() * x.x());
    }
    CHECK(elastic_energy(Kn, uniform) == Approx(elastic_energy(Ke, uniform)).epsilon(1e-12));
    CHECK(elastic_energy(Kn, bend) < elastic_energy(Ke, bend));
    // Rigid motions stay free.
    Eigen::VectorXd rot(3 * n);
    for (int v = 0; v < n; ++v)
        rot.segment<3>(3 * v) = Eigen::Vector3d(0.3, -0.2, 1.0).cross(mesh.V.row(v).transpose());
    CHECK((Kn * rot).norm() < 1e-10 * Kn.norm());
}

TEST_CASE("single-precision factor: within float round-off of CHOLMOD's double solve, stiff too",
          "[mechanics][fem]") {
    const TetMesh mesh = box_mesh();
    // nu 0.4999: nearly incompressible, the worst conditioning the spec allows.
    const double nu = GENERATE(0.45, 0.4999);
    INFO("nu " << nu);
    const int n = int(mesh.V.rows());
    std::vector<bool> clamped(static_cast<std::size_t>(n), false);
    std::vector<int> top;
    for (int v = 0; v < n; ++v) {
        clamped[std::size_t(v)] = mesh.V(v, 2) < 1e-12;
        if (std::abs(mesh.V(v, 2) - 1.5) < 1e-12) top.push_back(v);
    }
    const ElasticBody body(mesh, {Material{0.8, nu}}, clamped, top, {}, Embedding{},
                           Volumetric::nodal_average);
    // A smooth load on the top and a rough one (every dof, alternating signs).
    Eigen::VectorXd smooth = Eigen::VectorXd::Zero(3 * n), rough = smooth;
    for (int v : top)
        smooth(3 * v + 2) = -1e-2 * (1 + mesh.V(v, 0));
    for (int d = 0; d < 3 * n; ++d)
        rough(d) = (d % 7 - 3) * 1e-3;
    for (const Eigen::VectorXd& f : {smooth, rough}) {
        const Eigen::VectorXd exact = body.solve(f), single = body.precondition(f);
        CHECK((single - exact).norm() <= 1e-4 * exact.norm());
    }
    // The field responses (blocks of right-hand sides) equal single solves of unit forces.
    const Eigen::MatrixXf& field = body.candidate_field_responses();
    for (int c : {0, 3 * int(top.size()) / 2 + 1, 3 * int(top.size()) - 1}) {
        Eigen::VectorXd unit = Eigen::VectorXd::Zero(3 * n);
        unit(3 * top[std::size_t(c / 3)] + c % 3) = 1;
        const Eigen::VectorXd exact = body.solve(unit);
        CHECK((field.col(c).cast<double>() - exact).norm() <= 1e-4 * exact.norm());
    }
}
