#include "render/light_cache_file.hpp"

#include "render/spectrum.hpp"

#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <unistd.h>

namespace fs = std::filesystem;

namespace chromasim::render::detail {

namespace {

constexpr char kMagic[8] = {'C', 'S', 'L', 'C', 'A', 'C', 'H', '1'};
/// Bump when the cache's algorithm or layout changes without a chromasim version change.
constexpr int kFormat = 1;

/// 64-bit FNV-1a, stable across platforms and runs (the same hash as the mechanics cache's;
/// render does not depend on mechanics).
std::uint64_t fnv1a64(const void* data, std::size_t size, std::uint64_t h) {
    const auto* bytes = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < size; ++i) {
        h ^= bytes[i];
        h *= 0x100000001b3ull;
    }
    return h;
}

/// Builds the key from typed fields: each is hashed with its size and raw bytes.
struct KeyHash {
    std::uint64_t h = 0xcbf29ce484222325ull;
    void bytes(const void* data, std::size_t size) {
        const std::uint64_t n = size;
        h = fnv1a64(&n, sizeof n, h);
        h = fnv1a64(data, size, h);
    }
    template <class T> void value(const T& v) { bytes(&v, sizeof v); }
    void vec(const Vec3& v) { bytes(v.data(), 3 * sizeof(double)); }
    template <class M> void matrix(const M& m) {
        value(std::int64_t(m.rows()));
        value(std::int64_t(m.cols()));
        bytes(m.data(), sizeof(*m.data()) * std::size_t(m.size()));
    }
    void mesh(const SurfaceMesh& m) {
        matrix(m.V);
        matrix(m.F);
    }
    void spectrum(const Spectrum& s) { bytes(s.values.data(), sizeof s.values); }
};

template <class T> void put(std::string& out, const std::vector<T>& v) {
    const std::uint64_t n = v.size();
    out.append(reinterpret_cast<const char*>(&n), sizeof n);
    out.append(reinterpret_cast<const char*>(v.data()), sizeof(T) * v.size());
}

template <class T> bool get(std::string_view& in, std::vector<T>& v) {
    std::uint64_t n = 0;
    if (in.size() < sizeof n) return false;
    std::memcpy(&n, in.data(), sizeof n);
    in.remove_prefix(sizeof n);
    if (n > in.size() / sizeof(T)) return false;
    v.resize(n);
    std::memcpy(v.data(), in.data(), sizeof(T) * n);
    in.remove_prefix(sizeof(T) * n);
    return true;
}

template <class T> void put_value(std::string& out, const T& v) {
    out.append(reinterpret_cast<const char*>(&v), sizeof v);
}

template <class T> bool get_value(std::string_view& in, T& v) {
    if (in.size() < sizeof v) return false;
    std::memcpy(&v, in.data(), sizeof v);
    in.remove_prefix(sizeof v);
    return true;
}

} // namespace

std::uint64_t light_cache_key(const SensorFrame& rest, const OpticsParams& o,
                              const LightCacheSettings& settings, double led_scale) {
    KeyHash k;
    const std::string header = "chromasim " CHROMASIM_VERSION " light-cache";
    k.bytes(header.data(), header.size());
    k.value(kFormat);
    k.value(settings.paths_per_vertex);
    k.value(settings.direct_samples);
    k.value(settings.smoothing_mm);
    k.value(led_scale);
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
    k.value(o.refractive_index);
    k.vec(o.led_rgb);
    k.value(o.spectra.has_value());
    if (o.spectra) {
        for (const Spectrum& s : o.spectra->camera.sensitivity())
            k.spectrum(s);
        k.spectrum(o.spectra->camera.led_emission());
        k.spectrum(o.spectra->inner_marker_absorption_per_mm);
        k.spectrum(o.spectra->outer_marker_absorption_per_mm);
        k.spectrum(o.spectra->outer_marker_albedo);
        k.spectrum(o.spectra->coating_albedo);
    }
    for (const SurfaceMesh* m :
         {&rest.coating, &rest.inner_surface, &rest.inner_markers, &rest.outer_markers})
        k.mesh(*m);
    k.value(rest.triangles_per_marker);
    return k.h;
}

