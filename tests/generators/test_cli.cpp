// The executable as a user meets it: exit codes, messages, and nothing written on bad input.
#include "generators/io/gltf_io.hpp"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <variant>
#include <vector>

#include <unistd.h>

namespace fs = std::filesystem;

namespace {

struct Run {
    int code;
    std::string output; ///< stdout and stderr together
};

Run run_chromasim(const std::string& args) {
    const char* exe = std::getenv("CHROMASIM_EXE");
    REQUIRE(exe != nullptr); // set by CTest (tests/CMakeLists.txt)
    const fs::path log =
        fs::temp_directory_path() / ("chromasim_cli_test_" + std::to_string(::getpid()) + ".log");
    const std::string cmd = std::string(exe) + " " + args + " >" + log.string() + " 2>&1";
    const int status = std::system(cmd.c_str());
    std::stringstream s;
    s << std::ifstream(log).rdbuf();
    fs::remove(log);
    return {WEXITSTATUS(status), s.str()};
}

fs::path write_spec(const std::string& name, const std::string& text) {
    const fs::path p = fs::temp_directory_path() / (std::to_string(::getpid()) + "_" + name);
    std::ofstream(p) << text;
    return p;
}

} // namespace

TEST_CASE("validate accepts the quickstart spec", "[generators][cli]") {
    const Run r = run_chromasim("validate datasets_spec/quickstart.yaml");
    CHECK(r.code == 0);
    CHECK(r.output.find("ok") != std::string::npos);
}

TEST_CASE("a bad spec stops generate before any work and writes nothing", "[generators][cli]") {
    const fs::path spec = write_spec("chromasim_bad.yaml", "name: bad\nrender:\n  width_px: -3\n");
    const fs::path out =
        fs::temp_directory_path() / ("chromasim_cli_bad_out_" + std::to_string(::getpid()));
    fs::remove_all(out);
    const Run r = run_chromasim("generate " + spec.string() + " -o " + out.string());
    INFO(r.output);
    CHECK(r.code == 2);
    CHECK(r.output.find("chromasim_bad.yaml:3:13") != std::string::npos);
    CHECK(r.output.find("render.width_px") != std::string::npos);
    CHECK(r.output.find("'-3'") != std::string::npos);
    CHECK(r.output.find("[16, 4096]") != std::string::npos);
    CHECK_FALSE(fs::exists(out));
    CHECK(r.output.find("dome mesh") == std::string::npos); // no meshing was started
    fs::remove(spec);
}

TEST_CASE("validate reports a typo with its position and a suggestion", "[generators][cli]") {
    const fs::path spec = write_spec("chromasim_typo.yaml", "friction:\n  - muu: 0.5\n");
    const Run r = run_chromasim("validate " + spec.string());
    INFO(r.output);
    CHECK(r.code == 2);
    CHECK(r.output.find("chromasim_typo.yaml:2:5") != std::string::npos);
    CHECK(r.output.find("did you mean 'mu'") != std::string::npos);
    fs::remove(spec);
}

TEST_CASE("bad command lines are refused with usage help", "[generators][cli]") {
    CHECK(run_chromasim("").code != 0);
    CHECK(run_chromasim("frobnicate").code != 0);
    const Run missing_out = run_chromasim("generate datasets_spec/quickstart.yaml");
    CHECK(missing_out.code != 0);
    CHECK(missing_out.output.find("--output") != std::string::npos);
    const Run threads = run_chromasim("--threads -2 validate datasets_spec/quickstart.yaml");
    CHECK(threads.code != 0);
    const Run nofile = run_chromasim("validate /nonexistent/spec.yaml");
    CHECK(nofile.code == 2);
    CHECK(nofile.output.find("/nonexistent/spec.yaml") != std::string::npos);
}

TEST_CASE("spec-doc (and its old name schema) prints the documented key table",
          "[generators][cli]") {
    const Run r = run_chromasim("spec-doc");
    CHECK(r.code == 0);
    CHECK(r.output.find("`render.samples_per_pixel`") != std::string::npos);
    CHECK(r.output.find("chromasim spec-doc > docs/SPEC.md") != std::string::npos);
    const Run old = run_chromasim("schema");
    CHECK(old.code == 0);
    CHECK(old.output == r.output);
}

