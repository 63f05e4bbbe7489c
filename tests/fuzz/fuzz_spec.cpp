// libFuzzer target of the spec loader (docs/VALIDATION.md, "Fuzzing the spec loader"): any
// bytes as a spec file's text. The loader may accept them (a valid Spec) or reject them with a
// SpecError that names the file; anything else is a finding: another exception, a crash, an
// ASan/UBSan report, a hang. Built only with -DCHROMASIM_FUZZ=ON under clang
// (scripts/fuzz-spec).
#include "generators/spec/spec.hpp"

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
