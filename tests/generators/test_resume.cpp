// Nothing lost, nothing corrupt: manifest.json's checksums, byte-identical datasets for any
// thread count, and a generation killed (SIGKILL) at every kind of write step that --resume
// finishes into the dataset an uninterrupted run writes. Drives the executable as a user does.
#include "generators/io/file_io.hpp"

#include "run_chromasim.hpp"
#include "scratch_dir.hpp"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <cstdlib>
#include <filesystem>
#include <map>
#include <string>

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

namespace fs = std::filesystem;
using chromasim::generators::read_file;
using chromasim::generators::sha256_file;

namespace {

/// Two tiny trials (one per split), both fingers, every kind of output: PNG, EXR, labels,
/// markers, strain.
constexpr const char* kSpec = R"(name: resume
seed: 7
sensor: {mesh_level: coarse, element_order: 1}
render: {width_px: 40, height_px: 40, samples_per_pixel: 1, integrator: preview}
objects: [{name: flat, shape: flat}, {name: curved, shape: sphere, radius_mm: 45}]
friction: [{name: m, mu: 0.8}]
protocol: {frame_rate_Hz: 1, grip_N: 1.0, grasp_s: 2, hold_s: 1, load_rate_N_per_s: 0.6,
           target_load_N: 0.6, slip_frames: 0}
splits: [{name: train, fraction: 0.5}, {name: test, fraction: 0.5}]
outputs: {images: true, exr: true, labels: true, markers: true, strain: true}
)";

/// A scratch folder with the spec, a mechanics cache and an uninterrupted reference dataset.
struct Fixture {
    ScratchDir dir;
    fs::path spec, ref;
    std::map<std::string, std::string> ref_tree;
    nlohmann::json manifest;
    explicit Fixture(const std::string& name) : dir(name) {
        spec = dir.write("resume.yaml", kSpec);
        ref = dir.path / "ref";
        const Run r = generate(ref, "--threads 2");
        INFO(r.output);
        REQUIRE(r.code == 0);
        ref_tree = tree(ref);
        manifest = nlohmann::json::parse(read_file(ref / "manifest.json"));
    }
    /// `chromasim GLOBAL generate SPEC -q -o OUT --cache-dir C OPTIONS`, with `env` set.
    Run generate(const fs::path& out, const std::string& global = "",
                 const std::string& options = "", const std::string& env = "",
                 const fs::path& spec_file = {}) const {
        return run_chromasim(
            dir,
            global + " generate " + (spec_file.empty() ? spec : spec_file).string() + " -q -o " +
                out.string() + " --cache-dir " + (dir.path / "cache").string() + " " + options,
            env);
    }
    /// Frames of trial 0 (its left PNGs in the manifest).
    int first_trial_frames() const {
        int n = 0;
        for (const auto& [path, sha] : manifest["files"].items())
            n += path.find("trial_000000/left_") != std::string::npos && path.ends_with(".png");
        return n;
    }
    /// Runs with CHROMASIM_TEST_KILL_AT=kill_at (and `options`); requires the kill.
    void kill(const fs::path& out, int kill_at, const std::string& options = "") const {
        const Run r =
            generate(out, "", options, "CHROMASIM_TEST_KILL_AT=" + std::to_string(kill_at));
        INFO(r.output);
        REQUIRE(r.code == 128 + 9); // SIGKILL
    }
    /// Resumes; requires success and the reference's bytes, file by file.
    void resume_matches(const fs::path& out, const std::string& global = "") const {
        const Run r = generate(out, global, "--resume");
        INFO(r.output);
        REQUIRE(r.code == 0);
        CHECK(tree(out) == ref_tree);
        CHECK_FALSE(fs::exists(partial(out)));
    }
    fs::path partial(const fs::path& out) const { return out.string() + ".partial"; }
    /// Write steps of an uninterrupted run: each frame, each trial's record, the assembly.
    int steps() const {
        return manifest["counts"]["frames"].get<int>() + manifest["counts"]["trials"].get<int>() +
               1;
    }
};

} // namespace

