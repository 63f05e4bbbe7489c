#include "generators/io/gltf_io.hpp"
#include "scratch_dir.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <regex>
#include <string>
#include <vector>

using namespace chromasim;
using Catch::Matchers::Contains;
using Catch::Matchers::StartsWith;
namespace fs = std::filesystem;

namespace {

// The committed assets and how they are made (assets/README.md; regenerate with
// `CHROMASIM_WRITE_ASSETS=1 test_generators "[assets]"`).
const fs::path asset_dir = fs::path(CHROMASIM_SOURCE_DIR) / "assets" / "objects";
constexpr double sphere_radius_mm = 45.0, sphere_cap_deg = 30.0, sphere_edge_mm = 1.0;
mechanics::TriangleSurface sphere_asset_surface() {
    return mechanics::make_sphere_cap(sphere_radius_mm, sphere_cap_deg, sphere_edge_mm);
}
mechanics::TriangleSurface plate_asset_surface() {
    return mechanics::make_plate(40.0, 40.0, 1);
}

// Little-endian bytes of a glTF buffer, built from readable values.
struct Bytes {
    std::vector<unsigned char> data;
    template <class T> Bytes& add(std::initializer_list<T> values) {
        for (T v : values) {
            unsigned char b[sizeof(T)];
            std::memcpy(b, &v, sizeof(T));
            data.insert(data.end(), b, b + sizeof(T));
        }
        return *this;
    }
};

std::string base64(const std::vector<unsigned char>& in) {
    static const char* abc = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string out;
    for (std::size_t i = 0; i < in.size(); i += 3) {
        const std::uint32_t n = std::uint32_t(in[i]) << 16 |
                                (i + 1 < in.size() ? std::uint32_t(in[i + 1]) << 8 : 0u) |
                                (i + 2 < in.size() ? std::uint32_t(in[i + 2]) : 0u);
        out += abc[n >> 18 & 63];
        out += abc[n >> 12 & 63];
        out += i + 1 < in.size() ? abc[n >> 6 & 63] : '=';
        out += i + 2 < in.size() ? abc[n & 63] : '=';
    }
    return out;
}

// A hand-written .gltf: `body` holds the members after "asset" and "buffers" (no leading comma).
std::string gltf_text(const Bytes& buffer, const std::string& body) {
    return R"({"asset": {"version": "2.0"}, "buffers": [{"byteLength": )" +
           std::to_string(buffer.data.size()) +
           R"(, "uri": "data:application/octet-stream;base64,)" + base64(buffer.data) + "\"}], " +
           body + "}";
}

std::string load_error(const fs::path& file) {
    try {
        generators::load_gltf_surface(file);
    } catch (const std::runtime_error& e) {
        return e.what();
    }
    return "no error";
}

Eigen::Vector3d normal(const mechanics::TriangleSurface& s, Eigen::Index f) {
    const Eigen::Vector3d a = s.V.row(s.F(f, 0)), b = s.V.row(s.F(f, 1)), c = s.V.row(s.F(f, 2));
    return (b - a).cross(c - a);
}

} // namespace

TEST_CASE("write then load: identical triangles, positions to float precision", "[gltf]") {
    ScratchDir dir("roundtrip");
    mechanics::Pose pose;
    pose.rotation = mechanics::rotation_from_roll_pitch_yaw_deg(12.0, -5.0, 33.0);
    pose.translation_mm = {1.25, -3.5, 13.2};
    const auto surface =
        mechanics::posed_surface(mechanics::make_sphere_cap(45.0, 60.0, 3.0), pose);
    for (const char* name : {"cap.gltf", "cap.glb", "CAP.GLTF"}) {
        INFO(name);
        const fs::path file = dir.path / name;
        generators::write_gltf_surface(file, surface); // metres
        generators::GltfLoadReport report;
        const auto back = generators::load_gltf_surface(file, 1000.0, &report);
        REQUIRE(back.F == surface.F);
        REQUIRE(back.V.rows() == surface.V.rows());
        // float32 in metres: relative rounding 2^-24 each way, a little more for the scaling.
        const double bound = std::ldexp(1.0, -23) * surface.V.cwiseAbs().maxCoeff();
        CHECK((back.V - surface.V).cwiseAbs().maxCoeff() <= bound);
        CHECK(report.primitives_used == 1);
        CHECK(report.primitives_skipped == 0);
        CHECK(report.degenerate_triangles_dropped == 0);
    }
    // In mm with exactly representable coordinates the round trip is exact.
    const auto plate = mechanics::make_plate(40.0, 30.0, 4);
    generators::write_gltf_surface(dir.path / "plate.gltf", plate, 1.0);
    const auto back = generators::load_gltf_surface(dir.path / "plate.gltf", 1.0);
    CHECK(back.V == plate.V);
    CHECK(back.F == plate.F);
    // Nothing but the written files is left, and overwriting works.
    generators::write_gltf_surface(dir.path / "plate.gltf", plate, 1.0);
    int files = 0;
    for (const auto& entry : fs::directory_iterator(dir.path)) {
        CHECK_THAT(entry.path().string(), !Contains(".partial-"));
        ++files;
    }
    CHECK(files == 4);
}

