#include "generators/io/cache_file.hpp"

#include "generators/io/file_io.hpp"

#include <cstring>
#include <stdexcept>

#include <unistd.h>

namespace fs = std::filesystem;

namespace chromasim::generators {

namespace {

constexpr std::size_t kDigestHex = 64;

std::string header(std::string_view magic, std::uint64_t key, std::string_view payload) {
    std::string out(magic);
    out.append(reinterpret_cast<const char*>(&key), sizeof key);
    out += sha256_hex(payload);
    return out;
}

} // namespace

void CacheKey::bytes(const void* data, std::size_t size) {
    const std::uint64_t n = size;
    m_bytes.append(reinterpret_cast<const char*>(&n), sizeof n);
    m_bytes.append(static_cast<const char*>(data), size);
}

std::uint64_t CacheKey::key() const {
    return std::stoull(sha256_hex(m_bytes).substr(0, 16), nullptr, 16);
}

std::optional<std::string> read_cache_file(const fs::path& path, std::string_view magic,
                                           std::uint64_t key, std::string* problem) {
    std::error_code ec;
    if (!fs::exists(path, ec)) return std::nullopt;
    auto fail = [&](const std::string& why) -> std::optional<std::string> {
        if (problem) *problem = path.string() + ": " + why;
        return std::nullopt;
    };
    std::string bytes;
    try {
        bytes = read_file(path);
    } catch (const std::runtime_error& e) {
        return fail(e.what());
    }
    const std::size_t head = magic.size() + sizeof key + kDigestHex;
    if (bytes.size() < head || std::string_view(bytes).substr(0, magic.size()) != magic)
        return fail("not a chromasim cache file");
    std::uint64_t stored_key = 0;
    std::memcpy(&stored_key, bytes.data() + magic.size(), sizeof stored_key);
    if (stored_key != key) return fail("written for another key");
    const std::string_view digest = std::string_view(bytes).substr(head - kDigestHex, kDigestHex);
    if (sha256_hex(std::string_view(bytes).substr(head)) != digest)
        return fail("checksum mismatch (torn or corrupt file)");
    bytes.erase(0, head);
    return bytes;
}

bool write_cache_file(const fs::path& path, std::string_view magic, std::uint64_t key,
                      std::string_view payload, std::string* problem) {
    const fs::path tmp = path.string() + ".tmp-" + std::to_string(::getpid());
    try {
        fs::create_directories(path.parent_path());
        FileWriter out(tmp);
        out.append(header(magic, key, payload));
        out.append(payload);
        out.close();
        rename_path(tmp, path);
        return true;
    } catch (const std::exception& e) {
        if (problem) *problem = e.what();
        std::error_code ec;
        fs::remove(tmp, ec);
        return false;
    }
}

} // namespace chromasim::generators
