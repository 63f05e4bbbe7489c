#include "mechanics/contact_area.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <numbers>

using namespace chromasim::mechanics;

namespace {

/// A flat square of (2 m + 1)^2 nodes, spacing h (mm), cut into right triangles.
struct Grid {
    Points x;
    Triangles F;
};

Grid square_grid(int m, double h) {
    const int side = 2 * m + 1;
    Grid g;
    g.x.resize(side * side, 3);
    for (int i = 0; i < side; ++i)
        for (int j = 0; j < side; ++j)
            g.x.row(i * side + j) << (i - m) * h, (j - m) * h, 0.0;
    g.F.resize(2 * (side - 1) * (side - 1), 3);
    int f = 0;
    for (int i = 0; i + 1 < side; ++i)
        for (int j = 0; j + 1 < side; ++j) {
            const int a = i * side + j, b = a + side, c = a + 1, d = b + 1;
            g.F.row(f++) << a, b, d;
            g.F.row(f++) << a, d, c;
        }
    return g;
}

/// A Hertz-like contact of radius a: nodes inside touch (stick inside radius c, slip beyond),
/// nodes outside are free with the gap k (r - a)^(3/2) of an elastic contact's edge.
ContactSolution hertz_like(const Grid& g, double a, double c, double k = 0.05) {
    ContactSolution s;
    const Eigen::Index n = g.x.rows();
    s.state.assign(std::size_t(n), NodeContact::free);
    s.gap_mm = Eigen::VectorXd::Zero(n);
    for (Eigen::Index i = 0; i < n; ++i) {
        const double r = g.x.row(i).head<2>().norm();
        if (r <= a) {
            s.state[std::size_t(i)] = r <= c ? NodeContact::stick : NodeContact::slip;
            s.active.push_back(int(i));
        } else {
            s.gap_mm(i) = k * std::pow(r - a, 1.5);
        }
    }
    return s;
}

} // namespace

TEST_CASE("contact area: a Hertz edge between the nodes is found from the gaps outside",
          "[mechanics][contact]") {
    const double h = 0.5;
    const Grid g = square_grid(16, h);
    const ContactAreaMeter meter(g.F, int(g.x.rows()));
    // Radii that fall anywhere between nodes: the area follows the radius, not the nodes.
    double last = 0.0;
    for (double a : {2.0, 2.15, 2.3, 2.45, 3.1, 4.4}) {
        INFO("a = " << a);
        const ContactAreas areas = meter.measure(g.x, hertz_like(g, a, -1.0));
        CHECK(areas.contact_mm2 == Approx(std::numbers::pi * a * a).epsilon(0.02));
        CHECK(areas.contact_mm2 > last);
        CHECK(areas.stick_mm2 == 0.0);
        last = areas.contact_mm2;
    }
}

TEST_CASE("contact area: the stick part, a free node inside, and no contact",
          "[mechanics][contact]") {
    const Grid g = square_grid(16, 0.5);
    const ContactAreaMeter meter(g.F, int(g.x.rows()));
    const double a = 3.1, c = 1.6;
    ContactSolution s = hertz_like(g, a, c);
    const ContactAreas areas = meter.measure(g.x, s);
    CHECK(areas.stick_mm2 == Approx(std::numbers::pi * c * c).epsilon(0.15)); // midpoint rule
    CHECK(areas.stick_mm2 <= areas.contact_mm2);
    // A free node ringed by touching ones (a quadratic face's corner) is inside the patch.
    const int centre = int(g.x.rows() / 2);
    s.state[std::size_t(centre)] = NodeContact::free;
    s.gap_mm(centre) = 1e-4;
    const ContactAreas with_hole = meter.measure(g.x, s);
    CHECK(with_hole.contact_mm2 == Approx(areas.contact_mm2).epsilon(1e-12));
    CHECK(with_hole.stick_mm2 == Approx(areas.stick_mm2).epsilon(1e-12));
    // Everything slipping: no stick area; nothing touching: no area.
    for (NodeContact& state : s.state)
        if (state == NodeContact::stick) state = NodeContact::slip;
    CHECK(meter.measure(g.x, s).stick_mm2 == 0.0);
    CHECK(meter.measure(g.x, hertz_like(g, -1.0, 0.0)).contact_mm2 == 0.0);
    // A deformed surface counts its own (stretched) area.
    Points stretched = g.x;
    stretched.col(0) *= 1.1;
    const ContactAreas wide = meter.measure(stretched, hertz_like(g, a, 0.0));
    CHECK(wide.contact_mm2 == Approx(1.1 * meter.measure(g.x, hertz_like(g, a, 0.0)).contact_mm2)
                                  .epsilon(0.02));
}
