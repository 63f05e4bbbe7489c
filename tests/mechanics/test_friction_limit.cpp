// The friction limit under force control: dense sweeps of Q / (mu P) across 1 (values equal to
// 1 only up to rounding included) for flat, sphere and mesh objects, mu from 0 to 5, from rest
// and from a trial's previous frame. Every solution must be finite and physical: the bounds
// are those `chromasim check` applies to a dataset (docs/DATASET_FORMAT.md, "Label bounds").
#include "mechanics/contact.hpp"
#include "mechanics/dome_model.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <memory>
#include <string>
#include <vector>

using namespace chromasim::mechanics;

namespace {

const DomeModel& coarse_model() {
    static const DomeModel model(DomeModelOptions{});
    return model;
}

struct NamedObject {
    std::string name;
    ObjectShape shape;
};

std::vector<NamedObject> objects() {
    ObjectShape cap;
    cap.kind = ObjectShape::Kind::mesh;
    Pose pose;
    pose.translation_mm = {0, 0, 20};
    cap.mesh = std::make_shared<MeshHeightField>(make_sphere_cap(45.0, 30.0, 1.0), pose);
    return {{"flat", ObjectShape{}}, {"sphere", sphere_object(45.0)}, {"mesh", cap}};
}

/// The ratios swept: 0.98 to 1.02 in steps of 0.005, and 1 to within a few ulps.
std::vector<double> ratios() {
    std::vector<double> r;
    for (int k = -4; k <= 4; ++k)
        r.push_back(1.0 + 0.005 * k);
    for (double e : {1e-3, 1e-5, 1e-7, 1e-9, 1e-12, 1e-15})
        r.insert(r.end(), {1.0 - e, 1.0 + e});
    r.insert(r.end(), {std::nextafter(1.0, 0.0), std::nextafter(1.0, 2.0)});
    return r;
}

/// Every label of a frame finite and physical; `converged` only with status ok.
void check_physical(const FrameResult& f, const ContactLoad& load, double outer_radius_mm) {
    const ContactSolution& c = f.contact;
    INFO("status " << c.status << ", indentation " << c.indentation_mm << " mm, travel "
                   << c.object_displacement_mm.transpose() << " mm, f_t "
                   << c.tangential_force_N.norm() << " N");
    REQUIRE(c.converged);
    CHECK(c.status == "ok");
    CHECK(std::isfinite(c.indentation_mm));
    CHECK(c.object_displacement_mm.allFinite());
    CHECK(c.tangential_force_N.allFinite());
    CHECK(c.indentation_mm >= 0.0);
    CHECK(c.indentation_mm < outer_radius_mm);
    CHECK(c.object_displacement_mm.norm() < outer_radius_mm);
    CHECK(c.normal_force_N == Approx(load.normal_force_N).epsilon(1e-9));
    const double strength = load.mu * c.normal_force_N;
    CHECK(c.tangential_force_N.norm() <= strength * (1 + 1e-9) + 1e-12);
    CHECK(c.gamma >= 0.0);
    CHECK(c.gamma <= 1.0);
    if (c.sliding) CHECK(c.gamma == 0.0);
    // Under force control the pull is transmitted until the contact slides, then mu P.
    const double Q = load.tangential_force_N.norm();
    CHECK(c.tangential_force_N.norm() ==
          Approx(c.sliding ? strength : Q).epsilon(1e-9).margin(1e-12));
    if (gross_slip(load.mu, load.normal_force_N, Q)) CHECK(c.sliding);
}

} // namespace

