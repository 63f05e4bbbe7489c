// Tests of the ray queries of chromasim::render on the small synthetic sensor of
// test_frames.hpp: EmbreeScene's refits, kinds, hit walks and packets against single rays, and
// the shading model's transmittance through marker volumes along straight and grazing rays.
#include "render/embree_scene.hpp"
#include "render/shading.hpp"
#include "test_frames.hpp"
#include "test_meshes.hpp"

#include <Eigen/Geometry>
#include <catch2/catch.hpp>

#include <cmath>
#include <span>
#include <stdexcept>
#include <utility>
#include <vector>

using namespace chromasim::render;
using namespace chromasim::render::test;

namespace {

/// Length of the line origin + t w inside a prism of add_disc, by brute force: the share of
/// points 1e-5 mm apart that lie on the inner side of all its 14 planes.
double chord_mm(const Vec3& origin, const Vec3& w, const Vec3& centre, const Vec3& normal,
                double thickness_mm, double t_max_mm) {
    const Vec3 n = normal.normalized();
    std::vector<std::pair<Vec3, double>> planes{{n, 0.5 * thickness_mm}, {-n, 0.5 * thickness_mm}};
    for (int k = 0; k < kRim; ++k) {
        const Vec3 mid = 0.5 * (rim_point(centre, n, k) + rim_point(centre, n, k + 1)) - centre;
        planes.emplace_back(mid.normalized(), mid.norm());
    }
    const double step = 1e-5;
    int inside = 0;
    for (double t = 0.5 * step; t < t_max_mm; t += step) {
        const Vec3 p = origin + t * w - centre;
        bool in = true;
        for (const auto& [m, d] : planes)
            in = in && m.dot(p) <= d;
        inside += in;
    }
    return inside * step;
}

} // namespace

TEST_CASE("EmbreeScene refits in place when the topology is unchanged", "[render]") {
    detail::EmbreeScene scene;
    CHECK_FALSE(scene.closest_hit(Vec3::Zero(), Vec3::UnitZ(), 0.0, 100.0).hit());

    SensorFrame frame = marker_frame();
    CHECK(scene.set_frame(frame) == detail::SceneUpdate::built);
    const Vec3 axis = Vec3(0.01, 0.02, 1.0).normalized(); // off the fan's centre vertex
    auto first = scene.closest_hit(Vec3::Zero(), axis, 0.0, 100.0);
    const double bottom_mm = kInnerMarkerZ_mm - 0.5 * kThickness_mm;
    CHECK(first.kind == detail::SurfaceKind::inner_marker);
    CHECK(first.t_mm == Approx(bottom_mm / axis.z()).epsilon(1e-6));
    CHECK(first.normal.z() == Approx(-1.0).epsilon(1e-6)); // the inner face looks down

    frame.inner_markers.V.col(2).array() += 0.5f;
    CHECK(scene.set_frame(frame) == detail::SceneUpdate::refitted);
    const auto moved = scene.closest_hit(Vec3::Zero(), axis, 0.0, 100.0);
    CHECK(moved.t_mm == Approx((bottom_mm + 0.5) / axis.z()).epsilon(1e-6));
    const auto top = scene.closest_hit(Vec3::Zero(), axis, moved.t_mm + 1e-3, 100.0);
    CHECK(top.kind == detail::SurfaceKind::inner_marker);
    CHECK(top.t_mm == Approx((bottom_mm + 0.5 + kThickness_mm) / axis.z()).epsilon(1e-6));
    CHECK(top.normal.z() == Approx(1.0).epsilon(1e-6));
    const auto behind = scene.closest_hit(Vec3::Zero(), axis, top.t_mm + 1e-3, 100.0);
    CHECK(behind.kind == detail::SurfaceKind::coating);

    frame.inner_markers = SurfaceMesh{}; // topology change: rebuild
    CHECK(scene.set_frame(frame) == detail::SceneUpdate::built);
    CHECK(scene.closest_hit(Vec3::Zero(), axis, 0.0, 100.0).kind == detail::SurfaceKind::coating);
}

