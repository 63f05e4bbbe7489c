#pragma once
/// Files written so that they are complete or absent, and their SHA-256 checksums. Every error
/// names the path and the operating system's reason (errno): "No space left on device",
/// "Permission denied", "Not a directory".
#include <filesystem>
#include <string>
#include <string_view>

namespace chromasim::generators {

/// A file written in pieces (a dataset's labels.csv assembled from per-trial shards); every
/// failure throws std::runtime_error "cannot write PATH: REASON".
class FileWriter {
public:
    explicit FileWriter(std::filesystem::path path); ///< creates or truncates
    ~FileWriter();                                   ///< closes without checking (see close())
    FileWriter(const FileWriter&) = delete;
    FileWriter& operator=(const FileWriter&) = delete;
    void append(std::string_view bytes);
    void close(); ///< throws if the close fails (a full disk often shows only there)

private:
    std::filesystem::path m_path;
    int m_fd = -1;
};

/// Writes `bytes` to `path` (created or truncated) and closes it; throws std::runtime_error
/// "cannot write PATH: REASON" on any failure, the close included (a full disk often shows
/// only there).
void write_file(const std::filesystem::path& path, std::string_view bytes);

/// Writes `bytes` to "PATH.tmp", then renames it to `path`: a reader (or a run that was killed
/// and resumed) sees the old file, or none, or the whole new one.
void write_file_atomic(const std::filesystem::path& path, std::string_view bytes);

/// Renames `from` to `to` (replacing a file); throws std::runtime_error naming both and the
/// reason.
void rename_path(const std::filesystem::path& from, const std::filesystem::path& to);

/// The whole content of `path`; throws std::runtime_error "cannot read PATH: REASON".
std::string read_file(const std::filesystem::path& path);

/// SHA-256 of `bytes`, 64 lowercase hex digits (OpenSSL's libcrypto).
std::string sha256_hex(std::string_view bytes);

/// SHA-256 of the file at `path`, read in blocks; throws like read_file.
std::string sha256_file(const std::filesystem::path& path);

} // namespace chromasim::generators
