// chromasim spec-doc: print every spec key, the user manual of spec files (docs/SPEC.md).
#include "generators/cli/command.hpp"
#include "generators/spec/spec.hpp"

#include <iostream>

namespace chromasim::cli {
namespace gen = generators;

void add_spec_doc(CLI::App& app, Action& action) {
    auto* schema = app.add_subcommand(
        "spec-doc", "print every spec key: the user manual of spec files (Markdown table)");
    schema->alias("schema"); // its name before docs/SPEC.md
    schema->callback([&action] {
        action = [] {
            std::cout << gen::schema_markdown();
            return 0;
        };
    });
}

} // namespace chromasim::cli
