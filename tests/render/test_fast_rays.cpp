// Tests of the fast integrator's rays: the frame's share near the rim, shadow rays culled,
// Embree packets, the shadow filter and shadow-ray counts, marker ids along the refracted
// ray, and the hero wavelengths.
#include "fast_fixtures.hpp"
#include "render/fisheye_camera.hpp"

#include <catch2/catch.hpp>
#include <tbb/global_control.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <thread>

using namespace chromasim::render;
using namespace chromasim::render::detail;
using namespace chromasim::render::test;

// Near the rim the sphere model's shadow paths leave the layers below the rim plane, which
// blocks part of the light the cache counts: that share is taken off G_k on the triangles
// that had one at rest, and only near the rim.
TEST_CASE("fast integrator: the frame's share of the LEDs' light is taken near the rim only, "
          "within [0, 1]",
          "[render][fast]") {
    const SensorFrame rest = dome_with_box_markers();
    const SensorFrame pressed = pressed_flat(rest);
    FastOnFrame on(pressed, rest);
    auto& [scene, shading, path, fast] = on;
    const auto& V = pressed.coating.V;
    const auto& F = pressed.coating.F;
    int flagged = 0, shaded = 0;
    double lowest_polar = 180.0, smallest = 1.0, largest = 0.0;
    for (Eigen::Index t = 0; t < F.rows(); ++t) {
        const Vec3 a = V.row(F(t, 0)).cast<double>().transpose();
        const Vec3 b = V.row(F(t, 1)).cast<double>().transpose();
        const Vec3 c = V.row(F(t, 2)).cast<double>().transpose();
        Vec3 n = (b - a).cross(c - a).normalized();
        if (n.dot(a) > 0.0) n = -n; // towards the dome centre
        for (int k = 0; k < path.led_count(); ++k) {
            if (!fast.frame_share_taken(std::uint32_t(t), k)) continue;
            ++flagged;
            const Vec3 m = (a + b + c) / 3.0;
            lowest_polar =
                std::min(lowest_polar, std::acos(m.z() / m.norm()) * 180.0 / std::numbers::pi);
            // At the first corner: its unshadowed light times (1 - its share).
            const double open = fast.frame_direct(int(F(t, 0)), k).dot(n);
            if (!(open > 1e-9)) continue;
            const double share = 1.0 - fast.direct_at(std::uint32_t(t), 0.0, 0.0, n, k) / open;
            smallest = std::min(smallest, share);
            largest = std::max(largest, share);
            shaded += share > 1e-3;
        }
    }
    INFO(flagged << " (triangle, LED) pairs take the share, " << shaded
                 << " with a share at their first corner, in [" << smallest << ", " << largest
                 << "]; the highest at a polar angle of " << lowest_polar << " deg");
    CHECK(flagged > 10);
    CHECK(shaded > 0);
    CHECK(smallest >= -1e-6);
    CHECK(largest <= 1.0 + 1e-6);
    CHECK(lowest_polar > 60.0);
}

// Checked at rest, pressed and where the coating folds inwards.
TEST_CASE("fast integrator: shadow rays culled where they provably meet nothing leave the image as "
          "it was",
          "[render][fast]") {
    const SensorFrame rest = dome_with_box_markers();
    // A groove 1.8 mm deep on the coating's ring at 61.9 degrees: shadow rays from above it
    // meet its wall (the culling that leaves out the folds fails here, 0.08 off).
    const SensorFrame groove = grooved(rest, 60.0, 63.0, 1.8);
    RenderSettings settings;
    settings.integrator = Integrator::fast;
    settings.samples_per_pixel = 4;
    for (const auto& [name, frame] : {std::pair<const char*, SensorFrame>{"at rest", rest},
                                      {"pressed flat", pressed_flat(rest)},
                                      {"grooved", groove}}) {
        std::vector<float> images[2];
        std::uint64_t rays[2] = {0, 0};
        for (const bool cull : {false, true}) {
            Renderer renderer(CameraParams{32, 32, 84.0}, OpticsParams{});
            LightCacheSettings cache = small_cache();
            cache.cull_shadows = cull;
            small_cache_on(renderer, rest, frame, cache);
            renderer.count_rays(true);
            images[cull] = renderer.render(settings).rgb;
            rays[cull] = renderer.rays_counted();
        }
        double worst = 0.0, mean = 0.0;
        for (std::size_t i = 0; i < images[0].size(); ++i) {
            worst = std::max(worst, double(std::abs(images[1][i] - images[0][i])));
            mean += images[0][i] / double(images[0].size());
        }
        INFO(name << ": largest difference " << worst << " (image mean " << mean << "), rays "
                  << rays[1] << " culled against " << rays[0] << " traced");
        CHECK(mean > 0.05);
        // The culling's shadow rays take their direction by Newton from the frame's guess,
        // to 3.4e-3 rad at most (kShadowStepTolerance); without it, over the whole bracket to
        // 1e-9: their shadows' edges move by microns (9.5e-5 here at most). A ray culled that
        // meets a marker would leave its shadow out (0.08 off in the groove).
        CHECK(worst < 5e-4);
        CHECK(double(rays[1]) < 0.95 * double(rays[0]));
    }
}