TEST_CASE("EmbreeScene leaves out the surface kinds a query does not ask for", "[render]") {
    // The dome's inner surface, then the markers on the axis, then the coating.
    detail::EmbreeScene scene;
    scene.set_frame(dome_with_marker_frame());
    const Vec3 axis = Vec3(0.01, 0.02, 1.0).normalized();
    using detail::kind_bit;
    using detail::SurfaceKind;
    const auto first = [&](unsigned kinds) {
        return scene.closest_hit(Vec3::Zero(), axis, 0.0, 100.0, kinds);
    };
    const detail::RayHit all = first(detail::kAllKinds);
    CHECK(all.kind == SurfaceKind::inner_surface);
    const detail::RayHit no_surface =
        first(detail::kAllKinds & ~kind_bit(SurfaceKind::inner_surface));
    CHECK(no_surface.kind == SurfaceKind::inner_marker);
    CHECK(no_surface.t_mm > all.t_mm);
    // The same hit as the full query's past the surface.
    const detail::RayHit past = scene.closest_hit(Vec3::Zero(), axis, all.t_mm + 1e-4, 100.0);
    CHECK(past.kind == SurfaceKind::inner_marker);
    CHECK(no_surface.t_mm == Approx(past.t_mm).epsilon(1e-6));
    CHECK(no_surface.prim_id == past.prim_id);
    CHECK(first(kind_bit(SurfaceKind::coating)).kind == SurfaceKind::coating);
    CHECK(first(kind_bit(SurfaceKind::coating) | kind_bit(SurfaceKind::inner_marker)).kind ==
          SurfaceKind::inner_marker);
    CHECK_FALSE(first(kind_bit(SurfaceKind::none)).hit());
}

