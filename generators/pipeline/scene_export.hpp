#pragma once
/// `chromasim export-scene`: one frame's sensor as a glTF 2.0 scene for a viewer or Blender
/// (docs/EXPORT_SCENE.md): the deformed coating, inner surface and marker volumes with their
/// materials, the LEDs as emissive rectangles, the black frame, and a stand-in for the camera.
#include "generators/output/dataset_writer.hpp"
#include "generators/io/gltf_io.hpp"
#include "generators/spec/spec.hpp"
#include "render/scene_data.hpp"

#include <filesystem>
#include <iosfwd>
#include <string>

namespace chromasim::generators {

/// Vertex normals of `mesh`: the sum of the (unnormalised, so area-weighted) normals of the
/// triangles around each vertex, by winding, normalised. #V x 3; a vertex in no triangle of
/// non-zero area gets (0, 0, 1).
render::VertexArray area_weighted_normals(const render::SurfaceMesh& mesh);

/// What make_gltf_scene needs besides the frame, camera and optics.
struct SceneInfo {
    std::string name;                 ///< the glTF scene's name
    double marker_thickness_mm = 0.5; ///< thicknessFactor of the marker volumes
    GltfExtras extras;                ///< the glTF scene's extras (spec hash, frame, forces, ...)
};

/// The glTF scene of one sensor frame, the scene the renderer sees (mm, chromasim's dome
/// frame; docs/EXPORT_SCENE.md), with `optics`' RGB values:
/// - meshes "coating" (smooth normals, white diffuse), "inner_surface" when `frame` has one
///   (smooth normals, clear: transmission and ior), "inner_markers" and "outer_markers"
///   (flat-shaded closed volumes: transmission, ior 1 and a Beer-Lambert volume; the outer
///   ones scatter), "leds" (one emissive rectangle per LED in the LED plane) and "frame" (the
///   black plane z = 0 beyond the dome's inner radius);
/// - material extras for what glTF cannot say (the outer markers' scatter fraction);
/// - a perspective camera at the camera's pose, with the true fisheye intrinsics in its extras.
/// Throws std::invalid_argument for camera parameters the fisheye camera rejects.
GltfScene make_gltf_scene(const render::SensorFrame& frame, const render::CameraParams& camera,
                          const render::OpticsParams& optics, const SceneInfo& info);

struct SceneExportOptions {
    /// On-disk cache of the mechanics precomputation (empty: off), as for generate.
    std::filesystem::path cache_dir;
};

/// Which frame to export: trial, fingertip (0 left, 1 right) and frame within the trial.
struct SceneSelection {
    int trial = 0, finger = 0, frame = 0;
};

/// What export_scene did.
struct SceneExportReport {
    int trial = 0, finger = 0;
    int frame = 0;   ///< the exported frame
    int frames = 0;  ///< frames in the trial
    LabelRow labels; ///< the exported frame's labels.csv row (forces, Gamma, convergence)
    double total_s = 0.0;
};

/// Writes one fingertip's frame of a trial of a validated spec to `out` (.gltf or .glb,
/// written atomically). Checks first, before any work: the trial, finger and frame within the
/// plan (std::out_of_range naming --trial, --finger or --frame, the value and the allowed
/// range) and the output path (std::runtime_error naming it and what is allowed). Then solves
/// the finger's frames 0 to `frame` in order, each from the previous one (their stick/slip
/// history), as generate does, and exports the last. A frame whose solver did not converge
/// is exported all the same and reported on `log` and in the scene extras.
SceneExportReport export_scene(const Spec& spec, const SceneSelection& which,
                               const std::filesystem::path& out, const SceneExportOptions& options,
                               std::ostream& log);

} // namespace chromasim::generators
