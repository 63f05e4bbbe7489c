#pragma once
/// On-disk cache of precomputed mechanics (mesh and responses), keyed by a hash of everything
/// they depend on. A file is written to a temporary name and renamed, and carries a checksum:
/// a torn or corrupt file is detected, reported and recomputed, never used.
#include "mechanics/elastic_body.hpp"
#include "mechanics/tet_mesh.hpp"

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

namespace chromasim::mechanics {

/// 64-bit FNV-1a of a byte string (stable across platforms and runs).
std::uint64_t fnv1a64(std::string_view bytes, std::uint64_t seed = 0xcbf29ce484222325ull);

/// One cache file: 8 magic bytes, the key, an FNV-1a checksum of the payload, the payload.
/// Reads the payload at `path`: nullopt if absent, or (with `problem` naming the file and
/// why) not of this magic, for another key, or torn or corrupt.
std::optional<std::string> read_cache_file(const std::filesystem::path& path,
                                           std::string_view magic, std::uint64_t key,
                                           std::string* problem = nullptr);
/// Writes one to a temporary name and renames it into place. Returns false (with `problem`)
/// if the folder cannot be written: a cache is an optimisation, never a reason to fail.
bool write_cache_file(const std::filesystem::path& path, std::string_view magic, std::uint64_t key,
                      std::string_view payload, std::string* problem = nullptr);

struct CachedModel {
    TetMesh mesh;
    ElasticBodyResponses responses;
};

/// The file a key maps to inside `dir`.
std::filesystem::path cache_file(const std::filesystem::path& dir, std::uint64_t key);

/// Reads the entry for `key`; nullopt if absent, unreadable, for another key, or corrupt
/// (then `problem` says why).
std::optional<CachedModel> load_cached_model(const std::filesystem::path& dir, std::uint64_t key,
                                             std::string* problem = nullptr);

/// Writes the entry atomically (temporary file, then rename). Returns false (with `problem`)
/// if the folder cannot be written; the cache is an optimisation, never a reason to fail.
bool save_cached_model(const std::filesystem::path& dir, std::uint64_t key, const TetMesh& mesh,
                       const ElasticBodyResponses& responses, std::string* problem = nullptr);

} // namespace chromasim::mechanics