// It also walks past more markers than it keeps.
TEST_CASE("RayHits walks a ray's hits as successive closest_hit calls do in fewer traversals",
          "[render]") {
    // The dome with both marker layers, the inner one replaced by the apex marker plus a stack
    // of six more at x = 3 mm (twelve faces, more than RayHits keeps).
    SensorFrame frame = dome_with_marker_frame();
    std::vector<std::pair<Vec3, Vec3>> stack = {{Vec3(0.0, 0.0, kInnerMarkerZ_mm), Vec3::UnitZ()}};
    for (int i = 1; i < 7; ++i)
        stack.push_back({Vec3(3.0, 0.0, 10.6 + 0.25 * i), Vec3::UnitZ()});
    frame.inner_markers = discs(stack);
    detail::EmbreeScene scene;
    scene.set_frame(frame);
    Eigen::Matrix<double, 3, Eigen::Dynamic> random = Eigen::MatrixXd::Random(3, 400);
    std::vector<std::pair<Vec3, Vec3>> rays = {
        {Vec3::Zero(), Vec3(0.01, 0.02, 1.0).normalized()},            // the apex marker
        {Vec3(3.0, 0.0, 10.55), Vec3(0.001, 0.002, 1.0).normalized()}, // up the stack
        {Vec3(3.0, 0.0, 13.0), Vec3(0.001, 0.002, -1.0).normalized()}, // down it
        // The outer marker, off its fan's centre (a vertex many triangles share, where either
        // may answer).
        {Vec3::Zero(), (kOuterMarkerDirection + Vec3(0.003, 0.0, 0.0)).normalized()}};
    for (Eigen::Index i = 0; i < random.cols(); i += 2)
        rays.push_back({Vec3(random(0, i), random(1, i), 11.0 + random(2, i)),
                        Vec3(random.col(i + 1)).normalized()});
    std::size_t walked = 0, long_walks = 0, ties = 0;
    std::uint64_t traversals[2] = {0, 0};
    for (const unsigned kinds :
         {detail::kAllKinds,
          detail::kAllKinds & ~detail::kind_bit(detail::SurfaceKind::inner_surface)}) {
        for (const auto& [origin, direction] : rays) {
            std::vector<detail::RayHit> one_by_one, walk;
            scene.count_rays(true);
            for (double tnear = 0.0; one_by_one.size() < 20;) {
                const detail::RayHit hit = scene.closest_hit(origin, direction, tnear, 30.0, kinds);
                if (!hit.hit()) break;
                one_by_one.push_back(hit);
                tnear = hit.t_mm + detail::kHitGap_mm;
            }
            traversals[0] += scene.rays_counted();
            scene.count_rays(true);
            detail::RayHits hits(scene, origin, direction, 0.0, 30.0, kinds);
            for (double tnear = 0.0; walk.size() < 20;) {
                const detail::RayHit hit = hits.next(tnear);
                if (!hit.hit()) break;
                walk.push_back(hit);
                tnear = hit.t_mm + detail::kHitGap_mm;
            }
            traversals[1] += scene.rays_counted();
            INFO("ray from " << origin.transpose() << " along " << direction.transpose());
            // Through the apex marker into the coating, the inner surface left out: its two
            // faces and the coating in one traversal (and one more past the coating), against
            // four.
            if (origin == Vec3::Zero() && direction.x() == rays[0].second.x() &&
                !(kinds & detail::kind_bit(detail::SurfaceKind::inner_surface))) {
                CHECK(walk.size() == 3);
                CHECK(scene.rays_counted() == 2);
            }
            REQUIRE(walk.size() == one_by_one.size());
            for (std::size_t k = 0; k < walk.size(); ++k) {
                CHECK(walk[k].kind == one_by_one[k].kind);
                CHECK(walk[k].t_mm == Approx(one_by_one[k].t_mm).epsilon(1e-6));
                CHECK((walk[k].normal - one_by_one[k].normal).norm() < 1e-6);
                // The same triangle, or, where two triangles tie (the same distance and
                // normal, checked above: the stack's discs share their side walls, so a ray
                // through a wall where two discs overlap meets both at once), either of them:
                // which one answers a tie is Embree's order of candidates, which differs
                // between machines (seen on one AMD EPYC machine, not on another).
                ties += walk[k].prim_id != one_by_one[k].prim_id;
            }
            walked += walk.size();
            long_walks += walk.size() > detail::RayHits::kMarkers + 1;
        }
    }
    scene.count_rays(false);
    INFO(walked << " hits, " << ties << " ties, " << long_walks
                << " walks past more markers than kept; traversals " << traversals[1] << " against "
                << traversals[0]);
    CHECK(walked > 600);
    CHECK(ties <= 2); // of the 600 and more hits (2 seen: one ray, both kinds of query)
    CHECK(long_walks >= 2);
    CHECK(traversals[1] < traversals[0]);
}

