// Coulomb friction with stick/slip history: analytic single-node cycles, force against
// displacement control, a seed-001-style sliding ramp on the dome, per-node outputs and the
// surface strain grid.
#include "mechanics/contact.hpp"
#include "mechanics/dome_model.hpp"
#include "mechanics/surface_strain.hpp"

#include <catch2/catch.hpp>

#include <array>
#include <cmath>
#include <thread>
#include <tuple>
#include <vector>

using namespace chromasim::mechanics;

namespace {

const DomeModel& coarse_model() {
    static const DomeModel model(DomeModelOptions{});
    return model;
}

ContactLoad displaced(double P, double w, double mu) {
    ContactLoad l{P, {0, 0}, mu};
    l.tangential = TangentialControl::displacement;
    l.tangential_displacement_mm = {w, 0};
    return l;
}

} // namespace

TEST_CASE("one node under a displacement cycle: elastic stick, slip at mu P, reverse slip",
          "[mechanics][friction]") {
    // One node, compliance 0.5 mm/N along x and y (stiffness k = 2 N/mm), 1 mm/N along z.
    Eigen::MatrixXd C = Eigen::MatrixXd::Zero(3, 3);
    C.diagonal() << 0.5, 0.5, 1.0;
    const Eigen::VectorXd gap = Eigen::VectorXd::Zero(1);
    const double P = 1.0, mu = 0.5, k = 2.0; // slip at w = mu P / k = 0.25 mm
    ContactSolution s = solve_contact_step(C, gap, {P, {0, 0}, mu}, nullptr);
    REQUIRE(s.converged);
    // Tangential force for a displacement history, by hand: t = k (w - anchor), clamped at
    // +-mu P, the anchor following the object while slipping.
    double anchor = 0;
    for (double w : {0.1, 0.2, 0.3, 0.6, 0.5, 0.4, 0.2, 0.0, -0.3, 0.0}) {
        ContactSolution next = solve_contact_step(C, gap, displaced(P, w, mu), &s);
        INFO("w = " << w);
        REQUIRE(next.converged);
        double t = k * (w - anchor);
        if (std::abs(t) > mu * P) {
            t = std::copysign(mu * P, t);
            anchor = w - t / k;
        }
        CHECK(next.tangential_force_N.x() == Approx(t).margin(1e-12));
        CHECK(next.state[0] ==
              (std::abs(std::abs(t) - mu * P) < 1e-12 ? NodeContact::slip : NodeContact::stick));
        CHECK(next.residual_N < 1e-12);
        CHECK(next.residual_mm < 1e-12);
        s = next;
    }
}

TEST_CASE("held sets: kept whatever the load, and the free solution reproduced",
          "[mechanics][friction]") {
    // The node above (k = 2 N/mm, mu P = 0.5 N) slips beyond w = 0.25 mm.
    Eigen::MatrixXd C = Eigen::MatrixXd::Zero(3, 3);
    C.diagonal() << 0.5, 0.5, 1.0;
    const Eigen::VectorXd gap = Eigen::VectorXd::Zero(1);
    const double P = 1.0, mu = 0.5;
    const ContactSolution rest = solve_contact_step(C, gap, {P, {0, 0}, mu}, nullptr);
    const ContactSolution stuck = solve_contact_step(C, gap, displaced(P, 0.2, mu), &rest);
    const ContactSolution slid = solve_contact_step(C, gap, displaced(P, 0.4, mu), &rest);
    REQUIRE(stuck.state[0] == NodeContact::stick);
    REQUIRE(slid.state[0] == NodeContact::slip);
    // The stick set held at w = 0.4 mm: the node stays at its anchor, beyond the cone.
    const ContactSolution held =
        solve_contact_step(C, gap, displaced(P, 0.4, mu), &rest, {}, nullptr, false, &stuck);
    REQUIRE(held.converged);
    CHECK(held.state[0] == NodeContact::stick);
    CHECK(held.tangential_force_N.x() == Approx(2.0 * 0.4).margin(1e-12));
    // The slip set held where it is right gives the free solution.
    const ContactSolution same =
        solve_contact_step(C, gap, displaced(P, 0.4, mu), &rest, {}, nullptr, false, &slid);
    REQUIRE(same.converged);
    CHECK(same.state[0] == NodeContact::slip);
    CHECK(same.tangential_force_N.x() == Approx(mu * P).margin(1e-12));
    CHECK((same.forces_N - slid.forces_N).cwiseAbs().maxCoeff() < 1e-12);
}

