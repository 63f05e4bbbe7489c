// export-scene's library side: a hand-made sensor frame to glTF and back, as a viewer sees it.
#include "generators/io/gltf_io.hpp"
#include "generators/pipeline/scene_export.hpp"
#include "render/fisheye_camera.hpp"
#include "scratch_dir.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>

using namespace chromasim;
using Catch::Matchers::Contains;
using Catch::Matchers::StartsWith;
namespace fs = std::filesystem;

namespace {

render::SurfaceMesh surface(std::initializer_list<std::array<float, 3>> V,
                            std::initializer_list<std::array<std::uint32_t, 3>> F) {
    render::SurfaceMesh s;
    s.V.resize(Eigen::Index(V.size()), 3);
    s.F.resize(Eigen::Index(F.size()), 3);
    Eigen::Index i = 0;
    for (const auto& v : V)
        s.V.row(i++) << v[0], v[1], v[2];
    i = 0;
    for (const auto& f : F)
        s.F.row(i++) << f[0], f[1], f[2];
    return s;
}

// A closed tetrahedron around `c`, faces wound outwards.
render::SurfaceMesh tetrahedron(float x, float y, float z) {
    return surface({{x, y, z}, {x + 0.5f, y, z}, {x, y + 0.5f, z}, {x, y, z + 0.5f}},
                   {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}});
}

// Coating: a square at z = 12 facing the camera (-z); inner surface: one triangle at z = 10.
render::SensorFrame hand_made_frame() {
    render::SensorFrame f;
    f.coating =
        surface({{-1, -1, 12}, {1, -1, 12}, {1, 1, 12}, {-1, 1, 12}}, {{0, 2, 1}, {0, 3, 2}});
    f.inner_surface = surface({{0, 0, 10}, {1, 2, 10}, {2, 0, 10}}, {{0, 1, 2}});
    f.inner_markers = tetrahedron(0.0f, 0.0f, 10.5f);
    f.outer_markers = tetrahedron(1.0f, -2.0f, 12.2f);
    f.triangles_per_marker = 4;
    return f;
}

// chromasim (z up) to the file's frame (y up): (x, y, z) -> (x, z, -y).
Eigen::Vector3d y_up(const Eigen::Vector3d& p) {
    return {p.x(), p.z(), -p.y()};
}

double number(const generators::GltfExtras& e, const std::string& key) {
    REQUIRE(e.count(key) == 1);
    return std::get<double>(e.at(key));
}

void check_surface_y_up(const render::SurfaceMesh& back, const render::SurfaceMesh& original) {
    REQUIRE(back.V.rows() == original.V.rows());
    CHECK(back.F == original.F);
    for (Eigen::Index v = 0; v < back.V.rows(); ++v) {
        const Eigen::Vector3d expected = y_up(original.V.row(v).cast<double>().transpose());
        // float32 metres: about 1e-6 mm at these sizes.
        CHECK((back.V.row(v).cast<double>().transpose() - expected).norm() < 1e-5);
    }
}

} // namespace

TEST_CASE("area-weighted normals: triangles pull a shared vertex in proportion to their area",
          "[generators][gltf]") {
    // Triangle A (area 2) in z = 0 faces +z, triangle B (area 1) in x = 0 faces +x; vertex 0 is
    // shared; vertex 5 is in no triangle.
    const render::SurfaceMesh s = surface(
        {{0, 0, 0}, {2, 0, 0}, {0, 2, 0}, {0, 1, 0}, {0, 0, 2}, {5, 5, 5}}, {{0, 1, 2}, {0, 3, 4}});
    const render::VertexArray N = generators::area_weighted_normals(s);
    REQUIRE(N.rows() == 6);
    const Eigen::Vector3f shared = Eigen::Vector3f(1, 0, 2).normalized();
    CHECK((N.row(0).transpose() - shared).norm() < 1e-6f);
    CHECK((N.row(1).transpose() - Eigen::Vector3f::UnitZ()).norm() < 1e-6f);
    CHECK((N.row(4).transpose() - Eigen::Vector3f::UnitX()).norm() < 1e-6f);
    CHECK((N.row(5).transpose() - Eigen::Vector3f::UnitZ()).norm() < 1e-6f);
}

