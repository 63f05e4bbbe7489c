#include "generators/gltf_io.hpp"

// The one file that includes tinygltf. Debian's libtinygltf carries the implementation, so
// TINYGLTF_IMPLEMENTATION is not defined here (and no stb or JSON header is needed).
#include <tiny_gltf.h>

#include <Eigen/Dense>
#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <unistd.h>
#include <vector>

namespace chromasim::generators {

namespace fs = std::filesystem;

namespace {

[[noreturn]] void fail(const fs::path& file, const std::string& what) {
    throw std::runtime_error(file.string() + ": " + what);
}

std::string lowercase_extension(const fs::path& file) {
    std::string ext = file.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return char(std::tolower(c)); });
    return ext;
}

std::string trimmed(std::string s) {
    while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back())))
        s.pop_back();
    return s;
}

const char* component_name(int type) {
    switch (type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
        return "BYTE";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
        return "UNSIGNED_BYTE";
    case TINYGLTF_COMPONENT_TYPE_SHORT:
        return "SHORT";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
        return "UNSIGNED_SHORT";
    case TINYGLTF_COMPONENT_TYPE_INT:
        return "INT";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
        return "UNSIGNED_INT";
    case TINYGLTF_COMPONENT_TYPE_FLOAT:
        return "FLOAT";
    case TINYGLTF_COMPONENT_TYPE_DOUBLE:
        return "DOUBLE";
    default:
        return "unknown";
    }
}

const char* mode_name(int mode) {
    static const char* names[] = {"POINTS",    "LINES",          "LINE_LOOP",   "LINE_STRIP",
                                  "TRIANGLES", "TRIANGLE_STRIP", "TRIANGLE_FAN"};
    return mode >= 0 && mode <= 6 ? names[mode] : "unknown";
}

// ---- Loading --------------------------------------------------------------------------------

std::vector<unsigned char> read_bytes(const fs::path& file) {
    std::error_code ec;
    if (!fs::is_regular_file(file, ec))
        fail(file, fs::exists(file, ec) ? "not a regular file; expected a glTF 2.0 file"
                                        : "no such file; expected a glTF 2.0 file (.gltf or .glb)");
    std::ifstream in(file, std::ios::binary);
    if (!in) fail(file, "cannot open for reading");
    std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(in)),
                                     std::istreambuf_iterator<char>());
    if (in.bad()) fail(file, "read error");
    if (bytes.size() > std::numeric_limits<unsigned int>::max())
        fail(file, "larger than 4 GiB; glTF files are limited to 4 GiB");
    return bytes;
}

tinygltf::Model parse(const fs::path& file) {
    const std::vector<unsigned char> bytes = read_bytes(file);
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

// Bytes of one accessor: element k starts at data + k * stride.
struct AccessorBytes {
    const unsigned char* data = nullptr;
    std::size_t stride = 0;
    std::size_t count = 0;
    int component = 0;
};

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
    if (a.component != TINYGLTF_COMPONENT_TYPE_FLOAT)
        fail(file, "accessor " + std::to_string(index) + " (" + what + ") has component type " +
                       component_name(a.component) + "; POSITION must be FLOAT");
    std::vector<Eigen::Vector3d> p(a.count);
    for (std::size_t k = 0; k < a.count; ++k) {
        float xyz[3];
        std::memcpy(xyz, a.data + k * a.stride, sizeof xyz);
        p[k] = Eigen::Vector3f(xyz[0], xyz[1], xyz[2]).cast<double>();
        if (!p[k].allFinite())
            fail(file, "accessor " + std::to_string(index) + " (" + what + "): position " +
                           std::to_string(k) + " is not finite; positions must be finite");
    }
    return p;
}

std::vector<std::uint32_t> read_indices(const fs::path& file, const tinygltf::Model& model,
                                        int index, const std::string& what) {
    const AccessorBytes a = accessor_bytes(file, model, index, TINYGLTF_TYPE_SCALAR, what);
    std::vector<std::uint32_t> out(a.count);
    for (std::size_t k = 0; k < a.count; ++k) {
        const unsigned char* e = a.data + k * a.stride;
        switch (a.component) {
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
            out[k] = *e;
            break;
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
            std::uint16_t v;
            std::memcpy(&v, e, sizeof v);
            out[k] = v;
            break;
        }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
            std::memcpy(&out[k], e, sizeof out[k]);
            break;
        default:
            fail(file, "accessor " + std::to_string(index) + " (" + what + ") has component type " +
                           component_name(a.component) +
                           "; indices must be UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT");
        }
    }
    return out;
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