TEST_CASE("SHA-256 of known strings, and write errors name the file and the OS's reason",
          "[generators][resume]") {
    using namespace chromasim::generators;
    CHECK(sha256_hex("") == "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
    CHECK(sha256_hex("abc") == "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
    // A full disk, at the file level: /dev/full accepts the open and fails every write.
    if (fs::exists("/dev/full")) {
        try {
            write_file("/dev/full", std::string(1 << 16, 'x'));
            FAIL("no error writing to /dev/full");
        } catch (const std::runtime_error& e) {
            CHECK_THAT(e.what(), Catch::Contains("/dev/full"));
            CHECK_THAT(e.what(), Catch::Contains("No space left on device"));
        }
    } else {
        WARN("no /dev/full on this system: the full-disk write error is not checked");
    }
    ScratchDir dir("file_io");
    const fs::path file = dir.write("a_file", "x");
    try {
        write_file_atomic(file / "sub.txt", "y");
        FAIL("no error writing under a regular file");
    } catch (const std::runtime_error& e) {
        CHECK_THAT(e.what(), Catch::Contains((file / "sub.txt.tmp").string()));
        CHECK_THAT(e.what(), Catch::Contains("Not a directory"));
    }
    write_file_atomic(dir.path / "b.txt", "hello");
    CHECK(read_file(dir.path / "b.txt") == "hello");
    CHECK_FALSE(fs::exists(dir.path / "b.txt.tmp"));
}

// The manifest also holds the counts per split.
TEST_CASE("manifest.json lists every file's SHA-256 and the dataset is byte-identical on 1 and 2 "
          "threads",
          "[generators][resume]") {
    const Fixture f("manifest");
    const nlohmann::json& m = f.manifest;
    // Every file but the manifest itself, with its checksum; nothing else in the folder.
    std::map<std::string, std::string> listed =
        m["files"].get<std::map<std::string, std::string>>();
    std::map<std::string, std::string> on_disk = f.ref_tree;
    on_disk.erase("manifest.json");
    CHECK(listed == on_disk);
    CHECK(on_disk.count("labels.csv") == 1);
    CHECK(on_disk.count("markers.csv") == 1);
    CHECK(on_disk.count("spec.resolved.yaml") == 1);
    for (const auto& [path, sha] : on_disk) {
        INFO(path);
        CHECK(path.find("_progress") == std::string::npos);
        CHECK(path.find(".tmp") == std::string::npos);
    }
    CHECK(m["spec"]["sha256"] ==
          chromasim::generators::sha256_hex(read_file(f.ref / "spec.resolved.yaml")));
    CHECK(m["spec"]["resolved_yaml"] == read_file(f.ref / "spec.resolved.yaml"));
    CHECK(m["chromasim_version"] == CHROMASIM_VERSION);
    CHECK(m["instruction_set"] == CHROMASIM_ARCH);
    for (const char* dep :
         {"embree", "openimageio", "openexr", "eigen", "yaml-cpp", "tbb", "tinygltf"}) {
        INFO(dep);
        CHECK_FALSE(m["dependencies"][dep].get<std::string>().empty());
    }
    // Counts: two trials, one per split; two images (PNG and EXR) per finger and frame.
    const int frames = m["counts"]["frames"];
    CHECK(m["counts"]["trials"] == 2);
    CHECK(frames >= 6);
    CHECK(m["counts"]["images"] == 2 * 2 * frames);
    int split_frames = 0, pngs = 0;
    for (const char* split : {"train", "test"}) {
        CHECK(m["splits"][split]["trials"] == 1);
        split_frames += m["splits"][split]["frames"].get<int>();
    }
    CHECK(split_frames == frames);
    for (const auto& [path, sha] : on_disk)
        pngs += path.ends_with(".png");
    CHECK(pngs == 2 * frames);
    // No clock in it: the same spec on 1 and on 2 threads gives the same bytes, every file.
    for (const char* threads : {"--threads 1", "--threads 2"}) {
        const fs::path out = f.dir.path / (std::string("out") + threads[10]);
        const Run r = f.generate(out, threads);
        INFO(threads << "\n" << r.output);
        REQUIRE(r.code == 0);
        CHECK(tree(out) == f.ref_tree);
    }
}

TEST_CASE("a generation killed at any kind of write step and resumed is byte-identical to an "
          "uninterrupted run",
          "[generators][resume]") {
    const Fixture f("kill");
    const int steps = f.steps(), first = f.first_trial_frames();
    REQUIRE(first >= 2);
    REQUIRE(first + 1 < steps - 1);
    // Inside trial 0, at its last frame (record not yet written), right after its record,
    // inside trial 1, after the last record, and after the assembly (before the rename).
    for (const int kill_at : {1, 2, first, first + 1, first + 2, steps - 1, steps}) {
        INFO("killed at write step " << kill_at << " of " << steps);
        const fs::path out = f.dir.path / ("out_" + std::to_string(kill_at));
        f.kill(out, kill_at);
        CHECK_FALSE(fs::exists(out)); // nothing that looks like a dataset
        REQUIRE(fs::is_directory(f.partial(out)));
        // Without --resume: refused, both ways out named, nothing touched.
        const auto before = tree(f.partial(out));
        const Run refused = f.generate(out);
        INFO(refused.output);
        CHECK(refused.code == 2);
        CHECK_THAT(refused.output, Catch::Contains(f.partial(out).string()));
        CHECK_THAT(refused.output, Catch::Contains("--resume"));
        CHECK_THAT(refused.output, Catch::Contains("--overwrite"));
        CHECK(tree(f.partial(out)) == before);
        f.resume_matches(out, kill_at % 2 ? "--threads 1" : "--threads 2");
    }
    // Killed again while resuming (trial 1 redone and killed again), then resumed.
    const fs::path twice = f.dir.path / "twice";
    f.kill(twice, first + 2);
    f.kill(twice, 1, "--resume");
    f.resume_matches(twice);
}

// A trial whose files do not match their checksums is redone; --overwrite starts over.
TEST_CASE("resume redoes a damaged trial and refuses another spec or a running generation",
          "[generators][resume]") {
    const Fixture f("resume_checks");
    const int first = f.first_trial_frames();

    // A completed trial's image damaged after the kill (a disk error, a stray edit): redone.
    const fs::path damaged = f.dir.path / "damaged";
    f.kill(damaged, first + 2);
    const auto images = [&] {
        std::vector<fs::path> v;
        for (const auto& e : fs::recursive_directory_iterator(f.partial(damaged) / "images"))
            if (e.path().string().find("trial_000000/left_000000.png") != std::string::npos)
                v.push_back(e.path());
        return v;
    }();
    REQUIRE(images.size() == 1);
    chromasim::generators::write_file(images[0], "not a png");
    f.resume_matches(damaged);

    // Another spec (another seed): refused, naming the stored spec; the partial folder kept.
    const fs::path other = f.dir.path / "other";
    f.kill(other, 2);
    const fs::path seed_spec = f.dir.write("seed8.yaml", [] {
        std::string t = kSpec;
        t.replace(t.find("seed: 7"), 7, "seed: 8");
        return t;
    }());
    const Run mismatch = f.generate(other, "", "--resume", "", seed_spec);
    INFO(mismatch.output);
    CHECK(mismatch.code == 2);
    CHECK_THAT(mismatch.output,
               Catch::Contains((f.partial(other) / "spec.resolved.yaml").string()));
    CHECK_THAT(mismatch.output, Catch::Contains("another resolved spec"));
    CHECK(fs::is_directory(f.partial(other)));
    // --overwrite discards the interrupted run and writes the reference anew.
    const Run over = f.generate(other, "", "--overwrite");
    INFO(over.output);
    REQUIRE(over.code == 0);
    CHECK(tree(other) == f.ref_tree);
    CHECK_FALSE(fs::exists(f.partial(other)));

    // A generation holding the lock (this test holds it, as a running chromasim would).
    const fs::path locked = f.dir.path / "locked";
    f.kill(locked, 2);
    const int fd = ::open((f.partial(locked) / "lock").c_str(), O_RDWR);
    REQUIRE(fd >= 0);
    REQUIRE(::flock(fd, LOCK_EX | LOCK_NB) == 0);
    const Run busy = f.generate(locked, "", "--resume");
    INFO(busy.output);
    CHECK(busy.code == 2);
    CHECK_THAT(busy.output, Catch::Contains("another chromasim process"));
    const Run busy_plain = f.generate(locked); // running, not interrupted: the same answer
    INFO(busy_plain.output);
    CHECK(busy_plain.code == 2);
    CHECK_THAT(busy_plain.output, Catch::Contains("another chromasim process"));
    ::close(fd);
    f.resume_matches(locked);
}

TEST_CASE("an unwritable output path is refused with the path and the OS's reason and leaves "
          "nothing",
          "[generators][resume]") {
    const Fixture f("unwritable");
    // Under a regular file: fails for root too.
    const fs::path file = f.dir.write("plain_file", "x");
    const Run under_file = f.generate(file / "out");
    INFO(under_file.output);
    CHECK(under_file.code != 0);
    CHECK_THAT(under_file.output, Catch::Contains(file.string()));
    CHECK_THAT(under_file.output, Catch::Contains("Not a directory"));
    CHECK(read_file(file) == "x");
    // A write error in the middle of a run (here a file where trial 1's strain folder goes):
    // the error names the path and the reason, no dataset appears, the complete trial is kept,
    // and once the cause is gone --resume finishes the reference's bytes.
    const fs::path out = f.dir.path / "blocked";
    f.kill(out, f.first_trial_frames() + 2);
    fs::remove_all(f.partial(out) / "strain" / "test");
    const fs::path blocker = f.partial(out) / "strain" / "test";
    chromasim::generators::write_file(blocker, "in the way");
    const Run blocked = f.generate(out, "", "--resume");
    INFO(blocked.output);
    CHECK(blocked.code == 1);
    CHECK_THAT(blocked.output, Catch::Contains((blocker / "trial_000001").string()));
    CHECK_THAT(blocked.output, Catch::Contains("Not a directory"));
    CHECK_THAT(blocked.output, Catch::Contains("1 complete trial(s) are kept"));
    CHECK_FALSE(fs::exists(out));
    fs::remove(blocker);
    f.resume_matches(out);
    // A read-only folder: chmod does not stop root, so only checked as another user.
    if (::geteuid() == 0) {
        WARN("running as root, which chmod does not stop from writing: the read-only folder "
             "case is skipped (the regular-file case above covers the error path)");
    } else {
        const fs::path ro = f.dir.path / "read_only";
        fs::create_directories(ro);
        fs::permissions(ro, fs::perms::owner_read | fs::perms::owner_exec);
        const Run denied = f.generate(ro / "out");
        fs::permissions(ro, fs::perms::owner_all);
        INFO(denied.output);
        CHECK(denied.code != 0);
        CHECK_THAT(denied.output, Catch::Contains((ro / "out.partial").string()));
        CHECK_THAT(denied.output, Catch::Contains("Permission denied"));
        CHECK(fs::is_empty(ro));
    }
}

// A run killed between moving the replaced dataset aside and moving the new one in leaves
// DIR.old-<pid>; the resumed run removes it once the new dataset is in place.
TEST_CASE("resume removes the DIR.old-<pid> left by a run killed between its two renames",
          "[generators][resume]") {
    const Fixture f("old_copy");
    const fs::path out = f.dir.path / "out";
    f.kill(out, f.steps()); // assembled, not yet renamed: the state between the two renames
    const fs::path stale = out.string() + ".old-4242", other = out.string() + ".old-x1";
    for (const fs::path& p : {stale, other}) {
        fs::create_directories(p / "images");
        chromasim::generators::write_file_atomic(p / "labels.csv", "the replaced dataset\n");
    }
    f.resume_matches(out);
    CHECK_FALSE(fs::exists(stale));
    CHECK(fs::exists(other / "labels.csv")); // not of the form DIR.old-<digits>: not ours
}
