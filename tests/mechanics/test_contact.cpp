#include "mechanics/contact.hpp"
#include "mechanics/dome_model.hpp"

#include <catch2/catch.hpp>

#include <cmath>

using namespace chromasim::mechanics;

namespace {
const DomeModel& coarse_model() {
    static const DomeModel model(DomeModelOptions{});
    return model;
}
} // namespace

TEST_CASE("safety margin follows its definition and is clamped", "[mechanics][contact]") {
    CHECK(safety_margin(0.8, 1.0, 0.0) == Approx(1.0));
    CHECK(safety_margin(0.8, 1.0, 0.2) == Approx(0.75));
    CHECK(safety_margin(0.8, 1.0, 0.8) == Approx(0.0).margin(1e-15));
    CHECK(safety_margin(0.8, 1.0, 1.6) == 0.0);
    CHECK(safety_margin(0.0, 1.0, 0.0) == 0.0); // no frictional strength at all
}

TEST_CASE("two springs against a plane: active set and force control are exact",
          "[mechanics][contact]") {
    // Two decoupled nodes, compliances 1 and 2 mm/N (z), gaps 0 and 0.1 mm.
    Eigen::MatrixXd C = Eigen::MatrixXd::Zero(6, 6);
    C.diagonal() << 1, 1, 1, 2, 2, 2;
    Eigen::VectorXd gap(2);
    gap << 0.0, 0.1;
    SECTION("light load: one node in contact") {
        const ContactSolution s = solve_contact_step(C, gap, {0.05, {0, 0}, 0.5}, nullptr);
        REQUIRE(s.converged);
        CHECK(s.active == std::vector<int>{0});
        CHECK(s.indentation_mm == Approx(0.05)); // d = c1 P
    }
    SECTION("heavy load: both nodes, d from c1 f1 = d, c2 f2 = d - 0.1, f1 + f2 = P") {
        const double P = 1.0;
        const ContactSolution s = solve_contact_step(C, gap, {P, {0, 0}, 0.5}, nullptr);
        REQUIRE(s.converged);
        CHECK(s.active.size() == 2);
        const double d = (P + 0.1 / 2) / (1.0 + 0.5); // f1 = d, f2 = (d - 0.1) / 2
        CHECK(s.indentation_mm == Approx(d));
        CHECK(-s.forces_N(0, 2) == Approx(d));
        CHECK(s.normal_force_N == Approx(P));
    }
}

TEST_CASE("dome under a flat: force balance, no penetration, tensionless contact",
          "[mechanics][contact]") {
    const DomeModel& model = coarse_model();
    for (double P : {0.05, 0.5, 2.5}) {
        INFO("P = " << P);
        const FrameResult r = model.solve({P, {0, 0}, 0.8}, {true, true, true});
        REQUIRE(r.contact.converged);
        CHECK_FALSE(r.at_candidate_edge);
        CHECK(r.contact.normal_force_N == Approx(P).epsilon(1e-9));
        CHECK(r.contact.gamma == 1.0);
        for (int j : r.contact.active)
            CHECK(-r.contact.forces_N(j, 2) >= 0.0);
        // No node of the outer surface ends above the plane z = R - d.
        const double plane = 13.2 - r.contact.indentation_mm;
        for (int v = 0; v < model.mesh().V.rows(); ++v)
            REQUIRE(model.mesh().V(v, 2) + r.node_displacement_mm(v, 2) <= plane + 1e-7);
        // The apex markers move down with the indentation.
        CHECK(r.marker_points_mm(0, 2) < 10.75);
    }
}

TEST_CASE("dome contact stiffens with load: indentation and area grow with force",
          "[mechanics][contact]") {
    const DomeModel& model = coarse_model();
    double last_d = 0, last_area = 0;
    for (double P : {0.25, 0.5, 1.0, 2.0, 3.2}) {
        const FrameResult r = model.solve({P, {0, 0}, 0.8}, {});
        CHECK(r.contact.indentation_mm > last_d);
        CHECK(r.contact_area_mm2 >= last_area);
        last_d = r.contact.indentation_mm;
        last_area = r.contact_area_mm2;
    }
}