TEST_CASE("fast integrator: a pixel's samples traced in Embree packets of 16 match one by one to "
          "the bit",
          "[render][fast]") {
    const SensorFrame rest = dome_with_box_markers();
    const SensorFrame pressed = pressed_flat(rest);
    FastOnFrame on(pressed, rest);
    auto& [scene, shading, path, fast] = on;
    const LaneOptics<kRgbLanes> lanes = shading.rgb_lanes();
    // Bundles of 16 (and fewer) directions 1 degree across, from the apex to past the rim
    // (grazing, where the inner surface reflects most and the reflected ray meets the far
    // wall), over markers and bare coating. Not through the UV spheres' poles: a ray through
    // a vertex that many triangles share may take another of them in a packet than alone.
    int compared = 0, reflected = 0;
    for (const double polar : {0.1, 12.5, 25.0, 40.0, 62.5, 75.0, 83.0, 88.0}) {
        for (const double azimuth : {0.0, 33.0, 190.0}) {
            for (const std::size_t n : {std::size_t(16), std::size_t(5)}) {
                std::vector<Vec3> directions;
                std::vector<ShadowDraw> shadow;
                for (std::size_t i = 0; i < n; ++i) {
                    directions.push_back(unit_from_angles(polar + 0.25 * double(i % 4),
                                                          azimuth + 0.25 * double(i / 4)));
                    // Half the samples with their shadow uniforms given, half drawing them.
                    shadow.push_back(i % 2 ? ShadowDraw{}
                                           : ShadowDraw{(double(i) + 0.5) / double(n), 0.3, 0.8});
                }
                const std::vector<const LaneOptics<kRgbLanes>*> lane_sets(n, &lanes);
                const std::vector<const CacheLambdas<kRgbLanes>*> lambdas(n, nullptr);
                std::vector<RgbLanes> packed(n);
                // Two pixels' streams: the first half of the samples draws from one, the
                // rest from the other (a packet of two neighbouring pixels' samples).
                PixelRng a(7, std::uint64_t(polar * 1000 + azimuth)), b = a;
                PixelRng a2(8, std::uint64_t(polar * 1000 + azimuth)), b2 = a2;
                std::vector<PixelRng*> streams(n, &a);
                for (std::size_t i = n / 2; i < n; ++i)
                    streams[i] = &a2;
                fast.radiance16<kRgbLanes>(scene, Vec3::Zero(), directions, lane_sets, lambdas,
                                           shadow, streams, packed);
                for (std::size_t i = 0; i < n; ++i) {
                    const RgbLanes one =
                        fast.radiance<kRgbLanes>(scene, Vec3::Zero(), directions[i], lanes, nullptr,
                                                 i < n / 2 ? b : b2, shadow[i]);
                    INFO("polar " << polar << ", azimuth " << azimuth << ", sample " << i << " of "
                                  << n);
                    CHECK((packed[i] == one).all());
                    ++compared;
                    reflected += polar >= 75.0 && one.maxCoeff() > 0.0;
                }
                CHECK(a.uniform() == b.uniform()); // the same draws, in the same order
                CHECK(a2.uniform() == b2.uniform());
            }
        }
    }
    CHECK(compared == 8 * 3 * 21);
    CHECK(reflected > 0);
    CHECK_THROWS_WITH(fast.radiance16<kRgbLanes>(scene, Vec3::Zero(),
                                                 std::vector<Vec3>(17, Vec3::UnitZ()), {}, {}, {},
                                                 {}, std::span<RgbLanes>{}),
                      Catch::Contains("allowed: at most 16"));
}