// Its materials, LEDs and camera come back too.
TEST_CASE("a hand-made sensor frame written as .gltf and .glb reads back in metres with y up",
          "[generators][gltf]") {
    ScratchDir dir("scene_roundtrip");
    const render::SensorFrame frame = hand_made_frame();
    render::CameraParams camera;
    camera.width_px = 320;
    camera.height_px = 240;
    camera.position_mm = {0.5, -0.25, 1.0};
    camera.yaw_deg = 30.0;
    camera.pitch_deg = 10.0;
    render::OpticsParams optics;
    optics.led_count = 4;
    optics.led_ring_radius_mm = 9.0;
    optics.led_z_mm = -2.0;
    optics.led_rgb = {0.5, 2.0, 0.25};
    optics.lens_radius_mm = 7.0;
    const generators::SceneInfo info{"hand", 0.4, {{"frame", 7.0}, {"spec_sha256", "abc"}}};
    const generators::GltfScene scene = generators::make_gltf_scene(frame, camera, optics, info);

    for (const char* name : {"scene.gltf", "scene.glb"}) {
        INFO(name);
        const fs::path file = dir.path / name;
        generators::write_gltf_scene(file, scene);
        {
            std::ifstream in(file, std::ios::binary);
            std::string text((std::istreambuf_iterator<char>(in)), {});
            if (file.extension() == ".glb")
                CHECK(text.substr(0, 4) == "glTF");
            else
                CHECK_THAT(text, Contains("data:application/octet-stream;base64,"));
        }
        const generators::GltfSceneFile back = generators::read_gltf_scene(file);
        CHECK_THAT(back.generator, StartsWith("chromasim "));
        for (const char* ext :
             {"KHR_materials_transmission", "KHR_materials_volume", "KHR_materials_ior"})
            CHECK(std::count(back.extensions_used.begin(), back.extensions_used.end(), ext) == 1);
        // The LEDs are the renderer's area emitters, not punctual lights.
        CHECK(std::count(back.extensions_used.begin(), back.extensions_used.end(),
                         "KHR_lights_punctual") == 0);
        CHECK(back.scene.lights.empty());

        // Meshes: names, counts, positions (mm -> m, z up -> y up), normals.
        const auto& meshes = back.scene.meshes;
        REQUIRE(meshes.size() == 7);
        CHECK(meshes[0].name == "coating");
        CHECK(meshes[1].name == "inner_surface");
        CHECK(meshes[2].name == "inner_markers");
        CHECK(meshes[3].name == "outer_markers");
        CHECK(meshes[4].name == "leds");
        CHECK(meshes[5].name == "frame");
        check_surface_y_up(meshes[0].surface, frame.coating);
        check_surface_y_up(meshes[1].surface, frame.inner_surface);
        check_surface_y_up(meshes[2].surface, frame.inner_markers);
        check_surface_y_up(meshes[3].surface, frame.outer_markers);
        CHECK(meshes[4].surface.V.rows() == 4 * optics.led_count);
        CHECK(meshes[4].surface.F.rows() == 2 * optics.led_count);
        CHECK(meshes[0].normals.rows() == 0); // the coating: flat, as the renderer shades it
        CHECK(meshes[1].normals.rows() == 3);
        CHECK(meshes[2].normals.rows() == 0); // markers: flat shaded
        CHECK(meshes[3].normals.rows() == 0);
        // The stored numbers are metres: the first vertex of the file is the coating's first.
        const auto raw = generators::load_gltf_surface(file, 1.0);
        CHECK((raw.V.row(0).transpose() - 1e-3 * y_up({-1, -1, 12})).norm() < 1e-9);

        // Materials.
        const auto& coating = meshes[0].material;
        CHECK(coating.base_color.head<3>().isApprox(optics.coating_albedo));
        CHECK(coating.roughness == 1.0);
        CHECK(coating.metallic == 0.0);
        CHECK_FALSE(coating.transmission.has_value());
        REQUIRE(meshes[1].material.transmission.has_value());
        CHECK(*meshes[1].material.transmission == 1.0);
        CHECK(meshes[1].material.ior.value_or(0.0) == Approx(1.4));
        const auto& magenta = meshes[2].material;
        REQUIRE(magenta.volume.has_value());
        CHECK(magenta.transmission.value_or(0.0) == 1.0);
        CHECK(magenta.volume->thickness_mm == Approx(0.4));
        CHECK(magenta.volume->attenuation_distance_mm == Approx(1.0));
        for (int c = 0; c < 3; ++c)
            CHECK(magenta.volume->attenuation_color[c] ==
                  Approx(std::exp(-optics.inner_marker_absorption_per_mm[c])));
        const auto& cyan = meshes[3].material;
        REQUIRE(cyan.volume.has_value());
        CHECK(cyan.base_color.head<3>().isApprox(optics.outer_marker_albedo));
        CHECK(cyan.transmission.value_or(0.0) ==
              Approx(1.0 - optics.outer_marker_scatter_fraction));
        CHECK(cyan.volume->attenuation_color[0] ==
              Approx(std::exp(-optics.outer_marker_absorption_per_mm[0])));
        CHECK(meshes[4].material.emissive.isApprox(Eigen::Vector3d(0.25, 1.0, 0.125)));

        // Markers in silicone of their own index; the cyan ones' scattering in extras.
        CHECK(magenta.ior.value_or(0.0) == 1.0);
        CHECK(cyan.ior.value_or(0.0) == 1.0);
        CHECK(number(cyan.extras, "scatter_fraction") ==
              Approx(optics.outer_marker_scatter_fraction));

        // LEDs: one rectangle each in the LED plane, centred on the ring, the first on +x,
        // led_width_mm along the ring.
        const auto& leds = meshes[4].surface;
        for (int k = 0; k < optics.led_count; ++k) {
            const double phi = 2 * std::numbers::pi * k / optics.led_count;
            Eigen::Vector3d centre = Eigen::Vector3d::Zero();
            for (int j = 0; j < 4; ++j)
                centre += leds.V.row(4 * k + j).cast<double>().transpose() / 4;
            CHECK((centre - y_up({9 * std::cos(phi), 9 * std::sin(phi), -2})).norm() < 1e-5);
            const Eigen::Vector3d side =
                (leds.V.row(4 * k + 3) - leds.V.row(4 * k)).cast<double>().transpose();
            CHECK(side.norm() == Approx(optics.led_width_mm).epsilon(1e-5));
            CHECK(std::abs(side.dot(y_up({-std::sin(phi), std::cos(phi), 0}))) ==
                  Approx(optics.led_width_mm).epsilon(1e-5));
        }
        CHECK(number(meshes[4].material.extras, "relative_radiance") ==
              Approx(2.0 / (optics.led_width_mm * optics.led_height_mm)));
        // The frame: black, in the rim plane (file y = 0), from the inner radius outwards.
        const auto& frame_plane = meshes[5];
        CHECK(frame_plane.material.base_color.head<3>().isZero());
        for (Eigen::Index v = 0; v < frame_plane.surface.V.rows(); ++v) {
            const Eigen::Vector3d x = frame_plane.surface.V.row(v).cast<double>().transpose();
            CHECK(std::abs(x.y()) < 1e-9);
            CHECK(std::hypot(x.x(), x.z()) >= optics.frame_inner_radius_mm - 1e-4);
        }
        // The lens barrel: black, on the axis, of the lens radius, from just under the rim
        // plane to below the LEDs.
        const auto& barrel = meshes[6];
        CHECK(barrel.name == "lens_barrel");
        CHECK(barrel.material.base_color.head<3>().isZero());
        double top = -1e9, bottom = 1e9;
        for (Eigen::Index v = 0; v < barrel.surface.V.rows(); ++v) {
            const Eigen::Vector3d x = barrel.surface.V.row(v).cast<double>().transpose();
            const double r = std::hypot(x.x(), x.z());
            CHECK((r < 1e-9 || r == Approx(optics.lens_radius_mm).epsilon(1e-6)));
            top = std::max(top, x.y()), bottom = std::min(bottom, x.y());
        }
        CHECK(top < 0.0);
        CHECK(top > -0.1);
        CHECK(bottom < optics.led_z_mm);

        // Camera: the fisheye's pose, a 120 deg stand-in, the true intrinsics in its extras.
        REQUIRE(back.scene.camera.has_value());
        const auto& c = *back.scene.camera;
        const render::FisheyeCamera fisheye(camera);
        CHECK((c.position_mm - y_up(camera.position_mm)).norm() < 1e-9);
        for (int k = 0; k < 3; ++k)
            CHECK((c.rotation.col(k) - y_up(fisheye.rotation().col(k))).norm() < 1e-9);
        CHECK(c.yfov_rad == Approx(120.0 * std::numbers::pi / 180));
        CHECK(c.aspect_ratio == Approx(320.0 / 240.0));
        const render::CameraParams k = render::with_equidistant_intrinsics(camera);
        CHECK(std::get<std::string>(c.extras.at("model")) == "equidistant");
        CHECK(number(c.extras, "half_fov_deg") == 84.0);
        CHECK(number(c.extras, "fx") == Approx(k.fx_px));
        CHECK(number(c.extras, "fy") == Approx(k.fy_px));
        CHECK(number(c.extras, "cx") == Approx(k.cx_px));
        CHECK(number(c.extras, "cy") == Approx(k.cy_px));
        for (const char* ki : {"k1", "k2", "k3", "k4"})
            CHECK(number(c.extras, ki) == 0.0);
        CHECK(number(c.extras, "width") == 320.0);
        CHECK(number(c.extras, "height") == 240.0);

        // Scene extras.
        CHECK(back.scene.name == "hand");
        CHECK(number(back.scene.extras, "frame") == 7.0);
        CHECK(std::get<std::string>(back.scene.extras.at("spec_sha256")) == "abc");
    }
    for (const auto& entry : fs::directory_iterator(dir.path))
        CHECK_THAT(entry.path().string(), !Contains(".partial-"));
}