TEST_CASE("tangential pull: stick below mu P, full slip beyond, Gamma as defined",
          "[mechanics][contact]") {
    const DomeModel& model = coarse_model();
    const double P = 1.5, mu = 0.8;
    const FrameResult stick = model.solve({P, {0.3, 0.0}, mu}, {false, true});
    REQUIRE(stick.contact.converged);
    CHECK_FALSE(stick.contact.sliding);
    CHECK(stick.contact.tangential_force_N.x() == Approx(0.3));
    CHECK(stick.contact.tangential_force_N.y() == Approx(0.0).margin(1e-12));
    CHECK(stick.contact.gamma == Approx((mu * P - 0.3) / (mu * P)));
    // Pulling along +x drags the outer apex marker along +x, more than the inner one.
    const int per = model.markers().points_per_marker, n = model.markers().markers_per_layer;
    const double ux_outer = stick.marker_points_mm(n * per, 0) - model.markers().points(n * per, 0);
    const double ux_inner = stick.marker_points_mm(0, 0) - model.markers().points(0, 0);
    CHECK(ux_outer > 0);
    CHECK(ux_outer > ux_inner);

    const FrameResult slip = model.solve({P, {0.0, 5.0}, mu}, {});
    REQUIRE(slip.contact.converged);
    CHECK(slip.contact.sliding);
    CHECK(slip.contact.gamma == 0.0);
    CHECK(slip.contact.tangential_force_N.norm() == Approx(mu * P));
    CHECK(slip.contact.tangential_force_N.y() == Approx(mu * P)); // along the pull
}

TEST_CASE("every load of the grip range converges, sticking or sliding", "[mechanics][contact]") {
    const DomeModel& model = coarse_model();
    for (double P : {0.05, 0.25, 1.0, 2.5, 3.2})
        for (double ratio : {0.0, 0.1, 0.5, 0.9, 0.99, 1.0, 2.0})
            for (double mu : {0.0, 0.5, 1.1, 5.0}) {
                const ContactLoad load{P, {ratio * mu * P, 0.3 * ratio * mu * P}, mu};
                const FrameResult r = model.solve(load, {});
                INFO("P " << P << " ratio " << ratio << " mu " << mu);
                REQUIRE(r.contact.converged);
                CHECK_FALSE(r.at_candidate_edge);
                CHECK(r.contact.normal_force_N == Approx(P));
                CHECK(std::isfinite(r.contact.gamma));
                const double q = load.tangential_force_N.norm();
                const double ft = r.contact.tangential_force_N.norm();
                CHECK(r.contact.sliding == (q > 0 && q >= mu * P));
                CHECK(ft == Approx(r.contact.sliding ? mu * P : q).margin(1e-12));
            }
}

TEST_CASE("precomputed responses of coating and markers equal the full FE solve",
          "[mechanics][contact]") {
    const DomeModel& model = coarse_model();
    FrameRequest request{true, true, true};
    request.inner_surface = true;
    const FrameResult r = model.solve({2.0, {0.5, -0.4}, 0.8}, request);
    const SurfacePatch& coating = model.coating_surface();
    REQUIRE(r.coating_displacement_mm.rows() == Eigen::Index(coating.nodes.size()));
    const double scale = r.node_displacement_mm.cwiseAbs().maxCoeff();
    REQUIRE(scale > 0.1);
    double worst = 0;
    for (std::size_t i = 0; i < coating.nodes.size(); ++i)
        worst = std::max(worst, (r.coating_displacement_mm.row(Eigen::Index(i)) -
                                 r.node_displacement_mm.row(coating.nodes[i]))
                                    .cwiseAbs()
                                    .maxCoeff());
    // The inner surface: every vertex on the r = 10.5 mm sphere off the rim plane, normals
    // towards the centre, and its displacement equal to the full solve's.
    const SurfacePatch& inner = model.inner_surface();
    REQUIRE(inner.nodes.size() > 100);
    REQUIRE(r.inner_surface_displacement_mm.rows() == Eigen::Index(inner.nodes.size()));
    for (std::size_t i = 0; i < inner.nodes.size(); ++i) {
        const Eigen::RowVector3d X = model.mesh().V.row(inner.nodes[i]);
        CHECK(X.norm() == Approx(10.5).margin(0.05));
        worst = std::max(worst, (r.inner_surface_displacement_mm.row(Eigen::Index(i)) -
                                 r.node_displacement_mm.row(inner.nodes[i]))
                                    .cwiseAbs()
                                    .maxCoeff());
    }
    for (Eigen::Index f = 0; f < inner.F.rows(); ++f) {
        const Eigen::Vector3d a = model.mesh().V.row(inner.nodes[inner.F(f, 0)]),
                              b = model.mesh().V.row(inner.nodes[inner.F(f, 1)]),
                              c = model.mesh().V.row(inner.nodes[inner.F(f, 2)]);
        CHECK((b - a).cross(c - a).dot(a + b + c) < 0.0); // faces the centre
        CHECK(std::max({a.z(), b.z(), c.z()}) > 1e-9);    // not in the rim plane
    }
    // Markers: barycentric interpolation of the full field in the tet that holds each point.
    const TetLocator locator(model.mesh());
    const Points& X = model.markers().points;
    for (int p = 0; p < X.rows(); ++p) {
        const int t = locator.locate(X.row(p).transpose());
        const Eigen::Vector4d w = barycentric(model.mesh(), t, X.row(p).transpose());
        Eigen::RowVector3d x = X.row(p);
        for (int k = 0; k < 4; ++k)
            x += w(k) * r.node_displacement_mm.row(model.mesh().T(t, k));
        worst = std::max(worst, (r.marker_points_mm.row(p) - x).cwiseAbs().maxCoeff());
    }
    CHECK(worst < 1e-9 * scale);
}