TEST_CASE("the writer picks 16-bit indices below 65535 vertices and 32-bit above", "[gltf]") {
    ScratchDir dir("indices");
    for (int divisions : {100, 256}) { // 10,201 and 66,049 vertices
        const auto plate = mechanics::make_plate(10.0, 10.0, divisions);
        const fs::path file = dir.path / "plate.glb";
        generators::write_gltf_surface(file, plate);
        const auto back = generators::load_gltf_surface(file);
        REQUIRE(back.F == plate.F);
        const auto positions = std::uintmax_t(plate.V.size()) * 4;
        const auto index_size = plate.V.rows() < 65535 ? 2u : 4u;
        const auto indices = std::uintmax_t(plate.F.size()) * index_size;
        INFO("divisions " << divisions);
        CHECK(fs::file_size(file) >= positions + indices);
        CHECK(fs::file_size(file) < positions + indices + 2000); // JSON chunk and headers
    }
}

TEST_CASE("node hierarchies: TRS and column-major matrices compose, mirroring keeps the "
          "winding",
          "[gltf]") {
    ScratchDir dir("nodes");
    // One triangle, interleaved (byteStride 16: position and 4 spare bytes), UNSIGNED_BYTE
    // indices.
    Bytes b;
    b.add<float>({0, 0, 0, 9, 0.01f, 0, 0, 9, 0, 0.01f, 0, 9});
    b.add<std::uint8_t>({0, 1, 2, 0});
    const std::string body = R"(
      "scene": 0, "scenes": [{"nodes": [0, 2]}],
      "nodes": [
        {"translation": [0.01, 0, 0], "rotation": [0, 0, 0.7071067811865476, 0.7071067811865476],
         "scale": [2, 2, 2], "children": [1]},
        {"matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0.005,1], "mesh": 0},
        {"scale": [-1, 1, 1], "mesh": 0}],
      "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
      "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48, "byteStride": 16},
                      {"buffer": 0, "byteOffset": 48, "byteLength": 3}],
      "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"},
                    {"bufferView": 1, "componentType": 5121, "count": 3, "type": "SCALAR"}])";
    const auto s = generators::load_gltf_surface(dir.write("nodes.gltf", gltf_text(b, body)));
    REQUIRE(s.F.rows() == 2);
    // Node 1: p + (0, 0, 5 mm) in node 1, then scale 2, turn 90 deg about z, shift 10 mm in x.
    const double tol = 1e-5; // float positions
    CHECK((Eigen::Vector3d(s.V.row(s.F(0, 0))) - Eigen::Vector3d(10, 0, 10)).norm() < tol);
    CHECK((Eigen::Vector3d(s.V.row(s.F(0, 1))) - Eigen::Vector3d(10, 20, 10)).norm() < tol);
    CHECK((Eigen::Vector3d(s.V.row(s.F(0, 2))) - Eigen::Vector3d(-10, 0, 10)).norm() < tol);
    // Node 2 mirrors x; the triangle still faces +z like the original.
    CHECK(normal(s, 0).z() > 0.0);
    CHECK(normal(s, 1).z() > 0.0);
    CHECK(s.V.col(0).minCoeff() == Approx(-10.0).margin(tol));
}

TEST_CASE("strips, fans, non-indexed triangles, points skipped, degenerate triangles dropped",
          "[gltf]") {
    ScratchDir dir("modes");
    Bytes b;
    b.add<float>({0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0}); // 4 corners of a unit square
    b.add<std::uint16_t>({0, 1, 3, 2});                 // fan, at byte 48
    b.add<std::uint32_t>({0, 1, 2, 1, 1, 3});           // triangles, at byte 56
    const std::string body = R"(
      "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
      "meshes": [{"primitives": [
        {"attributes": {"POSITION": 0}, "mode": 5},
        {"attributes": {"POSITION": 0}, "indices": 1, "mode": 6},
        {"attributes": {"POSITION": 2}},
        {"attributes": {"POSITION": 0}, "mode": 0},
        {"attributes": {"POSITION": 0}, "indices": 3, "mode": 4}]}],
      "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
                      {"buffer": 0, "byteOffset": 48, "byteLength": 8},
                      {"buffer": 0, "byteOffset": 56, "byteLength": 24}],
      "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"},
                    {"bufferView": 1, "componentType": 5123, "count": 4, "type": "SCALAR"},
                    {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"},
                    {"bufferView": 2, "componentType": 5125, "count": 6, "type": "SCALAR"}])";
    generators::GltfLoadReport report;
    const auto s =
        generators::load_gltf_surface(dir.write("modes.gltf", gltf_text(b, body)), 1000.0, &report);
    CHECK(s.F.rows() == 2 + 2 + 1 + 1);
    CHECK(report.primitives_used == 4);
    CHECK(report.primitives_skipped == 1);
    CHECK(report.degenerate_triangles_dropped == 1);
    for (Eigen::Index f = 0; f < s.F.rows(); ++f)
        CHECK(normal(s, f).z() == Approx(1e6)); // every triangle: half of a 1 m square, +z
    CHECK(s.V.maxCoeff() == 1000.0);
}

