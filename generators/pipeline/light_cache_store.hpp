#pragma once
/// The fast integrator's light cache on disk: it depends only on the sensor at rest, its
/// optics and the cache settings, so a run (or a shard, or the next dataset of the same
/// sensor) reads it back instead of path-tracing it again (about 6 s on the coarse mesh).
///
/// One file per key in the mechanics cache's folder (`--cache-dir`), `light-<key>.bin`, a
/// checked cache file (generators/io/cache_file.hpp: a torn, corrupt or foreign file is
/// reported and rebuilt, never used). The key hashes everything the build reads: the chromasim version
/// and this layout, the settings, every optics value but the exposure (the spectra's values
/// included) and the rest frame's buffers (coating, inner surface, both marker meshes). The
/// build is deterministic, so a file and a fresh build give the same image bytes.
#include "render/renderer.hpp"

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

namespace chromasim::generators {

/// The key of the light cache of `rest` with these optics and settings.
std::uint64_t light_cache_key(const render::SensorFrame& rest, const render::OpticsParams& optics,
                              const render::LightCacheSettings& settings);

/// The file a key maps to inside `dir`.
std::filesystem::path light_cache_file(const std::filesystem::path& dir, std::uint64_t key);

/// Reads the entry for `key`; nullopt if absent, or (with `problem` saying why) unreadable,
/// for another key, corrupt or truncated.
std::optional<render::LightCache> load_light_cache(const std::filesystem::path& dir,
                                                   std::uint64_t key,
                                                   std::string* problem = nullptr);

/// Writes the entry atomically; false (with `problem`) if it cannot.
bool save_light_cache(const std::filesystem::path& dir, std::uint64_t key,
                      const render::LightCache& cache, std::string* problem = nullptr);

struct LightCacheOutcome {
    double seconds = 0.0;   ///< wall time of the build or the read
    bool from_file = false; ///< read from the folder
    std::string note;       ///< why a file was refused or could not be written
};

/// Gives `renderer` the light cache of `rest`: read from `dir` when a file of its key is
/// there and the renderer accepts it, else built (Renderer::set_light_cache) and, with a
/// `dir`, saved there.
LightCacheOutcome provide_light_cache(render::Renderer& renderer, const render::SensorFrame& rest,
                                      const render::OpticsParams& optics,
                                      const render::LightCacheSettings& settings,
                                      const std::filesystem::path& dir);

} // namespace chromasim::generators