TEST_CASE("object gaps: a flat touches the highest node, a sphere adds its sag",
          "[mechanics][contact]") {
    Points X(3, 3);
    X << 0, 0, 5.0, 3, 4, 5.0, 1, 0, 4.5; // r = 0, 5, 1
    const Eigen::VectorXd flat = object_gap({}, X);
    CHECK(flat(0) == 0.0);
    CHECK(flat(1) == 0.0);
    CHECK(flat(2) == Approx(0.5));
    const Eigen::VectorXd sphere = object_gap(sphere_object(10.0), X);
    CHECK(sphere(0) == 0.0);
    CHECK(sphere(1) == Approx(10.0 - std::sqrt(75.0)));
    CHECK(sphere(2) == Approx(0.5 + 10.0 - std::sqrt(99.0)));
}

TEST_CASE("dome under a sphere: smaller contact than a flat, flat as the radius grows",
          "[mechanics][contact]") {
    const DomeModel& model = coarse_model();
    const ContactLoad load{1.5, {0, 0}, 0.8};
    const FrameResult flat = model.solve(load, {});
    const FrameResult r45 = model.solve(load, {}, sphere_object(45.0));
    const FrameResult huge = model.solve(load, {}, sphere_object(1e6));
    REQUIRE(r45.contact.converged);
    CHECK(r45.contact.normal_force_N == Approx(1.5));
    CHECK(r45.contact_area_mm2 <= flat.contact_area_mm2); // nodal areas: coarse measure
    CHECK(r45.contact.indentation_mm > flat.contact.indentation_mm);
    // The sphere concentrates the load: a larger peak nodal force than the flat.
    CHECK(-r45.contact.forces_N.col(2).minCoeff() > -flat.contact.forces_N.col(2).minCoeff());
    CHECK(huge.contact.indentation_mm == Approx(flat.contact.indentation_mm).epsilon(1e-4));
    CHECK(huge.contact.active == flat.contact.active);
}

TEST_CASE("the volumetric formulation reaches the dome: nodal averaging is softer",
          "[mechanics][contact]") {
    DomeModelOptions element_options;
    element_options.volumetric = Volumetric::element;
    const DomeModel element(element_options);
    const ContactLoad load{1.5, {0, 0}, 0.8};
    const double d_nodal = coarse_model().solve(load, {}).contact.indentation_mm;
    const double d_element = element.solve(load, {}).contact.indentation_mm;
    CHECK(d_nodal > d_element * 1.01);
}