TEST_CASE("the committed object assets load as documented", "[gltf]") {
    SECTION("sphere cap, radius 45 mm") {
        const fs::path file = asset_dir / "sphere_cap_r45.glb";
        REQUIRE(fs::exists(file));
        CHECK(fs::file_size(file) < 300 * 1024);
        const auto s = generators::load_gltf_surface(file);
        const auto made = sphere_asset_surface(); // the file is up to date with the generator
        REQUIRE(s.F == made.F);
        CHECK((s.V - made.V).cwiseAbs().maxCoeff() < 1e-5);
        CHECK(s.F.rows() > 1000);
        CHECK(s.F.rows() < 6000);
        for (Eigen::Index v = 0; v < s.V.rows(); ++v)
            REQUIRE((Eigen::Vector3d(s.V.row(v)) - Eigen::Vector3d(0, 0, 45)).norm() ==
                    Approx(45.0).margin(1e-5));
        const mechanics::MeshHeightField field(s);
        CHECK(field.lowest_point().norm() < 1e-9);
        CHECK(field.bounds().max().z() ==
              Approx(45.0 * (1.0 - std::cos(M_PI / 6.0))).margin(1e-5)); // cap height
    }
    SECTION("plate, 40 x 40 mm") {
        const fs::path file = asset_dir / "plate_40x40.gltf";
        REQUIRE(fs::exists(file));
        const auto s = generators::load_gltf_surface(file);
        CHECK(s.F == plate_asset_surface().F);
        CHECK((s.V - plate_asset_surface().V).cwiseAbs().maxCoeff() < 1e-5);
        const mechanics::MeshHeightField field(s);
        CHECK(*field.lowest_z(0.0, 0.0) == 0.0);
        CHECK(*field.lowest_z(19.9, -19.9) == 0.0);
        CHECK_FALSE(field.lowest_z(20.01, 0.0));
    }
}

