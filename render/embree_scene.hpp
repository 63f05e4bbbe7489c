#pragma once
/// The Embree adapter: the only part of chromasim that sees Embree types (STYLE.md). It holds
/// the device, the scene and one triangle geometry per surface kind, and answers plain ray
/// queries.
#include "render/scene_data.hpp"

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>

namespace chromasim::render::detail {

/// What a ray hit. The values double as Embree geometry IDs plus one.
enum class SurfaceKind : std::uint8_t {
    none = 0,
    coating = 1,
    inner_marker = 2,
    outer_marker = 3,
    inner_surface = 4, ///< the air / clear-layer interface (SensorFrame::inner_surface)
};

/// A set of surface kinds, one bit each (closest_hit's `kinds`: the surfaces a ray can meet;
/// Embree's ray and geometry masks).
constexpr unsigned kind_bit(SurfaceKind kind) {
    return 1u << unsigned(kind);
}
inline constexpr unsigned kAllKinds = ~0u;

/// The closest intersection along a ray segment.
struct RayHit {
    double t_mm = 0.0;                    ///< distance along the (unit) ray direction
    SurfaceKind kind = SurfaceKind::none; ///< none: the segment hit nothing
    std::uint32_t prim_id = 0;            ///< triangle index within its SurfaceMesh
    Vec3 normal{0.0, 0.0, 0.0};           ///< unit geometric normal (winding order decides the
                                          ///< sign); zero for a degenerate triangle
    /// Unit shading normal on the same side as `normal`: on the inner surface the vertex
    /// normals (area-weighted) interpolated at the hit, elsewhere `normal`.
    Vec3 shading_normal{0.0, 0.0, 0.0};
    /// Barycentric coordinates of the hit in triangle `prim_id`: the point is
    /// (1 - u - v) p0 + u p1 + v p2 (the fast integrator's light cache interpolates with them).
    double u = 0.0, v = 0.0;
    bool hit() const { return kind != SurfaceKind::none; }
};

/// How `EmbreeScene::set_frame` brought the scene up to date.
enum class SceneUpdate : std::uint8_t {
    built,    ///< at least one geometry was (re)created: new topology, BVH built from scratch
    refitted, ///< same topology everywhere: vertices copied in place, BVHs refitted
};

/// Embree device + scene with the coating, inner-marker, outer-marker and inner-surface
/// triangle meshes.
/// Vertex and index arrays are owned here (Eigen, row-major, the vertex array padded by one
/// row as Embree requires) and shared with Embree without further copies. Ray queries are
/// thread-safe once `set_frame` has returned; `set_frame` itself must not run concurrently
/// with queries. Embree errors become std::runtime_error naming the call and Embree's message.
class EmbreeScene {
public:
    /// `device_config` is Embree's device configuration string ("" = defaults, e.g.
    /// "threads=4"). Throws std::runtime_error if Embree cannot create the device.
    explicit EmbreeScene(const std::string& device_config = "");
    ~EmbreeScene();
    EmbreeScene(const EmbreeScene&) = delete;
    EmbreeScene& operator=(const EmbreeScene&) = delete;

    /// Loads the frame. A mesh whose vertex count and triangle array equal the previous
    /// frame's is updated in place and refitted; any other mesh is rebuilt. Empty meshes
    /// are left out of the scene. Throws std::invalid_argument on out-of-range vertex
    /// indices or non-finite vertices (checked first: the previous frame stays loaded), and
    /// std::runtime_error on Embree errors.
    SceneUpdate set_frame(const SensorFrame& frame);

    /// True once a frame is loaded.
    bool has_frame() const;

    /// Closest hit of the ray origin + t * direction with t in [tnear_mm, tfar_mm], among the
    /// surfaces of the kinds in `kinds` (kind_bit; the others are passed through).
    /// `direction` must be unit length so that t is in mm. Pre-condition: has_frame().
    RayHit closest_hit(const Vec3& origin_mm, const Vec3& direction, double tnear_mm,
                       double tfar_mm, unsigned kinds = kAllKinds) const;