// The direct light given apart adds up and changes no sample.
TEST_CASE("fast integrator: the shadow filter brings a noisy image nearer the converged one",
          "[render][fast]") {
    const SensorFrame rest = dome_with_box_markers();
    const SensorFrame pressed = pressed_flat(rest);
    // The parts of a sample (radiance16 with and without `direct`): the same radiance to the
    // bit, the shadowed light within the unshadowed, the rest (indirect light) not negative.
    {
        FastOnFrame on(pressed, rest);
        auto& [scene, shading, path, fast] = on;
        const LaneOptics<kRgbLanes> lanes = shading.rgb_lanes();
        int shadowed = 0, lit = 0, parts = 0, clear = 0;
        for (const double polar : {5.0, 30.0, 55.0, 70.0, 80.0}) {
            for (const double azimuth : {0.0, 20.0, 45.0, 100.0}) {
                constexpr std::size_t n = 16;
                std::vector<Vec3> directions;
                std::vector<ShadowDraw> shadow;
                for (std::size_t i = 0; i < n; ++i) {
                    directions.push_back(unit_from_angles(polar + 0.4 * double(i % 4),
                                                          azimuth + 0.4 * double(i / 4)));
                    shadow.push_back({(double(i) + 0.5) / double(n), 0.3, 0.7});
                }
                const std::vector<const LaneOptics<kRgbLanes>*> lane_sets(n, &lanes);
                const std::vector<const CacheLambdas<kRgbLanes>*> lambdas(n, nullptr);
                std::vector<RgbLanes> plain(n), split(n);
                std::vector<DirectLight<kRgbLanes>> direct(n);
                PixelRng a(3, 9), b = a;
                std::vector<PixelRng*> sa(n, &a), sb(n, &b);
                fast.radiance16<kRgbLanes>(scene, Vec3::Zero(), directions, lane_sets, lambdas,
                                           shadow, sa, plain);
                fast.radiance16<kRgbLanes>(scene, Vec3::Zero(), directions, lane_sets, lambdas,
                                           shadow, sb, split, direct);
                for (std::size_t i = 0; i < n; ++i) {
                    INFO("polar " << polar << ", azimuth " << azimuth << ", sample " << i);
                    CHECK((plain[i] == split[i]).all());
                    const DirectLight<kRgbLanes>& d = direct[i];
                    CHECK((d.shadowed() <= d.lit() * (1 + 1e-12)).all());
                    CHECK((d.shadowed() >= 0.0).all());
                    CHECK((split[i] - d.shadowed() >= -1e-12).all());
                    shadowed += (d.shadowed().head<3>() < 0.99 * d.lit().head<3>()).any();
                    lit += (d.lit().head<3>() > 0.0).all();
                    // Each part: its LED's group among the 6 (one per LED), its groups'
                    // shares of the unshadowed light adding up to 1 where there is any,
                    // and `clear` only where nothing was in the shadow ray's way.
                    CHECK((d.parts >= 0 && d.parts <= kMaxDirectParts));
                    for (int q = 0; q < d.parts; ++q) {
                        const DirectPart<kRgbLanes>& part = d.part[std::size_t(q)];
                        CHECK((part.group >= 0 && part.group < fast.shadow_groups()));
                        double share = 0.0;
                        for (const double s : part.share)
                            share += s;
                        if ((part.lit > 0.0).any()) {
                            CHECK(share == Approx(1.0).margin(1e-12));
                            for (int g = fast.shadow_groups(); g < kMaxShadowGroups; ++g)
                                CHECK(part.share[std::size_t(g)] == 0.0);
                        }
                        if (part.clear) CHECK((part.shadowed == part.lit).all());
                        parts += 1, clear += part.clear;
                    }
                }
            }
        }
        CHECK(lit > 200);     // most samples see LED light on the coating
        CHECK(shadowed > 10); // and some of them through a marker's shadow
        CHECK(fast.shadow_groups() == 6);
        INFO(parts << " parts, " << clear << " clear");
        CHECK(parts >= lit); // a part for every sample that meets the coating
        CHECK(clear > 0);
        CHECK(clear < parts);
    }
    // The image: a 1-spp render, filtered and not, against a 256-spp one (unfiltered). On
    // these box markers, most of the noise is the camera's samples across their sharp
    // edges, so the filter takes off about an eighth (on the shipped dome, at 896 px and
    // 4 spp, three fifths: docs/VALIDATION.md); with the direct light's parts mixed up
    // between pixels or swapped, it adds error.
    Renderer renderer(CameraParams{96, 96, 84.0}, OpticsParams{});
    small_cache_on(renderer, rest, pressed);
    RenderSettings settings{256, 3};
    settings.integrator = Integrator::fast;
    const Image converged = renderer.render(settings);
    settings.samples_per_pixel = 1;
    settings.seed = 4;
    const Image noisy = renderer.render(settings);
    settings.shadow_filter_px = 0.0;
    CHECK(renderer.render(settings).rgb == noisy.rgb); // 0: no filter, the same bytes
    const auto rms = [&](const Image& image) {
        double sum = 0.0;
        for (std::size_t i = 0; i < image.rgb.size(); ++i)
            sum += std::pow(double(image.rgb[i]) - converged.rgb[i], 2);
        return std::sqrt(sum / double(image.rgb.size()));
    };
    settings.shadow_filter_px = 1.0;
    const Image filtered = renderer.render(settings);
    INFO("RMS against 256 spp: " << rms(noisy) << " unfiltered, " << rms(filtered) << " filtered");
    CHECK(rms(filtered) < 0.92 * rms(noisy));
    // The variance channel stays the unfiltered pixel's.
    settings.variance = true;
    const Image with_variance = renderer.render(settings);
    CHECK(with_variance.rgb == filtered.rgb);
    settings.shadow_filter_px = 0.0;
    CHECK(renderer.render(settings).variance == with_variance.variance);
    for (const double bad : {-0.5, kMaxShadowFilterPx + 1.0, std::nan("")}) {
        settings.shadow_filter_px = bad;
        CHECK_THROWS_WITH(renderer.render(settings), Catch::Contains("shadow_filter_px"));
    }
}