// Vertex index triples of a primitive's triangles, in the order of `mode`.
std::vector<std::array<std::uint32_t, 3>> triangle_indices(const std::vector<std::uint32_t>& idx,
                                                           int mode) {
    std::vector<std::array<std::uint32_t, 3>> t;
    const std::size_t n = idx.size();
    if (mode == TINYGLTF_MODE_TRIANGLES)
        for (std::size_t k = 0; k + 2 < n; k += 3)
            t.push_back({idx[k], idx[k + 1], idx[k + 2]});
    else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) // every other triangle reversed
        for (std::size_t k = 0; k + 2 < n; ++k)
            t.push_back(k % 2 == 0 ? std::array{idx[k], idx[k + 1], idx[k + 2]}
                                   : std::array{idx[k + 1], idx[k], idx[k + 2]});
    else if (mode == TINYGLTF_MODE_TRIANGLE_FAN)
        for (std::size_t k = 1; k + 1 < n; ++k)
            t.push_back({idx[0], idx[k], idx[k + 1]});
    return t;
}

class SurfaceBuilder {
public:
    SurfaceBuilder(const fs::path& file, const tinygltf::Model& model, double scale_to_mm)
        : m_file(file), m_model(model), m_scale(scale_to_mm), m_visited(model.nodes.size(), false) {
    }

    void add_node(int index, const Eigen::Affine3d& parent);
    mechanics::TriangleSurface finish() const;

    GltfLoadReport report;
    std::vector<int> skipped_modes = std::vector<int>(7, 0);

private:
    void add_primitive(const tinygltf::Primitive& p, const std::string& what,
                       const Eigen::Affine3d& world);

    const fs::path& m_file;
    const tinygltf::Model& m_model;
    double m_scale;
    std::vector<bool> m_visited;
    std::vector<Eigen::Vector3d> m_V;
    std::vector<Eigen::Vector3i> m_F;
};

void SurfaceBuilder::add_node(int index, const Eigen::Affine3d& parent) {
    if (index < 0 || std::size_t(index) >= m_model.nodes.size())
        fail(m_file, "node " + std::to_string(index) + " does not exist");
    if (m_visited[std::size_t(index)])
        fail(m_file, "node " + std::to_string(index) +
                         " is reached twice; glTF nodes must form disjoint trees");
    m_visited[std::size_t(index)] = true;
    const tinygltf::Node& node = m_model.nodes[std::size_t(index)];
    const Eigen::Affine3d world = parent * local_transform(node);
    if (node.mesh >= 0) {
        if (std::size_t(node.mesh) >= m_model.meshes.size())
            fail(m_file, "node " + std::to_string(index) + " uses mesh " +
                             std::to_string(node.mesh) + ", which does not exist");
        const auto& primitives = m_model.meshes[std::size_t(node.mesh)].primitives;
        for (std::size_t k = 0; k < primitives.size(); ++k)
            add_primitive(primitives[k],
                          "mesh " + std::to_string(node.mesh) + " primitive " + std::to_string(k),
                          world);
    }
    for (int child : node.children)
        add_node(child, world);
}

