// chromasim calibrate: fit a spec to images of the user's own sensor. The fit is Python
// (python/chromasim/calibrate.py: SciPy's least squares through the simulator's Python module);
// this command runs it with Debian's python3, this checkout's package and this build's module.
#include "generators/cli/command.hpp"

#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

namespace chromasim::cli {

namespace {

constexpr const char* kPython = "/usr/bin/python3";

/// Sets `name` to `value` unless the user set it; PYTHONPATH gets `value` in front.
void prepend_path(const char* name, const std::string& value) {
    const char* old = std::getenv(name);
    const std::string joined = old && *old ? value + ":" + old : value;
    ::setenv(name, joined.c_str(), 1);
}

int run_python(const std::vector<std::string>& args) {
    std::error_code ec;
    const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
    if (!ec && !std::getenv("CHROMASIM_BUILD_DIR"))
        ::setenv("CHROMASIM_BUILD_DIR", exe.parent_path().c_str(), 1);
    prepend_path("PYTHONPATH", CHROMASIM_PYTHON_DIR);
    std::vector<char*> argv{const_cast<char*>("python3"), const_cast<char*>("-m"),
                            const_cast<char*>("chromasim.calibrate")};
    for (const std::string& a : args)
        argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    ::execv(kPython, argv.data());
    std::cerr << "error: chromasim calibrate runs " << kPython << " -m chromasim.calibrate, which "
              << "could not start (" << std::strerror(errno)
              << "); allowed: Debian's python3 with python3-scipy and python3-openimageio "
              << "(scripts/install-deps installs them)\n";
    return 1;
}

} // namespace

void add_calibrate(CLI::App& app, Action& action) {
    auto* cmd = app.add_subcommand(
        "calibrate", "fit a spec to your sensor: a rest image, presses of known force "
                     "(`chromasim calibrate --help`; docs/CALIBRATION.md)");
    cmd->prefix_command(); // every argument, --help included, goes to the Python tool
    cmd->set_help_flag();
    cmd->callback(
        [cmd, &action] { action = [args = cmd->remaining()] { return run_python(args); }; });
}

} // namespace chromasim::cli
