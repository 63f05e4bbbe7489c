#pragma once
/// Frames, settings and light caches the fast integrator's tests share (test_fast*.cpp).
#include "render/embree_scene.hpp"
#include "render/fast_integrator.hpp"
#include "render/path_integrator.hpp"
#include "render/renderer.hpp"
#include "render/shading.hpp"
#include "test_meshes.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <utility>
#include <vector>

namespace chromasim::render::test {

using detail::EmbreeScene;
using detail::FastIntegrator;
using detail::PathIntegrator;
using detail::ShadingModel;

/// The fast integrator on a frame's scene, with the default optics (no spectra).
struct FastOnFrame {
    explicit FastOnFrame(const SensorFrame& frame) { scene.set_frame(frame); }
    /// And with a small light cache (8 paths, 4 LED points per vertex) built on `rest`.
    FastOnFrame(const SensorFrame& frame, const SensorFrame& rest) : FastOnFrame(frame) {
        LightCacheSettings settings;
        settings.paths_per_vertex = 8;
        settings.direct_samples = 4;
        fast.build_cache(rest, settings, nullptr, 1.0);
        fast.set_frame(frame, scene);
    }
    EmbreeScene scene;
    ShadingModel shading{OpticsParams{}};
    PathIntegrator path{shading};
    FastIntegrator fast{shading, path};
};

/// The light cache's LED vectors, [vertex * leds + k].
inline std::vector<Vec3> cached_vectors(const FastIntegrator& fast) {
    const std::vector<float>& d = fast.cache().direct;
    std::vector<Vec3> out;
    for (std::size_t i = 0; i + 2 < d.size(); i += 3)
        out.emplace_back(d[i], d[i + 1], d[i + 2]);
    return out;
}

/// The frame's LED vectors (FastIntegrator::frame_direct), in the same order.
inline std::vector<Vec3> frame_vectors(const FastIntegrator& fast, int vertices, int leds) {
    std::vector<Vec3> out;
    for (int v = 0; v < vertices; ++v)
        for (int k = 0; k < leds; ++k)
            out.push_back(fast.frame_direct(v, k));
    return out;
}


/// The coarse clear dome with a ring of box markers in each layer (12 triangles each).
inline SensorFrame dome_with_box_markers() {
    SensorFrame rest = clear_dome(16, 64, 24, 96);
    rest.inner_markers = box_markers(10.75, 0.5, 1.0);
    rest.outer_markers = box_markers(12.45, 0.5, 1.0);
    rest.triangles_per_marker = 12;
    return rest;
}

/// `rest` pressed by a plane tilted `degrees` about the y axis, both surfaces cut off beyond
/// it (as pressed_flat does level): the inner surface's cut is a flat facet the camera rays
/// meet far from normal incidence, so they bend there and their reflections cross the cavity
/// to the lit far wall.
inline SensorFrame pressed_tilted(const SensorFrame& rest, float degrees) {
    SensorFrame pressed = rest;
    const float tilt = degrees * float(std::numbers::pi) / 180.0f;
    const Eigen::Vector3f normal(std::sin(tilt), 0.0f, std::cos(tilt));
    for (auto [mesh, reach] :
         {std::pair{&pressed.inner_surface, 8.5f}, std::pair{&pressed.coating, 10.7f}})
        for (Eigen::Index v = 0; v < mesh->V.rows(); ++v) {
            const Eigen::Vector3f x = mesh->V.row(v).transpose();
            mesh->V.row(v) = (x - std::max(0.0f, normal.dot(x) - reach) * normal).transpose();
        }
    return pressed;
}

/// The default optics with the spectra of assets/spectra (spectral mode).
inline OpticsParams spectral_optics() {
    OpticsParams spectral;
    spectral.spectra = load_sensor_spectra(SensorSpectraFiles::in_directory(
        std::filesystem::path(CHROMASIM_SOURCE_DIR) / "assets" / "spectra"));
    return spectral;
}

/// The fast integrator at `spp` samples per pixel and `seed`, with the variance channel.
inline RenderSettings fast_with_variance(int spp, std::uint64_t seed) {
    RenderSettings settings{spp, seed};
    settings.integrator = Integrator::fast;
    settings.variance = true;
    return settings;
}

/// The tests' small light cache: 8 paths, 4 LED points per vertex.
inline LightCacheSettings small_cache() {
    LightCacheSettings cache;
    cache.paths_per_vertex = 8;
    cache.direct_samples = 4;
    return cache;
}

/// The renderer's light cache (by default the small one) built on `rest`, then `frame` loaded.
inline void small_cache_on(Renderer& renderer, const SensorFrame& rest, const SensorFrame& frame,
                    const LightCacheSettings& cache = small_cache()) {
    renderer.set_light_cache(rest, cache);
    renderer.set_frame(frame);
}

/// The path integrator's mean radiance along `d` from the origin over `paths` paths (seed 3),
/// its standard error, and the fast integrator's over `fast_samples` (seed 4).
struct AlongRay {
    detail::RgbLanes path, se, fast;
};
inline AlongRay along_ray(const PathIntegrator& path, const FastIntegrator& fast,
                          const EmbreeScene& scene,
                          const detail::LaneOptics<detail::kRgbLanes>& lanes, const Vec3& d,
                          int paths = 40000, int fast_samples = 64) {
    using detail::RgbLanes;
    RgbLanes p = RgbLanes::Zero(), p2 = RgbLanes::Zero(), f = RgbLanes::Zero();
    for (int i = 0; i < paths; ++i) {
        detail::PixelRng rng(3, std::uint64_t(i));
        const RgbLanes L = path.radiance(scene, Vec3::Zero(), d, lanes, rng);
        p += L;
        p2 += L.square();
    }
    for (int i = 0; i < fast_samples; ++i) {
        detail::PixelRng rng(4, std::uint64_t(i));
        f += fast.radiance<detail::kRgbLanes>(scene, Vec3::Zero(), d, lanes, nullptr, rng);
    }
    p /= paths;
    f /= fast_samples;
    return {p, ((p2 / paths - p.square()).max(0.0) / (paths - 1.0)).sqrt(), f};
}

} // namespace chromasim::render::test