TEST_CASE("force and displacement control agree, a zero increment changes nothing",
          "[mechanics][friction]") {
    const DomeModel& model = coarse_model();
    const FrameResult f = model.solve({1.5, {0.5, 0.2}, 0.8}, {});
    REQUIRE(f.contact.converged);
    REQUIRE_FALSE(f.contact.sliding);
    const Eigen::Vector2d w = f.contact.object_displacement_mm;
    CHECK(w.x() > 0);
    // The same object position under displacement control transmits the same force.
    ContactLoad hold{1.5, {0, 0}, 0.8};
    hold.tangential = TangentialControl::displacement;
    hold.tangential_displacement_mm = w;
    const FrameResult d = model.solve(hold, {}, {}, &f);
    REQUIRE(d.contact.converged);
    CHECK((d.contact.tangential_force_N - f.contact.tangential_force_N).norm() < 1e-9);
    CHECK((d.contact.forces_N - f.contact.forces_N).cwiseAbs().maxCoeff() < 1e-9);
    // And the same force again leaves the object where it is.
    const FrameResult again = model.solve({1.5, {0.5, 0.2}, 0.8}, {}, {}, &f);
    REQUIRE(again.contact.converged);
    CHECK((again.contact.object_displacement_mm - w).norm() < 1e-9);
    CHECK((again.contact.forces_N - f.contact.forces_N).cwiseAbs().maxCoeff() < 1e-9);
    CHECK(again.contact.slipping.empty()); // nothing moves, so nothing slips in this frame
}

// As in seed 001: Gamma falls to 0, and history matters on the way back.
TEST_CASE("sliding ramp: the force rises to mu P as the stick zone shrinks to nothing",
          "[mechanics][friction]") {
    const DomeModel& model = coarse_model();
    const double P = 1.2, mu = 0.8;
    FrameResult frame = model.solve({P, {0, 0}, mu}, {true}); // grasp
    REQUIRE(frame.contact.converged);
    double last_ft = 0, last_stick = frame.stick_area_mm2, last_gamma = 1.0;
    for (int i = 1; i <= 30; ++i) {
        const double w = 2.0 * i / 30; // the plate travels 2 mm
        FrameResult next =
            model.solve(displaced(P, w, mu), {false, false, false, true}, {}, &frame);
        INFO("w = " << w);
        REQUIRE(next.contact.converged);
        CHECK(next.contact.residual_mm < 1e-9);
        CHECK(next.contact.residual_N < 1e-9);
        const double ft = next.contact.tangential_force_N.norm();
        CHECK(ft >= last_ft - 1e-9);
        CHECK(next.stick_area_mm2 <= last_stick + 1e-9);
        CHECK(next.contact.gamma <= last_gamma + 1e-9);
        CHECK(ft <= mu * next.contact.normal_force_N * (1 + 1e-9));
        // Per-node outputs integrate to the totals.
        double fn = 0, fx = 0;
        for (std::size_t j = 0; j < model.candidate_nodes().size(); ++j) {
            fn += next.pressure_MPa(Eigen::Index(j)) * model.candidate_areas()[j];
            fx += next.traction_MPa(Eigen::Index(j), 0) * model.candidate_areas()[j];
        }
        CHECK(fn == Approx(P).epsilon(1e-9));
        CHECK(fx == Approx(next.contact.tangential_force_N.x()).epsilon(1e-9));
        last_ft = ft;
        last_stick = next.stick_area_mm2;
        last_gamma = next.contact.gamma;
        frame = std::move(next);
    }
    CHECK(frame.contact.sliding);
    CHECK(frame.contact.gamma == 0.0);
    CHECK(frame.stick_area_mm2 == 0.0);
    // Every node slips at mu lambda; their directions differ a little (the object drifted
    // sideways during the grasp), so the sum is within 1e-4 of mu P.
    CHECK(frame.contact.tangential_force_N.x() == Approx(mu * P).epsilon(1e-4));
    CHECK(frame.contact.tangential_force_N.norm() <= mu * P * (1 + 1e-12));
    // Back by 0.3 mm: the contact sticks again and the force drops; it does not retrace the
    // loading curve (at w = 1.7 mm on the way out the force was mu P).
    const FrameResult back = model.solve(displaced(P, 1.7, mu), {}, {}, &frame);
    REQUIRE(back.contact.converged);
    CHECK_FALSE(back.contact.sliding);
    CHECK(back.contact.tangential_force_N.x() < 0.9 * mu * P);
    CHECK(back.stick_area_mm2 > 0);
}

