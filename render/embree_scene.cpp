#include "render/embree_scene.hpp"

#include <Eigen/Geometry>
#include <embree3/rtcore.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <tuple>

namespace chromasim::render::detail {

namespace {

constexpr std::array<SurfaceKind, 4> kKinds = {SurfaceKind::coating, SurfaceKind::inner_marker,
                                               SurfaceKind::outer_marker,
                                               SurfaceKind::inner_surface};

unsigned geometry_id(SurfaceKind kind) {
    return unsigned(kind) - 1;
}

const char* kind_name(SurfaceKind kind) {
    switch (kind) {
    case SurfaceKind::coating:
        return "coating";
    case SurfaceKind::inner_marker:
        return "inner_markers";
    case SurfaceKind::outer_marker:
        return "outer_markers";
    case SurfaceKind::inner_surface:
        return "inner_surface";
    case SurfaceKind::none:
        break;
    }
    return "none";
}

const char* error_name(RTCError code) {
    switch (code) {
    case RTC_ERROR_NONE:
        return "RTC_ERROR_NONE";
    case RTC_ERROR_UNKNOWN:
        return "RTC_ERROR_UNKNOWN";
    case RTC_ERROR_INVALID_ARGUMENT:
        return "RTC_ERROR_INVALID_ARGUMENT";
    case RTC_ERROR_INVALID_OPERATION:
        return "RTC_ERROR_INVALID_OPERATION";
    case RTC_ERROR_OUT_OF_MEMORY:
        return "RTC_ERROR_OUT_OF_MEMORY";
    case RTC_ERROR_UNSUPPORTED_CPU:
        return "RTC_ERROR_UNSUPPORTED_CPU";
    case RTC_ERROR_CANCELLED:
        return "RTC_ERROR_CANCELLED";
    }
    return "unrecognised RTCError";
}

/// Embree's text for the last error raised on this thread. The callback only records it:
/// throwing through Embree's C interface is not allowed, so `check` throws afterwards.
thread_local std::string t_last_error_message;

void record_error(void* /*user*/, RTCError /*code*/, const char* message) {
    t_last_error_message = message ? message : "";
}

/// Throws std::runtime_error if Embree reported an error since the previous check.
void check(RTCDevice device, const std::string& call) {
    const RTCError code = rtcGetDeviceError(device);
    if (code == RTC_ERROR_NONE) return;
    std::string message = "Embree error in " + call + ": " + error_name(code);
    if (!t_last_error_message.empty()) message += " (" + t_last_error_message + ")";
    t_last_error_message.clear();
    throw std::runtime_error(message);
}

/// Throws std::invalid_argument if a triangle indexes past the vertex array or a vertex is
/// not finite (Embree would read out of bounds or build a broken BVH).
void validate(const SurfaceMesh& mesh, SurfaceKind kind) {
    const std::string where = std::string("SensorFrame::") + kind_name(kind);
    if (mesh.F.size() > 0 && mesh.F.maxCoeff() >= std::uint64_t(mesh.V.rows())) {
        throw std::invalid_argument(where + ": vertex index " + std::to_string(mesh.F.maxCoeff()) +
                                    " is out of range; allowed: [0, " +
                                    std::to_string(mesh.V.rows()) + ")");
    }
    if (!mesh.V.allFinite()) {
        throw std::invalid_argument(where + ": vertex positions must be finite (found NaN/inf)");
    }
}

/// One Embree triangle geometry and the arrays it shares with Embree.
struct MeshSlot {
    RTCGeometry geometry = nullptr;
    VertexArray V;   ///< (#V + 1) x 3: the last row pads Embree's 16-byte vertex loads
    TriangleArray F; ///< #F x 3
    Eigen::Index vertex_count = 0;
    VertexArray N; ///< unit vertex normals (inner surface only), area-weighted by winding

