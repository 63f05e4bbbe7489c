#include "generators/io/file_io.hpp"

#include <openssl/evp.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>
#include <stdexcept>

#include <fcntl.h>
#include <unistd.h>

namespace fs = std::filesystem;

namespace chromasim::generators {

namespace {

[[noreturn]] void fail(const char* what, const fs::path& path, int error) {
    throw std::runtime_error(std::string(what) + " " + path.string() + ": " + std::strerror(error));
}

/// A file descriptor closed on every path out.
struct Fd {
    int fd = -1;
    ~Fd() {
        if (fd >= 0) ::close(fd);
    }
};

struct DigestDeleter {
    void operator()(EVP_MD_CTX* c) const { EVP_MD_CTX_free(c); }
};
using Digest = std::unique_ptr<EVP_MD_CTX, DigestDeleter>;

Digest sha256_begin() {
    Digest ctx(EVP_MD_CTX_new());
    if (!ctx || EVP_DigestInit_ex(ctx.get(), EVP_sha256(), nullptr) != 1)
        throw std::runtime_error("OpenSSL: cannot start a SHA-256 digest");
    return ctx;
}

std::string sha256_end(EVP_MD_CTX* ctx) {
    unsigned char md[EVP_MAX_MD_SIZE];
    unsigned int size = 0;
    if (EVP_DigestFinal_ex(ctx, md, &size) != 1)
        throw std::runtime_error("OpenSSL: cannot finish a SHA-256 digest");
    static const char* hex = "0123456789abcdef";
    std::string out;
    for (unsigned int i = 0; i < size; ++i) {
        out += hex[md[i] >> 4];
        out += hex[md[i] & 15];
    }
    return out;
}

} // namespace

FileWriter::FileWriter(fs::path path) : m_path(std::move(path)) {
    m_fd = ::open(m_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (m_fd < 0) fail("cannot write", m_path, errno);
}

FileWriter::~FileWriter() {
    if (m_fd >= 0) ::close(m_fd);
}

void FileWriter::append(std::string_view bytes) {
    for (std::size_t done = 0; done < bytes.size();) {
        const ssize_t n = ::write(m_fd, bytes.data() + done, bytes.size() - done);
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) fail("cannot write", m_path, errno);
        done += std::size_t(n);
    }
}

void FileWriter::close() {
    const int fd = m_fd;
    m_fd = -1;
    if (fd >= 0 && ::close(fd) != 0) fail("cannot write", m_path, errno);
}

void write_file(const fs::path& path, std::string_view bytes) {
    FileWriter f(path);
    f.append(bytes);
    f.close();
}

void write_file_atomic(const fs::path& path, std::string_view bytes) {
    const fs::path tmp = path.string() + ".tmp";
    try {
        write_file(tmp, bytes);
    } catch (...) {
        ::unlink(tmp.c_str()); // a torn temporary is never left for a reader to trust
        throw;
    }
    rename_path(tmp, path);
}

void rename_path(const fs::path& from, const fs::path& to) {
    if (std::rename(from.c_str(), to.c_str()) != 0) {
        const int error = errno;
        throw std::runtime_error("cannot rename " + from.string() + " to " + to.string() + ": " +
                                 std::strerror(error));
    }
}

std::string read_file(const fs::path& path) {
    Fd f{::open(path.c_str(), O_RDONLY | O_CLOEXEC)};
    if (f.fd < 0) fail("cannot read", path, errno);
    std::string out;
    char block[1 << 16];
    for (;;) {
        const ssize_t n = ::read(f.fd, block, sizeof block);
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) fail("cannot read", path, errno);
        if (n == 0) return out;
        out.append(block, std::size_t(n));
    }
}

std::string sha256_hex(std::string_view bytes) {
    Digest ctx = sha256_begin();
    if (EVP_DigestUpdate(ctx.get(), bytes.data(), bytes.size()) != 1)
        throw std::runtime_error("OpenSSL: SHA-256 update failed");
    return sha256_end(ctx.get());
}

std::string sha256_file(const fs::path& path) {
    Fd f{::open(path.c_str(), O_RDONLY | O_CLOEXEC)};
    if (f.fd < 0) fail("cannot read", path, errno);
    Digest ctx = sha256_begin();
    char block[1 << 16];
    for (;;) {
        const ssize_t n = ::read(f.fd, block, sizeof block);
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) fail("cannot read", path, errno);
        if (n == 0) break;
        if (EVP_DigestUpdate(ctx.get(), block, std::size_t(n)) != 1)
            throw std::runtime_error("OpenSSL: SHA-256 update failed");
    }
    return sha256_end(ctx.get());
}

} // namespace chromasim::generators
