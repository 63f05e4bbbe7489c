#include "generators/io/gltf_io.hpp"

#include "generators/io/gltf_detail.hpp"

// The one file that includes tinygltf. Debian's libtinygltf carries the implementation, so
// TINYGLTF_IMPLEMENTATION is not defined here (and no stb or JSON header is needed).
#include <tiny_gltf.h>

#include <Eigen/Dense>
#include <Eigen/Geometry>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <numbers>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

namespace chromasim::generators {

namespace fs = std::filesystem;

namespace {

using detail::AccessorBytes;
using detail::fail;
using detail::IndexTriangles;

// gltf_mesh.cpp decodes accessors and primitives with the spec's numbers.
static_assert(detail::kComponentByte == TINYGLTF_COMPONENT_TYPE_BYTE &&
              detail::kComponentUnsignedByte == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
              detail::kComponentShort == TINYGLTF_COMPONENT_TYPE_SHORT &&
              detail::kComponentUnsignedShort == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
              detail::kComponentInt == TINYGLTF_COMPONENT_TYPE_INT &&
              detail::kComponentUnsignedInt == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT &&
              detail::kComponentFloat == TINYGLTF_COMPONENT_TYPE_FLOAT &&
              detail::kComponentDouble == TINYGLTF_COMPONENT_TYPE_DOUBLE);
static_assert(detail::kModeTriangles == TINYGLTF_MODE_TRIANGLES &&
              detail::kModeTriangleStrip == TINYGLTF_MODE_TRIANGLE_STRIP &&
              detail::kModeTriangleFan == TINYGLTF_MODE_TRIANGLE_FAN);

std::string trimmed(std::string s) {
    while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back())))
        s.pop_back();
    return s;
}

// ---- Loading --------------------------------------------------------------------------------

tinygltf::Model parse(const fs::path& file) {
    const std::vector<unsigned char> bytes = detail::read_bytes(file);
    tinygltf::TinyGLTF loader;
    tinygltf::Model model;
    std::string err, warn;
    const std::string base_dir = file.parent_path().string();
    const bool binary = bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0;
    const bool ok = binary ? loader.LoadBinaryFromMemory(&model, &err, &warn, bytes.data(),
                                                         unsigned(bytes.size()), base_dir)
                           : loader.LoadASCIIFromString(&model, &err, &warn,
                                                        reinterpret_cast<const char*>(bytes.data()),
                                                        unsigned(bytes.size()), base_dir);
    if (!ok)
        fail(file, std::string("not a valid glTF 2.0 ") +
                       (binary ? "binary (.glb)" : "JSON (.gltf)") +
                       " file: " + (err.empty() ? "tinygltf gave no reason" : trimmed(err)));
    if (!model.extensionsRequired.empty()) {
        std::string names;
        for (const auto& e : model.extensionsRequired)
            names += (names.empty() ? "" : ", ") + e;
        fail(file, "requires glTF extension(s) " + names +
                       "; chromasim reads plain glTF 2.0 meshes without required extensions");
    }
    return model;
}

AccessorBytes accessor_bytes(const fs::path& file, const tinygltf::Model& model, int index,
                             int type, const std::string& what) {
    const std::string where = "accessor " + std::to_string(index) + " (" + what + ")";
    if (index < 0 || std::size_t(index) >= model.accessors.size())
        fail(file, where + " does not exist");
    const tinygltf::Accessor& a = model.accessors[std::size_t(index)];
    if (a.sparse.isSparse)
        fail(file,
             where + " is sparse; sparse accessors are not supported, store the data densely");
    if (a.bufferView < 0 || std::size_t(a.bufferView) >= model.bufferViews.size())
        fail(file, where + " has no valid bufferView; every accessor must point into a buffer");
    if (a.type != type)
        fail(file, where + " has type " + std::to_string(a.type) + "; " + what + " must be " +
                       (type == TINYGLTF_TYPE_VEC3 ? "VEC3" : "SCALAR"));
    const tinygltf::BufferView& view = model.bufferViews[std::size_t(a.bufferView)];
    if (view.buffer < 0 || std::size_t(view.buffer) >= model.buffers.size())
        fail(file, where + ": bufferView " + std::to_string(a.bufferView) + " has no valid buffer");
    const auto& buffer = model.buffers[std::size_t(view.buffer)].data;
    const int component_size = tinygltf::GetComponentSizeInBytes(std::uint32_t(a.componentType));
    if (component_size <= 0) fail(file, where + " has an unknown component type");
    const std::size_t element = std::size_t(component_size) * (type == TINYGLTF_TYPE_VEC3 ? 3 : 1);
    const std::size_t stride = view.byteStride ? view.byteStride : element;
    const std::size_t end = a.count == 0 ? 0 : a.byteOffset + stride * (a.count - 1) + element;
    if (stride < element || view.byteOffset + view.byteLength > buffer.size() ||
        end > view.byteLength)
        fail(file, where + " reaches past the end of its bufferView or buffer (count " +
                       std::to_string(a.count) + ", byteStride " + std::to_string(stride) + ")");
    return {buffer.data() + view.byteOffset + a.byteOffset, stride, a.count, a.componentType};
}

