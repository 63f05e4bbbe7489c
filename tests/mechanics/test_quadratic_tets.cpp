// Quadratic (10-node) tets: shape functions, the curved dome's volume against the spheres',
// a cantilever against Timoshenko beam theory, and the neo-Hookean energy on them against
// the small-strain stiffness and finite differences.
#include "mechanics/dome_geometry.hpp"
#include "mechanics/dome_model.hpp"
#include "mechanics/linear_elasticity.hpp"
#include "mechanics/neo_hookean_quadratic.hpp"
#include "mechanics/quadratic_tets.hpp"
#include "mechanics/tetgen_adapter.hpp"

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <Eigen/SparseCholesky>
#include <catch2/catch.hpp>

#include <cmath>
#include <random>

using namespace chromasim::mechanics;

namespace {

/// TetGen box [0, L] x [0, W] x [0, W] mm.
TetMesh box_mesh(double L, double W, double max_volume_mm3) {
    Plc plc;
    plc.points.resize(8, 3);
    for (int i = 0; i < 8; ++i)
        plc.points.row(i) << (i & 1) * L, ((i >> 1) & 1) * W, ((i >> 2) & 1) * W;
    plc.facets = {{0, 1, 3, 2}, {4, 5, 7, 6}, {0, 1, 5, 4},
                  {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 3, 7, 5}};
    plc.regions.push_back({Eigen::Vector3d(L / 2, W / 2, W / 2), 1});
    TetgenOptions options;
    options.max_volume_mm3 = max_volume_mm3;
    options.preserve_surface = false;
    return tetrahedralize(plc, options);
}

/// Tip deflection (mm) of a cantilever [0, L] x [0, 1] x [0, 1] clamped at x = 0 under a
/// total force P (N) along -z spread over the tip face by tributary area.
double cantilever_tip(TetMesh mesh, bool quadratic, const Material& m, double L, double P) {
    if (quadratic) make_quadratic(mesh);
    const Eigen::SparseMatrix<double> K = assemble_stiffness(mesh, {m});
    const int n = int(mesh.V.rows());
    const auto tip_face = [L](const Eigen::Vector3d& p) { return std::abs(p.x() - L) < 1e-9; };
    const Triangles faces = split_faces(mesh, interface_faces(mesh, 1, -1));
    const std::vector<double> area = tributary_areas(mesh, faces, tip_face);
    std::vector<int> free_of(std::size_t(3 * n), -1);
    int kept = 0;
    for (int v = 0; v < n; ++v)
        if (mesh.V(v, 0) > 1e-9)
            for (int k = 0; k < 3; ++k)
                free_of[std::size_t(3 * v + k)] = kept++;
    Eigen::VectorXd f = Eigen::VectorXd::Zero(kept);
    double tip_area = 0;
    for (int v = 0; v < n; ++v)
        tip_area += area[std::size_t(v)];
    for (int v = 0; v < n; ++v)
        if (area[std::size_t(v)] > 0) f(free_of[std::size_t(3 * v + 2)]) = -P * area[v] / tip_area;
    const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(
        restrict_dofs(K, free_of, kept));
    REQUIRE(solver.info() == Eigen::Success);
    const Eigen::VectorXd u = solver.solve(f);
    double mean = 0;
    for (int v = 0; v < n; ++v)
        mean += area[std::size_t(v)] * u(free_of[std::size_t(3 * v + 2)]);
    return -mean / tip_area;
}

} // namespace

TEST_CASE("quadratic shape functions: a partition of unity, nodal, derivatives by differences",
          "[mechanics][quadratic]") {
    const Eigen::Vector4d L(0.1, 0.2, 0.3, 0.4);
    CHECK(shape10(L).sum() == Approx(1.0).epsilon(1e-14));
    // Node i sits at the corner or the edge midpoint; its function is 1 there, others 0.
    for (int i = 0; i < 10; ++i) {
        Eigen::Vector4d at = Eigen::Vector4d::Zero();
        if (i < 4) {
            at(i) = 1;
        } else {
            at(kTetEdges[i - 4][0]) = at(kTetEdges[i - 4][1]) = 0.5;
        }
        const Vector10d N = shape10(at);
        for (int j = 0; j < 10; ++j)
            CHECK(N(j) == Approx(i == j ? 1.0 : 0.0).margin(1e-14));
    }
    const Gradients10 D = shape10_derivatives(L);
    const double h = 1e-6;
    for (int k = 0; k < 3; ++k) {
        Eigen::Vector4d step = Eigen::Vector4d::Zero();
        step(k + 1) = h;
        step(0) = -h;
        const Vector10d fd = (shape10(L + step) - shape10(L - step)) / (2 * h);
        CHECK((fd - D.col(k)).norm() < 1e-8);
    }
}

TEST_CASE("quadratic dome: edge nodes on the spheres give each layer its volume",
          "[mechanics][quadratic]") {
    const DomeParams dome;
    TetMesh mesh = tetrahedralize(dome_plc(dome, mesh_level("coarse")), TetgenOptions{});
    const TetMesh linear = mesh;
    make_dome_quadratic(dome, mesh);
    REQUIRE(mesh.quadratic());
    CHECK(linear_part(mesh).V.rows() == linear.V.rows());
    for (int layer = 1; layer <= kLayerCount; ++layer) {
        const double exact = dome_layer_volume(dome, layer);
        const double flat = std::abs(mesh_volume(linear, layer) / exact - 1);
        const double curved = std::abs(mesh_volume(mesh, layer) / exact - 1);
        INFO("layer " << layer << ": linear " << flat << ", quadratic " << curved);
        CHECK(curved < 2e-4);
        CHECK(curved < 0.2 * flat);
    }
}