    bool has_topology_of(const SurfaceMesh& mesh) const {
        return geometry && vertex_count == mesh.V.rows() && F.rows() == mesh.F.rows() &&
               F == mesh.F;
    }
};

/// Area-weighted vertex normals of the slot's triangles (a vertex of no triangle gets zero).
void update_vertex_normals(MeshSlot& slot) {
    slot.N.setZero(slot.vertex_count, 3);
    for (Eigen::Index f = 0; f < slot.F.rows(); ++f) {
        const Eigen::RowVector3f a = slot.V.row(slot.F(f, 0)), b = slot.V.row(slot.F(f, 1)),
                                 c = slot.V.row(slot.F(f, 2));
        const Eigen::RowVector3f area_normal = (b - a).cross(c - a); // 2 x area, by winding
        for (int k = 0; k < 3; ++k)
            slot.N.row(slot.F(f, k)) += area_normal;
    }
    for (Eigen::Index v = 0; v < slot.vertex_count; ++v) {
        const float length = slot.N.row(v).norm();
        if (length > 0.0f) slot.N.row(v) /= length;
    }
}

RTCRayHit make_query(const Vec3& origin_mm, const Vec3& direction, double tnear_mm,
                     double tfar_mm) {
    RTCRayHit query{};
    query.ray.org_x = float(origin_mm.x());
    query.ray.org_y = float(origin_mm.y());
    query.ray.org_z = float(origin_mm.z());
    query.ray.dir_x = float(direction.x());
    query.ray.dir_y = float(direction.y());
    query.ray.dir_z = float(direction.z());
    query.ray.tnear = float(tnear_mm);
    query.ray.tfar = float(tfar_mm);
    query.ray.mask = std::numeric_limits<unsigned>::max();
    query.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    query.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    return query;
}

/// A bound from below on |x| over the points x of the mesh's triangles: per triangle the least
/// n . v over its corners, n a unit vector with n . (corners' sum) >= 0 (its normal; the sum's
/// direction if it has none); x is a convex combination of the corners, so |x| >= n . x >= that
/// least value. Less a round-off margin; 0 for no triangle or a bound below 0.
double cavity_radius(const SurfaceMesh& mesh) {
    double bound = std::numeric_limits<double>::infinity();
    for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
        std::array<Eigen::Vector3d, 3> v;
        for (int a = 0; a < 3; ++a)
            v[std::size_t(a)] = mesh.V.row(mesh.F(f, a)).cast<double>().transpose();
        Eigen::Vector3d n = (v[1] - v[0]).cross(v[2] - v[0]).normalized();
        const Eigen::Vector3d sum = v[0] + v[1] + v[2];
        if (!n.allFinite()) n = sum.normalized();
        if (!n.allFinite()) return 0.0; // a triangle at the centre
        if (n.dot(sum) < 0.0) n = -n;
        bound = std::min({bound, n.dot(v[0]), n.dot(v[1]), n.dot(v[2])});
    }
    return std::isfinite(bound) ? std::max(0.0, bound * (1.0 - 1e-9) - 1e-9) : 0.0;
}

} // namespace

struct EmbreeScene::Impl {
    RTCDevice device = nullptr;
    RTCScene scene = nullptr;
    std::array<MeshSlot, 4> slots; ///< indexed by Embree geometry ID
    /// The inner surface alone (a second geometry on the same shared buffers), for the
    /// path integrator's connections through the interface.
    RTCScene interface_scene = nullptr;
    RTCGeometry interface_geometry = nullptr;
    bool has_frame = false;
    /// A bound from below on the distance of the inner surface's points from the centre
    /// (in_cavity); 0 without an inner surface.
    double cavity_radius_mm = 0.0;
    bool counting = false;                      ///< count_rays
    mutable std::atomic<std::uint64_t> rays{0}; ///< closest_hit calls while counting

    explicit Impl(const std::string& device_config);
    ~Impl();
    void release(MeshSlot& slot, unsigned id);
    void create(MeshSlot& slot, const SurfaceMesh& mesh, unsigned id);
    void refit(MeshSlot& slot, const SurfaceMesh& mesh);
    /// A triangle geometry on the slot's buffers, hit by the rays whose `kinds` hold `mask`.
    RTCGeometry new_triangle_geometry(const MeshSlot& slot, unsigned mask);
    void set_interface(bool present, bool rebuilt);
    RayHit to_hit(const RTCRayHit& query) const;
    /// closest_hits16 in scene `in` (scene or interface_scene).
    void hits16(RTCScene in, std::span<const Vec3> origins_mm, std::span<const Vec3> directions,
                double tnear_mm, double tfar_mm, std::span<RayHit> out) const;
};