TEST_CASE("EmbreeScene packets of 16 rays answer as the rays one by one", "[render]") {
    // A dome with an inner surface and both marker layers; rays from the camera point and from
    // points in the layers, in random directions (a full packet and a partial one of 11),
    // with a near limit that skips the first surface for some rays.
    detail::EmbreeScene scene;
    scene.set_frame(dome_with_marker_frame());
    Eigen::Matrix<double, 3, Eigen::Dynamic> random = Eigen::MatrixXd::Random(3, 27 * 2);
    int compared = 0, hits = 0;
    for (const int count : {16, 11}) {
        for (const double tnear : {0.0, 1.0}) {
            std::vector<Vec3> origins, directions;
            for (int i = 0; i < count; ++i) {
                const Vec3 r = random.col(compared % random.cols());
                origins.push_back(i % 2 ? Vec3(0.0, 0.0, 0.0)
                                        : Vec3(0.3 * r.x(), 0.3 * r.y(), 11.5));
                Vec3 w = random.col((compared + 7) % random.cols());
                if (i == 0) w = Vec3(0.01, 0.02, 1.0); // through the markers on the axis
                directions.push_back(w.normalized());
                ++compared;
            }
            std::vector<detail::RayHit> packed(std::size_t(count), detail::RayHit{});
            scene.closest_hits16(origins, directions, tnear, 100.0, packed);
            for (int i = 0; i < count; ++i) {
                const detail::RayHit one = scene.closest_hit(
                    origins[std::size_t(i)], directions[std::size_t(i)], tnear, 100.0);
                const detail::RayHit& two = packed[std::size_t(i)];
                INFO("count " << count << ", tnear " << tnear << ", ray " << i);
                CHECK(two.kind == one.kind);
                CHECK(two.prim_id == one.prim_id);
                CHECK(two.t_mm == Approx(one.t_mm).epsilon(1e-5));
                CHECK(two.u == Approx(one.u).margin(1e-5));
                CHECK(two.v == Approx(one.v).margin(1e-5));
                CHECK((two.normal - one.normal).norm() < 1e-6);
                hits += one.hit();
            }
        }
    }
    CHECK(hits > 40); // most rays hit something: the comparison is not of empty answers
    std::vector<detail::RayHit> out(17);
    const std::vector<Vec3> seventeen(17, Vec3::UnitZ());
    CHECK_THROWS_AS(scene.closest_hits16(seventeen, seventeen, 0.0, 1.0, out),
                    std::invalid_argument);
    CHECK_THROWS_AS(scene.closest_hits16(std::span(seventeen).first(3),
                                         std::span(seventeen).first(2), 0.0, 1.0,
                                         std::span(out).first(3)),
                    std::invalid_argument);
}