fs::path light_cache_file(const fs::path& dir, std::uint64_t key) {
    char name[48];
    std::snprintf(name, sizeof name, "light-%016llx.bin", static_cast<unsigned long long>(key));
    return dir / name;
}

std::optional<LightCache> load_light_cache(const fs::path& dir, std::uint64_t key,
                                           std::string* problem) {
    const fs::path path = light_cache_file(dir, key);
    std::ifstream file(path, std::ios::binary);
    if (!file) return std::nullopt;
    std::ostringstream buffer;
    buffer << file.rdbuf();
    const std::string bytes = buffer.str();
    auto fail = [&](const char* why) -> std::optional<LightCache> {
        if (problem) *problem = path.string() + ": " + why;
        return std::nullopt;
    };
    constexpr std::size_t kHeader = sizeof kMagic + 2 * sizeof(std::uint64_t);
    if (bytes.size() < kHeader || std::memcmp(bytes.data(), kMagic, sizeof kMagic) != 0)
        return fail("not a chromasim light-cache file");
    std::uint64_t stored_key = 0, checksum = 0;
    std::memcpy(&stored_key, bytes.data() + sizeof kMagic, sizeof stored_key);
    std::memcpy(&checksum, bytes.data() + sizeof kMagic + 8, sizeof checksum);
    std::string_view payload(bytes.data() + kHeader, bytes.size() - kHeader);
    if (stored_key != key) return fail("written for another key");
    if (fnv1a64(payload.data(), payload.size(), 0xcbf29ce484222325ull) != checksum)
        return fail("checksum mismatch (torn or corrupt file)");
    LightCache c;
    if (!get_value(payload, c.vertices) || !get_value(payload, c.leds) ||
        !get_value(payload, c.lanes) || !get_value(payload, c.build_s) || !get(payload, c.direct) ||
        !get(payload, c.indirect) || !get(payload, c.indirect_above) ||
        !get(payload, c.point_rest) || !get(payload, c.coating_triangles) || !payload.empty())
        return fail("truncated payload");
    const auto nv = std::size_t(c.vertices), leds = std::size_t(c.leds),
               lanes = std::size_t(c.lanes);
    if (c.vertices < 0 || c.leds < 0 || c.lanes < 0 || c.direct.size() != nv * leds * 3 ||
        c.point_rest.size() != c.direct.size() || c.indirect.size() != nv * lanes ||
        c.indirect_above.size() != c.indirect.size() || c.coating_triangles.size() % 3 != 0)
        return fail("inconsistent sizes");
    return c;
}

bool save_light_cache(const fs::path& dir, std::uint64_t key, const LightCache& c,
                      std::string* problem) {
    std::string payload;
    put_value(payload, c.vertices);
    put_value(payload, c.leds);
    put_value(payload, c.lanes);
    put_value(payload, c.build_s);
    put(payload, c.direct);
    put(payload, c.indirect);
    put(payload, c.indirect_above);
    put(payload, c.point_rest);
    put(payload, c.coating_triangles);
    const std::uint64_t checksum = fnv1a64(payload.data(), payload.size(), 0xcbf29ce484222325ull);
    std::error_code ec;
    fs::create_directories(dir, ec);
    const fs::path path = light_cache_file(dir, key);
    const fs::path tmp = path.string() + ".tmp-" + std::to_string(::getpid());
    {
        std::ofstream out(tmp, std::ios::binary);
        out.write(kMagic, sizeof kMagic);
        out.write(reinterpret_cast<const char*>(&key), sizeof key);
        out.write(reinterpret_cast<const char*>(&checksum), sizeof checksum);
        out.write(payload.data(), std::streamsize(payload.size()));
        if (!out) {
            if (problem) *problem = "cannot write " + tmp.string();
            fs::remove(tmp, ec);
            return false;
        }
    }
    fs::rename(tmp, path, ec);
    if (ec) {
        if (problem) *problem = "cannot rename " + tmp.string() + ": " + ec.message();
        fs::remove(tmp, ec);
        return false;
    }
    return true;
}

} // namespace chromasim::render::detail