// shadow_rays_per_pixel: up to the sample count the same bytes; their parts add up to the same
// unshadowed light; the same bytes on 1 and 2 threads.
TEST_CASE("fast integrator: more shadow rays a pixel give the same image on average with less "
          "noise",
          "[render][fast]") {
    const SensorFrame rest = dome_with_box_markers();
    const SensorFrame pressed = pressed_flat(rest);
    // A sample's parts: with 3 shadow rays, 3 parts at the coating hit, their unshadowed
    // light adding up to the one-ray sample's, the radiance the mean of the rays' (its
    // shadowed light within the unshadowed).
    {
        FastOnFrame on(pressed, rest);
        auto& [scene, shading, path, fast] = on;
        const LaneOptics<kRgbLanes> lanes = shading.rgb_lanes();
        constexpr std::size_t n = 16;
        std::vector<Vec3> directions;
        std::vector<ShadowDraw> one, three;
        for (std::size_t i = 0; i < n; ++i) {
            directions.push_back(unit_from_angles(10.0 + 4.0 * double(i), 15.0 * double(i)));
            one.push_back({(double(i) + 0.5) / double(n), 0.3, 0.7});
            ShadowDraw d = one.back();
            d.rays = 3;
            d.further[0] = {0.9 - 0.05 * double(i), 0.6, 0.2};
            d.further[1] = {0.05 * double(i), 0.1, 0.9};
            three.push_back(d);
        }
        const std::vector<const LaneOptics<kRgbLanes>*> lane_sets(n, &lanes);
        const std::vector<const CacheLambdas<kRgbLanes>*> lambdas(n, nullptr);
        std::vector<RgbLanes> r1(n), r3(n);
        std::vector<DirectLight<kRgbLanes>> d1(n), d3(n);
        PixelRng a(3, 9), b = a;
        std::vector<PixelRng*> sa(n, &a), sb(n, &b);
        fast.radiance16<kRgbLanes>(scene, Vec3::Zero(), directions, lane_sets, lambdas, one, sa, r1,
                                   d1);
        fast.radiance16<kRgbLanes>(scene, Vec3::Zero(), directions, lane_sets, lambdas, three, sb,
                                   r3, d3);
        int lit = 0, differ = 0;
        for (std::size_t i = 0; i < n; ++i) {
            INFO("sample " << i << ": " << d1[i].parts << " and " << d3[i].parts << " parts");
            CHECK((d3[i].lit() - d1[i].lit()).abs().maxCoeff() <=
                  1e-12 * (1.0 + d1[i].lit().abs().maxCoeff()));
            CHECK((d3[i].shadowed() <= d3[i].lit() * (1 + 1e-12)).all());
            // The indirect light is the same: the radiances differ by the shadowed light's.
            CHECK(((r3[i] - d3[i].shadowed()) - (r1[i] - d1[i].shadowed())).abs().maxCoeff() <=
                  1e-12);
            if ((d1[i].lit() > 0.0).any()) {
                ++lit;
                CHECK(d3[i].parts == d1[i].parts + 2);
                differ += (d3[i].shadowed() != d1[i].shadowed()).any();
            }
        }
        CHECK(lit > 8);
        CHECK(differ > 0); // the other rays found other shadows somewhere
    }
    Renderer renderer(CameraParams{96, 96, 84.0}, OpticsParams{});
    small_cache_on(renderer, rest, pressed);
    RenderSettings settings{256, 3};
    settings.integrator = Integrator::fast;
    const Image converged = renderer.render(settings);
    settings = fast_with_variance(2, 4);
    const Image plain = renderer.render(settings);
    // Up to the pixel's sample count: one a sample, the same bytes.
    for (const int rays : {1, 2}) {
        settings.shadow_rays_per_pixel = rays;
        CHECK(renderer.render(settings).rgb == plain.rgb);
    }
    // 8 (4 a sample at 2 spp) and more: the same, at most 4 a sample.
    settings.shadow_rays_per_pixel = 8;
    const Image more = renderer.render(settings);
    settings.shadow_rays_per_pixel = 50;
    CHECK(renderer.render(settings).rgb == more.rgb);
    // The error against 256 spp, and the sums over the image against the converged one's
    // (both unbiased: within 4 standard deviations of the sum, from the variance channel).
    const auto compare = [&](const Image& image, double& rms, double& sum, double& var,
                             double& converged_sum) {
        rms = sum = var = converged_sum = 0.0;
        for (std::size_t i = 0; i < image.rgb.size(); ++i) {
            rms += std::pow(double(image.rgb[i]) - converged.rgb[i], 2);
            sum += image.rgb[i], var += image.variance[i], converged_sum += converged.rgb[i];
        }
        rms = std::sqrt(rms / double(image.rgb.size()));
    };
    double rms_plain, sum_plain, var_plain, rms_more, sum_more, var_more, sum_converged;
    compare(plain, rms_plain, sum_plain, var_plain, sum_converged);
    compare(more, rms_more, sum_more, var_more, sum_converged);
    INFO("RMS against 256 spp: " << rms_plain << " with one shadow ray a sample, " << rms_more
                                 << " with 4; sums " << sum_plain << ", " << sum_more
                                 << ", converged " << sum_converged << "; summed variances "
                                 << var_plain << ", " << var_more);
    CHECK(more.rgb != plain.rgb);
    CHECK(std::abs(sum_more - sum_converged) < 4.0 * std::sqrt(var_more));
    CHECK(std::abs(sum_plain - sum_converged) < 4.0 * std::sqrt(var_plain));
    // The shadow rays' noise is part of each sample's: less of it, with the filter too.
    CHECK(rms_more < 0.97 * rms_plain);
    CHECK(var_more < 0.97 * var_plain);
    settings.shadow_filter_px = 1.0;
    settings.shadow_rays_per_pixel = 0;
    const Image filtered_plain = renderer.render(settings);
    settings.shadow_rays_per_pixel = 8;
    const Image filtered_more = renderer.render(settings);
    double rms_fp, rms_fm, unused;
    compare(filtered_plain, rms_fp, unused, unused, unused);
    compare(filtered_more, rms_fm, unused, unused, unused);
    INFO("filtered: " << rms_fp << " with one a sample, " << rms_fm << " with 4");
    CHECK(rms_fm < rms_fp);
    // The same bytes on 1 and 2 threads.
    Image threads_one, threads_two;
    {
        tbb::global_control threads(tbb::global_control::max_allowed_parallelism, 1);
        threads_one = renderer.render(settings);
    }
    {
        tbb::global_control threads(tbb::global_control::max_allowed_parallelism, 2);
        threads_two = renderer.render(settings);
    }
    CHECK(threads_one.rgb == filtered_more.rgb);
    CHECK(threads_two.rgb == filtered_more.rgb);
    CHECK(threads_one.variance == threads_two.variance);
    settings.shadow_rays_per_pixel = -1;
    CHECK_THROWS_WITH(renderer.render(settings),
                      Catch::Contains("shadow_rays_per_pixel = -1 is invalid") &&
                          Catch::Contains("allowed: integer >= 0"));
}

