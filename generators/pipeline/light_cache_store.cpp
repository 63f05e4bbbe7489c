#include "generators/pipeline/light_cache_store.hpp"

#include "generators/io/cache_file.hpp"
#include "generators/io/stopwatch.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <string_view>

namespace fs = std::filesystem;

namespace chromasim::generators {

namespace {

constexpr std::string_view kMagic = "CSLCACH1";
/// Bump when the cache's algorithm or layout changes without a chromasim version change.
constexpr int kLayout = 5;

/// The key's typed fields on top of CacheKey.
struct KeyHash : CacheKey {
    void vec(const render::Vec3& v) { bytes(v.data(), 3 * sizeof(double)); }
    template <class M> void matrix(const M& m) {
        value(std::int64_t(m.rows()));
        value(std::int64_t(m.cols()));
        bytes(m.data(), sizeof(*m.data()) * std::size_t(m.size()));
    }
    void mesh(const render::SurfaceMesh& m) {
        matrix(m.V);
        matrix(m.F);
    }
    void spectrum(const render::Spectrum& s) { bytes(s.values.data(), sizeof s.values); }
};

template <class T> void put(std::string& out, const T& v) {
    out.append(reinterpret_cast<const char*>(&v), sizeof v);
}
template <class T> void put(std::string& out, const std::vector<T>& v) {
    put(out, std::uint64_t(v.size()));
    out.append(reinterpret_cast<const char*>(v.data()), sizeof(T) * v.size());
}
template <class T> bool get(std::string_view& in, T& v) {
    if (in.size() < sizeof v) return false;
    std::memcpy(&v, in.data(), sizeof v);
    in.remove_prefix(sizeof v);
    return true;
}
template <class T> bool get(std::string_view& in, std::vector<T>& v) {
    std::uint64_t n = 0;
    if (!get(in, n) || n > in.size() / sizeof(T)) return false;
    v.resize(n);
    std::memcpy(v.data(), in.data(), sizeof(T) * n);
    in.remove_prefix(sizeof(T) * n);
    return true;
}

} // namespace

std::uint64_t light_cache_key(const render::SensorFrame& rest, const render::OpticsParams& o,
                              const render::LightCacheSettings& settings) {
    KeyHash k;
    const std::string_view header = "chromasim " CHROMASIM_BUILD " light-cache";
    k.bytes(header.data(), header.size());
    k.value(kLayout);
    k.value(settings.paths_per_vertex);
    k.value(settings.direct_samples);
    k.value(settings.smoothing_mm);
    // Every optics value but the exposure (which scales images, not the cache).
    k.vec(o.coating_albedo);
    k.vec(o.inner_marker_absorption_per_mm);
    k.vec(o.outer_marker_absorption_per_mm);
    k.vec(o.outer_marker_albedo);
    k.value(o.outer_marker_scatter_fraction);
    k.value(o.led_count);
    k.value(o.led_ring_radius_mm);
    k.value(o.led_z_mm);
    k.value(o.led_width_mm);
    k.value(o.led_height_mm);
    k.value(o.frame_inner_radius_mm);
    k.value(o.lens_radius_mm);
    k.value(o.refractive_index);
    k.vec(o.led_rgb);
    // Gains all 1 key as no gains, so a spec that names them keeps its caches.
    if (std::any_of(o.led_gain.begin(), o.led_gain.end(), [](double g) { return g != 1.0; }))
        for (const double g : o.led_gain)
            k.value(g);
    k.value(o.spectra.has_value());
    if (o.spectra) {
        for (const render::Spectrum& s : o.spectra->camera.sensitivity())
            k.spectrum(s);
        k.spectrum(o.spectra->camera.led_emission());
        k.spectrum(o.spectra->inner_marker_absorption_per_mm);
        k.spectrum(o.spectra->outer_marker_absorption_per_mm);
        k.spectrum(o.spectra->outer_marker_albedo);
        k.spectrum(o.spectra->coating_albedo);
    }
    for (const render::SurfaceMesh* m :
         {&rest.coating, &rest.inner_surface, &rest.inner_markers, &rest.outer_markers})
        k.mesh(*m);
    k.value(rest.triangles_per_marker);
    return k.key();
}

fs::path light_cache_file(const fs::path& dir, std::uint64_t key) {
    char name[48];
    std::snprintf(name, sizeof name, "light-%016llx.bin", static_cast<unsigned long long>(key));
    return dir / name;
}

std::optional<render::LightCache> load_light_cache(const fs::path& dir, std::uint64_t key,
                                                   std::string* problem) {
    const fs::path path = light_cache_file(dir, key);
    const std::optional<std::string> bytes = read_cache_file(path, kMagic, key, problem);
    if (!bytes) return std::nullopt;
    std::string_view in(*bytes);
    render::LightCache c;
    // Only the layout here; whether the arrays fit this renderer is Renderer::set_light_cache's
    // check (provide_light_cache rebuilds when it refuses).
    if (!(get(in, c.vertices) && get(in, c.leds) && get(in, c.lanes) && get(in, c.build_s) &&
          get(in, c.direct) && get(in, c.indirect) && get(in, c.indirect_above) &&
          get(in, c.point_rest) && get(in, c.direct_edge) &&
          get(in, c.coating_triangles) && in.empty())) {
        if (problem) *problem = path.string() + ": truncated payload";
        return std::nullopt;
    }
    return c;
}

bool save_light_cache(const fs::path& dir, std::uint64_t key, const render::LightCache& c,
                      std::string* problem) {
    std::string payload;
    put(payload, c.vertices);
    put(payload, c.leds);
    put(payload, c.lanes);
    put(payload, c.build_s);
    put(payload, c.direct);
    put(payload, c.indirect);
    put(payload, c.indirect_above);
    put(payload, c.point_rest);
    put(payload, c.direct_edge);
    put(payload, c.coating_triangles);
    return write_cache_file(light_cache_file(dir, key), kMagic, key, payload, problem);
}

LightCacheOutcome provide_light_cache(render::Renderer& renderer, const render::SensorFrame& rest,
                                      const render::OpticsParams& optics,
                                      const render::LightCacheSettings& settings,
                                      const fs::path& dir) {
    const auto t0 = std::chrono::steady_clock::now();
    LightCacheOutcome out;
    const std::uint64_t key = dir.empty() ? 0 : light_cache_key(rest, optics, settings);
    std::optional<render::LightCache> stored;
    if (!dir.empty()) stored = load_light_cache(dir, key, &out.note);
    if (stored) {
        try { // the key covers the sensor, so a refusal means a damaged file
            renderer.set_light_cache(std::move(*stored), settings, rest);
            out.from_file = true;
        } catch (const std::invalid_argument& e) {
            out.note = light_cache_file(dir, key).string() + ": " + e.what();
        }
    }
    if (!out.from_file) {
        renderer.set_light_cache(rest, settings);
        std::string problem;
        if (!dir.empty() && !save_light_cache(dir, key, *renderer.light_cache(), &problem))
            out.note += (out.note.empty() ? "" : "; ") + problem;
    }
    out.seconds = seconds_since(t0);
    return out;
}

} // namespace chromasim::generators
