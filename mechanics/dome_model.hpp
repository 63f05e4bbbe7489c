#pragma once
/// The layered dome as a linear elastic FE model under a rigid object: meshing, then an
/// ElasticBody (one factorization, the compliance of the surface nodes that can touch, the
/// response of the coating and the markers), then a cheap contact solve per frame. Plain
/// data in, plain data out.
#include "mechanics/contact.hpp"
#include "mechanics/dome_geometry.hpp"
#include "mechanics/elastic_body.hpp"
#include "mechanics/hyperelastic_contact.hpp"
#include "mechanics/linear_elasticity.hpp"
#include "mechanics/surface_strain.hpp"
#include "mechanics/tet_mesh.hpp"

#include <array>
#include <filesystem>
#include <memory>
#include <string>

namespace chromasim::mechanics {

/// Constitutive model of the layers.
enum class MaterialModel {
    linear,     ///< small strain: a frame is a contact solve on precomputed responses
    neo_hookean ///< compressible neo-Hookean, large deformation (hyperelastic_contact.hpp)
};

struct DomeModelOptions {
    DomeParams dome;
    std::string mesh_level = "coarse";
    /// 1: linear tets; 2: quadratic (10-node) tets on the same corners, their edge nodes on the
    /// layers' spheres (quadratic_tets.hpp). Surfaces and contact then use every node.
    int element_order = 1;
    /// Materials of the layers, innermost first (indexed by Layer - 1); the fill's is `fill`.
    std::array<Material, kLayerCount> materials{
        {{0.8, 0.45}, {0.3, 0.45}, {0.8, 0.45}, {1.0, 0.45}}};
    /// Volumetric integration (linear_elasticity.hpp): nodal averaging relieves the locking of
    /// nearly incompressible layers.
    Volumetric volumetric = Volumetric::nodal_average;
    /// The library's default is the small-strain model, the building block its tests check
    /// against analytic answers; a spec's default is neo_hookean (generators/spec/spec_table.cpp).
    MaterialModel material = MaterialModel::linear;
    HyperelasticOptions hyperelastic;
    /// Folder of the on-disk cache of mesh and responses (empty: no cache). Entries are keyed
    /// by a hash of everything above and the chromasim version.
    std::filesystem::path cache_dir;
    /// Outer-surface nodes up to this polar angle may touch the object. Enough for the small
    /// strain model to 3 N; a spec's default is 50 deg, which large-deformation presses need.
    double contact_candidate_angle_deg = 35.0;
    /// Interior (r < the inner radius): hollow (air, the default), a rigid core to which the
    /// inner surface is bonded (every node of the inner surface clamped), or a soft fill:
    /// a meshed solid of material `fill` bonded to the inner layer, its base (z = 0) clamped.
    enum class Interior { hollow, rigid_core, soft_fill } interior = Interior::hollow;
    Material fill{0.05, 0.45};
    /// How a frame without a previous frame reaches its load from rest (contact.hpp).
    LoadPath load_path;
    /// Quadratic tets always use Goodman's approximation (`coupled` = false): coupled, contact
    /// at the six nodes of a face has active sets with no solution under sliding.
    ContactOptions contact;
    /// Grid of the surface strain eps_xx (FrameRequest::strain).
    StrainGridSpec strain_grid;
};

/// A surface of the mesh: the mesh nodes it uses and its triangles in local indices.
struct SurfacePatch {
    std::vector<int> nodes; ///< mesh node per local vertex
    Triangles F;            ///< local vertex indices; orientation documented where built
};

/// Timings (s) and sizes of the precomputation.
struct PrecomputeStats {
    double mesh_s = 0, assemble_s = 0, factorize_s = 0, compliance_s = 0, cache_s = 0;
    int nodes = 0, tets = 0, free_dofs = 0, candidates = 0;
    /// off (no cache folder) | hit (mesh and responses loaded) | miss (computed, then stored) |
    /// rejected (a file was there but unusable: `cache_note` says why; recomputed, rewritten)
    std::string cache = "off";
    std::string cache_note; ///< why a cache file was rejected or could not be written
};

/// What a frame produces. Fields are filled only when asked for (FrameRequest).
struct FrameResult {
    ContactSolution contact;
    double contact_area_mm2 = 0.0;        ///< deformed area in contact (contact_area.hpp)
    double stick_area_mm2 = 0.0;          ///< its part that sticks (contact_area.hpp)
    bool at_candidate_edge = false;       ///< contact reached the rim of the candidate cap
    Points coating_displacement_mm;       ///< per coating_surface() vertex (empty unless requested)
    Points inner_surface_displacement_mm; ///< per inner_surface() vertex (empty unless requested)
    Points marker_points_mm;              ///< deformed MarkerDiscs::points (empty unless requested)
    Points node_displacement_mm;          ///< #V x 3, every node (empty unless requested)
    /// Neo-Hookean frames solved from a previous frame: node_displacement_mm less that frame's
    /// (empty otherwise). The next frame starts from node_displacement_mm plus this step.
    Points node_step_mm;
    /// The next frame's HyperelasticOptions::first_step (large-deformation frames).
    double first_step = 1.0;
    /// Per candidate (candidate_nodes() order; empty unless requested): contact pressure
    /// (normal force over tributary area) and tangential traction on the dome. The stick /
    /// slip / free state per candidate is contact.state, the displacement contact.displacement_mm.
    Eigen::VectorXd pressure_MPa;
    RowVectors2 traction_MPa;
    StrainGrid strain; ///< eps_xx over the contact (empty unless requested)
    /// Neo-Hookean frames: relaxed fixed-point iterations over the frame's steps, and the
    /// smallest tet or nodal J reached (1 for linear frames).
    int material_iterations = 0;
    double min_jacobian = 1.0;
};

/// Which fields a frame computes. The coating and the markers come from the precomputed
/// response of the observed nodes to the contact forces (a small dense product); the full
/// field costs one sparse back-substitution.
struct FrameRequest {
    bool coating = false;       ///< coating displacement (images)
    bool markers = false;       ///< deformed marker discs (images, markers.csv)
    bool full_field = false;    ///< every node's displacement (tests, tools)
    bool surface = false;       ///< pressure and traction per candidate node
    bool strain = false;        ///< eps_xx grid (seed 001, eq. 3)
    bool inner_surface = false; ///< inner surface displacement (the path tracer's refraction)
};

class DomeModel {
public:
    /// Meshes, assembles, factorizes and precomputes. Throws std::runtime_error on failure
    /// (a singular system, a TetGen error, a marker outside the mesh).
    explicit DomeModel(const DomeModelOptions& options);
    ~DomeModel();

