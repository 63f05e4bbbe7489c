// The executable as a user meets it: exit codes, messages, and nothing written on bad input.
#include <catch2/catch.hpp>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <unistd.h>

namespace fs = std::filesystem;

namespace {

struct Run {
    int code;
    std::string output; ///< stdout and stderr together
};

Run run_chromasim(const std::string& args) {
    const char* exe = std::getenv("CHROMASIM_EXE");
    REQUIRE(exe != nullptr); // set by CTest (tests/CMakeLists.txt)
    const fs::path log =
        fs::temp_directory_path() / ("chromasim_cli_test_" + std::to_string(::getpid()) + ".log");
    const std::string cmd = std::string(exe) + " " + args + " >" + log.string() + " 2>&1";
    const int status = std::system(cmd.c_str());
    std::ifstream in(log);
    std::stringstream s;
    s << in.rdbuf();
    return {WEXITSTATUS(status), s.str()};
}

fs::path write_spec(const std::string& name, const std::string& text) {
    const fs::path p = fs::temp_directory_path() / (std::to_string(::getpid()) + "_" + name);
    std::ofstream(p) << text;
    return p;
}

} // namespace

TEST_CASE("validate accepts the quickstart spec", "[generators][cli]") {
    const Run r = run_chromasim("validate datasets_spec/quickstart.yaml");
    CHECK(r.code == 0);
    CHECK(r.output.find("ok") != std::string::npos);
}

TEST_CASE("a bad spec stops generate before any work and writes nothing", "[generators][cli]") {
    const fs::path spec = write_spec("chromasim_bad.yaml", "name: bad\nrender:\n  width_px: -3\n");
    const fs::path out =
        fs::temp_directory_path() / ("chromasim_cli_bad_out_" + std::to_string(::getpid()));
    fs::remove_all(out);
    const Run r = run_chromasim("generate " + spec.string() + " -o " + out.string());
    INFO(r.output);
    CHECK(r.code == 2);
    CHECK(r.output.find("chromasim_bad.yaml:3:13") != std::string::npos);
    CHECK(r.output.find("render.width_px") != std::string::npos);
    CHECK(r.output.find("'-3'") != std::string::npos);
    CHECK(r.output.find("[16, 4096]") != std::string::npos);
    CHECK_FALSE(fs::exists(out));
    CHECK(r.output.find("dome mesh") == std::string::npos); // no meshing was started
}

TEST_CASE("validate reports a typo with its position and a suggestion", "[generators][cli]") {
    const fs::path spec = write_spec("chromasim_typo.yaml", "object:\n  muu: 0.5\n");
    const Run r = run_chromasim("validate " + spec.string());
    INFO(r.output);
    CHECK(r.code == 2);
    CHECK(r.output.find("chromasim_typo.yaml:2:3") != std::string::npos);
    CHECK(r.output.find("did you mean 'mu'") != std::string::npos);
}

TEST_CASE("bad command lines are refused with usage help", "[generators][cli]") {
    CHECK(run_chromasim("").code != 0);
    CHECK(run_chromasim("frobnicate").code != 0);
    const Run missing_out = run_chromasim("generate datasets_spec/quickstart.yaml");
    CHECK(missing_out.code != 0);
    CHECK(missing_out.output.find("--output") != std::string::npos);
    const Run threads = run_chromasim("--threads -2 validate datasets_spec/quickstart.yaml");
    CHECK(threads.code != 0);
    const Run nofile = run_chromasim("validate /nonexistent/spec.yaml");
    CHECK(nofile.code == 2);
    CHECK(nofile.output.find("/nonexistent/spec.yaml") != std::string::npos);
}

TEST_CASE("schema prints the documented key table", "[generators][cli]") {
    const Run r = run_chromasim("schema");
    CHECK(r.code == 0);
    CHECK(r.output.find("`render.samples_per_pixel`") != std::string::npos);
}
