#include "mechanics/dome_geometry.hpp"
#include "mechanics/tetgen_adapter.hpp"

#include <Eigen/Geometry>
#include <catch2/catch.hpp>

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
    const MarkerDiscs discs = marker_discs(DomeParams{});
    REQUIRE(discs.points.rows() == 2 * 82 * 13);
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