// A frame without an inner surface exports none.
TEST_CASE("a Kannala-Brandt calibration goes to the camera extras as given", "[generators][gltf]") {
    render::SensorFrame frame = hand_made_frame();
    frame.inner_surface = {};
    render::CameraParams camera;
    camera.model = render::CameraModel::kannala_brandt;
    camera.fx_px = 90.5, camera.fy_px = 91.25, camera.cx_px = 127.0, camera.cy_px = 126.5;
    camera.k1 = 0.01, camera.k2 = -0.002, camera.k3 = 0.0005, camera.k4 = -0.0001;
    const generators::GltfScene scene =
        generators::make_gltf_scene(frame, camera, render::OpticsParams{}, {});
    for (const auto& m : scene.meshes)
        CHECK(m.name != "inner_surface");
    REQUIRE(scene.camera.has_value());
    const auto& e = scene.camera->extras;
    CHECK(std::get<std::string>(e.at("model")) == "kannala_brandt");
    CHECK(number(e, "fx") == 90.5);
    CHECK(number(e, "fy") == 91.25);
    CHECK(number(e, "cx") == 127.0);
    CHECK(number(e, "cy") == 126.5);
    CHECK(number(e, "k1") == 0.01);
    CHECK(number(e, "k2") == -0.002);
    CHECK(number(e, "k3") == 0.0005);
    CHECK(number(e, "k4") == -0.0001);
    CHECK(scene.lights.empty()); // the LEDs are emissive rectangles
}

