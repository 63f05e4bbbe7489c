// End to end: the quickstart spec through mechanics, render and writers, read back from disk.
#include "generators/io/image_io.hpp"
#include "generators/pipeline/generate.hpp"
#include "generators/pipeline/sensor_bridge.hpp"
#include "generators/plan/plan.hpp"
#include "generators/spec/spec.hpp"
#include "generators/spec/stage_params.hpp"

#include "test_files.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <sstream>
#include <vector>

#include <unistd.h>

namespace fs = std::filesystem;
using namespace chromasim::generators;
using namespace chromasim::generators::test;

namespace {

/// Options of a quiet run into `out`, everything else the default.
GenerateOptions quiet_to(const fs::path& out) {
    GenerateOptions options;
    options.out_dir = out;
    options.quiet = true;
    return options;
}

/// Pixel of a direction under the equidistant fisheye (the spec's 84 deg half field).
std::array<int, 2> pixel_of(double theta_deg, double phi_deg, int w, int h) {
    const double r = theta_deg / 84.0 * std::min(w, h) / 2.0;
    const double phi = phi_deg * M_PI / 180;
    return {int(w / 2.0 + r * std::cos(phi)), int(h / 2.0 + r * std::sin(phi))};
}

struct Quickstart {
    Spec spec = load_spec("datasets_spec/quickstart.yaml");
    Plan plan = make_plan(spec);
    fs::path out = fresh_dir("quickstart");
    GenerateReport report;
    Quickstart() {
        std::ostringstream log;
        report = generate(spec, quiet_to(out), log);
    }
    ~Quickstart() {
        std::error_code ec;
        fs::remove_all(out, ec);
    }
};
const Quickstart& quickstart() {
    static const Quickstart q;
    return q;
}

} // namespace

TEST_CASE("quickstart writes a complete dataset and nothing else", "[generators][e2e]") {
    const Quickstart& q = quickstart();
    const int frames = int(q.plan.frame_count());
    CHECK(q.report.trials == 2);
    CHECK(q.report.frames == frames);
    CHECK(q.report.images == 2 * frames); // left and right
    CHECK(q.report.flagged_frames == 0);
    for (const char* f : {"labels.csv", "markers.csv", "manifest.json", "spec.resolved.yaml"})
        CHECK(fs::is_regular_file(q.out / f));
    int pngs = 0;
    for (const auto& e : fs::recursive_directory_iterator(q.out / "images"))
        pngs += e.path().extension() == ".png";
    CHECK(pngs == 2 * frames);
    for (const TrialPlan& t : q.plan.trials) {
        char trial[32];
        std::snprintf(trial, sizeof trial, "trial_%06d", t.id);
        CHECK(fs::is_regular_file(q.out / "images" / t.split / trial / "left_000000.png"));
        CHECK(fs::is_regular_file(q.out / "images" / t.split / trial / "right_000000.png"));
    }
    for (const auto& e : fs::directory_iterator(q.out.parent_path()))
        CHECK(e.path().filename().string().find(q.out.filename().string() + ".partial") ==
              std::string::npos);
}

TEST_CASE("quickstart labels are finite, in range and follow the plan", "[generators][e2e]") {
    const Quickstart& q = quickstart();
    const auto rows = read_csv(q.out / "labels.csv");
    REQUIRE(rows.size() == q.plan.frame_count());
    std::size_t i = 0;
    for (const TrialPlan& t : q.plan.trials)
        for (const FramePlan& f : t.frames) {
            const CsvRow& r = rows[i++];
            INFO("trial " << t.id << " frame " << f.index);
            CHECK(r.at("split") == t.split);
            CHECK(std::stoi(r.at("trial")) == t.id);
            CHECK(std::stoi(r.at("frame")) == f.index);
            CHECK(num(r, "time_s") == Approx(f.time_s));
            CHECK(r.at("phase") == phase_name(f.phase));
            CHECK(r.at("object") == q.spec.objects[std::size_t(t.object)].name);
            CHECK(num(r, "load_N") == Approx(f.load_N));
            for (const std::string finger : {"left", "right"}) {
                const auto col = [&](const char* c) { return num(r, finger + "_" + c); };
                const double gamma = col("gamma"), fn = col("normal_force_N");
                CHECK(gamma >= 0.0);
                CHECK(gamma <= 1.0);
                CHECK(fn > 0.0);
                CHECK(col("indentation_mm") > 0.0);
                CHECK(col("contact_area_mm2") > 0.0);
                CHECK(r.at(finger + "_converged") == "1");
                CHECK(fs::is_regular_file(q.out / r.at(finger + "_image")));
            }
        }
    CHECK(num(rows.front(), "left_gamma") == 1.0); // grasp only: no tangential load
}