// It reuses the cache; the frame refused is one out of range.
TEST_CASE("export-scene writes any frame as glTF and refuses a bad frame or output before any work",
          "[generators][cli][gltf]") {
    const fs::path dir =
        fs::temp_directory_path() / ("chromasim_cli_export_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    const fs::path spec = write_spec(
        "chromasim_export.yaml",
        "name: export\nsensor: {mesh_level: coarse, element_order: 1}\n"
        "render: {width_px: 64, height_px: 48}\n"
        "fingers: {count: 1}\n"
        "protocol: {frame_rate_Hz: 1, grip_N: 1.0, grasp_s: 2, hold_s: 0, load_rate_N_per_s: "
        "0.3, target_load_N: 0.3}\n");
    const auto export_frame = [&](int frame, const std::string& file) {
        return run_chromasim("export-scene " + spec.string() + " --frame " + std::to_string(frame) +
                             " -o " + (dir / file).string() + " --cache-dir " +
                             (dir / "cache").string());
    };
    using chromasim::generators::GltfScene;
    const auto number = [](const GltfScene& s, const char* key) {
        return std::get<double>(s.extras.at(key));
    };
    const auto text = [](const GltfScene& s, const char* key) {
        return std::get<std::string>(s.extras.at(key));
    };

    // The last frame (after the two press frames) as .glb; computes and stores the model.
    const Run last = export_frame(2, "last.glb");
    INFO(last.output);
    REQUIRE(last.code == 0);
    CHECK(last.output.find("cache: miss") != std::string::npos);
    const GltfScene scene = chromasim::generators::read_gltf_scene(dir / "last.glb").scene;
    std::vector<std::string> names;
    for (const auto& m : scene.meshes)
        names.push_back(m.name);
    CHECK(names == std::vector<std::string>{"coating", "inner_surface", "inner_markers",
                                            "outer_markers", "leds", "frame", "lens_barrel"});
    CHECK(scene.meshes[0].surface.V.rows() > 100);
    CHECK(scene.meshes[2].surface.F.rows() == 82 * 48); // 82 prisms of 48 triangles per layer
    CHECK(scene.meshes[3].surface.F.rows() == 82 * 48);
    CHECK(scene.meshes[4].surface.F.rows() == 6 * 2); // 6 LED rectangles
    CHECK(scene.lights.empty());
    REQUIRE(scene.camera.has_value());
    CHECK(scene.camera->aspect_ratio == Approx(64.0 / 48.0));
    CHECK(number(scene, "frame") == 2.0);
    CHECK(text(scene, "phase") == "load");
    CHECK(text(scene, "finger") == "left");
    CHECK(number(scene, "trial") == 0.0);
    CHECK(number(scene, "normal_force_N") == Approx(1.0));
    CHECK(number(scene, "tangential_force_x_N") == Approx(0.3));
    CHECK(number(scene, "converged") == 1.0);
    const std::string spec_sha = text(scene, "spec_sha256"); // as a dataset's manifest has it
    CHECK(spec_sha.size() == 64);
    CHECK(spec_sha.find_first_not_of("0123456789abcdef") == std::string::npos);

    // The first frame as .gltf, from the cache; half the force: the apex (highest y) is less
    // pushed in.
    const Run first = export_frame(0, "first.gltf");
    INFO(first.output);
    REQUIRE(first.code == 0);
    CHECK(first.output.find("cache: hit") != std::string::npos);
    const GltfScene scene0 = chromasim::generators::read_gltf_scene(dir / "first.gltf").scene;
    CHECK(text(scene0, "phase") == "grasp");
    CHECK(number(scene0, "normal_force_N") == Approx(0.5));
    CHECK(scene0.meshes[0].surface.V.col(1).maxCoeff() >
          scene.meshes[0].surface.V.col(1).maxCoeff() + 0.05);

    // Out of range: named, with the allowed range; no meshing started, nothing written.
    const Run range = export_frame(3, "range.glb");
    INFO(range.output);
    CHECK(range.code != 0);
    CHECK(range.output.find("--frame 3") != std::string::npos);
    CHECK(range.output.find("[0, 2]") != std::string::npos);
    CHECK(range.output.find("dome mesh") == std::string::npos);
    CHECK_FALSE(fs::exists(dir / "range.glb"));
    const Run trial = run_chromasim("export-scene " + spec.string() + " --trial 1 --frame 0 -o " +
                                    (dir / "trial.glb").string());
    CHECK(trial.code != 0);
    CHECK(trial.output.find("--trial 1") != std::string::npos);
    CHECK(trial.output.find("[0, 0]") != std::string::npos);
    const Run finger = run_chromasim("export-scene " + spec.string() +
                                     " --finger right --frame 0 -o " + (dir / "f.glb").string());
    CHECK(finger.code != 0);
    CHECK(finger.output.find("--finger right is out of range") != std::string::npos);
    const Run obj = export_frame(0, "scene.obj");
    CHECK(obj.code != 0);
    CHECK(obj.output.find((dir / "scene.obj").string()) != std::string::npos);
    CHECK(obj.output.find(".glb") != std::string::npos);
    CHECK(obj.output.find("dome mesh") == std::string::npos);
    CHECK_FALSE(fs::exists(dir / "scene.obj"));
    fs::remove_all(dir);
    fs::remove(spec);
}

TEST_CASE("validate counts what a spec describes and generate --max-trials runs a slice as its own "
          "dataset",
          "[generators][cli]") {
    const Run v = run_chromasim("validate datasets_spec/seed000_train.yaml "
                                "datasets_spec/seed001_sliding.yaml");
    INFO(v.output);
    CHECK(v.code == 0);
    CHECK(v.output.find("seed000_train.yaml: ok (96 trials, ") != std::string::npos);
    CHECK(v.output.find("seed001_sliding.yaml: ok (336 trials, 10080 frames, 0 images)") !=
          std::string::npos);

    const fs::path out =
        fs::temp_directory_path() / ("chromasim_cli_slice_" + std::to_string(::getpid()));
    fs::remove_all(out);
    const std::string generate =
        "generate datasets_spec/seed001_sliding.yaml -q -o " + out.string();
    const Run slice = run_chromasim(generate + " --max-trials 1");
    INFO(slice.output);
    REQUIRE(slice.code == 0);
    CHECK(slice.output.find("wrote 1 of 336 trials, 30 frames") != std::string::npos);
    std::ifstream manifest_file(out / "manifest.json");
    const auto manifest = nlohmann::json::parse(manifest_file);
    CHECK(manifest["counts"]["trials"] == 1);
    CHECK(manifest["planned_trials"] == 336);
    CHECK(manifest["slice"]["max_trials"] == 1);
    // The same slice again is up to date; the whole spec is another dataset, refused.
    CHECK(run_chromasim(generate + " --max-trials 1").output.find("nothing to do") !=
          std::string::npos);
    const Run whole = run_chromasim(generate);
    CHECK(whole.code == 2);
    CHECK(whole.output.find("other content") != std::string::npos);
    fs::remove_all(out);
}
