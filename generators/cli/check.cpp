// chromasim check: list a dataset's impossible or inconsistent labels.
#include "generators/output/check.hpp"
#include "generators/cli/command.hpp"

#include <iostream>

namespace chromasim::cli {
namespace gen = generators;
namespace {

int run(const std::string& dataset) {
    const gen::CheckReport report = gen::check_dataset(dataset);
    gen::print_check_report(dataset, report, std::cout);
    return report.findings_total > 0 ? 1 : 0;
}

} // namespace

void add_check(CLI::App& app, Action& action) {
    auto dataset = std::make_shared<std::string>();
    auto* check = app.add_subcommand(
        "check", "list impossible or inconsistent labels of a dataset (exit 1 if any)");
    check->add_option("dataset", *dataset, "dataset folder (written by generate or merge)")
        ->required();
    on_chosen(check, action, dataset, run);
}

} // namespace chromasim::cli