TEST_CASE("quadratic tets: a cantilever bends as Timoshenko's beam, linear tets lock",
          "[mechanics][quadratic]") {
    // 10 x 1 x 1 mm, E 1 MPa, nu 0.3, tip load 1 mN. Timoshenko: P L^3 / (3 E I) + P L /
    // (k G A) with I = 1/12, k = 5/6; the clamped end adds a little more (3D).
    const Material m{1.0, 0.3};
    const double L = 10, P = 1e-3;
    const double G = m.E_MPa / (2 * (1 + m.nu));
    const double beam = P * L * L * L / (3 * m.E_MPa / 12.0) + P * L / (5.0 / 6.0 * G);
    const TetMesh mesh = box_mesh(L, 1.0, 0.05);
    const double quadratic = cantilever_tip(mesh, true, m, L, P);
    const double linear = cantilever_tip(mesh, false, m, L, P);
    INFO("beam " << beam << " mm, quadratic " << quadratic << ", linear " << linear);
    CHECK(quadratic / beam == Approx(1.0).margin(0.03));
    CHECK(linear / beam < 0.8);
}

// The Hessian at rest is the small-strain stiffness; energy, gradient and Hessian agree with
// finite differences; a rigid motion costs no energy and no force.
TEST_CASE("quadratic neo-Hookean: small-strain limit, differences, rigid motions",
          "[mechanics][quadratic]") {
    TetMesh mesh = box_mesh(2.0, 1.0, 0.2);
    make_quadratic(mesh);
    const std::vector<Material> materials{{0.8, 0.45}};
    const NeoHookeanQuadratic nh(mesh, materials);
    const int dofs = nh.dofs();
    const Eigen::SparseMatrix<double> K = assemble_quadratic_stiffness(mesh, materials);
    const Eigen::SparseMatrix<double> H0 = nh.hessian(Eigen::VectorXd::Zero(dofs), false);
    CHECK((Eigen::MatrixXd(H0) - Eigen::MatrixXd(K)).norm() < 1e-10 * Eigen::MatrixXd(K).norm());

    std::mt19937 rng(7);
    std::uniform_real_distribution<double> d(-0.05, 0.05);
    Eigen::VectorXd u(dofs);
    for (int i = 0; i < dofs; ++i)
        u(i) = d(rng);
    const Eigen::VectorXd g = nh.gradient(u);
    const Eigen::SparseMatrix<double> H = nh.hessian(u, false);
    Eigen::VectorXd dir(dofs);
    for (int i = 0; i < dofs; ++i)
        dir(i) = d(rng);
    const double h = 1e-6;
    const double fd_energy = (nh.energy(u + h * dir) - nh.energy(u - h * dir)) / (2 * h);
    CHECK(fd_energy == Approx(g.dot(dir)).epsilon(1e-6));
    const Eigen::VectorXd fd_gradient =
        (nh.gradient(u + h * dir) - nh.gradient(u - h * dir)) / (2 * h);
    CHECK((fd_gradient - H * dir).norm() < 1e-6 * (H * dir).norm());

    // A rotation by 60 deg about (1, 2, 3) and a shift: no energy, no force.
    const Eigen::Matrix3d R =
        Eigen::AngleAxisd(1.0472, Eigen::Vector3d(1, 2, 3).normalized()).matrix();
    Eigen::VectorXd rigid(dofs);
    for (int v = 0; v < mesh.V.rows(); ++v)
        rigid.segment<3>(3 * v) = (R - Eigen::Matrix3d::Identity()) * mesh.V.row(v).transpose() +
                                  Eigen::Vector3d(0.3, -0.2, 0.1);
    CHECK(std::abs(nh.energy(rigid)) < 1e-12);
    CHECK(nh.gradient(rigid).norm() < 1e-10);
    CHECK(nh.min_jacobian(rigid) == Approx(1.0).epsilon(1e-12));
}

TEST_CASE("quadratic dome: frictionless presses within 3 % of CalculiX's indentation",
          "[mechanics][quadratic]") {
    // CalculiX 2.20, NLGEOM with *HYPERELASTIC, NEO HOOKE, curved C3D10 of a 30 deg sector at
    // h 0.5 mm (converged to 0.3 %): scripts/crosscheck-calculix, docs/VALIDATION.md.
    DomeModelOptions options;
    options.mesh_level = "very_coarse";
    options.element_order = 2;
    options.material = MaterialModel::neo_hookean;
    options.contact_candidate_angle_deg = 50;
    const DomeModel model(options);
    struct Press {
        ObjectShape object;
        double force_N, calculix_mm;
    };
    const Press presses[] = {{ObjectShape{}, 1.0, 1.2625},
                             {ObjectShape{}, 3.2, 3.0725},
                             {sphere_object(45.0), 1.0, 1.3765},
                             {sphere_object(45.0), 3.2, 3.6131}};
    for (const Press& p : presses) {
        const FrameResult r = model.solve(ContactLoad{p.force_N, {0.0, 0.0}, 0.0}, {}, p.object);
        INFO((p.object.kind == ObjectShape::Kind::flat ? "flat" : "sphere")
             << " at " << p.force_N << " N: " << r.contact.indentation_mm << " mm, CalculiX "
             << p.calculix_mm << ", " << r.contact.status << ", " << r.material_iterations
             << " iterations, edge " << r.at_candidate_edge);
        CHECK(r.contact.converged);
        CHECK(r.contact.indentation_mm / p.calculix_mm == Approx(1.0).margin(0.03));
    }
}
