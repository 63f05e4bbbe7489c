#pragma once
/// Cache files that are complete and for the right key, or refused: 8 magic bytes, a 64-bit
/// key, the SHA-256 of the payload, the payload. Written to a per-process temporary name and
/// renamed, so shards that share a folder never see each other's half-written file.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

namespace chromasim::generators {

/// Builds a 64-bit cache key from typed fields: each is hashed with its size, then its bytes.
class CacheKey {
public:
    void bytes(const void* data, std::size_t size);
    template <class T> void value(const T& v) { bytes(&v, sizeof v); }
    /// The first 64 bits of the SHA-256 of everything added.
    std::uint64_t key() const;

private:
    std::string m_bytes;
};

/// The payload of the cache file at `path`: nullopt if absent, or (with `problem` naming the
/// file and why) not of this magic, for another key, or torn or corrupt.
std::optional<std::string> read_cache_file(const std::filesystem::path& path,
                                           std::string_view magic, std::uint64_t key,
                                           std::string* problem = nullptr);

/// Writes one atomically. Returns false (with `problem`) if the folder cannot be written: a
/// cache is an optimisation, never a reason to fail.
bool write_cache_file(const std::filesystem::path& path, std::string_view magic, std::uint64_t key,
                      std::string_view payload, std::string* problem = nullptr);

} // namespace chromasim::generators