TEST_CASE("quickstart markers: 164 per finger and frame, apex pushed in, moved along each "
          "finger's own pull",
          "[generators][e2e]") {
    const Quickstart& q = quickstart();
    const auto rows = read_csv(q.out / "markers.csv");
    const std::size_t frames = q.plan.frame_count();
    REQUIRE(rows.size() == 164 * 2 * frames);
    for (const auto& r : rows)
        for (const char* k : {"x0_mm", "y0_mm", "z0_mm", "ux_mm", "uy_mm", "uz_mm"})
            num(r, k);
    // The last load frame (before slip) of the first trial: apex markers (marker 0) of both
    // layers moved down, and the outer one along the pull: +x for the left finger, -x for the
    // right one (it sees the object from the other side).
    const TrialPlan& t = q.plan.trials[0];
    int last_load = -1;
    for (const FramePlan& f : t.frames)
        if (f.phase == Phase::load) last_load = f.index;
    REQUIRE(last_load > 0);
    const std::size_t left = std::size_t(last_load) * 2 * 164, right = left + 164;
    CHECK(rows[left].at("finger") == "left");
    CHECK(rows[right].at("finger") == "right");
    CHECK(std::stoi(rows[left].at("frame")) == last_load);
    CHECK(rows[left].at("layer") == "inner");
    CHECK(rows[left + 82].at("layer") == "outer");
    CHECK(num(rows[left], "uz_mm") < -0.1);
    CHECK(num(rows[left + 82], "ux_mm") > 0.0);
    CHECK(num(rows[right + 82], "ux_mm") < 0.0);
}

TEST_CASE("quickstart images: right size, not blank, markers visible", "[generators][e2e]") {
    const Quickstart& q = quickstart();
    const int w = q.spec.render.width_px, h = q.spec.render.height_px;
    const auto rows = read_csv(q.out / "labels.csv");
    const Image8 img = read_image8(q.out / rows.front().at("left_image"));
    REQUIRE(img.width == w);
    REQUIRE(img.height == h);
    REQUIRE(img.channels == 3);
    // Outside the image circle: black. Inside: lit and not uniform.
    for (int c = 0; c < 3; ++c)
        CHECK(img.at(0, 0, c) == 0);
    double sum = 0, sum2 = 0;
    for (auto v : img.data) {
        sum += v;
        sum2 += double(v) * v;
    }
    const double mean = sum / img.data.size();
    CHECK(mean > 20);
    CHECK(std::sqrt(sum2 / img.data.size() - mean * mean) > 10);
    // Background between rings (polar 18.75 deg, between the 12.5 and 25 deg rings): near grey.
    const auto bg = pixel_of(18.75, 0, w, h);
    const int br = img.at(bg[0], bg[1], 0), bgc = img.at(bg[0], bg[1], 1),
              bb = img.at(bg[0], bg[1], 2);
    CHECK(br > 100);
    CHECK(std::abs(br - bb) < 30);
    // A marker of the first ring (12.5 deg, azimuth 0): the stacked magenta filter over the
    // cyan marker shows blue: red and green well below the background, blue the largest.
    const auto mk = pixel_of(12.5, 0, w, h);
    const int mr = img.at(mk[0], mk[1], 0), mg = img.at(mk[0], mk[1], 1),
              mb = img.at(mk[0], mk[1], 2);
    INFO("marker pixel " << mr << "," << mg << "," << mb << "  background " << br << "," << bgc
                         << "," << bb);
    CHECK(mb > mr + 20);
    CHECK(mb > mg + 10);
    CHECK(mr < br - 40);
}

TEST_CASE("generate again: up to date, nothing rewritten", "[generators][e2e]") {
    const Quickstart& q = quickstart();
    const auto before = fs::last_write_time(q.out / "labels.csv");
    std::ostringstream log;
    const GenerateReport again = generate(q.spec, quiet_to(q.out), log);
    CHECK(again.up_to_date);
    CHECK(again.frames == 0);
    CHECK(fs::last_write_time(q.out / "labels.csv") == before);
}

