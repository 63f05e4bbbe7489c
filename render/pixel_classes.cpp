// Which pixels take more samples (those that mirror an LED, those on a marker's rim), chosen
// from the frame's geometry before any sample, and the marker id channels.
#include "render/renderer_impl.hpp"

namespace chromasim::render {

const Renderer::Impl::GridDirections& Renderer::Impl::grid_directions() const {
    std::call_once(grid_once, [this] {
        const int w = camera.width_px(), h = camera.height_px();
        const Vec3 none = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
        const auto fill = [&](std::vector<Vec3>& out, int nx, int ny, double offset) {
            out.resize(std::size_t(nx) * std::size_t(ny));
            for (int y = 0; y < ny; ++y)
                for (int x = 0; x < nx; ++x) {
                    const auto d = camera.direction(Eigen::Vector2d(x + offset, y + offset));
                    out[std::size_t(y) * std::size_t(nx) + std::size_t(x)] = d ? *d : none;
                }
        };
        fill(grid.corners, w + 1, h + 1, 0.0);
        fill(grid.centres, w, h, 0.5);
    });
    return grid;
}

std::vector<std::optional<Vec3>> Renderer::Impl::led_plane_crossings() const {
    const int w = camera.width_px(), h = camera.height_px();
    grid_directions();
    const auto at = [w](int x, int y) { return std::size_t(y) * std::size_t(w) + x; };
    const bool cavity = scene.in_cavity(camera.origin_mm());
    const double inf = std::numeric_limits<double>::infinity();
    std::vector<std::optional<Vec3>> crossing(std::size_t(w) * std::size_t(h));
    tbb::parallel_for(0, h, [&](int y) {
        std::array<Vec3, 16> origins, directions;
        std::array<detail::RayHit, 16> first;
        std::array<int, 16> xs;
        origins.fill(camera.origin_mm());
        for (int x0 = 0; x0 < w; x0 += 16) {
            std::size_t m = 0;
            for (int x = x0; x < std::min(w, x0 + 16); ++x)
                if (const auto d = grid_direction(x, y, true)) directions[m] = *d, xs[m++] = x;
            if (m == 0) continue;
            const auto o = std::span(origins.data(), m), d = std::span(directions.data(), m);
            if (cavity)
                scene.closest_interface_hits16(o, d, 0.0, inf, std::span(first.data(), m));
            else
                scene.closest_hits16(o, d, 0.0, inf, std::span(first.data(), m));
            for (std::size_t i = 0; i < m; ++i) {
                const detail::RayHit& hit = first[i];
                if (!hit.hit() || hit.kind != detail::SurfaceKind::inner_surface) continue;
                const Vec3& dir = directions[i];
                const Vec3 normal = detail::facing(hit.shading_normal, dir);
                const Vec3 reflected = (dir - 2.0 * dir.dot(normal) * normal).normalized();
                crossing[at(xs[i], y)] =
                    path.led_plane_crossing(camera.origin_mm() + hit.t_mm * dir, reflected);
            }
        }
    });
    return crossing;
}

std::vector<std::uint8_t>
Renderer::Impl::mirroring_pixels(const std::vector<std::optional<Vec3>>& crossing) const {
    const int w = camera.width_px(), h = camera.height_px();
    const auto at = [w](int x, int y) { return std::size_t(y) * std::size_t(w) + x; };
    std::vector<std::uint8_t> mirrored(crossing.size(), 0);
    tbb::parallel_for(0, h, [&](int y) {
        for (int x = 0; x < w; ++x) {
            const auto& q = crossing[at(x, y)];
            if (!q) continue;
            double reach = 0.0;
            for (const auto& [dx, dy] : {std::pair{1, 0}, {-1, 0}, {0, 1}, {0, -1}})
                if (x + dx >= 0 && x + dx < w && y + dy >= 0 && y + dy < h)
                    if (const auto& o = crossing[at(x + dx, y + dy)])
                        reach = std::max(reach, 0.5 * (*o - *q).norm());
            mirrored[at(x, y)] = path.near_led(*q, kReflectionMargin_mm + reach);
        }
    });
    return mirrored;
}

std::vector<std::uint8_t> Renderer::Impl::pixel_classes(bool mirrors, bool rims) const {
    const int w = camera.width_px(), h = camera.height_px();
    grid_directions();
    const std::size_t pixels = std::size_t(w) * std::size_t(h);
    const auto at = [w](int x, int y) { return std::size_t(y) * std::size_t(w) + x; };
    // The pixels that mirror an LED themselves (the centres' reflections onto the LEDs'
    // plane), then with their 8 neighbours.
    const std::vector<std::uint8_t> mirrored =
        mirrors ? mirroring_pixels(led_plane_crossings()) : std::vector<std::uint8_t>();
    // The markers at the pixels' corners, (w + 1) x (h + 1): corner (x, y) at image point
    // (x, y), the top left one of pixel (x, y).
    const std::size_t corners_per_row = std::size_t(w) + 1;
    std::vector<std::pair<std::int32_t, std::int32_t>> corner_ids(
        rims ? corners_per_row * (std::size_t(h) + 1) : 0);
    if (rims)
        tbb::parallel_for(0, h + 1, [&](int y) {
            marker_ids_row(y, std::span(corner_ids.data() + std::size_t(y) * corners_per_row,
                                        corners_per_row));
        });
    std::vector<std::uint8_t> out(pixels, 0);
    tbb::parallel_for(0, h, [&](int y) {
        for (int x = 0; x < w; ++x) {
            std::uint8_t& pixel_class = out[at(x, y)];
            if (mirrors)
                for (int dy = -1; dy <= 1 && pixel_class == 0; ++dy)
                    for (int dx = -1; dx <= 1; ++dx) {
                        const int qx = x + dx, qy = y + dy;
                        if (qx < 0 || qy < 0 || qx >= w || qy >= h) continue;
                        if (mirrored[at(qx, qy)]) pixel_class = 2;
                    }
            if (rims && pixel_class == 0) {
                const std::size_t c = std::size_t(y) * corners_per_row + std::size_t(x);
                const auto& ids = corner_ids[c];
                if (corner_ids[c + 1] != ids || corner_ids[c + corners_per_row] != ids ||
                    corner_ids[c + corners_per_row + 1] != ids)
                    pixel_class = 1;
            }
        }
    });
    return out;
}

void Renderer::Impl::marker_ids_row(int y,
                                    std::span<std::pair<std::int32_t, std::int32_t>> out) const {
    const int n = int(out.size());
    grid_directions();
    std::array<Vec3, 16> directions;
    std::array<std::pair<std::int32_t, std::int32_t>, 16> ids;
    std::array<int, 16> xs;
    for (int x0 = 0; x0 < n; x0 += 16) {
        std::size_t m = 0;
        for (int x = x0; x < std::min(n, x0 + 16); ++x) {
            out[std::size_t(x)] = {-1, -1};
            if (const auto d = grid_direction(x, y, false)) directions[m] = *d, xs[m++] = x;
        }
        if (m == 0) continue;
        fast.marker_ids16(scene, camera.origin_mm(), std::span(directions.data(), m),
                          triangles_per_marker, std::span(ids.data(), m));
        for (std::size_t i = 0; i < m; ++i)
            out[std::size_t(xs[i])] = ids[i];
    }
}

std::pair<std::int32_t, std::int32_t> Renderer::Impl::marker_ids(int x, int y,
                                                                 bool refracted) const {
    const Eigen::Vector2d at(x + 0.5, y + 0.5);
    if (!refracted || triangles_per_marker < 1) return marker_ids_at(at);
    const auto direction = camera.direction(at);
    if (!direction) return {-1, -1};
    std::pair<std::int32_t, std::int32_t> ids;
    fast.marker_ids16(scene, camera.origin_mm(), std::span(&*direction, 1), triangles_per_marker,
                      std::span(&ids, 1));
    return ids;
}

std::pair<std::int32_t, std::int32_t>
Renderer::Impl::marker_ids_at(const Eigen::Vector2d& at) const {
    std::int32_t ids[2] = {-1, -1};
    const auto direction = camera.direction(at);
    if (!direction || triangles_per_marker < 1) return {-1, -1};
    // The hits past the inner surface (left out of the query: the ray goes straight
    // through it), the markers before the coating from one traversal (RayHits).
    double tnear = 0.0;
    detail::RayHits hits(scene, camera.origin_mm(), *direction, tnear,
                         std::numeric_limits<double>::infinity(),
                         detail::kAllKinds & ~detail::kind_bit(detail::SurfaceKind::inner_surface));
    for (int i = 0; i < detail::kMaxHits; ++i) {
        const detail::RayHit hit = hits.next(tnear);
        if (!hit.hit() || hit.kind == detail::SurfaceKind::coating) break;
        tnear = hit.t_mm + detail::kHitGap_mm;
        std::int32_t& id = ids[hit.kind == detail::SurfaceKind::outer_marker ? 1 : 0];
        if (id < 0) id = std::int32_t(hit.prim_id / std::uint32_t(triangles_per_marker));
    }
    return {ids[0], ids[1]};
}

} // namespace chromasim::render
