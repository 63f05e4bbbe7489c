#include "mechanics/object_mesh.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <map>
#include <optional>
#include <random>
#include <thread>
#include <utility>

using namespace chromasim::mechanics;
using Catch::Matchers::Contains;

namespace {

// Largest circumradius (mm) of the surface's triangles.
double max_circumradius(const TriangleSurface& s) {
    double r = 0.0;
    for (Eigen::Index f = 0; f < s.F.rows(); ++f) {
        const Eigen::Vector3d a = s.V.row(s.F(f, 0)), b = s.V.row(s.F(f, 1)),
                              c = s.V.row(s.F(f, 2));
        const double la = (b - c).norm(), lb = (c - a).norm(), lc = (a - b).norm();
        r = std::max(r, la * lb * lc / (2.0 * (b - a).cross(c - a).norm()));
    }
    return r;
}

// A point a + t (b - a) on the x-y projection of the segment ab, rounded as any caller would.
Eigen::Vector2d on_segment(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double t) {
    return (a + t * (b - a)).head<2>();
}

// Lowest z over all triangles by brute force (barycentric coordinates from a 2 x 2 solve), or
// nullopt; `ambiguous` is set when the line passes within `margin` (barycentric) of an edge of
// any triangle, where the grid's tolerance may rightly decide either way.
std::optional<double> brute_lowest_z(const TriangleSurface& s, double x, double y, double margin,
                                     bool& ambiguous) {
    std::optional<double> best;
    ambiguous = false;
    for (Eigen::Index f = 0; f < s.F.rows(); ++f) {
        const Eigen::Vector3d a = s.V.row(s.F(f, 0)), b = s.V.row(s.F(f, 1)),
                              c = s.V.row(s.F(f, 2));
        Eigen::Matrix2d M;
        M << b.x() - a.x(), c.x() - a.x(), b.y() - a.y(), c.y() - a.y();
        if (std::abs(M.determinant()) < 1e-9) continue; // (near) vertical
        const Eigen::Vector2d l = M.inverse() * Eigen::Vector2d(x - a.x(), y - a.y());
        const double lmin = std::min({1.0 - l.sum(), l.x(), l.y()});
        if (std::abs(lmin) < margin) ambiguous = true;
        if (lmin < 0.0) continue;
        const double z = a.z() + l.x() * (b.z() - a.z()) + l.y() * (c.z() - a.z());
        if (!best || z < *best) best = z;
    }
    return best;
}

} // namespace

TEST_CASE("roll-pitch-yaw: R = Rz(yaw) Ry(pitch) Rx(roll), counter-clockwise positive",
          "[object_mesh]") {
    const Eigen::Vector3d x = Eigen::Vector3d::UnitX(), y = Eigen::Vector3d::UnitY(),
                          z = Eigen::Vector3d::UnitZ();
    CHECK((rotation_from_roll_pitch_yaw_deg(0, 0, 90) * x - y).norm() < 1e-15);
    CHECK((rotation_from_roll_pitch_yaw_deg(90, 0, 0) * y - z).norm() < 1e-15);
    CHECK((rotation_from_roll_pitch_yaw_deg(0, 90, 0) * z - x).norm() < 1e-15);
    // Roll first, then pitch: y -> z (roll) -> x (pitch). The other order would give y.
    CHECK((rotation_from_roll_pitch_yaw_deg(90, 90, 0) * y - x).norm() < 1e-15);
}

TEST_CASE("sphere cap generator: vertices on the sphere, outward triangles, closed sphere",
          "[object_mesh]") {
    const double R = 45.0;
    const TriangleSurface s = make_sphere_cap(R, 180.0, 2.0);
    const Eigen::Vector3d centre(0, 0, R);
    for (Eigen::Index v = 0; v < s.V.rows(); ++v)
        REQUIRE((Eigen::Vector3d(s.V.row(v)) - centre).norm() == Approx(R).epsilon(1e-14));
    // Every directed edge once, its reverse once: closed and consistently oriented.
    std::map<std::pair<int, int>, int> edges;
    for (Eigen::Index f = 0; f < s.F.rows(); ++f) {
        const Eigen::Vector3d a = s.V.row(s.F(f, 0)), b = s.V.row(s.F(f, 1)),
                              c = s.V.row(s.F(f, 2));
        REQUIRE((b - a).cross(c - a).dot((a + b + c) / 3.0 - centre) > 0.0);
        for (int k = 0; k < 3; ++k)
            ++edges[{s.F(f, k), s.F(f, (k + 1) % 3)}];
    }
    for (const auto& [e, n] : edges) {
        REQUIRE(n == 1);
        REQUIRE(edges.count({e.second, e.first}) == 1);
    }
    CHECK(s.V.rows() - Eigen::Index(edges.size() / 2) + s.F.rows() == 2); // Euler, genus 0
    CHECK(s.V.row(0).norm() == 0.0); // bottom pole at the origin
    validate_surface(s);
}

