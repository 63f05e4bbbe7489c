// Sharded runs: `generate --shard K/N` writes disjoint parts (round robin over the plan's
// trials), `merge` joins them into the bytes of an unsharded run, manifest.json included, and
// refuses (naming what is wrong, leaving nothing) parts that do not make one dataset. Drives
// the executable as a user does.
#include "generators/io/file_io.hpp"

#include "run_chromasim.hpp"
#include "scratch_dir.hpp"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using chromasim::generators::read_file;

namespace {

/// Three tiny trials (random sampling: shard 1/2 holds trials 0 and 2, shard 2/2 trial 1), both
/// fingers, every kind of output: PNG, EXR, labels, markers, strain.
constexpr const char* kSpec = R"(name: shard
seed: 7
sensor: {mesh_level: coarse, element_order: 1}
render: {width_px: 32, height_px: 32, samples_per_pixel: 1, integrator: preview}
objects: [{name: flat, shape: flat}, {name: curved, shape: sphere, radius_mm: 45}]
friction: [{name: m, mu: 0.8}]
sampling: {method: random, trials: 3}
protocol: {frame_rate_Hz: 1, grip_N: 1.0, grasp_s: 1, hold_s: 1, load_rate_N_per_s: 0.6,
           target_load_N: 0.6, slip_frames: 0}
splits: [{name: train, fraction: 0.5}, {name: test, fraction: 0.5}]
outputs: {images: true, exr: true, labels: true, markers: true, strain: true}
)";

/// A scratch folder with the spec, a mechanics cache, and the unsharded reference dataset.
struct Fixture {
    ScratchDir dir;
    fs::path spec, ref;
    std::map<std::string, std::string> ref_tree;
    explicit Fixture(const std::string& name, bool reference = true) : dir(name) {
        spec = dir.write("shard.yaml", kSpec);
        ref = dir.path / "ref";
        if (!reference) return;
        const Run r = generate(ref, "", "", {}, 2); // the parts run on 1 thread
        INFO(r.output);
        REQUIRE(r.code == 0);
        ref_tree = tree(ref);
    }
    /// `chromasim --threads T generate SPEC -q -o OUT --cache-dir C OPTIONS`, with `env` set.
    Run generate(const fs::path& out, const std::string& options = "", const std::string& env = "",
                 const fs::path& spec_file = {}, int threads = 1) const {
        return run_chromasim(dir,
                             "--threads " + std::to_string(threads) + " generate " +
                                 (spec_file.empty() ? spec : spec_file).string() + " -q -o " +
                                 out.string() + " --cache-dir " + (dir.path / "cache").string() +
                                 " " + options,
                             env);
    }
    /// Writes part K/N to `out`; requires success.
    fs::path part(const std::string& name, const std::string& shard,
                  const fs::path& spec_file = {}) const {
        const fs::path out = dir.path / name;
        const Run r = generate(out, "--shard " + shard, "", spec_file);
        INFO(r.output);
        REQUIRE(r.code == 0);
        return out;
    }
    Run merge(const std::vector<fs::path>& parts, const fs::path& out,
              const std::string& options = "") const {
        std::string args = "merge";
        for (const fs::path& p : parts)
            args.append(" ").append(p.string());
        return run_chromasim(dir, args + " -o " + out.string() + " " + options);
    }
    /// Merges `parts`; requires success and the reference's bytes, file by file.
    void merge_matches(const std::vector<fs::path>& parts, const fs::path& out) const {
        const Run r = merge(parts, out);
        INFO(r.output);
        REQUIRE(r.code == 0);
        CHECK(tree(out) == ref_tree);
        CHECK_FALSE(fs::exists(out.string() + ".partial"));
    }
    /// Merges `parts`; requires a refusal naming `what`, and nothing written.
    void merge_refused(const std::vector<fs::path>& parts, const std::string& what) const {
        const fs::path out = dir.path / "refused";
        const Run r = merge(parts, out);
        INFO(r.output);
        CHECK(r.code == 2);
        CHECK_THAT(r.output, Catch::Contains(what));
        CHECK_FALSE(fs::exists(out));
        CHECK_FALSE(fs::exists(out.string() + ".partial"));
    }
};

nlohmann::json part_json(const fs::path& part) {
    return nlohmann::json::parse(read_file(part / "part.json"));
}

