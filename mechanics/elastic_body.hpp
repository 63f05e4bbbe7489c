#pragma once
/// A linear elastic tet body loaded only through forces on a set of candidate surface nodes
/// (where an object may touch): one sparse factorization, then the compliance of the
/// candidates and the response of chosen observed points, so that a frame costs a small
/// contact solve and a dense product, never a sparse solve.
#include "mechanics/contact.hpp"
#include "mechanics/linear_elasticity.hpp"
#include "mechanics/tet_mesh.hpp"

#include <memory>
#include <vector>

namespace chromasim::mechanics {

/// Points embedded in the mesh: the tet holding each point and the point's barycentric
/// coordinates there (of the curved map on a quadratic mesh: interpolation_stencil turns them
/// into node weights).
struct Embedding {
    std::vector<int> tet;
    std::vector<Eigen::Vector4d> weights;
};

/// Embeds points (mm); throws std::runtime_error naming the first point outside the mesh.
Embedding embed(const TetMesh& mesh, const Points& P, const char* what = "point");

/// What the precomputation produces (and an on-disk cache can hold).
struct ElasticBodyResponses {
    Eigen::MatrixXd compliance; ///< 3n x 3n (mm/N) of the n candidates
    Eigen::MatrixXd observed;   ///< 3 #observed x 3n (mm/N): observed nodes, then points
};

struct ElasticBodyStats {
    double assemble_s = 0, factorize_s = 0, compliance_s = 0;
    int free_dofs = 0, candidates = 0;
};

class ElasticBody {
public:
    /// `materials[region - 1]` per tet; `clamped[v]` fixes node v; forces may act on the
    /// `candidates` (node ids); the response is precomputed for `observed_nodes` (first) and
    /// the `observed_points` embedding (after). Throws std::runtime_error if K is singular.
    ElasticBody(const TetMesh& mesh, const std::vector<Material>& materials,
                const std::vector<bool>& clamped, std::vector<int> candidates,
                std::vector<int> observed_nodes, Embedding observed_points,
                Volumetric volumetric = Volumetric::element);
    /// Same body from responses computed earlier (a cache): no factorization until
    /// full_displacement is first called. `observed_points` may be empty then.
    ElasticBody(const TetMesh& mesh, const std::vector<Material>& materials,
                const std::vector<bool>& clamped, std::vector<int> candidates,
                Volumetric volumetric, ElasticBodyResponses responses);
    ~ElasticBody();
    ElasticBody(const ElasticBody&) = delete;
    ElasticBody& operator=(const ElasticBody&) = delete;

    /// 3n x 3n compliance of the n candidates (mm/N; dofs x, y, z per candidate), symmetric.
    const Eigen::MatrixXd& compliance() const;
    const ElasticBodyResponses& responses() const;
    const std::vector<int>& candidates() const;

    /// Displacements (mm, 3 per row) of the observed nodes then the observed points under the
    /// candidate forces `forces_N` (n x 3; only rows in `active` are read).
    Points observed_displacement(const Eigen::Ref<const Points>& forces_N,
                                 const std::vector<int>& active) const;

    /// Every node's displacement (#V x 3, mm): one sparse back-substitution (after a
    /// factorization, the first time, for a body built from cached responses). Thread safe.
    Points full_displacement(const Eigen::Ref<const Points>& forces_N,
                             const std::vector<int>& active) const;

    /// Solves K u = f for a full-size force vector (3 #V, N; entries on clamped dofs are
    /// ignored) and returns the full-size displacement (mm; clamped dofs 0): one sparse
    /// back-substitution (after a factorization, the first time, for a body built from cached
    /// responses). Thread safe: calls on several threads run at once.
    Eigen::VectorXd solve(const Eigen::VectorXd& f_full) const;
    /// solve() with the factor in single precision (SupernodalSolve): about twice as fast and
    /// good to about cond(K) times float's round-off, for iterations whose fixed point does
    /// not depend on it. Thread safe.
    Eigen::VectorXd precondition(const Eigen::VectorXd& f_full) const;
    /// Every dof's displacement (3 #V rows, mm; clamped dofs 0) per unit force on each
    /// candidate dof (3n columns, N), from the single-precision factor (precondition): what a
    /// full solve under a change of the candidate forces needs, as one dense product. Computed
    /// on the first call (3n solves, in blocks on all cores) and kept: 4 x 3 #V x 3n bytes
    /// (147 MB on the very_coarse quadratic dome). Thread safe.
    const Eigen::MatrixXf& candidate_field_responses() const;
    const ElasticBodyStats& stats() const;

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

} // namespace chromasim::mechanics
