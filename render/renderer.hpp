#pragma once
/// Renders fisheye images of a deformed sensor with Embree.
#include "render/scene_data.hpp"

#include <cstdint>
#include <memory>
#include <optional>

namespace chromasim::render {

/// Owns the Embree device and scene. Build once per sensor, then call `set_frame` for each
/// frame: when only vertex positions change (same triangle counts), buffers are updated in
/// place and the BVH refitted instead of rebuilt.
class Renderer {
public:
    Renderer(const CameraParams& camera, const OpticsParams& optics);
    ~Renderer();
    Renderer(const Renderer&) = delete;
    Renderer& operator=(const Renderer&) = delete;

    /// Loads (first call, or changed topology) or refits (same topology) the scene.
    void set_frame(const SensorFrame& frame);

    /// Auto exposure of the path and fast integrators: path-traces `undeformed`'s bare dome (its
    /// coating and inner surface, no markers) from the dome centre along polar angles 0 to
    /// 70 deg, towards an LED and between two, and scales images so that the brightest of those
    /// maps to 0.8 (times OpticsParams::exposure), headroom for brighter spots under a press.
    /// Deterministic (fixed seeds and blocks). Without it, images use the preview integrator's
    /// analytic scale.
    void set_exposure_reference(const SensorFrame& undeformed);

    /// The fast integrator's light cache (render/fast_integrator.hpp), built on `undeformed`
    /// (the sensor at rest with its markers and inner surface): once per sensor, before
    /// rendering with Integrator::fast. Frames must then have the same coating topology.
    /// Returns the build's wall time in seconds.
    double set_light_cache(const SensorFrame& undeformed, const LightCacheSettings& settings);
    /// Uses a light cache built before for this sensor and optics (generators/
    /// light_cache_store.hpp reads them from disk). Throws std::invalid_argument when it is for
    /// another LED count or mode (spectral or RGB lanes), its arrays do not match, or a frame
    /// is loaded and its coating differs from the cache's. `settings`: those the cache was
    /// built with (generators/pipeline/light_cache_store.hpp keys files by them), and the per-frame
    /// refresh. `undeformed`: the sensor at rest it was built on (each frame's solves of the
    /// LEDs' light start from its connections, found again here in about a frame update's
    /// time); also throws when its coating is not the cache's.
    void set_light_cache(LightCache cache, const LightCacheSettings& settings,
                         const SensorFrame& undeformed);
    /// The light cache in use, or nullptr.
    const LightCache* light_cache() const;

    /// Renders the current frame. Linear RGB, auto-exposed so that the undeformed dome's
    /// brightest direction (set_exposure_reference; the preview integrator: its apex) maps to
    /// about 0.8 (times OpticsParams::exposure).
    Image render(const RenderSettings& settings) const;

    /// Projects a 3D point (mm, camera frame) to pixel coordinates; nullopt if outside the
    /// image circle. Exposed for tests and label overlays.
    std::optional<Eigen::Vector2d> project(const Vec3& p_mm) const;

    /// The memory the fast integrator's kept camera samples take (RenderSettings::
    /// camera_cache_mb), bytes; 0 while none are kept.
    std::size_t camera_samples_bytes() const;

    /// Benchmarks: count the rays the next renders trace (EmbreeScene::count_rays).
    void count_rays(bool on);
    std::uint64_t rays_counted() const;

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

} // namespace chromasim::render