/// The trial folders (trial_TTTTTT) that hold images in `root`.
std::vector<std::string> image_trials(const fs::path& root) {
    std::vector<std::string> trials;
    if (!fs::exists(root / "images")) return trials;
    for (const auto& split : fs::directory_iterator(root / "images"))
        for (const auto& trial : fs::directory_iterator(split.path()))
            trials.push_back(trial.path().filename().string());
    std::sort(trials.begin(), trials.end());
    return trials;
}

} // namespace

// The parts are disjoint and round-robin; 2 and 4 shards (one of them empty), resumed or not.
TEST_CASE("generate --shard K/N writes parts that merge into the unsharded dataset byte for byte",
          "[generators][shard]") {
    const Fixture f("shard_merge");
    REQUIRE(nlohmann::json::parse(read_file(f.ref / "manifest.json"))["counts"]["trials"] == 3);

    // 2 shards: round robin, 1/2 holds trials 0 and 2, 2/2 trial 1. Part 2/2 is killed at its
    // first frame; --resume with another shard is refused, with its own finishes it.
    const fs::path p1 = f.part("p1of2", "1/2");
    const fs::path p2 = f.dir.path / "p2of2";
    const Run killed = f.generate(p2, "--shard 2/2", "CHROMASIM_TEST_KILL_AT=1");
    INFO(killed.output);
    REQUIRE(killed.code == 128 + 9);
    const Run other_shard = f.generate(p2, "--shard 1/2 --resume");
    INFO(other_shard.output);
    CHECK(other_shard.code == 2);
    CHECK_THAT(other_shard.output, Catch::Contains("--shard 2/2"));
    const Run unsharded = f.generate(p2, "--resume");
    INFO(unsharded.output);
    CHECK(unsharded.code == 2);
    CHECK_THAT(unsharded.output, Catch::Contains("--shard 2/2"));
    const Run resumed = f.generate(p2, "--shard 2/2 --resume");
    INFO(resumed.output);
    REQUIRE(resumed.code == 0);
    CHECK(image_trials(p1) == std::vector<std::string>{"trial_000000", "trial_000002"});
    CHECK(image_trials(p2) == std::vector<std::string>{"trial_000001"});
    CHECK(part_json(p1)["trials"] == nlohmann::json::array({0, 2}));
    CHECK(part_json(p2)["shard"] == nlohmann::json({{"index", 2}, {"count", 2}}));
    CHECK(part_json(p2)["instruction_set"] == CHROMASIM_ARCH);
    for (const fs::path& p : {p1, p2}) {
        INFO(p);
        // What merge needs, not what it writes; the resolved spec is the dataset's, unsharded.
        CHECK(read_file(p / "spec.resolved.yaml") == read_file(f.ref / "spec.resolved.yaml"));
        CHECK(fs::exists(p / "_progress"));
        for (const char* whole : {"labels.csv", "markers.csv", "manifest.json"})
            CHECK_FALSE(fs::exists(p / whole));
        CHECK_FALSE(fs::exists(p.string() + ".partial"));
    }
    // A complete part is up to date; its files stay as they were after a merge (linked, not
    // moved).
    const Run again = f.generate(p1, "--shard 1/2");
    INFO(again.output);
    CHECK(again.code == 0);
    CHECK_THAT(again.output, Catch::Contains("already holds this part"));
    const auto p1_tree = tree(p1);
    f.merge_matches({p2, p1}, f.dir.path / "merged2");
    CHECK(tree(p1) == p1_tree);
    const Run merged_again = f.merge({p1, p2}, f.dir.path / "merged2");
    INFO(merged_again.output);
    CHECK(merged_again.code == 0);
    CHECK_THAT(merged_again.output, Catch::Contains("nothing to do"));

    // 4 shards of 3 trials: shard 4/4 owns no trial and is a valid, empty part.
    std::vector<fs::path> parts4;
    for (const char* k : {"1", "2", "3", "4"})
        parts4.push_back(f.part(std::string("p") + k + "of4", std::string(k) + "/4"));
    CHECK(part_json(parts4[3])["trials"] == nlohmann::json::array());
    CHECK(image_trials(parts4[3]).empty());
    f.merge_matches({parts4[3], parts4[1], parts4[0], parts4[2]}, f.dir.path / "merged4");
}