// Goodman's approximation leaves the normal problem frictionless.
TEST_CASE("friction during indentation: converges and obeys Coulomb with locked-in traction",
          "[mechanics][friction]") {
    const DomeModel& model = coarse_model();
    const FrameResult frictionless = model.solve({2.0, {0, 0}, 0.0}, {});
    REQUIRE(frictionless.contact.converged);
    for (double mu : {0.3, 0.8, 5.0}) {
        INFO("mu = " << mu);
        const FrameResult r = model.solve({2.0, {0, 0}, mu}, {true});
        REQUIRE(r.contact.converged);
        CHECK(r.contact.normal_force_N == Approx(2.0).epsilon(1e-12));
        CHECK(r.contact.tangential_force_N.norm() < 1e-9); // no pull: tractions balance
        double traction = 0;
        for (int j : r.contact.active) {
            const double t = r.contact.forces_N.row(j).head<2>().norm();
            CHECK(t <= mu * -r.contact.forces_N(j, 2) * (1 + 1e-9) + 1e-15);
            traction = std::max(traction, t);
        }
        CHECK(traction > 0); // radial tractions locked in by the indentation
    }
    DomeModelOptions goodman;
    goodman.contact.coupled = false;
    const DomeModel g(goodman);
    const FrameResult r = g.solve({2.0, {0, 0}, 0.8}, {});
    REQUIRE(r.contact.converged);
    CHECK(r.contact.indentation_mm == Approx(frictionless.contact.indentation_mm).epsilon(1e-9));
}

TEST_CASE("surface strain: exact for a linear field, eq. 3's quadratic terms, signs under a pull",
          "[mechanics][strain]") {
    const DomeModel& model = coarse_model();
    Points X(Eigen::Index(model.candidate_nodes().size()), 3);
    for (Eigen::Index i = 0; i < X.rows(); ++i)
        X.row(i) = model.mesh().V.row(model.candidate_nodes()[std::size_t(i)]);
    const SurfaceStrainSampler sampler(X, model.candidate_triangles(), StrainGridSpec{});
    Points u(X.rows(), 3);
    const double a = 0.02, b = -0.01, c = 0.03, e = 0.005;
    for (Eigen::Index i = 0; i < X.rows(); ++i)
        u.row(i) << a * X(i, 0) + b * X(i, 1), c * X(i, 0) + e * X(i, 1), 0.1 * X(i, 0);
    const StrainGrid grid = sampler.sample(u);
    REQUIRE(grid.nx == 101);
    REQUIRE(grid.ny == 76);
    for (double v : grid.eps_xx)
        REQUIRE(v == Approx(a + 0.5 * (a * a + c * c)).epsilon(1e-9));
    StrainGridSpec too_wide;
    too_wide.half_width_x_mm = 9.0;
    CHECK_THROWS_WITH(SurfaceStrainSampler(X, model.candidate_triangles(), too_wide),
                      Catch::Contains("outside the sampled surface patch"));

    // Pulled along +x, the skin is stretched behind the contact and compressed ahead of it.
    const FrameResult r = model.solve({1.5, {0.9, 0}, 0.8}, {false, false, false, false, true});
    REQUIRE(r.strain.eps_xx.size() == 101u * 76u);
    const int mid = r.strain.ny / 2;
    const auto at_x = [&](double x) {
        return r.strain.value(mid, int(std::lround((x - r.strain.x0_mm) / r.strain.dx_mm)));
    };
    CHECK(at_x(-3.0) > 0);
    CHECK(at_x(3.0) < 0);
}

