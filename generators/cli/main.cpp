// chromasim: the command line. Each subcommand's options and work live in a file of their own
// (command.hpp); main parses, limits the threads and turns errors into exit statuses.
#include "generators/cli/command.hpp"
#include "generators/spec/spec.hpp"

#include <CLI/CLI.hpp>
#include <tbb/global_control.h>

#include <iostream>
#include <memory>

int main(int argc, char** argv) {
    namespace cli = chromasim::cli;
    CLI::App app{"chromasim: synthetic tactile images and labels for camera-based fingertips"};
    app.set_version_flag("--version", std::string("chromasim ") + CHROMASIM_BUILD);
    app.require_subcommand(1);
    int threads = 0;
    app.add_option("--threads", threads, "worker threads (0: all cores)")
        ->check(CLI::Range(0, 1024));
    cli::Action action;
    cli::add_generate(app, action);
    cli::add_merge(app, action);
    cli::add_export_scene(app, action);
    cli::add_validate(app, action);
    cli::add_check(app, action);
    cli::add_spec_doc(app, action);
    cli::add_bench(app, action);
    cli::add_verify(app, action);
    cli::add_calibrate(app, action);

    CLI11_PARSE(app, argc, argv);
    std::unique_ptr<tbb::global_control> limit;
    if (threads > 0)
        limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                      std::size_t(threads));
    try {
        return action ? action() : 0;
    } catch (const chromasim::generators::SpecError& e) {
        std::cerr << "error: " << e.what() << '\n';
        return 2;
    } catch (const std::exception& e) {
        std::cerr << "error: " << e.what() << '\n';
        return 1;
    }
}