EmbreeScene::Impl::Impl(const std::string& device_config) {
    device = rtcNewDevice(device_config.c_str());
    if (!device) {
        throw std::runtime_error("Embree error in rtcNewDevice(\"" + device_config +
                                 "\"): " + error_name(rtcGetDeviceError(nullptr)) +
                                 " (check the device configuration string)");
    }
    rtcSetDeviceErrorFunction(device, record_error, nullptr);
    scene = rtcNewScene(device);
    // Two-level BVH (LOW) so that each geometry keeps its own BVH and honours the per-geometry
    // REFIT quality; ROBUST keeps rays through shared vertices and edges (marker fan centres)
    // from slipping through.
    rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_LOW);
    // CONTEXT_FILTER_FUNCTION: markers_then_hit's filter collects the marker hits.
    rtcSetSceneFlags(scene, RTC_SCENE_FLAG_DYNAMIC | RTC_SCENE_FLAG_ROBUST |
                                RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION);
    rtcCommitScene(scene); // an empty but valid scene: queries before set_frame miss
    interface_scene = rtcNewScene(device);
    rtcSetSceneBuildQuality(interface_scene, RTC_BUILD_QUALITY_LOW);
    rtcSetSceneFlags(interface_scene, RTC_SCENE_FLAG_DYNAMIC | RTC_SCENE_FLAG_ROBUST);
    rtcCommitScene(interface_scene);
    check(device, "creating the scene");
}

EmbreeScene::Impl::~Impl() {
    for (MeshSlot& slot : slots) {
        if (slot.geometry) rtcReleaseGeometry(slot.geometry);
    }
    if (interface_geometry) rtcReleaseGeometry(interface_geometry);
    if (scene) rtcReleaseScene(scene);
    if (interface_scene) rtcReleaseScene(interface_scene);
    if (device) rtcReleaseDevice(device);
}

void EmbreeScene::Impl::release(MeshSlot& slot, unsigned id) {
    if (!slot.geometry) return;
    rtcDetachGeometry(scene, id);
    rtcReleaseGeometry(slot.geometry);
    slot.geometry = nullptr;
    slot.vertex_count = 0;
    check(device, "detaching geometry " + std::to_string(id));
}

void EmbreeScene::Impl::create(MeshSlot& slot, const SurfaceMesh& mesh, unsigned id) {
    release(slot, id);
    slot.vertex_count = mesh.V.rows();
    slot.V.resize(slot.vertex_count + 1, 3);
    slot.V.topRows(slot.vertex_count) = mesh.V;
    slot.V.bottomRows(1).setZero();
    slot.F = mesh.F;
    slot.geometry = new_triangle_geometry(slot, kind_bit(SurfaceKind(id + 1)));
    rtcAttachGeometryByID(scene, slot.geometry, id);
    check(device, "creating geometry " + std::to_string(id));
}

RTCGeometry EmbreeScene::Impl::new_triangle_geometry(const MeshSlot& slot, unsigned mask) {
    RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    rtcSetGeometryMask(geometry, mask);
    rtcSetGeometryBuildQuality(geometry, RTC_BUILD_QUALITY_REFIT);
    rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                               slot.V.data(), 0, 3 * sizeof(float), size_t(slot.vertex_count));
    rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, slot.F.data(),
                               0, 3 * sizeof(std::uint32_t), size_t(slot.F.rows()));
    rtcCommitGeometry(geometry);
    return geometry;
}

/// Brings the interface-only scene in line with the inner-surface slot: a new geometry on the
/// slot's buffers after a rebuild, a refit after a refit.
void EmbreeScene::Impl::set_interface(bool present, bool rebuilt) {
    if (interface_geometry && (rebuilt || !present)) {
        rtcDetachGeometry(interface_scene, 0);
        rtcReleaseGeometry(interface_geometry);
        interface_geometry = nullptr;
    }
    if (present && !interface_geometry) {
        interface_geometry = new_triangle_geometry(slots[geometry_id(SurfaceKind::inner_surface)],
                                                   kind_bit(SurfaceKind::inner_surface));
        rtcAttachGeometryByID(interface_scene, interface_geometry, 0);
    } else if (present) {
        rtcUpdateGeometryBuffer(interface_geometry, RTC_BUFFER_TYPE_VERTEX, 0);
        rtcCommitGeometry(interface_geometry);
    }
    rtcCommitScene(interface_scene);
    check(device, "updating the interface scene");
}

void EmbreeScene::Impl::refit(MeshSlot& slot, const SurfaceMesh& mesh) {
    slot.V.topRows(slot.vertex_count) = mesh.V;
    rtcUpdateGeometryBuffer(slot.geometry, RTC_BUFFER_TYPE_VERTEX, 0);
    rtcCommitGeometry(slot.geometry);
    check(device, "updating vertices");
}