TEST_CASE("an output folder with other content is never overwritten silently",
          "[generators][e2e]") {
    const fs::path out = fresh_dir("occupied");
    fs::create_directories(out);
    std::ofstream(out / "precious.txt") << "user data";
    Spec spec = load_spec("datasets_spec/quickstart.yaml");
    std::ostringstream log;
    CHECK_THROWS_AS(generate(spec, quiet_to(out), log), SpecError);
    CHECK(fs::is_regular_file(out / "precious.txt"));
    CHECK(std::distance(fs::directory_iterator(out), fs::directory_iterator{}) == 1);
    fs::remove_all(out);
}

namespace {

/// Label rows of a labels-only run of `spec_text` (no images, no markers.csv written).
std::vector<CsvRow> labels_only(const std::string& spec_text) {
    const Spec spec =
        parse_spec(spec_text + "outputs: {images: false, markers: false}\n", "inline.yaml");
    const fs::path out = fresh_dir("labels_only");
    std::ostringstream log;
    generate(spec, quiet_to(out), log);
    const auto rows = read_csv(out / "labels.csv");
    CHECK_FALSE(fs::exists(out / "images"));
    CHECK_FALSE(fs::exists(out / "markers.csv"));
    fs::remove_all(out);
    return rows;
}

/// The folder of the first trial's images in a spec with the default single split.
const fs::path kFirstImage = fs::path("images") / "all" / "trial_000000";

/// One finger, `frames` grasp frames at 1 Hz to 1.5 N and nothing else: the load ramp's first
/// frame slips at once (100 N) and slip_frames 0 ends the trial before it.
std::string press_only(int frames) {
    return "fingers: {count: 1}\nprotocol: {frame_rate_Hz: 1, grip_N: 1.5, grasp_s: " +
           std::to_string(frames) +
           ", hold_s: 0, load_rate_N_per_s: 100, target_load_N: 100, slip_frames: 0}\n";
}

/// Indentation (mm) of one press frame of `object` (a YAML flow map).
double press_indentation(const std::string& object) {
    const auto rows = labels_only("name: s\nobjects: [" + object + "]\n" + press_only(1));
    REQUIRE(rows.size() == 1);
    return num(rows[0], "left_indentation_mm");
}

} // namespace

TEST_CASE("the spec's object reaches the mechanics: a sphere indents deeper than a flat",
          "[generators][e2e]") {
    const double flat = press_indentation("{shape: flat}");
    const double sphere = press_indentation("{shape: sphere, radius_mm: 45}");
    CHECK(sphere > flat * 1.01);
}

TEST_CASE("the spec's material model, load steps and interior reach the mechanics",
          "[generators]") {
    const Spec spec = parse_spec(
        "name: s\nsensor: {material_model: linear, contact_steps: 7, interior: rigid_core}\n",
        "inline.yaml");
    const chromasim::mechanics::DomeModelOptions o = dome_options(spec);
    CHECK(o.material == chromasim::mechanics::MaterialModel::linear);
    CHECK(o.load_path.normal_steps == 7);
    CHECK(o.load_path.tangential_steps == 7);
    CHECK(o.interior == chromasim::mechanics::DomeModelOptions::Interior::rigid_core);
    const chromasim::mechanics::DomeModelOptions d =
        dome_options(parse_spec("name: s\n", "x.yaml"));
    CHECK(d.material == chromasim::mechanics::MaterialModel::neo_hookean);
    CHECK(d.contact_candidate_angle_deg == 50);
    CHECK(d.load_path.normal_steps == 4);
}

// A missing or broken mesh file stops the run before any work.
TEST_CASE("a glTF mesh object from the spec presses like the analytic sphere it tessellates",
          "[generators][e2e]") {
    const std::string asset = CHROMASIM_SOURCE_DIR "/assets/objects/sphere_cap_r45.glb";
    const double sphere = press_indentation("{shape: sphere, radius_mm: 45}");
    const double mesh = press_indentation("{shape: mesh, mesh_file: '" + asset + "'}");
    CHECK(mesh == Approx(sphere).margin(0.0125)); // facets lie within 0.0125 mm of the sphere

    CHECK_THROWS_WITH(
        parse_spec("name: s\nobjects: [{shape: mesh, mesh_file: no/such.glb}]\n", "inline.yaml"),
        Catch::Contains("objects[0].mesh_file") && Catch::Contains("no existing file"));
    const fs::path dir = fresh_dir("broken_mesh");
    fs::create_directories(dir);
    std::ofstream(dir / "broken.glb") << "not a glTF file";
    std::ofstream(dir / "spec.yaml")
        << "name: s\nobjects: [{name: a}, {name: b, shape: mesh, mesh_file: broken.glb}]\n";
    // Read while the spec is checked, as validate does: refused at the key, nothing written.
    CHECK_THROWS_WITH(load_spec(dir / "spec.yaml"),
                      Catch::Contains("spec.yaml:2:") && Catch::Contains("objects[1].mesh_file") &&
                          Catch::Contains("not a usable object mesh (") &&
                          Catch::Contains("broken.glb"));
    CHECK_FALSE(fs::exists(dir / "out"));
    fs::remove_all(dir);
}

