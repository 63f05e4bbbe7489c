#pragma once
/// glTF 2.0 object meshes and sensor scenes: the one door to tinygltf (linked as Debian's
/// shared libtinygltf, which carries the implementation and its JSON and image dependencies).
///
/// glTF lengths are metres (glTF 2.0 spec, "Coordinate System and Units"); chromasim works in
/// millimetres, hence the default factors of 1000 and 1e-3 below.
#include "mechanics/object_mesh.hpp"
#include "render/scene_data.hpp"

#include <Eigen/Core>

#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <variant>
#include <vector>

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

// ---- Sensor scenes (chromasim export-scene, docs/EXPORT_SCENE.md) ----------------------------

/// A flat glTF `extras` object: key -> number or text (flags as 0 / 1, as in labels.csv).
using GltfExtras = std::map<std::string, std::variant<double, std::string>>;

/// KHR_materials_volume: light inside travels through a medium whose transmittance over a
/// distance x is attenuation_color^(x / attenuation_distance), per channel.
struct GltfVolume {
    double thickness_mm = 0.0; ///< thicknessFactor: typical thickness of the volume
    Eigen::Vector3d attenuation_color{1.0, 1.0, 1.0}; ///< in [0, 1]
    double attenuation_distance_mm = 1.0;             ///< > 0
};

/// A metallic-roughness material with the optional extensions chromasim uses.
struct GltfMaterial {
    std::string name;
    Eigen::Vector4d base_color{1.0, 1.0, 1.0, 1.0}; ///< linear RGBA, baseColorFactor
    double metallic = 0.0;
    double roughness = 1.0;
    Eigen::Vector3d emissive = Eigen::Vector3d::Zero(); ///< emissiveFactor, linear RGB
    bool double_sided = false;
    std::optional<double> transmission; ///< KHR_materials_transmission transmissionFactor
    std::optional<double> ior;          ///< KHR_materials_ior
    std::optional<GltfVolume> volume;   ///< KHR_materials_volume
    GltfExtras extras; ///< what glTF cannot say (chromasim's optical model; EXPORT_SCENE.md)
};

/// A named triangle mesh with one material.
struct GltfMesh {
    std::string name;
    render::SurfaceMesh surface; ///< V in mm, F with counter-clockwise front faces
    /// #V x 3 unit vertex normals (the NORMAL attribute), or empty: no NORMAL attribute, so a
    /// viewer shades each triangle flat (glTF 2.0, "Meshes").
    render::VertexArray normals;
    GltfMaterial material;
};

/// A KHR_lights_punctual light.
struct GltfLight {
    enum class Type { point, spot };
    std::string name;
    Type type = Type::point;
    Eigen::Vector3d position_mm = Eigen::Vector3d::Zero();
    Eigen::Vector3d direction{0.0, 0.0, -1.0};  ///< unit; where a spot light points
    Eigen::Vector3d color{1.0, 1.0, 1.0};       ///< linear RGB in [0, 1]
    double intensity_cd = 1.0;                  ///< candela (point and spot lights)
    double inner_cone_rad = 0.0;                ///< spot only, in [0, outer)
    double outer_cone_rad = 0.7853981633974483; ///< spot only, in (inner, pi / 2]
};

/// A perspective glTF camera.
struct GltfCamera {
    std::string name;
    Eigen::Vector3d position_mm = Eigen::Vector3d::Zero();
    /// Orientation as chromasim's cameras hold it: columns are the camera's image-right,
    /// image-down and forward (optical axis) directions. glTF cameras look along their local
    /// -Z with +Y up, so the writer turns this by 180 deg about the camera's x axis.
    Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
    double yfov_rad = 1.0;     ///< vertical field of view, in (0, pi)
    double aspect_ratio = 1.0; ///< width / height
    double znear_mm = 0.1, zfar_mm = 1000.0;
    GltfExtras extras;
};

/// A scene in chromasim's frame and units (mm, z up); the writer converts to glTF's metres
/// and y up.
struct GltfScene {
    std::string name;
    std::vector<GltfMesh> meshes;
    std::vector<GltfLight> lights;
    std::optional<GltfCamera> camera;
    GltfExtras extras; ///< the glTF scene's extras
};

/// Writes `scene` as glTF 2.0: one root node "chromasim_dome_frame" whose rotation (-90 deg
/// about x) maps chromasim's +z (up) to glTF's +y and chromasim's +y to glTF's -z, holding one
/// node per mesh (no transform), per light (translation, and a rotation that points its local
/// -Z along `direction`) and for the camera. Lengths times 1e-3 (metres): positions,
/// thickness and attenuation distance, znear and zfar. Every extension in use is listed in
/// extensionsUsed, none in extensionsRequired (a viewer without them still shows the meshes).
/// asset.generator is "chromasim <version>". `.gltf` (any case): JSON with the buffer
/// embedded as a base64 data URI; `.glb`: binary. Written to a temporary name beside `file`
/// and renamed into place.
/// Errors: std::invalid_argument for a mesh with an index out of range or normals of another
/// size than V; std::runtime_error naming the file for another extension, a missing or
/// unwritable folder or a failed write (nothing is left behind).
void write_gltf_scene(const std::filesystem::path& file, const GltfScene& scene);

/// Throws the std::runtime_error write_gltf_scene would for `file`'s extension or folder
/// (extension not .gltf or .glb; folder missing, not a folder or not writable), so a command
/// can refuse a bad output path before any work.
void check_gltf_output_path(const std::filesystem::path& file);

/// A glTF file read back into a GltfScene as a viewer sees it: every mesh and light node of
/// the default scene with its node transforms applied (the file's frame, y up for a file that
/// write_gltf_scene wrote), lengths times `scale_to_mm`. Meshes keep their node's name
/// (TRIANGLES primitives only; the first primitive's material), lights their light's name;
/// the camera (the first node with one) gets its world rotation in the GltfCamera convention.
struct GltfSceneFile {
    GltfScene scene;
    std::string generator;                    ///< asset.generator
    std::vector<std::string> extensions_used; ///< extensionsUsed
};
/// Errors: as load_gltf_surface, std::runtime_error starting with the file path.
GltfSceneFile read_gltf_scene(const std::filesystem::path& file, double scale_to_mm = 1000.0);

} // namespace chromasim::generators