// For every object and mu, Q / (mu P) in [0.98, 1.02], from rest and from a trial.
TEST_CASE("the friction limit under force control: labels are finite and bounded and continuous",
          "[mechanics][friction]") {
    const DomeModel& model = coarse_model();
    const double R = model.options().dome.radii_mm.back();
    const double P = 1.5;
    for (const NamedObject& object : objects())
        for (double mu : {0.0, 0.3, 1.1, 5.0}) {
            // A trial's history: the grip, then the pull in tenths of mu P up to 0.9.
            FrameResult ramp = model.solve({P, {0, 0}, mu}, {}, object.shape);
            for (int k = 1; k <= 9; ++k)
                ramp = model.solve({P, {0.1 * k * mu * P, 0}, mu}, {}, object.shape, &ramp);
            const double w_ramp = ramp.contact.object_displacement_mm.x();
            double w_below = 0, w_above = 0;
            for (double ratio : ratios()) {
                // mu 0: a pull of 1 mN for every ratio (nothing resists it).
                const double Q = mu > 0 ? ratio * mu * P : 1e-3 * ratio;
                const ContactLoad load{P, {Q, 0}, mu};
                INFO(object.name << ", mu " << mu << ", Q / (mu P) = " << ratio);
                const FrameResult from_rest = model.solve(load, {}, object.shape);
                check_physical(from_rest, load, R);
                const FrameResult in_trial = model.solve(load, {}, object.shape, &ramp);
                check_physical(in_trial, load, R);
                const double w = in_trial.contact.object_displacement_mm.x();
                // The travel grows with the pull and stops where the contact slides: within
                // 50 % of the travel at 0.9 mu P (Mindlin: 1 - 0.1^(2/3) = 78 % of the limit's).
                CHECK(w >= w_ramp - 1e-9);
                CHECK(std::abs(w) <= 1.5 * std::abs(w_ramp) + 1e-9);
                if (ratio == std::nextafter(1.0, 0.0)) w_below = w;
                if (ratio == std::nextafter(1.0, 2.0)) w_above = w;
            }
            // Continuous across the limit: one ulp either side of mu P, the same travel.
            CHECK(w_above == Approx(w_below).margin(1e-9));
        }
}

// Two fingertips' histories do not mix.
TEST_CASE("frames after a slide: the travel is held while sliding and a pull below mu P sticks "
          "again",
          "[mechanics][friction]") {
    const DomeModel& model = coarse_model();
    const double P = 1.5, mu = 1.1;
    const ObjectShape sphere = sphere_object(45.0);
    FrameResult f = model.solve({P, {0.9 * mu * P, 0}, mu}, {}, sphere);
    f = model.solve({P, {1.05 * mu * P, 0}, mu}, {}, sphere, &f);
    REQUIRE(f.contact.sliding);
    const Eigen::Vector2d onset = f.contact.object_displacement_mm;
    for (double ratio : {1.1, 1.3, 1.0}) {
        f = model.solve({P, {ratio * mu * P, 0}, mu}, {}, sphere, &f);
        REQUIRE(f.contact.converged);
        CHECK(f.contact.sliding);
        CHECK((f.contact.object_displacement_mm - onset).norm() < 1e-9);
    }
    // Below mu P the contact sticks again where the slide left it, and the object springs back
    // by the elastic part of 5 % of mu P: about 0.05 x 1.65 N x 0.85 mm/N (the tangential
    // compliance of the ramp to the onset).
    f = model.solve({P, {0.95 * mu * P, 0}, mu}, {}, sphere, &f);
    REQUIRE(f.contact.converged);
    CHECK_FALSE(f.contact.sliding);
    CHECK(f.contact.gamma == Approx(0.05).margin(1e-9));
    const double back_mm = onset.x() - f.contact.object_displacement_mm.x();
    CHECK(back_mm > 0.0);
    CHECK(back_mm < 0.1);
    // The flat's frame from the same loads is another object's: not the sphere's field.
    FrameResult flat = model.solve({P, {0.9 * mu * P, 0}, mu}, {}, ObjectShape{});
    flat = model.solve({P, {1.05 * mu * P, 0}, mu}, {}, ObjectShape{}, &flat);
    REQUIRE(flat.contact.converged);
    CHECK(std::abs(flat.contact.indentation_mm - f.contact.indentation_mm) > 0.01);
}

