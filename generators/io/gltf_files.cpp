#include "generators/io/gltf_detail.hpp"

// The glTF adapter's file handling: reading a file's bytes, refusing a bad output path before
// any work, and writing through a temporary file so that no half-written file is left.

#include <algorithm>
#include <cctype>
#include <fstream>
#include <iterator>
#include <limits>
#include <stdexcept>
#include <unistd.h>

namespace chromasim::generators {

namespace fs = std::filesystem;

namespace detail {

void fail(const fs::path& file, const std::string& what) {
    throw std::runtime_error(file.string() + ": " + what);
}

std::string lowercase_extension(const fs::path& file) {
    std::string ext = file.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return char(std::tolower(c)); });
    return ext;
}

std::vector<unsigned char> read_bytes(const fs::path& file) {
    std::error_code ec;
    if (!fs::is_regular_file(file, ec))
        fail(file, fs::exists(file, ec) ? "not a regular file; expected a glTF 2.0 file"
                                        : "no such file; expected a glTF 2.0 file (.gltf or .glb)");
    std::ifstream in(file, std::ios::binary);
    if (!in) fail(file, "cannot open for reading");
    std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(in)),
                                     std::istreambuf_iterator<char>());
    if (in.bad()) fail(file, "read error");
    if (bytes.size() > std::numeric_limits<unsigned int>::max())
        fail(file, "larger than 4 GiB; glTF files are limited to 4 GiB");
    return bytes;
}

void write_atomically(const fs::path& file, const std::function<bool(std::ostream&)>& write) {
    const fs::path tmp = file.string() + ".partial-" + std::to_string(::getpid());
    bool ok = false;
    {
        std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
        if (!out) fail(file, "cannot open " + tmp.string() + " for writing");
        ok = write(out);
        out.close();
        ok = ok && !out.fail();
    }
    std::error_code ec;
    if (ok) fs::rename(tmp, file, ec);
    if (!ok || ec) {
        const std::string why =
            ok ? "cannot rename " + tmp.string() + " into place: " + ec.message()
               : "write error (disk full or folder not writable?)";
        fs::remove(tmp, ec);
        fail(file, why);
    }
}

} // namespace detail

void check_gltf_output_path(const fs::path& file) {
    using detail::fail;
    const std::string ext = detail::lowercase_extension(file);
    if (ext != ".gltf" && ext != ".glb")
        fail(file, "unknown extension '" + file.extension().string() +
                       "'; use .gltf (JSON, embedded buffer) or .glb (binary)");
    const fs::path folder = file.parent_path().empty() ? fs::path(".") : file.parent_path();
    std::error_code ec;
    if (!fs::is_directory(folder, ec))
        fail(file, "folder " + folder.string() +
                       (fs::exists(folder, ec) ? " is not a folder" : " does not exist") +
                       "; the output goes into an existing, writable folder");
    if (::access(folder.c_str(), W_OK) != 0)
        fail(file, "folder " + folder.string() +
                       " is not writable; the output goes into an existing, writable folder");
}

} // namespace chromasim::generators
