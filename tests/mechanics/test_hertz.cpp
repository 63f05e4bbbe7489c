// Contact against theory: Hertz on an elastic block (the half-space stand-in).
#include "mechanics/block_model.hpp"
#include "mechanics/hertz.hpp"

#include <catch2/catch.hpp>

using namespace chromasim::mechanics;

namespace {
/// Mindlin's assumption: normal load without friction, then the tangential load in one step.
constexpr LoadPath kMindlin{1, 1, true, 1};
} // namespace

TEST_CASE("Hertz formulas reproduce SENSOR.md's scale check", "[mechanics][hertz]") {
    // R = 13.2 mm, E = 0.4 MPa, nu = 0.5: a = 2.65 mm at 1 N, 3.8 mm at 3 N.
    CHECK(hertz(1.0, 13.2, 0.4, 0.5).a_mm == Approx(2.65).margin(0.005));
    CHECK(hertz(3.0, 13.2, 0.4, 0.5).a_mm == Approx(3.8).margin(0.05));
    const HertzSolution h = hertz(1.0, 10.0, 1.0, 0.3);
    CHECK(h.delta_mm == Approx(h.a_mm * h.a_mm / 10.0));
    CHECK(h.p0_MPa * 2.0 / 3.0 * M_PI * h.a_mm * h.a_mm == Approx(1.0)); // integral of p = P
    CHECK(mindlin_stick_radius(2.0, 0.5, 1.0, 1.0) == Approx(2.0 * std::cbrt(0.5)));
    CHECK(mindlin_stick_radius(2.0, 1.5, 1.0, 1.0) == 0.0);
}

// nu = 0.49; the contact radius a, the approach and p0 against Hertz.
TEST_CASE("sphere on a near-incompressible block: Hertz contact and the Cattaneo-Mindlin stick "
          "radius",
          "[mechanics][hertz]") {
    const double nu = 0.49;
    BlockParams params = block_level("coarse"); // average nodal pressure: no locking
    params.material.nu = nu;
    const BlockModel block(params);
    const ObjectShape sphere = sphere_object(10.0);
    for (double P : {1.0, 2.5}) {
        INFO("P = " << P);
        const ContactSolution s = block.solve({P, {0, 0}, 0.5}, sphere, kMindlin);
        REQUIRE(s.converged);
        const HertzSolution h = hertz(P, 10.0, 1.0, nu);
        const ContactFit fit =
            fit_hertz_profile(block.candidate_positions(), block.candidate_areas(), s);
        REQUIRE(fit.nodes_used > 20);
        CHECK(fit.a_mm == Approx(h.a_mm).epsilon(0.03));
        CHECK(fit.p0_MPa == Approx(h.p0_MPa).epsilon(0.05));
        CHECK(s.indentation_mm == Approx(h.delta_mm).epsilon(0.03)); // far field: no correction
    }
    // Cattaneo-Mindlin: normal load frictionless, then Q at Q / (mu P) = 0.25, 0.5, 0.75.
    const double P = 1.0, mu = 0.5;
    const ContactSolution normal = block.solve({P, {0, 0}, mu}, sphere, kMindlin);
    const ContactFit fit =
        fit_hertz_profile(block.candidate_positions(), block.candidate_areas(), normal);
    const double a = hertz(P, 10.0, 1.0, nu).a_mm;
    double last_c = a;
    for (double ratio : {0.25, 0.5, 0.75}) {
        INFO("Q / (mu P) = " << ratio);
        const ContactSolution s = block.solve({P, {0.0, ratio * mu * P}, mu}, sphere, kMindlin);
        REQUIRE(s.converged);
        CHECK_FALSE(s.sliding);
        CHECK(s.tangential_force_N.y() == Approx(ratio * mu * P));
        const double c = fit_mindlin_stick_radius(
            block.candidate_positions(), block.candidate_areas(), s, fit.a_mm, fit.p0_MPa, mu);
        CHECK(c == Approx(mindlin_stick_radius(a, ratio * mu * P, mu, P)).epsilon(0.05));
        CHECK(c < last_c); // the slip front moves inwards as Q grows
        last_c = c;
        for (int j : s.active) // Coulomb: no traction above mu times the normal force
            CHECK(s.forces_N.row(j).head<2>().norm() <= mu * -s.forces_N(j, 2) * (1 + 1e-9));
    }
}