TEST_CASE("write_gltf_scene refuses a bad extension, a missing folder and a bad mesh, and "
          "leaves nothing behind",
          "[generators][gltf]") {
    ScratchDir dir("scene_errors");
    const generators::GltfScene scene = generators::make_gltf_scene(
        hand_made_frame(), render::CameraParams{}, render::OpticsParams{}, {});
    const fs::path obj = dir.path / "scene.obj";
    CHECK_THROWS_WITH(generators::write_gltf_scene(obj, scene),
                      StartsWith(obj.string()) && Contains(".gltf") && Contains(".glb"));
    const fs::path nowhere = dir.path / "no" / "such" / "scene.glb";
    CHECK_THROWS_WITH(generators::write_gltf_scene(nowhere, scene),
                      StartsWith(nowhere.string()) && Contains("does not exist"));
    std::ofstream(dir.path / "file") << "x";
    const fs::path under_file = dir.path / "file" / "scene.glb";
    CHECK_THROWS_WITH(generators::write_gltf_scene(under_file, scene),
                      StartsWith(under_file.string()) && Contains("is not a folder"));
    generators::GltfScene bad = scene;
    bad.meshes[0].surface.F(0, 0) = 99;
    CHECK_THROWS_AS(generators::write_gltf_scene(dir.path / "bad.glb", bad), std::invalid_argument);
    int files = 0;
    for ([[maybe_unused]] const auto& entry : fs::directory_iterator(dir.path))
        ++files;
    CHECK(files == 1); // "file" only
}