TEST_CASE("height field of a tessellated sphere is the analytic underside within the "
          "tessellation bound",
          "[object_mesh]") {
    const double R = 45.0;
    const TriangleSurface sphere = make_sphere_cap(R, 180.0, 1.5); // closed: top and bottom
    Pose pose;
    pose.rotation = rotation_from_roll_pitch_yaw_deg(7.0, -11.0, 31.0);
    pose.translation_mm = {0.3, -0.2, 13.2};
    const MeshHeightField field(sphere, pose);
    const Eigen::Vector3d C = pose.rotation * Eigen::Vector3d(0, 0, R) + pose.translation_mm;

    // Every facet lies inside the ball, in a plane at sqrt(R^2 - rc^2) from the centre (rc its
    // circumradius), so a point of the faceted underside is at rho in [R - delta, R] from C.
    const double delta = R - std::sqrt(R * R - std::pow(max_circumradius(sphere), 2));
    INFO("radial tessellation bound delta = " << delta << " mm");
    REQUIRE(delta < 0.02);

    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    double worst = 0.0;
    for (int n = 0; n < 20000; ++n) {
        const Eigen::Vector2d xy = C.head<2>() + R * Eigen::Vector2d(u(rng), u(rng));
        const double r = (xy - C.head<2>()).norm();
        if (r > R * std::sin(60.0 * M_PI / 180.0)) continue;
        const auto z = field.lowest_z(xy.x(), xy.y());
        REQUIRE(z);
        const double below = std::sqrt(R * R - r * r); // C.z minus the analytic underside
        const double bound = below - std::sqrt((R - delta) * (R - delta) - r * r);
        const double error = *z - (C.z() - below);
        REQUIRE(error >= -1e-9);
        REQUIRE(error <= bound + 1e-9);
        worst = std::max(worst, error);
    }
    INFO("largest vertical error " << worst << " mm");
    CHECK(worst > 0.0);
    // Beyond the silhouette the line misses.
    CHECK_FALSE(field.lowest_z(C.x() + R + 1e-3, C.y()));
    CHECK_FALSE(field.lowest_z(C.x(), C.y() - R - 1e-3));
}

TEST_CASE("a plate is a plane, a tilted plate is the tilted plane", "[object_mesh]") {
    const TriangleSurface plate = make_plate(40.0, 40.0, 3);
    SECTION("level") {
        Pose pose;
        pose.translation_mm = {1.0, 2.0, 3.0};
        const MeshHeightField field(plate, pose);
        std::mt19937 rng(1);
        std::uniform_real_distribution<double> u(-20.0, 20.0);
        for (int n = 0; n < 2000; ++n) {
            const auto z = field.lowest_z(1.0 + u(rng), 2.0 + u(rng));
            REQUIRE(z);
            REQUIRE(*z == Approx(3.0).margin(1e-12));
        }
        CHECK(field.lowest_z(-19.0, -18.0)); // corner (-19, -18) exactly
        CHECK_FALSE(field.lowest_z(21.0 + 1e-6, 2.0));
        CHECK_FALSE(field.lowest_z(1.0, -18.0 - 1e-6));
    }
    SECTION("tilted 10 deg about y, turned 25 deg about z") {
        Pose pose;
        pose.rotation = rotation_from_roll_pitch_yaw_deg(0.0, 10.0, 25.0);
        pose.translation_mm = {0.5, -1.0, 13.2};
        const MeshHeightField field(plate, pose);
        const Eigen::Vector3d n = pose.rotation * Eigen::Vector3d::UnitZ();
        const Eigen::Vector3d& t = pose.translation_mm;
        auto plane_z = [&](double x, double y) {
            return t.z() - (n.x() * (x - t.x()) + n.y() * (y - t.y())) / n.z();
        };
        std::mt19937 rng(2);
        std::uniform_real_distribution<double> u(-20.0, 20.0);
        for (int k = 0; k < 2000; ++k) {
            const Eigen::Vector3d p = pose.rotation * Eigen::Vector3d(u(rng), u(rng), 0.0) + t;
            const auto z = field.lowest_z(p.x(), p.y());
            REQUIRE(z);
            REQUIRE(*z == Approx(plane_z(p.x(), p.y())).margin(1e-9));
        }
        const Eigen::Vector3d out = pose.rotation * Eigen::Vector3d(20.001, 0.0, 0.0) + t;
        CHECK_FALSE(field.lowest_z(out.x(), out.y()));
        // The lowest point is the corner that the tilt lowers most, and it is on the plane.
        const Eigen::Vector3d low = field.lowest_point();
        CHECK(low.z() == Approx(plane_z(low.x(), low.y())).margin(1e-9));
        CHECK(low.z() == Approx(t.z() - 20.0 * std::sin(10.0 * M_PI / 180.0)).margin(1e-9));
    }
}

