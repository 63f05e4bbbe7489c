// chromasim generate: run a dataset spec and write the dataset.
#include "generators/cli/command.hpp"
#include "generators/pipeline/generate.hpp"
#include "generators/spec/spec.hpp"

#include <unistd.h>

#include <iostream>
#include <optional>

namespace chromasim::cli {
namespace gen = generators;
namespace {

struct GenerateArgs {
    std::string spec_path, out_dir;
    std::optional<std::string> shard;
    CacheOptions cache;
    gen::GenerateOptions options;
};

// Where each kind of output went, as a user looks for it.
void print_outputs(const gen::Spec& spec, const std::filesystem::path& out) {
    if (spec.outputs.images)
        std::cout << "  images: " << (out / "images").string()
                  << "/<split>/trial_NNNNNN/<finger>_NNNNNN.png\n";
    if (spec.outputs.exr)
        std::cout << "  exr: " << (out / "images").string()
                  << "/<split>/trial_NNNNNN/<finger>_NNNNNN.exr\n";
    if (spec.outputs.labels) std::cout << "  labels: " << (out / "labels.csv").string() << "\n";
    if (spec.outputs.markers) std::cout << "  markers: " << (out / "markers.csv").string() << "\n";
    if (spec.outputs.strain)
        std::cout << "  strain: " << (out / "strain").string()
                  << "/<split>/trial_NNNNNN/<finger>.csv\n";
}

int run(const GenerateArgs& args) {
    gen::GenerateOptions options = args.options;
    options.out_dir = args.out_dir;
    options.cache_dir = args.cache.chosen();
    if (args.shard) options.shard = gen::parse_shard(*args.shard); // before any work
    const gen::Spec spec = gen::load_spec(args.spec_path);          // validation before any work
    options.terminal = ::isatty(::fileno(stderr)) != 0;
    const gen::GenerateReport r = gen::generate(spec, options, std::cerr);
    if (r.up_to_date || r.moved_only) return 0; // generate() said so on the log
    if (r.resumed_trials > 0)
        std::cout << "chromasim: kept " << r.resumed_trials
                  << " trial(s) of the interrupted run (--resume)\n";
    const gen::Shard& part = options.shard;
    std::cout << "chromasim: wrote " << (part.sharded() ? "part " + part.text() + ", " : "")
              << r.trials << " of " << r.planned_trials << " trials, " << r.frames << " frames ("
              << r.images << " images, " << r.renders << " rendered; " << r.solves << " solves, "
              << r.reused_solves << " reused) to " << options.out_dir.string() << " in "
              << r.total_s << " s (precompute " << r.precompute_s << " s, mechanics "
              << r.mechanics_s << " s, render " << r.render_s << " s, write " << r.write_s
              << " s)\n";
    if (part.sharded()) { // the dataset's files come with the merge
        std::cout << "  when all " << part.count
                  << " parts are written: chromasim merge PART... -o "
                  << "DIR (docs/DATASET_FORMAT.md, \"Shards and merge (clusters)\")\n";
        return 0;
    }
    print_outputs(spec, options.out_dir);
    if (r.flagged_frames > 0)
        std::cerr << "chromasim: " << r.flagged_frames
                  << " frame(s) flagged as not converged (labels.csv: converged = 0)\n";
    return 0;
}

} // namespace

void add_generate(CLI::App& app, Action& action) {
    auto args = std::make_shared<GenerateArgs>();
    gen::GenerateOptions& options = args->options;
    auto* generate = app.add_subcommand("generate", "run a dataset spec and write the dataset");
    generate->add_option("spec", args->spec_path, "spec file (YAML)")->required();
    generate
        ->add_option("-o,--output", args->out_dir,
                     "output folder (created; written as DIR.partial, renamed when complete)")
        ->required();
    generate->add_flag("--overwrite", options.overwrite,
                       "replace an existing dataset once the new one is complete (and discard "
                       "an interrupted run's DIR.partial unless --resume)");
    generate->add_flag("--resume", options.resume,
                       "finish the interrupted run that left DIR.partial (same spec): its "
                       "complete trials are checked and kept");
    generate->add_flag("-q,--quiet", options.quiet, "no per-trial lines, no progress");
    generate
        ->add_option("--max-trials", options.max_trials,
                     "run only the first N trials of the plan (a slice; 0: all)")
        ->check(CLI::Range(0, 1 << 30));
    generate->add_option("--shard", args->shard,
                         "write only part K of N (K/N, 1 <= K <= N): trials t with t mod N = "
                         "K-1, for chromasim merge; combines with --max-trials (shards of the "
                         "slice), --resume and --overwrite");
    add_cache_options(generate, args->cache);
    on_chosen(generate, action, args, run);
}

} // namespace chromasim::cli