// The ids follow the markers as the samples see them; the preview integrator's ids go
// straight through the inner surface.
TEST_CASE("fast integrator: marker ids and rim pixels follow the camera ray refracted at the inner "
          "surface",
          "[render][fast]") {
    // A press tilted 35 degrees: the camera rays meet its flat cut well off normal incidence
    // and bend by several degrees on their way to the markers.
    const SensorFrame rest = dome_with_box_markers();
    const SensorFrame pressed = pressed_tilted(rest, 35.0f);
    const CameraParams camera{96, 96, 84.0};
    Renderer renderer(camera, OpticsParams{});
    small_cache_on(renderer, rest, pressed);
    RenderSettings settings{1, 5};
    settings.marker_ids = true;
    settings.integrator = Integrator::fast;
    const Image fast = renderer.render(settings);
    settings.integrator = Integrator::preview;
    const Image direct = renderer.render(settings);
    // The ids by hand: Snell's law at the inner surface's interpolated normal written out, then
    // closest_hit after closest_hit to the coating, the first marker face of each layer.
    EmbreeScene scene;
    scene.set_frame(pressed);
    const FisheyeCamera lens(camera);
    const double eta = 1.0 / OpticsParams{}.refractive_index;
    const double inf = std::numeric_limits<double>::infinity();
    const auto walk = [&](const Vec3& from, const Vec3& d, double tnear, unsigned kinds) {
        std::pair<std::int32_t, std::int32_t> ids{-1, -1};
        for (int i = 0; i < 32; ++i) {
            const RayHit hit = scene.closest_hit(from, d, tnear, inf, kinds);
            if (hit.kind != SurfaceKind::inner_marker && hit.kind != SurfaceKind::outer_marker)
                break;
            tnear = hit.t_mm + kHitGap_mm;
            std::int32_t& id = hit.kind == SurfaceKind::inner_marker ? ids.first : ids.second;
            if (id < 0) id = std::int32_t(hit.prim_id / 12);
        }
        return ids;
    };
    const unsigned no_interface = kAllKinds & ~kind_bit(SurfaceKind::inner_surface);
    int refracted_differs = 0, straight_differs = 0, with_marker = 0, bent = 0, wrong = 0;
    for (int y = 0; y < camera.height_px; ++y)
        for (int x = 0; x < camera.width_px; ++x) {
            const std::size_t p = std::size_t(y) * std::size_t(camera.width_px) + std::size_t(x);
            const auto d = lens.direction(Eigen::Vector2d(x + 0.5, y + 0.5));
            std::pair<std::int32_t, std::int32_t> seen{-1, -1}, straight{-1, -1};
            if (d) {
                straight = walk(lens.origin_mm(), *d, 0.0, no_interface);
                const RayHit in = scene.closest_hit(lens.origin_mm(), *d, 0.0, inf);
                if (in.kind == SurfaceKind::inner_surface && in.normal.dot(*d) < 0.0) {
                    const Vec3 n = in.shading_normal.dot(*d) < 0.0 ? in.shading_normal
                                                                   : Vec3(-in.shading_normal);
                    const double cos_i = -n.dot(*d);
                    const double k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
                    const Vec3 r = (eta * *d + (eta * cos_i - std::sqrt(k)) * n).normalized();
                    bent += std::acos(std::clamp(r.dot(*d), -1.0, 1.0)) >
                            2.0 * std::numbers::pi / 180.0;
                    seen = walk(lens.origin_mm() + in.t_mm * *d, r, kHitGap_mm, kAllKinds);
                }
            }
            with_marker += seen.first >= 0 || seen.second >= 0;
            wrong +=
                fast.inner_marker_id[p] != seen.first || fast.outer_marker_id[p] != seen.second;
            refracted_differs += seen != straight;
            straight_differs += direct.inner_marker_id[p] != straight.first ||
                                direct.outer_marker_id[p] != straight.second;
        }
    INFO(with_marker << " pixels show a marker, " << bent << " rays bend by more than 2 degrees, "
                     << refracted_differs << " pixels' ids change with the bend");
    CHECK(wrong == 0);
    CHECK(straight_differs == 0);
    // The bend matters here: without it the ids (and the rims) would be off.
    CHECK(bent > 500);
    CHECK(refracted_differs > 50);
    CHECK(with_marker > 500);
}