std::vector<Eigen::Vector3d> read_positions(const fs::path& file, const tinygltf::Model& model,
                                            int index, const std::string& what) {
    const AccessorBytes a = accessor_bytes(file, model, index, TINYGLTF_TYPE_VEC3, what);
    return detail::decode_positions(file, a, index, what);
}

std::vector<std::uint32_t> read_indices(const fs::path& file, const tinygltf::Model& model,
                                        int index, const std::string& what) {
    const AccessorBytes a = accessor_bytes(file, model, index, TINYGLTF_TYPE_SCALAR, what);
    return detail::decode_indices(file, a, index, what);
}

// Local transform of a node: its matrix, else translation * rotation * scale.
Eigen::Affine3d local_transform(const tinygltf::Node& node) {
    Eigen::Affine3d m = Eigen::Affine3d::Identity();
    if (node.matrix.size() == 16) {
        m.matrix() = Eigen::Map<const Eigen::Matrix4d>(node.matrix.data()); // column-major
        return m;
    }
    if (node.translation.size() == 3)
        m.translate(Eigen::Vector3d(node.translation[0], node.translation[1], node.translation[2]));
    if (node.rotation.size() == 4) // glTF stores x, y, z, w
        m.rotate(Eigen::Quaterniond(node.rotation[3], node.rotation[0], node.rotation[1],
                                    node.rotation[2])
                     .normalized());
    if (node.scale.size() == 3)
        m.scale(Eigen::Vector3d(node.scale[0], node.scale[1], node.scale[2]));
    return m;
}

// Calls visit(node index, node, world transform) for every node of scene `scene`, parents
// before children; rejects nodes that do not exist or are reached twice.
template <class Visit>
void walk_scene(const fs::path& file, const tinygltf::Model& model, int scene, Visit&& visit) {
    std::vector<bool> visited(model.nodes.size(), false);
    const auto walk = [&](const auto& self, int index, const Eigen::Affine3d& parent) -> void {
        if (index < 0 || std::size_t(index) >= model.nodes.size())
            fail(file, "node " + std::to_string(index) + " does not exist");
        if (visited[std::size_t(index)])
            fail(file, "node " + std::to_string(index) +
                           " is reached twice; glTF nodes must form disjoint trees");
        visited[std::size_t(index)] = true;
        const tinygltf::Node& node = model.nodes[std::size_t(index)];
        const Eigen::Affine3d world = parent * local_transform(node);
        visit(index, node, world);
        for (int child : node.children)
            self(self, child, world);
    };
    for (int root : model.scenes[std::size_t(scene)].nodes)
        walk(walk, root, Eigen::Affine3d::Identity());
}

// The default scene (scene 0 if none is named), checked.
int default_scene(const fs::path& file, const tinygltf::Model& model) {
    const int scene = model.defaultScene >= 0 ? model.defaultScene : 0;
    if (std::size_t(scene) >= model.scenes.size())
        fail(file, model.scenes.empty()
                       ? "no scene; the objects are read from the default scene"
                       : "default scene " + std::to_string(scene) + " does not exist");
    return scene;
}

