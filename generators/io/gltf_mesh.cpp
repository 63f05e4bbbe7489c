#include "generators/io/gltf_detail.hpp"

// The glTF adapter's geometry, apart from tinygltf's model: accessor bytes decoded into
// positions and indices, primitives into triangles, the surface load_gltf_surface returns, and
// the arrays and checks of scene meshes.

#include <cstring>
#include <stdexcept>
#include <utility>

namespace chromasim::generators::detail {

namespace fs = std::filesystem;

namespace {

const char* component_name(int type) {
    switch (type) {
    case kComponentByte:
        return "BYTE";
    case kComponentUnsignedByte:
        return "UNSIGNED_BYTE";
    case kComponentShort:
        return "SHORT";
    case kComponentUnsignedShort:
        return "UNSIGNED_SHORT";
    case kComponentInt:
        return "INT";
    case kComponentUnsignedInt:
        return "UNSIGNED_INT";
    case kComponentFloat:
        return "FLOAT";
    case kComponentDouble:
        return "DOUBLE";
    default:
        return "unknown";
    }
}

} // namespace

const char* mode_name(int mode) {
    static const char* names[] = {"POINTS",    "LINES",          "LINE_LOOP",   "LINE_STRIP",
                                  "TRIANGLES", "TRIANGLE_STRIP", "TRIANGLE_FAN"};
    return mode >= 0 && mode <= 6 ? names[mode] : "unknown";
}

// ---- Accessor data --------------------------------------------------------------------------

std::vector<Eigen::Vector3d> decode_positions(const fs::path& file, const AccessorBytes& a,
                                              int index, const std::string& what) {
    if (a.component != kComponentFloat)
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

std::vector<std::uint32_t> decode_indices(const fs::path& file, const AccessorBytes& a, int index,
                                          const std::string& what) {
    std::vector<std::uint32_t> out(a.count);
    for (std::size_t k = 0; k < a.count; ++k) {
        const unsigned char* e = a.data + k * a.stride;
        switch (a.component) {
        case kComponentUnsignedByte:
            out[k] = *e;
            break;
        case kComponentUnsignedShort: {
            std::uint16_t v;
            std::memcpy(&v, e, sizeof v);
            out[k] = v;
            break;
        }
        case kComponentUnsignedInt:
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

// ---- Triangles and surfaces -----------------------------------------------------------------

IndexTriangles triangle_indices(const std::vector<std::uint32_t>& idx, int mode) {
    IndexTriangles t;
    const std::size_t n = idx.size();
    if (mode == kModeTriangles)
        for (std::size_t k = 0; k + 2 < n; k += 3)
            t.push_back({idx[k], idx[k + 1], idx[k + 2]});
    else if (mode == kModeTriangleStrip) // every other triangle reversed
        for (std::size_t k = 0; k + 2 < n; ++k)
            t.push_back(k % 2 == 0 ? std::array{idx[k], idx[k + 1], idx[k + 2]}
                                   : std::array{idx[k + 1], idx[k], idx[k + 2]});
    else if (mode == kModeTriangleFan)
        for (std::size_t k = 1; k + 1 < n; ++k)
            t.push_back({idx[0], idx[k], idx[k + 1]});
    return t;
}

void SurfaceAssembly::skip(int mode) {
    ++report.primitives_skipped;
    ++m_skipped_modes[std::size_t(mode)];
}

void SurfaceAssembly::add(const std::vector<Eigen::Vector3d>& P, const IndexTriangles& triangles,
                          const Eigen::Affine3d& world) {
    const int base = int(m_V.size());
    for (const auto& x : P)
        m_V.push_back(m_scale * (world * x));
    const bool mirrored = world.linear().determinant() < 0.0; // keep the winding outward
    for (auto t : triangles) {
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

mechanics::TriangleSurface SurfaceAssembly::finish(const fs::path& file) const {
    if (m_F.empty()) {
        std::string what = "no triangle in the default scene";
        for (int mode = 0; mode < 4; ++mode)
            if (m_skipped_modes[std::size_t(mode)] > 0)
                what += "; " + std::to_string(m_skipped_modes[std::size_t(mode)]) + " " +
                        mode_name(mode) + " primitive(s) skipped";
        if (report.degenerate_triangles_dropped > 0)
            what += "; " + std::to_string(report.degenerate_triangles_dropped) +
                    " degenerate triangle(s) dropped";
        fail(file, what + "; an object needs TRIANGLES, TRIANGLE_STRIP or TRIANGLE_FAN "
                          "primitives with a non-zero area");
    }
    return mechanics::triangle_surface(m_V, m_F);
}

// ---- Scene meshes ---------------------------------------------------------------------------

void check_mesh(const GltfMesh& mesh) {
    const auto bad = [&](const std::string& what) {
        throw std::invalid_argument("write_gltf_scene: mesh '" + mesh.name + "': " + what);
    };
    const render::SurfaceMesh& s = mesh.surface;
    if (s.F.rows() == 0) bad("no triangle; leave an empty mesh out");
    if (s.F.maxCoeff() >= s.V.rows())
        bad("vertex index " + std::to_string(s.F.maxCoeff()) + " out of range [0, " +
            std::to_string(s.V.rows()) + ")");
    if (!s.V.allFinite()) bad("positions must be finite");
    if (mesh.normals.rows() != 0 && mesh.normals.rows() != s.V.rows())
        bad("normals must have one row per vertex or none");
}

void set_mesh_arrays(const std::vector<Eigen::Vector3d>& V, const IndexTriangles& F,
                     const std::vector<Eigen::Vector3d>& N, GltfMesh& g) {
    g.surface.V.resize(Eigen::Index(V.size()), 3);
    for (std::size_t i = 0; i < V.size(); ++i)
        g.surface.V.row(Eigen::Index(i)) = V[i].transpose().cast<float>();
    g.surface.F.resize(Eigen::Index(F.size()), 3);
    for (std::size_t f = 0; f < F.size(); ++f)
        g.surface.F.row(Eigen::Index(f)) << F[f][0], F[f][1], F[f][2];
    if (N.size() == V.size() && !N.empty()) {
        g.normals.resize(Eigen::Index(N.size()), 3);
        for (std::size_t i = 0; i < N.size(); ++i)
            g.normals.row(Eigen::Index(i)) = N[i].transpose().cast<float>();
    }
}

} // namespace chromasim::generators::detail