void SurfaceBuilder::add_primitive(const tinygltf::Primitive& p, const std::string& what,
                                   const Eigen::Affine3d& world) {
    if (p.mode < 0 || p.mode > TINYGLTF_MODE_TRIANGLE_FAN)
        fail(m_file, what + " has mode " + std::to_string(p.mode) + "; glTF modes are 0 to 6");
    if (p.mode < TINYGLTF_MODE_TRIANGLES) { // points and lines have no area
        ++report.primitives_skipped;
        ++skipped_modes[std::size_t(p.mode)];
        return;
    }
    const auto position = p.attributes.find("POSITION");
    if (position == p.attributes.end()) fail(m_file, what + " has no POSITION attribute");
    const auto P = read_positions(m_file, m_model, position->second, what + " POSITION");
    std::vector<std::uint32_t> idx;
    if (p.indices >= 0)
        idx = read_indices(m_file, m_model, p.indices, what + " indices");
    else
        for (std::uint32_t k = 0; k < P.size(); ++k)
            idx.push_back(k);

    const int base = int(m_V.size());
    for (const auto& x : P)
        m_V.push_back(m_scale * (world * x));
    const bool mirrored = world.linear().determinant() < 0.0; // keep the winding outward
    for (auto t : triangle_indices(idx, p.mode)) {
        for (std::uint32_t i : t)
            if (i >= P.size())
                fail(m_file, what + ": index " + std::to_string(i) + " is out of range [0, " +
                                 std::to_string(P.size()) +
                                 "); indices must refer to entries of POSITION");
        if (mirrored) std::swap(t[1], t[2]);
        const Eigen::Vector3i f(base + int(t[0]), base + int(t[1]), base + int(t[2]));
        if (mechanics::is_degenerate_triangle(m_V[std::size_t(f[0])], m_V[std::size_t(f[1])],
                                              m_V[std::size_t(f[2])]))
            ++report.degenerate_triangles_dropped;
        else
            m_F.push_back(f);
    }
    ++report.primitives_used;
}

mechanics::TriangleSurface SurfaceBuilder::finish() const {
    if (m_F.empty()) {
        std::string what = "no triangle in the default scene";
        for (int mode = 0; mode < 4; ++mode)
            if (skipped_modes[std::size_t(mode)] > 0)
                what += "; " + std::to_string(skipped_modes[std::size_t(mode)]) + " " +
                        mode_name(mode) + " primitive(s) skipped";
        if (report.degenerate_triangles_dropped > 0)
            what += "; " + std::to_string(report.degenerate_triangles_dropped) +
                    " degenerate triangle(s) dropped";
        fail(m_file, what + "; an object needs TRIANGLES, TRIANGLE_STRIP or TRIANGLE_FAN "
                            "primitives with a non-zero area");
    }
    return mechanics::triangle_surface(m_V, m_F);
}

// ---- Writing --------------------------------------------------------------------------------

template <class T> void append_bytes(std::vector<unsigned char>& out, const T& value) {
    const auto* p = reinterpret_cast<const unsigned char*>(&value);
    out.insert(out.end(), p, p + sizeof(T));
}

// Appends V * mm_to_unit as float32 to `data`; the POSITION accessor (on bufferView 0) with
// the min and max that glTF requires, taken from the stored floats.
tinygltf::Accessor append_positions(std::vector<unsigned char>& data, const mechanics::Points& V,
                                    double mm_to_unit) {
    tinygltf::Accessor pos;
    pos.bufferView = 0;
    pos.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
    pos.type = TINYGLTF_TYPE_VEC3;
    pos.count = std::size_t(V.rows());
    pos.minValues.assign(3, std::numeric_limits<double>::infinity());
    pos.maxValues.assign(3, -std::numeric_limits<double>::infinity());
    for (Eigen::Index v = 0; v < V.rows(); ++v)
        for (std::size_t k = 0; k < 3; ++k) {
            const float x = float(V(v, Eigen::Index(k)) * mm_to_unit);
            append_bytes(data, x);
            pos.minValues[k] = std::min(pos.minValues[k], double(x));
            pos.maxValues[k] = std::max(pos.maxValues[k], double(x));
        }
    return pos;
}

// Appends F to `data`, UNSIGNED_SHORT when #V < 65535 (65535 itself is reserved for primitive
// restart in glTF 2.0), else UNSIGNED_INT; the indices accessor (on bufferView 1).
tinygltf::Accessor append_indices(std::vector<unsigned char>& data,
                                  const mechanics::TriangleSurface& s) {
    const bool short_indices = s.V.rows() < 65535;
    for (Eigen::Index f = 0; f < s.F.rows(); ++f)
        for (int k = 0; k < 3; ++k)
            if (short_indices)
                append_bytes(data, std::uint16_t(s.F(f, k)));
            else
                append_bytes(data, std::uint32_t(s.F(f, k)));
    tinygltf::Accessor indices;
    indices.bufferView = 1;
    indices.componentType = short_indices ? TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT
                                          : TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
    indices.type = TINYGLTF_TYPE_SCALAR;
    indices.count = std::size_t(s.F.size());
    return indices;
}