EmbreeScene::EmbreeScene(const std::string& device_config)
    : m_impl(std::make_unique<Impl>(device_config)) {}

EmbreeScene::~EmbreeScene() = default;

bool EmbreeScene::has_frame() const {
    return m_impl->has_frame;
}

SceneUpdate EmbreeScene::set_frame(const SensorFrame& frame) {
    const std::array<const SurfaceMesh*, 4> meshes = {&frame.coating, &frame.inner_markers,
                                                      &frame.outer_markers, &frame.inner_surface};
    for (SurfaceKind kind : kKinds)
        validate(*meshes[geometry_id(kind)], kind);

    m_impl->has_frame = false; // until the commit below succeeds
    SceneUpdate update = SceneUpdate::refitted;
    bool interface_rebuilt = false;
    for (SurfaceKind kind : kKinds) {
        const unsigned id = geometry_id(kind);
        MeshSlot& slot = m_impl->slots[id];
        const SurfaceMesh& mesh = *meshes[id];
        if (mesh.F.rows() == 0) {
            if (slot.geometry) update = SceneUpdate::built;
            m_impl->release(slot, id);
        } else if (slot.has_topology_of(mesh)) {
            m_impl->refit(slot, mesh);
        } else {
            m_impl->create(slot, mesh, id);
            update = SceneUpdate::built;
            if (kind == SurfaceKind::inner_surface) interface_rebuilt = true;
        }
        if (kind == SurfaceKind::inner_surface && slot.geometry) update_vertex_normals(slot);
    }
    m_impl->set_interface(frame.inner_surface.F.rows() > 0, interface_rebuilt);
    m_impl->cavity_radius_mm = cavity_radius(frame.inner_surface);
    rtcCommitScene(m_impl->scene);
    check(m_impl->device, "rtcCommitScene");
    m_impl->has_frame = true;
    return update;
}

RayHit EmbreeScene::closest_hit(const Vec3& origin_mm, const Vec3& direction, double tnear_mm,
                                double tfar_mm, unsigned kinds) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRayHit query = make_query(origin_mm, direction, tnear_mm, tfar_mm);
    query.ray.mask = kinds;
    rtcIntersect1(m_impl->scene, &context, &query);
    if (m_impl->counting) m_impl->rays.fetch_add(1, std::memory_order_relaxed);
    return m_impl->to_hit(query);
}

namespace {

/// markers_then_hit's intersection context: Embree hands the filter a pointer to `context`,
/// the first member, so the filter finds the rest.
struct MarkerCollector {
    RTCIntersectContext context;
    std::span<RayHit> markers;
    std::size_t count = 0;
};

/// Every marker hit Embree finds is recorded and rejected, so the traversal goes on past it;
/// any other hit is accepted and shortens the ray as usual. Embree reports every primitive
/// the ray meets before the accepted closest hit (its BVH only prunes beyond tfar), so every
/// marker hit before it is recorded.
void collect_markers(const RTCFilterFunctionNArguments* args) {
    for (unsigned i = 0; i < args->N; ++i) {
        if (args->valid[i] == 0) continue;
        const auto kind = SurfaceKind(RTCHitN_geomID(args->hit, args->N, i) + 1);
        if (kind != SurfaceKind::inner_marker && kind != SurfaceKind::outer_marker) continue;
        auto* collector = reinterpret_cast<MarkerCollector*>(args->context);
        if (collector->count < collector->markers.size()) {
            RayHit& hit = collector->markers[collector->count];
            hit.t_mm = RTCRayN_tfar(args->ray, args->N, i);
            hit.kind = kind;
            hit.prim_id = RTCHitN_primID(args->hit, args->N, i);
            hit.normal =
                Vec3(RTCHitN_Ng_x(args->hit, args->N, i), RTCHitN_Ng_y(args->hit, args->N, i),
                     RTCHitN_Ng_z(args->hit, args->N, i))
                    .normalized();
            hit.shading_normal = hit.normal;
            hit.u = RTCHitN_u(args->hit, args->N, i);
            hit.v = RTCHitN_v(args->hit, args->N, i);
        }
        ++collector->count;
        args->valid[i] = 0;
    }
}

} // namespace