TEST_CASE("bad files give errors that start with the file and say what is allowed", "[gltf]") {
    ScratchDir dir("errors");
    Bytes b;
    b.add<float>({0, 0, 0, 1, 0, 0, 0, 1, 0});
    b.add<std::uint8_t>({0, 1, 7, 0});
    const std::string views =
        R"("bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                           {"buffer": 0, "byteOffset": 36, "byteLength": 3}],)";
    auto file_with = [&](const std::string& name, const std::string& primitive,
                         const std::string& accessors, const std::string& extra = "") {
        return dir.write(name, gltf_text(b, extra + R"("scenes": [{"nodes": [0]}],
            "nodes": [{"mesh": 0}], "meshes": [{"primitives": [)" +
                                                primitive + "]}], " + views + accessors));
    };
    const std::string positions =
        R"("accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"},
                         {"bufferView": 1, "componentType": 5121, "count": 3, "type": "SCALAR"}])";

    SECTION("missing file") {
        const fs::path file = dir.path / "absent.gltf";
        CHECK_THAT(load_error(file), StartsWith(file.string()) && Contains("no such file"));
    }
    SECTION("garbage, as JSON and as binary") {
        for (const auto& [name, text] :
             {std::pair{"garbage.gltf", std::string("this is not JSON {")},
              std::pair{"garbage.glb", std::string("glTF\x02\0\0\0garbage", 15)}}) {
            const fs::path file = dir.write(name, text);
            CHECK_THAT(load_error(file),
                       StartsWith(file.string()) && Contains("not a valid glTF 2.0"));
        }
    }
    SECTION("only POINTS") {
        const fs::path file =
            file_with("points.gltf", R"({"attributes": {"POSITION": 0}, "mode": 0})", positions);
        CHECK_THAT(load_error(file), StartsWith(file.string()) && Contains("no triangle") &&
                                         Contains("1 POINTS primitive(s) skipped") &&
                                         Contains("TRIANGLES, TRIANGLE_STRIP or TRIANGLE_FAN"));
    }
    SECTION("index out of range") {
        const fs::path file =
            file_with("index.gltf", R"({"attributes": {"POSITION": 0}, "indices": 1})", positions);
        CHECK_THAT(load_error(file),
                   StartsWith(file.string()) && Contains("index 7 is out of range [0, 3)"));
    }
    SECTION("POSITION not FLOAT") {
        const fs::path file =
            file_with("short.gltf", R"({"attributes": {"POSITION": 0}})",
                      R"("accessors": [{"bufferView": 0, "componentType": 5123, "normalized": true,
                              "count": 3, "type": "VEC3"}])");
        CHECK_THAT(load_error(file), StartsWith(file.string()) && Contains("UNSIGNED_SHORT") &&
                                         Contains("POSITION must be FLOAT"));
    }
    SECTION("accessor past the end of its buffer view") {
        const fs::path file =
            file_with("long.gltf", R"({"attributes": {"POSITION": 0}})",
                      R"("accessors": [{"bufferView": 0, "componentType": 5126, "count": 30,
                              "type": "VEC3"}])");
        CHECK_THAT(load_error(file), StartsWith(file.string()) && Contains("reaches past the end"));
    }
    SECTION("sparse accessor") {
        const fs::path file = file_with(
            "sparse.gltf", R"({"attributes": {"POSITION": 0}})",
            R"("accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                "sparse": {"count": 1,
                           "indices": {"bufferView": 1, "componentType": 5121},
                           "values": {"bufferView": 0}}}])");
        CHECK_THAT(load_error(file), StartsWith(file.string()) && Contains("sparse"));
    }
    SECTION("required extension") {
        const fs::path file =
            file_with("draco.gltf", R"({"attributes": {"POSITION": 0}})", positions,
                      R"("extensionsUsed": ["KHR_draco_mesh_compression"],
                         "extensionsRequired": ["KHR_draco_mesh_compression"], )");
        CHECK_THAT(load_error(file),
                   StartsWith(file.string()) && Contains("KHR_draco_mesh_compression"));
    }
    SECTION("writer: unknown extension, missing folder; nothing left behind") {
        const auto plate = mechanics::make_plate(40.0, 40.0);
        CHECK_THROWS_WITH(generators::write_gltf_surface(dir.path / "plate.obj", plate),
                          StartsWith((dir.path / "plate.obj").string()) && Contains(".glb"));
        const fs::path nowhere = dir.path / "no" / "such" / "plate.gltf";
        CHECK_THROWS_WITH(generators::write_gltf_surface(nowhere, plate),
                          StartsWith(nowhere.string()));
        CHECK_FALSE(fs::exists(dir.path / "plate.obj"));
        CHECK_THROWS_AS(
            generators::write_gltf_surface(dir.path / "bad.gltf", mechanics::TriangleSurface{}),
            std::invalid_argument);
        CHECK_FALSE(fs::exists(dir.path / "bad.gltf"));
    }
}

// The committed assets are what the generator writes, byte for byte but for the generator's
// version in the asset header. To regenerate them after changing the generator:
// CHROMASIM_WRITE_ASSETS=1 test_generators "[assets]" (assets/README.md).
TEST_CASE("the generator writes the committed object assets byte for byte", "[gltf][assets]") {
    ScratchDir dir("assets");
    const bool regenerate = std::getenv("CHROMASIM_WRITE_ASSETS") != nullptr;
    const fs::path out = regenerate ? asset_dir : dir.path;
    generators::write_gltf_surface(out / "sphere_cap_r45.glb", sphere_asset_surface());
    generators::write_gltf_surface(out / "plate_40x40.gltf", plate_asset_surface());
    // A .glb's JSON chunk (padded to 4 bytes) and binary chunk, or a .gltf's text, with the
    // asset's generator string masked.
    const auto content = [](const fs::path& file) {
        std::ifstream in(file, std::ios::binary);
        std::string bytes(std::istreambuf_iterator<char>(in), {});
        if (file.extension() == ".glb" && bytes.size() >= 20) {
            std::uint32_t json_length = 0;
            std::memcpy(&json_length, bytes.data() + 12, 4);
            std::string json = bytes.substr(20, json_length);
            json.erase(json.find_last_not_of(' ') + 1);
            bytes = json + "|" + bytes.substr(20 + std::size_t(json_length));
        }
        return std::regex_replace(bytes, std::regex(R"("generator"\s*:\s*"[^"]*")"),
                                  R"("generator": "")");
    };
    for (const char* name : {"sphere_cap_r45.glb", "plate_40x40.gltf"}) {
        INFO(name);
        REQUIRE(fs::exists(asset_dir / name));
        CHECK(content(out / name) == content(asset_dir / name));
    }
}
