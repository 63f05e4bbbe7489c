#pragma once
/// The fast integrator's light cache on disk: it depends only on the sensor at rest, its
/// optics and the cache settings, so a run (or a shard, or the next dataset of the same
/// sensor) reads it back instead of path-tracing it again (about 6 s on the coarse mesh).
///
/// The key hashes everything the build reads: the chromasim version and this file format,
/// the settings, every optics value (the spectra's values included) and the rest frame's
/// buffers (coating, inner surface, both marker meshes). A file is written to a temporary
/// name and renamed, and carries the key and a checksum of its payload: a torn, corrupt or
/// foreign file is reported and rebuilt, never used. The build is deterministic, so a file
/// and a fresh build hold the same floats.
#include "render/fast_integrator.hpp"

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

namespace chromasim::render::detail {

/// The key of the light cache of `rest` with these optics and settings (`led_scale`: the
/// spectral mode's relative LED intensity).
std::uint64_t light_cache_key(const SensorFrame& rest, const OpticsParams& optics,
                              const LightCacheSettings& settings, double led_scale);

/// The file a key maps to inside `dir`.
std::filesystem::path light_cache_file(const std::filesystem::path& dir, std::uint64_t key);

/// Reads the entry for `key`; nullopt if absent, or (with `problem` saying why) unreadable,
/// for another key, or corrupt.
std::optional<LightCache> load_light_cache(const std::filesystem::path& dir, std::uint64_t key,
                                           std::string* problem = nullptr);

/// Writes the entry atomically. Returns false (with `problem`) if it cannot: the cache is an
/// optimisation, never a reason to fail.
bool save_light_cache(const std::filesystem::path& dir, std::uint64_t key, const LightCache& cache,
                      std::string* problem = nullptr);

} // namespace chromasim::render::detail