    /// Closest hits of up to 16 rays at once, origins[i] + t * directions[i] with t in
    /// [tnear_mm, tfar_mm]: one Embree 16-wide packet flagged coherent. The answers are
    /// closest_hit's ray by ray; coherent rays (the samples of one pixel) cost several times
    /// less (`chromasim bench render` prints both rates). Throws std::invalid_argument unless
    /// the three spans have one size, at most 16. Pre-condition: has_frame().
    void closest_hits16(std::span<const Vec3> origins_mm, std::span<const Vec3> directions,
                        double tnear_mm, double tfar_mm, std::span<RayHit> out) const;
    /// closest_hits16 against the inner surface alone (closest_interface_hit's BVH): for rays
    /// from a point in the cavity (in_cavity), whose first surface can only be the inner
    /// surface (every other surface lies in or beyond the layers it bounds).
    void closest_interface_hits16(std::span<const Vec3> origins_mm,
                                  std::span<const Vec3> directions, double tnear_mm, double tfar_mm,
                                  std::span<RayHit> out) const;

    /// Closest hit of the inner surface alone (the other surfaces are not in this query's
    /// BVH); kind none if the ray misses it or the frame has none.
    RayHit closest_interface_hit(const Vec3& origin_mm, const Vec3& direction, double tnear_mm,
                                 double tfar_mm) const;
    /// True when the loaded frame has an inner surface.
    bool has_interface() const;
    /// True when p lies in the cavity the inner surface bounds, so that a ray from p meets the
    /// inner surface first or no surface at all (closest_interface_hits16 then answers it as
    /// closest_hit does): the frame has an inner surface, p is on or above the rim plane, and
    /// nearer the centre than any point of the inner surface (a bound from below: per
    /// triangle, the least n . v over its corners v, n its outward unit normal). A camera
    /// posed outside the cavity (the spec allows up to 10 mm off the centre per axis) gets
    /// false, and its rays the whole scene.
    bool in_cavity(const Vec3& p_mm) const;
    /// Vertices and unit vertex normals of inner-surface triangle `prim`.
    struct Triangle {
        Vec3 p[3];
        Vec3 n[3];
    };
    Triangle interface_triangle(std::uint32_t prim) const;
    /// How many triangles the inner surface has (0 without one).
    std::uint32_t interface_triangles() const;

    /// The hits of the ray origin + t * direction, t in [tnear_mm, tfar_mm], among `kinds`,
    /// in one traversal: the closest hit of a kind other than the markers (coating, inner
    /// surface, or none), returned, and every marker hit before it, into `markers` (sorted
    /// by t; `count` gets how many there were, more than markers.size() if they did not
    /// fit). RayHits walks them in order. Pre-condition: has_frame().
    RayHit markers_then_hit(const Vec3& origin_mm, const Vec3& direction, double tnear_mm,
                            double tfar_mm, unsigned kinds, std::span<RayHit> markers,
                            std::size_t& count) const;

    /// Counting of traversals (closest_hit, markers_then_hit, and each ray of
    /// closest_hits16) for benchmarks (off by default; when off it costs one
    /// predictable branch per ray). Switching it on resets the count.
    void count_rays(bool on);
    std::uint64_t rays_counted() const;

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

/// A ray's hits in order of distance, as successive EmbreeScene::closest_hit calls with
/// growing tnear would give them, from one traversal (markers_then_hit) while they can, where
/// successive closest_hit calls take three traversals for a shadow ray through a marker
/// (entry, exit, nothing) and one per marker face plus the coating for a camera ray.
class RayHits {
public:
    RayHits(const EmbreeScene& scene, const Vec3& origin_mm, const Vec3& direction, double tnear_mm,
            double tfar_mm, unsigned kinds = kAllKinds);
    /// The closest hit at t >= tnear_mm (at least the tnear given so far; closest_hit's
    /// answer): from the traversal's, or, past a non-marker hit closer than tnear_mm (or
    /// markers that did not fit), by closest_hit.
    RayHit next(double tnear_mm);
    /// The most marker hits kept from the traversal.
    static constexpr std::size_t kMarkers = 8;

private:
    const EmbreeScene& m_scene;
    Vec3 m_origin, m_direction;
    double m_tfar;
    unsigned m_kinds;
    std::array<RayHit, kMarkers> m_markers;
    std::size_t m_count = 0, m_at = 0;
    RayHit m_end;
};

} // namespace chromasim::render::detail