// fast_wavelengths 8 has a little more noise; 0 picks by the samples per pixel, other
// counts are refused.
TEST_CASE("fast integrator: 8 hero wavelengths a sample estimate the same colours as 16",
          "[render][fast]") {
    const SensorFrame rest = dome_with_box_markers();
    const SensorFrame pressed = pressed_flat(rest);
    Renderer renderer(CameraParams{48, 48, 84.0}, spectral_optics());
    small_cache_on(renderer, rest, pressed);
    // 8 wavelengths with seeds 21 and 22, 16 with seed 22 (the same camera samples as the
    // second 8, other wavelengths).
    RenderSettings settings = fast_with_variance(16, 21);
    settings.fast_wavelengths = 8;
    const Image eight = renderer.render(settings);
    settings.seed = 22;
    const Image eight_again = renderer.render(settings);
    settings.fast_wavelengths = 16;
    const Image sixteen = renderer.render(settings);
    REQUIRE(eight.rgb.size() == sixteen.rgb.size());
    CHECK(eight_again.rgb != sixteen.rgb); // the setting is the render's
    // Per channel: the image's mean (the wavelengths' colours: a wrong table or white balance
    // moves it everywhere), and the pixels' differences against their variance channels (a
    // chi-square per value, below 1 where the strata beat independent samples): 8 against 16
    // as far apart as 8 against 8 with other samples.
    std::array<double, 3> mean8{}, mean16{}, mean8b{};
    double chi2 = 0.0, chi2_same = 0.0, var8 = 0.0, var16 = 0.0;
    std::size_t counted = 0;
    for (std::size_t i = 0; i < eight.rgb.size(); ++i) {
        mean8[i % 3] += eight.rgb[i], mean16[i % 3] += sixteen.rgb[i];
        mean8b[i % 3] += eight_again.rgb[i];
        const double v8 = eight.variance[i], v8b = eight_again.variance[i],
                     v16 = sixteen.variance[i];
        if (v8 + v16 <= 0.0 || v8 + v8b <= 0.0) continue;
        chi2 += std::pow(double(eight.rgb[i]) - sixteen.rgb[i], 2) / (v8 + v16);
        chi2_same += std::pow(double(eight.rgb[i]) - eight_again.rgb[i], 2) / (v8 + v8b);
        var8 += v8, var16 += v16;
        ++counted;
    }
    REQUIRE(counted > 3000);
    chi2 /= double(counted), chi2_same /= double(counted);
    INFO("chi-square per value: 8 against 16 " << chi2 << ", 8 against 8 (another seed) "
                                               << chi2_same << "; variance 8 / 16 "
                                               << var8 / var16);
    for (int c = 0; c < 3; ++c) {
        INFO("channel " << c << ": mean " << mean8[std::size_t(c)] << " (8), "
                        << mean8b[std::size_t(c)] << " (8, another seed), "
                        << mean16[std::size_t(c)] << " (16)");
        CHECK(mean8b[std::size_t(c)] == Approx(mean16[std::size_t(c)]).epsilon(0.001));
        CHECK(mean8[std::size_t(c)] == Approx(mean16[std::size_t(c)]).epsilon(0.002));
    }
    // The two counts differ by no more than two draws of one count do.
    CHECK(chi2 < 1.15 * chi2_same);
    CHECK(chi2 > 0.85 * chi2_same);
    CHECK(chi2 < 1.0);
    // Fewer wavelengths, no more than a little more noise (here the camera samples' positions
    // on the markers' sharp edges hold most of it).
    CHECK(var8 < 1.2 * var16);
    // 0 (the default): 16 at one sample per pixel, 8 from 2 on.
    for (const int spp : {1, 2}) {
        settings.samples_per_pixel = spp;
        settings.fast_wavelengths = spp == 1 ? 16 : 8;
        const Image chosen = renderer.render(settings);
        settings.fast_wavelengths = 0;
        CHECK(renderer.render(settings).rgb == chosen.rgb);
        CHECK(fast_wavelengths_of(settings) == (spp == 1 ? 16 : 8));
    }
    for (const int bad : {-1, 4, 12, 32}) {
        settings.fast_wavelengths = bad;
        CHECK_THROWS_WITH(renderer.render(settings),
                          Catch::Contains("fast_wavelengths = " + std::to_string(bad)) &&
                              Catch::Contains("8 or 16"));
    }
}