TEST_CASE("lines exactly on shared edges and vertices never miss", "[object_mesh]") {
    SECTION("level plate grid: exact grid lines and vertices") {
        const MeshHeightField field(make_plate(40.0, 40.0, 8)); // lines every 5 mm, exact
        for (int i = 0; i <= 8; ++i)
            for (int j = 0; j <= 32; ++j) {
                const double a = -20.0 + 5.0 * i, b = -20.0 + 1.25 * j;
                const auto h1 = field.hit(a, b), h2 = field.hit(b, a);
                REQUIRE(h1);
                REQUIRE(h2);
                REQUIRE(h1->z_mm == 0.0);
                REQUIRE(h2->z_mm == 0.0);
            }
        // Diagonals of the squares are shared edges too.
        for (int k = 0; k <= 40; ++k)
            REQUIRE(field.hit(-20.0 + k, -20.0 + k));
    }
    SECTION("posed sphere cap: every vertex and points along every edge") {
        const TriangleSurface cap = make_sphere_cap(45.0, 60.0, 1.7);
        Pose pose;
        pose.rotation = rotation_from_roll_pitch_yaw_deg(3.0, -4.0, 41.0);
        pose.translation_mm = {0.7, -0.4, 13.2};
        const MeshHeightField field(cap, pose);
        const TriangleSurface& s = field.surface();
        // Tilted by only a few degrees, the 60 deg cap has no overhang: a line through a point
        // of the surface meets it there, so z is that point's z (up to rounding).
        for (Eigen::Index v = 0; v < s.V.rows(); ++v) {
            const auto z = field.lowest_z(s.V(v, 0), s.V(v, 1));
            REQUIRE(z);
            REQUIRE(*z == Approx(s.V(v, 2)).margin(1e-9));
        }
        for (Eigen::Index f = 0; f < s.F.rows(); ++f)
            for (int k = 0; k < 3; ++k) {
                const Eigen::Vector3d a = s.V.row(s.F(f, k)), b = s.V.row(s.F(f, (k + 1) % 3));
                for (double t : {0.5, 1.0 / 3.0, 0.7182818284590452}) {
                    const Eigen::Vector2d p = on_segment(a, b, t);
                    const auto z = field.lowest_z(p.x(), p.y());
                    REQUIRE(z);
                    REQUIRE(*z == Approx(a.z() + t * (b.z() - a.z())).margin(1e-9));
                }
            }
    }
}

