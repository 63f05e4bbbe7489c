// The generation's progress reporter (generators/pipeline/progress.hpp) and what `generate` prints with
// it: plain lines when the log is not a terminal, a line redrawn in place when it is, nothing
// with --quiet.
#include "generators/pipeline/progress.hpp"

#include <catch2/catch.hpp>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <sys/wait.h>
#include <unistd.h>

using chromasim::generators::Progress;

TEST_CASE("progress: frames done, frames per second and time left", "[generators][progress]") {
    // 120 of 680 frames in 37.5 s: 3.2 frames/s, 560 left take 175 s.
    CHECK(Progress::describe(120, 680, 37.5, false) ==
          "  progress: 120/680 frames  3.20 frames/s  ETA 2 min 55 s");
    CHECK(Progress::describe(680, 680, 100.0, false) ==
          "  progress: 680/680 frames  6.80 frames/s  ETA 0 s");
    CHECK(Progress::describe(0, 10, 0.0, false) == "  progress: 0/10 frames  0.00 frames/s  ETA ?");
    // Half done: half the bar.
    CHECK(Progress::describe(340, 680, 10.0, true) ==
          "  [############............]  340/680 frames  34.00 frames/s  ETA 10 s");

    std::ostringstream plain, terminal, quiet;
    {
        Progress p(plain, 3, false, false, 0.0); // a line at every frame
        for (int i = 0; i < 3; ++i)
            p.advance();
        p.finish();
    }
    CHECK(plain.str().find('\r') == std::string::npos);
    CHECK(plain.str().find("  progress: 1/3 frames") == 0);
    CHECK(plain.str().find("  progress: 3/3 frames") != std::string::npos);
    {
        Progress p(terminal, 3, true, false);
        p.advance(3);
        p.clear();
        p.finish();
    }
    CHECK(terminal.str().find("\r  [") != std::string::npos);
    CHECK(terminal.str().find("\r\033[K") != std::string::npos);
    CHECK(terminal.str().back() == '\n');
    {
        Progress p(quiet, 3, true, true, 0.0);
        p.advance(3);
        p.clear();
        p.finish();
    }
    CHECK(quiet.str().empty());
}

TEST_CASE("generate prints progress lines to a log that is not a terminal, none with --quiet",
          "[generators][progress][cli]") {
    const char* exe = std::getenv("CHROMASIM_EXE");
    REQUIRE(exe != nullptr); // set by CTest (tests/CMakeLists.txt)
    namespace fs = std::filesystem;
    const std::string id = std::to_string(::getpid());
    auto run = [&](const std::string& args) {
        const fs::path out = fs::temp_directory_path() / ("chromasim_progress_" + id);
        const fs::path log = fs::temp_directory_path() / ("chromasim_progress_" + id + ".log");
        fs::remove_all(out);
        const std::string cmd = std::string(exe) + " generate datasets_spec/quickstart.yaml -o " +
                                out.string() + " --max-trials 1 " + args + " >" + log.string() +
                                " 2>&1";
        const int status = std::system(cmd.c_str());
        CHECK(WEXITSTATUS(status) == 0);
        std::ifstream in(log);
        std::stringstream s;
        s << in.rdbuf();
        fs::remove_all(out);
        fs::remove(log);
        return s.str();
    };
    const std::string loud = run("");
    INFO(loud);
    CHECK(loud.find("  progress: ") != std::string::npos);
    CHECK(loud.find(" frames/s  ETA ") != std::string::npos);
    CHECK(loud.find('\r') == std::string::npos);
    const std::string quiet = run("--quiet");
    INFO(quiet);
    CHECK(quiet.find("progress:") == std::string::npos);
}
