#include "mechanics/dome_geometry.hpp"
#include "mechanics/tetgen_adapter.hpp"

#include <Eigen/Geometry>
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <map>

using namespace chromasim::mechanics;

namespace {
const TetMesh& coarse_dome() {
    static const TetMesh mesh = [] {
        TetgenOptions options;
        options.max_volume_mm3 = mesh_level("coarse").max_volume_mm3;
        return tetrahedralize(dome_plc(DomeParams{}, mesh_level("coarse").edge_mm), options);
    }();
    return mesh;
}
} // namespace

TEST_CASE("marker pattern has 82 markers per layer in rings of 6, 12, 17, 21, 25",
          "[mechanics][markers]") {
    const auto dirs = marker_directions(DomeParams{});
    REQUIRE(dirs.size() == 82);
    std::map<long, int> per_ring; // keyed by polar angle in 0.1 deg
    for (const auto& d : dirs) {
        REQUIRE(d.norm() == Approx(1.0).epsilon(1e-12));
        ++per_ring[std::lround(std::acos(d.z()) * 1800 / M_PI)];
    }
    const std::map<long, int> expected{{0, 1},    {125, 6},  {250, 12},
                                       {375, 17}, {500, 21}, {625, 25}};
    CHECK(per_ring == expected);
}

TEST_CASE("marker jitter moves each centre within its radius, per layer and seed",
          "[mechanics][markers]") {
    DomeParams dome;
    const auto nominal = marker_directions(dome);
    dome.marker_jitter_mm = 0.1;
    dome.marker_jitter_seed = 7;
    const auto inner = marker_directions(dome, 0), outer = marker_directions(dome, 1);
    REQUIRE(inner.size() == 82);
    double largest = 0;
    int moved_apart = 0;
    for (std::size_t m = 0; m < 82; ++m) {
        REQUIRE(inner[m].norm() == Approx(1.0).epsilon(1e-12));
        // The offset along the sphere of the markers' mid radius (10.75 and 12.45 mm).
        const double di = std::acos(std::min(1.0, inner[m].dot(nominal[m]))) * 10.75;
        const double dout = std::acos(std::min(1.0, outer[m].dot(nominal[m]))) * 12.45;
        CHECK(di <= 0.1 + 1e-9);
        CHECK(dout <= 0.1 + 1e-9);
        largest = std::max({largest, di, dout});
        moved_apart += inner[m].dot(outer[m]) < 1 - 1e-12;
    }
    CHECK(largest > 0.08);     // 164 draws uniform in the disc
    CHECK(moved_apart == 82);  // the layers are printed apart
    CHECK(marker_directions(dome, 0) == inner);
    dome.marker_jitter_seed = 8;
    CHECK(marker_directions(dome, 0) != inner);
}

TEST_CASE("meshed shell volume is within 1% of the analytic hemispherical shell",
          "[mechanics][mesh]") {
    const TetMesh& mesh = coarse_dome();
    const DomeParams dome;
    const double exact = dome_layer_volume(dome);
    CHECK(mesh_volume(mesh) == Approx(exact).epsilon(0.01));
    // Each layer is a region of its own, and each has the right volume too.
    for (int layer = 1; layer <= kLayerCount; ++layer) {
        INFO("layer " << layer);
        CHECK(mesh_volume(mesh, layer) == Approx(dome_layer_volume(dome, layer)).epsilon(0.02));
    }
    for (int t = 0; t < mesh.T.rows(); ++t)
        REQUIRE(tet_volume(mesh, t) > 0);
}

TEST_CASE("hollow interior: no node inside the inner radius, none below the rim plane",
          "[mechanics][mesh]") {
    const TetMesh& mesh = coarse_dome();
    for (int v = 0; v < mesh.V.rows(); ++v) {
        REQUIRE(mesh.V.row(v).norm() >= 10.5 * (1 - 1e-3));
        REQUIRE(mesh.V.row(v).norm() <= 13.2 * (1 + 1e-9));
        REQUIRE(mesh.V(v, 2) >= -1e-12);
    }
}