// The mesh of node `index` (which has one), checked.
const tinygltf::Mesh& node_mesh(const fs::path& file, const tinygltf::Model& model, int index,
                                const tinygltf::Node& node) {
    if (std::size_t(node.mesh) >= model.meshes.size())
        fail(file, "node " + std::to_string(index) + " uses mesh " + std::to_string(node.mesh) +
                       ", which does not exist");
    return model.meshes[std::size_t(node.mesh)];
}

// The triangles of a primitive with `vertices` POSITION entries: its indices (0, 1, ... if it
// has none) in the order of its mode, each checked against `vertices`.
IndexTriangles primitive_triangles(const fs::path& file, const tinygltf::Model& model,
                                   const tinygltf::Primitive& p, const std::string& what,
                                   std::size_t vertices) {
    std::vector<std::uint32_t> idx;
    if (p.indices >= 0)
        idx = read_indices(file, model, p.indices, what + " indices");
    else
        for (std::uint32_t k = 0; k < vertices; ++k)
            idx.push_back(k);
    auto triangles = detail::triangle_indices(idx, p.mode);
    for (const auto& t : triangles)
        for (std::uint32_t i : t)
            if (i >= vertices)
                fail(file, what + ": index " + std::to_string(i) + " is out of range [0, " +
                               std::to_string(vertices) +
                               "); indices must refer to entries of POSITION");
    return triangles;
}

// The primitives of a scene's nodes, read into one surface (detail::SurfaceAssembly).
class SurfaceBuilder {
public:
    SurfaceBuilder(const fs::path& file, const tinygltf::Model& model, double scale_to_mm)
        : surface(scale_to_mm), m_file(file), m_model(model) {}

    void add_node(int index, const tinygltf::Node& node, const Eigen::Affine3d& world);

    detail::SurfaceAssembly surface;

private:
    void add_primitive(const tinygltf::Primitive& p, const std::string& what,
                       const Eigen::Affine3d& world);

    const fs::path& m_file;
    const tinygltf::Model& m_model;
};

void SurfaceBuilder::add_node(int index, const tinygltf::Node& node, const Eigen::Affine3d& world) {
    if (node.mesh < 0) return;
    const auto& primitives = node_mesh(m_file, m_model, index, node).primitives;
    for (std::size_t k = 0; k < primitives.size(); ++k)
        add_primitive(primitives[k],
                      "mesh " + std::to_string(node.mesh) + " primitive " + std::to_string(k),
                      world);
}

void SurfaceBuilder::add_primitive(const tinygltf::Primitive& p, const std::string& what,
                                   const Eigen::Affine3d& world) {
    if (p.mode < 0 || p.mode > TINYGLTF_MODE_TRIANGLE_FAN)
        fail(m_file, what + " has mode " + std::to_string(p.mode) + "; glTF modes are 0 to 6");
    if (p.mode < TINYGLTF_MODE_TRIANGLES) { // points and lines have no area
        surface.skip(p.mode);
        return;
    }
    const auto position = p.attributes.find("POSITION");
    if (position == p.attributes.end()) fail(m_file, what + " has no POSITION attribute");
    const auto P = read_positions(m_file, m_model, position->second, what + " POSITION");
    surface.add(P, primitive_triangles(m_file, m_model, p, what, P.size()), world);
}

// ---- Writing --------------------------------------------------------------------------------

template <class T> void append_bytes(std::vector<unsigned char>& out, const T& value) {
    const auto* p = reinterpret_cast<const unsigned char*>(&value);
    out.insert(out.end(), p, p + sizeof(T));
}

// The model's one buffer, grown view by view; every view starts 4-byte aligned and carries
// one accessor.
class BufferWriter {
public:
    explicit BufferWriter(tinygltf::Model& model) : m_model(model) {}

