#include "mechanics/model_cache.hpp"

#include <cstdio>
#include <cstring>
#include <fstream>
#include <unistd.h>

namespace fs = std::filesystem;

namespace chromasim::mechanics {

namespace {

constexpr std::string_view kMagic = "CSMCACH2";

/// Appends a dense matrix (rows, cols, raw storage) to a byte buffer.
template <class M> void put(std::string& out, const M& m) {
    const std::int64_t dims[2] = {m.rows(), m.cols()};
    out.append(reinterpret_cast<const char*>(dims), sizeof dims);
    out.append(reinterpret_cast<const char*>(m.data()), sizeof(*m.data()) * std::size_t(m.size()));
}

/// Reads back what put() wrote; false if the buffer is too short.
template <class M> bool get(std::string_view& in, M& m) {
    std::int64_t dims[2];
    if (in.size() < sizeof dims) return false;
    std::memcpy(dims, in.data(), sizeof dims);
    in.remove_prefix(sizeof dims);
    if (dims[0] < 0 || dims[1] < 0) return false;
    const std::size_t bytes = sizeof(*m.data()) * std::size_t(dims[0] * dims[1]);
    if (in.size() < bytes) return false;
    m.resize(dims[0], dims[1]);
    std::memcpy(m.data(), in.data(), bytes);
    in.remove_prefix(bytes);
    return true;
}

} // namespace

std::uint64_t fnv1a64(std::string_view bytes, std::uint64_t h) {
    for (unsigned char c : bytes) {
        h ^= c;
        h *= 0x100000001b3ull;
    }
    return h;
}

fs::path cache_file(const fs::path& dir, std::uint64_t key) {
    char name[40];
    std::snprintf(name, sizeof name, "model-%016llx.bin", static_cast<unsigned long long>(key));
    return dir / name;
}

std::optional<std::string> read_cache_file(const fs::path& path, std::string_view magic,
                                           std::uint64_t key, std::string* problem) {
    std::ifstream file(path, std::ios::binary | std::ios::ate);
    if (!file) return std::nullopt;
    auto fail = [&](const char* why) -> std::optional<std::string> {
        if (problem) *problem = path.string() + ": " + why;
        return std::nullopt;
    };
    // The header, then the payload read straight into its own buffer (a fine mesh's file is
    // hundreds of MB: no second copy).
    const std::streamoff size = file.tellg();
    file.seekg(0);
    const std::size_t header = magic.size() + 2 * sizeof(std::uint64_t);
    std::string head(header, '\0');
    if (size < std::streamoff(header) || !file.read(head.data(), std::streamsize(header)) ||
        std::string_view(head).substr(0, magic.size()) != magic)
        return fail("not a chromasim cache file");
    std::uint64_t stored_key = 0, checksum = 0;
    std::memcpy(&stored_key, head.data() + magic.size(), sizeof stored_key);
    std::memcpy(&checksum, head.data() + magic.size() + 8, sizeof checksum);
    if (stored_key != key) return fail("written for another key");
    std::string payload(std::size_t(size) - header, '\0');
    if (!file.read(payload.data(), std::streamsize(payload.size())) || fnv1a64(payload) != checksum)
        return fail("checksum mismatch (torn or corrupt file)");
    return payload;
}

bool write_cache_file(const fs::path& path, std::string_view magic, std::uint64_t key,
                      std::string_view payload, std::string* problem) {
    const std::uint64_t checksum = fnv1a64(payload);
    std::error_code ec;
    fs::create_directories(path.parent_path(), ec);
    const fs::path tmp = path.string() + ".tmp-" + std::to_string(::getpid());
    {
        std::ofstream out(tmp, std::ios::binary);
        out.write(magic.data(), std::streamsize(magic.size()));
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

std::optional<CachedModel> load_cached_model(const fs::path& dir, std::uint64_t key,
                                             std::string* problem) {
    const fs::path path = cache_file(dir, key);
    std::optional<std::string> bytes = read_cache_file(path, kMagic, key, problem);
    if (!bytes) return std::nullopt;
    std::string_view payload(*bytes);
    CachedModel m;
    if (!get(payload, m.mesh.V) || !get(payload, m.mesh.T) || !get(payload, m.mesh.region) ||
        !get(payload, m.mesh.T10) || !get(payload, m.responses.compliance) ||
        !get(payload, m.responses.observed) || !payload.empty()) {
        if (problem) *problem = path.string() + ": truncated payload";
        return std::nullopt;
    }
    return m;
}

bool save_cached_model(const fs::path& dir, std::uint64_t key, const TetMesh& mesh,
                       const ElasticBodyResponses& responses, std::string* problem) {
    std::string payload;
    put(payload, mesh.V);
    put(payload, mesh.T);
    put(payload, mesh.region);
    put(payload, mesh.T10);
    put(payload, responses.compliance);
    put(payload, responses.observed);
    return write_cache_file(cache_file(dir, key), kMagic, key, payload, problem);
}

} // namespace chromasim::mechanics
