// chromasim export-scene: write one frame's scene as glTF 2.0.
#include "generators/cli/command.hpp"
#include "generators/pipeline/scene_export.hpp"
#include "generators/spec/spec.hpp"

#include <cmath>
#include <iostream>

namespace chromasim::cli {
namespace gen = generators;
namespace {

struct ExportArgs {
    std::string spec_path, finger = "left", out;
    gen::SceneSelection which;
    CacheOptions cache;
};

int run(const ExportArgs& args) {
    gen::SceneExportOptions options;
    options.cache_dir = args.cache.chosen();
    gen::SceneSelection which = args.which;
    which.finger = args.finger == "right" ? 1 : 0;
    const gen::Spec spec = gen::load_spec(args.spec_path); // validation before any work
    const gen::SceneExportReport r = gen::export_scene(spec, which, args.out, options, std::cerr);
    const gen::LabelRow& l = r.labels;
    std::cout << "chromasim: wrote trial " << r.trial << " " << gen::finger_name(r.finger)
              << " frame " << r.frame << " of " << r.frames << " (" << l.phase << ", Fn "
              << l.normal_force_N << " N, Ft " << std::hypot(l.tangential_x_N, l.tangential_y_N)
              << " N, Gamma " << l.gamma << ") to " << args.out << " in " << r.total_s << " s\n";
    return 0;
}

} // namespace

void add_export_scene(CLI::App& app, Action& action) {
    auto args = std::make_shared<ExportArgs>();
    auto* command = app.add_subcommand(
        "export-scene", "write one frame's scene as glTF 2.0 (meshes, materials, LEDs, camera)");
    command->add_option("spec", args->spec_path, "spec file (YAML)")->required();
    command->add_option("--trial", args->which.trial, "trial of the plan (0: the first)")
        ->capture_default_str();
    command->add_option("--finger", args->finger, "fingertip")
        ->check(CLI::IsMember({"left", "right"}))
        ->capture_default_str();
    command
        ->add_option("--frame", args->which.frame, "frame of the trial to export (0: the first)")
        ->required();
    command
        ->add_option("-o,--output", args->out,
                     "output file: .gltf (JSON, embedded buffers) or .glb (binary)")
        ->required();
    add_cache_options(command, args->cache);
    on_chosen(command, action, args, run);
}

} // namespace chromasim::cli