    // X (#X x 3) times `scale` as a FLOAT VEC3 accessor; with the min and max that glTF
    // requires for POSITION, taken from the stored floats, if `bounds`. Returns its index.
    template <class Derived>
    int add_vec3(const Eigen::MatrixBase<Derived>& X, double scale, bool bounds) {
        const std::size_t begin = start_view();
        tinygltf::Accessor a;
        a.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
        a.type = TINYGLTF_TYPE_VEC3;
        a.count = std::size_t(X.rows());
        std::vector<double> lo(3, std::numeric_limits<double>::infinity()), hi(3, -lo[0]);
        for (Eigen::Index v = 0; v < X.rows(); ++v)
            for (std::size_t k = 0; k < 3; ++k) {
                const float x = float(double(X(v, Eigen::Index(k))) * scale);
                append_bytes(m_data, x);
                lo[k] = std::min(lo[k], double(x));
                hi[k] = std::max(hi[k], double(x));
            }
        if (bounds) {
            a.minValues = lo;
            a.maxValues = hi;
        }
        return add_accessor(std::move(a), begin, TINYGLTF_TARGET_ARRAY_BUFFER);
    }

    // Triangle indices F (#F x 3), UNSIGNED_SHORT when vertices < 65535 (65535 itself is
    // reserved for primitive restart in glTF 2.0), else UNSIGNED_INT. Returns its index.
    template <class Derived>
    int add_indices(const Eigen::MatrixBase<Derived>& F, Eigen::Index vertices) {
        const std::size_t begin = start_view();
        const bool short_indices = vertices < 65535;
        for (Eigen::Index f = 0; f < F.rows(); ++f)
            for (Eigen::Index k = 0; k < 3; ++k)
                if (short_indices)
                    append_bytes(m_data, std::uint16_t(F(f, k)));
                else
                    append_bytes(m_data, std::uint32_t(F(f, k)));
        tinygltf::Accessor a;
        a.componentType = short_indices ? TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT
                                        : TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
        a.type = TINYGLTF_TYPE_SCALAR;
        a.count = std::size_t(F.size());
        return add_accessor(std::move(a), begin, TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
    }

    // Pads the data to 4 bytes and stores it as the model's buffer 0 (no buffer if nothing
    // was added: a glTF buffer holds at least one byte).
    void finish() {
        start_view();
        if (!m_data.empty()) m_model.buffers.emplace_back().data = std::move(m_data);
    }

private:
    std::size_t start_view() {
        while (m_data.size() % 4 != 0)
            m_data.push_back(0);
        return m_data.size();
    }
    int add_accessor(tinygltf::Accessor a, std::size_t begin, int target) {
        tinygltf::BufferView view;
        view.buffer = 0;
        view.byteOffset = begin;
        view.byteLength = m_data.size() - begin;
        view.target = target;
        a.bufferView = int(m_model.bufferViews.size());
        m_model.bufferViews.push_back(view);
        m_model.accessors.push_back(std::move(a));
        return int(m_model.accessors.size()) - 1;
    }

    tinygltf::Model& m_model;
    std::vector<unsigned char> m_data;
};

tinygltf::Model new_model() {
    tinygltf::Model m;
    m.asset.version = "2.0";
    m.asset.generator = "chromasim " CHROMASIM_VERSION;
    return m;
}

// One buffer, two views, two accessors, one mesh of one TRIANGLES primitive, one node, one
// scene.
tinygltf::Model surface_model(const mechanics::TriangleSurface& surface, double mm_to_unit) {
    tinygltf::Model m = new_model();
    BufferWriter buffer(m);
    tinygltf::Primitive primitive;
    primitive.attributes["POSITION"] = buffer.add_vec3(surface.V, mm_to_unit, true);
    primitive.indices = buffer.add_indices(surface.F, surface.V.rows());
    primitive.mode = TINYGLTF_MODE_TRIANGLES;
    buffer.finish();
    m.meshes.emplace_back().primitives.push_back(primitive);
    m.nodes.emplace_back().mesh = 0;
    m.scenes.emplace_back().nodes.push_back(0);
    m.defaultScene = 0;
    return m;
}

// Writes `model` to a temporary name beside `file`, then renames it into place
// (detail::write_atomically).
void write_model(const fs::path& file, const tinygltf::Model& model) {
    const bool binary = detail::lowercase_extension(file) == ".glb";
    detail::write_atomically(file, [&](std::ostream& out) {
        tinygltf::TinyGLTF writer;
        return writer.WriteGltfSceneToStream(&model, out, true, binary);
    });
}

// ---- Scenes: plain data <-> tinygltf ---------------------------------------------------------

constexpr double kMmToM = 1e-3;
constexpr const char* kTransmission = "KHR_materials_transmission";
constexpr const char* kIor = "KHR_materials_ior";
constexpr const char* kVolume = "KHR_materials_volume";
constexpr const char* kLights = "KHR_lights_punctual";

tinygltf::Value number_array(const Eigen::VectorXd& x) {
    tinygltf::Value::Array a;
    for (Eigen::Index k = 0; k < x.size(); ++k)
        a.emplace_back(x[k]);
    return tinygltf::Value(std::move(a));
}

std::vector<double> std_vector(const Eigen::VectorXd& x) {
    return {x.data(), x.data() + x.size()};
}

// glTF stores a rotation as the quaternion (x, y, z, w).
std::vector<double> gltf_rotation(const Eigen::Matrix3d& R) {
    const Eigen::Quaterniond q(R);
    return {q.x(), q.y(), q.z(), q.w()};
}

tinygltf::Value extras_value(const GltfExtras& extras) {
    tinygltf::Value::Object o;
    for (const auto& [key, value] : extras)
        o[key] = std::visit([](const auto& v) { return tinygltf::Value(v); }, value);
    return tinygltf::Value(std::move(o));
}

// Numbers and text of a flat extras object (flags as 0 / 1); anything else is left out.
GltfExtras read_extras(const tinygltf::Value& v) {
    GltfExtras extras;
    if (!v.IsObject()) return extras;
    for (const std::string& key : v.Keys()) {
        const tinygltf::Value& x = v.Get(key);
        if (x.IsNumber())
            extras[key] = x.GetNumberAsDouble();
        else if (x.IsBool())
            extras[key] = x.Get<bool>() ? 1.0 : 0.0;
        else if (x.IsString())
            extras[key] = x.Get<std::string>();
    }
    return extras;
}

tinygltf::Material gltf_material(const GltfMaterial& g, std::set<std::string>& used) {
    tinygltf::Material m;
    m.name = g.name;
    m.pbrMetallicRoughness.baseColorFactor = std_vector(g.base_color);
    m.pbrMetallicRoughness.metallicFactor = g.metallic;
    m.pbrMetallicRoughness.roughnessFactor = g.roughness;
    m.emissiveFactor = std_vector(g.emissive);
    m.doubleSided = g.double_sided;
    const auto add = [&](const char* name, tinygltf::Value::Object o) {
        m.extensions[name] = tinygltf::Value(std::move(o));
        used.insert(name);
    };
    if (g.transmission)
        add(kTransmission, {{"transmissionFactor", tinygltf::Value(*g.transmission)}});
    if (g.ior) add(kIor, {{"ior", tinygltf::Value(*g.ior)}});
    if (g.volume)
        add(kVolume,
            {{"thicknessFactor", tinygltf::Value(g.volume->thickness_mm * kMmToM)},
             {"attenuationDistance", tinygltf::Value(g.volume->attenuation_distance_mm * kMmToM)},
             {"attenuationColor", number_array(g.volume->attenuation_color)}});
    if (!g.extras.empty()) m.extras = extras_value(g.extras);
    return m;
}

// Adds a node below the root (node 0) and returns it.
tinygltf::Node& add_child(tinygltf::Model& m, const std::string& name) {
    m.nodes[0].children.push_back(int(m.nodes.size()));
    tinygltf::Node& node = m.nodes.emplace_back();
    node.name = name;
    return node;
}

void add_mesh(tinygltf::Model& m, BufferWriter& buffer, const GltfMesh& g,
              std::set<std::string>& used) {
    detail::check_mesh(g);
    tinygltf::Primitive p;
    p.attributes["POSITION"] = buffer.add_vec3(g.surface.V, kMmToM, true);
    if (g.normals.rows() != 0) p.attributes["NORMAL"] = buffer.add_vec3(g.normals, 1.0, false);
    p.indices = buffer.add_indices(g.surface.F, g.surface.V.rows());
    p.mode = TINYGLTF_MODE_TRIANGLES;
    p.material = int(m.materials.size());
    m.materials.push_back(gltf_material(g.material, used));
    tinygltf::Mesh& mesh = m.meshes.emplace_back();
    mesh.name = g.name;
    mesh.primitives.push_back(p);
    add_child(m, g.name).mesh = int(m.meshes.size()) - 1;
}

void add_light(tinygltf::Model& m, const GltfLight& g) {
    tinygltf::Light light;
    light.name = g.name;
    light.type = g.type == GltfLight::Type::spot ? "spot" : "point";
    light.color = std_vector(g.color);
    light.intensity = g.intensity_cd;
    light.spot.innerConeAngle = g.inner_cone_rad;
    light.spot.outerConeAngle = g.outer_cone_rad;
    tinygltf::Node& node = add_child(m, g.name);
    node.translation = std_vector(g.position_mm * kMmToM);
    // A glTF light shines along its node's -Z.
    node.rotation = gltf_rotation(
        Eigen::Quaterniond::FromTwoVectors(-Eigen::Vector3d::UnitZ(), g.direction.normalized())
            .toRotationMatrix());
    node.extensions[kLights] =
        tinygltf::Value(tinygltf::Value::Object{{"light", tinygltf::Value(int(m.lights.size()))}});
    m.lights.push_back(std::move(light));
}

// chromasim cameras: x right, y down, z forward; glTF cameras: x right, y up, looking along -z.
const Eigen::Matrix3d kFlipYZ = Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();

void add_camera(tinygltf::Model& m, const GltfCamera& g) {
    tinygltf::Camera camera;
    camera.name = g.name;
    camera.type = "perspective";
    camera.perspective.yfov = g.yfov_rad;
    camera.perspective.aspectRatio = g.aspect_ratio;
    camera.perspective.znear = g.znear_mm * kMmToM;
    camera.perspective.zfar = g.zfar_mm * kMmToM;
    camera.extras = extras_value(g.extras);
    tinygltf::Node& node = add_child(m, g.name);
    node.translation = std_vector(g.position_mm * kMmToM);
    node.rotation = gltf_rotation(g.rotation * kFlipYZ);
    node.camera = int(m.cameras.size());
    m.cameras.push_back(std::move(camera));
}

tinygltf::Model scene_model(const GltfScene& scene) {
    tinygltf::Model m = new_model();
    // Root: chromasim's z up becomes glTF's y up (-90 deg about x: +y -> -z, +z -> +y).
    tinygltf::Node& root = m.nodes.emplace_back();
    root.name = "chromasim_dome_frame";
    root.rotation = gltf_rotation(
        Eigen::AngleAxisd(-0.5 * std::numbers::pi, Eigen::Vector3d::UnitX()).toRotationMatrix());
    std::set<std::string> used;
    BufferWriter buffer(m);
    for (const GltfMesh& mesh : scene.meshes)
        add_mesh(m, buffer, mesh, used);
    buffer.finish();
    for (const GltfLight& light : scene.lights)
        add_light(m, light);
    if (!scene.lights.empty()) used.insert(kLights);
    if (scene.camera) add_camera(m, *scene.camera);
    tinygltf::Scene& s = m.scenes.emplace_back();
    s.name = scene.name;
    s.nodes.push_back(0);
    s.extras = extras_value(scene.extras);
    m.defaultScene = 0;
    m.extensionsUsed.assign(used.begin(), used.end());
    return m;
}

// ---- Scenes: reading back -------------------------------------------------------------------

double number_or(const tinygltf::Value& object, const char* key, double fallback) {
    return object.Has(key) && object.Get(key).IsNumber() ? object.Get(key).GetNumberAsDouble()
                                                         : fallback;
}

template <int N>
Eigen::Matrix<double, N, 1> vector_or(const std::vector<double>& x,
                                      Eigen::Matrix<double, N, 1> fallback) {
    return x.size() == std::size_t(N) ? Eigen::Matrix<double, N, 1>(
                                            Eigen::Map<const Eigen::Matrix<double, N, 1>>(x.data()))
                                      : fallback;
}

GltfMaterial read_material(const tinygltf::Material& m, double scale_to_mm) {
    GltfMaterial g;
    g.name = m.name;
    g.base_color = vector_or<4>(m.pbrMetallicRoughness.baseColorFactor, g.base_color);
    g.metallic = m.pbrMetallicRoughness.metallicFactor;
    g.roughness = m.pbrMetallicRoughness.roughnessFactor;
    g.emissive = vector_or<3>(m.emissiveFactor, g.emissive);
    g.double_sided = m.doubleSided;
    const auto ext = [&](const char* name) {
        const auto it = m.extensions.find(name);
        return it == m.extensions.end() ? nullptr : &it->second;
    };
    if (const auto* t = ext(kTransmission)) g.transmission = number_or(*t, "transmissionFactor", 0);
    if (const auto* i = ext(kIor)) g.ior = number_or(*i, "ior", 1.5);
    if (const auto* v = ext(kVolume)) {
        GltfVolume volume;
        volume.thickness_mm = number_or(*v, "thicknessFactor", 0.0) * scale_to_mm;
        volume.attenuation_distance_mm =
            number_or(*v, "attenuationDistance", std::numeric_limits<double>::infinity()) *
            scale_to_mm;
        if (v->Has("attenuationColor") && v->Get("attenuationColor").ArrayLen() == 3)
            for (int k = 0; k < 3; ++k)
                volume.attenuation_color[k] = v->Get("attenuationColor").Get(k).GetNumberAsDouble();
        g.volume = volume;
    }
    g.extras = read_extras(m.extras);
    return g;
}

class SceneReader {
public:
    SceneReader(const fs::path& file, const tinygltf::Model& model, double scale_to_mm)
        : m_file(file), m_model(model), m_scale(scale_to_mm) {}