// The protocol of seed 001's sliding plate; the contact ends sliding.
TEST_CASE("a slide trial moves the object as asked while the force rises to mu f_n and the contact "
          "slides",
          "[generators][e2e]") {
    const auto rows = labels_only(
        "name: s\nfriction: [{mu: 0.5}]\nfingers: {count: 1}\n"
        "protocol: {type: slide, grip_N: 1.2, grasp_s: 0, hold_s: 0, slide: {start_mm: 0.25, "
        "end_mm: 2.0, frames: 8}}\n");
    REQUIRE(rows.size() == 8);
    double last_ft = 0;
    for (std::size_t i = 0; i < rows.size(); ++i) {
        CHECK(num(rows[i], "left_object_travel_x_mm") == Approx(0.25 + 1.75 * double(i) / 7));
        CHECK(num(rows[i], "left_requested_tangential_force_N") == 0.0);
        CHECK(num(rows[i], "left_tangential_force_N") >= last_ft - 1e-9);
        CHECK(num(rows[i], "left_converged") == 1.0);
        CHECK(rows[i].at("phase") == "slide");
        last_ft = num(rows[i], "left_tangential_force_N");
    }
    CHECK(last_ft == Approx(0.5 * 1.2).epsilon(1e-3));
    CHECK(num(rows.back(), "left_sliding") == 1.0);
    CHECK(num(rows.back(), "left_gamma") == 0.0);
    CHECK(num(rows.front(), "left_gamma") > 0.0);
}

namespace {
/// Centroid (x, y) of the nodal normal forces of a frame, mm.
Eigen::Vector2d force_centroid(const chromasim::mechanics::DomeModel& model,
                               const chromasim::mechanics::FrameResult& r) {
    Eigen::Vector2d c = Eigen::Vector2d::Zero();
    double total = 0;
    for (int j : r.contact.active) {
        const double f = -r.contact.forces_N(j, 2);
        const int node = model.candidate_nodes()[std::size_t(j)];
        c += f * model.mesh().V.row(node).head<2>().transpose();
        total += f;
    }
    return c / total;
}
} // namespace

TEST_CASE("object poses reach the mechanics: an offset sphere and a tilted flat touch where "
          "geometry says",
          "[generators][object]") {
    using namespace chromasim;
    const Spec base = parse_spec("name: pose\n", "pose.yaml");
    const mechanics::DomeModel model(dome_options(base));
    const mechanics::ContactLoad load{0.5, {0, 0}, 0.8};

    Spec sphere = parse_spec("objects:\n  - shape: sphere\n    offset_x_mm: 3\n", "pose.yaml");
    // First touch on the line between the centres: polar angle asin(3 / (13.2 + 45)).
    const mechanics::FrameResult s = model.solve(load, {}, object_shape(sphere, sphere.objects[0]));
    REQUIRE(s.contact.converged);
    // Margin: a tenth of the node spacing on the default very_coarse mesh's contact cap (about
    // 1 mm between the split faces' nodes).
    const Eigen::Vector2d cs = force_centroid(model, s);
    CHECK(cs.x() == Approx(13.2 * 3 / 58.2).margin(0.1));
    CHECK(std::abs(cs.y()) < 0.25);

    // A flat pitched by 20 deg (about y, counter-clockwise) faces along -z rotated to
    // (-sin 20, 0, -cos 20): it touches the dome where the dome's normal is opposite,
    // at polar angle 20 deg on the +x side.
    const Spec flat = parse_spec("objects:\n  - shape: flat\n    pitch_deg: 20\n", "pose.yaml");
    const mechanics::ObjectShape tilted = object_shape(flat, flat.objects[0]);
    CHECK(tilted.kind == mechanics::ObjectShape::Kind::mesh);
    const mechanics::FrameResult f = model.solve(load, {}, tilted);
    REQUIRE(f.contact.converged);
    const Eigen::Vector2d cf = force_centroid(model, f);
    CHECK(cf.x() == Approx(13.2 * std::sin(20 * std::numbers::pi / 180)).margin(0.2));
    CHECK(std::abs(cf.y()) < 0.25);
    // An untilted flat stays the analytic plane whatever its offset and yaw.
    const Spec moved = parse_spec("objects:\n  - offset_x_mm: 5\n    yaw_deg: 30\n", "pose.yaml");
    CHECK(object_shape(moved, moved.objects[0]).kind == mechanics::ObjectShape::Kind::flat);
    // A tilt that would leave the contact cap is refused when the spec is read.
    CHECK_THROWS_WITH(parse_spec("objects:\n  - shape: flat\n    roll_deg: 32\n", "pose.yaml"),
                      Catch::Contains("objects[0].pitch_deg") &&
                          Catch::Contains("sensor.contact_candidate_angle_deg"));
    CHECK_NOTHROW(parse_spec("objects:\n  - shape: flat\n    roll_deg: 29\n", "pose.yaml"));
    CHECK_THROWS_WITH(parse_spec("sensor: {contact_candidate_angle_deg: 25}\nobjects:\n"
                                 "  - shape: flat\n    roll_deg: 21\n",
                                 "pose.yaml"),
                      Catch::Contains("objects[0].pitch_deg"));
}

