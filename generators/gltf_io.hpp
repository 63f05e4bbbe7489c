#pragma once
/// glTF 2.0 object meshes: the one door to tinygltf (linked as Debian's shared libtinygltf,
/// which carries the implementation and its JSON and image dependencies).
///
/// glTF lengths are metres (glTF 2.0 spec, "Coordinate System and Units"); chromasim works in
/// millimetres, hence the default factors of 1000 and 1e-3 below.
#include "mechanics/object_mesh.hpp"

#include <filesystem>

namespace chromasim::generators {

/// What load_gltf_surface took and left out.
struct GltfLoadReport {
    int primitives_used = 0;    ///< TRIANGLES, TRIANGLE_STRIP or TRIANGLE_FAN primitives read
    int primitives_skipped = 0; ///< POINTS, LINES, LINE_LOOP or LINE_STRIP: no area, left out
    int degenerate_triangles_dropped = 0; ///< repeated or collinear vertices (strip joins)
};

/// Loads the triangles of a .gltf (JSON; buffers embedded as data URIs or in files beside it)
/// or .glb (binary) file, told apart by the "glTF" magic of the binary form, into one surface
/// in mm (positions times `scale_to_mm`; 1000 for glTF's metres).
///
/// - Walks the node trees of the default scene (scene 0 if none is named), applying each
///   node's matrix or translation * rotation * scale to its meshes; a mesh used by several
///   nodes appears once per node. A mirroring transform (det < 0) flips the winding back.
/// - Primitives: TRIANGLES, TRIANGLE_STRIP and TRIANGLE_FAN are read, indexed (UNSIGNED_BYTE,
///   UNSIGNED_SHORT or UNSIGNED_INT indices) or not; POINTS and LINES* have no area and are
///   skipped and counted in `report`. POSITION must be a FLOAT VEC3 accessor (any byteStride);
///   sparse accessors, accessors without a bufferView and required extensions (Draco,
///   quantization, ...) are rejected.
/// - Degenerate triangles (mechanics::is_degenerate_triangle, after the transform and the
///   scale) are dropped and counted; the rest passes mechanics::validate_surface.
///
/// Errors: std::runtime_error whose message starts with the file path and says what is wrong
/// and what is allowed: missing or unreadable file, tinygltf's parse error, no scene, a bad
/// accessor, an index out of range, non-finite positions, no triangle at all.
/// std::invalid_argument if `scale_to_mm` is not finite and > 0.
mechanics::TriangleSurface load_gltf_surface(const std::filesystem::path& file,
                                             double scale_to_mm = 1000.0,
                                             GltfLoadReport* report = nullptr);

/// Writes `surface` (mm) as a minimal glTF 2.0 file: one scene, one node without transform,
/// one TRIANGLES primitive, positions times `mm_to_unit` as FLOAT (1e-3: metres), indices
/// UNSIGNED_SHORT when #V < 65535 else UNSIGNED_INT. `.gltf` (any case): JSON with the buffer
/// embedded as a base64 data URI; `.glb`: binary. Written to a temporary name beside `file`
/// and renamed into place, so `file` is never half-written.
/// Errors: std::invalid_argument for an invalid surface (validate_surface) or a non-positive
/// `mm_to_unit`; std::runtime_error naming the file for another extension or a failed write.
void write_gltf_surface(const std::filesystem::path& file,
                        const mechanics::TriangleSurface& surface, double mm_to_unit = 1e-3);

} // namespace chromasim::generators