    void add_node(int index, const tinygltf::Node& node, const Eigen::Affine3d& world) {
        if (node.mesh >= 0) add_mesh(index, node, world);
        if (const auto it = node.extensions.find(kLights); it != node.extensions.end())
            add_light(index, it->second, world);
        if (node.camera >= 0 && !scene.camera) add_camera(index, node, world);
    }

    GltfScene scene;

private:
    void add_mesh(int index, const tinygltf::Node& node, const Eigen::Affine3d& world);
    void add_light(int index, const tinygltf::Value& ext, const Eigen::Affine3d& world);
    void add_camera(int index, const tinygltf::Node& node, const Eigen::Affine3d& world);

    const fs::path& m_file;
    const tinygltf::Model& m_model;
    double m_scale;
};

void SceneReader::add_mesh(int index, const tinygltf::Node& node, const Eigen::Affine3d& world) {
    const tinygltf::Mesh& mesh = node_mesh(m_file, m_model, index, node);
    std::vector<Eigen::Vector3d> V, N;
    IndexTriangles F;
    GltfMesh g;
    g.name = mesh.name.empty() ? node.name : mesh.name;
    const Eigen::Matrix3d normal_matrix = world.linear().inverse().transpose();
    for (std::size_t k = 0; k < mesh.primitives.size(); ++k) {
        const tinygltf::Primitive& p = mesh.primitives[k];
        const std::string what =
            "mesh " + std::to_string(node.mesh) + " primitive " + std::to_string(k);
        if (p.mode < TINYGLTF_MODE_TRIANGLES || !p.attributes.count("POSITION")) continue;
        if (k == 0 && p.material >= 0 && std::size_t(p.material) < m_model.materials.size())
            g.material = read_material(m_model.materials[std::size_t(p.material)], m_scale);
        const auto P = read_positions(m_file, m_model, p.attributes.at("POSITION"), what);
        const auto base = std::uint32_t(V.size());
        for (const auto& t : primitive_triangles(m_file, m_model, p, what, P.size()))
            F.push_back({base + t[0], base + t[1], base + t[2]});
        for (const auto& x : P)
            V.push_back(m_scale * (world * x));
        if (const auto n = p.attributes.find("NORMAL"); n != p.attributes.end())
            for (const auto& x : read_positions(m_file, m_model, n->second, what + " NORMAL"))
                N.push_back((normal_matrix * x).normalized());
    }
    detail::set_mesh_arrays(V, F, N, g);
    scene.meshes.push_back(std::move(g));
}

void SceneReader::add_light(int index, const tinygltf::Value& ext, const Eigen::Affine3d& world) {
    const int k = ext.Has("light") ? ext.Get("light").GetNumberAsInt() : -1;
    if (k < 0 || std::size_t(k) >= m_model.lights.size())
        fail(m_file, "node " + std::to_string(index) + " uses light " + std::to_string(k) +
                         ", which does not exist");
    const tinygltf::Light& light = m_model.lights[std::size_t(k)];
    GltfLight g;
    g.name = light.name;
    g.type = light.type == "spot" ? GltfLight::Type::spot : GltfLight::Type::point;
    g.position_mm = m_scale * world.translation();
    g.direction = (world.linear() * -Eigen::Vector3d::UnitZ()).normalized();
    g.color = vector_or<3>(light.color, g.color);
    g.intensity_cd = light.intensity;
    g.inner_cone_rad = light.spot.innerConeAngle;
    g.outer_cone_rad = light.spot.outerConeAngle;
    scene.lights.push_back(std::move(g));
}

void SceneReader::add_camera(int index, const tinygltf::Node& node, const Eigen::Affine3d& world) {
    if (std::size_t(node.camera) >= m_model.cameras.size())
        fail(m_file, "node " + std::to_string(index) + " uses camera " +
                         std::to_string(node.camera) + ", which does not exist");
    const tinygltf::Camera& camera = m_model.cameras[std::size_t(node.camera)];
    GltfCamera g;
    g.name = camera.name;
    g.position_mm = m_scale * world.translation();
    g.rotation = world.linear() * kFlipYZ;
    g.yfov_rad = camera.perspective.yfov;
    g.aspect_ratio = camera.perspective.aspectRatio;
    g.znear_mm = camera.perspective.znear * m_scale;
    g.zfar_mm = camera.perspective.zfar * m_scale;
    g.extras = read_extras(camera.extras);
    scene.camera = std::move(g);
}

} // namespace