RayHit EmbreeScene::markers_then_hit(const Vec3& origin_mm, const Vec3& direction, double tnear_mm,
                                     double tfar_mm, unsigned kinds, std::span<RayHit> markers,
                                     std::size_t& count) const {
    MarkerCollector collector;
    rtcInitIntersectContext(&collector.context);
    collector.context.filter = collect_markers;
    collector.markers = markers;
    RTCRayHit query = make_query(origin_mm, direction, tnear_mm, tfar_mm);
    query.ray.mask = kinds;
    rtcIntersect1(m_impl->scene, &collector.context, &query);
    if (m_impl->counting) m_impl->rays.fetch_add(1, std::memory_order_relaxed);
    count = collector.count;
    // In order of t; ties (a ray through an edge two triangles share) by kind and triangle,
    // so the order does not depend on Embree's.
    const auto kept = markers.first(std::min(count, markers.size()));
    std::sort(kept.begin(), kept.end(), [](const RayHit& a, const RayHit& b) {
        return std::tie(a.t_mm, a.kind, a.prim_id) < std::tie(b.t_mm, b.kind, b.prim_id);
    });
    return m_impl->to_hit(query);
}

RayHits::RayHits(const EmbreeScene& scene, const Vec3& origin_mm, const Vec3& direction,
                 double tnear_mm, double tfar_mm, unsigned kinds)
    : m_scene(scene), m_origin(origin_mm), m_direction(direction), m_tfar(tfar_mm), m_kinds(kinds) {
    m_end =
        scene.markers_then_hit(origin_mm, direction, tnear_mm, tfar_mm, kinds, m_markers, m_count);
}

RayHit RayHits::next(double tnear_mm) {
    if (m_count <= m_markers.size()) {
        while (m_at < m_count && m_markers[m_at].t_mm < tnear_mm)
            ++m_at;
        const bool before_end =
            !m_end.hit() || (m_at < m_count && m_markers[m_at].t_mm <= m_end.t_mm);
        if (m_at < m_count && before_end) return m_markers[m_at++];
        if (!m_end.hit() || m_end.t_mm >= tnear_mm) return m_end;
    }
    // Past the traversal's end (closer than tnear_mm), or more markers than were kept.
    return m_scene.closest_hit(m_origin, m_direction, tnear_mm, m_tfar, m_kinds);
}

void EmbreeScene::closest_hits16(std::span<const Vec3> origins_mm, std::span<const Vec3> directions,
                                 double tnear_mm, double tfar_mm, std::span<RayHit> out) const {
    m_impl->hits16(m_impl->scene, origins_mm, directions, tnear_mm, tfar_mm, out);
}

void EmbreeScene::closest_interface_hits16(std::span<const Vec3> origins_mm,
                                           std::span<const Vec3> directions, double tnear_mm,
                                           double tfar_mm, std::span<RayHit> out) const {
    m_impl->hits16(m_impl->interface_scene, origins_mm, directions, tnear_mm, tfar_mm, out);
}

void EmbreeScene::Impl::hits16(RTCScene in, std::span<const Vec3> origins_mm,
                               std::span<const Vec3> directions, double tnear_mm, double tfar_mm,
                               std::span<RayHit> out) const {
    const std::size_t count = origins_mm.size();
    if (directions.size() != count || out.size() != count || count > 16)
        throw std::invalid_argument("EmbreeScene::closest_hits16: " + std::to_string(count) +
                                    " origins, " + std::to_string(directions.size()) +
                                    " directions, " + std::to_string(out.size()) +
                                    " results; allowed: one size, at most 16");
    if (count == 0) return;
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    alignas(64) RTCRayHit16 packet;
    alignas(64) int valid[16];
    for (std::size_t k = 0; k < 16; ++k) {
        // Lanes past `count` are inactive; they repeat lane 0 so that every field is finite.
        const std::size_t i = k < count ? k : 0;
        const RTCRayHit one = make_query(origins_mm[i], directions[i], tnear_mm, tfar_mm);
        valid[k] = k < count ? -1 : 0;
        packet.ray.org_x[k] = one.ray.org_x;
        packet.ray.org_y[k] = one.ray.org_y;
        packet.ray.org_z[k] = one.ray.org_z;
        packet.ray.dir_x[k] = one.ray.dir_x;
        packet.ray.dir_y[k] = one.ray.dir_y;
        packet.ray.dir_z[k] = one.ray.dir_z;
        packet.ray.tnear[k] = one.ray.tnear;
        packet.ray.tfar[k] = one.ray.tfar;
        packet.ray.time[k] = one.ray.time;
        packet.ray.mask[k] = one.ray.mask;
        packet.ray.id[k] = unsigned(k);
        packet.ray.flags[k] = one.ray.flags;
        packet.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
        packet.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
    }
    rtcIntersect16(valid, in, &context, &packet);
    if (counting) rays.fetch_add(count, std::memory_order_relaxed);
    for (std::size_t k = 0; k < count; ++k) {
        RTCRayHit one{};
        one.ray.tfar = packet.ray.tfar[k];
        // The interface scene's one geometry is the inner surface.
        one.hit.geomID = in == interface_scene && packet.hit.geomID[k] != RTC_INVALID_GEOMETRY_ID
                             ? geometry_id(SurfaceKind::inner_surface)
                             : packet.hit.geomID[k];
        one.hit.primID = packet.hit.primID[k];
        one.hit.Ng_x = packet.hit.Ng_x[k];
        one.hit.Ng_y = packet.hit.Ng_y[k];
        one.hit.Ng_z = packet.hit.Ng_z[k];
        one.hit.u = packet.hit.u[k];
        one.hit.v = packet.hit.v[k];
        out[k] = to_hit(one);
    }
}

