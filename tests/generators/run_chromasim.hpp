#pragma once
// Test helper: drives the chromasim executable as a user does (CHROMASIM_EXE, set by CTest), and
// reads a folder back as relative path -> SHA-256.
#include "generators/io/file_io.hpp"

#include "scratch_dir.hpp"

#include <catch2/catch.hpp>

#include <cstdlib>
#include <filesystem>
#include <map>
#include <string>

#include <sys/wait.h>

struct Run {
    int code;           ///< exit status, or 128 + signal
    std::string output; ///< stdout and stderr together
};

/// Runs `env chromasim args`, output to a log in `dir`.
inline Run run_chromasim(const ScratchDir& dir, const std::string& args,
                         const std::string& env = "") {
    const char* exe = std::getenv("CHROMASIM_EXE");
    REQUIRE(exe != nullptr); // set by CTest (tests/CMakeLists.txt)
    const std::filesystem::path log = dir.path / "run.log";
    const std::string cmd = env + " " + exe + " " + args + " >" + log.string() + " 2>&1";
    const int status = std::system(cmd.c_str());
    int code = -1;
    if (WIFEXITED(status)) code = WEXITSTATUS(status);
    if (WIFSIGNALED(status)) code = 128 + WTERMSIG(status);
    return {code, chromasim::generators::read_file(log)};
}

/// Every file under `root`: relative path -> SHA-256.
inline std::map<std::string, std::string> tree(const std::filesystem::path& root) {
    std::map<std::string, std::string> sums;
    for (const auto& e : std::filesystem::recursive_directory_iterator(root))
        if (e.is_regular_file())
            sums[std::filesystem::relative(e.path(), root).generic_string()] =
                chromasim::generators::sha256_file(e.path());
    return sums;
}