TEST_CASE("stage settings hold only what the outputs need: no optics without images",
          "[generators][spec]") {
    const StageSettings labels =
        stage_settings(parse_spec("outputs: {images: false}\n", "stages.yaml"));
    CHECK_FALSE(labels.optics.has_value());
    CHECK_FALSE(labels.sensor.has_value());
    const StageSettings images = stage_settings(parse_spec("name: stages\n", "stages.yaml"));
    REQUIRE(images.optics.has_value());
    CHECK(images.optics->spectra.has_value()); // the default sensor's spectra, read once
    CHECK_FALSE(images.sensor.has_value());    // render.sensor is off by default
    const StageSettings exr = stage_settings(parse_spec(
        "outputs: {images: false, exr: true}\nrender: {sensor: {enabled: true}}\n", "stages.yaml"));
    CHECK(exr.optics.has_value());
    CHECK_FALSE(exr.sensor.has_value()); // the EXR stays noise-free: no PNG to record
    const StageSettings noisy =
        stage_settings(parse_spec("render: {sensor: {enabled: true}}\n", "stages.yaml"));
    CHECK(noisy.sensor.has_value());
    CHECK(images.friction_names == std::vector<std::string>{Spec{}.friction[0].name});
    CHECK(images.objects.size() == 1);
    CHECK_FALSE(images.objects[0].mesh.has_value()); // a flat: no file to read
}