TEST_CASE("every marker point lies inside exactly one tet of its own layer",
          "[mechanics][markers]") {
    const TetMesh& mesh = coarse_dome();
    const std::vector<double> margin = marker_face_margins_mm(DomeParams{}, mesh);
    const MarkerDiscs discs = marker_discs(DomeParams{}, margin);
    REQUIRE(discs.points.rows() == 2 * 82 * 3 * 13);
    const TetLocator locator(mesh);
    for (int i = 0; i < discs.points.rows(); ++i) {
        const Eigen::Vector3d p = discs.points.row(i);
        const auto strictly_inside = locator.containing(p, -1e-12); // min barycentric > 1e-12
        INFO("marker point " << i << " at " << p.transpose());
        REQUIRE(strictly_inside.size() == 1);
        const int layer = i < discs.points.rows() / 2 ? kInnerMarkerLayer : kOuterMarkerLayer;
        CHECK(mesh.region(strictly_inside[0]) == layer);
        CHECK(locator.locate(p) == strictly_inside[0]);
    }
    // Each marker is a spherical-shell sector: mid-thickness, inner-face and outer-face rings
    // on spheres, the faces the margin (the coarse facets' deepest sag + 5 um) inside the
    // 0.5 mm layer (SENSOR.md: 0.5 mm thick discs filling their layer); side edges radial.
    REQUIRE(margin.size() == 164);
    for (int m = 0; m < 2 * discs.markers_per_layer; ++m) {
        INFO("marker " << m);
        CHECK(margin[std::size_t(m)] > 0.005 + 1.0 * 1.0 / (8 * 13.2)); // a 1 mm chord's sag
        CHECK(margin[std::size_t(m)] < 0.045);
        const double t = 0.5 - 2 * margin[std::size_t(m)];
        CHECK(discs.thickness_mm[std::size_t(m)] == Approx(t));
        const double mid = m < discs.markers_per_layer ? 10.75 : 12.45;
        for (int ring = 0; ring < 3; ++ring) {
            const double r = mid + (ring == 0 ? 0.0 : ring == 1 ? -0.5 * t : 0.5 * t);
            for (int k = 0; k <= discs.rim_points; ++k)
                CHECK(discs.points.row(discs.ring_row(m, ring) + k).norm() ==
                      Approx(r).epsilon(1e-12));
        }
        for (int k = 0; k <= discs.rim_points; ++k) {
            const Eigen::Vector3d in = discs.points.row(discs.ring_row(m, 1) + k);
            const Eigen::Vector3d out = discs.points.row(discs.ring_row(m, 2) + k);
            CHECK(in.normalized().isApprox(out.normalized(), 1e-12));
        }
    }
}

TEST_CASE("coating interface is the 12.7 mm sphere, facing the centre", "[mechanics][mesh]") {
    const TetMesh& mesh = coarse_dome();
    const Triangles F = interface_faces(mesh, kCoating, kOuterMarkerLayer);
    REQUIRE(F.rows() > 100);
    double area = 0;
    for (int f = 0; f < F.rows(); ++f) {
        const Eigen::Vector3d a = mesh.V.row(F(f, 0)), b = mesh.V.row(F(f, 1)),
                              c = mesh.V.row(F(f, 2));
        for (const auto& p : {a, b, c})
            REQUIRE(p.norm() == Approx(12.7).epsilon(1e-9));
        const Eigen::Vector3d n = (b - a).cross(c - a);
        REQUIRE(n.dot(a + b + c) < 0); // points inwards
        area += 0.5 * n.norm();
    }
    CHECK(area == Approx(2 * M_PI * 12.7 * 12.7).epsilon(0.01));
}

TEST_CASE("refined level: graded where contact happens, volume within 1 %, every marker inside "
          "its own layer",
          "[mechanics][mesh]") {
    const MeshLevel level = mesh_level("refined");
    TetgenOptions options;
    options.max_volume_mm3 = level.max_volume_mm3;
    const Plc plc = dome_plc(DomeParams{}, level);
    REQUIRE(plc.point_size_mm.size() == std::size_t(plc.points.rows()));
    const TetMesh mesh = tetrahedralize(plc, options);
    const DomeParams dome;
    CHECK(mesh_volume(mesh) == Approx(dome_layer_volume(dome)).epsilon(0.01));
    // Outer-surface nodes per unit area: within 30 deg of the apex against beyond 60 deg.
    const double R = dome.radii_mm.back();
    int near = 0, far = 0;
    for (int v = 0; v < mesh.V.rows(); ++v) {
        const Eigen::Vector3d p = mesh.V.row(v);
        if (std::abs(p.norm() - R) > 1e-6) continue;
        const double theta = std::acos(std::clamp(p.z() / R, -1.0, 1.0)) * 180 / M_PI;
        near += theta < 30;
        far += theta > 60 && p.z() > 1e-9;
    }
    const double cap_near = 1 - std::cos(30 * M_PI / 180), band_far = std::cos(60 * M_PI / 180);
    CHECK(near / cap_near > 4.0 * far / band_far); // (1.2 / 0.5)^2 = 5.8 times denser
    const MarkerDiscs discs = marker_discs(dome, marker_face_margins_mm(dome, mesh));
    const TetLocator locator(mesh);
    for (int i = 0; i < discs.points.rows(); ++i) {
        const int t = locator.locate(discs.points.row(i).transpose());
        REQUIRE(t >= 0);
        CHECK(mesh.region(t) ==
              (i < discs.points.rows() / 2 ? kInnerMarkerLayer : kOuterMarkerLayer));
    }
    CHECK_THROWS_WITH(mesh_level("ultra"), Catch::Contains("refined, reference"));
}