tinygltf::BufferView buffer_view(std::size_t offset, std::size_t length, int target) {
    tinygltf::BufferView view;
    view.buffer = 0;
    view.byteOffset = offset;
    view.byteLength = length;
    view.target = target;
    return view;
}

// One buffer, two views, two accessors, one mesh of one TRIANGLES primitive, one node, one
// scene.
tinygltf::Model surface_model(const mechanics::TriangleSurface& surface, double mm_to_unit) {
    tinygltf::Model m;
    m.asset.version = "2.0";
    m.asset.generator = "chromasim " CHROMASIM_VERSION;
    tinygltf::Buffer buffer;
    m.accessors.push_back(append_positions(buffer.data, surface.V, mm_to_unit));
    const std::size_t position_bytes = buffer.data.size();
    m.accessors.push_back(append_indices(buffer.data, surface));
    m.bufferViews = {buffer_view(0, position_bytes, TINYGLTF_TARGET_ARRAY_BUFFER),
                     buffer_view(position_bytes, buffer.data.size() - position_bytes,
                                 TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER)};
    while (buffer.data.size() % 4 != 0)
        buffer.data.push_back(0);
    m.buffers.push_back(std::move(buffer));

    tinygltf::Primitive primitive;
    primitive.attributes["POSITION"] = 0;
    primitive.indices = 1;
    primitive.mode = TINYGLTF_MODE_TRIANGLES;
    m.meshes.emplace_back().primitives.push_back(primitive);
    m.nodes.emplace_back().mesh = 0;
    m.scenes.emplace_back().nodes.push_back(0);
    m.defaultScene = 0;
    return m;
}

} // namespace

mechanics::TriangleSurface load_gltf_surface(const fs::path& file, double scale_to_mm,
                                             GltfLoadReport* report) {
    if (!(scale_to_mm > 0.0 && std::isfinite(scale_to_mm)))
        throw std::invalid_argument("load_gltf_surface: scale_to_mm must be finite and > 0");
    const tinygltf::Model model = parse(file);
    int scene = model.defaultScene >= 0 ? model.defaultScene : 0;
    if (std::size_t(scene) >= model.scenes.size())
        fail(file, model.scenes.empty()
                       ? "no scene; the objects are read from the default scene"
                       : "default scene " + std::to_string(scene) + " does not exist");
    SurfaceBuilder builder(file, model, scale_to_mm);
    for (int root : model.scenes[std::size_t(scene)].nodes)
        builder.add_node(root, Eigen::Affine3d::Identity());
    mechanics::TriangleSurface surface = builder.finish();
    if (report) *report = builder.report;
    return surface;
}

void write_gltf_surface(const fs::path& file, const mechanics::TriangleSurface& surface,
                        double mm_to_unit) {
    mechanics::validate_surface(surface);
    if (!(mm_to_unit > 0.0 && std::isfinite(mm_to_unit)))
        throw std::invalid_argument("write_gltf_surface: mm_to_unit must be finite and > 0");
    const std::string ext = lowercase_extension(file);
    if (ext != ".gltf" && ext != ".glb")
        fail(file, "unknown extension '" + file.extension().string() +
                       "'; use .gltf (JSON, embedded buffer) or .glb (binary)");
    const tinygltf::Model model = surface_model(surface, mm_to_unit);

    const fs::path tmp = file.string() + ".partial-" + std::to_string(::getpid());
    bool ok = false;
    {
        std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
        if (!out) fail(file, "cannot open " + tmp.string() + " for writing");
        tinygltf::TinyGLTF writer;
        ok = writer.WriteGltfSceneToStream(&model, out, true, ext == ".glb");
        out.close();
        ok = ok && !out.fail();
    }
    std::error_code ec;
    if (ok) fs::rename(tmp, file, ec);
    if (!ok || ec) {
        const std::string why =
            ok ? "cannot rename " + tmp.string() + " into place: " + ec.message()
               : "write error (disk full or folder not writable?)";
        fs::remove(tmp, ec);
        fail(file, why);
    }
}

} // namespace chromasim::generators