// Hence 2 samples of 8 wavelengths are about as noisy in colour as 1 of 16.
TEST_CASE("fast integrator: a pixel's samples split the hero wavelengths' strata between them",
          "[render][fast]") {
    // A narrow camera that sees the coating through one wide inner (magenta) marker at the
    // apex: every pixel's colour is the filter's product with the LEDs' spectrum, so the
    // wavelengths drawn make much of its noise.
    SensorFrame rest = clear_dome(16, 64, 24, 96);
    rest.inner_markers = box_markers(10.75, 0.5, 3.0);
    rest.triangles_per_marker = 12;
    Renderer renderer(CameraParams{48, 48, 5.0}, spectral_optics());
    small_cache_on(renderer, rest, rest);
    // The noise: half the mean squared difference of two seeds' images, over the values.
    const auto noise = [&](int spp, int wavelengths) {
        RenderSettings settings{spp, 31};
        settings.integrator = Integrator::fast;
        settings.fast_wavelengths = wavelengths;
        const Image a = renderer.render(settings);
        settings.seed = 32;
        const Image b = renderer.render(settings);
        double sum = 0.0;
        for (std::size_t i = 0; i < a.rgb.size(); ++i)
            sum += std::pow(double(a.rgb[i]) - b.rgb[i], 2);
        return sum / 2.0 / double(a.rgb.size());
    };
    const double eight_2 = noise(2, 8), sixteen_1 = noise(1, 16), eight_1 = noise(1, 8);
    INFO("variance: 2 spp x 8 wavelengths " << eight_2 << ", 1 x 16 " << sixteen_1 << ", 1 x 8 "
                                            << eight_1);
    // Measured 1.74e-4, 1.59e-4 and 4.56e-4. With each sample's 8 drawn over the whole
    // strata (0.26.0's draw, where sets i and i + 128 hold the same wavelengths) 2 x 8 gave
    // 2.11e-4: 1.32 times 1 x 16 and 0.47 times 1 x 8.
    CHECK(eight_2 < 1.2 * sixteen_1);
    CHECK(eight_2 < 0.42 * eight_1);
}