// A missing, duplicate or incomplete shard; parts of another spec, shard count or instruction
// set; a damaged file.
TEST_CASE("merge refuses a missing or mismatched or damaged shard by name and writes nothing",
          "[generators][shard]") {
    const Fixture f("shard_refuse", false);
    const fs::path p1 = f.part("p1", "1/2"), p2 = f.part("p2", "2/2");
    const auto p1_tree = tree(p1), p2_tree = tree(p2);

    f.merge_refused({p1}, "shard 2/2 is missing");
    f.merge_refused({p1, p1, p2}, "shard 1/2 is given twice");
    // Another spec (another seed): its part's spec.resolved.yaml is named.
    const fs::path seed8 = f.dir.write("seed8.yaml", [] {
        std::string t = kSpec;
        t.replace(t.find("seed: 7"), 7, "seed: 8");
        return t;
    }());
    const fs::path other = f.part("other", "2/2", seed8);
    f.merge_refused({p1, other}, (other / "spec.resolved.yaml").string());
    // Another shard count (4/4 owns no trial: quick to write).
    const fs::path of4 = f.part("of4", "4/4");
    f.merge_refused({p1, p2, of4}, (of4 / "part.json").string());
    // A part of a build for another instruction set (its part.json says so).
    const fs::path isa = f.dir.path / "isa";
    fs::copy(p2, isa, fs::copy_options::recursive);
    {
        std::string json = chromasim::generators::read_file(isa / "part.json");
        const std::string ours = "\"instruction_set\": \"" CHROMASIM_ARCH "\"";
        REQUIRE(json.find(ours) != std::string::npos);
        json.replace(json.find(ours), ours.size(), "\"instruction_set\": \"other-cpu\"");
        chromasim::generators::write_file(isa / "part.json", json);
    }
    f.merge_refused({p1, isa}, "built for instruction set other-cpu");
    f.merge_refused({p1, isa}, (isa / "part.json").string());
    // Incomplete: a shard killed at its first frame leaves PART.partial.
    const fs::path killed = f.dir.path / "killed";
    const Run k = f.generate(killed, "--shard 2/2", "CHROMASIM_TEST_KILL_AT=1");
    INFO(k.output);
    REQUIRE(k.code == 128 + 9);
    f.merge_refused({p1, killed}, "is not complete");
    f.merge_refused({p1, fs::path(killed.string() + ".partial")}, "unfinished part");
    f.merge_refused({p1, f.dir.path / "nowhere"}, "nowhere: does not exist");
    f.merge_refused({p1, f.ref.parent_path()}, "holds no part.json");
    // A damaged file in a copy of part 2: the file is named.
    const fs::path damaged = f.dir.path / "damaged";
    fs::copy(p2, damaged, fs::copy_options::recursive);
    fs::path image;
    for (const auto& e : fs::recursive_directory_iterator(damaged / "images"))
        if (e.path().filename() == "left_000001.png") image = e.path();
    REQUIRE_FALSE(image.empty());
    chromasim::generators::write_file(image, "not a png");
    f.merge_refused({p1, damaged}, image.string());
    // A part as the output, even with --overwrite.
    const Run self = f.merge({p1, p2}, p1, "--overwrite");
    INFO(self.output);
    CHECK(self.code == 2);
    CHECK_THAT(self.output, Catch::Contains("is both a part and the output"));
    // None of it touched the parts, and the good ones still merge.
    CHECK(tree(p1) == p1_tree);
    CHECK(tree(p2) == p2_tree);
    const Run ok = f.merge({p1, p2}, f.dir.path / "merged");
    INFO(ok.output);
    CHECK(ok.code == 0);
}

TEST_CASE("generate rejects a bad --shard value before any work, naming the argument and the "
          "value",
          "[generators][shard]") {
    const Fixture f("shard_args", false);
    for (const char* value : {"0/2", "3/2", "1/0", "a/b", "1-2", "1/2/3", "-1/2"}) {
        const fs::path out = f.dir.path / "out";
        const Run r = f.generate(out, std::string("'--shard=") + value + "'");
        INFO(value << "\n" << r.output);
        CHECK(r.code == 2);
        CHECK_THAT(r.output, Catch::Contains(std::string("--shard: value '") + value + "'"));
        CHECK_THAT(r.output, Catch::Contains("1 <= K <= N"));
        CHECK_FALSE(fs::exists(out));
        CHECK_FALSE(fs::exists(out.string() + ".partial"));
    }
    // An empty value is refused by the command-line parser itself, naming the option.
    const Run empty = f.generate(f.dir.path / "out", "--shard=");
    INFO(empty.output);
    CHECK(empty.code != 0);
    CHECK_THAT(empty.output, Catch::Contains("--shard"));
    CHECK_FALSE(fs::exists(f.dir.path / "out"));
}