mechanics::TriangleSurface load_gltf_surface(const fs::path& file, double scale_to_mm,
                                             GltfLoadReport* report) {
    if (!(scale_to_mm > 0.0 && std::isfinite(scale_to_mm)))
        throw std::invalid_argument("load_gltf_surface: scale_to_mm must be finite and > 0");
    const tinygltf::Model model = parse(file);
    SurfaceBuilder builder(file, model, scale_to_mm);
    walk_scene(file, model, default_scene(file, model),
               [&](int index, const tinygltf::Node& node, const Eigen::Affine3d& world) {
                   builder.add_node(index, node, world);
               });
    mechanics::TriangleSurface surface = builder.surface.finish(file);
    if (report) *report = builder.surface.report;
    return surface;
}

void write_gltf_surface(const fs::path& file, const mechanics::TriangleSurface& surface,
                        double mm_to_unit) {
    mechanics::validate_surface(surface);
    if (!(mm_to_unit > 0.0 && std::isfinite(mm_to_unit)))
        throw std::invalid_argument("write_gltf_surface: mm_to_unit must be finite and > 0");
    check_gltf_output_path(file);
    write_model(file, surface_model(surface, mm_to_unit));
}

void write_gltf_scene(const fs::path& file, const GltfScene& scene) {
    check_gltf_output_path(file);
    write_model(file, scene_model(scene));
}

GltfSceneFile read_gltf_scene(const fs::path& file, double scale_to_mm) {
    if (!(scale_to_mm > 0.0 && std::isfinite(scale_to_mm)))
        throw std::invalid_argument("read_gltf_scene: scale_to_mm must be finite and > 0");
    const tinygltf::Model model = parse(file);
    const int scene = default_scene(file, model);
    SceneReader reader(file, model, scale_to_mm);
    walk_scene(file, model, scene,
               [&](int index, const tinygltf::Node& node, const Eigen::Affine3d& world) {
                   reader.add_node(index, node, world);
               });
    GltfSceneFile out;
    out.scene = std::move(reader.scene);
    out.scene.name = model.scenes[std::size_t(scene)].name;
    out.scene.extras = read_extras(model.scenes[std::size_t(scene)].extras);
    out.generator = model.asset.generator;
    out.extensions_used = model.extensionsUsed;
    return out;
}

} // namespace chromasim::generators