TEST_CASE("grid queries equal a brute-force search over all triangles, overhangs included",
          "[object_mesh]") {
    // Pitched by 70 deg the cap overhangs: many vertical lines meet it twice, the lower wins.
    const TriangleSurface cap = make_sphere_cap(45.0, 60.0, 4.0);
    Pose pose;
    pose.rotation = rotation_from_roll_pitch_yaw_deg(5.0, 70.0, 20.0);
    pose.translation_mm = {2.0, -1.0, 13.2};
    const MeshHeightField field(cap, pose);
    const Eigen::AlignedBox2d box = field.grid_box();
    std::mt19937 rng(4);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::uniform_int_distribution<int> cell_i(0, field.grid_cells().x()),
        cell_j(0, field.grid_cells().y());
    int hits = 0, misses = 0;
    for (int n = 0; n < 3000; ++n) {
        // Half the points anywhere (and beyond) the grid, half exactly on cell boundaries.
        Eigen::Vector2d p =
            box.min() +
            (box.sizes().array() * 1.2 * Eigen::Array2d(u(rng) - 0.1, u(rng) - 0.1)).matrix();
        if (n % 2) p.x() = box.min().x() + cell_i(rng) * field.cell_mm();
        if (n % 4 == 1) p.y() = box.min().y() + cell_j(rng) * field.cell_mm();
        bool ambiguous = false;
        const auto expected = brute_lowest_z(field.surface(), p.x(), p.y(), 1e-7, ambiguous);
        if (ambiguous) continue;
        const auto z = field.lowest_z(p.x(), p.y());
        REQUIRE(z.has_value() == expected.has_value());
        if (expected) REQUIRE(*z == Approx(*expected).margin(1e-9));
        ++(expected ? hits : misses);
    }
    CHECK(hits > 500);
    CHECK(misses > 500);
}

TEST_CASE("steep triangles: z never leaves the triangle's z range near its edges",
          "[object_mesh]") {
    // Projected width 1e-6 mm, 10 mm tall: a slope of 1e7. Within the tolerance outside the
    // base edge, extrapolation would give z ~ -0.1 mm; the clamped weights give the edge.
    TriangleSurface s;
    s.V.resize(3, 3);
    s.V << 0.0, 0.0, 0.0, 10.0, 0.0, 0.0, 5.0, 1e-6, 10.0;
    s.F.resize(1, 3);
    s.F << 0, 1, 2;
    const MeshHeightField field(s);
    for (double x : {1.0, 2.5, 5.0, 7.5, 9.0}) {
        const auto z = field.lowest_z(x, -0.5 * field.tolerance_mm());
        REQUIRE(z);
        REQUIRE(*z >= 0.0);
        REQUIRE(*z <= 10.0);
    }
    CHECK_FALSE(field.lowest_z(5.0, -2.0 * field.tolerance_mm()));
}

TEST_CASE("lowest point, bounds and misses", "[object_mesh]") {
    const TriangleSurface cap = make_sphere_cap(45.0, 60.0, 2.0);
    Pose pose;
    pose.translation_mm = {0.0, 0.0, 13.2};
    const MeshHeightField field(cap, pose);
    CHECK(field.lowest_point() == Eigen::Vector3d(0.0, 0.0, 13.2));
    CHECK(*field.lowest_z(0.0, 0.0) == Approx(13.2).margin(1e-12)); // the pole: a fan's vertex
    const double rim = 45.0 * std::sin(60.0 * M_PI / 180.0);
    CHECK(field.bounds().min().z() == 13.2);
    CHECK(field.bounds().max().z() == Approx(13.2 + 22.5).epsilon(1e-12));
    CHECK(field.bounds().max().x() == Approx(rim).epsilon(1e-12));
    CHECK_FALSE(field.hit(rim + 1e-3, 0.0));
    CHECK_FALSE(field.hit(1e6, 0.0));
    CHECK_FALSE(field.hit(std::nan(""), 0.0));
    CHECK_FALSE(field.hit(0.0, std::numeric_limits<double>::infinity()));

    Points X(3, 3);
    X << 0.0, 0.0, 99.0, 1e6, 0.0, 0.0, 1.0, 1.0, 0.0;
    const Eigen::VectorXd z = field.lowest_z_all(X);
    CHECK(z(0) == Approx(13.2).margin(1e-12));
    CHECK(std::isinf(z(1)));
    CHECK(z(2) == Approx(13.2 + 45.0 - std::sqrt(45.0 * 45.0 - 2.0)).margin(0.02));
}