// They see nothing but the inner surface, and tell which points are in the cavity.
TEST_CASE("EmbreeScene's inner-surface packets answer rays in the cavity as closest_hit does",
          "[render]") {
    // Rays in the cavity: from the camera point, and from points on the inner surface back
    // into the cavity (as the fast integrator's reflections). Their first surface in the whole
    // scene is the inner surface or nothing, and the inner surface's own BVH gives the same.
    detail::EmbreeScene scene;
    scene.set_frame(dome_with_marker_frame());
    Eigen::Matrix<double, 3, Eigen::Dynamic> random = Eigen::MatrixXd::Random(3, 64);
    int compared = 0, hits = 0;
    for (const int count : {16, 11, 2}) {
        std::vector<Vec3> origins, directions;
        for (int i = 0; i < count; ++i, ++compared) {
            Vec3 w = random.col(compared % random.cols()).normalized();
            if (i % 2 == 0) {
                // Mostly up into the dome; every fourth ray may leave through the base.
                origins.push_back(Vec3::Zero());
                w = Vec3(w.x(), w.y(), std::abs(w.z()) + (i % 4 == 0 ? -0.3 : 0.1)).normalized();
            } else {
                // A point of the inner surface, and a direction back into the cavity.
                const detail::RayHit out = scene.closest_hit(
                    Vec3::Zero(), Vec3(w.x(), w.y(), std::abs(w.z()) + 0.1).normalized(), 0.0,
                    100.0);
                REQUIRE(out.kind == detail::SurfaceKind::inner_surface);
                const Vec3 dir = Vec3(w.x(), w.y(), std::abs(w.z()) + 0.1).normalized();
                origins.push_back(out.t_mm * dir);
                w = (random.col((compared + 5) % random.cols()).normalized() - 1.5 * dir)
                        .normalized();
            }
            directions.push_back(w);
        }
        std::vector<detail::RayHit> packed(std::size_t(count), detail::RayHit{});
        const double tnear = detail::kHitGap_mm;
        scene.closest_interface_hits16(origins, directions, tnear, 100.0, packed);
        for (int i = 0; i < count; ++i) {
            const auto k = std::size_t(i);
            const detail::RayHit one = scene.closest_hit(origins[k], directions[k], tnear, 100.0);
            const detail::RayHit& two = packed[k];
            INFO("count " << count << ", ray " << i);
            CHECK(two.kind == one.kind);
            CHECK(two.prim_id == one.prim_id);
            CHECK(two.t_mm == Approx(one.t_mm).epsilon(1e-5));
            CHECK(two.u == Approx(one.u).margin(1e-5));
            CHECK(two.v == Approx(one.v).margin(1e-5));
            CHECK((two.normal - one.normal).norm() < 1e-6);
            CHECK((two.shading_normal - one.shading_normal).norm() < 1e-6);
            hits += one.kind == detail::SurfaceKind::inner_surface;
        }
    }
    CHECK(hits > 10);
    // From inside the layers the whole scene meets markers and the coating; the inner surface's
    // BVH does not.
    const std::vector<Vec3> in_layers(4, Vec3(0.0, 0.0, 11.5));
    const std::vector<Vec3> up(4, Vec3(0.01, 0.02, 1.0).normalized());
    std::vector<detail::RayHit> packed(4);
    scene.closest_interface_hits16(in_layers, up, 0.0, 100.0, packed);
    const detail::RayHit whole = scene.closest_hit(in_layers[0], up[0], 0.0, 100.0);
    CHECK(whole.kind != detail::SurfaceKind::none);
    CHECK(whole.kind != detail::SurfaceKind::inner_surface);
    for (const detail::RayHit& hit : packed)
        CHECK(hit.kind == detail::SurfaceKind::none);
    // Which points count as in the cavity: the centre and points well inside the inner
    // surface, on or above the rim plane; not in the layers, below the rim plane or outside.
    CHECK(scene.in_cavity(Vec3::Zero()));
    CHECK(scene.in_cavity(Vec3(3.0, -2.0, 5.0)));
    CHECK_FALSE(scene.in_cavity(Vec3(0.0, 0.0, 11.5)));
    CHECK_FALSE(scene.in_cavity(Vec3(0.0, 0.0, -1.0)));
    CHECK_FALSE(scene.in_cavity(Vec3(10.0, 10.0, 10.0)));
    SensorFrame bare = dome_with_marker_frame();
    bare.inner_surface = SurfaceMesh{};
    detail::EmbreeScene without;
    without.set_frame(bare);
    CHECK_FALSE(without.in_cavity(Vec3::Zero()));
}

TEST_CASE("shadow transmittance multiplies marker transmissions, the coating blocks", "[render]") {
    const OpticsParams optics;
    const detail::ShadingModel shading(optics);
    SensorFrame frame = marker_frame();
    frame.outer_markers = discs({{Vec3(0.0, 0.0, 12.4), Vec3::UnitZ()}}); // z 12.155..12.645
    detail::EmbreeScene scene;
    scene.set_frame(frame);
    const Vec3 from(0.0, 0.0, 1.0);
    const Eigen::Array3d a_in = optics.inner_marker_absorption_per_mm.array();
    const detail::Rgb inner = (-a_in * kThickness_mm).exp();
    const detail::Rgb outer =
        (1.0 - optics.outer_marker_scatter_fraction) *
        (-optics.outer_marker_absorption_per_mm.array() * kThickness_mm).exp();
    const detail::Rgb clear = shading.transmittance(scene, from, Vec3(0.0, 0.0, 10.0));
    const detail::Rgb one = shading.transmittance(scene, from, Vec3(0.0, 0.0, 12.0));
    const detail::Rgb two = shading.transmittance(scene, from, Vec3(0.0, 0.0, 12.68));
    const detail::Rgb blocked = shading.transmittance(scene, from, Vec3(0.0, 0.0, 14.0));
    // Segments that start or end inside the inner volume (z 10.505..10.995) count only the
    // part inside.
    const detail::Rgb from_inside =
        shading.transmittance(scene, Vec3(0.0, 0.0, 10.75), Vec3(0.0, 0.0, 12.0));
    const detail::Rgb into = shading.transmittance(scene, from, Vec3(0.0, 0.0, 10.801));
    for (int k = 0; k < 3; ++k) {
        CHECK(clear[k] == 1.0);
        CHECK(one[k] == Approx(inner[k]).epsilon(1e-6));
        CHECK(two[k] == Approx(inner[k] * outer[k]).epsilon(1e-5));
        CHECK(blocked[k] == 0.0);
        CHECK(from_inside[k] == Approx(std::exp(-a_in[k] * 0.245)).epsilon(1e-6));
        CHECK(into[k] == Approx(std::exp(-a_in[k] * (0.8 - 0.505))).epsilon(1e-5));
    }
}

