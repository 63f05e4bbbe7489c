// Each pixel's camera samples: drawn from its stream and strata (kept from render to render
// for the fast integrator), traced through the preview, path or fast integrator and summed.
#include "render/renderer_impl.hpp"

namespace chromasim::render {

template <Integrator I>
detail::Rgb Renderer::Impl::sample_pixel(int x, int y, int nx, int ny,
                                         const RenderSettings& settings, double scale,
                                         detail::Rgb* sum2, int& inside) const {
    const std::uint64_t index = std::uint64_t(y) * std::uint64_t(camera.width_px()) + x;
    detail::PixelRng rng(settings.seed, index);
    const detail::PixelSeeds seeds(settings.seed, index);
    detail::Rgb sum = detail::Rgb::Zero();
    inside = 0;
    for (int sy = 0; sy < ny; ++sy) {
        for (int sx = 0; sx < nx; ++sx) {
            const Draw d = draw(x, y, sy * nx + sx, nx, ny, rng, seeds);
            if (!d.direction) continue;
            ++inside;
            const detail::Rgb value =
                sample_rgb<I>(scene, camera.origin_mm(), *d.direction, d.u_lambda, rng);
            sum += value;
            if (sum2) *sum2 += (value * scale).square();
        }
    }
    return sum;
}

Renderer::Impl::Draw Renderer::Impl::draw(int x, int y, int k, int nx, int ny,
                                          detail::PixelRng& rng,
                                          const detail::PixelSeeds& seeds) const {
    const int count = nx * ny;
    Draw d;
    const double jx = rng.uniform(), jy = rng.uniform();
    const auto [u, v] = detail::multi_jittered(k, nx, ny, seeds.position, jx, jy);
    d.direction = camera.direction(Eigen::Vector2d(x + u, y + v));
    // Outside the field in a pixel its edge crosses: a position drawn anew, uniformly
    // over the pixel until inside (at most kFieldRedraws tries; still outside: the sample
    // is dropped). With the pixel's value the coverage times the mean of its samples
    // inside (render()), this keeps the estimate unbiased: stratum k's sample is uniform
    // over the part of the stratum inside, else over the part of the pixel inside, and
    // those two weigh in as the coverage and its complement.
    if (!d.direction && camera.field_coverage(x, y) > 0.0)
        for (int i = 0; i < kFieldRedraws && !d.direction; ++i) {
            const double rx = rng.uniform(), ry = rng.uniform();
            d.direction = camera.direction(Eigen::Vector2d(x + rx, y + ry));
        }
    if (wavelengths)
        d.u_lambda =
            (detail::wavelength_stratum(k, count, seeds.wavelength) + rng.uniform()) / count;
    return d;
}

std::optional<std::pair<Vec3, int>>
Renderer::Impl::fast_draw(int x, int y, int k, int nx, int ny, detail::PixelRng& rng,
                          const detail::PixelSeeds& seeds) const {
    const Draw d = draw(x, y, k, nx, ny, rng, seeds);
    if (!d.direction) return std::nullopt;
    const int hero =
        hero_sets.empty() ? 0 : std::clamp(int(d.u_lambda * kHeroSets), 0, kHeroSets - 1);
    return std::make_pair(*d.direction, hero);
}

void Renderer::Impl::keep_for(SampleClass sample_class, std::uint64_t seed, int count, int rays,
                              std::size_t budget_bytes) const {
    KeptSamples& k = kept[sample_class];
    std::size_t pixels =
        budget_bytes > 0 && count > 0 ? std::size_t(camera.width_px()) * camera.height_px() : 0;
    if (k.seed == seed && k.count == count && k.rays == rays && k.pixel.size() == pixels) return;
    for (const auto& d : k.pixel)
        if (d) kept_bytes -= PixelDraws::size(k.count, k.rays) * sizeof(double);
    kept_bytes -= k.pixel.size() * sizeof(std::unique_ptr<double[]>);
    k.pixel.clear();
    k.pixel.shrink_to_fit();
    k.seed = seed, k.count = count, k.rays = rays;
    // The budget holds the pixels' index too (8 bytes a pixel and count).
    const std::size_t index_bytes = pixels * sizeof(std::unique_ptr<double[]>);
    if (kept_bytes + index_bytes > budget_bytes) pixels = 0;
    kept_bytes += pixels * sizeof(std::unique_ptr<double[]>);
    k.pixel.resize(pixels);
}

std::optional<Renderer::Impl::PixelDraws>
Renderer::Impl::pixel_draws(SampleClass sample_class, int x, int y, std::uint64_t seed, int count,
                            int rays, std::size_t budget_bytes,
                            std::vector<double>& scratch) const {
    KeptSamples& k = kept[sample_class]; // keep_for: for this seed, count and rays
    const std::size_t index = pixel_index(x, y);
    const bool keep = budget_bytes > 0 && !k.pixel.empty(); // the store, within the budget
    if (keep && k.pixel[index]) return PixelDraws{k.pixel[index].get(), count};
    if (!(camera.field_coverage(x, y) > 0.0)) return std::nullopt;
    const auto [nx, ny] = detail::strata_grid(count);
    detail::PixelRng rng(seed, index);
    const detail::PixelSeeds seeds =
        sample_class == kLedClass ? detail::PixelSeeds(seed, index) : pixel_seeds(seed, x, y);
    const std::size_t size = PixelDraws::size(count, rays);
    scratch.resize(size);
    for (int s = 0; s < count; ++s) {
        const auto d = fast_draw(x, y, s, nx, ny, rng, seeds);
        const Vec3 w = d ? d->first : Vec3::Zero();
        for (int a = 0; a < 3; ++a)
            scratch[std::size_t(3 * s + a)] = w[a];
        scratch[std::size_t(3 * count + s)] = d ? double(d->second) : PixelDraws::kOutside;
    }
    for (int r = 0; r < rays; ++r) {
        const std::array<double, 3> u = detail::shadow_uniforms(r, rays, seeds);
        for (int a = 0; a < 3; ++a)
            scratch[std::size_t(4 * count + 3 * r + a)] = u[std::size_t(a)];
    }
    if (keep) {
        const std::size_t bytes = size * sizeof(double);
        if (kept_bytes.fetch_add(bytes) + bytes <= budget_bytes) {
            k.pixel[index] = std::make_unique_for_overwrite<double[]>(size);
            std::copy(scratch.begin(), scratch.end(), k.pixel[index].get());
            return PixelDraws{k.pixel[index].get(), count};
        }
        kept_bytes -= bytes; // over the budget: drawn anew each render
    }
    return PixelDraws{scratch.data(), count};
}

void Renderer::Impl::sample_pixels_fast(int x, int y, int pixels, int nx, int ny,
                                        const RenderSettings& settings, double scale,
                                        const PixelSums& out, SampleClass sample_class,
                                        std::size_t budget_bytes) const {
    if (hero_sets.empty())
        batches<detail::kRgbLanes>(x, y, pixels, nx, ny, settings, scale, out, sample_class,
                                   budget_bytes);
    else if (fast_wavelengths_of(settings) == detail::kFastSpectralLanes)
        batches<detail::kFastSpectralLanes>(x, y, pixels, nx, ny, settings, scale, out,
                                            sample_class, budget_bytes);
    else
        batches<detail::kSpectralLanes>(x, y, pixels, nx, ny, settings, scale, out, sample_class,
                                        budget_bytes);
    if (!out.led.empty()) reflected_leds(x, y, pixels, settings, out.led, budget_bytes);
}

void Renderer::Impl::leds_out_of_reach(int x, int y, int pixels,
                                       std::span<std::uint8_t> out) const {
    grid_directions();
    const double inf = std::numeric_limits<double>::infinity();
    const bool cavity = scene.in_cavity(camera.origin_mm());
    std::array<Vec3, 16> origins, directions;
    origins.fill(camera.origin_mm());
    std::array<detail::RayHit, 16> hits;
    // 4 pixels' corners a packet.
    for (int j0 = 0; j0 < pixels; j0 += 4) {
        const int n = std::min(4, pixels - j0);
        std::array<bool, 4> valid{};
        for (int j = 0; j < n; ++j) {
            valid[std::size_t(j)] = true;
            for (int c = 0; c < 4; ++c) {
                const auto d = grid_direction(x + j0 + j + (c & 1), y + (c >> 1), false);
                valid[std::size_t(j)] = valid[std::size_t(j)] && d.has_value();
                directions[std::size_t(4 * j + c)] = d ? *d : Vec3::UnitZ();
            }
        }
        const std::size_t m = std::size_t(4 * n);
        const auto o = std::span(origins.data(), m), d = std::span(directions.data(), m);
        if (cavity)
            scene.closest_interface_hits16(o, d, 0.0, inf, std::span(hits.data(), m));
        else
            scene.closest_hits16(o, d, 0.0, inf, std::span(hits.data(), m));
        for (int j = 0; j < n; ++j) {
            std::array<Vec3, 4> q;
            bool proof = valid[std::size_t(j)];
            for (int c = 0; c < 4 && proof; ++c) {
                const std::size_t i = std::size_t(4 * j + c);
                const detail::RayHit& hit = hits[i];
                if (!hit.hit() || hit.kind != detail::SurfaceKind::inner_surface) {
                    proof = false;
                    break;
                }
                const Vec3& dir = directions[i];
                const Vec3 normal = detail::facing(hit.shading_normal, dir);
                const Vec3 reflected = (dir - 2.0 * dir.dot(normal) * normal).normalized();
                const auto crossing =
                    path.led_plane_crossing(camera.origin_mm() + hit.t_mm * dir, reflected);
                if (!crossing || !crossing->allFinite())
                    proof = false;
                else
                    q[std::size_t(c)] = *crossing;
            }
            if (proof) {
                double spread = 0.0;
                for (int a = 0; a < 4; ++a)
                    for (int b = a + 1; b < 4; ++b)
                        spread = std::max(spread, (q[std::size_t(a)] - q[std::size_t(b)]).norm());
                // Round the quad: corners 0 (x, y), 1 (x + 1, y), 3, 2.
                proof = !path.quad_near_led({q[0], q[1], q[3], q[2]},
                                            kReflectionMargin_mm + kLedCullSpread * spread);
            }
            out[std::size_t(j0 + j)] = proof;
        }
    }
}

void Renderer::Impl::reflected_leds(int x, int y, int pixels, const RenderSettings& settings,
                                    std::span<LedSums> out, std::size_t budget_bytes) const {
    const int count = settings.reflected_led_samples_per_pixel;
    std::array<std::uint8_t, kMaxBatchPixels> skip{};
    leds_out_of_reach(x, y, pixels, std::span(skip.data(), std::size_t(pixels)));
    std::array<Vec3, 16> directions;
    std::array<int, 16> owner;
    std::array<double, 16> fresnel;
    std::size_t m = 0;
    const auto flush = [&] {
        fast.reflected_leds16(scene, camera.origin_mm(), std::span(directions.data(), m),
                              std::span(fresnel.data(), m));
        for (std::size_t i = 0; i < m; ++i) {
            LedSums& sums = out[std::size_t(owner[i])];
            sums.sum += fresnel[i];
            sums.sum2 += fresnel[i] * fresnel[i];
        }
        m = 0;
    };
    thread_local std::vector<double> scratch;
    for (int j = 0; j < pixels; ++j) {
        LedSums& sums = out[std::size_t(j)];
        sums = {};
        if (skip[std::size_t(j)]) continue;
        const auto draws = pixel_draws(kLedClass, x + j, y, settings.seed ^ kReflectedLedSeed,
                                       count, 0, budget_bytes, scratch);
        if (!draws) continue;
        for (int k = 0; k < count; ++k) {
            if (draws->hero(k) == PixelDraws::kOutside) continue;
            ++sums.inside;
            directions[m] = draws->direction(k);
            owner[m++] = j;
            if (m == directions.size()) flush();
        }
    }
    if (m > 0) flush();
}

template <int N>
void Renderer::Impl::batches(int x, int y, int pixels, int nx, int ny,
                             const RenderSettings& settings, double scale, const PixelSums& out,
                             SampleClass sample_class, std::size_t budget_bytes) const {
    const int count = nx * ny;
    const bool split = !out.direct.empty();
    const int rays = shadow_rays(settings, count);
    const auto groups = std::size_t(split ? fast.shadow_groups() : 0);
    const detail::LaneOptics<N> rgb = [&] {
        if constexpr (N == detail::kRgbLanes)
            return shading.rgb_lanes();
        else
            return detail::LaneOptics<N>{};
    }();
    // Each pixel's camera samples (kept, or drawn now into a scratch of its own), and its
    // shading's stream (kShadeSeed: apart from the draws', so that kept samples are the
    // ones drawn anew).
    thread_local std::array<std::vector<double>, kMaxBatchPixels> scratch;
    std::array<std::optional<PixelDraws>, kMaxBatchPixels> draws;
    std::array<std::optional<detail::PixelRng>, kMaxBatchPixels> shade_rngs;
    for (int j = 0; j < pixels; ++j) {
        draws[std::size_t(j)] = pixel_draws(sample_class, x + j, y, settings.seed, count, rays,
                                            budget_bytes, scratch[std::size_t(j)]);
        shade_rngs[std::size_t(j)].emplace(settings.seed ^ kShadeSeed, pixel_index(x + j, y));
        out.sums[std::size_t(j)] = detail::Rgb::Zero();
        out.inside[std::size_t(j)] = 0;
        if (!out.sum2.empty()) out.sum2[std::size_t(j)] = detail::Rgb::Zero();
        for (std::size_t g = 0; g < groups; ++g) {
            DirectSums& d = out.direct[std::size_t(j)];
            d.lit[g] = d.chosen[g] = d.shadowed[g] = detail::Rgb::Zero();
        }
    }
    std::array<Vec3, 16> directions;
    std::array<const detail::LaneOptics<N>*, 16> lanes;
    std::array<const detail::CacheLambdas<N>*, 16> lambda;
    std::array<const HeroSetN<N>*, 16> sets;
    std::array<detail::ShadowDraw, 16> shadow;
    std::array<detail::PixelRng*, 16> streams;
    std::array<int, 16> owner; // the sample's pixel, 0 .. pixels - 1
    std::array<detail::LanesN<N>, 16> radiance;
    std::array<detail::DirectLight<N>, 16> direct;
    // Packets of equal size: 20 samples as 10 + 10, not 16 + 4 (a part-empty packet
    // wastes Embree's lanes).
    const int total = pixels * count;
    const int packets = (total + 15) / 16, size = (total + packets - 1) / packets;
    for (int first = 0; first < total; first += size) {
        std::size_t m = 0;
        for (int s = first; s < std::min(total, first + size); ++s) {
            const int j = s / count, k = s % count;
            // The sample's shadow rays: the pixel's `rays` spread evenly over its samples
            // (at least one each), their uniforms stratified over the pixel's rays.
            const int r0 = k * rays / count, r1 = (k + 1) * rays / count;
            const std::optional<PixelDraws>& d = draws[std::size_t(j)];
            if (!d || d->hero(k) == PixelDraws::kOutside) continue;
            const int hero = int(d->hero(k));
            ++out.inside[std::size_t(j)];
            directions[m] = d->direction(k);
            const std::array<double, 3> u = d->uniforms(r0);
            shadow[m] = {.u_led = u[0], .u1 = u[1], .u2 = u[2], .rays = r1 - r0};
            for (int r = r0 + 1; r < r1; ++r)
                shadow[m].further[std::size_t(r - r0 - 1)] = d->uniforms(r);
            streams[m] = &*shade_rngs[std::size_t(j)];
            owner[m] = j;
            if constexpr (N != detail::kRgbLanes) {
                // Set hero / N: the lanes of set i sit at (i + 1/2) / kHeroSets + l / N
                // in the sampling CDF, so sets i and i + kHeroSets / N hold the same
                // wavelengths, and a draw's stratum over [0, 1) is no stratum of them.
                // Scaled into [0, 1 / N), sample k's lanes lie in stratum k of each of
                // the N intervals: a pixel's count x N wavelengths are stratified.
                const HeroSetN<N>& h = hero_table<N>()[std::size_t(hero / N)];
                sets[m] = &h, lanes[m] = &h.lanes, lambda[m] = &h.cache_lambdas;
            } else {
                lanes[m] = &rgb, lambda[m] = nullptr;
            }
            ++m;
        }
        fast.radiance16<N>(
            scene, camera.origin_mm(), std::span(directions.data(), m),
            std::span<const detail::LaneOptics<N>* const>(lanes.data(), m),
            std::span<const detail::CacheLambdas<N>* const>(lambda.data(), m),
            std::span<const detail::ShadowDraw>(shadow.data(), m),
            std::span<detail::PixelRng* const>(streams.data(), m), std::span(radiance.data(), m),
            split ? std::span(direct.data(), m) : std::span<detail::DirectLight<N>>{},
            out.led.empty());
        for (std::size_t i = 0; i < m; ++i) {
            const auto rgb_of = [&](const detail::LanesN<N>& lanes_value) {
                if constexpr (N != detail::kRgbLanes)
                    return detail::Rgb(sets[i]->to_rgb * lanes_value.matrix());
                else
                    return detail::Rgb(lanes_value.template head<3>());
            };
            const detail::Rgb value = rgb_of(radiance[i]);
            const auto j = std::size_t(owner[i]);
            out.sums[j] += value;
            if (!out.sum2.empty()) out.sum2[j] += (value * scale).square();
            if (split) {
                DirectSums& d = out.direct[j];
                for (int q = 0; q < direct[i].parts; ++q) {
                    const detail::DirectPart<N>& part = direct[i].part[std::size_t(q)];
                    const detail::Rgb lit = rgb_of(part.lit);
                    for (std::size_t g = 0; g < groups; ++g)
                        d.lit[g] += part.share[g] * lit;
                    const auto g = std::size_t(part.group);
                    d.chosen[g] += lit;
                    d.shadowed[g] += part.clear ? lit : rgb_of(part.shadowed);
                }
            }
        }
    }
}

template <Integrator I>
detail::Rgb Renderer::Impl::sample_rgb(const detail::EmbreeScene& in, const Vec3& origin,
                                       const Vec3& direction, double u_lambda,
                                       detail::PixelRng& rng) const {
    static_assert(I != Integrator::fast, "the fast integrator samples in packets");
    constexpr bool path_traced = I == Integrator::path;
    if (hero_sets.empty()) { // RGB mode
        const auto lanes = shading.rgb_lanes();
        return path_traced ? detail::Rgb(path.radiance(in, origin, direction, lanes, rng).head<3>())
                           : shading.radiance(in, origin, direction);
    }
    const HeroSet& h =
        hero_sets[std::size_t(std::clamp(int(u_lambda * kHeroSets), 0, kHeroSets - 1))];
    const detail::Lanes radiance = path_traced ? path.radiance(in, origin, direction, h.lanes, rng)
                                               : shading.radiance(in, origin, direction, h.lanes);
    return detail::Rgb(h.to_rgb * radiance.matrix());
}

template detail::Rgb Renderer::Impl::sample_pixel<Integrator::preview>(int, int, int, int,
                                                                       const RenderSettings&,
                                                                       double, detail::Rgb*,
                                                                       int&) const;
template detail::Rgb Renderer::Impl::sample_pixel<Integrator::path>(int, int, int, int,
                                                                    const RenderSettings&, double,
                                                                    detail::Rgb*, int&) const;
template detail::Rgb Renderer::Impl::sample_rgb<Integrator::path>(const detail::EmbreeScene&,
                                                                  const Vec3&, const Vec3&, double,
                                                                  detail::PixelRng&) const;

} // namespace chromasim::render
