#pragma once
// The chromasim executable's subcommands, one file each. Each adds itself to the app and, when
// the user chose it, leaves in `action` the work to run after parsing.
#include "generators/pipeline/generate.hpp"

#include <CLI/CLI.hpp>

#include <filesystem>
#include <functional>
#include <memory>
#include <string>

namespace chromasim::cli {

/// The chosen subcommand's work; returns the process's exit status.
using Action = std::function<int()>;

void add_generate(CLI::App& app, Action& action);
void add_merge(CLI::App& app, Action& action);
void add_export_scene(CLI::App& app, Action& action);
void add_validate(CLI::App& app, Action& action);
void add_check(CLI::App& app, Action& action);
void add_spec_doc(CLI::App& app, Action& action);
void add_bench(CLI::App& app, Action& action);
void add_verify(CLI::App& app, Action& action);
void add_calibrate(CLI::App& app, Action& action);

/// --cache-dir and --no-cache, as generate, export-scene and verify sensor take them.
struct CacheOptions {
    std::string dir = generators::default_cache_dir().string();
    bool off = false;
    /// The folder to use; empty (no cache) with --no-cache.
    std::filesystem::path chosen() const { return off ? std::filesystem::path() : std::filesystem::path(dir); }
};

inline void add_cache_options(CLI::App* command, CacheOptions& cache) {
    command
        ->add_option("--cache-dir", cache.dir,
                     "cache of mesh and contact responses, reused across runs")
        ->capture_default_str();
    command->add_flag("--no-cache", cache.off, "neither read nor write the cache");
}

/// Leaves `run(options)` in `action` when `command` is chosen; `options` outlive the parse.
template <class Options, class Run>
void on_chosen(CLI::App* command, Action& action, std::shared_ptr<Options> options, Run run) {
    command->callback([&action, options, run] { action = [options, run] { return run(*options); }; });
}

} // namespace chromasim::cli