TEST_CASE("grazing rays through markers take the real chord, squeezed markers stay finite",
          "[render]") {
    // A ray along (almost) +z through an inner prism tilted 85 deg: thickness / |cos| would
    // be 5.6 mm; the volume's real chord is about a disc diameter.
    const OpticsParams optics;
    const detail::ShadingModel shading(optics);
    SensorFrame frame = bare_frame();
    const Vec3 tilted_normal = unit_from_angles(85.0, 0.0);
    frame.inner_markers = discs({{Vec3(0.0, 0.0, kInnerMarkerZ_mm), tilted_normal}});
    detail::EmbreeScene with_disc, without_disc;
    with_disc.set_frame(frame);
    without_disc.set_frame(bare_frame());
    const Vec3 ray = Vec3(0.0, 0.001, 1.0).normalized();
    const detail::Rgb seen = shading.radiance(with_disc, Vec3::Zero(), ray);
    const detail::Rgb reference = shading.radiance(without_disc, Vec3::Zero(), ray);
    const double chord = chord_mm(Vec3::Zero(), ray, Vec3(0.0, 0.0, kInnerMarkerZ_mm),
                                  tilted_normal, kThickness_mm, 12.0);
    CHECK(chord > 0.9);
    CHECK(chord < 1.1);
    const detail::Rgb expected = (-optics.inner_marker_absorption_per_mm.array() * chord).exp();
    for (int k = 0; k < 3; ++k)
        CHECK(seen[k] / reference[k] == Approx(expected[k]).epsilon(1e-4));

    // A marker squeezed to zero thickness: its faces coincide; the ray enters and leaves at
    // once (path 0), nothing is absorbed, and nothing turns NaN.
    MeshBuilder flat;
    add_disc(flat, Vec3(0.0, 0.0, kInnerMarkerZ_mm), Vec3::UnitZ(), 0.0);
    frame.inner_markers = flat.build();
    with_disc.set_frame(frame);
    const detail::Rgb squeezed = shading.radiance(with_disc, Vec3::Zero(), ray);
    for (int k = 0; k < 3; ++k)
        CHECK(squeezed[k] == Approx(reference[k]).epsilon(1e-9));

    // Whole images with discs seen edge-on and nearly edge-on, one absorption channel zero
    // (an infinite path would turn 0 * inf into NaN).
    OpticsParams clear_red = optics;
    clear_red.inner_marker_absorption_per_mm.x() = 0.0;
    frame.inner_markers = discs({{Vec3(0.0, 0.0, kInnerMarkerZ_mm), Vec3::UnitX()},
                                 {Vec3(2.0, 0.0, 10.5), unit_from_angles(89.99, 180.0)},
                                 {Vec3(0.0, 3.0, 10.3), unit_from_angles(90.0, 90.0)}});
    frame.outer_markers = discs({{Vec3(-3.0, 0.0, 12.0), Vec3::UnitX()}});
    CHECK(all_finite(render_frame(CameraParams{64, 64, 84.0}, clear_red, frame)));
}