TEST_CASE("a tessellated 45 mm sphere presses like the analytic sphere, a posed plate like a "
          "flat",
          "[mechanics][object_mesh]") {
    const DomeModel& model = coarse_model();
    const ContactLoad load{1.5, {0.3, 0}, 0.8};
    const FrameResult sphere = model.solve(load, {}, sphere_object(45.0));
    ObjectShape cap;
    cap.kind = ObjectShape::Kind::mesh;
    // Cap of the sphere, lowest point at z = 20 mm (the gap is relative to first touch).
    Pose pose;
    pose.translation_mm = {0, 0, 20};
    cap.mesh = std::make_shared<MeshHeightField>(make_sphere_cap(45.0, 30.0, 1.0), pose);
    const FrameResult meshed = model.solve(load, {}, cap);
    REQUIRE(meshed.contact.converged);
    // Facets lie at most 0.0125 mm inside the sphere (test_object_mesh): same contact to that.
    CHECK(meshed.contact.indentation_mm == Approx(sphere.contact.indentation_mm).margin(0.0125));
    CHECK(meshed.contact.active.size() == Approx(double(sphere.contact.active.size())).margin(3));
    ObjectShape plate;
    plate.kind = ObjectShape::Kind::mesh;
    plate.mesh = std::make_shared<MeshHeightField>(make_plate(40, 40, 4), pose);
    const FrameResult flat = model.solve(load, {});
    const FrameResult plated = model.solve(load, {}, plate);
    // Gaps equal to rounding; the frictional problem need not have a unique solution, and the
    // iterations may end on another one (both converged to 1e-15): equal to 1e-3.
    CHECK(plated.contact.indentation_mm == Approx(flat.contact.indentation_mm).epsilon(1e-3));
    CHECK(plated.contact.active == flat.contact.active);
    ObjectShape hollow;
    hollow.kind = ObjectShape::Kind::mesh; // no height field
    CHECK_THROWS_AS(object_gap(hollow, Points::Zero(2, 3)), std::invalid_argument);
}

// A trial's next frame is solved from the previous state.
TEST_CASE("neo-Hookean frames: the linear answer at small load and deeper but invertible at 3.2 N",
          "[mechanics][hyperelastic]") {
    const DomeModel& linear = coarse_model();
    DomeModelOptions options;
    options.material = MaterialModel::neo_hookean;
    const DomeModel nh(options);
    const ContactLoad small{0.02, {0.005, 0}, 0.8};
    const FrameResult a = linear.solve(small, {false, true});
    const FrameResult b = nh.solve(small, {false, true});
    REQUIRE(b.contact.converged);
    CHECK(b.material_iterations > 0);
    CHECK(b.contact.indentation_mm == Approx(a.contact.indentation_mm).epsilon(0.01));
    const double uz_lin = a.marker_points_mm(0, 2) - linear.markers().points(0, 2);
    const double uz_nh = b.marker_points_mm(0, 2) - nh.markers().points(0, 2);
    CHECK(uz_nh == Approx(uz_lin).epsilon(0.01));

    // Several millimetres of indentation: converged, no element near inversion, force balance.
    const ContactLoad big{3.2, {0, 0}, 0.8};
    const FrameResult deep = nh.solve(big, {true, true});
    REQUIRE(deep.contact.converged);
    CHECK(deep.contact.indentation_mm > 2.0);
    CHECK(deep.contact.indentation_mm > linear.solve(big, {}).contact.indentation_mm);
    CHECK(deep.min_jacobian > 0.5);
    CHECK(deep.contact.normal_force_N == Approx(3.2).epsilon(1e-9));
    CHECK(deep.marker_points_mm.allFinite());
    CHECK(deep.coating_displacement_mm.allFinite());
    // The next frame of a trial pulls a little: one step from the previous state.
    const FrameResult next = nh.solve({3.2, {0.4, 0}, 0.8}, {}, {}, &deep);
    REQUIRE(next.contact.converged);
    CHECK(next.contact.tangential_force_N.x() == Approx(0.4).epsilon(1e-9));
    CHECK(next.contact.object_displacement_mm.x() > 0);
}