// The pull goes in small steps up to and past mu P; every frame converges, and once
// sliding the dome keeps sliding.
namespace {

/// The neo-Hookean dome on linear tets (coarse) or on quadratic tets (very_coarse, a spec's
/// default).
DomeModelOptions neo_hookean_dome(int element_order) {
    DomeModelOptions options;
    options.material = MaterialModel::neo_hookean;
    options.contact_candidate_angle_deg = 50;
    options.element_order = element_order;
    options.mesh_level = element_order == 2 ? "very_coarse" : "coarse";
    return options;
}

} // namespace

TEST_CASE("the neo-Hookean dome pulled past mu P converges and slides once its stick zone vanishes",
          "[mechanics][friction][neo_hookean]") {
    const int order = GENERATE(1, 2);
    INFO("element order " << order);
    const DomeModel model(neo_hookean_dome(order));
    const double P = 1.0, mu = 1.06;
    for (const NamedObject& object : {objects()[0], objects()[1]}) {
        INFO(object.name);
        FrameResult f = model.solve({P, {0.9 * mu * P, 0}, mu}, {}, object.shape);
        REQUIRE(f.contact.converged);
        CHECK_FALSE(f.contact.sliding);
        bool slid = false;
        Eigen::Vector2d onset{0, 0};
        // The seed protocols' steps near the limit: 0.5 % of mu P per frame.
        for (double ratio = 0.905; ratio < 1.02; ratio += 0.005) {
            const ContactLoad load{P, {ratio * mu * P, 0}, mu};
            f = model.solve(load, {}, object.shape, &f);
            INFO("Q / (mu P) " << ratio << ", iterations " << f.material_iterations);
            check_physical(f, load, 13.2);
            if (slid) {
                CHECK(f.contact.sliding);
                CHECK((f.contact.object_displacement_mm - onset).norm() < 1e-9);
            } else if (f.contact.sliding) {
                slid = true;
                onset = f.contact.object_displacement_mm;
                // The stick zone resolved down to a few nodes first: Mindlin's c = a (1 - Q /
                // (mu P))^(1/3) is 0.37 a at 0.95 and 0.41 a at 0.93, about one node spacing of
                // the coarse dome and of the very_coarse one's split faces.
                CHECK(ratio > (order == 1 ? 0.95 : 0.925));
            }
        }
        CHECK(slid);
        CHECK(onset.norm() > 0.3); // Mindlin-like finite travel, about 1 mm here
        CHECK(onset.norm() < 3.0);
    }
}

// A grasp's controller raises the grip once its object slides: under the same pull the
// contact then sticks again (the slide is kept only while Q / (mu P) does not drop).
TEST_CASE("a sliding contact sticks again when the grip rises under the same pull",
          "[mechanics][friction]") {
    const DomeModel& model = coarse_model();
    const double mu = 0.8, Q = 0.9;
    for (const NamedObject& object : {objects()[0], objects()[1]}) {
        INFO(object.name);
        FrameResult f = model.solve({1.0, {0.5, 0}, mu}, {}, object.shape);
        f = model.solve({1.0, {Q, 0}, mu}, {}, object.shape, &f);
        REQUIRE(f.contact.converged);
        REQUIRE(f.contact.sliding);
        const FrameResult same = model.solve({1.0, {Q, 0}, mu}, {}, object.shape, &f);
        CHECK(same.contact.sliding);
        const FrameResult looser = model.solve({0.9, {Q, 0}, mu}, {}, object.shape, &f);
        CHECK(looser.contact.sliding);
        const ContactLoad firmer{2.0, {Q, 0}, mu};
        const FrameResult held = model.solve(firmer, {}, object.shape, &f);
        check_physical(held, firmer, 13.2);
        CHECK_FALSE(held.contact.sliding);
        CHECK(held.contact.tangential_force_N.norm() == Approx(Q).epsilon(1e-6));
    }
}