RayHit EmbreeScene::closest_interface_hit(const Vec3& origin_mm, const Vec3& direction,
                                          double tnear_mm, double tfar_mm) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRayHit query = make_query(origin_mm, direction, tnear_mm, tfar_mm);
    rtcIntersect1(m_impl->interface_scene, &context, &query);
    if (m_impl->counting) m_impl->rays.fetch_add(1, std::memory_order_relaxed);
    if (query.hit.geomID != RTC_INVALID_GEOMETRY_ID)
        query.hit.geomID = geometry_id(SurfaceKind::inner_surface);
    return m_impl->to_hit(query);
}

RayHit EmbreeScene::Impl::to_hit(const RTCRayHit& query) const {
    RayHit hit;
    if (query.hit.geomID == RTC_INVALID_GEOMETRY_ID) return hit;
    hit.t_mm = query.ray.tfar;
    hit.kind = SurfaceKind(query.hit.geomID + 1);
    hit.prim_id = query.hit.primID;
    hit.normal = Vec3(query.hit.Ng_x, query.hit.Ng_y, query.hit.Ng_z).normalized();
    hit.shading_normal = hit.normal;
    hit.u = query.hit.u;
    hit.v = query.hit.v;
    if (hit.kind == SurfaceKind::inner_surface) {
        const MeshSlot& slot = slots[geometry_id(SurfaceKind::inner_surface)];
        const auto f = slot.F.row(hit.prim_id);
        const double u = query.hit.u, v = query.hit.v;
        const Vec3 n =
            ((1.0 - u - v) * slot.N.row(f(0)) + u * slot.N.row(f(1)) + v * slot.N.row(f(2)))
                .cast<double>()
                .transpose();
        // Keep the shading normal on the geometric normal's side whatever the conventions.
        const double length = n.norm();
        if (length > 0.0) hit.shading_normal = (n.dot(hit.normal) < 0.0 ? -n : n) / length;
    }
    return hit;
}

bool EmbreeScene::has_interface() const {
    return m_impl->interface_geometry != nullptr;
}

bool EmbreeScene::in_cavity(const Vec3& p_mm) const {
    return has_interface() && p_mm.z() >= 0.0 && p_mm.norm() < m_impl->cavity_radius_mm;
}

EmbreeScene::Triangle EmbreeScene::interface_triangle(std::uint32_t prim) const {
    const MeshSlot& slot = m_impl->slots[geometry_id(SurfaceKind::inner_surface)];
    Triangle t;
    for (int k = 0; k < 3; ++k) {
        t.p[k] = slot.V.row(slot.F(prim, k)).cast<double>().transpose();
        t.n[k] = slot.N.row(slot.F(prim, k)).cast<double>().transpose();
    }
    return t;
}

std::uint32_t EmbreeScene::interface_triangles() const {
    if (!has_interface()) return 0;
    return std::uint32_t(m_impl->slots[geometry_id(SurfaceKind::inner_surface)].F.rows());
}

void EmbreeScene::count_rays(bool on) {
    m_impl->rays.store(0);
    m_impl->counting = on;
}

std::uint64_t EmbreeScene::rays_counted() const {
    return m_impl->rays.load();
}

} // namespace chromasim::render::detail
