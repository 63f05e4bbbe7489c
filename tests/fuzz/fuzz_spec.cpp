// libFuzzer target of the spec loader (docs/VALIDATION.md, "Fuzzing the spec loader"): any
// bytes as a spec file's text. The loader may accept them (a valid Spec) or reject them with a
// SpecError that names the file; anything else is a finding: another exception, a crash, an
// ASan/UBSan report, a hang. An accepted spec must also be one generate can record: its text
// values go into JSON (the manifest, the trial records), so they must dump. Built only with
// -DCHROMASIM_FUZZ=ON under clang (scripts/fuzz-spec).
#include "generators/spec/spec.hpp"
#include "generators/spec/spec_schema.hpp"

#include <nlohmann/json.hpp>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

namespace {

constexpr std::string_view kFile = "fuzz.yaml";

[[noreturn]] void finding(const char* what, const std::string& detail) {
    std::fprintf(stderr, "fuzz_spec: %s\n%s\n", what, detail.c_str());
    std::abort();
}

} // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    namespace gen = chromasim::generators;
    const std::string text(reinterpret_cast<const char*>(data), size);
    gen::Spec spec;
    try {
        spec = gen::parse_spec(text, std::string(kFile));
    } catch (const gen::SpecError& e) {
        // Every rejection names the file first (file:line:column where there is a place).
        if (std::string_view(e.what()).substr(0, kFile.size()) != kFile)
            finding("a SpecError that does not start with the file name", e.what());
        return 0;
    }
    // Every text value of an accepted spec dumps as JSON, as the manifest will write it.
    nlohmann::json texts = nlohmann::json::array();
    for (const gen::SchemaEntry& e : gen::spec_schema()) {
        if (e.type != gen::ValueType::String && e.type != gen::ValueType::Enum) continue;
        const gen::SchemaList* list = e.list().empty() ? nullptr : gen::find_schema_list(e.list());
        for (std::size_t i = 0; i < (list ? list->size(spec) : 1); ++i)
            texts.push_back(std::get<std::string>(e.get(spec, i)));
    }
    try {
        (void)texts.dump();
    } catch (const std::exception& e) {
        finding("an accepted spec's text cannot be written as JSON", e.what());
    }
    // An accepted spec's resolved YAML (written next to every dataset) is itself a valid spec
    // that resolves to the same text.
    try {
        const gen::Spec again = gen::parse_spec(spec.resolved_yaml, std::string(kFile));
        if (again.resolved_yaml != spec.resolved_yaml)
            finding("the resolved YAML does not resolve to itself",
                    spec.resolved_yaml + "\n----\n" + again.resolved_yaml);
    } catch (const gen::SpecError& e) {
        finding("the resolved YAML of an accepted spec is rejected",
                std::string(e.what()) + "\n----\n" + spec.resolved_yaml);
    }
    return 0;
}