TEST_CASE("stiff cases: nu = 0.4999 and a 1000:1 layer stiffness ratio stay finite and converge",
          "[mechanics][contact][extreme]") {
    DomeModelOptions incompressible;
    for (auto& m : incompressible.materials)
        m.nu = 0.4999;
    DomeModelOptions contrast;
    contrast.materials[1].E_MPa = 0.01; // clear layer 1000 times softer than the others (10 MPa)
    for (int k : {0, 2, 3})
        contrast.materials[std::size_t(k)].E_MPa = 10.0;
    for (const DomeModelOptions* options : {&incompressible, &contrast}) {
        const DomeModel model(*options);
        for (double P : {0.05, 1.5}) {
            const FrameResult r = model.solve({P, {0.3 * P, 0.0}, 0.8}, {true, true, false});
            INFO("P " << P);
            REQUIRE(r.contact.converged);
            CHECK(r.contact.normal_force_N == Approx(P));
            CHECK(r.coating_displacement_mm.allFinite());
            CHECK(r.marker_points_mm.allFinite());
            CHECK(r.contact.indentation_mm > 0);
            CHECK(r.contact.indentation_mm < 13.2);
        }
    }
}

TEST_CASE("a rigid core under the shell: stiffer, the inner surface does not move",
          "[mechanics][contact]") {
    DomeModelOptions options;
    options.interior = DomeModelOptions::Interior::rigid_core;
    const DomeModel core(options);
    const ContactLoad load{1.5, {0.3, 0}, 0.8};
    const FrameResult r = core.solve(load, {false, false, true});
    REQUIRE(r.contact.converged);
    CHECK(r.contact.indentation_mm < 0.5 * coarse_model().solve(load, {}).contact.indentation_mm);
    const double r_inner = options.dome.radii_mm.front();
    int inner = 0;
    for (int v = 0; v < core.mesh().V.rows(); ++v)
        if (std::abs(core.mesh().V.row(v).norm() - r_inner) <= 1e-9 * r_inner) {
            ++inner;
            CHECK(r.node_displacement_mm.row(v).norm() == 0.0);
        }
    CHECK(inner > 100);
}

TEST_CASE("a soft fill: meshed inside the shell, between hollow and rigid core, tends to both "
          "limits",
          "[mechanics][contact]") {
    const ContactLoad load{1.5, {0.3, 0}, 0.8};
    const double hollow = coarse_model().solve(load, {}).contact.indentation_mm;
    DomeModelOptions core_options;
    core_options.interior = DomeModelOptions::Interior::rigid_core;
    const double core = DomeModel(core_options).solve(load, {}).contact.indentation_mm;

    DomeModelOptions options;
    options.interior = DomeModelOptions::Interior::soft_fill;
    const DomeModel gel(options); // 0.05 MPa: a clear silicone gel
    const TetMesh& mesh = gel.mesh();
    const double fill_volume = dome_layer_volume(options.dome, kFill);
    CHECK(mesh_volume(mesh, kFill) == Approx(fill_volume).epsilon(0.01));
    CHECK(mesh_volume(mesh) - mesh_volume(mesh, kFill) ==
          Approx(dome_layer_volume(options.dome)).epsilon(0.01));
    const FrameResult r = gel.solve(load, {false, false, true});
    REQUIRE(r.contact.converged);
    const double soft = r.contact.indentation_mm;
    CHECK(soft < 0.98 * hollow);
    CHECK(soft > 1.5 * core);
    // The fill's base does not move; the inner surface (bonded to the fill) does.
    const double r_inner = options.dome.radii_mm.front();
    double inner_max = 0;
    for (int v = 0; v < mesh.V.rows(); ++v) {
        CHECK(mesh.V(v, 2) >= 0.0);
        if (mesh.V(v, 2) == 0.0) CHECK(r.node_displacement_mm.row(v).norm() == 0.0);
        if (std::abs(mesh.V.row(v).norm() - r_inner) <= 1e-9 * r_inner)
            inner_max = std::max(inner_max, r.node_displacement_mm.row(v).norm());
    }
    CHECK(inner_max > 0.1);

    // Limits: a fill 500 times softer than the gel is nearly air; a 1000 MPa fill is nearly a
    // rigid core.
    options.fill.E_MPa = 1e-4;
    CHECK(DomeModel(options).solve(load, {}).contact.indentation_mm ==
          Approx(hollow).epsilon(0.002));
    options.fill.E_MPa = 1000;
    CHECK(DomeModel(options).solve(load, {}).contact.indentation_mm == Approx(core).epsilon(0.01));
}