TEST_CASE("EXR output: linear RGB like the PNG, marker ids and variance channels on request",
          "[generators][e2e]") {
    const fs::path dir = fresh_dir("exr");
    fs::create_directories(dir);
    const fs::path spec_file = dir / "exr.yaml";
    {
        std::ofstream f(spec_file);
        f << "name: exr\nrender:\n  width_px: 64\n  height_px: 64\n  samples_per_pixel: 2\n  "
             "integrator: preview\n"
          << press_only(1)
          << "outputs:\n  exr: true\n  marker_ids: true\n  variance: true\n  markers: false\n";
    }
    const fs::path out = dir / "out";
    GenerateOptions options;
    options.out_dir = out;
    options.quiet = true;
    std::ostringstream log;
    generate(load_spec(spec_file), options, log);
    const ImageF exr = read_image_float(out / kFirstImage / "left_000000.exr");
    const Image8 png = read_image8(out / kFirstImage / "left_000000.png");
    REQUIRE(exr.width == 64);
    CHECK(exr.image_per_radiance > 0.0); // the exposure, to turn pixels back into radiance
    for (const char* c : {"R", "G", "B", "variance.R", "variance.G", "variance.B",
                          "inner_marker_id", "outer_marker_id"})
        CHECK(std::find(exr.channels.begin(), exr.channels.end(), c) != exr.channels.end());
    int inner_seen = 0;
    for (int y = 0; y < 64; ++y)
        for (int x = 0; x < 64; ++x) {
            // The PNG is the EXR's RGB, sRGB-encoded and rounded to 8 bits.
            const char* rgb[3] = {"R", "G", "B"};
            for (int c = 0; c < 3; ++c) {
                const double v = std::clamp(double(exr.at(x, y, rgb[c])), 0.0, 1.0);
                CHECK(std::abs(255.0 * srgb_encode(v) - png.at(x, y, c)) <= 0.5001);
            }
            const float id = exr.at(x, y, "inner_marker_id");
            CHECK(id == std::round(id));
            CHECK(id >= -1.0f);
            CHECK(id < 82.0f);
            inner_seen += id >= 0.0f;
            CHECK(exr.at(x, y, "variance.G") >= 0.0f);
        }
    CHECK(inner_seen > 100);
    std::ifstream labels(out / "labels.csv");
    std::string header, first;
    std::getline(labels, header);
    std::getline(labels, first);
    CHECK(header.rfind("split,trial,frame,time_s,phase,", 0) == 0);
    CHECK(header.find(",left_image,left_exr,") != std::string::npos);
    CHECK(first.find("images/all/trial_000000/left_000000.exr") != std::string::npos);
    // Channels without the EXR they belong to are refused before any work.
    CHECK_THROWS_WITH(parse_spec("outputs:\n  marker_ids: true\n", "bad.yaml"),
                      Catch::Contains("outputs.exr") && Catch::Contains("marker_ids"));
    // The EXR alone: no PNG, and the images folder still made for it.
    {
        std::ofstream f(spec_file);
        f << "name: exr_only\nrender:\n  width_px: 32\n  height_px: 32\n  samples_per_pixel: 1\n  "
             "integrator: preview\n"
          << press_only(1) << "outputs:\n  images: false\n  exr: true\n  markers: false\n";
    }
    options.out_dir = dir / "exr_only";
    generate(load_spec(spec_file), options, log);
    CHECK(read_image_float(options.out_dir / kFirstImage / "left_000000.exr").width == 32);
    CHECK_FALSE(fs::exists(options.out_dir / kFirstImage / "left_000000.png"));
    fs::remove_all(dir);
}

TEST_CASE("render.sensor: the PNG is the sensor's recording, the EXR stays the noise-free render",
          "[generators][e2e]") {
    const fs::path dir = fresh_dir("sensor");
    fs::create_directories(dir);
    GenerateOptions options;
    options.quiet = true;
    options.cache_dir = dir / "cache"; // the second run reuses the first one's mesh
    auto run = [&](const std::string& name, const std::string& sensor) {
        const fs::path spec_file = dir / (name + ".yaml");
        std::ofstream(spec_file) << "name: sensor\nrender:\n  width_px: 48\n  height_px: 48\n  "
                                    "samples_per_pixel: 1\n  integrator: preview\n"
                                 << sensor << press_only(2)
                                 << "outputs:\n  exr: true\n  markers: false\n";
        options.out_dir = dir / name;
        std::ostringstream log;
        generate(load_spec(spec_file), options, log);
        return options.out_dir / kFirstImage;
    };
    const fs::path plain = run("plain", "");
    const fs::path noisy = run("noisy", "  sensor:\n    enabled: true\n    vignetting:\n"
                                        "      model: none\n");
    for (const char* frame : {"left_000000", "left_000001"}) {
        INFO(frame);
        const ImageF exr_plain = read_image_float(plain / (std::string(frame) + ".exr"));
        const ImageF exr_noisy = read_image_float(noisy / (std::string(frame) + ".exr"));
        CHECK(exr_plain.data == exr_noisy.data); // the EXR is the render, bit for bit
        const Image8 png_plain = read_image8(plain / (std::string(frame) + ".png"));
        const Image8 png_noisy = read_image8(noisy / (std::string(frame) + ".png"));
        REQUIRE(png_plain.data.size() == png_noisy.data.size());
        // Noise of a few 8-bit levels about the same image: unbiased, no vignetting asked for.
        double sum = 0, sum_abs = 0;
        int differ = 0;
        for (std::size_t i = 0; i < png_plain.data.size(); ++i) {
            const double d = double(png_noisy.data[i]) - double(png_plain.data[i]);
            sum += d;
            sum_abs += std::abs(d);
            differ += d != 0;
        }
        const double n = double(png_plain.data.size());
        INFO("mean difference " << sum / n << ", mean |difference| " << sum_abs / n);
        CHECK(differ > n / 4);
        CHECK(std::abs(sum / n) < 0.2);
        CHECK(sum_abs / n < 4.0);
    }
    fs::remove_all(dir);
}
