#pragma once
/// The glTF adapter's internals shared by its three files: gltf_io.cpp (the one file that
/// includes tinygltf: glTF models to and from chromasim's data), gltf_mesh.cpp (accessor data,
/// triangles and surfaces) and gltf_files.cpp (reading, checking and writing the files).
/// Include only from those.
#include "generators/io/gltf_io.hpp"

#include <Eigen/Geometry>

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <ostream>
#include <string>
#include <vector>

namespace chromasim::generators::detail {

// glTF 2.0 enumerations, as the spec numbers them (gltf_io.cpp checks them against tinygltf's).
inline constexpr int kComponentByte = 5120, kComponentUnsignedByte = 5121, kComponentShort = 5122,
                     kComponentUnsignedShort = 5123, kComponentInt = 5124,
                     kComponentUnsignedInt = 5125, kComponentFloat = 5126, kComponentDouble = 5130;
inline constexpr int kModeTriangles = 4, kModeTriangleStrip = 5, kModeTriangleFan = 6;

// ---- Files (gltf_files.cpp) -----------------------------------------------------------------

/// Throws std::runtime_error "FILE: WHAT".
[[noreturn]] void fail(const std::filesystem::path& file, const std::string& what);

/// `file`'s extension in lowercase (".gltf", ".glb", ...).
std::string lowercase_extension(const std::filesystem::path& file);

/// The bytes of a glTF file; fails for a missing, unreadable or over 4 GiB file.
std::vector<unsigned char> read_bytes(const std::filesystem::path& file);

/// Calls `write` on a temporary file beside `file`, then renames it into place; removes the
/// temporary file on any failure (`write` returning false, a failed write or rename).
void write_atomically(const std::filesystem::path& file,
                      const std::function<bool(std::ostream&)>& write);

// ---- Accessor data, triangles and surfaces (gltf_mesh.cpp) ------------------------------------

/// Name of a primitive mode (0 to 6), as the glTF spec writes it.
const char* mode_name(int mode);

/// Bytes of one accessor: element k starts at data + k * stride.
struct AccessorBytes {
    const unsigned char* data = nullptr;
    std::size_t stride = 0;
    std::size_t count = 0;
    int component = 0;
};

/// The VEC3 elements of accessor `index` (`what` names it in errors): FLOAT only, finite.
std::vector<Eigen::Vector3d> decode_positions(const std::filesystem::path& file,
                                              const AccessorBytes& a, int index,
                                              const std::string& what);

/// The SCALAR elements of accessor `index`: UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT.
std::vector<std::uint32_t> decode_indices(const std::filesystem::path& file, const AccessorBytes& a,
                                          int index, const std::string& what);

/// Vertex index triples of triangles.
using IndexTriangles = std::vector<std::array<std::uint32_t, 3>>;

/// The triangles of a primitive's indices `idx`, in the order of `mode` (none for a mode
/// without area).
IndexTriangles triangle_indices(const std::vector<std::uint32_t>& idx, int mode);

/// The one surface load_gltf_surface builds from the primitives it reads, in mm.
class SurfaceAssembly {
public:
    explicit SurfaceAssembly(double scale_to_mm) : m_scale(scale_to_mm) {}

    /// Counts a primitive of `mode` (POINTS or LINES*: no area) as skipped.
    void skip(int mode);
    /// Adds a primitive: its POSITION entries `P` placed by `world` and times the scale, and its
    /// `triangles` (indices into P), their winding flipped back under a mirroring `world`.
    /// Degenerate triangles are dropped and counted.
    void add(const std::vector<Eigen::Vector3d>& P, const IndexTriangles& triangles,
             const Eigen::Affine3d& world);
    /// The surface; fails, saying what was left out, if it has no triangle.
    mechanics::TriangleSurface finish(const std::filesystem::path& file) const;

    GltfLoadReport report;

private:
    double m_scale;
    std::vector<int> m_skipped_modes = std::vector<int>(7, 0);
    std::vector<Eigen::Vector3d> m_V;
    std::vector<Eigen::Vector3i> m_F;
};

/// Throws the std::invalid_argument write_gltf_scene gives for a mesh it cannot write.
void check_mesh(const GltfMesh& mesh);

/// Sets `g`'s surface from vertices `V` (mm) and triangles `F`, and its normals from `N` when
/// there is one per vertex.
void set_mesh_arrays(const std::vector<Eigen::Vector3d>& V, const IndexTriangles& F,
                     const std::vector<Eigen::Vector3d>& N, GltfMesh& g);

} // namespace chromasim::generators::detail
