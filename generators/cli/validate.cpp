// chromasim validate: check spec files and say what they describe; do no work.
#include "generators/cli/command.hpp"
#include "generators/plan/plan.hpp"
#include "generators/spec/spec.hpp"

#include <iostream>

namespace chromasim::cli {
namespace gen = generators;
namespace {

int run(const std::vector<std::string>& paths) {
    std::vector<gen::Spec> specs; // every file is checked before anything is printed
    for (const auto& p : paths)
        specs.push_back(gen::load_spec(p));
    for (std::size_t i = 0; i < specs.size(); ++i) {
        const gen::Plan plan = gen::make_plan(specs[i]);
        const std::size_t frames = plan.frame_count();
        const std::size_t images =
            specs[i].outputs.images ? frames * std::size_t(specs[i].fingers.count) : 0;
        std::cout << paths[i] << ": ok (" << plan.trials.size() << " trials, " << frames
                  << " frames, " << images << " images"
                  << (plan.sensors.empty() ? std::string()
                                           : ", " + std::to_string(plan.sensors.size()) + " sensors")
                  << ")\n";
    }
    return 0;
}

} // namespace

void add_validate(CLI::App& app, Action& action) {
    auto paths = std::make_shared<std::vector<std::string>>();
    auto* validate = app.add_subcommand("validate", "check spec files; do no work");
    validate->add_option("spec", *paths, "spec file(s)")->required();
    on_chosen(validate, action, paths, run);
}

} // namespace chromasim::cli
