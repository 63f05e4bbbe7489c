// chromasim merge: join the parts of a sharded generate into the dataset an unsharded run
// writes.
#include "generators/cli/command.hpp"
#include "generators/output/merge.hpp"

#include <iostream>

namespace chromasim::cli {
namespace gen = generators;
namespace {

struct MergeArgs {
    std::vector<std::string> parts;
    std::string out_dir;
    gen::MergeOptions options;
};

int run(const MergeArgs& args) {
    gen::MergeOptions options = args.options;
    for (const std::string& p : args.parts)
        options.parts.emplace_back(p);
    options.out_dir = args.out_dir;
    const gen::MergeReport r = gen::merge(options, std::cerr);
    if (r.up_to_date) return 0; // merge() said so on the log
    std::cout << "chromasim: merged " << r.parts << " parts, " << r.trials << " trials (" << r.files
              << " files of trials, " << r.copied << " copied, the others hard-linked) into "
              << options.out_dir.string() << " in " << r.total_s << " s\n";
    return 0;
}

} // namespace

void add_merge(CLI::App& app, Action& action) {
    auto args = std::make_shared<MergeArgs>();
    auto* merge = app.add_subcommand(
        "merge", "join the parts of a sharded generate (--shard K/N) into the dataset an "
                 "unsharded run writes");
    merge->add_option("parts", args->parts, "the N part folders, any order (e.g. out/part_*)")
        ->required();
    merge
        ->add_option("-o,--output", args->out_dir,
                     "dataset folder (written as DIR.partial, renamed when complete)")
        ->required();
    merge->add_flag("--overwrite", args->options.overwrite,
                    "replace an existing dataset once the new one is complete, and discard a "
                    "DIR.partial");
    on_chosen(merge, action, args, run);
}

} // namespace chromasim::cli