TEST_CASE("neo-Hookean frames solved on two threads at once equal the same frames in turn",
          "[mechanics][hyperelastic]") {
    DomeModelOptions options;
    options.material = MaterialModel::neo_hookean;
    const DomeModel nh(options);
    const std::array<ContactLoad, 2> loads{ContactLoad{1.5, {0.6, 0}, 0.8},
                                           ContactLoad{1.0, {0, 0.3}, 0.5}};
    std::array<FrameResult, 2> in_turn, at_once;
    for (std::size_t k = 0; k < 2; ++k)
        in_turn[k] = nh.solve(loads[k], {});
    std::vector<std::thread> threads;
    for (std::size_t k = 0; k < 2; ++k)
        threads.emplace_back([&, k] { at_once[k] = nh.solve(loads[k], {}); });
    for (auto& t : threads)
        t.join();
    for (std::size_t k = 0; k < 2; ++k) {
        REQUIRE(in_turn[k].contact.converged);
        CHECK(at_once[k].contact.converged);
        CHECK(at_once[k].node_displacement_mm == in_turn[k].node_displacement_mm);
        CHECK(at_once[k].marker_points_mm == in_turn[k].marker_points_mm);
    }
}

TEST_CASE("a neo-Hookean step that does not converge is retried in halves",
          "[mechanics][hyperelastic]") {
    // A grasp doubled from 1.25 to 2.5 N in one frame: in one step the iteration stops at its
    // limit on linear tets; its halves converge.
    DomeModelOptions options;
    options.material = MaterialModel::neo_hookean;
    const DomeModel nh(options);
    for (const ObjectShape& object : {ObjectShape{}, sphere_object(45.0)}) {
        const FrameResult first = nh.solve({1.25, {0, 0}, 0.8}, {}, object);
        REQUIRE(first.contact.converged);
        const FrameResult second = nh.solve({2.5, {0, 0}, 0.8}, {}, object, &first);
        CHECK(second.contact.converged);
        CHECK(second.contact.normal_force_N == Approx(2.5).epsilon(1e-9));
        CHECK(second.contact.indentation_mm > first.contact.indentation_mm);
        CHECK(second.contact.tangential_force_N.norm() < 1e-6);
    }
}

// Euler's identity makes the Newton rows homogeneous.
TEST_CASE("friction law: the solver's linearization matches central finite differences",
          "[mechanics][friction]") {
    const double mu = 0.7, r = 3.0, h = 1e-6;
    const std::vector<std::tuple<Eigen::Vector2d, double, Eigen::Vector2d>> points{
        {{0.4, -0.1}, 0.5, {0.08, 0.03}},   // slipping: |t - r g| > mu lambda
        {{-0.2, 0.3}, 0.2, {-0.05, 0.12}},  // slipping, another quadrant
        {{0.05, 0.02}, 1.0, {0.01, -0.01}}, // inside the disc (sticking)
    };
    for (const auto& [t, lambda, g] : points) {
        const bool slip = (t - r * g).norm() > mu * lambda;
        INFO("t " << t.transpose() << " lambda " << lambda << " slip " << slip);
        const FrictionLaw law = friction_law(t, lambda, g, mu, r, slip);
        // Residual: t - proj(t - r g) onto the disc of radius mu lambda.
        const Eigen::Vector2d tau = t - r * g;
        const Eigen::Vector2d proj = slip ? Eigen::Vector2d(mu * lambda * tau.normalized()) : tau;
        CHECK((law.residual - (t - proj)).norm() < 1e-15);
        for (int k = 0; k < 2; ++k) {
            const Eigen::Vector2d e = Eigen::Vector2d::Unit(k);
            const Eigen::Vector2d dt = (friction_law(t + h * e, lambda, g, mu, r, slip).residual -
                                        friction_law(t - h * e, lambda, g, mu, r, slip).residual) /
                                       (2 * h);
            const Eigen::Vector2d dg = (friction_law(t, lambda, g + h * e, mu, r, slip).residual -
                                        friction_law(t, lambda, g - h * e, mu, r, slip).residual) /
                                       (2 * h);
            CHECK((dt - law.d_t.col(k)).norm() < 1e-8);
            CHECK((dg - law.d_g.col(k)).norm() < 1e-8);
        }
        const Eigen::Vector2d dl = (friction_law(t, lambda + h, g, mu, r, slip).residual -
                                    friction_law(t, lambda - h, g, mu, r, slip).residual) /
                                   (2 * h);
        CHECK((dl - law.d_lambda).norm() < 1e-8);
        // Positive homogeneity: phi = d_t t + d_g g + d_lambda lambda.
        CHECK((law.d_t * t + law.d_g * g + law.d_lambda * lambda - law.residual).norm() < 1e-14);
    }
}