TEST_CASE("grid stays small and correct for very uneven triangle sizes", "[object_mesh]") {
    // One 1000 mm triangle plus a fine plate: the mean-side cell would be large, the cap on
    // the cell count must hold, and queries stay exact.
    TriangleSurface s = make_plate(10.0, 10.0, 50);
    const Eigen::Index nv = s.V.rows(), nf = s.F.rows();
    s.V.conservativeResize(nv + 3, 3);
    s.V.row(nv) << -500.0, -500.0, 5.0;
    s.V.row(nv + 1) << 500.0, -500.0, 5.0;
    s.V.row(nv + 2) << 0.0, 500.0, 5.0;
    s.F.conservativeResize(nf + 1, 3);
    s.F.row(nf) << int(nv), int(nv + 1), int(nv + 2);
    const MeshHeightField field(s);
    const Eigen::Vector2i cells = field.grid_cells();
    CHECK(double(cells.x()) * cells.y() <= 4.0 * double(s.F.rows()) + 64.0);
    CHECK(*field.lowest_z(1.23, -4.56) == 0.0);           // the plate, below the big triangle
    CHECK(*field.lowest_z(100.0, -100.0) == Approx(5.0)); // only the big triangle
}

TEST_CASE("concurrent const queries agree with serial ones", "[object_mesh]") {
    const MeshHeightField field(make_sphere_cap(45.0, 60.0, 2.0));
    Points X(4000, 3);
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(-40.0, 40.0);
    for (Eigen::Index i = 0; i < X.rows(); ++i)
        X.row(i) << u(rng), u(rng), 0.0;
    const Eigen::VectorXd serial = field.lowest_z_all(X);
    std::vector<Eigen::VectorXd> results(4);
    std::vector<std::thread> threads;
    for (std::size_t k = 0; k < results.size(); ++k)
        threads.emplace_back([&, k] { results[k] = field.lowest_z_all(X); });
    for (auto& t : threads)
        t.join();
    for (const auto& r : results)
        CHECK((r.array() == serial.array()).all()); // bit for bit, misses (inf) included
}

TEST_CASE("invalid surfaces and poses are rejected with a clear message", "[object_mesh]") {
    const TriangleSurface good = make_plate(40.0, 40.0, 1);
    SECTION("no triangles") {
        TriangleSurface s = good;
        s.F.resize(0, 3);
        CHECK_THROWS_WITH(MeshHeightField(s), Contains("no triangles"));
    }
    SECTION("non-finite coordinate") {
        TriangleSurface s = good;
        s.V(2, 1) = std::nan("");
        CHECK_THROWS_WITH(MeshHeightField(s), Contains("vertex 2 has a non-finite coordinate"));
    }
    SECTION("index out of range") {
        TriangleSurface s = good;
        s.F(1, 2) = 4;
        CHECK_THROWS_WITH(MeshHeightField(s),
                          Contains("triangle 1 has vertex index 4, outside [0, 4)"));
        s.F(1, 2) = -1;
        CHECK_THROWS_AS(MeshHeightField(s), std::invalid_argument);
    }
    SECTION("degenerate triangles") {
        TriangleSurface s = good;
        s.F.row(1) << 0, 0, 3;
        CHECK_THROWS_WITH(MeshHeightField(s), Contains("triangle 1") && Contains("degenerate"));
        s = good;
        s.V.row(3) = 0.5 * (s.V.row(0) + s.V.row(1)); // collinear with 0 and 1
        CHECK_THROWS_WITH(validate_surface(s), Contains("degenerate"));
    }
    SECTION("bad pose") {
        Pose pose;
        pose.rotation *= 2.0;
        CHECK_THROWS_WITH(MeshHeightField(good, pose), Contains("not a proper rotation"));
        pose.rotation = Eigen::Vector3d(-1.0, 1.0, 1.0).asDiagonal();
        CHECK_THROWS_WITH(MeshHeightField(good, pose), Contains("not a proper rotation"));
        pose = Pose{};
        pose.translation_mm.x() = std::numeric_limits<double>::infinity();
        CHECK_THROWS_WITH(MeshHeightField(good, pose), Contains("non-finite"));
    }
    SECTION("a vertical plate has no underside") {
        Pose pose;
        pose.rotation = rotation_from_roll_pitch_yaw_deg(90.0, 0.0, 0.0);
        CHECK_THROWS_WITH(MeshHeightField(good, pose), Contains("vertical"));
    }
    SECTION("generators reject bad sizes") {
        CHECK_THROWS_AS(make_sphere_cap(45.0, 0.0, 1.0), std::invalid_argument);
        CHECK_THROWS_AS(make_sphere_cap(-1.0, 60.0, 1.0), std::invalid_argument);
        CHECK_THROWS_AS(make_plate(40.0, 40.0, 0), std::invalid_argument);
    }
}
