// chromasim verify: the mechanics and the render against analytic references, and the sensor's
// laws measured from rendered images.
#include "generators/cli/command.hpp"
#include "generators/io/image_io.hpp"
#include "generators/validation/verify.hpp"
#include "generators/validation/verify_render.hpp"
#include "generators/validation/verify_sensor.hpp"

#include <fstream>
#include <iostream>
#include <stdexcept>

namespace chromasim::cli {
namespace gen = generators;
namespace {

// Writes `write(out)` to the file `path` unless it is empty.
template <class Write>
void write_json(const std::string& path, Write write) {
    if (path.empty()) return;
    std::ofstream json(path);
    write(json);
    if (!json) throw std::runtime_error("cannot write " + path);
}

struct MechanicsArgs {
    gen::VerifyOptions options;
    bool dome_curve = false;
    std::string json;
};

int run_mechanics(const MechanicsArgs& args) {
    const auto cases = gen::verify_mechanics(args.options);
    gen::print_verify_table(cases, std::cout);
    if (args.dome_curve) {
        std::cout << "\n";
        gen::print_dome_curve(std::cout);
    }
    write_json(args.json, [&](std::ostream& out) { gen::write_verify_json(cases, out); });
    return 0;
}

void add_mechanics(CLI::App* verify, Action& action) {
    auto args = std::make_shared<MechanicsArgs>();
    gen::VerifyOptions& o = args->options;
    auto* command =
        verify->add_subcommand("mechanics", "Hertz and Cattaneo-Mindlin on an elastic block");
    command->add_option("--levels", o.levels, "block mesh levels")
        ->delimiter(',')
        ->check(CLI::IsMember({"coarse", "medium", "fine"}));
    command->add_option("--nu", o.nus, "Poisson ratios")
        ->delimiter(',')
        ->check(CLI::Range(0.0, 0.4999));
    command->add_option("--volumetric", o.volumetrics, "formulations")
        ->delimiter(',')
        ->check(CLI::IsMember({"nodal_average", "element"}));
    command->add_flag("--dome-curve", args->dome_curve,
                      "also print the dome's force-indentation curve beside Hertz");
    command->add_option("--json", args->json, "also write the cases to this JSON file");
    on_chosen(command, action, args, run_mechanics);
}

struct RenderArgs {
    std::string json, reference_out;
    int reference_spp = 4096;
};

int run_render(const RenderArgs& args) {
    if (!args.reference_out.empty()) {
        gen::write_exr(args.reference_out, gen::render_reference_dome(args.reference_spp, 1));
        std::cout << "wrote " << args.reference_out << " (" << gen::kReferenceDomeSize_px
                  << " px, " << args.reference_spp << " spp)\n";
        return 0;
    }
    const auto cases = gen::verify_render();
    gen::print_render_verify_table(cases, std::cout);
    write_json(args.json, [&](std::ostream& out) { gen::write_render_verify_json(cases, out); });
    return 0;
}

void add_render(CLI::App* verify, Action& action) {
    auto args = std::make_shared<RenderArgs>();
    auto* command = verify->add_subcommand(
        "render", "fisheye projection, filter product, determinism, convergence slope");
    command->add_option("--json", args->json, "also write the cases to this JSON file");
    command
        ->add_option("--write-reference", args->reference_out,
                     "only write the committed reference image (EXR) and stop")
        ->check(CLI::NonexistentPath);
    command->add_option("--reference-spp", args->reference_spp, "its samples per pixel")
        ->check(CLI::Range(1, 1 << 20));
    on_chosen(command, action, args, run_render);
}

struct SensorArgs {
    gen::SensorVerifyOptions options;
    std::string spec, json, picture, keep;
    CacheOptions cache;
};

int run_sensor(const SensorArgs& args) {
    gen::SensorVerifyOptions options = args.options;
    options.spec_file = args.spec;
    options.json = args.json;
    options.picture = args.picture;
    options.keep_dir = args.keep;
    options.cache_dir = args.cache.chosen();
    const auto report = gen::verify_sensor(options, std::cout);
    gen::print_sensor_verify(report, std::cout);
    write_json(args.json, [&](std::ostream& out) { gen::write_sensor_verify_json(report, out); });
    return report.all_met() ? 0 : 1;
}

void add_sensor(CLI::App* verify, Action& action) {
    auto args = std::make_shared<SensorArgs>();
    auto* command = verify->add_subcommand(
        "sensor", "the sensor's hue, size and centroid laws, measured from rendered images");
    command->add_option("spec", args->spec,
                        "spec whose sensor and render sections to verify (default: the "
                        "default sensor, fast integrator, 2 spp)");
    command->add_option("--size-px", args->options.size_px, "image side (px)")
        ->check(CLI::Range(16, 4096))
        ->capture_default_str();
    command->add_option("--json", args->json, "also write the results to this JSON file");
    command->add_option("--picture", args->picture,
                        "write the apex marker at rest and at 3 N to this PNG");
    command->add_option("--keep", args->keep, "keep the rendered dataset in this new folder");
    add_cache_options(command, args->cache);
    on_chosen(command, action, args, run_sensor);
}

} // namespace

void add_verify(CLI::App& app, Action& action) {
    auto* verify = app.add_subcommand("verify", "validation against analytic references");
    verify->require_subcommand(1);
    add_mechanics(verify, action);
    add_render(verify, action);
    add_sensor(verify, action);
}

} // namespace chromasim::cli