    /// Solves one quasi-static frame of `object` under `load`: from `previous` (the frame
    /// before in a trial: its stick/slip history carries over) in options().load_path's
    /// steps, or from rest along that path. Neo-Hookean frames always fill
    /// node_displacement_mm (the next frame starts from it). Safe to call from several threads.
    FrameResult solve(const ContactLoad& load, const FrameRequest& request,
                      const ObjectShape& object = {}, const FrameResult* previous = nullptr) const;

    const TetMesh& mesh() const;
    const MarkerDiscs& markers() const;
    /// Inner face of the coating (interface of layers 3 and 4), normals towards the centre.
    const SurfacePatch& coating_surface() const;
    /// The inner surface of a hollow dome (boundary of the inner layer facing the air cavity,
    /// r = radii_mm[0], less the rim plane), normals towards the cavity; empty for the other
    /// interiors, whose inner layer is bonded to a solid.
    const SurfacePatch& inner_surface() const;
    /// Outer-surface nodes that may touch (mesh node ids), their tributary areas (mm^2), and
    /// the outer triangles between them (indices into candidate_nodes()).
    const std::vector<int>& candidate_nodes() const;
    const std::vector<double>& candidate_areas() const;
    const Triangles& candidate_triangles() const;
    const DomeModelOptions& options() const;
    const PrecomputeStats& stats() const;

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

} // namespace chromasim::mechanics
